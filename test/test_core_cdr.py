"""Serialized-message templates: stamp and values patched in the bytes, read back by rclpy's
deserializer.
"""

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from pma_model_ros.core.cdr import sentinels, StampedTemplate


@pytest.mark.parametrize('n', [1, 4, 64])
def test_joint_state_effort_and_stamp_patched(n):
    names = [f'muscle_{i:02d}' for i in range(n)]  # names of varying length: padding differs
    template = StampedTemplate(
        serialize_message(JointState(name=names, effort=sentinels(n).tolist())), n
    )
    forces = [100.0 + 7.5 * i for i in range(n)]
    template.values[:] = forces
    msg = deserialize_message(template(1767225600, 999999999), JointState)
    assert list(msg.name) == names and list(msg.effort) == forces
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1767225600, 999999999)


def test_missing_sentinels_and_big_endian_are_refused():
    with pytest.raises(ValueError, match='sentinel'):
        StampedTemplate(b'\x00\x01\x00\x00' + bytes(40), 1)
    with pytest.raises(ValueError, match='little-endian'):
        StampedTemplate(b'\x00\x00\x00\x00' + sentinels(1).tobytes(), 1)
