"""Calibration from a recording: the quasi-static samples of pressure, length and measured force as
a force map.

A recording holds ``<ns>/pressure`` (FluidPressure, absolute Pa), ``<ns>/muscle_state``
(JointState: position = length [m] of the entry ``joint``) and a measured tension [N]: a load
cell's ``<ns>/force`` (WrenchStamped, force.x) or, without one, the JointState's effort.

At each force sample (its header stamp), pressure and length are interpolated linearly in
their own header stamps.  **Quasi-static criterion**: a sample is kept when, over the centred
window of ``window`` seconds around it (entirely inside the recording, at least
``MIN_SAMPLES`` samples), the least-squares slopes of the length and of the pressure are at
most ``max_length_rate`` [m/s] and ``max_pressure_rate`` [Pa/s] in magnitude.  This drops
motion (friction and hysteresis make the force depend on the direction of motion) and fast
pressure changes (air temperature, sensor lag), and the slope over a window, unlike a
difference of neighbours, is not dominated by sensor noise.

Each sample also carries the hysteresis branch it was reached on (the play operator of the length,
:mod:`~pma_model_ros.core.physics.hysteresis`, with model_node's default deadband): the direction
of the last motion, so a two-branch model can be identified from the held points (``two_branches``:
then the samples from before the muscle's first motion, branch unknown, are left out).

The kept samples are averaged in cells of ``PRESSURE_CELL`` x ``LENGTH_CELL`` x branch (equal
weight per region of the map however long the recording stayed there; far fewer points for the
fit; each length cell a row of the map), measured forces below 0 N (noise on a slack muscle) are
set to 0 N (:func:`~pma_model_ros.core.identification.force_map.cell_means`), and the result is a
:class:`~pma_model_ros.core.identification.force_map.ForceMap`: identification is then exactly that
of a force-map CSV (:func:`~pma_model_ros.core.identification.protocols.fit_best`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bag_io import (
    BagError,
    connections_of,
    deserialize,
    FLUID_PRESSURE,
    JOINT_STATE,
    messages,
    open_bag,
    topic,
    WRENCH_STAMPED,
)
from .estimate import muscle_namespace
from ..core.files.node_parameters import SPECS
from ..core.identification.force_map import cell_means, ForceMap, LENGTH_CELL, PRESSURE_CELL
from ..core.identification.progress import Meter
from ..core.physics.geometry import STANDARD_ATMOSPHERE
from ..core.physics.hysteresis import branches
from ..wire.cdr import stamp_ns

MIN_SAMPLES = 3  #: fewest samples in a window for a slope
#: simulator_node's settings of a recording that fits (docs/cli.md's, run verbatim by a test): five
#: lengths, each held 7.5 s of every 10 s, while the pressure sweeps the map's range in 14 s
#: (46 kPa/s); about 70 s.
SIMULATOR_SETTINGS = '-p trajectory:=steps -p steps:=5 -p period:=10.0 -p sweep_period:=28.0'


@dataclass(frozen=True)
class QuasiStatic:
    """The quasi-static criterion (module docstring)."""

    window: float = 1.0  #: [s] centred window of the slopes
    max_length_rate: float = 1e-3  #: [m/s]
    max_pressure_rate: float = 50e3  #: [Pa/s]

    def __post_init__(self) -> None:
        for name in ('window', 'max_length_rate', 'max_pressure_rate'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f'quasi-static {name} must be > 0, got {value}')


@dataclass(frozen=True)
class Samples:
    """Aligned samples at the force stamps: time [s], gauge pressure [Pa], length [m], measured
    force [N].
    """

    time: np.ndarray
    pressure: np.ndarray
    length: np.ndarray
    force: np.ndarray
    #: hysteresis branch of the length's motion so far: +1, -1, 0 before the first motion
    direction: np.ndarray


def window_slopes(t: np.ndarray, x: np.ndarray, window: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares slope of ``x`` over ``t`` in the centred ``window`` around each sample, and
    the count in it.
    """
    t0 = t - t[0]
    lo = np.searchsorted(t0, t0 - window / 2, 'left')
    hi = np.searchsorted(t0, t0 + window / 2, 'right')
    sums = [np.concatenate([[0.0], np.cumsum(v)]) for v in (t0, x, t0 * t0, t0 * x)]
    s_t, s_x, s_tt, s_tx = (c[hi] - c[lo] for c in sums)
    n = (hi - lo).astype(float)
    with np.errstate(invalid='ignore', divide='ignore'):
        slope = (n * s_tx - s_t * s_x) / (n * s_tt - s_t * s_t)
    return slope, hi - lo


