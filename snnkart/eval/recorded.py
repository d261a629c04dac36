"""Recording a deployment's chip inputs: an engine wrapper that keeps every window's input
current and raster as the backend ran them, for ``inputs.npz``
(:mod:`snnkart.contract.deploy_inputs`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.backends.backend import Backend
from snnkart.contract.deploy_inputs import DeployInputs


class RecordingEngine:
    """``engine`` unchanged (every attribute is its own), with each window's current and raster
    kept, and each ``reset`` (an episode's start) noted."""

    def __init__(self, engine: Any) -> None:
        self._engine = engine
        self.currents: list[np.ndarray] = []
        self.rasters: list[np.ndarray] = []
        self.episode_starts: list[int] = []

    def window(self, current: np.ndarray) -> np.ndarray:
        raster = self._engine.window(current)
        self.currents.append(np.array(current))
        self.rasters.append(np.asarray(raster, dtype=bool))
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
    current = (
        _compact(np.stack(recorder.currents))
        if recorder.currents
        else np.zeros((0, engine.steps, sizes[0]))
    )
    raster = np.stack(recorder.rasters) if recorder.rasters else np.zeros(
        (0, engine.steps + engine.depth, sum(sizes)), dtype=bool
    )  # fmt: skip
    return DeployInputs(
        current=current, raster=raster,
        episode_starts=np.asarray(recorder.episode_starts, dtype=np.int64),
        sizes=tuple(sizes), num_steps=engine.steps, depth=engine.depth, first_seed=first_seed,
        arithmetic=backend.arithmetic, backend=backend.name,
    )  # fmt: skip


def _compact(current: np.ndarray) -> np.ndarray:
    """Integer currents (Lava fixed point: at most 18 bits) as int32; floats as they are."""
    if np.issubdtype(current.dtype, np.integer):
        return current.astype(np.int32)
    return current
