"""ROS time in seconds (nodes/ros_time.py): the node clock is the system clock by default."""

import time

import pytest
import rclpy

from pma_model_ros.nodes.ros_time import now_seconds


@pytest.mark.ros
def test_now_is_the_system_time_in_seconds():
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('ros_time_test', context=context)
        before, now, after = time.time(), now_seconds(node), time.time()
        assert before - 1e-3 <= now <= after + 1e-3
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
