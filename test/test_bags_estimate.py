"""``pma-model bag estimate``: the model node's decisions over a recording, on both storages; bad
input.
"""

import csv
import math
import subprocess
import sys

from hypothesis import event, example, given
from hypothesis import strategies as st
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

from bag_reference import csv_rows, per_message, raw_messages, same
from budget import examples
from conftest import CONFIGS, edited_copy
from pma_model_ros.bags.bag_io import (
    BagWriter,
    DIAGNOSTIC_ARRAY,
    FLUID_PRESSURE,
    JOINT_STATE,
    read,
    SENSOR_DATA,
    TYPESTORE,
    WRENCH_STAMPED,
)
from pma_model_ros.bags.estimate import CHUNK, estimate_bag
from pma_model_ros.bags.synthetic import record_simulation, START_NS
from pma_model_ros.core.files.param_file import node_settings, read_parameters
from pma_model_ros.core.physics.hysteresis import branches
from pma_model_ros.core.runtime.engine import Engine

T = TYPESTORE.types
SETTINGS = node_settings(read_parameters(CONFIGS['DMSP-10-250']))
JOINT = SETTINGS.joint_name
NS = '/arm/left'


def header(ns: int):
    return T['std_msgs/msg/Header'](
        T['builtin_interfaces/msg/Time'](ns // 10**9, ns % 10**9), 'sensor'
    )


def eventful_bag(path, storage):
    """3 s at 100 Hz with a NaN pressure, a JointState without the joint, a stale length and force
    commands.
    """
    Vector3, Wrench = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Wrench']
    with BagWriter(path, storage) as bag:
        p_conn = bag.topic(f'{NS}/pressure', FLUID_PRESSURE, [SENSOR_DATA])
        s_conn = bag.topic(f'{NS}/muscle_state', JOINT_STATE, [SENSOR_DATA])
        c_conn = bag.topic(f'{NS}/force_command', WRENCH_STAMPED)
        for k in range(300):
            t = START_NS + k * 10**7
            pressure = 101325.0 + 3e5 + 2e5 * math.sin(k / 20) if k != 50 else math.nan
            bag.write(p_conn, t + 2 * 10**5, T[FLUID_PRESSURE](header(t), pressure, 0.0))
            stamp = t - 5 * 10**8 if k == 120 else t  # one length 0.5 s old: stale
            name = ['elbow'] if k == 80 else [JOINT]
            state = T[JOINT_STATE](
                header(stamp),
                name,
                np.array([0.22 + 0.02 * math.cos(k / 30)]),
                np.array([-0.02 * math.sin(k / 30) / 0.3]),
                np.array([]),
            )
            bag.write(s_conn, t + 4 * 10**5, state)
            if k % 10 == 5:
                wrench = T[WRENCH_STAMPED](
                    header(t), Wrench(Vector3(100.0 + k / 3, 0.0, 0.0), Vector3(0.0, 0.0, 0.0))
                )
                bag.write(c_conn, t + 6 * 10**5, wrench)
    return path


def node_reference(bag):
    """What model_node's callbacks make of the bag, message by message: the engine's calls on the
    messages rosbags deserializes (not the wire layer).
    """
    est = Engine([SETTINGS.config], hold=1.0)
    estimates, commands = [], []
    for topic, now, msg in read(bag):
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        estimated = None
        if topic.endswith('/pressure'):
            estimated = est.pressure(0, float(msg.fluid_pressure), stamp, now)
        elif topic.endswith('/muscle_state'):
            if list(msg.name) == [JOINT]:
                rate = msg.velocity[0] if len(msg.velocity) else math.nan
                estimated = est.length(0, float(msg.position[0]), float(rate), stamp, now)
            else:
                est.reject(0, 'muscle_state', f"joint '{JOINT}' not in {list(msg.name)}", now)
        elif (pressure := est.command(0, msg.wrench.force.x, now, stamp)) is not None:
            commands.append((now, pressure))
        if estimated:
            estimates.append((now, est.stamp, est.forces.item(0)))
    return estimates, commands, est.counts(0)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_offline_estimate_is_the_node_message_by_message(tmp_path, storage):
    bag = eventful_bag(tmp_path / 'in', storage)
    summary = estimate_bag(
        bag, SETTINGS, tmp_path / 'out', csv=tmp_path / 'est.csv', progress=False
    )
    expected, commands, counts = node_reference(bag)
    out = {}
    for topic, time_ns, msg in read(tmp_path / 'out'):
        out.setdefault(topic, []).append((time_ns, msg))
    got = [
        (t, m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m.wrench.force.x)
        for t, m in out[f'{NS}/force_estimate']
    ]
    assert len(expected) > 500 and got == expected  # same pairs, stamps, forces (exact)
    assert {m.header.frame_id for _, m in out[f'{NS}/force_estimate']} == {SETTINGS.frame_id}
    assert [(t, m.fluid_pressure) for t, m in out[f'{NS}/pressure_command']] == commands and len(
        commands
    ) == 30
    assert summary.counts == counts
    assert summary.reasons == {  # the two rejections of the reference, by reason
        SETTINGS.joint_name: {
            'pressure': (1, 'invalid input: pressure is nan Pa'),
            f"joint '{JOINT}' not in ['elbow']": (
                1,
                f"invalid input: joint '{JOINT}' not in ['elbow']",
            ),
        }
    }
    assert (
        counts['rejected pressure'] == 1
        and counts['rejected muscle_state'] == 1
        and counts['stale skipped'] >= 1
    )
    # the originals, unchanged
    originals = {
        topic: [(t, m) for t, m in msgs]
        for topic, msgs in out.items()
        if 'force_' not in topic and topic != '/diagnostics' and 'pressure_command' not in topic
    }
    assert {t: len(v) for t, v in originals.items()} == {
        f'{NS}/pressure': 300,
        f'{NS}/muscle_state': 300,
    }
    # diagnostics: ERROR until both inputs are in, OK, ERROR for the bad inputs and the stale
    # length, 1 Hz beside
    levels = [(t, m.status[0].level, m.status[0].message) for t, m in out['/diagnostics']]
    assert levels[0] == (START_NS + 2 * 10**5, 2, 'no muscle_state received yet')
    assert any(m.startswith('invalid input: pressure is nan') for _, _, m in levels)
    assert any("joint 'DMSP-10-250' not in ['elbow']" in m for _, _, m in levels)
    assert any(m == 'estimating' for _, level, m in levels) and levels[-1][1] < 2, levels[-1]
    # named as the live node in the recording's namespace names them (nodes/diagnostics.py)
    assert {(m.status[0].name, m.status[0].hardware_id) for _, m in out['/diagnostics']} == {
        (f'arm/left/model_node: {JOINT}', f'/arm/left/model_node/{JOINT}')
    }
    with open(tmp_path / 'est.csv') as f:
        rows = list(csv.DictReader(f))
    assert [(int(r['log_time_ns']), float(r['force_n'])) for r in rows] == [
        (t, f) for t, _, f in expected
    ]


def bag_estimate(bag, *args: str, config=CONFIGS['DMSP-10-250']) -> subprocess.CompletedProcess:
    """``pma-model bag estimate <bag> --config <config> <args>`` as a user runs it."""
    return subprocess.run(
        [sys.executable, '-m', 'pma_model_ros.cli', 'bag', 'estimate', str(bag)]
        + ['--config', str(config), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_storage_conversion_and_cli(tmp_path):
    bag = record_simulation(tmp_path / 'sim.mcap', 1.0, '/m1', rate=100.0)
    proc = bag_estimate(bag, '--out', str(tmp_path / 'out'), '--storage', 'sqlite3')
    assert proc.returncode == 0, proc.stderr
    assert '/m1: 300 messages read; wrote 199 force_estimate' in proc.stdout
    assert (tmp_path / 'out' / 'out.db3').is_file()
    assert sum(1 for topic, _, _ in read(tmp_path / 'out') if topic == '/m1/force_estimate') == 199


def wrong_type_bag(path):
    with BagWriter(path) as bag:
        conn = bag.topic('/m1/pressure', WRENCH_STAMPED)
        bag.topic('/m1/muscle_state', JOINT_STATE)
        bag.write(
            conn,
            START_NS,
            T[WRENCH_STAMPED](
                header(START_NS),
                T['geometry_msgs/msg/Wrench'](
                    T['geometry_msgs/msg/Vector3'](1.0, 0.0, 0.0),
                    T['geometry_msgs/msg/Vector3'](0.0, 0.0, 0.0),
                ),
            ),
        )


def noetic_bag(path):
    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        writer.add_connection('/m1/pressure', FLUID_PRESSURE, typestore=store)
        writer.add_connection('/m1/muscle_state', JOINT_STATE, typestore=store)


def truncated_bag(path):
    record_simulation(path, 1.0, '/m1', rate=100.0)
    file = path / f'{path.name}.mcap'
    file.write_bytes(file.read_bytes()[:20000])


def force_only_bag(path):
    with BagWriter(path) as bag:
        bag.topic('/m1/force', WRENCH_STAMPED)


@pytest.mark.parametrize(
    'make, words',
    [
        (None, 'bag not found'),
        (truncated_bag, 'truncated'),
        (force_only_bag, 'no <namespace>/pressure and <namespace>/muscle_state topics'),
        (
            wrong_type_bag,
            'topic /m1/pressure has type geometry_msgs/msg/WrenchStamped, expected '
            'sensor_msgs/msg/FluidPressure',
        ),
        (noetic_bag, "differs from ROS 2 Jazzy's"),
    ],
)
def test_bad_bags_one_line_exit_2_no_output(tmp_path, make, words):
    bag = tmp_path / 'in'
    if make is not None:
        make(bag)
    out_dir = tmp_path / 'results'
    out_dir.mkdir()
    proc = bag_estimate(bag, '--out', str(out_dir / 'out'), '--csv', str(out_dir / 'e.csv'))
    assert proc.returncode == 2 and proc.stdout == ''
    assert (
        proc.stderr.count('\n') == 1 and words in proc.stderr and 'Traceback' not in proc.stderr
    ), proc.stderr
    assert list(out_dir.iterdir()) == []


EXAMPLE = CONFIGS['DMSP-10-250'].parent / 'example_multi_muscle.yaml'


def multi_muscle_bag(
    path, combined: bool, names: list[str], ticks: int = 200, offsets: list[float] | None = None
):
    """``ticks`` at 100 Hz of every muscle of the example file: lengths then pressures each tick,
    as combined JointStates or as each muscle's own topics; the inputs of each tick.  With
    ``offsets`` (combined): then a ``measured_forces`` JointState of the tick's stamp, each
    muscle's force its model's at the tick's inputs (branch 0) plus its offset [N].
    """
    specs = {name: muscle_model(read_parameters(EXAMPLE), name=name) for name in names}
    inputs = []
    with BagWriter(path, 'mcap') as bag:
        if combined:
            conns = (
                bag.topic(f'{NS}/muscle_states', JOINT_STATE, [SENSOR_DATA]),
                bag.topic(f'{NS}/muscle_pressures', JOINT_STATE, [SENSOR_DATA]),
                bag.topic(f'{NS}/measured_forces', JOINT_STATE, [SENSOR_DATA]),
            )
        else:
            conns = {
                n: (
                    bag.topic(f'{NS}/{n}/muscle_state', JOINT_STATE, [SENSOR_DATA]),
                    bag.topic(f'{NS}/{n}/pressure', FLUID_PRESSURE, [SENSOR_DATA]),
                )
                for n in names
            }
        for k in range(ticks):
            t = START_NS + k * 10**7
            gauge = np.array([3e5 + 2e5 * math.sin(k / 15 + i) for i in range(len(names))])
            length = np.array(
                [
                    specs[n].domain.length_min
                    + (specs[n].domain.length_max - specs[n].domain.length_min)
                    * (0.5 + 0.5 * math.cos(k / 25 + i))
                    for i, n in enumerate(names)
                ]
            )
            rate = np.array([-0.01 * math.sin(k / 25 + i) for i in range(len(names))])
            inputs.append((t + 4 * 10**5, gauge, length, rate))
            empty = np.zeros(0)
            if combined:
                bag.write(
                    conns[0],
                    t + 2 * 10**5,
                    T[JOINT_STATE](header(t), list(names), length, rate, empty),
                )
                bag.write(
                    conns[1],
                    t + 4 * 10**5,
                    T[JOINT_STATE](header(t), list(names), gauge + 101325.0, empty, empty),
                )
                if offsets is not None:
                    forces = [
                        float(specs[n].force(gauge[i], length[i], 0.0).force) + offsets[i]
                        for i, n in enumerate(names)
                    ]
                    bag.write(
                        conns[2],
                        t + 6 * 10**5,
                        T[JOINT_STATE](header(t), list(names), empty, empty, np.array(forces)),
                    )
            else:
                for i, n in enumerate(names):
                    bag.write(
                        conns[n][0],
                        t + 2 * 10**5,
                        T[JOINT_STATE](header(t), [n], length[i : i + 1], rate[i : i + 1], empty),
                    )
                    bag.write(
                        conns[n][1],
                        t + 4 * 10**5,
                        T[FLUID_PRESSURE](header(t), gauge[i] + 101325.0, 0.0),
                    )
    return inputs


def muscle_model(parameters, name):
    from pma_model_ros.core.files.param_file import muscle_model as build

    return build(parameters[name])


@pytest.mark.parametrize('mode', ['combined', 'per_muscle'])
def test_multi_muscle_parameter_file(tmp_path, mode):
    """Bag estimate of a muscles: file in both input modes: each muscle's force, at each tick's
    pressures, is its own model's at that tick's inputs (the core, muscle by muscle).
    """
    from pma_model_ros.core.files.param_file import all_node_settings

    parameters = read_parameters(EXAMPLE)
    names = parameters['muscles']
    inputs = multi_muscle_bag(tmp_path / 'in', mode == 'combined', names)
    summary = estimate_bag(
        tmp_path / 'in',
        all_node_settings(parameters),
        tmp_path / 'out',
        names=names,
        combined=mode == 'combined',
        progress=False,
    )
    models = [muscle_model(parameters, n) for n in names]
    # a hysteresis branch follows each muscle's length series (play operator, the default 0.5 mm
    # deadband)
    branch = np.array(
        [branches([length[i] for _, _, length, _ in inputs], 0.5e-3) for i in range(len(names))]
    ).T
    expected = {
        t: [float(m.force(g, L, b).force) for m, g, L, b in zip(models, gauge, length, branch[k])]
        for k, (t, gauge, length, _) in enumerate(inputs)
    }
    got: dict[int, dict[str, float]] = {}
    for topic, time_ns, msg in read(tmp_path / 'out'):
        if topic == f'{NS}/force_estimates':
            got.setdefault(time_ns, {}).update(zip(msg.name, msg.effort.tolist()))
        elif topic.endswith('/force_estimate') and time_ns in expected:
            got.setdefault(time_ns, {})[topic.split('/')[-2]] = msg.wrench.force.x
    checked = [t for t in expected if t in got]
    assert len(checked) == len(inputs)
    for t in checked:
        assert [got[t][n] for n in names] == pytest.approx(expected[t], rel=1e-9, abs=1e-6), t
    assert summary.counts['estimates'] == summary.estimates == 4 * (2 * len(inputs) - 1)
    statuses = [m.status for topic, _, m in read(tmp_path / 'out') if topic == '/diagnostics']
    assert {(s.name, s.hardware_id) for s in statuses[-1]} == {
        (f'arm/left/model_node: {n}', f'/arm/left/model_node/{n}') for n in names
    }


# --- random recordings: the one pass publishes what the node does, message for message
# ----------------------------------------------------------------------------------


def variant_settings(name: str):
    """Node settings of the single-muscle variants the random recordings use."""
    if name == 'martens':
        return SETTINGS
    if name == 'hildebrandt gauge':  # its float and array coefficients differ in ulps
        parameters = read_parameters(CONFIGS['DMSP-10-250'])
        return node_settings(parameters | {'pressure_reference': 'gauge'}, 'hildebrandt')
    parameters = read_parameters(CONFIGS['DMSP-10-100'])  # sarosi_hysteresis
    if name == 'hysteresis by pressure':
        parameters = parameters | {'hysteresis': {'input': 'pressure'}}
    return node_settings(parameters)


VARIANTS = ('martens', 'hildebrandt gauge', 'hysteresis by length', 'hysteresis by pressure')

#: One recorded message: topic (the node's inputs; a load cell's force and another node's
#: /diagnostics, which are no inputs), log-time step [ms] (0: same time), stamp - log time [ms]
#: (some stale, some from the future), value (a unit draw mapped into the muscle's ranges, or NaN
#: and out of range values), and its form: usual, another joint's JointState, a JointState of two
#: joints, another frame_id (a new layout), big-endian CDR (the deserializer), an infinite rate,
#: a zero stamp (a command taken as sent now; an input stale).
step_strategy = st.tuples(
    st.sampled_from(['pressure', 'muscle_state'] * 4 + ['force_command'] * 2 + ['force', 'other']),
    st.sampled_from([0, 1, 1, 1, 2, 5, 150, 1300]),
    st.sampled_from([0] * 6 + [-1, -2, -120, 80]),
    st.one_of(*[st.floats(0.0, 1.0)] * 7, st.sampled_from([math.nan, -2.0, 30.0])),
    st.sampled_from(
        ['usual'] * 12 + ['other', 'two', 'frame', 'big-endian', 'inf rate', 'unstamped']
    ),
)


def warm_up(ticks: int) -> list[tuple]:
    """``ticks`` ms of a usual pressure and length each (lengths moving to and fro)."""
    return [
        (topic, 1 if topic == 'pressure' else 0, 0, 0.1 + 0.08 * ((7 * i) % 11), 'usual')
        for i in range(ticks)
        for topic in ('pressure', 'muscle_state')
    ]


#: A pressure and a length stamped 120 ms before their log time and 1 ms apart (a stale pair for
#: ``approximate_time``, which the draws' independent stamps almost never make), between usual
#: ticks.
STALE_PAIR = warm_up(5) + [
    ('pressure', 1, -120, 0.5, 'usual'),
    ('muscle_state', 0, -119, 0.5, 'usual'),
    *warm_up(3),
]

#: A recording: a warm-up of up to 15 usual ticks (pairs from the start), then random steps.
messages_strategy = st.tuples(
    st.integers(0, 15), st.lists(step_strategy, min_size=1, max_size=40)
).map(lambda drawn: warm_up(drawn[0]) + drawn[1])


def random_bag(path, storage, steps, settings=SETTINGS):
    """A recording of the steps for the muscle of ``settings`` (values from unit draws)."""
    Vector3, Wrench = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Wrench']
    model, joint = settings.config.model, settings.joint_name
    low, high = model.domain.length_min, model.domain.length_max
    gauge = settings.config.pressure_reference == 'gauge'
    with BagWriter(path, storage) as bag:
        types = {
            'pressure': (f'{NS}/pressure', FLUID_PRESSURE),
            'muscle_state': (f'{NS}/muscle_state', JOINT_STATE),
            'force_command': (f'{NS}/force_command', WRENCH_STAMPED),
            'force': (f'{NS}/force', WRENCH_STAMPED),
            'other': ('/diagnostics', DIAGNOSTIC_ARRAY),
        }
        conns = {key: bag.topic(name, kind, [SENSOR_DATA]) for key, (name, kind) in types.items()}
        t = START_NS
        for topic, step, offset, unit, form in steps:
            t += step * 10**6
            stamp = header(0 if form == 'unstamped' else t + offset * 10**6)
            if form == 'frame':
                stamp.frame_id = 'another_frame'
            usual = 0 <= unit <= 1
            if topic == 'pressure':
                value = (1.2 * unit - 0.15) * model.spec.max_pressure if usual else unit * 1e5
                msg = T[FLUID_PRESSURE](stamp, value + (0.0 if gauge else 101325.0), 0.0)
            elif topic == 'muscle_state':
                length = low + (1.3 * unit - 0.15) * (high - low) if usual else unit
                rate = [math.inf if form == 'inf rate' else 0.01 * (unit - 0.5)]
                names = {'other': ['elbow'], 'two': ['elbow', joint]}.get(form, [joint])
                lengths = [0.2, length] if form == 'two' else [length]
                msg = T[JOINT_STATE](
                    stamp,
                    names,
                    np.array(lengths),
                    np.array(rate * len(names) if unit == unit else []),
                    np.array([]),
                )
            elif topic == 'other':  # another node's status
                status = T['diagnostic_msgs/msg/DiagnosticStatus'](1, 'other: x', 'hm', 'x', [])
                msg = T[DIAGNOSTIC_ARRAY](stamp, [status])
            else:
                force = 300 * unit if unit == unit else math.nan
                msg = T[WRENCH_STAMPED](
                    stamp, Wrench(Vector3(force, 0.0, 0.0), Vector3(0.0, 0.0, 0.0))
                )
            kind = types[topic][1]
            data = TYPESTORE.serialize_cdr(msg, kind, little_endian=form != 'big-endian')
            bag.write_raw(conns[topic], t, data)
    return path


#: What a drawn recording exercised, by counter label prefix: shown by
#: ``pytest --hypothesis-show-statistics`` (docs/bags.md quotes the counts).
COVERAGE = {
    'rejected': 'rejects an input',
    'stale skipped': 'skips a stale input',
    'pressure commands': 'commands a pressure',
    'unpaired': 'loses an input to pairing_slop',
}


def record_coverage(counts: dict[str, int], estimates: int) -> None:
    """Hypothesis events of one example: whether (and how often) it estimated; :data:`COVERAGE`."""
    event('estimates' if estimates else 'no estimate')
    if estimates >= 10:
        event('ten estimates or more')
    for prefix, what in COVERAGE.items():
        if any(n for label, n in counts.items() if label.startswith(prefix)):
            event(what)


@pytest.mark.parametrize('outputs_only', [True, False], ids=['outputs-only', 'copying'])
@pytest.mark.parametrize('pairing', ['every_input', 'approximate_time'])
@examples(60)
@given(
    steps=messages_strategy,
    storage=st.sampled_from(['mcap', 'sqlite3']),
    variant=st.sampled_from(VARIANTS),
    chunk=st.sampled_from([3, 10, CHUNK]),
)
@example(steps=STALE_PAIR, storage='mcap', variant='martens', chunk=3)
def test_random_recordings_published_as_the_node_message_by_message(
    tmp_path_factory, pairing, outputs_only, steps, storage, variant, chunk
):
    """Random interleavings of pressure, muscle_state and force_command, with gaps (up to 1.3 s:
    the 1 Hz status between), stale and future stamps, bad messages (NaN, out of range, another
    joint) and unusual bytes (a new layout, big-endian): ``bag estimate``'s output bag holds what
    the node's callbacks publish message by message (:mod:`bag_reference`), byte for byte and in
    the same order: estimates, commands, every /diagnostics status (levels, texts, counters,
    rates), the copies; the same counters and CSV rows.  Four muscles: martens; hildebrandt with a
    gauge sensor; a hysteresis model following the length, and one following the pressure.  The
    recording is decided in stretches of 3, 10 or all messages (the state carries over).
    """
    tmp = tmp_path_factory.mktemp('bag')
    chosen = variant_settings(variant)
    bag = random_bag(tmp / 'in', storage, steps, chosen)
    slop = 0.0015
    summary = estimate_bag(
        bag,
        chosen,
        tmp / 'out',
        csv=tmp / 'est.csv',
        progress=False,
        outputs_only=outputs_only,
        pairing=pairing,
        slop=slop,
        chunk=chunk,
    )
    want, rows, counts = per_message(
        bag, [chosen], NS, outputs_only=outputs_only, pairing=pairing, slop=slop
    )
    got = raw_messages(tmp / 'out')
    assert [m[:2] for m in got] == [m[:2] for m in want]  # topics and log times, in order
    assert got == want  # and every byte
    assert summary.counts == counts
    assert summary.estimates == len(rows)
    record_coverage(counts, len(rows))
    got_rows = csv_rows(tmp / 'est.csv')
    assert len(got_rows) == len(rows)
    for a, b in zip(got_rows, rows):
        assert a[:2] == b[:2] and a[5:] == b[5:] and all(map(same, a[2:5], b[2:5])), (a, b)


#: One message of a four-muscle recording: topic, log-time step [ms], stamp - log time [ms], a
#: unit draw per muscle, the form (combined JointStates: all muscles in order, some, shuffled, an
#: extra joint, mismatched arrays, empty; a muscle's own topic: usual, another joint,
#: big-endian), and which muscle (its own topic; the one a combined 'some' leaves out).
multi_step_strategy = st.tuples(
    st.sampled_from(['pressure', 'muscle_state'] * 2 + ['force_command']),
    st.sampled_from([0, 1, 1, 1, 2, 150, 1300]),
    st.sampled_from([0] * 6 + [-2, -120, 80]),
    st.lists(
        st.one_of(*[st.floats(0.0, 1.0)] * 9, st.sampled_from([math.nan, -2.0, 30.0])),
        min_size=4,
        max_size=4,
    ),
    st.sampled_from(['all'] * 8 + ['some', 'shuffled', 'extra', 'mismatched', 'empty']),
    st.integers(0, 3),
)


def multi_warm_up(ticks: int) -> list[tuple]:
    """``ticks`` ms of usual pressures and lengths of every muscle."""
    return [
        (t, 1 if t == 'pressure' else 0, 0, [0.1 + 0.08 * ((7 * i + k) % 11) for k in range(4)])
        + ('all', i % 4)
        for i in range(ticks)
        for t in ('pressure', 'muscle_state')
    ]


def random_multi_bag(path, storage, steps, settings, names, combined):
    """A recording of the steps for the muscles of ``settings`` (named ``names``)."""
    Vector3, Wrench = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Wrench']
    models = [s.config.model for s in settings]
    joints = [s.joint_name for s in settings]
    with BagWriter(path, storage) as bag:
        if combined:
            conns = {
                t: bag.topic(f'{NS}/{name}', JOINT_STATE, [SENSOR_DATA])
                for t, name in (
                    ('pressure', 'muscle_pressures'),
                    ('muscle_state', 'muscle_states'),
                    ('force_command', 'force_commands'),
                )
            }
        else:
            conns = {
                (t, k): bag.topic(f'{NS}/{n}/{t}', kind, [SENSOR_DATA])
                for k, n in enumerate(names)
                for t, kind in (
                    ('pressure', FLUID_PRESSURE),
                    ('muscle_state', JOINT_STATE),
                    ('force_command', WRENCH_STAMPED),
                )
            }
        t = START_NS
        for topic, step, offset, units, form, which in steps:
            t += step * 10**6
            values = []
            for model, unit in zip(models, units):
                usual = 0 <= unit <= 1
                if topic == 'pressure':
                    gauge = (1.2 * unit - 0.15) * model.spec.max_pressure
                    values.append(101325.0 + gauge if usual else unit * 1e5)
                elif topic == 'muscle_state':
                    low, high = model.domain.length_min, model.domain.length_max
                    values.append(low + (1.3 * unit - 0.15) * (high - low) if usual else unit)
                else:
                    values.append(300 * unit if unit == unit else math.nan)
            rates = [0.01 * (u - 0.5) if u == u else math.inf for u in units]
            if combined:
                order = list(range(4))
                if form == 'some':
                    order.remove(which)
                elif form == 'shuffled':
                    order = order[which:] + order[:which]
                names_out = [joints[k] for k in order] + (['elbow'] if form == 'extra' else [])
                numbers = [values[k] for k in order] + ([0.1] if form == 'extra' else [])
                speeds = [rates[k] for k in order] + ([0.0] if form == 'extra' else [])
                if form == 'mismatched':
                    numbers = numbers[:-1]
                if form == 'empty':
                    names_out, numbers, speeds = [], [], []
                empty = np.array([])
                fields = {
                    'pressure': (np.array(numbers), empty, empty),
                    'muscle_state': (np.array(numbers), np.array(speeds), empty),
                    'force_command': (empty, empty, np.array(numbers)),
                }[topic]
                msg = T[JOINT_STATE](header(t + offset * 10**6), names_out, *fields)
                bag.write(conns[topic], t, msg)
                continue
            k = which
            stamp = header(t + offset * 10**6)
            if topic == 'pressure':
                msg = T[FLUID_PRESSURE](stamp, values[k], 0.0)
            elif topic == 'muscle_state':
                joint = 'elbow' if form == 'extra' else joints[k]
                msg = T[JOINT_STATE](
                    stamp, [joint], np.array([values[k]]), np.array([rates[k]]), np.array([])
                )
            else:
                msg = T[WRENCH_STAMPED](
                    stamp, Wrench(Vector3(values[k], 0.0, 0.0), Vector3(0.0, 0.0, 0.0))
                )
            kind = {'pressure': FLUID_PRESSURE, 'muscle_state': JOINT_STATE}.get(
                topic, WRENCH_STAMPED
            )
            data = TYPESTORE.serialize_cdr(msg, kind, little_endian=form != 'mismatched')
            bag.write_raw(conns[topic, k], t, data)


@pytest.mark.parametrize('pairing', ['every_input', 'approximate_time'])
@pytest.mark.parametrize('mode', ['combined', 'per_muscle'])
@examples(40)
@given(
    ticks=st.integers(0, 10),
    steps=st.lists(multi_step_strategy, min_size=1, max_size=30),
    storage=st.sampled_from(['mcap', 'sqlite3']),
    outputs_only=st.booleans(),
    chunk=st.sampled_from([5, CHUNK]),
)
def test_random_multi_muscle_recordings_published_as_the_node_message_by_message(
    tmp_path_factory, mode, pairing, ticks, steps, storage, outputs_only, chunk
):
    """Four muscles of the example file (martens, hildebrandt, and a hysteresis model), in both
    input modes: random JointStates of every muscle (some missing, shuffled, an extra joint,
    mismatched or empty arrays) or each muscle's own topics (another joint, big-endian): the
    output bag is the node's, byte for byte and in order; the same counters and CSV rows.
    """
    from pma_model_ros.core.files.param_file import all_node_settings

    tmp = tmp_path_factory.mktemp('bag')
    parameters = read_parameters(EXAMPLE)
    names, combined = parameters['muscles'], mode == 'combined'
    chosen = all_node_settings(parameters)
    random_multi_bag(tmp / 'in', storage, multi_warm_up(ticks) + steps, chosen, names, combined)
    slop = 0.0015
    summary = estimate_bag(
        tmp / 'in',
        chosen,
        tmp / 'out',
        names=names,
        combined=combined,
        csv=tmp / 'est.csv',
        progress=False,
        outputs_only=outputs_only,
        pairing=pairing,
        slop=slop,
        chunk=chunk,
    )
    want, rows, counts = per_message(
        tmp / 'in',
        chosen,
        NS,
        names,
        combined,
        outputs_only=outputs_only,
        pairing=pairing,
        slop=slop,
    )
    got = raw_messages(tmp / 'out')
    assert [m[:2] for m in got] == [m[:2] for m in want]
    assert got == want
    assert summary.counts == counts
    assert summary.estimates == len(rows)
    record_coverage(counts, len(rows))
    got_rows = csv_rows(tmp / 'est.csv')
    assert len(got_rows) == len(rows)
    for a, b in zip(got_rows, rows):
        assert a[:2] == b[:2] and a[5:] == b[5:] and all(map(same, a[2:5], b[2:5])), (a, b)


def test_pairing_comes_from_the_parameter_file(tmp_path):
    """``pairing: approximate_time`` in the parameter file: bag estimate pairs as that node does
    (one estimate per tick of the simulator, whose pressure and length share a stamp), not every
    input.
    """
    bag = record_simulation(tmp_path / 'sim.mcap', 1.0, '/m1', rate=100.0)
    config = edited_copy(
        CONFIGS['DMSP-10-250'],
        tmp_path,
        '    max_input_age: 0.1\n',
        '    max_input_age: 0.1\n    pairing: approximate_time\n    pairing_slop: 0.001\n',
    )
    words = {}
    for name, path in (('every', CONFIGS['DMSP-10-250']), ('approximate', config)):
        proc = bag_estimate(bag, '--out', str(tmp_path / name), '--outputs-only', config=path)
        assert proc.returncode == 0, proc.stderr
        words[name] = proc.stdout
    assert 'wrote 199 force_estimate' in words['every']
    assert 'wrote 100 force_estimate' in words['approximate']


@pytest.mark.parametrize(
    'config, joint, words',
    [
        (
            'DMSP-20-300',
            None,
            "500 × invalid input: joint 'DMSP-20-300' not in ['DMSP-10-250']; the recording's "
            'JointState names (in brackets) hold no joint of',
        ),
        (
            'DMSP-10-100',
            'DMSP-10-250',
            # the simulated DMSP-10-250 at 0.198 m (its shortest) > L0/cos(Theta0) of the 10-100
            'invalid input: length 0.198 m outside the geometry (0, 0.1139) m (the first); the '
            'recorded lengths lie outside the geometry of the muscle of',
        ),
    ],
)
def test_estimate_with_another_muscles_file_says_why_and_writes_nothing(
    tmp_path, config, joint, words
):
    """Another muscle's file: nothing estimated, so nothing written and exit code 2, with the
    reason of the rejections and their count (5 s at 100 Hz: 500 muscle_states).
    """
    bag = record_simulation(tmp_path / 'sim.mcap', 5.0, '/m1', rate=100.0)
    out, table = tmp_path / 'out', tmp_path / 'est.csv'
    args = ['--out', str(out), '--csv', str(table), *(['--joint', joint] if joint else [])]
    proc = bag_estimate(bag, *args, config=CONFIGS[config])
    assert proc.returncode == 2 and proc.stdout == ''
    assert proc.stderr.startswith(f'pma-model: error: {bag}: no force estimated, nothing written')
    assert words in proc.stderr and len(proc.stderr.splitlines()) == 1
    assert not out.exists() and not table.exists()


def test_estimate_joint_maps_the_recorded_entry(tmp_path):
    """--joint names the recorded JointState entry for a file of another name: the DMSP-20-300's
    geometry takes the simulated DMSP-10-250's lengths, so every pair is estimated (as
    test_storage_conversion_and_cli's 199 of 1 s at 100 Hz).
    """
    bag = record_simulation(tmp_path / 'sim.mcap', 1.0, '/m1', rate=100.0)
    out = str(tmp_path / 'out')
    proc = bag_estimate(bag, '--out', out, '--joint', 'DMSP-10-250', config=CONFIGS['DMSP-20-300'])
    assert proc.returncode == 0, proc.stderr
    assert 'wrote 199 force_estimate' in proc.stdout and '(0 inputs rejected)' in proc.stdout


def residual_reference(bag):
    """The residual model_node (``residual.enabled``) makes of a one-muscle recording, message by
    message through its wire layer (its callbacks' calls), over the whole recording.
    """
    from pma_model_ros.bags.offline_inputs import DESERIALIZE
    from pma_model_ros.bags.offline_node import WHOLE
    from pma_model_ros.core.files.param_file import node_engine
    from pma_model_ros.core.runtime.residual import Residuals, Thresholds
    from pma_model_ros.wire.muscle_inputs import MuscleInputs

    messages = raw_messages(bag)
    engine = node_engine([SETTINGS], 'every_input', 0.0)
    model = SETTINGS.config.model
    residual = Residuals(
        [SETTINGS.band],
        [model.domain.pressure_max],
        [model.model.name],
        engine.pairing.max_age,
        Thresholds(window=WHOLE),
        len(messages),
    )
    inputs = MuscleInputs(engine, [JOINT], [SETTINGS.frame_id], DESERIALIZE, residual)
    for topic, now, data in messages:
        if topic.endswith('/force'):
            inputs.measured_force(0, data, now)
        elif (inputs.pressure if topic.endswith('/pressure') else inputs.muscle_state)(
            0, data, now
        ) is not None:
            inputs.served(0)
    return residual, messages[-1][1]


@pytest.mark.parametrize('gain', [1.0, 0.6])
def test_a_recorded_measured_force_is_judged_as_the_node_judges_it(tmp_path, gain):
    from pma_model_ros.bags.estimate import residual_line

    bag = record_simulation(
        tmp_path / 'sim', 4.0, '/m1', rate=100.0, drift__gain=gain, sweep_period=4.0
    )
    summary = estimate_bag(bag, SETTINGS, tmp_path / 'out', progress=False)
    reference, end = residual_reference(bag)
    line = summary.residual[JOINT]
    assert line == residual_line(reference, 0, end)
    figures = reference.figures(0, end)
    assert figures.samples == 400  # every force (its stamp's length completes an estimate)
    assert line.endswith('samples: 400 paired, 0 rejected, 0 unpaired, 0 unjudged')
    if gain == 1.0:  # the truth is the map the model was fitted to: within its held-out band
        assert figures.rms < figures.band and '; OK;' in line
    else:  # 40 % less force than served: the bias is about -40 % of the mean force / max force
        assert figures.bias < -5 and 'model drift' in line
    proc = bag_estimate(bag, '--out', str(tmp_path / 'cli'))
    assert proc.returncode == 0 and f'{JOINT}: {line}' in proc.stdout, proc.stdout + proc.stderr


def test_a_combined_recording_of_measured_forces_is_judged_per_muscle(tmp_path):
    """``measured_forces`` of every muscle, each its model's force plus 2 % of its map's max force:
    bias, RMS and worst 2 % for every muscle with held-out errors (the finger's file has none).
    """
    from pma_model_ros.core.files.param_file import all_node_settings

    parameters = read_parameters(EXAMPLE)
    names = parameters['muscles']
    settings = all_node_settings(parameters)
    offsets = [0.02 * s.band.max_force if s.band else 0.0 for s in settings]
    multi_muscle_bag(tmp_path / 'in', True, names, offsets=offsets)
    summary = estimate_bag(
        tmp_path / 'in', settings, tmp_path / 'out', names=names, combined=True, progress=False
    )
    assert summary.residual.pop('finger') == ('unknown: the parameter file has no held_out errors')
    assert list(summary.residual) == ['biceps', 'triceps', 'wrist_flexor']
    for line in summary.residual.values():
        assert line.startswith('measured - served: bias 2 %, RMS 2 %, worst 2 % over 200 samples')
        assert line.endswith('samples: 200 paired, 0 rejected, 0 unpaired, 0 unjudged')
