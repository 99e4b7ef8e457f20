"""The /diagnostics writer (pma_model_ros/wire/diagnostics.py): the bytes rosbags' serializer
writes for the same DiagnosticArray, which rclpy deserializes back to it (rclpy's own serializer
leaves whatever was in memory in the alignment padding, so its bytes differ there).
"""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message

from budget import examples
from pma_model_ros.bags.bag_io import TYPESTORE
from pma_model_ros.wire.cdr import split
from pma_model_ros.wire.diagnostics import diagnostic_array

#: Texts of every length mod 4 (padding 0..3 bytes before the next count), non-ASCII included.
texts = st.text(st.characters(codec='utf-8', exclude_characters='\x00'), max_size=9)
entries = st.lists(
    st.tuples(
        texts,
        texts,
        st.integers(0, 3),
        texts,
        st.dictionaries(st.sampled_from(['estimates', 'model', 'é', 'a b', '']) | texts, texts),
    ),
    max_size=5,
)
stamps = st.integers(0, 2**31 * 10**9 - 1)


def rclpy_message(stamp_ns: int, entries: list) -> DiagnosticArray:
    msg = DiagnosticArray(
        status=[
            DiagnosticStatus(
                level=bytes([level]),
                name=f'model_node: {name}',
                hardware_id=hardware_id,
                message=message,
                values=[KeyValue(key=k, value=v) for k, v in values.items()],
            )
            for name, hardware_id, level, message, values in entries
        ]
    )
    msg.header.stamp.sec, msg.header.stamp.nanosec = split(stamp_ns)
    return msg


@examples(300)
@given(stamp=stamps, first=entries, second=entries)
def test_the_bytes_are_rclpys_and_rosbags(stamp, first, second):
    """Two arrays in turn (the second reuses the first's cached keys at other alignments): each
    is rosbags' serialization byte for byte and rclpy's message when deserialized.
    """
    t = TYPESTORE.types
    for entries in (first, second):
        got = diagnostic_array(stamp, 'model_node', entries)
        header = t['std_msgs/msg/Header'](t['builtin_interfaces/msg/Time'](*split(stamp)), '')
        statuses = [
            t['diagnostic_msgs/msg/DiagnosticStatus'](
                level,
                f'model_node: {name}',
                message,
                hardware_id,
                [t['diagnostic_msgs/msg/KeyValue'](k, v) for k, v in values.items()],
            )
            for name, hardware_id, level, message, values in entries
        ]
        array = t['diagnostic_msgs/msg/DiagnosticArray'](header, statuses)
        assert got == TYPESTORE.serialize_cdr(array, 'diagnostic_msgs/msg/DiagnosticArray')
        assert deserialize_message(got, DiagnosticArray) == rclpy_message(stamp, entries)


def test_an_empty_array_by_hand():
    """No status: encapsulation, stamp (sec, nanosec), frame_id '' (length 1, NUL), padding to
    the count 0.
    """
    assert diagnostic_array(5 * 10**9 + 7, 'model_node', []) == (
        b'\x00\x01\x00\x00' + b'\x05\x00\x00\x00\x07\x00\x00\x00' + b'\x01\x00\x00\x00\x00'
        b'\x00\x00\x00' + b'\x00\x00\x00\x00'
    )