def quasi_static(samples: Samples, criterion: QuasiStatic) -> np.ndarray:
    """Mask of the samples that meet ``criterion`` (module docstring)."""
    t = samples.time
    inside = (t - t[0] >= criterion.window / 2) & (t[-1] - t >= criterion.window / 2)
    dl, n = window_slopes(t, samples.length, criterion.window)
    dp, _ = window_slopes(t, samples.pressure, criterion.window)
    return (
        inside
        & (n >= MIN_SAMPLES)
        & (np.abs(dl) <= criterion.max_length_rate)
        & (np.abs(dp) <= criterion.max_pressure_rate)
    )


def read_samples(
    bag: str | Path,
    joint: str,
    ambient_pressure: float,
    namespace: str | None = None,
    force_topic: str | None = None,
) -> Samples:
    """Pressure, length and measured force of a recording, aligned at the force stamps (module
    docstring).

    ``force_topic``: relative to the namespace or absolute; WrenchStamped (force.x) or JointState
    (effort of ``joint``).  Default: ``<ns>/force`` if recorded, else the effort in
    ``muscle_state``.
    """
    with open_bag(bag) as reader:
        ns = muscle_namespace(reader, namespace)
        have = {c.topic: c.msgtype for c in reader.connections}
        pressure, state = topic(ns, 'pressure'), topic(ns, 'muscle_state')
        if force_topic is None:
            force_topic = topic(ns, 'force') if topic(ns, 'force') in have else state
        elif not force_topic.startswith('/'):
            force_topic = topic(ns, force_topic)
        if have.get(force_topic) not in (WRENCH_STAMPED, JOINT_STATE, None):
            raise BagError(
                f'topic {force_topic} has type {have[force_topic]}, expected {WRENCH_STAMPED} '
                f'or {JOINT_STATE}'
            )
        connections = connections_of(
            reader, {pressure, state, force_topic}, {pressure: FLUID_PRESSURE, state: JOINT_STATE}
        )
        series: dict[str, list[tuple[float, float]]] = {'pressure': [], 'length': [], 'force': []}
        names: set[str] = set()  # the JointState entries recorded
        meter = Meter(sum(c.msgcount for c in connections), f'reading {Path(bag).name} (messages)')
        for count, (connection, _, data) in enumerate(messages(reader, connections), 1):
            if count % 1000 == 0:
                meter.update(count)
            msg = deserialize(data, connection)
            stamp = stamp_ns(msg.header.stamp.sec, msg.header.stamp.nanosec) * 1e-9
            if connection.topic == pressure:
                series['pressure'].append((stamp, msg.fluid_pressure - ambient_pressure))
            if connection.topic == force_topic and connection.msgtype == WRENCH_STAMPED:
                series['force'].append((stamp, msg.wrench.force.x))
            if connection.msgtype == JOINT_STATE:
                names.update(msg.name)
            if connection.msgtype == JOINT_STATE and joint in msg.name:
                i = msg.name.index(joint)
                if connection.topic == state and i < len(msg.position):
                    series['length'].append((stamp, msg.position[i]))
                if connection.topic == force_topic and i < len(msg.effort):
                    series['force'].append((stamp, msg.effort[i]))
        meter.update(meter.total)
    return _align(series, str(bag), joint, force_topic, names)


