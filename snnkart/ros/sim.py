"""``snnkart ros sim``: snnkart's gazebo env playing Gazebo's part over real ROS topics.

It publishes the env's LIDAR as ``/scan`` (sensor_msgs/LaserScan), its pose and velocity as
``/odom`` (nav_msgs/Odometry, REP 103 frames, see :mod:`snnkart.ros.convert`) and the simulated
time on ``/clock``, and applies each ``/cmd_vel`` (geometry_msgs/Twist) as the robot's velocity.

- Lock-step: the simulation advances one env step per command, so results do not depend on
  the backend's latency. Until a command comes it publishes the same state again (every
  ``RESEND`` seconds), so neither side can miss the other at start-up.
- Real time: the simulation advances at the env's 60 steps per second with the latest command
  (zero before the first one).

The episode's trajectory, lap time and end are returned (and written as JSON by the command).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snnkart.envs.constants import DT, PIXELS_PER_METRE
from snnkart.ros.convert import OdomFrame, odom_from_env, scan_from_rays
from snnkart.ros.rospy_import import import_ros

RESEND = 0.2
"""Seconds between repeats of an unanswered lock-step state."""


@dataclass
class SimResult:
    mode: str
    steps: int = 0
    positions: list[tuple[float, float]] = field(default_factory=list)
    finished: bool = False
    lap_time: float | None = None
    crashed: bool = False
    ended: str = "running"
    wall_seconds: float = 0.0


class SimBridge:
    """The env behind the topics; ``run()`` drives one episode."""

    def __init__(
        self,
        env: Any,
        seed: int,
        lock_step: bool,
        timeout: float = 30.0,
        odom_origin: str = "track",
    ) -> None:
        self.ros = import_ros()
        self.env = env
        self.unwrapped = env.unwrapped
        self.seed = seed
        self.lock_step = lock_step
        self.timeout = timeout
        self.odom_origin = odom_origin  # "track", or "spawn": where the episode started
        self.frame = OdomFrame()
        self.cmd: tuple[float, float] | None = None
        self.cmd_event = threading.Event()
        rospy = self.ros["rospy"]
        msgs = self.ros
        self.scan_pub = rospy.Publisher("/scan", msgs["sensor_msgs.msg"].LaserScan, queue_size=4)
        self.odom_pub = rospy.Publisher("/odom", msgs["nav_msgs.msg"].Odometry, queue_size=4)
        self.clock_pub = rospy.Publisher("/clock", msgs["rosgraph_msgs.msg"].Clock, queue_size=4)
        self.cmd_sub = rospy.Subscriber("/cmd_vel", msgs["geometry_msgs.msg"].Twist, self._on_cmd)

    def _on_cmd(self, msg: Any) -> None:
        self.cmd = (float(msg.linear.x), float(msg.angular.z))
        self.cmd_event.set()

    def publish(self, step: int) -> None:
        rospy = self.ros["rospy"]
        stamp = rospy.Time.from_sec(step * DT)
        clock = self.ros["rosgraph_msgs.msg"].Clock()
        clock.clock = stamp
        self.clock_pub.publish(clock)
        u = self.unwrapped
        offsets, range_px = u.ray_geometry
        range_m = range_px / PIXELS_PER_METRE
        scan = scan_from_rays(offsets, u.lidar_distances * range_m, range_m)
        msg = self.ros["sensor_msgs.msg"].LaserScan()
        msg.header.stamp, msg.header.frame_id = stamp, "base_scan"
        msg.angle_min, msg.angle_increment = scan.angle_min, scan.angle_increment
        msg.angle_max = scan.angle_min + scan.angle_increment * (len(scan.ranges) - 1)
        msg.range_min, msg.range_max = scan.range_min, scan.range_max
        msg.ranges = [float(r) for r in scan.ranges]
        self.scan_pub.publish(msg)
        (x, y), (v, w) = u.position, u.velocity
        odom = self.frame.from_track(odom_from_env(x, y, u.heading, v, w))
        o = self.ros["nav_msgs.msg"].Odometry()
        o.header.stamp, o.header.frame_id, o.child_frame_id = stamp, "odom", "base_footprint"
        o.pose.pose.position.x, o.pose.pose.position.y = odom.x, odom.y
        o.pose.pose.orientation.z = float(np.sin(odom.yaw / 2))
        o.pose.pose.orientation.w = float(np.cos(odom.yaw / 2))
        o.twist.twist.linear.x, o.twist.twist.angular.z = odom.v, odom.w
        self.odom_pub.publish(o)

    def _connected(self) -> bool:
        """Wait until a driver subscribes to the scan and odometry and publishes commands."""
        deadline = time.monotonic() + self.timeout
        pubs = (self.scan_pub, self.odom_pub)
        while not (
            all(p.get_num_connections() for p in pubs) and self.cmd_sub.get_num_connections()
        ):
            if time.monotonic() > deadline or self.ros["rospy"].is_shutdown():
                return False
            time.sleep(0.02)
        return True

    def _next_command(self, step: int) -> tuple[float, float] | None:
        """Lock-step: the command answering this state (None: none within the timeout)."""
        deadline = time.monotonic() + self.timeout
        while not self.cmd_event.wait(RESEND):
            if time.monotonic() > deadline or self.ros["rospy"].is_shutdown():
                return None
            self.publish(step)
        self.cmd_event.clear()
        return self.cmd

    def run(self, max_steps: int | None = None) -> SimResult:
        result = SimResult("lock-step" if self.lock_step else "real-time")
        self.env.reset(seed=self.seed)
        result.positions.append(tuple(self.unwrapped.position))
        if self.odom_origin == "spawn":  # wheel odometry counts from where the robot started
            x, y = self.unwrapped.position
            self.frame = OdomFrame.at_pose(x, y, self.unwrapped.heading)
        if not self._connected():
            result.ended = f"no driver connected within {self.timeout:g} s"
            return result
        start = next_tick = time.monotonic()
        self.publish(0)
        while max_steps is None or result.steps < max_steps:
            if self.lock_step:
                cmd = self._next_command(result.steps)
                if cmd is None:
                    result.ended = "no command within the timeout"
                    break
            else:  # paced by the wall clock: rospy's Rate would follow /clock under use_sim_time
                # a step late (the CPU was busy) is not made up in a burst of steps the
                # driver could not answer: the simulation runs slower than real time instead
                next_tick = max(next_tick + DT, time.monotonic() - DT)
                time.sleep(max(0.0, next_tick - time.monotonic()))
                cmd = self.cmd or (0.0, 0.0)
            self.unwrapped.set_velocity(*cmd)
            _, _, terminated, truncated, info = self.unwrapped.step(None)
            result.steps += 1
            result.positions.append(tuple(self.unwrapped.position))
            self.publish(result.steps)
            if terminated or truncated:
                result.finished = bool(info["lap_finished"])
                result.lap_time, result.crashed = info["lap_time"], bool(info["crashed"])
                result.ended = (
                    "finished" if result.finished else ("crashed" if result.crashed else "ended")
                )
                break
        result.wall_seconds = time.monotonic() - start
        return result
