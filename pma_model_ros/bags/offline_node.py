"""The model node over a recording, offline: the core of ``bag estimate`` (:mod:`.estimate`).

:class:`OfflineNode` takes the recording in stretches: each input topic's messages are decoded into
arrays at once (:mod:`~pma_model_ros.wire.columns`), the engine's rules run over each muscle's
arrays (:class:`~pma_model_ros.core.runtime.recording.Recording`), and what the node would publish
(estimates, pressure commands, /diagnostics) is written from templates beside the copies, in the
order the node publishes it. The node's topics, as the nodes name them, are defined here.

A recording that holds a measured force (:data:`MEASURED`, :data:`COMBINED_MEASURED`) is also
judged as model_node judges it with ``residual.enabled``
(:class:`~pma_model_ros.core.runtime.residual.Residuals`, each measured force at its log time, in
message order with the estimates), over the whole recording: :attr:`OfflineNode.residual`.
"""

from __future__ import annotations

import csv as csv_module
from dataclasses import dataclass, field

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader

from .bag_io import (
    BagWriter,
    connections_of,
    DIAGNOSTIC_ARRAY,
    FLUID_PRESSURE,
    JOINT_STATE,
    RELIABLE,
    topic,
    WRENCH_STAMPED,
)
from .offline_inputs import decode, DESERIALIZE, pick
from ..core.files.node_parameters import SPECS, topic_prefixes
from ..core.files.param_file import in_node, node_engine, NodeSettings
from ..core.physics.flags import describe
from ..core.runtime.recording import COMMAND_IN, Estimates, Recording
from ..core.runtime.residual import Residuals, Thresholds
from ..core.runtime.timeline import Report
from ..wire.cdr import fluid_pressure, joint_state, MALFORMED, Template, wrench_stamped
from ..wire.columns import joint_columns, stamped_floats
from ..wire.diagnostics import diagnostic_array

#: The node's input topics of one muscle (relative names) and their types, in the order of the
#: input kinds of :mod:`~pma_model_ros.core.runtime.recording` (PRESSURE_IN, LENGTH_IN,
#: COMMAND_IN).
INPUTS = {'pressure': FLUID_PRESSURE, 'muscle_state': JOINT_STATE, 'force_command': WRENCH_STAMPED}
#: The node's input topics in combined mode, all JointStates (same order).
COMBINED_INPUTS = ('muscle_pressures', 'muscle_states', 'force_commands')
#: The node's output topics (relative names) written here: per muscle, and in combined mode.
OUTPUTS = ('force_estimate', 'pressure_command')
COMBINED_OUTPUTS = ('force_estimates', 'pressure_commands')
DIAGNOSTICS = '/diagnostics'
#: A muscle's measured force (WrenchStamped, relative names): model_node's input, or for one
#: muscle the simulator's ``force`` (what ``fit --bag`` reads), the first recorded; combined: one
#: JointState (effort by name).
MEASURED = ('measured_force', 'force')
COMBINED_MEASURED = 'measured_forces'
MEASURED_IN = COMMAND_IN + 1  #: the input kind of a measured force (not the engine's)
#: [s] the window of the offline residual: the whole recording
WHOLE = 1e9
NODE = 'model_node'  #: the node's name (its executable's default)
CSV_COLUMNS = (
    'log_time_ns',
    'stamp_s',
    'pressure_pa',
    'length_m',
    'length_rate_mps',
    'force_n',
    'flags',
    'joint',
)


