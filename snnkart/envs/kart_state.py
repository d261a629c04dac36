"""The read-only state of a kart env that renderers, drivers and the HUD read (a mixin of
:class:`snnkart.envs.base.KartEnv`, which sets the underscored attributes)."""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.envs.constants import DT
from snnkart.envs.lidar import ray_ends


class KartState:
    """Kart position, heading, lap state, LIDAR and last step, for renderers and drivers."""

    _x: float
    _y: float
    _heading: float
    _next_cp: int
    _finished: bool
    _from_spawn: bool
    _steps: int
    _lidar: np.ndarray
    _ray_angles: np.ndarray
    _ray_range: float
    _last_action: Any
    _last_terms: dict[str, float]
    _episode_return: float

    @property
    def position(self) -> tuple[float, float]:
        """Kart centre, px."""
        return (self._x, self._y)

    @property
    def heading(self) -> float:
        """Heading (rad, clockwise on screen from +x); 0 in the grid env."""
        return self._heading

    @property
    def next_checkpoint(self) -> int:
        """Index of the checkpoint to pass next (0-based)."""
        return self._next_cp

    @property
    def lap_finished(self) -> bool:
        return self._finished and self._from_spawn

    @property
    def elapsed_time(self) -> float:
        """Simulated seconds since the episode began."""
        return self._steps * DT

    @property
    def episode_steps(self) -> int:
        return self._steps

    @property
    def lidar_distances(self) -> np.ndarray:
        """Normalised ray distances of the last observation, in [0, 1] (1 = no hit)."""
        return self._lidar

    @property
    def last_action(self) -> Any:
        return self._last_action

    @property
    def last_reward_terms(self) -> dict[str, float]:
        return self._last_terms

    @property
    def episode_return(self) -> float:
        return self._episode_return

    @property
    def lidar_hits(self) -> np.ndarray:
        """Ray end points of the last observation, px, shape ``[n_rays, 2]``."""
        return ray_ends(self._x, self._y, self._ray_angles, self._lidar * self._ray_range)
