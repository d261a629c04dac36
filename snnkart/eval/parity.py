"""Checking a backend step by step: on every observation its same-arithmetic reference must
give the same raster (bit for bit), and the float32 reference measures what the backend's
arithmetic changes (identical actions, spike flips)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from snnkart import faults
from snnkart.backends.base import Arithmetic
from snnkart.backends.loading import Opened
from snnkart.backends.registry import make_backend
from snnkart.contract.deploy_record import DeployRecord
from snnkart.errors import ParityError

if TYPE_CHECKING:
    from snnkart.backends.backend import RunningPolicy as AnyBackend


@dataclass
class Parity:
    """Running agreement of a backend with its references over the same observations."""

    env_steps: int = 0
    exact_reference: str | None = None
    exact_mismatched_windows: int = 0
    exact_mismatched_actions: int = 0
    float32_action_agreement: int = 0
    float32_spike_flips: int = 0
    neuron_steps: int = 0
    float32_count_differences: list[int] = field(default_factory=list)
    float32_form: bool = True
    """The policy has a float32 reference (a sigma-delta policy has none: its float32 fields
    are then left out of the record, not 0)."""
    first_mismatch: dict[str, int] | None = None
    """Where the backend first differed from its same-arithmetic reference: the env step
    (counted over the whole deploy, from 0), the episode, the step within it, the layer and
    the row of the window."""

    def as_dict(self) -> dict[str, Any]:
        n = max(self.env_steps, 1)
        f32 = self.float32_form
        return {
            "env_steps": self.env_steps,
            "same_arithmetic_reference": self.exact_reference,
            "same_arithmetic_mismatched_windows": self.exact_mismatched_windows,
            "same_arithmetic_mismatched_actions": self.exact_mismatched_actions,
            "float32_identical_action_fraction": (
                self.float32_action_agreement / n if f32 else None
            ),
            "float32_spike_flips": self.float32_spike_flips if f32 else None,
            "float32_spike_flips_per_million_neuron_steps": (
                1e6 * self.float32_spike_flips / max(self.neuron_steps, 1) if f32 else None
            ),
            "first_same_arithmetic_mismatch": self.first_mismatch,
        }


def _same_action(a: Any, b: Any) -> bool:
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


class CheckedPredictor:
    """Runs ``primary`` and, on the same observation, its references; returns primary's action."""

    def __init__(
        self,
        primary: AnyBackend,
        exact: AnyBackend | None,
        float32: AnyBackend | None,
    ) -> None:
        self.primary = primary
        self.exact = exact
        self.float32 = float32
        self.parity = Parity(
            exact_reference=None if exact is None else exact.arithmetic,
            float32_form=primary.float32_form,
        )
        self.step_seconds = 0.0
        self.episode, self.episode_step = -1, 0  # where the first parity mismatch happened

    def reset(self) -> None:
        """An episode's start, for the backend and its references alike (a stateful policy's
        state is zeroed in each)."""
        for backend in (self.primary, self.exact, self.float32):
            if backend is not None:
                backend.reset()
        self.episode += 1
        self.episode_step = 0

    def predict(self, obs: np.ndarray) -> Any:
        faults.fault_point("step")
        t0 = time.perf_counter()
        window, out = self.primary.step(obs)
        self.step_seconds += time.perf_counter() - t0
        action = self.primary.codec.decode(out)
        p = self.parity
        p.env_steps += 1
        if self.exact is not None:
            ref_window, ref_out = self.exact.step(obs)
            differs = not np.array_equal(window.raster, ref_window.raster)
            p.exact_mismatched_windows += differs
            p.exact_mismatched_actions += not _same_action(action, self.exact.codec.decode(ref_out))
            if differs and p.first_mismatch is None:
                p.first_mismatch = _where(window.raster, ref_window.raster, self.exact.raster_sizes)
                p.first_mismatch.update(
                    env_step=p.env_steps - 1, episode=self.episode, episode_step=self.episode_step
                )
        self.episode_step += 1
        if self.float32 is not None:
            f_window, f_out = self.float32.step(obs)
            p.float32_action_agreement += _same_action(action, self.float32.codec.decode(f_out))
            p.float32_spike_flips += _flips(window, f_window)
            p.neuron_steps += f_window.logical.size
        return action


def _where(raster: np.ndarray, reference: np.ndarray, sizes: tuple[int, ...]) -> dict[str, int]:
    """The first layer (and window row) in which two rasters differ."""
    if raster.shape != reference.shape:
        return {"layer": -1, "row": -1}
    offsets = np.cumsum((0, *sizes))
    for layer in range(len(sizes)):
        cols = slice(int(offsets[layer]), int(offsets[layer + 1]))
        rows = np.flatnonzero((raster[:, cols] != reference[:, cols]).any(axis=1))
        if rows.size:
            return {"layer": layer, "row": int(rows[0])}
    return {"layer": -1, "row": -1}


def _flips(a: Any, b: Any) -> int:
    return int(np.count_nonzero(a.logical != b.logical))


def open_backends(
    policy: Opened, backend: str, arithmetic: Arithmetic, seed: int
) -> tuple[AnyBackend, AnyBackend | None, AnyBackend | None]:
    """The backend, its same-arithmetic reference (None for the reference itself) and the
    float32 reference (None when the backend is the float32 reference), all on ``policy``."""
    primary = make_backend(policy, backend, arithmetic, seed)
    try:
        exact_arithmetic, float32_arithmetic = primary.parity_references()
        exact = float32 = None
        if exact_arithmetic is not None:
            exact = make_backend(policy, "nir-ref", exact_arithmetic, seed)
        if float32_arithmetic is not None:
            float32 = make_backend(policy, "nir-ref", float32_arithmetic, seed)
    except BaseException:
        primary.close()
        raise
    return primary, exact, float32


def check_parity(record: DeployRecord) -> None:
    """Raise :class:`ParityError` if any env step differed from the same-arithmetic reference:
    "every env step checked" is a guard, not only a measurement."""
    p = record.parity
    bad = p.same_arithmetic_mismatched_windows
    if not bad:
        return
    first = p.first_same_arithmetic_mismatch or {}
    layer = first.get("layer", -1)
    raise ParityError(
        f"parity failure: {record.backend} ({record.precision}) differs from the numpy "
        f"reference ({p.same_arithmetic_reference}) in {bad} of {p.env_steps} env steps; "
        f"the first is env step {first.get('env_step')} (episode {first.get('episode')}, step "
        f"{first.get('episode_step')}), "
        + (f"layer {layer}, window row {first.get('row')}" if layer >= 0 else "window shape")
        + "; this is a bug in the backend or the reference (please report it with the NIR file)",
        record,
    )
