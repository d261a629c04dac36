"""What every spiking backend shares: the arithmetic names, the window and count records, the
backend interface and the registry that opens a backend by name.

One name for one concept: the *arithmetic* a network is computed in is ``float32`` (torch's
order of operations), ``float64`` (what Lava's floating-point models compute) or ``fixed``
(Lava's bit-accurate models on the quantised network). The user-facing ``--precision`` of
``lava-sim`` (``float`` or ``fixed``) maps onto it in :func:`arithmetic_for`, the only place
that validates it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, cast

import numpy as np

from snnkart.errors import DeployError

if TYPE_CHECKING:
    from snnkart.backends.host import HostCodec
    from snnkart.backends.network import ChainNetwork
    from snnkart.backends.quantize import FixedPointNetwork
    from snnkart.contract.manifest import Manifest

Arithmetic = Literal["float32", "float64", "fixed"]
ARITHMETICS: tuple[Arithmetic, ...] = ("float32", "float64", "fixed")

PRECISIONS: dict[str, dict[str, Arithmetic]] = {
    "lava-sim": {"float": "float64", "fixed": "fixed"},
    "nir-ref": {"float32": "float32", "float64": "float64", "float": "float64", "fixed": "fixed"},
}
"""Per backend, the accepted ``--precision`` words and the arithmetic each means."""
BACKENDS = tuple(PRECISIONS)


def check_arithmetic(arithmetic: str) -> Arithmetic:
    if arithmetic not in ARITHMETICS:
        raise ValueError(f"unknown arithmetic {arithmetic!r}; choose one of {ARITHMETICS}")
    return cast(Arithmetic, arithmetic)


def arithmetic_for(backend: str, precision: str) -> Arithmetic:
    """The arithmetic ``--backend backend --precision precision`` asks for."""
    if backend not in PRECISIONS:
        raise DeployError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    words = PRECISIONS[backend]
    if precision not in words:
        raise DeployError(f"--precision for {backend} is {' or '.join(words)}, not {precision!r}")
    return words[precision]


@dataclass
class WindowResult:
    """One env step: the raster of every Lava step in the window (``[rows, sum(sizes)]``,
    rows = T for float32, T + L for the Lava arithmetics) and what it means."""

    raster: np.ndarray
    logical: np.ndarray  # [T, sum(sizes)] the policy's own steps, layer by layer
    last_counts: np.ndarray  # [n_last] spikes of the last layer over the logical steps
    spikes: np.ndarray  # per layer, logical steps
    neuron_updates: np.ndarray
    overhead_spikes: np.ndarray
    overhead_neuron_updates: np.ndarray


@dataclass
class SpikeCounts:
    """Per layer: spikes, synaptic operations (spikes x fan-out) and neuron updates of the
    policy's logical steps, and apart from them the pipeline's fill/drain overhead."""

    n_layers: int = 2
    spikes: np.ndarray = field(init=False)
    synops: np.ndarray = field(init=False)
    neuron_updates: np.ndarray = field(init=False)
    overhead_spikes: np.ndarray = field(init=False)
    overhead_synops: np.ndarray = field(init=False)
    overhead_neuron_updates: np.ndarray = field(init=False)
    env_steps: int = 0

    def __post_init__(self) -> None:
        for name in (
            "spikes", "synops", "neuron_updates",
            "overhead_spikes", "overhead_synops", "overhead_neuron_updates",
        ):  # fmt: skip
            setattr(self, name, np.zeros(self.n_layers, dtype=np.int64))

    def add(self, window: WindowResult, fan_out: tuple[int, ...]) -> None:
        fan = np.asarray(fan_out, dtype=np.int64)
        self.spikes += window.spikes
        self.synops += window.spikes * fan
        self.neuron_updates += window.neuron_updates
        self.overhead_spikes += window.overhead_spikes
        self.overhead_synops += window.overhead_spikes * fan
        self.overhead_neuron_updates += window.overhead_neuron_updates
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


def split_window(raster: np.ndarray, sizes: tuple[int, ...], T: int) -> WindowResult:
    """Separate a pipelined window (row i..i+T-1 are layer i's logical steps) into the policy's
    steps and the fill/drain overhead. A float32 window (T rows) has no overhead."""
    rows = raster.shape[0]
    pipelined = rows != T
    offsets = np.cumsum((0, *sizes))
    logical = np.zeros((T, offsets[-1]), dtype=bool)
    spikes, overhead = [], []
    for i in range(len(sizes)):
        cols = slice(offsets[i], offsets[i + 1])
        shift = i if pipelined else 0
        logical[:, cols] = raster[shift : shift + T, cols]
        valid = int(logical[:, cols].sum())
        spikes.append(valid)
        overhead.append(int(raster[:, cols].sum()) - valid)
    n_arr = np.asarray(sizes, dtype=np.int64)
    return WindowResult(
        raster=raster,
        logical=logical,
        last_counts=logical[:, offsets[-2] :].sum(axis=0),
        spikes=np.asarray(spikes, dtype=np.int64),
        neuron_updates=n_arr * T,
        overhead_spikes=np.asarray(overhead, dtype=np.int64),
        overhead_neuron_updates=n_arr * (rows - T),
    )


class SpikingBackend(Protocol):
    """A running network: ``step(obs)`` encodes the observation on the host, runs one window
    of T SNN steps and returns the window and the readout; ``predict`` the decoded action."""

    name: str
    arithmetic: Arithmetic
    chain: ChainNetwork
    manifest: Manifest
    codec: HostCodec
    counts: SpikeCounts
    fixed: FixedPointNetwork | None

    def reset(self) -> None: ...
    def step(self, obs: np.ndarray) -> tuple[WindowResult, np.ndarray]: ...
    def predict(self, obs: np.ndarray) -> Any: ...
    def close(self) -> None: ...
    def __enter__(self) -> SpikingBackend: ...
    def __exit__(self, *exc: object) -> None: ...


def open_backend(nir_path: Path, backend: str, precision: str, seed: int = 0) -> SpikingBackend:
    """The backend ``backend`` running ``nir_path`` in the arithmetic ``precision`` asks for."""
    arithmetic = arithmetic_for(backend, precision)
    if backend == "lava-sim":
        from snnkart.backends.lava_sim import LavaSimPredictor

        return LavaSimPredictor(nir_path, "float" if arithmetic == "float64" else "fixed", seed)
    from snnkart.backends.reference import NIRReference

    return NIRReference(nir_path, arithmetic, seed)
