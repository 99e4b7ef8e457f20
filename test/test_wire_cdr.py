"""The wire layer (pma_model_ros/wire) against rclpy's own serializer and deserializer: what it
reads from message bytes is what rclpy deserializes, what it writes is what rclpy deserializes
back; and it writes the bytes rosbags' serializer writes.
"""

import math

from geometry_msgs.msg import WrenchStamped
from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import FluidPressure, JointState

from budget import examples
from node_messages import big_endian, stamped
from pma_model_ros.bags.bag_io import JOINT_STATE, TYPESTORE
from pma_model_ros.wire.cdr import (
    FLOATS,
    fluid_pressure,
    joint_state,
    split,
    stamped_float,
    wrench_stamped,
)
from pma_model_ros.wire.columns import joint_columns, stamped_floats
from pma_model_ros.wire.joint_state import JointIndex, JointStateArrays, JointStateReader
from pma_model_ros.wire.muscle_inputs import stamped_value

EXAMPLES = 300
#: Names and frame_ids of every length mod 4 (padding 0..3 bytes), non-ASCII included.
texts = st.text(st.characters(codec='utf-8', exclude_characters='\x00'), max_size=9)
floats = st.floats(allow_nan=True, allow_infinity=True)
arrays = st.lists(floats, max_size=5)
stamps = st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 10**9 - 1))


@st.composite
def joint_states(draw, names=None):
    msg = JointState(
        name=draw(st.lists(texts, max_size=5)) if names is None else names,
        position=draw(arrays),
        velocity=draw(arrays),
        effort=draw(arrays),
    )
    msg.header.frame_id = draw(texts)
    msg.header.stamp.sec, msg.header.stamp.nanosec = draw(stamps)
    return msg


def same(got, msg) -> None:
    """``got`` (JointStateArrays) holds what ``msg`` (a deserialized JointState) holds, NaN too."""
    assert got.stamp == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert list(got.names) == list(msg.name)
    for field in ('position', 'velocity', 'effort'):
        np.testing.assert_array_equal(getattr(got, field), np.asarray(getattr(msg, field)))


@examples(EXAMPLES)
@given(
    first=joint_states(),
    stream=st.lists(st.tuples(st.booleans(), joint_states()), min_size=1, max_size=6),
)
def test_reader_equals_rclpy_deserialize(first, stream):
    """A stream where each message repeats the previous one's names or brings new ones: every read
    equals rclpy's deserialization; a repeated layout is read at the cached offsets.
    """
    reader = JointStateReader(lambda data: deserialize_message(data, JointState))
    previous = first
    for keep, msg in [(False, first), *stream]:
        if keep:  # the layout of the previous message, new numbers and stamp
            msg.name, msg.header.frame_id = previous.name, previous.header.frame_id
            msg.position = [v * 2 for v in previous.position]
            msg.velocity, msg.effort = list(previous.velocity), list(previous.effort)
        data = serialize_message(msg)
        fast = reader.fast
        got = reader(data)
        same(got, deserialize_message(data, JointState))
        if keep:
            assert reader.fast == fast + 1  # read without the deserializer
        previous = msg


