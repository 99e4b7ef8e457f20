"""QoS of the nodes' topics, each overridable by ROS parameters (rclpy's QoSOverridingOptions).

Every publisher and subscription of the four nodes is created by :func:`publisher` or
:func:`subscription`, which declare for it the read-only parameters
``qos_overrides.<topic>.<publisher|subscription>.<depth|reliability>`` (``<topic>`` fully
qualified, e.g. ``/left_biceps/pressure``; rclpy's :class:`QoSOverridingOptions`), set by a
parameter file or ``-p`` and applied when the entity is created (model_node and joint_node: at
``configure``; :func:`warn_unknown_overrides` then names an override of a topic the node has
not).  The defaults are the profiles below (copied per entity: an override changes only
the entity it names).  Two policies, not rclpy's default three: ``history`` stays ``keep_last``
(``keep_all`` with a best-effort sensor stream only grows a queue), and each policy is one more
entry of ``ros2 param list`` per topic.
"""

from __future__ import annotations

import copy
from typing import Callable, Iterable

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import qos_profile_sensor_data, QoSPolicyKind, QoSProfile
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.subscription import Subscription

from ..core.hints import did_you_mean

#: The prefix of the QoS override parameters (rclpy's).
PREFIX = 'qos_overrides.'

OVERRIDABLE = QoSOverridingOptions([QoSPolicyKind.DEPTH, QoSPolicyKind.RELIABILITY])
#: Inputs of sensors: sensor-data QoS (best effort, volatile) with a queue of 100 instead of 5 (0.1
#: s at 1 kHz): a briefly stalled node catches up, and inputs older than max_input_age are counted
#: stale (ERROR) instead of being dropped unseen.  Reliable publishers match it too.
SENSOR_INPUT = QoSProfile(
    depth=100,
    reliability=qos_profile_sensor_data.reliability,
    durability=qos_profile_sensor_data.durability,
    history=qos_profile_sensor_data.history,
)
SENSOR_OUTPUT = qos_profile_sensor_data  #: the simulators' measurements
RELIABLE = QoSProfile(depth=10)  #: commands, estimates, /diagnostics


def publisher(node: Node, msg_type, topic: str, qos: QoSProfile) -> Publisher:
    """``node``'s publisher of ``topic`` with ``qos`` as overridden by its parameters."""
    return node.create_publisher(
        msg_type, topic, copy.copy(qos), qos_overriding_options=OVERRIDABLE
    )


def subscription(
    node: Node, msg_type, topic: str, callback: Callable, qos: QoSProfile, raw: bool = False
) -> Subscription:
    """``node``'s subscription of ``topic`` with ``qos`` as overridden by its parameters (``raw``:
    the callback takes the message bytes).
    """
    return node.create_subscription(
        msg_type, topic, callback, copy.copy(qos), raw=raw, qos_overriding_options=OVERRIDABLE
    )


def only_overrides(changes: list[Parameter]) -> bool:
    """Whether a parameter change sets QoS overrides only (declared as their entity is created),
    which the muscles' settings do not read: a node need not rebuild them (model_node at 64
    muscles spent 0.2 s of start-up rebuilding them once per override).
    """
    return all(p.name.startswith(PREFIX) for p in changes)


def warn_unknown_overrides(node: Node, overrides: Iterable[str]) -> list[str]:
    """Once the node's entities exist: one warning per name of ``overrides`` (what its parameter
    files and ``-p`` set) under ``qos_overrides.`` that no entity of the node declared (a topic
    it has not, or a policy not overridable), with the nearest declared one; the warnings.
    """
    names = [n for n in overrides if n.startswith(PREFIX) and not node.has_parameter(n)]
    declared = list(node.get_parameters_by_prefix(PREFIX[:-1])) if names else []
    warnings = [
        f"unknown parameter '{name}'{did_you_mean(name, [PREFIX + d for d in declared])}: ignored"
        for name in sorted(names)
    ]
    for line in warnings:
        node.get_logger().warning(line)
    return warnings
