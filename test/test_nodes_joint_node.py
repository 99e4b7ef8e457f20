"""joint_node's callbacks called in-process, on a private rclpy Context: no DDS, no timing.

The node is built from the example joint file; the expected torques and stiffnesses come from the
single muscles' forces (test/test_core_joint.py checks those by hand), the pressure commands from
the core inverse.
"""

import copy
import math
import re
import subprocess
import time

import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import FluidPressure, JointState
import yaml

from conftest import REPO
from node_messages import AMBIENT, raw, record
from pma_model_ros.core.files.joint_file import load_joints
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.hysteresis import Follow
from pma_model_ros.nodes.joint_node import JointNode
from pma_model_ros.nodes.startup import StartupError
from pma_model_ros.tools import node_process

EXAMPLE = REPO / 'config' / 'example_joint.yaml'
ELBOW = load_joints(EXAMPLE)[0]
RATE = 50.0  # [Hz] of the torque commands to the stand-in forward_command_controller


@pytest.fixture
def make_node(private_node):
    """A factory of JointNodes (a joint file and parameter overrides) on their own Contexts."""

    def make(params_file=EXAMPLE, **overrides):
        return private_node(JointNode, '--params-file', params_file, overrides=overrides)

    return make


def joint_states_at(stamp, angles: dict[str, float]) -> JointState:
    msg = JointState(name=list(angles), position=list(angles.values()))
    msg.header.stamp = stamp
    return msg


def pressure_at(stamp, absolute: float) -> FluidPressure:
    msg = FluidPressure(fluid_pressure=absolute)
    msg.header.stamp = stamp
    return msg


def joint_state(node, theta, name='elbow', velocity=0.0):
    msg = JointState(name=[name], position=[theta], velocity=[velocity])
    msg.header.stamp = node.get_clock().now().to_msg()
    return msg


def pressure(node, absolute):
    msg = FluidPressure(fluid_pressure=absolute)
    msg.header.stamp = node.get_clock().now().to_msg()
    return msg


def command(**efforts):
    return JointState(name=list(efforts), effort=list(efforts.values()))


def test_estimate_is_the_worked_example(make_node):
    node = make_node()
    torques, stiffnesses = record(node._torque_pub), record(node._stiffness_pub)
    node._on_states(raw(joint_state(node, 0.5)))
    assert torques == []  # no pressures yet
    node._on_pressure(0, 0, raw(pressure(node, AMBIENT + 400e3)))  # flexor
    node._on_pressure(0, 1, raw(pressure(node, AMBIENT + 300e3)))  # extensor
    state = joint_state(node, 0.5)
    node._on_states(raw(state))
    expected = ELBOW.forward(0.5, 400e3, 300e3)
    assert torques[-1].name == ['elbow'] and torques[-1].header.stamp == state.header.stamp
    assert torques[-1].effort[0] == pytest.approx(float(expected.torque), rel=1e-9)
    assert (
        round(torques[-1].effort[0], 3) == -0.692 and round(stiffnesses[-1].effort[0], 2) == 3.84
    )
    assert stiffnesses[-1].effort[0] == pytest.approx(float(expected.stiffness), rel=1e-9)


def test_stale_pressure_gives_no_estimate_and_an_error(make_node):
    node = make_node()
    torques, diagnostics = record(node._torque_pub), record(node._diag_pub)
    old = pressure(node, AMBIENT + 400e3)
    old.header.stamp.sec -= 5
    node._on_pressure(0, 0, raw(old))
    node._on_pressure(0, 1, raw(pressure(node, AMBIENT + 300e3)))
    node._on_states(raw(joint_state(node, 0.0)))
    assert torques == []
    node.publish_status(node.now())
    status = diagnostics[-1].status[0]
    assert (status.level, status.name, status.hardware_id) == (
        b'\x02',
        'joint_node: elbow',
        '/joint_node/elbow',  # unset: instance-specific
    )
    # 5 s older than now when it was stamped, plus the time the test took since (a loaded
    # machine: some ms)
    age = re.fullmatch(
        r'stale flexor pressure: newest stamp is ([0-9.]+) s old \(max_input_age 0.1 s\)',
        status.message,
    )
    assert age is not None and 5.0 <= float(age.group(1)) < 5.5, status.message