@examples(EXAMPLES // 3)
@given(msg=joint_states())
def test_big_endian_messages_are_deserialized(msg):
    """A big-endian message (another encapsulation): decoded by the deserializer every time."""
    ours = TYPESTORE.types[JOINT_STATE](
        TYPESTORE.types['std_msgs/msg/Header'](
            TYPESTORE.types['builtin_interfaces/msg/Time'](
                msg.header.stamp.sec, msg.header.stamp.nanosec
            ),
            msg.header.frame_id,
        ),
        list(msg.name),
        np.array(msg.position, float),
        np.array(msg.velocity, float),
        np.array(msg.effort, float),
    )
    data = bytes(TYPESTORE.serialize_cdr(ours, JOINT_STATE, little_endian=False))
    reader = JointStateReader(lambda data: deserialize_message(data, JointState))
    for _ in range(2):
        same(reader(data), deserialize_message(data, JointState))
    assert reader.fast == 0 and reader.decoded == 2


@examples(EXAMPLES)
@given(
    names=st.lists(texts, max_size=6),
    field=st.sampled_from(['position', 'velocity', 'effort']),
    frame=texts,
    stamp=st.integers(-(2**31) * 10**9, 2**31 * 10**9 - 1),
    data=st.data(),
)
def test_joint_state_template_equals_rclpy_and_rosbags(names, field, frame, stamp, data):
    template = joint_state(names, field, frame)
    values = data.draw(st.lists(floats, min_size=len(names), max_size=len(names)))
    template.values[:] = values
    out = template(stamp)
    msg = deserialize_message(out, JointState)
    expected = JointState(name=names, **{field: values})
    expected.header.frame_id = frame
    expected.header.stamp.sec, expected.header.stamp.nanosec = split(stamp)
    same(arrays_of(msg), expected)
    rosbags = TYPESTORE.deserialize_cdr(out, JOINT_STATE)
    assert bytes(TYPESTORE.serialize_cdr(rosbags, JOINT_STATE)) == out  # byte for byte


def arrays_of(msg) -> JointStateArrays:
    return JointStateArrays(
        msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec,
        list(msg.name),
        *(np.asarray(getattr(msg, f), float) for f in ('position', 'velocity', 'effort')),
    )


@examples(EXAMPLES)
@given(frame=texts, value=floats, stamp=stamps)
def test_stamped_float_reads_and_writes_like_rclpy(frame, value, stamp):
    for kind, template, field in (
        (FluidPressure, fluid_pressure, 'fluid_pressure'),
        (WrenchStamped, wrench_stamped, 'force'),
    ):
        msg = stamped(kind, frame, stamp, value)
        ns = stamp[0] * 10**9 + stamp[1]
        got_stamp, got = stamped_float(serialize_message(msg), FLOATS[field])
        assert got_stamp == ns and (got == value or math.isnan(got) and math.isnan(value))
        ours = template(frame)
        ours.values[0] = value
        back = deserialize_message(ours(ns), kind)
        assert (back.header.stamp.sec, back.header.stamp.nanosec, back.header.frame_id) == (
            *stamp,
            frame,
        )
        field_value = back.fluid_pressure if kind is FluidPressure else back.wrench.force.x
        assert field_value == value or math.isnan(value) and math.isnan(field_value), field


def test_stamped_float_refuses_what_it_cannot_read():
    data = serialize_message(FluidPressure(fluid_pressure=3.0))
    floats = FLOATS['fluid_pressure']
    # an empty frame_id ends at byte 17: the value at 20..28 (8-aligned from byte 4), the
    # variance at 28..36
    assert stamped_float(data[:24], floats) is None  # truncated in the value
    assert stamped_float(data[:28], floats) is None  # the value, without its variance
    assert stamped_float(data[:36], floats) == (0, 3.0)
    assert stamped_float(b'\x00\x00' + data[2:], floats) is None  # big-endian encapsulation


def test_joint_index_per_layout():
    reader = JointStateReader(lambda data: deserialize_message(data, JointState))
    index = JointIndex(['b', 'c', 'x'])
    msg = reader(serialize_message(JointState(name=['a', 'b', 'c'], position=[1.0, 2.0, 3.0])))
    take, present, problems = index.of(msg)
    assert take.tolist()[:2] == [1, 2] and present.tolist() == [True, True, False]
    assert problems == ["joint 'x' not in ['a', 'b', 'c']"]
    assert index.of(msg)[0] is take  # cached for the layout
    bad = reader(serialize_message(JointState(name=['b', 'c', 'x'], position=[1.0])))
    assert index.of(bad)[2] == ['mismatched arrays: 3 names, 1 positions, 0 velocities'] * 3


@pytest.mark.parametrize('n', [1, 64])
def test_reading_many_messages_of_one_layout_is_fast_after_the_first(n):
    names = [f'm{i:02d}' for i in range(n)]
    reader = JointStateReader(lambda data: deserialize_message(data, JointState))
    for k in range(5):
        msg = JointState(name=names, position=[k + 0.5] * n)
        msg.header.stamp.sec = k
        same(reader(serialize_message(msg)), msg)
    assert (reader.decoded, reader.fast) == (1, 4)


def ignored_bytes(data: bytes) -> list[int]:
    """The bytes of a JointState rclpy's deserializer ignores, found by changing each one in turn
    (the padding, whatever the wire layer thinks it is).
    """
    msg = deserialize_message(data, JointState)
    ignored = []
    for i in range(4, len(data)):
        changed = bytearray(data)
        changed[i] ^= 0xA5
        try:
            other = deserialize_message(bytes(changed), JointState)
        except Exception:  # e.g. a string that is no UTF-8 any more
            continue
        if (
            other.header == msg.header
            and other.name == msg.name
            and all(
                np.array_equal(getattr(other, f), getattr(msg, f), equal_nan=True)
                for f in ('position', 'velocity', 'effort')
            )
        ):
            ignored.append(i)
    return ignored


@examples(EXAMPLES // 3)
@given(msg=joint_states(), garbage=st.binary(min_size=64, max_size=64), data=st.data())
def test_garbage_in_the_padding_keeps_the_cached_layout(msg, garbage, data):
    """The serializer of rclpy leaves whatever was in memory in the padding (seen: 3 bytes after an
    empty frame_id changing from message to message); such a message is still read at the cached
    layout, and equals rclpy's deserialization.
    """
    reader = JointStateReader(lambda data: deserialize_message(data, JointState))
    clean = serialize_message(msg)
    reader(clean)
    msg.position = data.draw(
        st.lists(floats, min_size=len(msg.position), max_size=len(msg.position))
    )
    dirty = bytearray(serialize_message(msg))
    ignored = ignored_bytes(bytes(dirty))
    for i, at in enumerate(ignored):
        dirty[at] = garbage[i % len(garbage)]
    got = reader(bytes(dirty))
    same(got, deserialize_message(bytes(dirty), JointState))
    assert (reader.decoded, reader.fast) == (1, 1)


# --- many messages at once (bag estimate): what reading each one gives
# ----------------------------------------------------------------------


rate_values = st.one_of(floats, st.sampled_from([math.inf, -math.inf, math.nan]))


@st.composite
def usual_joint_states(draw):
    """Messages (JointState) whose arrays mostly match the names (velocity sometimes empty)."""
    names = draw(st.lists(texts, max_size=5, unique=True))
    n = len(names)
    sizes = st.sampled_from([n, n, n, 0, n + 1])
    msg = JointState(
        name=names,
        position=draw(st.lists(floats, min_size=(k := draw(sizes)), max_size=k)),
        velocity=draw(st.lists(rate_values, min_size=(k := draw(sizes)), max_size=k)),
        effort=draw(st.lists(floats, min_size=(k := draw(sizes)), max_size=k)),
    )
    msg.header.frame_id = draw(texts)
    msg.header.stamp.sec, msg.header.stamp.nanosec = draw(stamps)
    return msg


@examples(EXAMPLES // 2)
@given(
    first=usual_joint_states(),
    stream=st.lists(
        st.tuples(st.sampled_from(['repeat'] * 3 + ['new', 'big-endian']), usual_joint_states()),
        min_size=2,
        max_size=12,
    ),
    extra=st.lists(texts, max_size=2),
    field=st.sampled_from(['position', 'effort']),
    data=st.data(),
)
def test_joint_columns_equal_reading_each_message(first, stream, extra, field, data):
    """Messages (JointState) of repeated layouts (new numbers and stamps), new layouts and
    big-endian ones, read at once for some joints (named in the messages or not): the same stamps,
    values, rates, which joints each gives and why not, as the per-message reader and index give
    each.
    """
    messages, previous = [], first
    for form, msg in [('new', first), *stream]:
        if form == 'repeat':
            msg.name, msg.header.frame_id = previous.name, previous.header.frame_id
            for f in ('position', 'velocity', 'effort'):
                old = getattr(previous, f)
                kind = rate_values if f == 'velocity' else floats
                setattr(msg, f, data.draw(st.lists(kind, min_size=len(old), max_size=len(old))))
        messages.append(big_endian(msg) if form == 'big-endian' else serialize_message(msg))
        previous = msg
    names = sorted({n for msg in [first] + [m for _, m in stream] for n in msg.name})
    joints = list(
        dict.fromkeys(
            data.draw(st.lists(st.sampled_from(names), min_size=1, max_size=3)) if names else []
        )
    )
    joints = list(dict.fromkeys(joints + extra)) or ['j']

    def deserialize(raw):
        return deserialize_message(raw, JointState)

    got = joint_columns(messages, joints, field, deserialize)
    reader, index = JointStateReader(deserialize), JointIndex(joints, field)
    for i, raw in enumerate(messages):
        msg = reader(raw)
        take, present, problems = index.of(msg)
        assert got.stamps[i] == msg.stamp
        assert got.present[i].tolist() == (
            present.tolist() if present is not None else [True] * len(joints)
        )
        assert got.named[i].tolist() == [j in msg.names for j in joints]
        assert got.problems[i] == (problems if present is not None else [])
        here = got.present[i]
        values = getattr(msg, field)[take][here] if here.any() else []
        np.testing.assert_array_equal(got.values[i][here], values)
        if field == 'position' and here.any():
            rates = msg.velocity[take][here] if len(msg.velocity) else np.full(here.sum(), np.nan)
            np.testing.assert_array_equal(
                got.rates[i][here], np.where(np.isfinite(rates), rates, np.nan)
            )


@examples(EXAMPLES // 2)
@given(
    stream=st.lists(
        st.tuples(texts, floats, stamps, st.sampled_from(['le'] * 4 + ['big-endian'])),
        min_size=1,
        max_size=10,
    ),
    kind=st.sampled_from(['FluidPressure', 'WrenchStamped']),
)
def test_stamped_floats_equal_reading_each_message(stream, kind):
    """Messages (FluidPressure or WrenchStamped) of any frame_ids (padding), stamps and values,
    some big-endian: read at once, the stamps and values that reading each gives.
    """
    cls, field = {
        'FluidPressure': (FluidPressure, 'fluid_pressure'),
        'WrenchStamped': (WrenchStamped, 'force'),
    }[kind]
    messages = []
    for frame, value, stamp, form in stream:
        msg = stamped(cls, frame, stamp, value)
        messages.append(big_endian(msg) if form == 'big-endian' else serialize_message(msg))

    def deserialize(raw):
        return deserialize_message(raw, cls)

    stamps_got, values_got, malformed = stamped_floats(messages, deserialize, field)
    assert not malformed.any()
    expected = [stamped_value(raw, deserialize, field) for raw in messages]
    assert stamps_got.tolist() == [s for s, _ in expected]
    np.testing.assert_array_equal(values_got, [v for _, v in expected])


def test_known_names_with_other_array_lengths_are_a_layout_of_their_own():
    """A message whose names equal the cached layout's but whose arrays have other lengths (big-
    endian, so decoded rather than read at the layout's offsets) gets its own verdict: the joint
    has no position (none sent), not the cached layout's index into an empty array.
    """
    reader = JointStateReader(lambda raw: deserialize_message(raw, JointState))
    index = JointIndex(['a'])
    usual = reader(serialize_message(JointState(name=['a'], position=[0.2])))
    assert index.of(usual)[1] is None  # present: every joint
    odd = reader(big_endian(JointState(name=['a'], velocity=[0.0])))
    take, present, problems = index.of(odd)
    assert present.tolist() == [False] and problems == ['empty name or position array']
    again = reader(serialize_message(JointState(name=['a'], position=[0.3])))
    assert index.of(again)[1] is None and again.position[index.of(again)[0]].tolist() == [0.3]
    messages = [serialize_message(JointState(name=['a'], position=[0.2]))]
    messages.append(big_endian(JointState(name=['a'])))
    got = joint_columns(
        messages,
        ['a'],
        'position',
        lambda raw: deserialize_message(raw, JointState),
    )
    assert got.present.tolist() == [[True], [False]]
    assert got.problems[1] == ['empty name or position array']
