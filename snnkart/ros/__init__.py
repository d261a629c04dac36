"""The robotics bridge: drive a differential-drive robot with a deployed policy over ROS.

:mod:`snnkart.ros.convert` turns messages into the gazebo env's observation and actions into
velocity setpoints, independent of any ROS version (plain numbers in, plain numbers out); the
node adapters are thin. Nothing here imports rospy at import time.
"""
