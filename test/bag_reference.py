"""model_node's callbacks over a recording, message by message: the reference that ``bag
estimate``'s one pass is compared with.

Each recorded message's bytes go, in log-time order, through the calls the node's raw subscriptions
make (the wire layer, :class:`~pma_model_ros.wire.muscle_inputs.MuscleInputs`, on one
:class:`~pma_model_ros.core.runtime.engine.Engine`), with "now" = the message's log time, the 1 Hz
status timer firing on bag time and a status on every change the engine reports due.  This was
``bag estimate`` until its one pass; the nodes still decide so.
"""

import math

import numpy as np
from rosbags.rosbag2 import Reader

from pma_model_ros.bags.bag_io import DIAGNOSTIC_ARRAY, topic, TYPESTORE
from pma_model_ros.bags.offline_inputs import DESERIALIZE
from pma_model_ros.bags.offline_node import (
    COMBINED_INPUTS,
    COMBINED_OUTPUTS,
    DIAGNOSTICS,
    INPUTS,
    OUTPUTS,
)
from pma_model_ros.core.files.node_parameters import topic_prefixes
from pma_model_ros.core.files.param_file import node_engine
from pma_model_ros.core.physics.flags import describe
from pma_model_ros.core.runtime.health import DIAGNOSTIC_PERIOD_NS
from pma_model_ros.wire.cdr import fluid_pressure
from pma_model_ros.wire.muscle_inputs import MuscleInputs

T = TYPESTORE.types
PRESSURE, STATE, COMMAND = range(3)


def raw_messages(bag):
    """(topic, log time [ns], bytes) of every message of a bag, in the order it reads them."""
    with Reader(bag) as reader:
        return [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]


def per_message(
    bag,
    settings,
    namespace,
    names=(),
    combined=False,
    outputs_only=False,
    pairing='every_input',
    slop=0.0005,
):
    """What the node publishes for the recording ``bag`` (the inputs' topics under
    ``namespace``): (messages as (topic, log time, bytes) in publish order, with the copies of the
    recorded ones bag estimate keeps; CSV rows; the counters summed over muscles).
    """
    prefixes = topic_prefixes(names)
    if combined:
        roles = {topic(namespace, t): (role, -1) for role, t in enumerate(COMBINED_INPUTS)}
        replaced = {topic(namespace, t) for t in COMBINED_OUTPUTS}
    else:
        roles = {
            topic(namespace, f'{p}{t}'): (role, k)
            for k, p in enumerate(prefixes)
            for role, t in enumerate(INPUTS)
        }
        replaced = {topic(namespace, f'{p}{t}') for p in prefixes for t in OUTPUTS}
    engine = node_engine(settings, pairing, slop)
    joints = [s.joint_name for s in settings]
    inputs = MuscleInputs(engine, joints, [s.frame_id for s in settings], DESERIALIZE)
    commands = [fluid_pressure(s.frame_id) for s in settings]
    out, rows, next_status = [], [], None

    # the live model_node in ``namespace``: /<namespace>/model_node (nodes/diagnostics.py)
    node = f'{namespace.strip("/")}/model_node'.lstrip('/')

    def status(time_ns):
        entries = [
            T['diagnostic_msgs/msg/DiagnosticStatus'](
                int(s.level),
                f'{node}: {joint}',
                s.message,
                setting.hardware_id or f'/{node}/{joint}',  # unset: the node's default
                [
                    T['diagnostic_msgs/msg/KeyValue'](key, v)
                    for key, v in (s.values | setting.status_values(engine.inputs(k)[1])).items()
                ],
            )
            for k, (joint, setting, s) in enumerate(
                zip(joints, settings, engine.statuses(time_ns))
            )
        ]
        header = T['std_msgs/msg/Header'](
            T['builtin_interfaces/msg/Time'](time_ns // 10**9, time_ns % 10**9), ''
        )
        data = TYPESTORE.serialize_cdr(T[DIAGNOSTIC_ARRAY](header, entries), DIAGNOSTIC_ARRAY)
        out.append((DIAGNOSTICS, time_ns, data))

    def estimated(k, data, now):
        if data is None:
            return
        name = 'force_estimates' if k is None else f'{prefixes[k]}force_estimate'
        out.append((topic(namespace, name), now, data))
        stamp = f'{engine.stamp // 10**9}.{engine.stamp % 10**9:09d}'
        for i in np.flatnonzero(engine.estimated).tolist():
            muscle = i if k is None else k
            gauge, length, rate = engine.inputs(muscle)
            force, flags = engine.forces.item(i), describe(int(engine.flags[i]))
            rows.append((now, stamp, gauge, length, rate, force, flags, joints[muscle]))

    with Reader(bag) as reader:
        for connection, now, data in reader.messages():
            if next_status is None:
                next_status = now + DIAGNOSTIC_PERIOD_NS
            while now >= next_status:
                status(next_status)
                next_status += DIAGNOSTIC_PERIOD_NS
            name = connection.topic
            if name not in replaced and (not outputs_only or name == DIAGNOSTICS):
                out.append((name, now, bytes(data)))
            role, k = roles.get(name, (None, 0))
            if role is None:
                continue
            if role == COMMAND and combined:
                got = inputs.force_commands(data, now)
                if got is not None:
                    out.append((topic(namespace, 'pressure_commands'), now, got(now)))
            elif role == COMMAND:
                pressure = inputs.force_command(k, data, now)
                if pressure is not None:
                    commands[k].values[0] = pressure
                    name = f'{prefixes[k]}pressure_command'
                    out.append((topic(namespace, name), now, commands[k](now)))
            elif combined:
                read = inputs.pressures if role == PRESSURE else inputs.states
                estimated(None, read(data, now), now)
            else:
                read = inputs.pressure if role == PRESSURE else inputs.muscle_state
                estimated(k, read(k, data, now), now)
            if engine.status_due(now):
                status(now)
    counts = {}
    for k in range(len(settings)):
        for key, n in engine.counts(k).items():
            counts[key] = counts.get(key, 0) + n
    return out, rows, counts


def csv_rows(path):
    """The rows of a ``--csv`` file as the reference's tuples (numbers parsed)."""
    import csv

    with open(path, newline='') as f:
        return [
            (
                int(r['log_time_ns']),
                r['stamp_s'],
                float(r['pressure_pa']),
                float(r['length_m']),
                float(r['length_rate_mps']),
                float(r['force_n']),
                r['flags'],
                r['joint'],
            )
            for r in csv.DictReader(f)
        ]


def same(a: float, b: float) -> bool:
    """Equal, NaN equal to NaN."""
    return a == b or (math.isnan(a) and math.isnan(b))
