"""gazebo: a two-wheel differential-drive robot (the original's ``drive_env``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from snnkart.envs.base import KartEnv
from snnkart.envs.config import GazeboConfig
from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.envs.observation import ObsField


@dataclass
class DiffDrive:
    """Gazebo's action model: how an action moves the commanded linear speed ``v`` (px/s along
    the heading) and turn rate ``w`` (rad/s, clockwise on screen). The env applies it to its
    body; a ROS node (:mod:`snnkart.ros`) turns it into ``cmd_vel`` setpoints."""

    vmax: float
    wmax: float
    dv: float  # linear change per step, px/s
    decay: float  # of the turn rate per step
    drag: float  # the linear speed is divided by it after each step (discrete actions)
    discrete: bool
    v: float = 0.0
    w: float = 0.0

    @classmethod
    def of(cls, p: Any, discrete: bool) -> DiffDrive:
        """From a :class:`~snnkart.envs.config.GazeboPhysics`."""
        ppm = PIXELS_PER_METRE
        return cls(
            p.max_linear_m_s * ppm,
            p.max_angular_rad_s,
            p.linear_step_m_s * ppm,
            p.angular_decay,
            p.drag_per_step,
            discrete,
        )

    def command(self, action: Any) -> tuple[float, float]:
        """Apply ``action``; the velocity to drive at during this step."""
        w_cmd = 0.0
        if self.discrete:
            a = int(action)
            if a == 1:
                self.v = min(self.v + self.dv, self.vmax)
            elif a == 2:
                self.v = max(self.v - self.dv, 0.0)
            elif a == 3:
                w_cmd = -self.wmax
            elif a == 4:
                w_cmd = self.wmax
        else:
            lin, ang = (float(a) for a in np.clip(action, -1.0, 1.0))
            self.v += min(max(lin * self.vmax - self.v, -self.dv), self.dv)
            w_cmd = ang * self.wmax
        self.w = self.w * self.decay + (1.0 - self.decay) * w_cmd
        return self.v, self.w

    def coast(self) -> float:
        """After the step: discrete control's drag on the linear speed; the new speed."""
        if self.discrete:
            self.v /= self.drag
        return self.v


