"""One model_node serving several muscles (config/example_multi_muscle.yaml), over DDS, in both
input modes.
"""

import subprocess

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
import pytest
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from conftest import REPO
from node_messages import AMBIENT, pressure, state, status_prefix
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.tools import node_process

pytestmark = pytest.mark.ros

EXAMPLE = REPO / 'config' / 'example_multi_muscle.yaml'
#: muscle: (its shipped single-muscle file, gauge pressure [Pa], length [m], length rate [m/s])
INPUTS = {
    'biceps': ('dmsp_20_300', 400e3, 0.26, 0.0),
    'triceps': ('dmsp_20_300', 250e3, 0.28, -0.02),
    'wrist_flexor': ('dmsp_10_250', 500e3, 0.23, 0.01),
    'finger': ('dmsp_10_100', 600e3, 0.095, 0.01),
}


def expected_forces() -> dict[str, float]:
    """Each muscle's force from its own single-muscle file and model, with the core."""
    example = read_parameters(EXAMPLE)
    # a muscle held at one length has not moved: a hysteresis branch is unknown (branch 0),
    # whatever its rate
    return {
        name: float(
            muscle_model(read_parameters(REPO / 'config' / f'{cfg}.yaml'), example[name]['model'])
            .force(p, L, 0.0)
            .force
        )
        for name, (cfg, p, L, rate) in INPUTS.items()
    }


def test_example_blocks_are_the_shipped_muscles():
    example = read_parameters(EXAMPLE)
    assert example['muscles'] == list(INPUTS)
    for name, (cfg, *_) in INPUTS.items():
        shipped = read_parameters(REPO / 'config' / f'{cfg}.yaml')
        for key in ('muscle', 'length_range', 'pressure_range', 'models'):
            assert example[name][key] == shipped[key], (name, key)
    assert expected_forces()['triceps'] > 0 and len(set(expected_forces().values())) == 4


def joint_states(stamp, names, values, rates=()):
    msg = JointState(name=list(names), position=list(values), velocity=list(rates))
    msg.header.stamp = stamp
    return msg


def combined_inputs(ros, namespace, skip_state: str = ''):
    """A function publishing muscle_pressures and muscle_states (names in different orders)."""
    pressures = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_pressures', qos_profile_sensor_data
    )
    states = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_states', qos_profile_sensor_data
    )

    def publish():
        stamp = ros.now().to_msg()
        pressures.publish(
            joint_states(stamp, INPUTS, [AMBIENT + p for _, p, _, _ in INPUTS.values()])
        )
        order = [name for name in reversed(INPUTS) if name != skip_state]
        states.publish(
            joint_states(
                stamp, order, [INPUTS[n][2] for n in order], [INPUTS[n][3] for n in order]
            )
        )

    return publish


def test_combined_mode_estimates_every_muscle_as_its_own_file(ros, processes, namespace):
    node = processes.node('model_node', namespace, EXAMPLE)
    estimates = ros.collect(JointState, f'{namespace}/force_estimates')
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    expected = expected_forces()
    why = lambda: processes.output(node)  # noqa: E731

    def matches() -> bool:
        return (
            bool(estimates)
            and list(estimates[-1].name) == list(INPUTS)
            and all(
                f == pytest.approx(expected[n], rel=1e-9, abs=1e-9)
                for n, f in zip(estimates[-1].name, estimates[-1].effort)
            )
        )

    ros.spin_until(
        matches,
        30,
        f'force_estimates equal to {expected}',
        every=combined_inputs(ros, namespace),
        diagnose=lambda: f'last: {estimates[-1:]}\n{why()}',
    )
    ours = status_prefix(namespace)
    ros.spin_until(
        lambda: any(len(d.status) == 4 and d.status[0].name.startswith(ours) for d in diagnostics),
        10,
        'one DiagnosticArray with a status per muscle',
        every=combined_inputs(ros, namespace),
        diagnose=why,
    )


