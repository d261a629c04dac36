"""The prices of graded messages (a sigma-delta chain's), derived from a chip's binary ones.

**No profile publishes the energy of a graded message or a graded synaptic event.** Both are
derived from the chip's own price of a (binary) spike and synaptic op, for a payload of ``b``
bits, as ``k x price`` with ``k`` from 1 (the payload rides in the message at no extra cost)
up to the number of the chip's native units the payload takes: ``ceil(b / 8)`` 8-bit words on
a chip with graded messages (Loihi 2, whose per-op prices derive from totals over 8-bit
operations), ``b`` one-bit spikes (and ``b`` accumulates, bit-serially) on a chip that carries
binary spikes only (every other profile: an emulation). The central value is ``k = 1``. These
derived prices are added to the chip profile under their own names (``graded_message_<b>b``,
``graded_synop_<b>b``, ``graded_hop_<b>b``), so the joint uncertainty samples their ranges.
"""

from __future__ import annotations

import math
from dataclasses import replace

from snnkart.energy.profiles import Price, Profile

WORD_BITS = 8
"""The payload unit of a chip with graded messages: Loihi 2's per-op prices derive from
Hala Point's totals over 8-bit operations (>15 TOPS/W, 8-bit; snn-nir-lava.md §3.2)."""
GRADED = {"message": "spike", "synop": "synaptic_op", "hop": "hop"}
"""Each graded price and the chip's binary price it is derived from."""


def payload_units(chip: Profile, bits: int) -> int:
    """How many of ``chip``'s native units a payload of ``bits`` takes at the most: 8-bit
    words on a chip with graded messages, single bits on a binary one."""
    if chip.rule("messages").value == "graded":
        return max(1, math.ceil(bits / WORD_BITS))
    return max(1, bits)


def graded_op(kind: str, bits: int) -> str:
    """The name of the derived price of a graded ``kind`` (message, synop, hop) of ``bits``."""
    return f"graded_{kind}_{bits}b"


def graded_price(chip: Profile, kind: str, bits: int) -> Price:
    """The derived price of one graded ``kind`` with a ``bits`` payload (module docstring)."""
    base = chip.prices[GRADED[kind]]
    k = payload_units(chip, bits)
    rule = chip.rule("messages")
    unit = f"{WORD_BITS}-bit words" if rule.value == "graded" else "one-bit spikes"
    source = (
        f"no graded {kind} energy is published for {chip.name}; derived from its "
        f"{GRADED[kind]} ({base.value:g} pJ, {base.low:g}-{base.high:g}; {base.tag}) x k, "
        f"k = 1 (the payload free) to {k} (a {bits}-bit payload as {k} {unit}; "
        f"rules.messages = {rule.value}: {rule.source})"
    )
    return Price(base.value, base.low, base.high * k, "pJ", "derived", source)


def with_graded_prices(chip: Profile, message_bits: tuple[int, ...]) -> Profile:
    """``chip`` with the derived graded prices for payloads of ``message_bits``."""
    prices = dict(chip.prices)
    for bits in sorted({b for b in message_bits if b}):
        for kind in GRADED:
            if GRADED[kind] in chip.prices:
                prices[graded_op(kind, bits)] = graded_price(chip, kind, bits)
    return replace(chip, prices=prices)
