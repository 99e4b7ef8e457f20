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
