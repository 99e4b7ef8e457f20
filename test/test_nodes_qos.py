"""QoS overridable by parameters (nodes/qos.py): an override of ``qos_overrides.<topic>.<publisher|
subscription>.<policy>`` changes the QoS of the entity it names, and only that one; in-process
(the entities' profiles and the middleware's graph) and once seen from a second process.
"""

import pytest
from rclpy.qos import ReliabilityPolicy
import yaml

from conftest import CONFIGS, REPO
from pma_model_ros.nodes.joint_node import JointNode
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.nodes.qos import SENSOR_INPUT
from pma_model_ros.nodes.simulator_node import SimulatorNode

EXAMPLE_JOINT = REPO / 'config' / 'example_joint.yaml'
RELIABLE, BEST_EFFORT = ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT


@pytest.fixture
def make(private_node):
    """A factory: node class and its rclpy arguments, on a private Context."""
    return private_node


def profiles(node) -> dict[str, object]:
    """The QoS profile of each of the node's publishers and subscriptions, by ``pub /topic`` and
    ``sub /topic``.
    """
    return {
        **{f'pub {p.topic_name}': p.qos_profile for p in node.publishers},
        **{f'sub {s.topic_name}': s.qos_profile for s in node.subscriptions},
    }


def test_model_node_override_changes_only_the_entity_it_names(make):
    node = make(
        ModelNode,
        '--params-file',
        CONFIGS['DMSP-10-250'],
        '-p',
        'qos_overrides./pressure.subscription.reliability:=reliable',
        '-p',
        'qos_overrides./force_estimate.publisher.depth:=3',
    )
    qos = profiles(node)
    assert (qos['sub /pressure'].reliability, qos['sub /pressure'].depth) == (RELIABLE, 100)
    assert qos['sub /muscle_state'].reliability == BEST_EFFORT  # its own default
    assert (qos['pub /force_estimate'].depth, qos['pub /pressure_command'].depth) == (3, 10)
    assert SENSOR_INPUT.reliability == BEST_EFFORT  # the shared default is left alone
    # the middleware's view of the subscription
    (seen,) = node.get_subscriptions_info_by_topic('/pressure')
    assert seen.qos_profile.reliability == RELIABLE
    described = node.describe_parameter('qos_overrides./pressure.subscription.reliability')
    assert described.read_only
    assert node.get_parameter('qos_overrides./muscle_state.subscription.reliability').value == (
        'best_effort'
    )


def test_joint_node_and_simulator_take_overrides_from_a_parameter_file(make, tmp_path):
    """The parameter-file form of docs/nodes.md: under ``qos_overrides:``, topic by topic."""
    overrides = tmp_path / 'qos.yaml'
    overrides.write_text(
        yaml.safe_dump(
            {
                '/**': {
                    'ros__parameters': {
                        'qos_overrides': {
                            '/joint_states': {'subscription': {'depth': 7}},
                            '/flexor/pressure_command': {
                                'publisher': {'reliability': 'best_effort'}
                            },
                            '/pressure': {'publisher': {'reliability': 'reliable'}},
                        }
                    }
                }
            }
        )
    )
    joint = profiles(make(JointNode, '--params-file', EXAMPLE_JOINT, '--params-file', overrides))
    assert joint['sub /joint_states'].depth == 7
    assert joint['pub /flexor/pressure_command'].reliability == BEST_EFFORT
    assert joint['pub /extensor/pressure_command'].reliability == RELIABLE
    simulator = profiles(make(SimulatorNode, '--params-file', overrides))
    assert simulator['pub /pressure'].reliability == RELIABLE
    assert simulator['pub /muscle_state'].reliability == BEST_EFFORT


@pytest.mark.ros
def test_an_override_is_what_another_process_sees(ros, processes, namespace):
    proc = processes.node(
        'model_node',
        namespace,
        CONFIGS['DMSP-10-250'],
        **{f'qos_overrides.{namespace}/pressure.subscription.reliability': 'reliable'},
    )
    infos = {}

    def discovered() -> bool:
        for topic in ('pressure', 'muscle_state'):
            infos[topic] = ros.node.get_subscriptions_info_by_topic(f'{namespace}/{topic}')
        return all(infos.values())

    ros.spin_until(
        discovered, 20, "model_node's subscriptions", diagnose=lambda: processes.output(proc)
    )
    assert [i.qos_profile.reliability for i in infos['pressure']] == [RELIABLE]
    assert [i.qos_profile.reliability for i in infos['muscle_state']] == [BEST_EFFORT]
