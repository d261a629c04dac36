"""Messages <-> the gazebo env's observation and actions, independent of the ROS version.

Frames. A track point ``(x_px, y_px)`` (y down, 100 px per metre) is the point
``(x_px / 100, -y_px / 100)`` m, and a heading ``h`` (clockwise on screen) the yaw ``-h``
(counter-clockwise, ROS's REP 103). By default the track is given in the odometry frame; with
an :class:`OdomFrame` (``--odom-origin spawn``) odometry counts from the track's spawn, as a
real robot's wheel odometry counts from where it was switched on. Odometry's
``twist.linear.x`` is the forward speed, ``twist.angular.z`` the counter-clockwise turn rate.

LIDAR. A ``LaserScan`` has beams at ``angle_min + j * angle_increment`` (counter-clockwise,
robot frame). Each env ray (at its offset from the heading, clockwise) takes the beam nearest in
angle (around the circle); a range that is NaN, infinite, below ``range_min`` or above
``range_max`` means no hit; the distance is clipped to the env's ray range and divided by it.
A scan made from the env's own rays (:func:`scan_from_rays`, the simulator side) converts
back to exactly those rays.

Actions. A discrete action moves the env's velocity state (:class:`snnkart.envs.gazebo.
DiffDrive`); the node publishes that state as ``cmd_vel``, within the robot's limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.envs.constants import KART_RADIUS_PX, PIXELS_PER_METRE
from snnkart.envs.gazebo import DiffDrive, GazeboEnv
from snnkart.envs.geometry import segment_distance
from snnkart.errors import DeployError

PPM = PIXELS_PER_METRE


@dataclass(frozen=True)
class Odom:
    """A planar odometry reading: position (m) and yaw (rad, counter-clockwise) in the odometry
    frame, forward speed (m/s) and turn rate (rad/s, counter-clockwise)."""

    x: float
    y: float
    yaw: float
    v: float
    w: float


@dataclass(frozen=True)
class Scan:
    """The fields of a ``sensor_msgs/LaserScan`` that the conversion reads."""

    angle_min: float
    angle_increment: float
    ranges: np.ndarray  # m
    range_min: float
    range_max: float


@dataclass(frozen=True)
class OdomFrame:
    """Where the odometry frame's origin lies in the track's frame (m, m, rad; REP 103).

    The identity (the default) is the track given in the odometry frame. A real robot's wheel
    odometry starts at zero where it was switched on: placed at the track's spawn, its frame is
    :meth:`at_spawn`. Velocities are in the robot's own frame and need no transform."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    @classmethod
    def at_pose(cls, x_px: float, y_px: float, heading: float) -> OdomFrame:
        pose = odom_from_env(x_px, y_px, heading, 0.0, 0.0)
        return cls(pose.x, pose.y, pose.yaw)

    @classmethod
    def at_spawn(cls, track: Any) -> OdomFrame:
        x, y = track.spawn_position
        return cls.at_pose(x, y, track.spawn_heading)

    def to_track(self, odom: Odom) -> Odom:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        x, y = self.x + c * odom.x - s * odom.y, self.y + s * odom.x + c * odom.y
        return Odom(x, y, odom.yaw + self.yaw, odom.v, odom.w)

    def from_track(self, odom: Odom) -> Odom:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = odom.x - self.x, odom.y - self.y
        return Odom(c * dx + s * dy, -s * dx + c * dy, odom.yaw - self.yaw, odom.v, odom.w)


def odom_from_env(x_px: float, y_px: float, heading: float, v_px: float, w_cw: float) -> Odom:
    """The odometry of a robot at an env pose and velocity (the simulator side)."""
    return Odom(x_px / PPM, -y_px / PPM, -heading, v_px / PPM, -w_cw)


def env_from_odom(odom: Odom) -> tuple[float, float, float, float, float]:
    """``(x_px, y_px, heading, v_px, w_cw)`` in the env's frame."""
    return odom.x * PPM, -odom.y * PPM, -odom.yaw, odom.v * PPM, -odom.w


