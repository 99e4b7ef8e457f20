"""Recorded rosbag2 data: read and write (mcap and sqlite3), offline estimation, replay,
calibration.

Bags are read and written with the pure-Python ``rosbags`` library and ROS 2 Jazzy's
message definitions; only :mod:`.play` needs rclpy.
"""
