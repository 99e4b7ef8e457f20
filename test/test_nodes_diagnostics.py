"""The /diagnostics message (nodes/diagnostics.py): one status per entry, named after the node,
stamped with the node's clock, serialized.
"""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import pytest
from rclpy.serialization import deserialize_message
from rclpy.time import Time

from pma_model_ros.nodes.diagnostics import diagnostic_array

pytestmark = pytest.mark.ros


def test_one_status_per_entry_named_after_the_node_with_its_level_and_values(ros):
    entries = [
        ('elbow', 'DMSP-10-250', 0, 'OK', {'estimates': '12', 'rejected': '0'}),
        ('wrist', 'DMSP-20-300', 2, 'stale pressure', {}),
    ]
    before = ros.node.get_clock().now()
    msg = deserialize_message(diagnostic_array(ros.node, entries), DiagnosticArray)
    after = ros.node.get_clock().now()
    full = ros.node.get_name()
    assert [s.name for s in msg.status] == [f'{full}: elbow', f'{full}: wrist']
    assert [s.hardware_id for s in msg.status] == ['DMSP-10-250', 'DMSP-20-300']
    # the level is one byte with the standard values (OK = 0, ERROR = 2)
    assert [s.level for s in msg.status] == [DiagnosticStatus.OK, DiagnosticStatus.ERROR]
    assert [s.message for s in msg.status] == ['OK', 'stale pressure']
    assert [(v.key, v.value) for v in msg.status[0].values] == [
        ('estimates', '12'),
        ('rejected', '0'),
    ]
    assert msg.status[1].values == []
    assert before <= Time.from_msg(msg.header.stamp) <= after


def test_no_entries_is_an_empty_array(ros):
    assert deserialize_message(diagnostic_array(ros.node, []), DiagnosticArray).status == []


def test_two_nodes_of_the_shipped_file_in_two_namespaces_report_distinct_statuses(private_node):
    """Each status names its node by its fully qualified name, and an unset ``hardware_id`` is
    instance-specific: two model_nodes (and two joint_nodes) of one file collide in neither.
    """
    from conftest import CONFIGS, REPO
    from node_messages import record
    from pma_model_ros.nodes.joint_node import JointNode
    from pma_model_ros.nodes.model_node import ModelNode

    for cls, params_file in (
        (ModelNode, CONFIGS['DMSP-10-250']),
        (JointNode, REPO / 'config' / 'example_joint.yaml'),
    ):
        statuses = []
        for namespace in ('/left_arm', '/right_arm'):
            node = private_node(cls, '-r', f'__ns:={namespace}', '--params-file', params_file)
            sent = record(node._diag_pub)
            node.publish_status(node.now())
            statuses.append(sent[-1].status[0])
        name = node.get_name()
        joint = statuses[0].name.split(': ')[1]
        assert [s.name for s in statuses] == [
            f'left_arm/{name}: {joint}',
            f'right_arm/{name}: {joint}',
        ]
        assert [s.hardware_id for s in statuses] == [
            f'/left_arm/{name}/{joint}',
            f'/right_arm/{name}/{joint}',
        ]
