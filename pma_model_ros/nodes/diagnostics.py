"""The /diagnostics message of model_node and joint_node: a status per muscle or joint, named as
diagnostic_updater names its tasks' statuses (``<node name>: <muscle or joint>``).
"""

from __future__ import annotations

from typing import Iterable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node


def diagnostic_array(
    node: Node, entries: Iterable[tuple[str, str, int, str, dict[str, str]]]
) -> DiagnosticArray:
    """A DiagnosticArray stamped with the node clock.

    Each entry is (name, hardware_id, level, message, values); its status is named
    ``<node name>: <name>``.
    """
    full = node.get_name()
    msg = DiagnosticArray(
        status=[
            DiagnosticStatus(
                level=bytes([int(level)]),
                name=f'{full}: {name}',
                message=message,
                hardware_id=hardware_id,
                values=[KeyValue(key=key, value=value) for key, value in values.items()],
            )
            for name, hardware_id, level, message, values in entries
        ]
    )
    msg.header.stamp = node.get_clock().now().to_msg()
    return msg
