"""Bags of the simulated muscle written without ROS: what ``simulator_node --record`` writes,
faster than real time.

For tests, benchmarks and demos on a machine without DDS: the same physics
(:class:`~pma_model_ros.core.simulation.muscle.SimulatedMuscle`), the same topics, types,
QoS and stamps as the node (log time = header stamp), at exact sample times.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.interfaces import Qos

from .bag_io import (
    BagWriter,
    FLUID_PRESSURE,
    JOINT_STATE,
    SENSOR_DATA,
    topic,
    TYPESTORE,
    WRENCH_STAMPED,
)
from ..core.simulation.muscle import defaults, SimulatedMuscle

#: 2026-01-01T00:00:00Z [ns]: the first stamp of a synthetic recording.
START_NS = 1_767_225_600_000_000_000
_BLOCK = 10_000  # samples simulated per vectorised force evaluation


def record_simulation(
    out: str | Path,
    duration: float,
    namespace: str = '/',
    storage: str | None = None,
    offered: Qos = SENSOR_DATA,
    **params: object,
) -> Path:
    """Write ``duration`` [s] of the simulator at ``params['rate']`` [Hz] to a new bag ``out``; its
    path.

    ``params`` are simulator parameters (``noise__force_std=1.0`` for ``noise.force_std``);
    ``offered`` is the QoS the recording says its topics were published with (the simulator's
    sensor-data QoS by default; ``pma-model bag play`` publishes with it).
    """
    p = defaults(**params)
    period_ns = round(1e9 / float(p['rate']))
    muscle = SimulatedMuscle(p, START_NS * 1e-9)
    types = TYPESTORE.types
    Header, Time = types['std_msgs/msg/Header'], types['builtin_interfaces/msg/Time']
    FluidPressure, JointState = (
        types['sensor_msgs/msg/FluidPressure'],
        types['sensor_msgs/msg/JointState'],
    )
    WrenchStamped, Wrench, Vector3 = (
        types[f'geometry_msgs/msg/{t}'] for t in ('WrenchStamped', 'Wrench', 'Vector3')
    )
    zero = Vector3(0.0, 0.0, 0.0)
    with BagWriter(out, storage) as bag:
        pressure_topic = bag.topic(topic(namespace, 'pressure'), FLUID_PRESSURE, [offered])
        state_topic = bag.topic(topic(namespace, 'muscle_state'), JOINT_STATE, [offered])
        force_topic = bag.topic(topic(namespace, 'force'), WRENCH_STAMPED, [offered])
        times_ns = START_NS + np.arange(int(duration * float(p['rate']))) * period_ns
        for block in np.array_split(times_ns, max(1, times_ns.size // _BLOCK)):
            r = muscle.run(block * 1e-9)
            for i, now_ns in enumerate(block.tolist()):
                header = Header(Time(now_ns // 10**9, now_ns % 10**9), muscle.joint)
                bag.write(pressure_topic, now_ns, FluidPressure(header, r.pressure[i], 0.0))
                bag.write(
                    state_topic,
                    now_ns,
                    JointState(
                        header,
                        [muscle.joint],
                        r.length[i : i + 1],
                        r.rate[i : i + 1],
                        r.force[i : i + 1],
                    ),
                )
                bag.write(
                    force_topic,
                    now_ns,
                    WrenchStamped(header, Wrench(Vector3(r.force[i], 0.0, 0.0), zero)),
                )
    return Path(out)