def _align(
    series: dict[str, list[tuple[float, float]]],
    bag: str,
    joint: str,
    force_topic: str,
    names: set[str],
) -> Samples:
    arrays = {}
    for name, rows in series.items():
        data = np.array(rows, float).reshape(-1, 2)
        data = data[np.all(np.isfinite(data), axis=1)]
        if len(data) < 2:
            where = (
                f" (joint '{joint}' in {force_topic})"
                if name == 'force'
                else f" (joint '{joint}')"
            )
            absent = (
                f'; the recording has no JointState entry {joint!r}, only {sorted(names)}: '
                "name the muscle's entry with --joint NAME"
                if name != 'pressure' and joint not in names
                else ''
            )
            raise BagError(
                f'{bag}: fewer than 2 valid {name} samples{where if name != "pressure" else ""}'
                + absent
            )
        arrays[name] = data[np.argsort(data[:, 0], kind='stable')]
    t, force = arrays['force'].T
    start = max(arrays['pressure'][0, 0], arrays['length'][0, 0])
    end = min(arrays['pressure'][-1, 0], arrays['length'][-1, 0])
    keep = (t >= start) & (t <= end)
    if keep.sum() < 2:
        raise BagError(
            f'{bag}: the force samples do not overlap the pressure and length samples in time'
        )
    t, force = t[keep], force[keep]
    pressure = np.interp(t, *arrays['pressure'].T)
    length = np.interp(t, *arrays['length'].T)
    return Samples(
        t, pressure, length, force, branches(length, SPECS['hysteresis.length_deadband'].default)
    )


@dataclass(frozen=True)
class Calibration:
    force_map: ForceMap  #: cell means of the quasi-static samples
    samples: int  #: aligned force samples in the recording
    kept: int  #: of which quasi-static


def force_map_from_bag(
    bag: str | Path,
    joint: str,
    ambient_pressure: float = STANDARD_ATMOSPHERE,
    criterion: QuasiStatic = QuasiStatic(),
    namespace: str | None = None,
    force_topic: str | None = None,
    two_branches: bool = False,
) -> Calibration:
    """The force map of a recording's quasi-static samples (module docstring); ``two_branches``:
    only samples whose hysteresis branch is known, the map carrying each point's direction.
    """
    samples = read_samples(bag, joint, ambient_pressure, namespace, force_topic)
    mask = quasi_static(samples, criterion)
    if two_branches:
        mask &= samples.direction != 0
    try:
        force_map = cell_means(
            samples.pressure[mask],
            samples.length[mask],
            samples.force[mask],
            samples.direction[mask],
        )
        force_map.subset(force_map.force > 0)  # the fit's points: force at two lengths or more
    except ValueError:
        raise BagError(_too_few(str(bag), samples, mask, criterion)) from None
    return Calibration(force_map, int(mask.size), int(mask.sum()))


def _too_few(bag: str, samples: Samples, mask: np.ndarray, criterion: QuasiStatic) -> str:
    """Why the quasi-static samples cannot be fitted, and which recording would give more."""
    pulling = mask & (samples.force > 0)
    held = np.unique(np.round(samples.length[pulling] / LENGTH_CELL)) * LENGTH_CELL
    at = ', '.join(f'{v:.4f}' for v in held[:6]) + (' ...' if held.size > 6 else '')
    return (
        f'{bag}: {int(mask.sum())} of {mask.size} samples are quasi-static over '
        f'{criterion.window:g} s windows ({_why_not(samples, criterion)}); '
        f'{int(pulling.sum())} of them with force, at {held.size} length(s)'
        f'{f" ({at} m)" if held.size else ""}: too few to fit (force in 3 or more cells of '
        f'{PRESSURE_CELL / 1e3:g} kPa x {LENGTH_CELL * 1e3:g} mm, over 2 lengths or more). '
        'Record holding each length while the pressure ramps at most '
        f'{criterion.max_pressure_rate:g} Pa/s (simulator_node: {SIMULATOR_SETTINGS}), or loosen '
        '--max-pressure-rate / --max-length-rate'
    )


def _why_not(samples: Samples, criterion: QuasiStatic) -> str:
    """Which rate bound the samples fail, how many, and their median rate."""
    dl, _ = window_slopes(samples.time, samples.length, criterion.window)
    dp, _ = window_slopes(samples.time, samples.pressure, criterion.window)
    reasons = []
    for rate, bound, what, unit, digits in (
        (np.abs(dp), criterion.max_pressure_rate, '|dp/dt|', 'Pa/s', '.0f'),
        (np.abs(dl), criterion.max_length_rate, '|dL/dt|', 'm/s', '.2g'),
    ):
        over = rate > bound
        if over.any():
            reasons.append(
                f'{what} > {bound:g} {unit} at {int(over.sum())} of them (median '
                f'{np.nanmedian(rate):{digits}} {unit})'
            )
    return ', '.join(reasons) or 'the rates are within the bounds'
