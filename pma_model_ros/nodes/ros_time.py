"""Conversions between ROS time messages and seconds."""

from __future__ import annotations

from rclpy.node import Node


def now_seconds(node: Node) -> float:
    """The node clock (ROS time; sim time with use_sim_time) in seconds."""
    return node.get_clock().now().nanoseconds * 1e-9
