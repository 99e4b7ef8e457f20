"""Reading and writing bags with rosbags: both storages, atomic output, foreign and damaged
bags.
"""

import numpy as np
import pytest

try:
    import rosbags  # noqa: F401
except ImportError:  # pip-only (a -pip rosdep key): colcon test on a ROS install without it
    pytest.skip(
        'needs rosbags, a pip-only library: pip install -r requirements-dev.txt',
        allow_module_level=True,
    )
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from pma_model_ros.bags.bag_io import (
    BagError,
    BagWriter,
    FLUID_PRESSURE,
    read,
    SENSOR_DATA,
    storage_for,
    storage_of,
    TYPESTORE,
)
from pma_model_ros.bags.synthetic import record_simulation, START_NS

STORAGES = ('mcap', 'sqlite3')
T = TYPESTORE.types


def pressure_msg(typestore, sec: int, value: float):
    types = typestore.types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec, 0), frame_id='m'
    )
    return types[FLUID_PRESSURE](header, value, 0.0)


@pytest.mark.parametrize('storage', STORAGES)
def test_round_trip_and_storage(tmp_path, storage):
    out = tmp_path / 'bag'
    with BagWriter(out, storage) as bag:
        conn = bag.topic('/m/pressure', FLUID_PRESSURE, [SENSOR_DATA])
        for k in range(5):
            bag.write(conn, (10 + k) * 10**9, pressure_msg(TYPESTORE, 10 + k, 2e5 + k))
    assert storage_of(out) == storage
    assert [p.name for p in tmp_path.iterdir()] == ['bag']  # no temporary left beside it
    got = list(read(out))
    assert [(t, ns) for t, ns, _ in got] == [('/m/pressure', (10 + k) * 10**9) for k in range(5)]
    assert [m.fluid_pressure for _, _, m in got] == [2e5 + k for k in range(5)]
    assert [m.header.stamp.sec for _, _, m in got] == [10 + k for k in range(5)]
    # the storage file alone reads too (what ros2 bag record writes inside the directory)
    file = next(out.glob('*.mcap' if storage == 'mcap' else '*.db3'))
    assert storage_of(file) == storage and len(list(read(file))) == 5


@pytest.mark.parametrize('name, storage', [('run1.mcap', 'mcap'), ('run1.db3', 'sqlite3')])
def test_a_name_with_a_storage_suffix_is_that_one_file(tmp_path, name, storage):
    """``--record run1.mcap`` makes run1.mcap (it made run1.mcap/run1.mcap.mcap)."""
    with BagWriter(tmp_path / name) as bag:
        conn = bag.topic('/m/pressure', FLUID_PRESSURE, [SENSOR_DATA])
        bag.write(conn, 10**9, pressure_msg(TYPESTORE, 1, 2e5))
    assert [p.name for p in tmp_path.iterdir()] == [name] and (tmp_path / name).is_file()
    assert storage_of(tmp_path / name) == storage and len(list(read(tmp_path / name))) == 1
    with pytest.raises(BagError, match='run2.mcap: a .mcap file cannot hold sqlite3'):
        BagWriter(tmp_path / 'run2.mcap', 'sqlite3')


def test_storage_for_new_bags():
    assert storage_for('run.mcap') == 'mcap' and storage_for('run.db3') == 'sqlite3'
    assert storage_for('run') == 'mcap' and storage_for('run.mcap', 'sqlite3') == 'sqlite3'
    with pytest.raises(BagError, match='unknown storage'):
        storage_for('run', 'rosbag1')


def test_failed_writer_leaves_nothing(tmp_path):
    out = tmp_path / 'bag'
    with pytest.raises(RuntimeError):
        with BagWriter(out) as bag:
            conn = bag.topic('/p', FLUID_PRESSURE)
            bag.write(conn, 1, pressure_msg(TYPESTORE, 1, 1e5))
            raise RuntimeError('interrupted')
    assert list(tmp_path.iterdir()) == []
    out.mkdir()
    with pytest.raises(BagError, match='exists already'):
        BagWriter(out)


@pytest.mark.parametrize('storage', STORAGES)
def test_synthetic_recording_has_the_simulator_topics(tmp_path, storage):
    bag = record_simulation(tmp_path / 'sim', 0.5, '/m1', storage, rate=100.0)
    topics = {}
    for topic, time_ns, msg in read(bag):
        topics.setdefault(topic, []).append((time_ns, msg))
    assert sorted(topics) == ['/m1/force', '/m1/muscle_state', '/m1/pressure']
    assert all(len(v) == 50 for v in topics.values())
    state_time, state = topics['/m1/muscle_state'][1]
    assert (
        state_time
        == START_NS + 10**7
        == state.header.stamp.sec * 10**9 + state.header.stamp.nanosec
    )
    assert state.name == ['DMSP-10-250'] and 0.198 <= state.position[0] <= 0.25
    forces = [m.wrench.force.x for _, m in topics['/m1/force']]
    assert np.allclose(forces, [m.effort[0] for _, m in topics['/m1/muscle_state']])


def test_other_distro_definitions(tmp_path):
    """ROS 1 definitions (Header.seq) are refused; Humble's, equal to Jazzy's for these types, are
    read.
    """
    for store, name in ((Stores.ROS1_NOETIC, 'noetic'), (Stores.ROS2_HUMBLE, 'humble')):
        typestore = get_typestore(store)
        with Writer(tmp_path / name, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conn = writer.add_connection('/m/pressure', FLUID_PRESSURE, typestore=typestore)
            if name == 'humble':
                msg = pressure_msg(typestore, 3, 2e5)
            else:
                types = typestore.types
                header = types['std_msgs/msg/Header'](
                    7, types['builtin_interfaces/msg/Time'](3, 0), 'm'
                )
                msg = types[FLUID_PRESSURE](header, 2e5, 0.0)
            writer.write(conn, 3 * 10**9, typestore.serialize_cdr(msg, FLUID_PRESSURE))
    with pytest.raises(BagError, match="differs from ROS 2 Jazzy's"):
        list(read(tmp_path / 'noetic'))
    assert [m.fluid_pressure for _, _, m in read(tmp_path / 'humble')] == [2e5]


@pytest.mark.parametrize('storage', STORAGES)
@pytest.mark.parametrize('keep', [0.0, 0.5, 0.97])
def test_truncated_bag_is_a_bag_error(tmp_path, storage, keep):
    bag = record_simulation(tmp_path / 'sim', 2.0, '/m1', storage, rate=100.0)
    file = next(p for p in bag.iterdir() if p.name != 'metadata.yaml')
    data = file.read_bytes()
    file.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(BagError, match='truncated'):
        list(read(bag))


def test_missing_and_non_bags(tmp_path):
    with pytest.raises(BagError, match='bag not found'):
        list(read(tmp_path / 'nope'))
    with pytest.raises(BagError, match='not a readable rosbag2 bag'):
        list(read(tmp_path))  # a directory without metadata.yaml
    (tmp_path / 'x.mcap').write_text('not a bag')
    with pytest.raises(BagError, match='not a readable rosbag2 bag'):
        list(read(tmp_path / 'x.mcap'))
    bag = record_simulation(tmp_path / 'sim', 0.1, '/m1', rate=100.0)
    with pytest.raises(BagError, match='no topic /m2/pressure'):
        list(read(bag, ['/m2/pressure']))
