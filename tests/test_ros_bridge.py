"""The bridge pair over a real rosmaster: ``snnkart ros sim`` (the gazebo env behind /scan,
/odom, /clock and /cmd_vel) and ``snnkart ros drive`` (a pretrained gazebo policy,
``tests/data/policies/gazebo-snn``, made by ``scripts/make_test_policy.py --env gazebo``).
In lock-step the robot drives the same trajectory as the policy in the env directly; in real
time it still finishes. Both lap times are printed."""

from __future__ import annotations

import json
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from ros_helpers import MISSING, ROSMASTER, ros_env, rosmaster

from snnkart.eval.episodes import run_episodes

pytestmark = pytest.mark.skipif(ROSMASTER is None, reason=MISSING)
POLICY = Path(__file__).parent / "data" / "policies" / "gazebo-snn"
SNNKART = str(Path(sys.executable).with_name("snnkart"))
SEED = 10_000


def _direct(predictor, env) -> tuple[list[tuple[float, float]], dict]:
    """The policy in the env directly: its positions and its episode."""
    positions: list[tuple[float, float]] = []
    env.reset(seed=SEED)  # the first position, as the simulator records it
    positions.append(tuple(env.unwrapped.position))
    result = run_episodes(env, predictor, 1, seed=SEED,
                          on_step=lambda e: positions.append(tuple(e.unwrapped.position)))  # fmt: skip
    return positions, result[0].__dict__


