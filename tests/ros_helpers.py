"""The ROS tests' shared pieces: whether ROS 1 is installed, and the master (snnkart.ros.master)."""

from __future__ import annotations

import shutil

from snnkart.ros.master import ros_env, rosmaster
from snnkart.ros.rospy_import import DEBIAN_PACKAGES

ROSMASTER = shutil.which("rosmaster")
MISSING = f"optional: ROS 1 is not installed (apt-get install {DEBIAN_PACKAGES})"

__all__ = ["MISSING", "ROSMASTER", "ros_env", "rosmaster"]
