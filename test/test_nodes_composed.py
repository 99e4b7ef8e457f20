"""pma_composed (nodes/composed.py): model_node and joint_node, and the simulators, in one process
and one executor from one parameter file (config/example_composed.yaml).
"""

import shutil
import sys

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from lifecycle_msgs.srv import GetState
import pytest
from sensor_msgs.msg import JointState
import yaml

from conftest import CONFIGS, edited_copy, lines_of_failed_start, REPO
from node_messages import RELIABLE_QOS

EXAMPLE = REPO / 'config' / 'example_composed.yaml'
EVERY_NODE = ['model_node', 'joint_node', 'simulator_node', 'joint_simulator_node']


def composed(*args: str) -> list[str]:
    return [sys.executable, '-m', 'pma_model_ros.nodes.composed', *map(str, args)]


def sections(path) -> dict:
    return {
        name: entry['ros__parameters'] for name, entry in yaml.safe_load(path.read_text()).items()
    }


def test_the_example_is_the_shipped_muscle_and_joint():
    example = sections(EXAMPLE)
    muscle = sections(CONFIGS['DMSP-10-250'])['/**']
    model = example['/**/model_node']
    assert {k: v for k, v in model.items() if k != 'models'} == {
        k: v for k, v in muscle.items() if k != 'models'
    }
    martens = muscle['models']['martens']
    assert model['models'] == {
        'martens': {'params': martens['params'], 'extrapolates': martens['extrapolates']}
    }
    assert example['/**/joint_node'] == sections(REPO / 'config' / 'example_joint.yaml')['/**']


@pytest.mark.ros
def test_every_node_comes_up_and_answers_in_one_process(ros, processes, namespace):
    """The simulators feed the two nodes inside the process: a force estimate and a torque
    estimate come out, and each managed node answers its lifecycle service, active.
    """
    proc = processes.start(
        composed(
            '--nodes',
            *EVERY_NODE,
            '--ros-args',
            '-r',
            f'__ns:={namespace}',
            '--params-file',
            EXAMPLE,
        )
    )
    why = lambda: processes.output(proc)  # noqa: E731
    forces = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    torques = ros.collect(JointState, f'{namespace}/torque_estimate', RELIABLE_QOS)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    ros.spin_until(lambda: forces and torques, 30, 'a force and a torque estimate', diagnose=why)
    for node in ('model_node', 'joint_node'):
        state = ros.call(GetState, f'{namespace}/{node}/get_state', GetState.Request())
        assert state.current_state.label == 'active', why()
    ros.spin_until(  # the graph's node names arrive by discovery, after the services may answer
        lambda: (
            {(namespace, n) for n in EVERY_NODE}
            <= {(ns, n) for n, ns in ros.node.get_node_names_and_namespaces()}
        ),
        10,
        'the four nodes in the graph',
        diagnose=why,
    )
    ros.spin_until(
        lambda: (
            {f'{namespace[1:]}/model_node: DMSP-10-250', f'{namespace[1:]}/joint_node: elbow'}
            <= {s.name for d in diagnostics for s in d.status}
        ),
        10,
        'both statuses on /diagnostics',
        diagnose=why,
    )
    assert proc.poll() is None, why()
    print(
        f'\npma_composed (pid {proc.pid}): {", ".join(EVERY_NODE)} in {namespace}; '
        f'{len(forces)} force estimates, {len(torques)} torque estimates, both nodes active'
    )


@pytest.mark.parametrize(
    'old, new, words',
    [
        ('positive: flexor', 'positive: biceps', "joint 'elbow': positive must name"),
        (
            '    joints: [elbow]\n',
            '    joints: [elbow]\n    executor: events\n',
            'the nodes of one process share one executor, got model_node: single, '
            'joint_node: events',
        ),
    ],
)
def test_a_bad_section_ends_the_process_with_one_fatal_line(tmp_path, old, new, words):
    path = edited_copy(EXAMPLE, tmp_path, old, new)
    shutil.copy(EXAMPLE.parent / 'dmsp_10_250.yaml', tmp_path)  # its muscles' file, beside it
    lines = lines_of_failed_start(composed('--ros-args', '--params-file', path))
    fatal = [line for line in lines if 'FATAL' in line]
    assert fatal == lines[-1:] and '[pma_composed]: invalid parameters: ' in fatal[0], lines
    assert words in fatal[0], fatal[0]
