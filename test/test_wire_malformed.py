"""Malformed message bytes through the wire layer: the readers against rclpy's deserializer
(equal on every message it reads, a clean refusal of every message it refuses, the cached-layout
fast paths included), and a seeded fuzz of thousands of refused messages per topic through
model_node's translation (:class:`MuscleInputs`, both input modes) and ``bag estimate``'s column
readers: nothing raised, nothing answered, each one counted as invalid input, and the next valid
input answered.
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
from conftest import CONFIGS
from node_messages import AMBIENT, damage, HARMS, malformed, refused, stamped
from pma_model_ros.core.files.param_file import node_settings, read_parameters
from pma_model_ros.core.runtime.engine import Engine, Level
from pma_model_ros.nodes.model_node import DESERIALIZE
from pma_model_ros.wire.cdr import MALFORMED, MalformedMessage
from pma_model_ros.wire.columns import joint_columns, stamped_floats
from pma_model_ros.wire.joint_state import JointStateReader
from pma_model_ros.wire.muscle_inputs import MuscleInputs, stamped_value

EXAMPLES = 400
FUZZ = 2000  #: refused messages per topic in the seeded fuzz
SEED = 20261126
texts = st.text(st.characters(codec='utf-8', exclude_characters='\x00'), max_size=9)
floats = st.floats(allow_nan=True, allow_infinity=True)
stamps = st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 10**9 - 1))
harms = st.lists(
    st.tuples(st.sampled_from(HARMS), st.integers(0, 2**16), st.binary(min_size=1, max_size=40)),
    min_size=1,
    max_size=3,
)
STAMPED = {FluidPressure: 'fluid_pressure', WrenchStamped: 'force'}


def rclpy_reads(data: bytes, kind):
    """The deserialization of ``data`` by rclpy, or None where rclpy refuses it."""
    return None if refused(data, kind) else deserialize_message(data, kind)


def equal_float(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


@examples(EXAMPLES)
@given(
    kind=st.sampled_from([FluidPressure, WrenchStamped]),
    frame=texts,
    stamp=stamps,
    value=floats,
    harm=harms,
)
def test_stamped_reader_equals_rclpy_or_refuses(kind, frame, stamp, value, harm):
    data = damage(serialize_message(stamped(kind, frame, stamp, value)), harm)
    expected = rclpy_reads(data, kind)
    read = DESERIALIZE[kind.__name__]
    field = STAMPED[kind]
    if expected is None:
        with pytest.raises(MalformedMessage, match=MALFORMED):
            stamped_value(data, read, field)
        return
    got_stamp, got = stamped_value(data, read, field)
    want = expected.fluid_pressure if kind is FluidPressure else expected.wrench.force.x
    assert got_stamp == expected.header.stamp.sec * 10**9 + expected.header.stamp.nanosec
    assert equal_float(got, want)


@examples(EXAMPLES)
@given(
    names=st.lists(texts, max_size=4),
    position=st.lists(floats, max_size=4),
    velocity=st.lists(floats, max_size=4),
    frame=texts,
    stamp=stamps,
    harm=harms,
    learned=st.booleans(),
)
def test_joint_state_reader_equals_rclpy_or_refuses(
    names, position, velocity, frame, stamp, harm, learned
):
    """With ``learned``, the reader first reads the undamaged message: the damaged one meets its
    cached layout (the fast path: counts and strings compared, values read in place).
    """
    msg = JointState(name=names, position=position, velocity=velocity)
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    good = serialize_message(msg)
    data = damage(good, harm)
    reader = JointStateReader(DESERIALIZE['JointState'])
    if learned:
        reader(good)
    expected = rclpy_reads(data, JointState)
    if expected is None:
        with pytest.raises(MalformedMessage, match=MALFORMED):
            reader(data)
        return
    got = reader(data)
    assert got.stamp == expected.header.stamp.sec * 10**9 + expected.header.stamp.nanosec
    assert list(got.names) == list(expected.name)
    for field in ('position', 'velocity', 'effort'):
        np.testing.assert_array_equal(getattr(got, field), np.asarray(getattr(expected, field)))


def test_a_damaged_count_behind_a_cached_layout_is_not_read():
    """A message of the cached layout whose position count is corrupt: rclpy refuses it, and so
    does the reader, although the names before the count are the cached ones.
    """
    good = serialize_message(JointState(name=['a', 'b'], position=[1.0, 2.0]))
    reader = JointStateReader(DESERIALIZE['JointState'])
    reader(good)
    # the position count sits after the names: header (12), frame '' (8), 2 names (4 + 8 + 8)
    at = good.index((2).to_bytes(4, 'little'), 36)
    bad = good[:at] + (2**31 - 1).to_bytes(4, 'little') + good[at + 4 :]
    assert refused(bad, JointState)
    with pytest.raises(MalformedMessage):
        reader(bad)
    assert reader(good).position.tolist() == [1.0, 2.0]  # and the layout is still used
    assert reader.fast == 1


# --- the seeded fuzz through model_node's translation
#: the valid inputs after the fuzz: gauge pressure [Pa], length [m]; Table A2 (Martens & Boblan
#: 2017, DMSP-10-250) measured 35.17 N there, and 542.5 N at most on the map
P, L, MEASURED = 310e3, 0.234, 35.17
NOW = 100 * 10**9


def good_inputs(names: list[str]) -> dict[str, bytes]:
    """Valid messages of every input topic for the muscles ``names`` (stamped NOW)."""
    sec, nanosec = divmod(NOW, 10**9)
    out = {
        'pressure': FluidPressure(fluid_pressure=AMBIENT + P),
        'muscle_state': JointState(name=names[:1], position=[L], velocity=[0.0]),
        'force_command': WrenchStamped(),
        'muscle_pressures': JointState(name=names, position=[AMBIENT + P] * len(names)),
        'muscle_states': JointState(name=names, position=[L] * len(names)),
        'force_commands': JointState(name=names, effort=[50.0] * len(names)),
    }
    out['force_command'].wrench.force.x = 50.0
    for msg in out.values():
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return {topic: serialize_message(msg) for topic, msg in out.items()}


KINDS = {
    'pressure': FluidPressure,
    'muscle_state': JointState,
    'force_command': WrenchStamped,
    'muscle_pressures': JointState,
    'muscle_states': JointState,
    'force_commands': JointState,
}
SOURCE = {
    'pressure': 'pressure',
    'muscle_state': 'muscle_state',
    'force_command': 'force_command',
    'muscle_pressures': 'pressure',
    'muscle_states': 'muscle_state',
    'force_commands': 'force_command',
}


def call(inputs: MuscleInputs, topic: str, data: bytes):
    """What model_node's callback of ``topic`` hands the wire layer (muscle 0 of per-muscle
    topics).
    """
    if topic in ('pressure', 'muscle_state', 'force_command'):
        return getattr(inputs, topic)(0, data, NOW)
    return getattr(
        inputs, {'muscle_pressures': 'pressures', 'muscle_states': 'states'}.get(topic, topic)
    )(data, NOW)


@pytest.mark.parametrize('mode', ['per_muscle', 'combined'])
def test_fuzz_thousands_of_malformed_messages_per_topic(mode):
    settings = node_settings(read_parameters(CONFIGS['DMSP-10-250']))
    model = settings.config.model
    names = ['left', 'right'] if mode == 'combined' else [settings.joint_name]
    engine = Engine([settings.config] * len(names), hold=1.0)
    inputs = MuscleInputs(engine, names, ['f'] * len(names), DESERIALIZE)
    good = good_inputs(names)
    topics = (
        ['muscle_pressures', 'muscle_states', 'force_commands']
        if mode == 'combined'
        else ['pressure', 'muscle_state', 'force_command']
    )
    rng = np.random.default_rng(SEED)
    # a valid length first: a pressure read from a malformed message would be answered
    assert call(inputs, topics[1], good[topics[1]]) is None
    for topic in topics:
        bad = malformed(rng, good[topic], KINDS[topic], FUZZ)
        before = [engine.counts(k).get(f'rejected {SOURCE[topic]}', 0) for k in range(len(names))]
        answers = [call(inputs, topic, data) for data in bad]
        assert answers == [None] * FUZZ
        for k in range(len(names)):
            assert engine.counts(k)[f'rejected {SOURCE[topic]}'] == before[k] + FUZZ
            assert engine.level(k, NOW) == (Level.ERROR, f'invalid input: {MALFORMED}')
    # the next valid pressure is answered: the force at (P, L) of the muscle's model
    answer = call(inputs, topics[0], good[topics[0]])
    assert answer is not None
    kind = JointState if mode == 'combined' else WrenchStamped
    msg = deserialize_message(answer, kind)
    forces = list(msg.effort) if mode == 'combined' else [msg.wrench.force.x]
    assert forces == pytest.approx([float(model.force(P, L).force)] * len(names), rel=1e-12)
    assert forces[0] == pytest.approx(MEASURED, abs=0.03 * 542.5)  # within 3 % of the map's max
    assert engine.level(0, NOW + 2 * 10**9)[1] != f'invalid input: {MALFORMED}'  # held for 1 s


def test_bag_readers_give_no_value_of_a_malformed_message():
    """``bag estimate``'s column readers (rosbags' deserializer behind them) over messages rclpy
    serialized (a JointState with bytes after its end, which rosbags' own check refuses) and
    damaged ones rclpy refuses: no exception; the good ones read, the damaged ones marked
    malformed, with no value.
    """
    from pma_model_ros.bags.offline_inputs import DESERIALIZE as ROSBAGS

    rng = np.random.default_rng(SEED)
    good = good_inputs(['a'])
    for topic, field in (('pressure', 'fluid_pressure'), ('force_command', 'force')):
        kind = KINDS[topic]
        datas = [good[topic], *malformed(rng, good[topic], kind, 200), good[topic]]
        stamps, values, bad = stamped_floats(datas, ROSBAGS[kind.__name__], field)
        assert not bad[0] and not bad[-1] and values[0] == values[-1] != 0
        for i in np.flatnonzero(bad).tolist():
            assert math.isnan(values[i])
        assert bad.sum() >= 150  # rosbags refuses most of what rclpy refuses
    datas = [good['muscle_states'], *malformed(rng, good['muscle_states'], JointState, 200)]
    datas.append(good['muscle_states'])
    got = joint_columns(datas, ['a'], 'position', ROSBAGS['JointState'])
    assert got.present[0, 0] and got.present[-1, 0] and got.values[-1, 0] == L
    rows = [row for row, problems in enumerate(got.problems) if problems == [MALFORMED]]
    assert len(rows) >= 150
    assert not got.present[rows, 0].any() and np.isnan(got.values[rows, 0]).all()