def _bridge(
    tmp_path: Path, policy: Path, backend: str, lock_step: bool, origin: str = "track"
) -> dict:
    mode = "--lock-step" if lock_step else "--real-time"
    out = tmp_path / f"sim-{backend}-{mode[2:]}.json"
    with rosmaster() as uri:
        env = ros_env(uri)
        sim = subprocess.Popen([SNNKART, "ros", "sim", "--policy", str(policy), mode,
                                "--seed", str(SEED), "--out",
                                str(out), "--timeout", "60", "--odom-origin", origin], env=env,
                               text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        drive = subprocess.Popen([SNNKART, "ros", "drive", str(policy), "--backend", backend,
                                  mode, "--max-seconds", "150", "--timeout", "10",
                                  "--odom-origin", origin], env=env,
                                 text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        try:
            _, sim_err = sim.communicate(timeout=200)
            drive_out, drive_err = drive.communicate(timeout=60)
        finally:
            for p in (sim, drive):
                if p.poll() is None:
                    p.kill()
    assert sim.returncode == 0, sim_err[-2000:]
    assert drive.returncode == 0, drive_err[-2000:]
    record = json.loads(out.read_text())
    record["drive"] = json.loads(drive_out.strip().splitlines()[-1])
    return record


@pytest.mark.timeout(300)
@pytest.mark.parametrize("backend", ["torch", "nir-ref", "lava-sim"])
def test_lock_step_drives_the_same_trajectory_as_the_env(tmp_path: Path, backend: str) -> None:
    """torch: the trained policy; nir-ref and lava-sim: its export in fixed point, against the
    reference of that arithmetic in the env directly (Lava is bit-exact with it)."""
    from snnkart.backends.reference import NIRReference
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.trained import TorchPredictor, load_run

    run = load_run(POLICY)
    policy = POLICY
    if backend == "torch":
        predictor = TorchPredictor(run)
    else:
        policy, _ = export_nir(run, tmp_path / "policy.nir")
        predictor = NIRReference(policy, "fixed")
    env = run.config.make_env(track=run.track)
    try:
        positions, episode = _direct(predictor, env)
    finally:
        env.close()
    if backend == "torch":
        assert episode["finished"], episode  # the fixture drives
    record = _bridge(tmp_path, policy, backend, lock_step=True)
    assert record["finished"] == episode["finished"], record["ended"]
    assert record["steps"] == len(positions) - 1, record["ended"]
    np.testing.assert_allclose(np.array(record["positions"]), np.array(positions), atol=1e-6)
    if episode["finished"]:
        assert record["lap_time"] == pytest.approx(episode["lap_time"])
        assert record["drive"]["finished"] and record["drive"]["stopped"] == "finished the lap"
    print(f"lock-step {backend}: {record['ended']}, lap time {record['lap_time']} s "
          f"({record['steps']} steps, {record['wall_seconds']:.1f} s wall-clock, median "
          f"{record['drive']['latency_ms_median']:.2f} ms from messages to Twist)")  # fmt: skip


@pytest.mark.timeout(300)
def test_real_time_still_finishes(tmp_path: Path) -> None:
    """The driver's control loop keeps the env's rate (its action model integrates once per
    step): at 44 commands/s instead of 60 the robot turned too late and crashed one run in four."""
    record = _bridge(tmp_path, POLICY, "torch", lock_step=False)
    assert record["finished"], record["ended"]
    assert record["drive"]["commands"] >= 0.9 * record["steps"], record["drive"]
    print(f"real-time lap time {record['lap_time']:.2f} s ({record['steps']} steps, "
          f"{record['wall_seconds']:.1f} s wall-clock)")  # fmt: skip


@pytest.mark.timeout(300)
def test_odometry_from_where_the_robot_started_still_finishes(tmp_path: Path) -> None:
    """As on a real robot: the simulator's odometry counts from the episode's start (the spawn
    with this seed's jitter), and the driver takes the track's spawn as its origin, so it
    believes itself a few centimetres from where it is; it still finishes the lap."""
    from snnkart.envs import make

    env = make("gazebo", track="small_S")
    try:
        env.reset(seed=SEED)
        u = env.unwrapped
        offset = np.subtract(u.position, u.track.spawn_position)
    finally:
        env.close()
    assert np.abs(offset).max() > 1.0  # the belief is off (px)
    record = _bridge(tmp_path, POLICY, "torch", lock_step=True, origin="spawn")
    assert record["finished"], record["ended"]
    assert record["drive"]["finished"], record["drive"]  # its own count of checkpoints agrees
    print(f"odometry from the start, {np.hypot(*offset):.1f} px off the spawn: lap "
          f"{record['lap_time']:.2f} s ({record['steps']} steps)")  # fmt: skip


@pytest.mark.timeout(60)
def test_drive_refuses_without_a_master_and_for_other_envs(tmp_path: Path) -> None:
    env = ros_env("http://127.0.0.1:9/")  # nothing listens there
    start = time.monotonic()
    result = subprocess.run([SNNKART, "ros", "drive", str(POLICY)], env=env, text=True,
                            capture_output=True, timeout=50)  # fmt: skip
    assert result.returncode == 2 and "no rosmaster reachable" in result.stderr
    assert time.monotonic() - start < 30
    grid = Path(__file__).parent / "data" / "policies" / "grid-snn"
    with rosmaster() as uri:
        result = subprocess.run([SNNKART, "ros", "drive", str(grid)], env=ros_env(uri),
                                text=True, capture_output=True, timeout=50)  # fmt: skip
    assert result.returncode == 2 and "trained on the grid env" in result.stderr


LISTENER = r"""
import json, sys, time
from snnkart.ros.rospy_import import init_node, import_ros
rospy = init_node("listener")
geometry = import_ros()["geometry_msgs.msg"]
got = []
rospy.Subscriber("/cmd_vel", geometry.Twist, lambda m: got.append((m.linear.x, m.angular.z)))
end = time.monotonic() + float(sys.argv[1])
announced = False
while time.monotonic() < end:
    time.sleep(0.05)
    if not announced and sum(1 for g in got if g != (0.0, 0.0)) >= 30:
        print("driving", flush=True)  # half a second into the lap
        announced = True
print(json.dumps({"count": len(got), "last": got[-1] if got else None,
                  "moving": sum(1 for g in got if g != (0.0, 0.0))}))
"""


def _foreground_sigint() -> None:
    """A terminal's Ctrl-C, even where CI starts the suite with SIGINT ignored."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.timeout(120)
@pytest.mark.parametrize("how", ["stale", "ctrl-c", "sigterm"])
def test_the_robot_is_stopped_when_input_ends_or_on_ctrl_c(tmp_path: Path, how: str) -> None:
    """The simulator stops publishing after 2 s (stale input), or the driver gets SIGINT or
    SIGTERM (what roslaunch and systemd send) while driving: either way the last command on
    /cmd_vel is a zero Twist, and the driver says why."""
    import signal

    with rosmaster() as uri:
        env = ros_env(uri)
        listener = subprocess.Popen([sys.executable, "-c", LISTENER, "12"], env=env, text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        steps = "120" if how == "stale" else "1500"  # 2 s, or more than the test lasts
        sim = subprocess.Popen([SNNKART, "ros", "sim", "--real-time", "--max-steps", steps,
                                "--seed", str(SEED)], env=env, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        drive = subprocess.Popen([SNNKART, "ros", "drive", str(POLICY), "--real-time",
                                  "--timeout", "1"], env=env, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 preexec_fn=_foreground_sigint)  # fmt: skip
        try:
            if how != "stale":  # half a second into the lap (it takes 6.5 s), not a fixed wait
                ready, _, _ = select.select([listener.stdout], [], [], 60)
                assert ready and listener.stdout.readline().strip() == "driving"
                drive.send_signal(signal.SIGINT if how == "ctrl-c" else signal.SIGTERM)
            drive_out, drive_err = drive.communicate(timeout=60)
            heard = json.loads(listener.communicate(timeout=30)[0].strip().splitlines()[-1])
            sim.communicate(timeout=30)
        finally:
            for p in (sim, drive, listener):
                if p.poll() is None:
                    p.kill()
    assert heard["moving"] > 10, heard  # it drove
    assert heard["last"] == [0.0, 0.0], heard  # and was stopped
    if how == "stale":
        # the simulator publishes each scan just before its odometry: the scan may be judged
        # silent a moment before the odometry is ("no scan", or "no scan and odometry")
        assert drive.returncode == 0, drive_err
        assert "no scan" in drive_out and "for 1 s: stopped the robot" in drive_out, drive_out
    else:
        code, name = (130, "SIGINT") if how == "ctrl-c" else (143, "SIGTERM")
        assert drive.returncode == code and f"interrupted ({name})" in drive_err, drive_err
        assert "the robot was stopped" in drive_err, drive_err


SCANS_ONLY = r"""
import math, sys, time
import numpy as np
from snnkart.ros.rospy_import import init_node, import_ros
from snnkart.envs import make
from snnkart.ros.master import ros_env
rospy = init_node("fake_robot")
ros = import_ros()
scan_pub = rospy.Publisher("/scan", ros["sensor_msgs.msg"].LaserScan, queue_size=4)
odom_pub = rospy.Publisher("/odom", ros["nav_msgs.msg"].Odometry, queue_size=4)
start = time.monotonic()
while time.monotonic() - start < 8:
    scan = ros["sensor_msgs.msg"].LaserScan(angle_min=-math.pi, angle_increment=math.pi / 8,
                                           range_min=0.1, range_max=3.0, ranges=[2.0] * 16)
    scan.header.stamp = rospy.Time.now()
    scan_pub.publish(scan)
    if time.monotonic() - start < 3:  # the odometry driver dies after 3 s
        odom = ros["nav_msgs.msg"].Odometry()
        odom.header.stamp = scan.header.stamp
        odom.pose.pose.position.x, odom.pose.pose.position.y = 1.8, -4.5
        odom.pose.pose.orientation.w = 1.0
        odom_pub.publish(odom)
    time.sleep(0.02)
"""


@pytest.mark.timeout(90)
def test_the_robot_is_stopped_when_odometry_alone_goes_silent(tmp_path: Path) -> None:
    with rosmaster() as uri:
        env = ros_env(uri)
        listener = subprocess.Popen([sys.executable, "-c", LISTENER, "10"], env=env, text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        robot = subprocess.Popen([sys.executable, "-c", SCANS_ONLY], env=env, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        try:
            drive = subprocess.run([SNNKART, "ros", "drive", str(POLICY), "--real-time",
                                    "--timeout", "1"], env=env, text=True, capture_output=True,
                                   timeout=60)  # fmt: skip
            heard = json.loads(listener.communicate(timeout=30)[0].strip().splitlines()[-1])
        finally:
            for p in (robot, listener):
                if p.poll() is None:
                    p.kill()
    assert drive.returncode == 0, drive.stderr[-2000:]
    assert "no odometry for 1 s" in drive.stdout, drive.stdout  # the scans kept coming
    assert heard["count"] > 0 and heard["last"] == [0.0, 0.0], heard
