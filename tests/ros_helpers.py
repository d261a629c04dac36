"""A rosmaster of the test's own on a free loopback port (shared by the ROS tests)."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import time
import xmlrpc.client
from collections.abc import Iterator

ROSMASTER = shutil.which("rosmaster")
MISSING = (
    "optional: ROS 1 is not installed (apt-get install python3-rospy python3-rosmaster "
    "python3-sensor-msgs python3-geometry-msgs python3-nav-msgs)"
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def rosmaster() -> Iterator[str]:
    """Start ``rosmaster --core`` on a free port, yield its URI, stop it."""
    assert ROSMASTER is not None
    port = free_port()
    uri = f"http://127.0.0.1:{port}/"
    env = {**os.environ, "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "127.0.0.1"}
    proc = subprocess.Popen([ROSMASTER, "--core", "-p", str(port)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    try:
        deadline = time.monotonic() + 20
        while True:
            try:
                xmlrpc.client.ServerProxy(uri).getPid("/test")
                break
            except OSError:
                if time.monotonic() > deadline or proc.poll() is not None:
                    raise RuntimeError("rosmaster did not start") from None
                time.sleep(0.1)
        yield uri
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def ros_env(uri: str) -> dict[str, str]:
    return {**os.environ, "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "127.0.0.1",
            "SDL_VIDEODRIVER": "dummy"}  # fmt: skip