@dataclass
class Summary:
    """What :func:`.estimate.estimate_bag` read and wrote."""

    namespace: str
    messages: int = 0  #: messages read (all topics)
    estimates: int = 0  #: force estimates written (one per muscle estimated)
    commands: int = 0  #: pressure commands written (one per muscle commanded)
    diagnostics: int = 0  #: /diagnostics messages written
    #: the engine's counters at the end, summed over muscles
    counts: dict[str, int] = field(default_factory=dict)
    #: each muscle's rejections by reason (joint name -> reason -> (how many, the first's text);
    #: :meth:`~pma_model_ros.core.runtime.recording.Recording.reasons`)
    reasons: dict[str, dict[str, tuple[int, str]]] = field(default_factory=dict)
    #: with a recorded measured force, each muscle's residual over the whole recording: one line
    #: (the figures, as model_node's ``residual [% of max force]``, the level and the counts)
    residual: dict[str, str] = field(default_factory=dict)


class _Outputs:
    """Messages to write, each with its place: (position of the message it goes with, slot)."""

    #: slots around a message: 1 Hz status before it, its copy, its answer, on-change status
    TIMER, COPY, ANSWER, CHANGE = range(4)

    def __init__(self) -> None:
        self.keys: list[np.ndarray] = []
        self.connections: list[Connection] = []
        self.which: list[np.ndarray] = []  # index into connections
        self.times: list[np.ndarray] = []
        self.data: list[bytes] = []

    def add(self, connection: Connection, at, slot: int, times, data: list[bytes]) -> None:
        """Messages of ``connection`` going with the messages at positions ``at``."""
        if not len(data):
            return
        self.keys.append(np.asarray(at, np.int64) * 4 + slot)
        self.which.append(np.full(len(data), len(self.connections)))
        self.connections.append(connection)
        self.times.append(np.asarray(times, np.int64))
        self.data += data

    def write(self, writer: BagWriter) -> None:
        """Everything, in the order the node publishes it."""
        if not self.data:
            return
        order = np.argsort(np.concatenate(self.keys), kind='stable')
        which, times = np.concatenate(self.which)[order], np.concatenate(self.times)[order]
        connections = [self.connections[i] for i in which.tolist()]
        writer.write_many(connections, times.tolist(), [self.data[i] for i in order.tolist()])


