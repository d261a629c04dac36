"""Recording a deployment's chip inputs: an engine wrapper that keeps every window's input
current and raster as the backend ran them, for ``inputs.npz``
(:mod:`snnkart.contract.deploy_inputs`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.backends.backend import Backend
from snnkart.contract.deploy_inputs import DeployInputs


class RecordingEngine:
    """``engine`` unchanged (every attribute is its own), with each window's current (one row
    when it is held for the T steps) and raster (bits packed) kept, and each ``reset`` (an
    episode's start) noted: about 0.4 kB per env step for a 64-64 policy at T = 8."""

    def __init__(self, engine: Any) -> None:
        self._engine = engine
        self.currents: list[np.ndarray] = []
        self.rasters: list[np.ndarray] = []
        self.episode_starts: list[int] = []

    def window(self, current: np.ndarray) -> np.ndarray:
        raster = self._engine.window(current)
        held = current.shape[0] > 1 and bool((current == current[:1]).all())
        self.currents.append(_compact(current[:1] if held else current))
        self.rasters.append(np.packbits(np.asarray(raster, dtype=bool), axis=-1))
        return raster

    def reset(self) -> None:
        self.episode_starts.append(len(self.rasters))
        self._engine.reset()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._engine, name)


def record_inputs(backend: Backend) -> RecordingEngine:
    """Wrap ``backend``'s engine in a :class:`RecordingEngine` and return it."""
    recorder = RecordingEngine(backend.engine)
    backend.engine = recorder
    return recorder


def recorded_inputs(backend: Backend, recorder: RecordingEngine, first_seed: int) -> DeployInputs:
    """What ``recorder`` kept of ``backend``'s run, as the ``inputs.npz`` record."""
    engine, sizes = recorder._engine, backend.chain.sizes
    n, rows = sum(sizes), engine.steps + engine.depth
    currents = recorder.currents
    if any(len(c) != len(currents[0]) for c in currents):  # held in some steps only
        currents = [np.broadcast_to(c, (engine.steps, c.shape[1])) for c in currents]
    current = np.stack(currents) if currents else np.zeros((0, engine.steps, sizes[0]))
    raster = (
        np.unpackbits(np.stack(recorder.rasters), axis=-1, count=n).astype(bool)
        if recorder.rasters
        else np.zeros((0, rows, n), dtype=bool)
    )
    return DeployInputs(
        current=current,
        raster=raster,
        episode_starts=np.asarray(recorder.episode_starts, dtype=np.int64),
        sizes=tuple(sizes),
        num_steps=engine.steps,
        depth=engine.depth,
        first_seed=first_seed,
        arithmetic=backend.arithmetic,
        backend=backend.name,
    )


def _compact(current: np.ndarray) -> np.ndarray:
    """A copy; integer currents (Lava fixed point: at most 18 bits) as int32."""
    if np.issubdtype(current.dtype, np.integer):
        return current.astype(np.int32)
    return np.array(current)
