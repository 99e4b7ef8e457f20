"""Conversions between ROS time messages and seconds."""
from __future__ import annotations

from builtin_interfaces.msg import Time
from rclpy.node import Node


def seconds(stamp: Time) -> float:
    """A header stamp in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def now_seconds(node: Node) -> float:
    """The node clock (ROS time; sim time with use_sim_time) in seconds."""
    return node.get_clock().now().nanoseconds * 1e-9
