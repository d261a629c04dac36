"""A rosmaster of one's own on a free loopback port (tests, benchmarks, demos)."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import time
import xmlrpc.client
from collections.abc import Iterator

from snnkart.ros.rospy_import import DEBIAN_PACKAGES, RosUnavailableError


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def rosmaster(start_timeout: float = 20.0) -> Iterator[str]:
    """Start ``rosmaster --core`` on a free port, yield its URI, stop it."""
    exe = shutil.which("rosmaster")
    if exe is None:
        raise RosUnavailableError(f"no rosmaster; on Debian: apt-get install {DEBIAN_PACKAGES}")
    port = free_port()
    uri = f"http://127.0.0.1:{port}/"
    env = {**os.environ, "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "127.0.0.1"}
    proc = subprocess.Popen(
        [exe, "--core", "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + start_timeout
        while True:
            try:
                xmlrpc.client.ServerProxy(uri).getPid("/snnkart")
                break
            except OSError:
                if time.monotonic() > deadline or proc.poll() is not None:
                    raise RosUnavailableError("rosmaster did not start") from None
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
    """The environment of a process that talks to the master at ``uri``."""
    return {
        **os.environ,
        "ROS_MASTER_URI": uri,
        "ROS_HOSTNAME": "127.0.0.1",
        "SDL_VIDEODRIVER": "dummy",
    }