def test_combined_state_without_one_muscle_rejects_only_it(ros, processes, namespace):
    node = processes.node('model_node', namespace, EXAMPLE)
    estimates = ros.collect(JointState, f'{namespace}/force_estimates')
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    ours = status_prefix(namespace)
    publish = combined_inputs(ros, namespace, skip_state='finger')

    def reported() -> bool:
        statuses = {s.name.removeprefix(ours): s for d in diagnostics[-1:] for s in d.status}
        return (
            set(statuses) == set(INPUTS)
            and statuses['finger'].level == DiagnosticStatus.ERROR
            and "joint 'finger' not in" in statuses['finger'].message
            and all(statuses[n].level == DiagnosticStatus.OK for n in INPUTS if n != 'finger')
        )

    ros.spin_until(
        reported,
        15,
        'ERROR for finger only',
        every=publish,
        diagnose=lambda: f'{diagnostics[-1:]}\n{processes.output(node)}',
    )
    expected = expected_forces()
    assert estimates and list(estimates[-1].name) == ['biceps', 'triceps', 'wrist_flexor']
    assert list(estimates[-1].effort) == pytest.approx(
        [expected[n] for n in estimates[-1].name], rel=1e-9
    )


def test_combined_force_commands_give_pressure_commands_of_the_named_muscles(
    ros, processes, namespace
):
    node = processes.node('model_node', namespace, EXAMPLE)
    commands = ros.collect(JointState, f'{namespace}/pressure_commands')
    publisher = ros.node.create_publisher(JointState, f'{namespace}/force_commands', 10)
    inputs = combined_inputs(ros, namespace)
    wanted = {'finger': 40.0, 'triceps': 300.0}
    example = read_parameters(EXAMPLE)
    expected = {
        name: float(
            muscle_model(
                read_parameters(REPO / 'config' / f'{INPUTS[name][0]}.yaml'),
                example[name]['model'],
            )
            .pressure(force, INPUTS[name][2], 0.0)
            .pressure
        )
        + AMBIENT  # held at one length: a hysteresis branch is unknown (0)
        for name, force in wanted.items()
    }

    def publish():
        inputs()  # keeps the lengths fresh
        publisher.publish(JointState(name=list(wanted), effort=list(wanted.values())))

    ros.spin_until(
        lambda: (
            commands
            and dict(zip(commands[-1].name, commands[-1].position))
            == pytest.approx(expected, rel=1e-9)
        ),
        30,
        f'pressure_commands {expected}',
        every=publish,
        diagnose=lambda: f'last: {commands[-1:]}\n{processes.output(node)}',
    )


def test_per_muscle_mode_uses_each_muscles_topics(ros, processes, namespace):
    node = processes.node('model_node', namespace, EXAMPLE, input_mode='per_muscle')
    expected = expected_forces()
    estimates = {
        name: ros.collect(WrenchStamped, f'{namespace}/{name}/force_estimate') for name in INPUTS
    }
    pubs = {
        name: (
            ros.node.create_publisher(
                FluidPressure, f'{namespace}/{name}/pressure', qos_profile_sensor_data
            ),
            ros.node.create_publisher(
                JointState, f'{namespace}/{name}/muscle_state', qos_profile_sensor_data
            ),
        )
        for name in INPUTS
    }

    def publish():
        stamp = ros.now().to_msg()
        for name, (_, p, L, rate) in INPUTS.items():
            pubs[name][0].publish(pressure(stamp, AMBIENT + p))
            pubs[name][1].publish(state(stamp, L, rate, name=name))

    def matches() -> bool:
        return all(
            got
            and got[-1].wrench.force.x == pytest.approx(expected[n], rel=1e-9, abs=1e-9)
            and got[-1].header.frame_id == n
            for n, got in estimates.items()
        )

    ros.spin_until(
        matches,
        30,
        f'each <name>/force_estimate equal to {expected}',
        every=publish,
        diagnose=lambda: processes.output(node),
    )


