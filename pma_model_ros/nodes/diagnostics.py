"""The /diagnostics message of model_node and joint_node: a status per muscle or joint, named as
diagnostic_updater names its tasks' statuses (``<node>: <muscle or joint>``), ``<node>`` the
node's fully qualified name without its leading slash (``left_arm/model_node``; ``model_node``
in the root namespace), so that two nodes of one name in two namespaces report distinct statuses.
"""

from __future__ import annotations

from typing import Iterable

from rclpy.node import Node

from ..wire import diagnostics


def diagnostic_array(
    node: Node, entries: Iterable[tuple[str, str, int, str, dict[str, str]]]
) -> bytes:
    """A DiagnosticArray of ``node`` stamped with its clock, serialized (publish it as it is;
    :func:`~pma_model_ros.wire.diagnostics.diagnostic_array`).

    Each entry is (name, hardware_id, level, message, values); its status is named
    ``<node>: <name>``.
    """
    return diagnostics.diagnostic_array(
        node.get_clock().now().nanoseconds, node.get_fully_qualified_name().lstrip('/'), entries
    )
