"""What crosses the host<->chip link per env step (one inference) of a deployed spiking policy.

In: the first layer's input current for each of the T SNN steps, ``T x n1`` values of one word
each, as the Lava bridge sends them (current encoding holds one current for the T steps, but
the bridge still sends it T times). Out: the last layer's spikes of the T logical steps, one
bit per neuron and step (``payload_bits`` per message for graded spikes), which is all the
host's readout needs. The Lava bridge also returns the other layers' spikes and the pipeline's
fill/drain rows to record the counts and check parity; that is the simulation's bookkeeping,
not what a deployment sends, so it is not counted.
"""

from __future__ import annotations

WORD_BITS = {"float32": 32, "float64": 64, "float": 64, "fixed": 24}
"""Bits of one input-current value per arithmetic (or a deployment's precision word): float32,
float64 (Lava's floating point), and fixed point, whose host port carries 24-bit integers
(``LavaPyType(np.int32, precision=24)`` in :mod:`snnkart.backends.lava_procs.bridge`)."""


def word_bits(precision: str) -> int:
    """Bits of one input-current value in ``precision`` (an arithmetic or a precision word)."""
    if precision not in WORD_BITS:
        raise ValueError(f"unknown precision {precision!r}; one of {', '.join(WORD_BITS)}")
    return WORD_BITS[precision]


def link_bits(
    num_steps: int, n_first: int, n_last: int, precision: str, payload_bits: int = 0
) -> tuple[int, int]:
    """``(host_to_chip, chip_to_host)`` bits per env step: ``T x n1`` currents of
    :func:`word_bits` in, ``T x n_last`` spike flags (or graded payloads) out."""
    return (
        num_steps * n_first * word_bits(precision),
        num_steps * n_last * max(1, payload_bits),
    )


def sigma_delta_link_bits(
    input_messages: int, n_out: int, num_message_bits: int
) -> tuple[int, int]:
    """``(host_to_chip, chip_to_host)`` bits of one env step of a sigma-delta policy, the
    extension of :func:`link_bits` to graded, sparse messages: the host's input Delta sends only
    its messages (``input_messages`` x ``num_message_bits``, payload only, no address bits),
    and the host reads the ``n_out`` readout values once, after the last Lava step, one
    ``num_message_bits`` word each."""
    return input_messages * num_message_bits, n_out * num_message_bits
