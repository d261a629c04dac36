"""What a sigma-delta chain does per env step, counted from its raster (every sending layer's
sent values at each of the ``rows`` Lava steps, and the readout Sigma's value), the same way
for every engine.

Sending layers, in order: the input Delta, each SigmaDelta, the readout Sigma. Per layer and
env step:

- ``messages``: non-zero values sent (a graded message each). The input Delta is the host's
  encoder: its messages cross the host->chip link. The readout Sigma's "messages" are the
  non-zero readout values the host reads after the last row (chip->host);
- ``payload_bits``: messages x ``num_message_bits``;
- ``synaptic_events``: messages x fan-out of the Dense they enter (0 for the readout: it feeds
  the host, not a Dense);
- ``updates_clocked``: layer size x rows, every neuron at every Lava step, as a clocked chip
  updates them (the input Delta's are host work);
- ``updates_active``: neuron-rows in which the neuron received a non-zero input or sent a
  message. The input received by a SigmaDelta or the Sigma at row ``r`` is what its Dense
  delivers, ``W @ s[r - 1]`` with ``s`` the previous layer's sent values (``s[-1]``: the last
  row of the previous env step; the weights as the chain uses them), non-zero in at least one
  synapse sum; the input Delta "receives" a non-zero input when its observation value differs
  from the one it held the row before. A neuron with neither is idle: on a chip where an idle
  neuron costs nothing, only these are paid.

Link bits per env step (an extension of :mod:`snnkart.contract.link` for graded, sparse
messages; :func:`snnkart.contract.link.sigma_delta_link_bits`): host->chip, the input Delta's
messages x ``num_message_bits`` (payload only: no address bits, as ``payload_bits``);
chip->host, every readout value once per env step x ``num_message_bits``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.contract.link import sigma_delta_link_bits

COUNTED = ("messages", "payload_bits", "synaptic_events", "updates_clocked", "updates_active")


@dataclass
class SigmaDeltaStep:
    """One env step's counts per sending layer (module docstring) and its link bits."""

    messages: np.ndarray
    payload_bits: np.ndarray
    synaptic_events: np.ndarray
    updates_clocked: np.ndarray
    updates_active: np.ndarray
    host_to_chip_bits: int
    chip_to_host_bits: int


class SigmaDeltaCounter:
    """Counts env steps of one chain (``weights``: its Dense matrices as it uses them, the
    readout's last); remembers the last row's sent values and input across env steps, as the
    chain's state persists."""

    def __init__(self, weights: list[np.ndarray], rows: int, num_message_bits: int) -> None:
        self.weights = weights
        self.sizes = (int(weights[0].shape[1]), *(int(w.shape[0]) for w in weights))
        self.offsets = np.cumsum((0, *self.sizes))
        self.rows = rows
        self.bits = num_message_bits
        self.fan_out = np.array([*(w.shape[0] for w in weights), 0], np.int64)
        self.last_sent = [np.zeros(n) for n in self.sizes[:-1]]
        self.last_x = np.zeros(self.sizes[0])

    def count(self, raster: np.ndarray, x: np.ndarray) -> SigmaDeltaStep:
        """The counts of one env step's ``raster`` ``[rows, sum(sizes)]`` on input ``x``."""
        cols = [raster[:, self.offsets[k] : self.offsets[k + 1]] for k in range(len(self.sizes))]
        sent, readout = cols[:-1], cols[-1]
        messages = [np.count_nonzero(s) for s in sent] + [np.count_nonzero(readout[-1])]
        active = [self._delta_active(sent[0], x)]
        for k, w in enumerate(self.weights):
            before = np.vstack([self.last_sent[k][None], sent[k][:-1]])
            received = (before @ np.asarray(w).T) != 0
            own = sent[k + 1] != 0 if k + 1 < len(sent) else np.zeros_like(received)
            active.append(int(np.count_nonzero(received | own)))
        self.last_sent = [s[-1].copy() for s in sent]
        self.last_x = np.asarray(x).copy()
        msgs = np.array(messages, np.int64)
        host_in, host_out = sigma_delta_link_bits(int(msgs[0]), self.sizes[-1], self.bits)
        return SigmaDeltaStep(
            messages=msgs,
            payload_bits=msgs * self.bits,
            synaptic_events=msgs * self.fan_out,
            updates_clocked=np.array(self.sizes, np.int64) * self.rows,
            updates_active=np.array(active, np.int64),
            host_to_chip_bits=host_in,
            chip_to_host_bits=host_out,
        )

    def _delta_active(self, sent: np.ndarray, x: np.ndarray) -> int:
        """Input Delta neuron-rows whose value changed (row 0 against the last env step's
        input; later rows hold it) or that sent."""
        changed = np.zeros_like(sent, dtype=bool)
        changed[0] = np.asarray(x) != self.last_x
        return int(np.count_nonzero(changed | (sent != 0)))


class SigmaDeltaTotals:
    """Running sums of :class:`SigmaDeltaStep` over a deployment."""

    def __init__(self, layers: tuple[str, ...], rows: int, num_message_bits: int) -> None:
        self.layers, self.rows, self.bits = layers, rows, num_message_bits
        self.env_steps = 0
        self.sums = {name: np.zeros(len(layers), np.int64) for name in COUNTED}
        self.host_to_chip_bits = self.chip_to_host_bits = 0

    def add(self, step: SigmaDeltaStep) -> None:
        for name in COUNTED:
            self.sums[name] += getattr(step, name)
        self.host_to_chip_bits += step.host_to_chip_bits
        self.chip_to_host_bits += step.chip_to_host_bits
        self.env_steps += 1

    def as_dict(self) -> dict[str, Any]:
        """The deploy record's ``counts`` (:class:`snnkart.contract.deploy_record.Counts`):
        ``spikes``/``synops``/``neuron_updates`` are the messages, synaptic events and clocked
        updates of every sending layer, and ``sigma_delta`` holds every count by its name."""
        s = {name: v.tolist() for name, v in self.sums.items()}
        return {
            "env_steps": self.env_steps,
            "spikes": s["messages"],
            "synops": s["synaptic_events"],
            "neuron_updates": s["updates_clocked"],
            "pipeline_overhead": None,
            "sigma_delta": {
                "layers": list(self.layers),
                "rows_per_env_step": self.rows,
                "num_message_bits": self.bits,
                **s,
                "host_to_chip_bits": self.host_to_chip_bits,
                "chip_to_host_bits": self.chip_to_host_bits,
            },
        }
