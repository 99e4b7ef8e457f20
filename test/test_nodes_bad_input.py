"""Bad parameter files end model_node with one clear line; bad messages are refused and reported."""
import math
import subprocess

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS
from node_messages import AMBIENT, JOINT, pressure, stamp_key, state
from pma_model_ros import node_process

pytestmark = pytest.mark.ros

GOOD = CONFIGS['DMSP-10-250'].read_text()
#: name: (parameter file text, words the one error line must contain)
BAD_FILES = {
    'missing key': (GOOD.replace('inner_diameter: 0.01, ', ''), "'muscle.inner_diameter' is not set"),
    'wrong type': (GOOD.replace('nominal_length: 0.25', 'nominal_length: long'), 'muscle.nominal_length'),
    'unknown model': (GOOD.replace('    model: martens', '    model: foo'), "parameter 'model': unknown model 'foo'"),
    'negative geometry': (GOOD.replace('inner_diameter: 0.01', 'inner_diameter: -0.01'), 'muscle.inner_diameter'),
    'wrong parameter count': (GOOD.replace('params: [116867130.487, ', 'params: ['), "model 'martens' needs 5"),
    'yaml list': ('- a\n- b\n', 'params file'),
    'yaml scalar': ('42\n', "'muscle.name' is not set"),
}


@pytest.mark.parametrize('case', BAD_FILES)
def test_bad_parameter_file_fails_with_one_line(case, tmp_path, namespace):
    text, words = BAD_FILES[case]
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    proc = subprocess.run(node_process.command('model_node', namespace, path), capture_output=True, text=True,
                          timeout=60)
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert proc.returncode != 0 and len(lines) == 1, f'exit {proc.returncode}, output:\n' + '\n'.join(lines)
    assert words in lines[0] and 'Traceback' not in lines[0], lines[0]


def test_bad_command_line_value_fails_with_one_line(namespace):
    cmd = node_process.command('model_node', namespace, CONFIGS['DMSP-10-250'], {'max_input_age': -1.0})
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert proc.returncode != 0 and len(lines) == 1 and 'max_input_age' in lines[0], lines


def _bad_pressure(value):
    return lambda stamp: ('pressure', pressure(stamp, value))


def _bad_state(**fields):
    def build(stamp):
        msg = JointState(**fields)
        msg.header.stamp = stamp
        return 'muscle_state', msg
    return build


#: name: (message builder, words in the diagnostic message, counter)
BAD_MESSAGES = {
    'NaN pressure': (_bad_pressure(math.nan), 'pressure is nan', 'rejected pressure'),
    'negative pressure': (_bad_pressure(-5.0), 'negative absolute pressure', 'rejected pressure'),
    'absurd pressure': (_bad_pressure(1e9), 'absurd pressure', 'rejected pressure'),
    'NaN length': (_bad_state(name=[JOINT], position=[math.nan]), 'length nan', 'rejected muscle_state'),
    'unknown joint': (_bad_state(name=['elbow'], position=[0.23]), "joint 'DMSP-10-250' not in",
                      'rejected muscle_state'),
    'empty arrays': (_bad_state(), 'empty name or position', 'rejected muscle_state'),
    'mismatched arrays': (_bad_state(name=[JOINT, 'elbow'], position=[0.23]), 'mismatched arrays',
                          'rejected muscle_state'),
}


def test_bad_messages_are_refused_and_reported(ros, processes, namespace):
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'])
    why = lambda: processes.output(node)  # noqa: E731
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    pubs = {'pressure': ros.node.create_publisher(FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data),
            'muscle_state': ros.node.create_publisher(JointState, f'{namespace}/muscle_state',
                                                      qos_profile_sensor_data)}

    def ours():
        return [s for d in diagnostics for s in d.status if s.name.startswith(f'{namespace}/model_node')]

    def publish_good():
        stamp = ros.now().to_msg()
        pubs['pressure'].publish(pressure(stamp, AMBIENT + 300e3))
        pubs['muscle_state'].publish(state(stamp, 0.23))

    ros.spin_until(lambda: estimates, 30, 'a first estimate from good input', every=publish_good, diagnose=why)
    bad_stamps = set()
    for case, (build, words, counter) in BAD_MESSAGES.items():
        before = len(ours())

        def publish_bad():
            stamp = ros.now().to_msg()
            topic, msg = build(stamp)
            bad_stamps.add(stamp.sec * 10**9 + stamp.nanosec)
            pubs[topic].publish(msg)

        def reported():
            return any(s.level == DiagnosticStatus.ERROR and words in s.message
                       and int(dict((kv.key, kv.value) for kv in s.values).get(counter, 0)) > 0
                       for s in ours()[before:])

        ros.spin_until(reported, 10, f'/diagnostics ERROR "{words}" for {case}', every=publish_bad, diagnose=why)
        assert node.poll() is None, f'model_node died on {case}\n{why()}'
    assert all(math.isfinite(e.wrench.force.x) for e in estimates)
    assert not bad_stamps & {stamp_key(e) for e in estimates}, 'an estimate carries the stamp of a bad message'
