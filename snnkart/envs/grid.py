"""grid: free 4-direction movement (the original's ``directional_env``, "LatEnv")."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from snnkart.envs.base import KartEnv
from snnkart.envs.config import GridConfig
from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.envs.observation import ObsField

# World directions of the discrete actions (x right, y down).
DIRECTIONS = ((0.0, 0.0), (0.0, -1.0), (0.0, 1.0), (-1.0, 0.0), (1.0, 0.0))
"""The discrete actions' unit impulses (x, y): none, up (-y), down (+y), left, right."""


class GridEnv(KartEnv[GridConfig]):
    """A kart that accelerates freely in the four world directions and never rotates.

    ## Description
    The easiest of the three snnkart racing tasks. Each action adds a velocity impulse in a
    world direction; the speed is capped and decays by the drag factor every step. Walls end
    the episode on contact; checkpoints must be passed in order, the last one is the finish.

    ## Action Space
    ``action_mode="discrete"`` (default): ``Discrete(5)``: 0 none, 1 up (-y), 2 down (+y),
    3 left (-x), 4 right (+x). ``"continuous"``: ``Box(-1, 1, (2,))`` = (x, y) impulse, scaled
    by ``physics.impulse_m_s`` and limited to unit length.

    ## Observation Space
    ``Box`` of float32, size ``n_rays + 5``:

    | index | name | range | meaning |
    |---|---|---|---|
    | 0 .. n-1 | lidar | [0, 1] | world-fixed rays, ray k at -180 deg + k*fov/n (0 deg = +x), distance / range, 1 = no hit |
    | n | velocity_x | [-1, 1] | x velocity / max speed |
    | n+1 | velocity_y | [-1, 1] | y velocity / max speed (y down) |
    | n+2 | checkpoint_cos | [-1, 1] | cos of the world direction in which the shortest drivable path to the next checkpoint line leaves (around corners; straight at the nearest point of the line when touching it) |
    | n+3 | checkpoint_sin | [-1, 1] | sin of that direction |
    | n+4 | checkpoint_distance | [0, 1] | min(path length to the line / checkpoint_distance_scale_m, 1) (geodesic; `snnkart/envs/geodesic.py`) |

    ## Rewards
    Per step, the sum of the terms in :class:`~snnkart.envs.config.RewardConfig` (each one
    reported in ``info["reward_terms"]``): progress toward the next checkpoint line (per metre of the shortest drivable path to it,
    ``snnkart/envs/geodesic.py``),
    checkpoint bonus, finish bonus, passive time penalty, wall penalty, stand-still penalty.

    ## Starting State
    The track's spawn point plus a uniform offset of +-``spawn.jitter`` px per axis, at rest.

    ## Episode End
    ``terminated``: finish line crossed, wall touched, or standing still (staying within
    ``stand_still_radius_m`` of one spot) for ``stand_still_steps`` steps. ``truncated``: the time limit (``max_episode_steps``,
    default the track's ``time_limit_s``).

    ## Arguments
    ``track`` (built-in name or path), ``action_mode``, ``config`` (:class:`GridConfig` or a
    dict), ``render_mode`` (``"human"``, ``"rgb_array"`` or None).

    ## Version History
    * v0: initial version (original physics scale: 0.15 m/s impulses, 4 m/s cap).
    """

    config_class = GridConfig
    env_name = "grid"
    discrete_actions = 5
    egocentric = False
    ACTION_NAMES: ClassVar[tuple[str, ...]] = ("none", "up", "down", "left", "right")

    def _kinematic_fields(self) -> tuple[ObsField, ...]:
        return (
            ObsField("velocity_x", 1, -1.0, 1.0, "x velocity / max speed"),
            ObsField("velocity_y", 1, -1.0, 1.0, "y velocity / max speed"),
        )

    def _reset_vehicle(self) -> None:
        p = self.config.physics
        self._vx = self._vy = 0.0
        self._moved_vx = self._moved_vy = 0.0
        self._impulse = p.impulse_m_s * PIXELS_PER_METRE
        self._vmax = p.max_speed_m_s * PIXELS_PER_METRE
        self._drag = p.drag_per_step

    @property
    def velocity_px(self) -> tuple[float, float]:
        """The velocity (px per step) the next action adds its impulse to."""
        return self._vx, self._vy

    @property
    def impulse_px(self) -> float:
        """The velocity change (px per step) of a full action."""
        return self._impulse

    def _apply_action(self, action: Any) -> None:
        if self.action_mode == "discrete":
            ux, uy = DIRECTIONS[int(action)]
        else:
            ux, uy = (float(a) for a in np.clip(action, -1.0, 1.0))
            norm = math.hypot(ux, uy)
            if norm > 1.0:
                ux, uy = ux / norm, uy / norm
        vx = self._vx + self._impulse * ux
        vy = self._vy + self._impulse * uy
        speed = math.hypot(vx, vy)
        if speed > self._vmax:
            vx, vy = vx * self._vmax / speed, vy * self._vmax / speed
        self._vx, self._vy = vx, vy
        self._body.velocity = (vx, vy)

    def _after_physics(self) -> None:
        self._moved_vx, self._moved_vy = self._vx, self._vy
        self._vx /= self._drag
        self._vy /= self._drag

    def _write_kinematics(self, out: np.ndarray, start: int) -> int:
        # The velocity the kart moved with in the last step (before drag), as the original.
        out[start] = self._moved_vx / self._vmax
        out[start + 1] = self._moved_vy / self._vmax
        return start + 2

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self._vx, self._vy) / PIXELS_PER_METRE