def test_diagnostics_on_change_as_model_node_with_the_hardware_id(make_node):
    """The statuses are model_node's (texts, counters, input rates), published when a level
    changes, not only at 1 Hz; ``hardware_id`` is the joint's parameter.
    """
    node = make_node(**{'elbow.hardware_id': 'left arm, elbow valves'})
    node.engine.health.report_interval = 0  # every change at once
    diagnostics = record(node._diag_pub)
    node._on_states(raw(joint_state(node, 0.0)))
    assert [d.status[0].message for d in diagnostics] == ['no flexor pressure received yet']
    node._on_pressure(0, 0, raw(pressure(node, AMBIENT + 300e3)))
    node._on_pressure(0, 1, raw(pressure(node, AMBIENT + 300e3)))
    assert [d.status[0].message for d in diagnostics[1:]] == ['estimating']  # all inputs fresh
    node._on_states(raw(joint_state(node, 0.0)))
    assert len(diagnostics) == 2  # no change
    node.publish_status(node.now())  # the 1 Hz timer's report
    status = diagnostics[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert (status.level, status.message, status.hardware_id) == (
        b'\x00',
        'estimating',
        'left arm, elbow valves',
    )
    assert (values['received joint_states'], values['estimates']) == ('2', '1')
    assert values['joint_states: Events since startup'] == '2'


def test_torque_command_publishes_absolute_pressures_at_the_newest_angle(make_node):
    node = make_node()
    flexor, extensor = (record(p) for p in node._command_pubs[0])
    node._on_states(raw(joint_state(node, -0.3)))
    node._on_torque(raw(command(elbow=2.5)))
    expected = ELBOW.pressures_one(-0.3, 2.5, 300e3, 'min')  # the file's co-contraction
    assert flexor[-1].fluid_pressure == pytest.approx(expected.pressures[0] + AMBIENT, rel=1e-12)
    assert extensor[-1].fluid_pressure == pytest.approx(300e3 + AMBIENT, rel=1e-12)
    assert ELBOW.forward(
        -0.3, flexor[-1].fluid_pressure - AMBIENT, extensor[-1].fluid_pressure - AMBIENT
    ).torque == pytest.approx(2.5, rel=1e-9)


def test_stiffness_then_cocontraction_commands_switch_the_inverse(make_node):
    node = make_node()
    flexor, extensor = (record(p) for p in node._command_pubs[0])
    node._on_states(raw(joint_state(node, 0.2)))
    node._on_level('stiffness_command', raw(command(elbow=4.5)))
    node._on_torque(raw(command(elbow=1.0)))
    got = ELBOW.forward(
        0.2, flexor[-1].fluid_pressure - AMBIENT, extensor[-1].fluid_pressure - AMBIENT
    )
    assert (float(got.torque), float(got.stiffness)) == pytest.approx((1.0, 4.5), rel=1e-9)
    node._on_level('cocontraction_command', raw(command(elbow=400e3)))
    node._on_torque(raw(command(elbow=-1.0)))
    assert flexor[-1].fluid_pressure == pytest.approx(400e3 + AMBIENT, rel=1e-12)


def test_out_of_reach_command_saturates_and_warns(make_node):
    node = make_node()
    flexor, diagnostics = record(node._command_pubs[0][0]), record(node._diag_pub)
    node._on_pressure(0, 0, raw(pressure(node, AMBIENT + 300e3)))
    node._on_pressure(0, 1, raw(pressure(node, AMBIENT + 300e3)))
    node._on_states(raw(joint_state(node, 0.0)))
    node.publish_status(node.now())
    assert diagnostics[-1].status[0].level == b'\x00'
    node._on_torque(raw(command(elbow=100.0)))
    top = 800e3  # the rated pressure (hildebrandt is served extrapolated beyond the map's 650 kPa)
    assert flexor[-1].fluid_pressure == pytest.approx(top + AMBIENT)
    node.publish_status(node.now())
    status = diagnostics[-1].status[0]
    assert status.level == b'\x01' and 'SATURATED' in status.message


@pytest.mark.parametrize(
    'message, problem',
    [
        (JointState(name=['elbow'], position=[]), '1 names, 0 positions'),
        (JointState(name=['elbow'], position=[math.nan]), 'angle is nan rad'),
        (JointState(name=['elbow'], position=[9.0]), 'outside its geometry'),
    ],
)
def test_bad_joint_states_are_errors(make_node, message, problem):
    node = make_node()
    diagnostics = record(node._diag_pub)
    node._on_states(raw(message))
    node.publish_status(node.now())
    status = diagnostics[-1].status[0]
    assert status.level == b'\x02' and problem in status.message


def test_command_before_any_angle_and_bad_pressure_are_errors(make_node):
    node = make_node()
    diagnostics = record(node._diag_pub)
    node._on_torque(raw(command(elbow=1.0)))
    node.publish_status(node.now())
    assert 'before any angle' in diagnostics[-1].status[0].message
    node._on_pressure(0, 1, raw(pressure(node, -3.0)))
    node.publish_status(node.now())
    assert "muscle 'extensor': negative absolute pressure" in diagnostics[-1].status[0].message


def test_stale_torque_command_gives_no_pressure_command(make_node):
    """A torque_command stamped farther than max_input_age from the node clock is refused as
    stale, counted and shown; an unstamped one (zero stamp) is answered.
    """
    node = make_node()
    flexor, diagnostics = record(node._command_pubs[0][0]), record(node._diag_pub)
    node._on_states(raw(joint_state(node, 0.5)))
    old = command(elbow=1.0)
    old.header.stamp = node.get_clock().now().to_msg()
    old.header.stamp.sec -= 2
    node._on_torque(raw(old))
    assert flexor == [] and node.engine.counts(0)['stale command'] == 1
    node.publish_status(node.now())
    age = re.fullmatch(
        r'stale torque_command: stamp is ([0-9.]+) s old \(max_input_age 0.1 s\)',
        diagnostics[-1].status[0].message,
    )
    assert age is not None and 2.0 <= float(age.group(1)) < 2.5  # 2 s and the test's own time
    node._on_torque(raw(command(elbow=1.0)))
    assert len(flexor) == 1


def test_bad_parameters_fail_at_startup(make_node):
    with pytest.raises(StartupError, match="joint 'elbow': positive must name"):
        make_node(**{'elbow.positive': 'biceps'})
    with pytest.raises(StartupError, match='cocontraction_mode'):
        make_node(**{'elbow.cocontraction_mode': 'max'})


def arm_file(tmp_path, n=4):
    """A joint file of ``n`` copies of the example elbow, muscles
    ``j<k>_flexor``/``j<k>_extensor``.
    """
    elbow = read_parameters(EXAMPLE)['elbow']
    for muscle in ('flexor', 'extensor'):  # the shipped files, not beside the file in tmp_path
        elbow[muscle]['file'] = str(EXAMPLE.parent / elbow[muscle]['file'])
    joints = {}
    for k in range(n):
        joints[f'j{k}'] = {
            key: copy.deepcopy(v) for key, v in elbow.items() if key not in ('flexor', 'extensor')
        } | {
            'muscles': [f'j{k}_flexor', f'j{k}_extensor'],
            'positive': f'j{k}_flexor',
            f'j{k}_flexor': dict(elbow['flexor']),
            f'j{k}_extensor': dict(elbow['extensor']),
        }
    path = tmp_path / 'arm.yaml'
    path.write_text(
        yaml.safe_dump({'/**': {'ros__parameters': {'joints': list(joints), **joints}}})
    )
    return path


def test_four_joints_answer_one_joint_states_with_one_message_each(make_node, tmp_path):
    node = make_node(params_file=arm_file(tmp_path))
    torques, stiffnesses = record(node._torque_pub), record(node._stiffness_pub)
    pressures = [(100e3 * (k + 2), 100e3 * (5 - k)) for k in range(4)]
    for k, pair in enumerate(pressures):
        for m in (0, 1):
            node._on_pressure(k, m, raw(pressure(node, AMBIENT + pair[m])))
    angles = [-0.6, -0.2, 0.2, 0.6]
    msg = JointState(
        name=['j3', 'j0', 'j2', 'j1'],
        position=[angles[3], angles[0], angles[2], angles[1]],
        velocity=[0.0] * 4,
    )
    msg.header.stamp = node.get_clock().now().to_msg()
    node._on_states(raw(msg))
    assert len(torques) == 1 and torques[0].name == msg.name  # in the order of joint_states
    for k in range(4):
        expected, i = ELBOW.forward(angles[k], *pressures[k]), msg.name.index(f'j{k}')
        assert torques[0].effort[i] == pytest.approx(float(expected.torque), rel=1e-9)
        assert stiffnesses[0].effort[i] == pytest.approx(float(expected.stiffness), rel=1e-9)
    msg.name, msg.position = ['j0', 'j1', 'j2', 'j3'], angles  # the node's order: prebuilt
    node._on_states(raw(msg))
    assert torques[1].name == msg.name and torques[1].effort == pytest.approx(
        [float(ELBOW.forward(angles[k], *pressures[k]).torque) for k in range(4)], rel=1e-9
    )


def test_hysteresis_branches_follow_the_muscle_lengths_not_the_velocity(make_node, tmp_path):
    """Two DMSP-10-100 (sarosi_hysteresis) on a 10 mm pulley, by a muscle file whose
    ``hysteresis`` mapping (1 mm deadband) reaches the node; after θ rose 0 → 0.2 rad (muscle a
    shortened 2 mm: branch -1, b +1) joint_states within ±0.04 mm and with velocities of
    alternating sign keep both branches.
    """
    single = read_parameters(REPO / 'config' / 'dmsp_10_100.yaml')
    single['hysteresis'] = {'length_deadband': 0.001}
    (tmp_path / 'finger.yaml').write_text(yaml.safe_dump({'/**': {'ros__parameters': single}}))
    muscle = {'file': 'finger.yaml', 'length_at_zero': 0.0875}
    finger = {'radius': [0.01], 'limits': [-1.0, 1.0], 'muscles': ['a', 'b'], 'positive': 'a'}
    path = tmp_path / 'joint.yaml'
    path.write_text(
        yaml.safe_dump(
            {
                '/**': {
                    'ros__parameters': {
                        'joints': ['finger'],
                        'finger': finger | {'a': muscle, 'b': dict(muscle)},
                    }
                }
            }
        )
    )
    node = make_node(params_file=path, config_dir=str(tmp_path))
    assert node.engine.joints[0].follows == (Follow('length', 0.001),) * 2
    torques = record(node._torque_pub)
    node._on_pressure(0, 0, raw(pressure(node, AMBIENT + 600e3)))
    node._on_pressure(0, 1, raw(pressure(node, AMBIENT + 500e3)))
    node._on_states(raw(joint_state(node, 0.0, 'finger')))
    angles = [0.2] + [0.2 + 0.004 * (-1) ** k for k in range(20)]
    for k, theta in enumerate(angles):
        node._on_states(raw(joint_state(node, theta, 'finger', velocity=(-1) ** k * 0.5)))
    sarosi = muscle_model(single)
    expected = [
        0.01
        * (
            float(sarosi.force(600e3, 0.0875 - 0.01 * theta, -1.0).force)
            - float(sarosi.force(500e3, 0.0875 + 0.01 * theta, 1.0).force)
        )
        for theta in angles
    ]
    assert [t.effort[0] for t in torques[1:]] == pytest.approx(expected, rel=1e-9)


def test_parameters_are_read_only(make_node):
    """joint_node reads its parameters at start-up: every one says so and refuses a change."""
    node = make_node()
    ours = [name for name in node.get_parameters_by_prefix('') if name != 'use_sim_time']
    assert ours and all(d.read_only for d in node.describe_parameters(ours))
    result = node.set_parameters([Parameter('elbow.cocontraction', value=200e3)])[0]
    assert not result.successful and 'read-only' in result.reason
    assert node.get_parameter('elbow.cocontraction').value == 300e3


def test_a_new_declaration_is_no_change(make_node):
    """A parameter declared after the node is built (by code that adds to the node) is accepted
    as no change of the joints.
    """
    node = make_node()
    assert node.declare_parameter('added_later', 'events').value == 'events'


def test_without_config_dir_muscle_files_are_the_shipped_ones(make_node, monkeypatch, tmp_path):
    """``config_dir`` unset: relative muscle files are found in the package's share directory,
    whatever the working directory.
    """
    monkeypatch.chdir(tmp_path)
    node = make_node()
    for muscle, expected in zip(node.engine.joints[0].muscles, ELBOW.muscles):
        assert (muscle.spec, muscle.model, muscle.domain) == (
            expected.spec,
            expected.model,
            expected.domain,
        )
        assert muscle.theta.tolist() == expected.theta.tolist()


def test_relative_muscle_files_are_found_beside_the_joint_file(make_node, monkeypatch, tmp_path):
    """``config_dir`` unset, the node started with a joint file (its ``--params-file``): a
    relative muscle file is found beside it, as ``pma-model joint`` finds it (the muscle there
    is a DMSP-20-300, not the shipped DMSP-10-250 of the name it is given).
    """
    (tmp_path / 'dmsp_10_250.yaml').write_text((REPO / 'config' / 'dmsp_20_300.yaml').read_text())
    path = tmp_path / 'elbow.yaml'
    path.write_text(EXAMPLE.read_text())
    monkeypatch.setattr('sys.argv', ['joint_node', '--ros-args', '--params-file', str(path)])
    node = make_node(params_file=path)
    assert [m.spec.name for m in node.engine.joints[0].muscles] == ['DMSP-20-300'] * 2
    assert [m.spec for m in node.engine.joints[0].muscles] == [
        m.spec for m in load_joints(path)[0].muscles
    ]


def test_process_with_a_bad_file_exits_1_with_one_line(tmp_path):
    """A muscle file that is not in ``config_dir``: one line naming the joint, muscle and file."""
    proc = subprocess.run(
        [
            *node_process.command('joint_node', '/bad_joint', EXAMPLE),
            '-p',
            f'config_dir:={tmp_path}',
        ],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert proc.returncode == 1
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    assert (
        len(lines) == 1
        and "joint 'elbow', muscle 'flexor'" in lines[0]
        and 'dmsp_10_250.yaml' in lines[0]
    )


def test_gauge_pressure_reference_reads_and_commands_gauge_pressures(make_node):
    """``pressure_reference: gauge``: the worked example's torque from gauge readings, and torque
    commands in gauge pressure (the absolute node's less the ambient pressure).
    """
    commanded = {}
    for reference, offset in (('absolute', AMBIENT), ('gauge', 0.0)):
        node = make_node(pressure_reference=reference)
        torques, flexor = record(node._torque_pub), record(node._command_pubs[0][0])
        node._on_pressure(0, 0, raw(pressure(node, offset + 400e3)))
        node._on_pressure(0, 1, raw(pressure(node, offset + 300e3)))
        node._on_states(raw(joint_state(node, 0.5)))
        assert torques[-1].effort[0] == pytest.approx(-0.691819, abs=5e-6)  # docs/joints.md
        node._on_torque(raw(command(elbow=1.0)))
        commanded[reference] = flexor[-1].fluid_pressure
    assert commanded['gauge'] == pytest.approx(574986, abs=1)  # docs/joints.md: flexor, gauge
    assert commanded['absolute'] - commanded['gauge'] == pytest.approx(AMBIENT, rel=1e-12)


def test_identification_results_are_values_of_the_joint_status(make_node):
    """Each muscle's results of its model (the example: hildebrandt of config/dmsp_10_250.yaml)."""
    node = make_node()
    diagnostics = record(node._diag_pub)
    node.publish_status(node.now())
    values = {kv.key: kv.value for kv in diagnostics[-1].status[0].values}
    err = read_parameters(REPO / 'config' / 'dmsp_10_250.yaml')['models']['hildebrandt']['err']
    for muscle in ('flexor', 'extensor'):
        assert values[f'{muscle} identification err [% of max force]'] == f'{err:.6g}'


def test_forward_commands_are_the_pressure_commands_in_the_configured_order(make_node, tmp_path):
    """One Float64MultiArray per torque command, in ``forward_command_order``, each value the
    muscle's ``pressure_command`` (absolute Pa here, gauge with ``pressure_reference: gauge``);
    nothing until every muscle had a command, then the others' last values.
    """
    order = ['j1_extensor', 'j0_flexor', 'j1_flexor', 'j0_extensor']
    for reference in ('absolute', 'gauge'):
        node = make_node(
            arm_file(tmp_path, 2),
            forward_command_topic='pressure_controller/commands',
            forward_command_order=order,
            pressure_reference=reference,
        )
        assert node._forward_pub.topic_name == '/pressure_controller/commands'
        forward = record(node._forward_pub)
        sent = {
            muscle: record(node._command_pubs[k][i])
            for k, joint in enumerate(node.engine.joints)
            for i, muscle in enumerate(joint.muscle_names)
        }
        node._on_states(raw(JointState(name=['j0', 'j1'], position=[0.2, -0.3])))
        node._on_torque(raw(command(j0=1.0)))
        assert forward == []  # j1 never commanded
        expected = []
        for efforts in ({'j0': 0.5, 'j1': -1.0}, {'j1': -0.5}):  # the second: j0's values held
            node._on_torque(raw(command(**efforts)))
            expected.append([sent[m][-1].fluid_pressure for m in order])
        assert [list(message.data) for message in forward] == expected
        assert expected[0][::2] != expected[1][::2]  # j1's changed (j0's: held, by the line above)
        offset = AMBIENT if reference == 'absolute' else 0.0
        assert all(offset <= v <= offset + 800e3 for v in expected[1]), expected[1]


@pytest.mark.parametrize(
    'order, words',
    [
        (['j0_flexor', 'j0_flexr'], "'j0_flexr' is no muscle of the joints (did you mean"),
        (['j0_flexor', 'j0_flexor'], 'a muscle named twice'),
    ],
)
def test_a_bad_forward_command_order_fails_configure(make_node, tmp_path, order, words):
    with pytest.raises(StartupError, match=re.escape(words)):
        make_node(
            arm_file(tmp_path, 2), forward_command_topic='c/commands', forward_command_order=order
        )


@pytest.mark.ros
def test_stand_in_forward_command_controller(ros, processes, namespace, tmp_path):
    """joint_node (a process) and, in this process, a stand-in of ros2_control's
    forward_command_controller subscribed to ``<controller>/commands``: one Float64MultiArray per
    torque command (the rate of the commands), every value in the controller's order, each the
    muscle's absolute pressure command [Pa] of the same torque command; nothing until every muscle
    had a command; a command of one joint repeats the other's last values.
    """
    from std_msgs.msg import Float64MultiArray

    from node_messages import RELIABLE_QOS

    order = ['j1_extensor', 'j0_flexor', 'j1_flexor', 'j0_extensor']
    # queues deep enough for a node process stalled a while on a loaded machine (a depth of 10
    # lost commands there): the QoS overrides of nodes/qos.py
    deep = {
        f'qos_overrides.{namespace}/{topic}.depth': 1000
        for topic in (
            'torque_command.subscription',
            'pressure_controller/commands.publisher',
            *(f'{m}/pressure_command.publisher' for m in order),
        )
    }
    proc = processes.node(
        'joint_node',
        namespace,
        arm_file(tmp_path, 2),
        forward_command_topic='pressure_controller/commands',
        forward_command_order='[' + ', '.join(order) + ']',
        **deep,
    )
    why = lambda: processes.output(proc)  # noqa: E731
    controller, arrivals = [], []  # the stand-in controller's messages, their arrival [s]
    ros.node.create_subscription(
        Float64MultiArray,
        f'{namespace}/pressure_controller/commands',
        lambda msg: (controller.append(msg), arrivals.append(time.monotonic())),
        RELIABLE_QOS,
    )
    commands = {
        m: ros.collect(FluidPressure, f'{namespace}/{m}/pressure_command', RELIABLE_QOS)
        for m in order
    }
    estimates = ros.collect(JointState, f'{namespace}/torque_estimate', RELIABLE_QOS)
    states = ros.node.create_publisher(JointState, f'{namespace}/joint_states', RELIABLE_QOS)
    pressures = {
        m: ros.node.create_publisher(FluidPressure, f'{namespace}/{m}/pressure', RELIABLE_QOS)
        for m in order
    }
    torques = ros.node.create_publisher(JointState, f'{namespace}/torque_command', RELIABLE_QOS)
    sent = []

    def angles():
        """Both joints' angles, with their four muscles' pressures (fresh: estimates follow)."""
        stamp = ros.now().to_msg()
        for pub in pressures.values():
            pub.publish(pressure_at(stamp, AMBIENT + 300e3))
        states.publish(joint_states_at(stamp, {'j0': 0.2, 'j1': -0.3}))

    def send(**efforts):
        torques.publish(command(**efforts))
        sent.append(efforts)

    ros.spin_until(
        lambda: any(list(e.name) == ['j0', 'j1'] for e in estimates),
        20,
        'both angles known (an estimate of both joints)',
        every=angles,
        diagnose=why,
    )
    # one command of j0 alone: its muscles are commanded, the controller gets nothing (j1 unknown)
    send(j0=1.0)
    ros.spin_until(lambda: commands['j0_flexor'], 10, 'the j0 command', diagnose=why)
    end = time.monotonic() + 0.5
    ros.spin_until(lambda: time.monotonic() > end, 5, 'quiet')
    assert controller == [], 'a forward command before every muscle had a command'
    # both joints at RATE: one array per command, in the controller's order
    start = {m: len(c) for m, c in commands.items()}
    sent.clear()
    began = time.monotonic()
    end = began + 2.0
    ros.spin_until(
        lambda: time.monotonic() > end,
        10,
        'two seconds of torque commands',
        every=lambda: send(j0=0.2 + 0.01 * len(sent), j1=-0.2 - 0.01 * len(sent)),
        period=1 / RATE,
    )
    count, sending = len(sent), time.monotonic() - began
    ros.spin_until(
        lambda: len(controller) >= count,
        10,
        f'{count} forward commands',
        diagnose=lambda: (
            f'{len(controller)} arrays, pressure commands since '
            f'{ {m: len(c) - start[m] for m, c in commands.items()} }\n{why()}'
        ),
    )
    ros.spin_until(
        lambda: all(len(c) >= start[m] + count for m, c in commands.items()),
        10,
        'every pressure command',
        diagnose=why,
    )
    assert len(controller) == count, (len(controller), count)
    receiving = (count - 1) / (arrivals[count - 1] - arrivals[0])  # [Hz], shown
    for k, message in enumerate(controller):
        expected = [commands[m][start[m] + k].fluid_pressure for m in order]
        assert list(message.data) == expected, k
        assert all(AMBIENT < v <= AMBIENT + 800e3 for v in message.data), message.data  # rated
    # j1 alone: j0's last values held
    last = list(controller[-1].data)
    send(j1=0.4)
    ros.spin_until(
        lambda: len(controller) > count, 10, 'the j1-only forward command', diagnose=why
    )
    held = list(controller[-1].data)
    assert (held[1], held[3]) == (last[1], last[3]) and (held[0], held[2]) != (last[0], last[2])
    print(
        f'\nstand-in controller: {count} torque commands in {sending:.2f} s '
        f'({count / sending:.1f} Hz) -> {count} arrays received at {receiving:.1f} Hz, each of '
        f'{len(order)} values ({", ".join(order)}) equal to the pressure commands, e.g. '
        f'{[round(v) for v in controller[0].data]} Pa absolute; none before both joints were '
        'commanded; j1 alone: j0 held'
    )


def test_forward_commands_without_an_order_come_in_the_default_order(make_node, tmp_path):
    """An empty ``forward_command_order`` (its default) means every muscle, joint by joint, the
    positive one first: the node starts with only ``forward_command_topic`` set.
    """
    node = make_node(arm_file(tmp_path, 2), forward_command_topic='pressure_controller/commands')
    assert node.get_parameter('forward_command_order').value == []
    forward = record(node._forward_pub)
    order = [m for joint in node.engine.joints for m in joint.muscle_names]
    sent = {
        muscle: record(node._command_pubs[k][i])
        for k, joint in enumerate(node.engine.joints)
        for i, muscle in enumerate(joint.muscle_names)
    }
    node._on_states(raw(JointState(name=['j0', 'j1'], position=[0.2, -0.3])))
    node._on_torque(raw(command(j0=0.5, j1=-1.0)))
    assert [list(m.data) for m in forward] == [[sent[m][-1].fluid_pressure for m in order]]


def test_an_empty_array_default_is_declared_typed(make_node):
    """A parameter whose default is ``[]`` is declared with that value (not left unset), and a
    value of another type is refused.
    """
    node = make_node()
    assert node.get_parameter('forward_command_order').value == []
    with pytest.raises(StartupError, match='must be of type STRING_ARRAY, got INTEGER'):
        make_node(forward_command_order=3)


def test_pressures_of_one_joint_state_give_the_worked_example(make_node):
    """``pressure_input: joint_state``: the muscles' pressures in one ``muscle_pressures``
    JointState (joint_state_broadcaster's message: every joint of the robot, the angle and each
    muscle's ``pressure`` interface mapped to ``position``), absolute or gauge by
    ``pressure_reference``, or in the ``pressure_field`` named; the per-muscle topics are gone.
    The same message as ``joint_states`` too: docs/joints.md's worked example, -0.692 N·m.
    """
    expected = ELBOW.forward(0.5, 400e3, 300e3)
    for reference, offset, field in (
        ('absolute', AMBIENT, 'position'),
        ('gauge', 0.0, 'position'),
        ('absolute', AMBIENT, 'effort'),
    ):
        node = make_node(
            pressure_input='joint_state', pressure_reference=reference, pressure_field=field
        )
        topics = {s.topic_name for s in node.subscriptions}
        assert '/muscle_pressures' in topics and '/flexor/pressure' not in topics, topics
        torques = record(node._torque_pub)
        pressures = [0.5, offset + 300e3, offset + 400e3]  # elbow's angle first
        msg = JointState(name=['elbow', 'extensor', 'flexor'], position=pressures)
        if field == 'effort':  # the positions no pressures: the efforts'
            msg.position, msg.effort = [0.5, 1e9, 1e9], [0.0, *pressures[1:]]
        msg.header.stamp = node.get_clock().now().to_msg()
        node._on_pressures(raw(msg))
        node._on_states(raw(msg))
        assert torques[-1].name == ['elbow'], (reference, field)
        assert torques[-1].effort[0] == pytest.approx(float(expected.torque), rel=1e-9)
        assert round(torques[-1].effort[0], 3) == -0.692


def test_a_pressure_joint_state_without_a_muscle_is_an_error_naming_it(make_node):
    """A ``muscle_pressures`` lacking the extensor: the flexor's pressure is taken, the joint's
    status is ERROR naming the missing entry, and no estimate is made without it.
    """
    node = make_node(pressure_input='joint_state')
    torques, diagnostics = record(node._torque_pub), record(node._diag_pub)
    msg = JointState(name=['flexor'], position=[AMBIENT + 400e3])
    msg.header.stamp = node.get_clock().now().to_msg()
    node._on_pressures(raw(msg))
    node._on_states(raw(joint_state(node, 0.5)))
    assert torques == []
    node.publish_status(node.now())
    status = diagnostics[-1].status[0]
    assert status.level == b'\x02' and "'extensor' not in ['flexor']" in status.message, status
    values = {v.key: v.value for v in status.values}
    assert values['received pressure'] == '2' and values['rejected pressure'] == '1', values


def test_a_bad_pressure_input_fails_configure(make_node):
    with pytest.raises(StartupError, match="unknown input 'joint_states'; one of per_muscle"):
        make_node(pressure_input='joint_states')


@pytest.mark.ros
def test_stand_in_joint_state_broadcaster(ros, processes, namespace, tmp_path):
    """joint_node (a process) with ``pressure_input: joint_state``, ``muscle_pressures`` remapped
    to ``joint_states``, and in this process a stand-in of ros2_control's joint_state_broadcaster:
    one JointState per cycle with both joints' angles and the four muscles' pressures (their
    ``pressure`` state interfaces in ``position``).  Each torque estimate is the joints' forward
    model at the pressures of that message.
    """
    from node_messages import RELIABLE_QOS

    path = arm_file(tmp_path, 2)  # two copies of the example elbow
    proc = processes.start(
        node_process.command(
            'joint_node',
            namespace,
            path,
            {'pressure_input': 'joint_state', 'config_dir': str(REPO / 'config')},
        )
        + ['-r', 'muscle_pressures:=joint_states']
    )
    why = lambda: processes.output(proc)  # noqa: E731
    estimates = ros.collect(JointState, f'{namespace}/torque_estimate', RELIABLE_QOS)
    broadcaster = ros.node.create_publisher(JointState, f'{namespace}/joint_states', RELIABLE_QOS)
    names = ['j0', 'j1', 'j0_flexor', 'j0_extensor', 'j1_flexor', 'j1_extensor']
    gauges = [400e3, 300e3, 250e3, 500e3]  # [Pa]

    def broadcast():
        msg = JointState(name=names, position=[0.2, -0.3, *(AMBIENT + g for g in gauges)])
        msg.velocity = [0.0] * len(names)
        msg.effort = [0.0] * len(names)
        msg.header.stamp = ros.now().to_msg()
        broadcaster.publish(msg)

    ros.spin_until(
        lambda: any(list(e.name) == ['j0', 'j1'] for e in estimates),
        20,
        'an estimate of both joints from the broadcaster alone',
        every=broadcast,
        diagnose=why,
    )
    answer = next(e for e in estimates if list(e.name) == ['j0', 'j1'])
    for theta, (p0, p1), torque in zip((0.2, -0.3), (gauges[:2], gauges[2:]), answer.effort):
        assert torque == pytest.approx(float(ELBOW.forward(theta, p0, p1).torque), rel=1e-9)
    print(f'\nstand-in joint_state_broadcaster: torques {list(answer.effort)} N·m')
