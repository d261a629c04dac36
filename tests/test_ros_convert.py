"""The ROS-independent conversion (snnkart.ros.convert): from the simulator's messages the node
builds exactly the gazebo env's observation, and its velocity commands are the env's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snnkart.envs import make
from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.ros.convert import (
    ObservationBuilder,
    Odom,
    OdomFrame,
    Scan,
    VelocityCommands,
    env_from_odom,
    odom_from_env,
    rays_from_scan,
    scan_from_rays,
    yaw_from_quaternion,
)


def _messages(env) -> tuple[Scan, Odom]:
    """What the simulator side publishes for the env's current state."""
    u = env.unwrapped
    offsets, range_px = u.ray_geometry
    scan = scan_from_rays(offsets, u.lidar_distances * range_px / PIXELS_PER_METRE,
                          range_px / PIXELS_PER_METRE)  # fmt: skip
    return scan, odom_from_env(*u.position, u.heading, *u.velocity)


def _driver(obs: np.ndarray, rng: np.random.Generator) -> int:
    """Steer towards the next checkpoint (obs: ..., cos, sin, distance), with some noise."""
    sin = obs[-2]
    if rng.random() < 0.15:
        return int(rng.integers(0, 5))
    if abs(sin) > 0.2:
        return 4 if sin > 0 else 3
    return 1


@pytest.mark.parametrize("track,origin", [("small_S", "track"), ("big_S", "track"),
                                          ("small_S", "elsewhere"), ("big_S", "elsewhere")])  # fmt: skip
def test_the_node_builds_the_env_observation_from_the_simulators_messages(
    track: str, origin: str
) -> None:
    """origin "track": the track is given in the odometry frame (bit for bit); "elsewhere": the
    odometry frame's origin lies half a metre from the start, turned by 0.7 rad (to rounding;
    at the start itself the spawns face east, where a wrong rotation would not show)."""
    env, shadow = make("gazebo", track=track), make("gazebo", track=track)
    rng = np.random.default_rng(0)
    try:
        obs, _ = env.reset(seed=1)
        u = env.unwrapped
        x0, y0 = u.position
        moved = OdomFrame.at_pose(x0 + 30.0, y0 - 40.0, u.heading + 0.7)
        frame = moved if origin == "elsewhere" else OdomFrame()
        builder, commands = ObservationBuilder(shadow, frame), VelocityCommands(shadow)
        steps = passed = 0
        while steps < 600:
            scan, odom = _messages(env)
            built = builder.observe(scan, frame.from_track(odom))
            if origin == "track":
                np.testing.assert_array_equal(built, obs, err_msg=str(steps))
            else:
                np.testing.assert_allclose(built, obs, rtol=0, atol=1e-9, err_msg=str(steps))
            assert builder.next_cp == env.unwrapped.next_checkpoint, steps
            action = _driver(obs, rng)
            lin, ang = commands(action)
            obs, _, terminated, truncated, info = env.step(action)
            u = env.unwrapped
            assert lin == pytest.approx(u._moved_v / PIXELS_PER_METRE, abs=1e-12)
            assert ang == pytest.approx(-u.velocity[1], abs=1e-12)  # counter-clockwise
            passed = max(passed, info["checkpoint"])
            steps += 1
            if terminated or truncated:
                break
        assert passed >= 1  # the check covered a checkpoint change
    finally:
        env.close()
        shadow.close()


def test_frames_round_trip_and_follow_rep_103() -> None:
    odom = odom_from_env(250.0, 100.0, math.pi / 2, 150.0, 0.5)  # facing down the screen
    assert (odom.x, odom.y, odom.yaw, odom.v, odom.w) == (2.5, -1.0, -math.pi / 2, 1.5, -0.5)
    assert env_from_odom(odom) == (250.0, 100.0, math.pi / 2, 150.0, 0.5)
    assert yaw_from_quaternion(math.sin(0.3), math.cos(0.3)) == pytest.approx(0.6)


def test_an_odometry_frame_maps_poses_both_ways() -> None:
    """A robot switched on at the spawn reads (0, 0, 0) there, and 1 m ahead and 0.5 m to its
    left (REP 103: y to the left) reads (1, 0.5); the frame maps each back to the track."""
    frame = OdomFrame.at_pose(180.0, 450.0, math.pi / 2)  # facing down the screen: yaw -pi/2
    at = odom_from_env(180.0, 450.0, math.pi / 2, 0.0, 0.0)
    ahead = odom_from_env(230.0, 550.0, math.pi / 2, 1.0, 0.2)  # 1 m ahead, 0.5 m to its left
    start, moved = frame.from_track(at), frame.from_track(ahead)
    assert (start.x, start.y, start.yaw) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert (moved.x, moved.y, moved.yaw) == pytest.approx((1.0, 0.5, 0.0), abs=1e-12)
    assert (moved.v, moved.w) == (ahead.v, ahead.w)  # the robot's own frame
    back = frame.to_track(moved)
    assert (back.x, back.y, back.yaw) == pytest.approx((ahead.x, ahead.y, ahead.yaw), abs=1e-12)
    assert OdomFrame().to_track(ahead) == ahead


def test_a_scan_is_resampled_to_the_env_rays() -> None:
    offsets = np.array([-math.pi, -math.pi / 2, 0.0, math.pi / 2])  # behind, left, ahead, right
    beams = np.full(360, 5.0)
    angles = -math.pi + np.arange(360) * (2 * math.pi / 360)  # counter-clockwise from behind
    beams[np.argmin(np.abs(angles - 0.0))] = 1.0  # ahead
    beams[np.argmin(np.abs(angles - math.pi / 2))] = np.inf  # left (ccw +90): no return
    beams[np.argmin(np.abs(angles + math.pi / 2))] = 0.5  # right
    beams[0] = np.nan  # behind
    scan = Scan(-math.pi, 2 * math.pi / 360, beams, 0.12, 3.5)
    rays = rays_from_scan(scan, offsets, 2.0)
    np.testing.assert_allclose(rays, [1.0, 1.0, 0.5, 0.25])  # NaN, inf: no hit; 5 m clipped
    short = Scan(-math.pi, 2 * math.pi / 360, np.full(360, 0.05), 0.12, 3.5)
    np.testing.assert_allclose(rays_from_scan(short, offsets, 2.0), 1.0)  # below range_min
    with pytest.raises(ValueError, match="no beams"):
        rays_from_scan(Scan(0.0, 0.1, np.array([]), 0.0, 1.0), offsets, 2.0)


def test_the_builder_refuses_other_envs() -> None:
    env = make("steer", track="small_S")
    try:
        with pytest.raises(ValueError, match="gazebo env, not SteerEnv"):
            ObservationBuilder(env)
    finally:
        env.close()


def test_commands_stay_within_the_robots_limits() -> None:
    env = make("gazebo", track="small_S")
    try:
        free, limited = VelocityCommands(env), VelocityCommands(env, 0.22, 1.0)
        out_free = [free(a) for a in [1] * 80 + [3] * 10]
        out_lim = [limited(a) for a in [1] * 80 + [3] * 10]
    finally:
        env.close()
    assert max(v for v, _ in out_free) > 1.5 and max(abs(w) for _, w in out_free) > 1.4
    assert max(v for v, _ in out_lim) == 0.22 and 0.99 < max(abs(w) for _, w in out_lim) <= 1.0
