"""Malformed message bytes at every raw subscription of model_node (both input modes) and
joint_node: thousands per topic through the callbacks in-process (a private Context), then a
few hundred per topic over DDS from a second process at live nodes, the simulators included
(their subscriptions are rclpy's own).  Nothing may crash, nothing be published from a malformed
message, each one is invalid input in ``/diagnostics``, and the next valid input is answered.
"""

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
import yaml

from conftest import CONFIGS, REPO
from node_messages import AMBIENT, force_command, malformed, pressure, raw, record, state
from pma_model_ros.core.joint_file import load_joints
from pma_model_ros.core.param_file import muscle_model, read_parameters
from pma_model_ros.nodes.joint_node import JointNode
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.wire.cdr import MALFORMED

FUZZ = 2000  #: malformed messages per topic, in-process
SEED = 20261127
P, L = 300e3, 0.234  #: valid gauge pressure [Pa] and length [m] of a DMSP-10-250
MULTI = REPO / 'config' / 'example_multi_muscle.yaml'
JOINTS = REPO / 'config' / 'example_joint.yaml'
INVALID = f'invalid input: {MALFORMED}'


def malformed_like(rng, msg, count: int = FUZZ) -> list[bytes]:
    """``count`` damaged copies of ``msg`` that rclpy's deserializer refuses."""
    return malformed(rng, serialize_message(msg), type(msg), count)


def errors(diagnostics: list) -> list[str]:
    """The messages of the ERROR statuses of the newest DiagnosticArray."""
    return [s.message for s in diagnostics[-1].status if s.level == b'\x02']


def test_model_node_per_muscle(private_node):
    node = private_node(ModelNode, '--params-file', CONFIGS['DMSP-10-250'])
    model = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'martens')
    estimates, commands = record(node._estimate_pubs[0]), record(node._command_pubs[0])
    diagnostics = record(node._diag_pub)
    rng = np.random.default_rng(SEED)
    stamp = node.get_clock().now().to_msg()
    node._on_state(0, raw(state(stamp, L)))  # a valid length: a pressure would be answered
    for callback, msg in (
        (node._on_pressure, pressure(stamp, AMBIENT + P)),
        (node._on_state, state(stamp, L)),
        (node._on_command, force_command(50.0)),
    ):
        for data in malformed_like(rng, msg):
            callback(0, data)
        node.publish_status(node.now())
        assert errors(diagnostics) == [INVALID]
    assert estimates == [] and commands == []
    stamp = node.get_clock().now().to_msg()
    node._on_state(0, raw(state(stamp, L)))  # (the length before the fuzz is stale by now)
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + P)))
    assert [m.wrench.force.x for m in estimates] == pytest.approx(
        [float(model.force(P, L).force)], rel=1e-9
    )
    node._on_command(0, raw(force_command(50.0)))
    assert len(commands) == 1 and commands[0].fluid_pressure > AMBIENT


def test_model_node_combined(private_node):
    node = private_node(ModelNode, '--params-file', MULTI)
    blocks = yaml.safe_load(MULTI.read_text())['/**']['ros__parameters']
    names = blocks['muscles']
    lengths = [blocks[n]['length_range'][1] for n in names]  # the longest: pulling at P
    estimates, commands = record(node._estimate_pubs[0]), record(node._command_pubs[0])
    diagnostics = record(node._diag_pub)
    rng = np.random.default_rng(SEED)

    def states(values, field='position'):
        msg = JointState(name=names, **{field: values})
        msg.header.stamp = node.get_clock().now().to_msg()
        return msg

    node._on_states(raw(states(lengths)))
    for callback, msg in (
        (node._on_pressures, states([AMBIENT + P] * len(names))),
        (node._on_states, states(lengths)),
        (node._on_commands, states([50.0] * len(names), 'effort')),
    ):
        for data in malformed_like(rng, msg):
            callback(data)
        node.publish_status(node.now())
        assert errors(diagnostics) == [INVALID] * len(names)
    assert estimates == [] and commands == []
    node._on_states(raw(states(lengths)))
    node._on_pressures(raw(states([AMBIENT + P] * len(names))))
    assert len(estimates) == 1 and list(estimates[0].name) == names
    assert all(f > 0 for f in estimates[0].effort)
    node._on_commands(raw(states([50.0] * len(names), 'effort')))
    assert len(commands) == 1 and all(p > AMBIENT for p in commands[0].position)


def test_joint_node(private_node):
    node = private_node(JointNode, '--params-file', JOINTS)
    elbow = load_joints(JOINTS)[0]
    torques, diagnostics = record(node._torque_pub), record(node._diag_pub)
    commands = [record(pub) for pub in node._command_pubs[0]]
    rng = np.random.default_rng(SEED)

    def joint_states(field='position', value=0.5):
        msg = JointState(name=['elbow'], **{field: [value]})
        msg.header.stamp = node.get_clock().now().to_msg()
        return msg

    stamp = node.get_clock().now().to_msg()
    for m in (0, 1):  # fresh pressures: a joint_states message would be answered
        node._on_pressure(0, m, raw(pressure(stamp, AMBIENT + P)))
    for callback, msg in (
        (lambda data: node._on_pressure(0, 0, data), pressure(stamp, AMBIENT + P)),
        (node._on_states, joint_states()),
        (node._on_torque, joint_states('effort', 1.0)),
        (lambda data: node._on_level('stiffness_command', data), joint_states('effort', 3.0)),
        (lambda data: node._on_level('cocontraction_command', data), joint_states('effort', 1e5)),
    ):
        for data in malformed_like(rng, msg, FUZZ // 2):
            callback(data)
        node.publish_status(node.now())
        assert errors(diagnostics) == [INVALID]
    assert torques == [] and commands == [[], []]
    stamp = node.get_clock().now().to_msg()
    for m, gauge in ((0, 400e3), (1, 300e3)):
        node._on_pressure(0, m, raw(pressure(stamp, AMBIENT + gauge)))
    node._on_states(raw(joint_states()))
    assert len(torques) == 1
    assert torques[0].effort[0] == pytest.approx(
        float(elbow.forward(0.5, 400e3, 300e3).torque), rel=1e-9
    )