class GazeboEnv(KartEnv[GazeboConfig]):
    """A differential-drive robot, as the ROS/Gazebo TurtleBot3 setup: it can turn in place.

    ## Description
    The robot drives along its heading with no side slip. In discrete mode each step changes
    EITHER the linear OR the angular velocity, never both; the angular velocity decays quickly
    (x ``angular_decay`` per step) when no turn key is held, as in the original, so turning
    needs the key held. ``physics.preset="turtlebot3"`` uses the real robot's limits
    (0.22 m/s, 2.84 rad/s) and a 10x longer time limit.

    ## Action Space
    ``action_mode="discrete"`` (default): ``Discrete(5)``: 0 none, 1 accelerate, 2 brake
    (down to standstill, no reverse), 3 turn left, 4 turn right. ``"continuous"``:
    ``Box(-1, 1, (2,))`` = (linear, angular) velocity command as ROS ``cmd_vel``
    (``linear.x``, ``angular.z`` with positive = right, i.e. clockwise on screen) in units of
    the limits; the linear speed follows the command at most ``linear_step_m_s`` per step
    (reverse allowed) and the angular velocity follows it with the first-order lag.

    ## Observation Space
    ``Box`` of float32, size ``n_rays + 7``:

    | index | name | range | meaning |
    |---|---|---|---|
    | 0 .. n-1 | lidar | [0, 1] | egocentric rays, ray k at heading - 180 deg + k*fov/n, distance / range, 1 = no hit |
    | n | linear_velocity | [-1, 1] | forward speed / max linear speed |
    | n+1 | angular_velocity | [-1, 1] | yaw rate / max angular speed (positive = clockwise on screen) |
    | n+2 | heading_cos | [-1, 1] | cos of the heading (world frame, y down) |
    | n+3 | heading_sin | [-1, 1] | sin of the heading |
    | n+4 | checkpoint_cos | [-1, 1] | cos of the direction in which the shortest drivable path to the next checkpoint line leaves (around corners), relative to the heading |
    | n+5 | checkpoint_sin | [-1, 1] | sin of that direction (positive = to the right) |
    | n+6 | checkpoint_distance | [0, 1] | min(path length to the line / checkpoint_distance_scale_m, 1) (geodesic; `snnkart/envs/geodesic.py`) |

    ## Rewards
    As :class:`~snnkart.envs.grid.GridEnv`: progress, checkpoint, finish, time, wall and
    stand-still terms, each in ``info["reward_terms"]``.

    ## Starting State
    The track's spawn point and heading, +-``spawn.jitter`` px per axis, at rest.

    ## Episode End
    ``terminated``: finish, wall contact, or standing still (within
    ``stand_still_radius_m`` of one spot for ``stand_still_steps`` steps). ``truncated``: time limit.

    ## Arguments
    ``track``, ``action_mode``, ``config`` (:class:`GazeboConfig` or a dict), ``render_mode``.

    ## Version History
    * v0: initial version (original scale: 2 m/s, +0.03 m/s per accelerate step).
    """

    config_class = GazeboConfig
    env_name = "gazebo"
    discrete_actions = 5
    egocentric = True
    ACTION_NAMES: ClassVar[tuple[str, ...]] = ("none", "accelerate", "brake", "left", "right")
    _velocity_override: tuple[float, float] | None = None  # set_velocity's, for one step

    def _kinematic_fields(self) -> tuple[ObsField, ...]:
        return (
            ObsField("linear_velocity", 1, -1.0, 1.0, "forward speed / max linear speed"),
            ObsField("angular_velocity", 1, -1.0, 1.0, "yaw rate / max angular speed"),
            ObsField("heading_cos", 1, -1.0, 1.0, "cos of the heading"),
            ObsField("heading_sin", 1, -1.0, 1.0, "sin of the heading"),
        )

    def _time_limit_factor(self) -> float:
        return self.config.physics.time_limit_factor

    def _reset_vehicle(self) -> None:
        self._drive = DiffDrive.of(self.config.physics, self.action_mode == "discrete")
        self._v = 0.0  # px/s along the heading
        self._w = 0.0  # rad/s, clockwise on screen
        self._vmax, self._wmax = self._drive.vmax, self._drive.wmax

    def set_velocity(self, v_m_s: float, w_ccw: float) -> None:
        """Drive the next step at this velocity (a ``cmd_vel`` setpoint, m/s and rad/s
        counter-clockwise, clipped to the physics limits) instead of an action's: what the ROS
        simulator bridge applies."""
        v = min(max(v_m_s * PIXELS_PER_METRE, -self._drive.vmax), self._drive.vmax)
        w = min(max(-w_ccw, -self._drive.wmax), self._drive.wmax)
        self._velocity_override = (v, w)

    def _apply_action(self, action: Any) -> None:
        override = self._velocity_override
        if override is not None:  # a cmd_vel setpoint (set_velocity)
            self._velocity_override = None
            self._drive.v, self._drive.w = override
            self._v, self._w = override
        else:
            self._v, self._w = self._drive.command(action)
        h = self._heading
        self._body.velocity = (self._v * math.cos(h), self._v * math.sin(h))
        self._body.angular_velocity = self._w

    def _after_physics(self) -> None:
        self._heading = self._body.angle  # integrated by pymunk from the angular velocity
        self._moved_v = self._v
        self._v = self._drive.coast()

    def _write_kinematics(self, out: np.ndarray, start: int) -> int:
        out[start] = self._v / self._vmax
        out[start + 1] = self._w / self._wmax
        out[start + 2] = math.cos(self._heading)
        out[start + 3] = math.sin(self._heading)
        return start + 4

    def observe_measured(
        self,
        x: float,
        y: float,
        heading: float,
        v: float,
        w: float,
        next_cp: int,
        lidar: np.ndarray,
    ) -> np.ndarray:
        """The observation this env builds for a robot at ``(x, y)`` px, ``heading`` (rad,
        clockwise on screen), moving at ``v`` px/s and turning at ``w`` rad/s (clockwise), with
        ``next_cp`` to pass next and measured normalised ray distances ``lidar``: what a ROS
        node (:mod:`snnkart.ros`) gives the policy. The env's own episode is not advanced."""
        self._x, self._y, self._heading, self._v, self._w = x, y, heading, v, w
        self._next_cp, self._geo_k = next_cp, -1  # the path distance from this position
        return self._observe(np.asarray(lidar, dtype=np.float64))

    @property
    def velocity(self) -> tuple[float, float]:
        """The velocity state: forward px/s and turn rate rad/s (clockwise), as observed."""
        return self._v, self._w

    @property
    def ray_geometry(self) -> tuple[np.ndarray, float]:
        """The rays' directions relative to the heading (rad, clockwise) and their range, px."""
        return self._ray_offsets, self._ray_range

    @property
    def speed_m_s(self) -> float:
        return abs(self._v) / PIXELS_PER_METRE
