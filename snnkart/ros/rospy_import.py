"""Import ROS 1's Python packages (Debian's, for the system Python) into snnkart's Python.

Debian's ``python3-rospy`` and the message packages live in ``/usr/lib/python3/dist-packages``.
They are pure Python and work from the project's Python 3.10 when that directory is *appended*
to ``sys.path``, after the project's own site-packages, so numpy, torch and everything else
still come from the project's environment (prepending it would shadow them). This happens only
here, when the ROS bridge is used, never for the whole environment.
"""

from __future__ import annotations

import sys
from types import ModuleType

from snnkart.errors import SnnkartError

ROS_DIST_PACKAGES = "/usr/lib/python3/dist-packages"
DEBIAN_PACKAGES = (
    "python3-rospy python3-rosmaster python3-sensor-msgs python3-geometry-msgs python3-nav-msgs"
)


class RosUnavailableError(SnnkartError, RuntimeError):
    """ROS 1's Python packages are not installed."""


def import_ros() -> dict[str, ModuleType]:
    """rospy and the message modules the bridge uses, or a clear error saying what to install."""
    if ROS_DIST_PACKAGES not in sys.path:
        sys.path.append(ROS_DIST_PACKAGES)
    try:
        import rospy
        from geometry_msgs import msg as geometry_msgs
        from nav_msgs import msg as nav_msgs
        from rosgraph_msgs import msg as rosgraph_msgs
        from sensor_msgs import msg as sensor_msgs
    except ImportError as exc:
        raise RosUnavailableError(
            f"ROS 1 is not installed ({exc}); on Debian: apt-get install {DEBIAN_PACKAGES}"
        ) from exc
    return {
        "rospy": rospy,
        "sensor_msgs.msg": sensor_msgs,
        "nav_msgs.msg": nav_msgs,
        "geometry_msgs.msg": geometry_msgs,
        "rosgraph_msgs.msg": rosgraph_msgs,
    }


def check_master() -> str:
    """The master's URI (``ROS_MASTER_URI``), or a clear error if none answers there: rospy's
    ``init_node`` would otherwise wait for one forever."""
    import os
    import socket
    import xmlrpc.client

    uri = os.environ.get("ROS_MASTER_URI", "http://localhost:11311/")
    previous = socket.getdefaulttimeout()
    socket.setdefaulttimeout(3.0)
    try:
        xmlrpc.client.ServerProxy(uri).getPid("/snnkart")
    except (OSError, xmlrpc.client.Error) as exc:
        raise RosUnavailableError(
            f"no rosmaster reachable at {uri} ({exc}); start one (rosmaster --core -p PORT) and "
            "set ROS_MASTER_URI to it"
        ) from exc
    finally:
        socket.setdefaulttimeout(previous)
    return uri


def init_node(name: str) -> ModuleType:
    """rospy, with this process's node started on the running master."""
    check_master()
    rospy = import_ros()["rospy"]
    rospy.init_node(name, anonymous=True, disable_signals=True)
    return rospy