class OfflineNode:
    """The model node over a recording: its inputs decoded into arrays per topic, the engine's
    decisions made over them at once (:class:`~pma_model_ros.core.runtime.recording.Recording`),
    and what the node would publish written beside the copies, in the node's order.
    """

    def __init__(
        self,
        settings: list[NodeSettings],
        names: list[str],
        combined: bool,
        namespace: str,
        reader: Reader,
        writer: BagWriter,
        rows: csv_module.writer | None,
        outputs_only: bool = False,
        pairing: str = SPECS['pairing'].default,
        slop: float = SPECS['pairing_slop'].default,
    ) -> None:
        prefixes = topic_prefixes(names)
        inputs = (
            {topic(namespace, name): (role, -1) for role, name in enumerate(COMBINED_INPUTS)}
            if combined
            else {
                topic(namespace, f'{prefix}{name}'): (role, k)
                for k, prefix in enumerate(prefixes)
                for role, name in enumerate(INPUTS)
            }
        )
        present = {c.topic for c in reader.connections}
        measured = self._measured_topics(present, namespace, prefixes, combined, bool(names))
        types = {
            t: JOINT_STATE if combined else list(INPUTS.values())[role]
            for t, (role, _) in inputs.items()
        } | dict.fromkeys(measured, JOINT_STATE if combined else WRENCH_STAMPED)
        inputs |= measured
        connections_of(reader, [t for t in inputs if t in present], types)
        self.roles = {c.id: inputs[c.topic] for c in reader.connections if c.topic in inputs}
        replaced = (
            {topic(namespace, name) for name in COMBINED_OUTPUTS}
            if combined
            else {topic(namespace, f'{prefix}{name}') for prefix in prefixes for name in OUTPUTS}
        )
        self.copies: dict[int, Connection] = {}
        self._diagnostics = None
        for c in reader.connections:
            if c.topic in replaced or outputs_only and c.topic != DIAGNOSTICS:
                continue
            self.copies[c.id] = writer.copy_topic(c)
            if c.topic == DIAGNOSTICS and c.msgtype == DIAGNOSTIC_ARRAY:
                self._diagnostics = self.copies[c.id]
        if self._diagnostics is None:
            self._diagnostics = writer.topic(DIAGNOSTICS, DIAGNOSTIC_ARRAY, [RELIABLE])
        has_commands = any(role == COMMAND_IN for role, _ in self.roles.values())
        if combined:
            self._estimates = [
                writer.topic(topic(namespace, 'force_estimates'), JOINT_STATE, [RELIABLE])
            ]
            self._commands = [
                writer.topic(topic(namespace, 'pressure_commands'), JOINT_STATE, [RELIABLE])
            ]
        else:
            self._estimates = [
                writer.topic(topic(namespace, f'{p}force_estimate'), WRENCH_STAMPED, [RELIABLE])
                for p in prefixes
            ]
            self._commands = (
                [
                    writer.topic(
                        topic(namespace, f'{p}pressure_command'), FLUID_PRESSURE, [RELIABLE]
                    )
                    for p in prefixes
                ]
                if has_commands
                else []
            )
        #: the live node's fully qualified name in ``namespace``: its statuses' names and default
        #: hardware_ids (nodes/diagnostics.py)
        self.instance = topic(namespace, NODE)
        settings = in_node(settings, self.instance)
        self.settings, self.writer, self.rows, self.combined = settings, writer, rows, combined
        self.engine = node_engine(settings, pairing, slop)
        self.recording = Recording(self.engine, arrays=combined)
        self.joints = [s.joint_name for s in settings]
        self._wrenches = [wrench_stamped(s.frame_id) for s in settings]
        self._pressures = [fluid_pressure(s.frame_id) for s in settings]
        self._joint_states: dict[tuple, Template] = {}  # by (names, field)
        self.summary = Summary(namespace)
        ids = max(self.roles, default=0) + 1
        self._role = np.full(ids, -1)
        self._muscle = np.full(ids, -1)
        for cid, (role, k) in self.roles.items():
            self._role[cid], self._muscle[cid] = role, k
        self._copied = np.zeros(max(self.copies, default=0) + 1, bool)
        self._copied[list(self.copies)] = True
        #: the residual of the measured forces, if the recording holds any (module docstring)
        self.residual = (
            Residuals(
                [s.band for s in settings],
                [s.config.model.domain.pressure_max for s in settings],
                [s.config.model.model.name for s in settings],
                self.engine.pairing.max_age,
                Thresholds(window=WHOLE),
                max(1, sum(c.msgcount for c in reader.connections if c.topic in measured)),
            )
            if measured
            else None
        )
        self.last_time = 0  #: [ns] the log time of the last message

    @staticmethod
    def _measured_topics(
        present: set[str], namespace: str, prefixes: list[str], combined: bool, named: bool
    ) -> dict[str, tuple[int, int]]:
        """The recorded measured-force topics: {topic: (MEASURED_IN, muscle; -1: combined)}."""
        if combined:
            t = topic(namespace, COMBINED_MEASURED)
            return {t: (MEASURED_IN, -1)} if t in present else {}
        found = {}
        for k, prefix in enumerate(prefixes):
            for name in MEASURED[:1] if named else MEASURED:
                if (t := topic(namespace, f'{prefix}{name}')) in present:
                    found[t] = (MEASURED_IN, k)
                    break
        return found

    def process(self, ids: list[int], times: list[int], data: list[bytes]) -> None:
        """A stretch of the recording, in log-time order: its messages' connection ids, log
        times [ns] and bytes.
        """
        ids, times = np.array(ids, np.int64), np.array(times, np.int64)
        first = self.summary.messages
        known = ids < len(self._role)
        roles = np.where(known, self._role[np.where(known, ids, 0)], -1)
        muscles = np.where(known, self._muscle[np.where(known, ids, 0)], -1)
        inputs = decode(roles, muscles, times, data, first, self.joints, self.combined)
        input_at = first + np.flatnonzero((roles >= 0) & (roles != MEASURED_IN))
        stretch = self.recording.step(inputs, first, times, input_at)
        if self.residual is not None:
            self._residual(stretch, roles, muscles, times, data, first)
        self.last_time = int(times[-1])
        out = _Outputs()
        copied = ids < len(self._copied)
        copied[copied] = self._copied[ids[copied]]
        for cid in np.unique(ids[copied]).tolist():
            rows = np.flatnonzero(ids == cid)
            out.add(self.copies[cid], first + rows, out.COPY, times[rows], pick(data, rows))
        self._answers(stretch, out, first, times)
        for report in stretch.reports:
            slot = out.CHANGE if report.after else out.TIMER
            out.add(self._diagnostics, [report.at], slot, [report.now], [self._status(report)])
        self.summary.diagnostics += len(stretch.reports)
        out.write(self.writer)
        self.summary.messages += len(data)

    def _answers(self, stretch, out: _Outputs, first: int, times: np.ndarray) -> None:
        """The estimates and commands of the stretch as messages (and CSV rows)."""
        summary = self.summary
        summary.estimates += sum(len(e.at) for e in stretch.estimates)
        summary.commands += sum(len(c.at) for c in stretch.commands)
        if self.combined:
            self._combined(stretch, out, first, times)
        else:
            for k, (e, c) in enumerate(zip(stretch.estimates, stretch.commands)):
                out.add(
                    self._estimates[k],
                    e.at,
                    out.ANSWER,
                    times[e.at - first],
                    self._wrenches[k].batch(e.stamp, e.force),
                )
                if self._commands:
                    log = times[c.at - first]
                    out.add(
                        self._commands[k],
                        c.at,
                        out.ANSWER,
                        log,
                        self._pressures[k].batch(log, c.pressure),
                    )
        if self.rows is not None:
            self._csv(stretch, first, times)

    def _residual(self, stretch, roles, muscles, times, data, first: int) -> None:
        """Each muscle's estimates and measured forces of the stretch into :attr:`residual`, in
        message order, as the node's callbacks take them.
        """
        rows = np.flatnonzero(roles == MEASURED_IN)
        n = len(self.joints)
        # per muscle: (rows, stamps [ns], forces [N], {index: why refused})
        measured: list[tuple] = []
        if self.combined:
            got = joint_columns(pick(data, rows), self.joints, 'effort', DESERIALIZE['JointState'])
            for k in range(n):
                mine = got.named[:, k]
                refused = {}
                for i in np.flatnonzero(mine & ~got.present[:, k]).tolist():
                    absent = np.flatnonzero(~got.present[i]).tolist()
                    refused[i] = got.problems[i][absent.index(k)]
                measured.append((rows[mine], got.stamps[mine], got.values[mine, k], refused, mine))
        else:
            for k in range(n):
                mine = rows[muscles[rows] == k]
                stamps, forces, malformed = stamped_floats(
                    pick(data, mine), DESERIALIZE['WrenchStamped'], 'force'
                )
                refused = dict.fromkeys(np.flatnonzero(malformed).tolist(), MALFORMED)
                measured.append((mine, stamps, forces, refused, None))
        estimates = stretch.estimates
        stamps = [e.stamp for e in estimates]
        if self.combined:  # a message's stamp: the newest among the muscles it estimates
            at = np.concatenate([e.at for e in estimates])
            where, row = np.unique(at, return_inverse=True)
            newest = np.full(len(where), np.iinfo(np.int64).min)
            np.maximum.at(newest, row, np.concatenate(stamps))
            ends = np.cumsum([len(e.at) for e in estimates]).tolist()
            stamps = [newest[row[end - len(e.at) : end]] for e, end in zip(estimates, ends)]
        residual = self.residual
        for k, (e, stamp, (mrows, mstamps, forces, refused, mine)) in enumerate(
            zip(estimates, stamps, measured)
        ):
            if mine is not None:  # refused indices are among the message's rows, not muscle k's
                refused = {int(np.cumsum(mine)[i]) - 1: why for i, why in refused.items()}
            events = np.concatenate([e.at, first + mrows])
            order = np.argsort(events, kind='stable').tolist()
            served = len(e.at)
            for i in order:
                if i < served:
                    residual.served(
                        k,
                        stamp.item(i),
                        e.force.item(i),
                        e.gauge.item(i),
                        e.length.item(i),
                        e.flags.item(i),
                    )
                elif (j := i - served) in refused:
                    residual.reject(k, refused[j])
                else:
                    residual.measured(
                        k, mstamps.item(j), forces.item(j), times.item(mrows.item(j))
                    )

    def _combined(self, stretch, out: _Outputs, first: int, times: np.ndarray) -> None:
        """One JointState per input message of every muscle estimated (commanded)."""
        for results, value, connection, kind in (
            (stretch.estimates, 'force', self._estimates[0], 'effort'),
            (stretch.commands, 'pressure', self._commands[0], 'position'),
        ):
            at = np.concatenate([r.at for r in results])
            if not at.size:
                continue
            where, row = np.unique(at, return_inverse=True)
            mask = np.zeros((len(where), len(self.joints)), bool)
            values = np.zeros(mask.shape)
            stamps = np.full(len(where), np.iinfo(np.int64).min)
            ends = np.cumsum([len(r.at) for r in results]).tolist()
            for k, (r, end) in enumerate(zip(results, ends)):
                i = row[end - len(r.at) : end]  # the messages of muscle k's answers
                mask[i, k] = True
                values[i, k] = getattr(r, value)
                if kind == 'effort':
                    np.maximum.at(stamps, i, r.stamp)
            log = times[where - first]
            stamps = stamps if kind == 'effort' else log
            data: list[bytes] = [b''] * len(where)
            for pattern in np.unique(mask, axis=0):
                rows = np.flatnonzero((mask == pattern).all(axis=1))
                names = tuple(j for j, m in zip(self.joints, pattern.tolist()) if m)
                template = self._joint_states.get((names, kind))
                if template is None:
                    template = self._joint_states[names, kind] = joint_state(names, kind)
                for i, message in zip(
                    rows.tolist(), template.batch(stamps[rows], values[rows][:, pattern])
                ):
                    data[i] = message
            out.add(connection, where, out.ANSWER, log, data)

    def _csv(self, stretch, first: int, times: np.ndarray) -> None:
        e = stretch.estimates
        at = np.concatenate([r.at for r in e])
        muscle = np.concatenate([np.full(len(r.at), k) for k, r in enumerate(e)])
        order = np.lexsort((muscle, at))
        columns = [np.concatenate([getattr(r, f) for r in e])[order] for f in Estimates._fields]
        at, stamp, force, flags, gauge, length, rate = columns
        if self.combined:  # the message's stamp: the newest among the muscles it estimates
            where, row = np.unique(at, return_inverse=True)
            newest = np.full(len(where), np.iinfo(np.int64).min)
            np.maximum.at(newest, row, stamp)
            stamp = newest[row]
        names = {}
        self.rows.writerows(
            (
                t,
                f'{s // 10**9}.{s % 10**9:09d}',
                g,
                L,
                v,
                f,
                names.get(x) or names.setdefault(x, describe(x)),
                self.joints[k],
            )
            for t, s, g, L, v, f, x, k in zip(
                times[at - first].tolist(),
                stamp.tolist(),
                gauge.tolist(),
                length.tolist(),
                rate.tolist(),
                force.tolist(),
                flags.tolist(),
                muscle[order].tolist(),
            )
        )

    def _status(self, report: Report) -> bytes:
        return diagnostic_array(
            report.now,
            self.instance.lstrip('/'),
            (
                s.status_entry(status, length)
                for s, status, length in zip(self.settings, report.statuses, report.lengths)
            ),
        )
