"""ROS 1 for real: a rosmaster on a free loopback port, and rospy from the project's Python
(Debian's packages appended to sys.path by snnkart.ros.rospy_import, numpy and torch still the
project's), carrying the bridge's messages both ways."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from ros_helpers import MISSING, ROSMASTER, rosmaster

pytestmark = pytest.mark.skipif(ROSMASTER is None, reason=MISSING)
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def master() -> Iterator[str]:
    with rosmaster() as uri:
        yield uri


CHILD = r"""
import json, math, sys, threading
import numpy as np
from snnkart.ros.rospy_import import import_ros
from snnkart.ros.convert import Scan, rays_from_scan, scan_from_rays
ros = import_ros()
import torch
rospy, sensor, geometry = ros["rospy"], ros["sensor_msgs.msg"], ros["geometry_msgs.msg"]
rospy.init_node("snnkart_test", anonymous=True, disable_signals=True)
got = {}
done = threading.Event()
def on_scan(msg):
    try:
        got["scan"] = Scan(msg.angle_min, msg.angle_increment, np.array(msg.ranges),
                           msg.range_min, msg.range_max)
    except Exception as exc:
        got["error"] = repr(exc)
def on_cmd(msg):
    got["cmd"] = (msg.linear.x, msg.angular.z)
    done.set()
rospy.Subscriber("/scan", sensor.LaserScan, on_scan)
rospy.Subscriber("/cmd_vel", geometry.Twist, on_cmd)
scan_pub = rospy.Publisher("/scan", sensor.LaserScan, queue_size=1)
cmd_pub = rospy.Publisher("/cmd_vel", geometry.Twist, queue_size=1)
offsets = -math.pi + np.arange(16) * (2 * math.pi / 16)
distances = np.linspace(0.2, 3.0, 16)
made = scan_from_rays(offsets, distances, 3.0)
msg = sensor.LaserScan(angle_min=made.angle_min, angle_increment=made.angle_increment,
                       range_min=made.range_min, range_max=made.range_max,
                       ranges=list(made.ranges))
twist = geometry.Twist()
twist.linear.x, twist.angular.z = 0.22, -1.5
import time
for _ in range(100):
    scan_pub.publish(msg)
    cmd_pub.publish(twist)
    time.sleep(0.1)
    if done.is_set() and ("scan" in got or "error" in got):
        break
if "scan" not in got:
    sys.exit(f"no scan received: {got}")
rays = rays_from_scan(got["scan"], offsets, 3.0)
print(json.dumps({
    "rays_equal": bool(np.allclose(rays, distances / 3.0, rtol=0, atol=1e-6)),
    "cmd": got["cmd"], "numpy": np.__file__, "torch": torch.__file__,
    "rospy": rospy.__file__,
}))
rospy.signal_shutdown("done")
"""


@pytest.mark.timeout(90)
def test_rospy_from_the_project_python_carries_the_bridge_messages(master: str) -> None:
    env = {**os.environ, "ROS_MASTER_URI": master, "ROS_HOSTNAME": "127.0.0.1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}  # fmt: skip
    result = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                            env=env, timeout=80)  # fmt: skip
    assert result.returncode == 0, result.stderr[-2000:]
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert out["rays_equal"] and out["cmd"] == [0.22, -1.5]
    venv = str(Path(sys.executable).parent.parent)
    assert out["numpy"].startswith(venv) and out["torch"].startswith(venv), out
    assert out["rospy"].startswith("/usr/lib/python3/dist-packages"), out
    import numpy

    assert "/usr/lib/python3/dist-packages" not in sys.path  # the tests' own process untouched
    assert numpy.__file__.startswith(venv)
