"""``snnkart ros drive``: a deployed policy driving a differential-drive robot over ROS.

It subscribes to ``/scan`` and ``/odom``, builds exactly the observation the gazebo env would
(:class:`snnkart.ros.convert.ObservationBuilder`), runs the policy on its backend and publishes
``/cmd_vel`` by the env's own action model, within the robot's limits.

- Lock-step (with ``snnkart ros sim --lock-step``): one command per (scan, odom) pair of the
  same stamp, once ``/cmd_vel`` has a subscriber (so no command is lost); a state the simulator
  resends is answered only if it was not before.
- Real time: a command at the control rate from the latest messages.

Safety first: if scans or odometry stop arriving for longer than ``timeout``, or the backend
fails, it publishes a zero Twist and says why; on Ctrl-C and on every exit it publishes a zero
Twist before returning.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from snnkart.envs.constants import DT
from snnkart.ros.convert import (
    ObservationBuilder,
    Odom,
    OdomFrame,
    Scan,
    VelocityCommands,
    yaw_from_quaternion,
)
from snnkart.ros.rospy_import import import_ros


@dataclass
class DriveResult:
    commands: int = 0
    stopped: str = "running"  # why the node stopped driving
    finished: bool = False
    latencies: list[float] | None = None  # s, message in -> Twist out


class DriveNode:
    def __init__(
        self,
        env: Any,
        predictor: Any,
        lock_step: bool,
        timeout: float = 2.0,
        rate: float = 1 / DT,
        limits: tuple[float | None, float | None] = (None, None),
        frame: OdomFrame | None = None,
    ) -> None:
        self.ros = import_ros()
        self.builder = ObservationBuilder(env, frame)
        self.commands = VelocityCommands(env, *limits)
        self.predictor = predictor
        self.lock_step, self.timeout, self.rate = lock_step, timeout, rate
        self.lock = threading.Lock()
        self.scan: tuple[float, Scan] | None = None
        self.odom: tuple[float, Odom] | None = None
        now = time.monotonic()
        self.last_seen = {"scan": now, "odometry": now}  # when each last arrived
        self.pub_lock = threading.Lock()  # a command and the stop never interleave
        self.last_stamp = -1.0
        self.last_cmd = (0.0, 0.0)
        self.result = DriveResult(latencies=[])
        self.done = threading.Event()
        self.ready = threading.Event()  # the command topic has a subscriber
        rospy, msgs = self.ros["rospy"], self.ros
        self.pub = rospy.Publisher("/cmd_vel", msgs["geometry_msgs.msg"].Twist, queue_size=4)
        rospy.Subscriber("/scan", msgs["sensor_msgs.msg"].LaserScan, self._on_scan)
        rospy.Subscriber("/odom", msgs["nav_msgs.msg"].Odometry, self._on_odom)

    def _on_scan(self, msg: Any) -> None:
        scan = Scan(
            msg.angle_min,
            msg.angle_increment,
            np.asarray(msg.ranges, dtype=np.float64),
            msg.range_min,
            msg.range_max,
        )
        self.last_seen["scan"] = time.monotonic()  # outside the lock: a slow act is not silence
        with self.lock:
            self.scan = (msg.header.stamp.to_sec(), scan)
        if self.lock_step:
            self._act_if_paired()

    def _on_odom(self, msg: Any) -> None:
        p, q, t = msg.pose.pose, msg.pose.pose.orientation, msg.twist.twist
        odom = Odom(
            p.position.x, p.position.y, yaw_from_quaternion(q.z, q.w), t.linear.x, t.angular.z
        )
        self.last_seen["odometry"] = time.monotonic()
        with self.lock:
            self.odom = (msg.header.stamp.to_sec(), odom)
        if self.lock_step:
            self._act_if_paired()

    def _act_if_paired(self) -> None:
        with self.lock:
            if self.scan is None or self.odom is None or self.scan[0] != self.odom[0]:
                return
            if not self.ready.is_set() or self.scan[0] == self.last_stamp:
                return  # not connected yet, or the simulator resent a state already answered
            self.last_stamp = self.scan[0]
            self._act(self.scan[1], self.odom[1])

    def _act(self, scan: Scan, odom: Odom) -> None:
        if self.done.is_set():
            return
        start = time.perf_counter()
        try:
            obs = self.builder.observe(scan, odom)
            cmd = self.commands(self.predictor.predict(obs))
        except Exception as exc:  # a failed backend must not leave the robot driving
            self.stop(f"the policy backend failed: {type(exc).__name__}: {exc}")
            return
        with self.pub_lock:
            if self.done.is_set():  # stopped while predicting: the zero stays the last word
                return
            self.publish(*cmd)
        self.last_cmd = cmd
        self.result.commands += 1
        assert self.result.latencies is not None
        self.result.latencies.append(time.perf_counter() - start)
        if self.builder.finished:
            self.result.finished = True

    def publish(self, linear: float, angular: float) -> None:
        twist = self.ros["geometry_msgs.msg"].Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        self.pub.publish(twist)

    def stop(self, why: str) -> None:
        """Zero velocity, and the reason; no command is published after it."""
        with self.pub_lock:
            if not self.done.is_set():
                self.result.stopped = why
                self.done.set()
            self.publish(0.0, 0.0)
        self.last_cmd = (0.0, 0.0)

    def spin(self, max_seconds: float | None = None) -> DriveResult:
        """Drive until finished, stale input, a failure, Ctrl-C or ``max_seconds``."""
        rospy = self.ros["rospy"]
        start = time.monotonic()
        period = 1.0 / self.rate
        while self.pub.get_num_connections() == 0 and not rospy.is_shutdown():
            if time.monotonic() - start > self.timeout:
                self.result.stopped = f"nothing subscribes to /cmd_vel after {self.timeout:g} s"
                return self.result
            time.sleep(0.02)
        self.ready.set()
        now = next_tick = time.monotonic()
        self.last_seen = {"scan": now, "odometry": now}
        try:
            while not self.done.is_set() and not rospy.is_shutdown():
                if max_seconds is not None and time.monotonic() - start > max_seconds:
                    self.stop("time is up")
                    break
                silent = [
                    k for k, t in self.last_seen.items() if time.monotonic() - t > self.timeout
                ]
                if silent:
                    what = " and ".join(silent)
                    self.stop(f"no {what} for {self.timeout:g} s: stopped the robot")
                    break
                with self.lock:
                    latest = (self.scan, self.odom)
                if not self.lock_step and latest[0] is not None and latest[1] is not None:
                    self._act(latest[0][1], latest[1][1])
                if self.result.finished:
                    self.stop("finished the lap")
                    break
                if self.lock_step:
                    time.sleep(0.01)
                    continue
                # ticks on a fixed grid: the action model integrates once per env step, so
                # the rate must not sag by the time acting takes; a tick missed is dropped
                next_tick = max(next_tick + period, time.monotonic())
                time.sleep(max(0.0, next_tick - time.monotonic()))
        except KeyboardInterrupt:
            self.stop("interrupted: stopped the robot")
            raise
        finally:
            self.stop(self.result.stopped if self.done.is_set() else "stopped")
            self._flush()
        return self.result

    def _flush(self, within: float = 1.0) -> None:
        """Wait (at most ``within`` s) until rospy's sending threads have sent the queued
        commands. They are daemon threads, and rospy's exit hook closes the connections: a
        zero still queued when the process exits never reaches the robot (seen once under load:
        the listener's last command was the policy's)."""
        connections = getattr(getattr(self.pub, "impl", None), "connections", [])
        end = time.monotonic() + within
        while time.monotonic() < end and any(getattr(c, "_queue", None) for c in connections):
            time.sleep(0.005)
        time.sleep(0.1)  # the thread writes what it took from the queue outside its lock
