"""What every spiking backend shares: the arithmetic names and the window and count records.

One name for one concept: the *arithmetic* a network is computed in is ``float32`` (torch's
order of operations), ``float64`` (what Lava's floating-point models compute) or ``fixed``
(Lava's bit-accurate models on the quantised network). The user-facing ``--precision`` of each
backend maps onto it in :func:`snnkart.backends.registry.arithmetic_for`, the only place that
validates it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np

Arithmetic = Literal["float32", "float64", "fixed"]
ARITHMETICS: tuple[Arithmetic, ...] = ("float32", "float64", "fixed")


def check_arithmetic(arithmetic: str) -> Arithmetic:
    if arithmetic not in ARITHMETICS:
        raise ValueError(f"unknown arithmetic {arithmetic!r}; choose one of {ARITHMETICS}")
    return cast(Arithmetic, arithmetic)


@dataclass
class WindowResult:
    """One env step: the raster of every engine step in the window (``[rows, sum(sizes)]``,
    rows = steps + the engine's pipeline depth: T for float32, T + L for the Lava
    arithmetics) and what it means. A raster is boolean (binary spikes) or integer (graded
    spikes: a message's value; zero is no message)."""

    raster: np.ndarray
    logical: np.ndarray  # [steps, sum(sizes)] the policy's own steps, layer by layer
    last_counts: np.ndarray  # [n_last] the last layer's output summed over the logical steps
    spikes: np.ndarray  # per layer: messages (spikes) in the logical steps
    neuron_updates: np.ndarray
    overhead_spikes: np.ndarray
    overhead_neuron_updates: np.ndarray
    payload_bits: np.ndarray  # per layer: bits the logical steps' messages carry (0: binary)
    host_to_chip_bits: int = 0
    chip_to_host_bits: int = 0


COUNTED = (
    "spikes",
    "synops",
    "neuron_updates",
    "overhead_spikes",
    "overhead_synops",
    "overhead_neuron_updates",
    "payload_bits",
)


@dataclass
class SpikeCounts:
    """Per layer: spikes, synaptic operations (spikes x fan-out) and neuron updates of the
    policy's logical steps, and apart from them the pipeline's fill/drain overhead.

    Also kept, in memory only (not in :meth:`as_dict`, so ``deploy.json`` is unchanged): the
    message payload bits per layer (0: no engine of today has graded spikes) and the
    host<->chip I/O bits the backend sent and received (:mod:`snnkart.contract.link`)."""

    n_layers: int = 2
    spikes: np.ndarray = field(init=False)
    synops: np.ndarray = field(init=False)
    neuron_updates: np.ndarray = field(init=False)
    overhead_spikes: np.ndarray = field(init=False)
    overhead_synops: np.ndarray = field(init=False)
    overhead_neuron_updates: np.ndarray = field(init=False)
    payload_bits: np.ndarray = field(init=False)
    env_steps: int = 0
    host_to_chip_bits: int = 0
    chip_to_host_bits: int = 0

    def __post_init__(self) -> None:
        for name in COUNTED:
            setattr(self, name, np.zeros(self.n_layers, dtype=np.int64))

    def add(self, window: WindowResult, fan_out: tuple[int, ...]) -> None:
        fan = np.asarray(fan_out, dtype=np.int64)
        self.spikes += window.spikes
        self.synops += window.spikes * fan
        self.neuron_updates += window.neuron_updates
        self.overhead_spikes += window.overhead_spikes
        self.overhead_synops += window.overhead_spikes * fan
        self.overhead_neuron_updates += window.overhead_neuron_updates
        self.payload_bits += window.payload_bits
        self.host_to_chip_bits += window.host_to_chip_bits
        self.chip_to_host_bits += window.chip_to_host_bits
        self.env_steps += 1

    def as_dict(self) -> dict[str, Any]:
        return {
            "env_steps": self.env_steps,
            "spikes": self.spikes.tolist(),
            "synops": self.synops.tolist(),
            "neuron_updates": self.neuron_updates.tolist(),
            "pipeline_overhead": {
                "spikes": self.overhead_spikes.tolist(),
                "synops": self.overhead_synops.tolist(),
                "neuron_updates": self.overhead_neuron_updates.tolist(),
            },
        }


def split_window(
    raster: np.ndarray,
    sizes: tuple[int, ...],
    steps: int,
    depth: int | None = None,
    payload_bits: int = 0,
) -> WindowResult:
    """Separate a window of ``steps`` logical steps through a pipeline ``depth`` deep (layer i's
    logical steps are rows i..i+steps-1; default depth: the rows beyond ``steps``) into the
    policy's steps and the fill/drain overhead. A window without a pipeline (float32: depth 0)
    has no overhead. ``payload_bits``: the bits one message carries (0 for a binary spike)."""
    rows = raster.shape[0]
    depth = rows - steps if depth is None else depth
    if rows != steps + depth or depth not in (0, len(sizes) - 1):
        raise ValueError(
            f"a window of {steps} steps through {len(sizes)} layers has {steps} rows (no "
            f"pipeline) or {steps + len(sizes) - 1}, not {rows} (depth {depth})"
        )
    offsets = np.cumsum((0, *sizes))
    logical = np.zeros((steps, offsets[-1]), dtype=raster.dtype)
    spikes, overhead = [], []
    for i in range(len(sizes)):
        cols = slice(offsets[i], offsets[i + 1])
        shift = i if depth else 0
        logical[:, cols] = raster[shift : shift + steps, cols]
        valid = int(np.count_nonzero(logical[:, cols]))
        spikes.append(valid)
        overhead.append(int(np.count_nonzero(raster[:, cols])) - valid)
    n_arr = np.asarray(sizes, dtype=np.int64)
    messages = np.asarray(spikes, dtype=np.int64)
    return WindowResult(
        raster=raster,
        logical=logical,
        last_counts=logical[:, offsets[-2] :].sum(axis=0),
        spikes=messages,
        neuron_updates=n_arr * steps,
        overhead_spikes=np.asarray(overhead, dtype=np.int64),
        overhead_neuron_updates=n_arr * depth,
        payload_bits=messages * payload_bits,
    )
