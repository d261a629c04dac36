"""steer: a car with throttle/brake and steering at once (kinematic bicycle model)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from snnkart.envs.base import KartEnv
from snnkart.envs.config import SteerConfig
from snnkart.envs.constants import DT, KART_RADIUS_PX, PIXELS_PER_METRE
from snnkart.envs.observation import ObsField

_THROTTLE = (-1.0, 0.0, 1.0)  # brake, coast, throttle
_STEER = (-1.0, 0.0, 1.0)  # left, straight, right


class SteerEnv(KartEnv[SteerConfig]):
    """A car: throttle or brake and steering in the same step; it cannot turn in place.

    ## Description
    The hardest and most realistic snnkart task. Kinematic bicycle model: the yaw rate is
    ``v * tan(delta) / wheelbase``, so the turn rate grows with speed and is zero at rest.
    The steering angle ``delta`` moves toward the commanded angle at ``steer_rate_deg_s``.
    Braking slows the car; braking at a standstill reverses it (up to ``max_reverse_m_s``).

    ## Action Space
    ``action_mode="discrete"`` (default): ``Discrete(9)``, action = 3 * throttle + steer with
    throttle in {0 brake, 1 coast, 2 throttle} and steer in {0 left, 1 straight, 2 right};
    4 is "coast straight". ``"continuous"``: ``Box(-1, 1, (2,))`` = (throttle, steer):
    throttle > 0 accelerates, < 0 brakes and then reverses; steer is the commanded angle in units of the lock
    (positive = right, clockwise on screen).

    ## Observation Space
    ``Box`` of float32, size ``n_rays + 7``:

    | index | name | range | meaning |
    |---|---|---|---|
    | 0 .. n-1 | lidar | [0, 1] | egocentric rays, ray k at heading - 180 deg + k*fov/n, distance / range, 1 = no hit |
    | n | speed | [-1, 1] | forward speed / max speed (negative when reversing) |
    | n+1 | steering | [-1, 1] | steering angle / steering lock (positive = right) |
    | n+2 | heading_cos | [-1, 1] | cos of the heading (world frame, y down) |
    | n+3 | heading_sin | [-1, 1] | sin of the heading |
    | n+4 | checkpoint_cos | [-1, 1] | cos of the direction in which the shortest drivable path to the next checkpoint line leaves (around corners, one turning radius from the walls), relative to the heading |
    | n+5 | checkpoint_sin | [-1, 1] | sin of that direction (positive = to the right) |
    | n+6 | checkpoint_distance | [0, 1] | min(path length to the line / checkpoint_distance_scale_m, 1) (geodesic; `snnkart/envs/geodesic.py`) |

    ## Rewards
    As :class:`~snnkart.envs.grid.GridEnv`, plus ``steering``: ``-reward.steering * |delta| /
    lock`` per step.

    ## Starting State
    The track's spawn point and heading, +-``spawn.jitter`` px per axis, at rest, wheels straight.

    ## Episode End
    ``terminated``: finish, wall contact, or standing still (within
    ``stand_still_radius_m`` of one spot for ``stand_still_steps`` steps). ``truncated``: time limit.

    ## Arguments
    ``track``, ``action_mode``, ``config`` (:class:`SteerConfig` or a dict), ``render_mode``.

    ## Version History
    * v0: initial version (2.5 m/s, 2.4 m/s^2 throttle, 0.25 m wheelbase, 35 deg lock).
    """

    config_class = SteerConfig
    env_name = "steer"
    discrete_actions = 9
    egocentric = True
    ACTION_NAMES: ClassVar[tuple[str, ...]] = tuple(
        f"{t}+{s}" for t in ("brake", "coast", "throttle") for s in ("left", "straight", "right")
    )
    IDLE_ACTION: ClassVar[int] = 4  # coast+straight

    def _kinematic_fields(self) -> tuple[ObsField, ...]:
        return (
            ObsField("speed", 1, -1.0, 1.0, "forward speed / max speed (negative in reverse)"),
            ObsField("steering", 1, -1.0, 1.0, "steering angle / steering lock"),
            ObsField("heading_cos", 1, -1.0, 1.0, "cos of the heading"),
            ObsField("heading_sin", 1, -1.0, 1.0, "sin of the heading"),
        )

    def _reset_vehicle(self) -> None:
        p = self.config.physics
        self._v = 0.0  # px/s
        self._delta = 0.0  # rad
        self._vmax = p.max_speed_m_s * PIXELS_PER_METRE
        self._vrev = min(p.max_reverse_m_s, p.max_speed_m_s) * PIXELS_PER_METRE
        self._accel = p.throttle_m_s2 * PIXELS_PER_METRE * DT
        self._brake = p.brake_m_s2 * PIXELS_PER_METRE * DT
        self._lock = p.max_steer_rad
        self._steer_step = math.radians(p.steer_rate_deg_s) * DT
        self._wheelbase = p.wheelbase_m * PIXELS_PER_METRE
        self._drag = p.drag_per_step

    def _apply_action(self, action: Any) -> None:
        if self.action_mode == "discrete":
            a = int(action)
            throttle, steer = _THROTTLE[a // 3], _STEER[a % 3]
        else:
            throttle, steer = (float(a) for a in np.clip(action, -1.0, 1.0))
        # Throttle drives forward (and brakes a reversing car); brake stops, then reverses.
        if throttle > 0.0:
            rate = self._brake if self._v < 0.0 else self._accel
            self._v = min(self._v + throttle * rate, self._vmax)
        elif throttle < 0.0:
            rate = self._brake if self._v > 0.0 else self._accel
            self._v = max(self._v + throttle * rate, -self._vrev)
        target = steer * self._lock
        self._delta += min(max(target - self._delta, -self._steer_step), self._steer_step)
        self._yaw_rate = self._v * math.tan(self._delta) / self._wheelbase
        h = self._heading
        self._body.velocity = (self._v * math.cos(h), self._v * math.sin(h))
        self._body.angular_velocity = self._yaw_rate

    def _after_physics(self) -> None:
        self._heading = self._body.angle  # integrated by pymunk from the angular velocity
        self._v /= self._drag

    def _write_kinematics(self, out: np.ndarray, start: int) -> int:
        out[start] = self._v / self._vmax
        out[start + 1] = self._delta / self._lock
        out[start + 2] = math.cos(self._heading)
        out[start + 3] = math.sin(self._heading)
        return start + 4

    def _default_route_clearance(self) -> float:
        """The turning radius at full lock (0.36 m by default), or the kart radius if larger:
        the route then bends no tighter than the car can turn."""
        p = self.config.physics
        turning = p.wheelbase_m / math.tan(p.max_steer_rad) * PIXELS_PER_METRE
        return max(KART_RADIUS_PX, turning)

    def _extra_reward_terms(self, terms: dict[str, float]) -> None:
        terms["steering"] = -self.config.reward.steering * abs(self._delta) / self._lock

    @property
    def speed_m_s(self) -> float:
        return abs(self._v) / PIXELS_PER_METRE