GOOD = EXAMPLE.read_text()
#: name: (parameter file text, words the one error line must contain)
BAD_FILES = {
    'missing key in one block': (
        GOOD.replace('inner_diameter: 0.02, ', '', 1),
        "muscle 'biceps': parameter 'muscle.inner_diameter' is not set",
    ),
    'unknown model in one block': (
        GOOD.replace('model: hildebrandt', 'model: foo'),
        "muscle 'triceps': parameter 'model': unknown model 'foo'",
    ),
    'duplicate muscle': (
        GOOD.replace('[biceps, triceps, wrist_flexor, finger]', '[biceps, biceps]'),
        'duplicate names',
    ),
    'bad input mode': (
        GOOD.replace('input_mode: combined', 'input_mode: fast'),
        "unknown mode 'fast'",
    ),
}


@pytest.mark.parametrize('case', BAD_FILES)
def test_bad_multi_muscle_file_fails_with_one_line(case, tmp_path, namespace):
    text, words = BAD_FILES[case]
    assert text != GOOD
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    proc = subprocess.run(
        node_process.command('model_node', namespace, path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert proc.returncode == 1 and len(lines) == 1, (
        f'exit {proc.returncode}, output:\n' + '\n'.join(lines)
    )
    assert 'FATAL' in lines[0] and words in lines[0] and 'Traceback' not in lines[0], lines[0]


def test_stand_in_forward_command_controller(ros, processes, namespace):
    """model_node (a process, combined) with ``forward_command_topic`` and, in this process, a
    stand-in of ros2_control's forward_command_controller on ``<controller>/commands``: each
    Float64MultiArray holds every muscle's absolute pressure command [Pa] in the controller's
    order (``forward_command_order``), the pressures that give the wanted tensions by each
    muscle's own model, and equals the node's ``pressure_commands`` of the same force command.
    """
    from std_msgs.msg import Float64MultiArray

    from node_messages import RELIABLE_QOS

    order = ['triceps', 'finger', 'biceps', 'wrist_flexor']
    node = processes.node(
        'model_node',
        namespace,
        EXAMPLE,
        forward_command_topic='muscle_controller/commands',
        forward_command_order='[' + ', '.join(order) + ']',
    )
    controller = ros.collect(Float64MultiArray, f'{namespace}/muscle_controller/commands')
    commands = ros.collect(JointState, f'{namespace}/pressure_commands', RELIABLE_QOS)
    publisher = ros.node.create_publisher(JointState, f'{namespace}/force_commands', 10)
    inputs = combined_inputs(ros, namespace)
    wanted = {'biceps': 150.0, 'triceps': 300.0, 'wrist_flexor': 80.0, 'finger': 40.0}
    example = read_parameters(EXAMPLE)
    expected = [
        float(
            muscle_model(
                read_parameters(REPO / 'config' / f'{INPUTS[name][0]}.yaml'),
                example[name]['model'],
            )
            .pressure(wanted[name], INPUTS[name][2], 0.0)
            .pressure
        )
        + AMBIENT  # held at one length: a hysteresis branch is unknown (0)
        for name in order
    ]

    def publish():
        inputs()  # keeps the lengths fresh
        publisher.publish(JointState(name=list(wanted), effort=list(wanted.values())))

    ros.spin_until(
        lambda: len(controller) >= 3,
        30,
        'three forward commands',
        every=publish,
        diagnose=lambda: f'last: {controller[-1:]}\n{processes.output(node)}',
    )
    for message in controller:
        assert list(message.data) == pytest.approx(expected, rel=1e-9)
    ros.spin_until(lambda: len(commands) >= len(controller), 10, 'the pressure commands')
    first = dict(zip(commands[0].name, commands[0].position))
    assert list(controller[0].data) == [first[name] for name in order]
    print(f'\nstand-in controller: {len(controller)} arrays {order}: {list(controller[0].data)}')
