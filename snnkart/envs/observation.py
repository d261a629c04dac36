"""The observation vector's layout: named blocks with their true bounds.

Every env observes ``lidar`` (its rays), then its own kinematic blocks, then the way to the
next checkpoint along the track (cosine, sine, distance); the layout is recorded with every
checkpoint and NIR export (see :mod:`snnkart.envs.spec`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces


@dataclass(frozen=True)
class ObsField:
    """One named block of the observation vector, with its true bounds."""

    name: str
    size: int
    low: float
    high: float
    description: str


def observation_layout(n_rays: int, kinematics: Sequence[ObsField]) -> tuple[ObsField, ...]:
    return (
        ObsField("lidar", n_rays, 0.0, 1.0, "ray distance / range, 1 = no hit"),
        *kinematics,
        ObsField("checkpoint_cos", 1, -1.0, 1.0, "cos of the way to the next checkpoint"),
        ObsField("checkpoint_sin", 1, -1.0, 1.0, "sin of the way to the next checkpoint"),
        ObsField("checkpoint_distance", 1, 0.0, 1.0, "min(path distance / scale, 1)"),
    )


def observation_space(layout: Sequence[ObsField]) -> spaces.Box:
    """The float32 box of ``layout``'s bounds."""
    low = np.concatenate([np.full(f.size, f.low) for f in layout])
    high = np.concatenate([np.full(f.size, f.high) for f in layout])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32))
