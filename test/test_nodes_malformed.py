"""Malformed message bytes at every raw subscription of model_node (both input modes) and
joint_node: thousands per topic through the callbacks in-process (a private Context), then a
few hundred per topic over DDS from a second process at live nodes, the simulators included
(their subscriptions are rclpy's own).  Nothing may crash, nothing be published from a malformed
message, each one is invalid input in ``/diagnostics``, and the next valid input is answered.
"""

from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, JointState
from test_nodes_model_node import frozen_clock
import yaml

from conftest import CONFIGS, REPO
from node_messages import (
    AMBIENT,
    big_endian,
    force_command,
    JOINT,
    malformed,
    pressure,
    raw,
    record,
    RELIABLE_QOS,
    SENSOR_QOS,
    state,
)
from pma_model_ros.core.files.joint_file import load_joints
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
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
    stamp = frozen_clock(node)  # fresh however slowly the test runs
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
    stamp = frozen_clock(node)  # fresh however slowly the test runs
    node._on_state(0, raw(state(stamp, L)))  # (the length before the fuzz is stale by now)
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + P)))
    assert [m.wrench.force.x for m in estimates] == pytest.approx(
        [float(model.force(P, L).force)], rel=1e-9
    )
    node._on_command(0, raw(force_command(50.0)))
    assert len(commands) == 1 and commands[0].fluid_pressure > AMBIENT


def test_model_node_a_known_joint_state_layout_with_no_length(private_node):
    """A muscle_state with the cached layout's names but no position (big-endian, so decoded):
    invalid input for the muscle, not a read past an empty array in the callback.
    """
    node = private_node(ModelNode, '--params-file', CONFIGS['DMSP-10-250'])
    estimates, diagnostics = record(node._estimate_pubs[0]), record(node._diag_pub)
    stamp = frozen_clock(node)  # fresh however slowly the test runs
    node._on_state(0, raw(state(stamp, L)))  # the layout of one joint, one length
    empty = state(stamp, L)
    empty.position, empty.velocity = [], []
    node._on_state(0, big_endian(empty))
    node.publish_status(node.now())
    assert errors(diagnostics) == ['invalid input: empty name or position array']
    node._on_state(0, raw(state(stamp, L)))
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + P)))
    assert len(estimates) == 1


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


# --- over DDS: a second process's publishers at live nodes
DDS_FUZZ = 300  #: malformed messages per topic over DDS


def publish_malformed(ros, ns: str, topics: dict[str, object], seed: int) -> None:
    """``DDS_FUZZ`` refused copies of each ``topics`` message (name relative to ``ns``), published
    as bytes on a reliable publisher, the test's executor spun between them.
    """
    from rclpy.qos import QoSProfile

    rng = np.random.default_rng(seed)
    for topic, msg in topics.items():
        pub = ros.node.create_publisher(type(msg), f'{ns}/{topic}', QoSProfile(depth=1000))
        ros.spin_until(lambda: pub.get_subscription_count() > 0, 20, f'a subscriber of {topic}')
        for data in malformed_like(rng, msg, DDS_FUZZ):
            pub.publish(data)
            ros.executor.spin_once(timeout_sec=0)


def stamped_now(ros, msg):
    msg.header.stamp = ros.now().to_msg()
    return msg


SCENARIOS = {
    'model_node per_muscle': (
        'model_node',
        CONFIGS['DMSP-10-250'],
        {
            'pressure': FluidPressure(fluid_pressure=AMBIENT + P),
            'muscle_state': JointState(name=[JOINT], position=[L], velocity=[0.0]),
            'force_command': force_command(50.0),
        },
        ('muscle_state', 'pressure'),
        'force_estimate',
    ),
    'model_node combined': (
        'model_node',
        MULTI,
        {
            'muscle_pressures': JointState(name=['wrist_flexor'], position=[AMBIENT + P]),
            'muscle_states': JointState(name=['wrist_flexor'], position=[L]),
            'force_commands': JointState(name=['wrist_flexor'], effort=[50.0]),
        },
        ('muscle_states', 'muscle_pressures'),
        'force_estimates',
    ),
    'joint_node': (
        'joint_node',
        JOINTS,
        {
            'flexor/pressure': FluidPressure(fluid_pressure=AMBIENT + P),
            'extensor/pressure': FluidPressure(fluid_pressure=AMBIENT + P),
            'joint_states': JointState(name=['elbow'], position=[0.5]),
            'torque_command': JointState(name=['elbow'], effort=[1.0]),
            'stiffness_command': JointState(name=['elbow'], effort=[3.0]),
            'cocontraction_command': JointState(name=['elbow'], effort=[1e5]),
        },
        ('flexor/pressure', 'extensor/pressure', 'joint_states'),
        'torque_estimate',
    ),
    'simulator_node': (
        'simulator_node',
        None,
        {'pressure_command': FluidPressure(fluid_pressure=2e5)},
        (),
        'pressure',
    ),
    'joint_simulator_node': (
        'joint_simulator_node',
        None,
        {
            'flexor/pressure_command': FluidPressure(fluid_pressure=2e5),
            'angle_command': JointState(name=['elbow'], position=[0.1]),
        },
        (),
        'joint_states',
    ),
}


@pytest.mark.ros
@pytest.mark.parametrize('scenario', SCENARIOS)
def test_live_node_survives_malformed_messages_over_dds(scenario, ros, processes, namespace):
    """The node keeps running, publishes nothing from the malformed messages, says so in
    /diagnostics (this package's estimating nodes), and answers valid input right after.
    """
    from diagnostic_msgs.msg import DiagnosticArray

    node_name, params, topics, valid, answer = SCENARIOS[scenario]
    proc = processes.node(node_name, namespace, params)
    answer_type = {'pressure': FluidPressure, 'force_estimate': WrenchStamped}.get(
        answer, JointState
    )
    answers = ros.collect(answer_type, f'{namespace}/{answer}', SENSOR_QOS)  # (any publisher)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    why = lambda: processes.output(proc)  # noqa: E731
    publish_malformed(ros, namespace, topics, SEED)
    estimating = bool(valid)
    if estimating:
        ros.spin_until(
            lambda: any(INVALID in s.message for d in diagnostics for s in d.status),
            30,
            f'{INVALID} in /diagnostics',
            diagnose=why,
        )
        assert answers == [], 'an answer from a malformed message'
    before = len(answers)
    pubs = {
        topic: ros.node.create_publisher(type(topics[topic]), f'{namespace}/{topic}', 10)
        for topic in valid
    }

    def send_valid():
        for topic in valid:
            pubs[topic].publish(stamped_now(ros, topics[topic]))

    ros.spin_until(
        lambda: len(answers) > before,
        30,
        f'{answer} after the fuzz',
        every=send_valid,
        diagnose=why,
    )
    assert proc.poll() is None, why()