def scan_from_rays(offsets_cw: np.ndarray, distances_m: np.ndarray, range_m: float) -> Scan:
    """A scan whose beams are the env's rays (evenly spaced: a full circle or a symmetric
    fan), nearest first in counter-clockwise order; ``range_m``: no hit."""
    angles = -np.asarray(offsets_cw, dtype=np.float64)
    order = np.argsort(angles)
    step = float(np.diff(angles[order]).mean()) if len(angles) > 1 else 0.0
    return Scan(float(angles[order][0]), step, np.asarray(distances_m)[order], 0.0, range_m)


def rays_from_scan(scan: Scan, offsets_cw: np.ndarray, range_m: float) -> np.ndarray:
    """The env's normalised ray distances ``[n]`` from a scan (nearest beam per ray)."""
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    if ranges.size == 0:
        raise ValueError("the scan has no beams")
    beams = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
    want = -np.asarray(offsets_cw, dtype=np.float64)
    gap = np.angle(np.exp(1j * (want[:, None] - beams[None, :])))  # wrapped to (-pi, pi]
    nearest = ranges[np.argmin(np.abs(gap), axis=1)]
    valid = np.isfinite(nearest) & (nearest >= scan.range_min) & (nearest <= scan.range_max)
    hit = np.where(valid, nearest, range_m)
    return np.minimum(hit, range_m) / range_m


class ObservationBuilder:
    """The gazebo env's observation from odometry and a scan, with the checkpoints counted in
    order as the env counts them (the robot's circle touching the next line)."""

    def __init__(self, env: Any, frame: OdomFrame | None = None) -> None:
        unwrapped = getattr(env, "unwrapped", env)
        if not isinstance(unwrapped, GazeboEnv):
            raise ValueError(
                f"the ROS bridge drives the gazebo env, not {type(unwrapped).__name__}"
            )
        self.env = unwrapped
        self.offsets, range_px = unwrapped.ray_geometry
        self.range_m = range_px / PPM
        self.lines = [(c.a, c.b) for c in unwrapped.track.checkpoints]
        self.next_cp = 0
        self.frame = frame or OdomFrame()

    @property
    def finished(self) -> bool:
        return self.next_cp >= len(self.lines)

    def observe(self, scan: Scan, odom: Odom) -> np.ndarray:
        x, y, heading, v, w = env_from_odom(self.frame.to_track(odom))
        while not self.finished and self._touches(x, y, self.next_cp):
            self.next_cp += 1
        lidar = rays_from_scan(scan, self.offsets, self.range_m)
        cp = min(self.next_cp, len(self.lines) - 1)
        return self.env.observe_measured(x, y, heading, v, w, cp, lidar)

    def _touches(self, x: float, y: float, k: int) -> bool:
        (ax, ay), (bx, by) = self.lines[k]
        return bool(segment_distance(x, y, ax, ay, bx, by) <= KART_RADIUS_PX)


class VelocityCommands:
    """Actions -> ``cmd_vel`` (m/s forward, rad/s counter-clockwise), by the env's own action
    model, clipped to the robot's limits."""

    def __init__(self, env: Any, max_linear: float | None = None, max_angular: float | None = None):
        unwrapped = getattr(env, "unwrapped", env)
        physics = unwrapped.config.physics
        for name, limit in (("max_linear", max_linear), ("max_angular", max_angular)):
            if limit is not None and not limit > 0:
                raise DeployError(f"--{name.replace('_', '-')} must be positive, not {limit}")
        self.drive = DiffDrive.of(physics, unwrapped.action_mode == "discrete")
        self.max_linear = min(max_linear or math.inf, physics.max_linear_m_s)
        self.max_angular = min(max_angular or math.inf, physics.max_angular_rad_s)
        # the model's own state stays within the robot's limits, so braking shows at once
        self.drive.vmax = min(self.drive.vmax, self.max_linear * PPM)
        self.drive.wmax = min(self.drive.wmax, self.max_angular)

    def reset(self) -> None:
        self.drive.v = self.drive.w = 0.0

    def __call__(self, action: Any) -> tuple[float, float]:
        v, w = self.drive.command(action)
        self.drive.coast()
        lin = min(max(v / PPM, -self.max_linear), self.max_linear)
        ang = min(max(-w, -self.max_angular), self.max_angular)
        return lin, ang


def yaw_from_quaternion(z: float, w: float) -> float:
    """The yaw of a planar orientation quaternion (x = y = 0)."""
    return 2.0 * math.atan2(z, w)
