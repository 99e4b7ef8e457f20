"""Offline force estimation: what ``model_node`` would publish for a recording, written to a new
bag.

The model node's decisions over the recording in one pass, with "now" = each message's log time
(what the node's clock reads when the bag is played with ``--clock`` into a node with
``use_sim_time``): the recording is read in stretches; each input topic's messages are decoded
into arrays at once (:mod:`~pma_model_ros.wire.columns`), the engine's rules run over each
muscle's arrays (:class:`~pma_model_ros.core.recording.Recording`), and the answers are written
from templates, in the order the node publishes them.  ``test/test_bags_estimate.py`` pins the
output to the node's callbacks driven message by message (the wire layer and
:class:`~pma_model_ros.core.engine.Engine`), byte for byte.  The topics are those of the
parameter file's muscles, under the recording's namespace:

* one muscle: ``<ns>/pressure`` (FluidPressure), ``<ns>/muscle_state`` (JointState) and, if
  recorded, ``<ns>/force_command`` (WrenchStamped); with ``muscles:`` and ``input_mode:
  per_muscle`` the same under ``<ns>/<name>/``;
* ``input_mode: combined``: ``<ns>/muscle_pressures``, ``<ns>/muscle_states``,
  ``<ns>/force_commands`` (JointStates of every muscle).

So the output holds, beside every original message (copied as recorded):

* ``force_estimate`` per muscle (WrenchStamped: stamp = the newer input's header stamp,
  ``frame_id``, force.x = tension [N]), or one ``force_estimates`` JointState (combined), at the
  log time of the input that completed it;
* ``pressure_command`` (FluidPressure, absolute Pa), or ``pressure_commands`` (JointState), for
  each usable force command, stamped with its log time;
* ``/diagnostics``: the node's status of every muscle every second of bag time and on each level
  change.

Topics of these names already in the recording are replaced (``/diagnostics`` is kept and merged).
"""

from __future__ import annotations

from contextlib import contextmanager
import csv as csv_module
from dataclasses import dataclass, field
from itertools import islice
import math
import os
from pathlib import Path
import sys
import tempfile
import time
from typing import Iterable, Iterator, Sequence, TextIO

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader

from .bag_io import (
    BagError,
    BagWriter,
    connections_of,
    DIAGNOSTIC_ARRAY,
    FLUID_PRESSURE,
    JOINT_STATE,
    messages,
    open_bag,
    RELIABLE,
    storage_of,
    topic,
    TYPESTORE,
    WRENCH_STAMPED,
)
from ..core.engine import Engine
from ..core.flags import describe
from ..core.health import REPORT_INTERVAL_PER_STATUS
from ..core.node_parameters import SPECS
from ..core.param_file import NodeSettings
from ..core.recording import Estimates, Inputs, Recording, Report
from ..wire.cdr import fluid_pressure, joint_state, Template, wrench_stamped
from ..wire.columns import joint_columns, stamped_floats

#: The node's input topics of one muscle (relative names) and their types.
INPUTS = {'pressure': FLUID_PRESSURE, 'muscle_state': JOINT_STATE, 'force_command': WRENCH_STAMPED}
#: The node's input topics in combined mode, all JointStates.
COMBINED_INPUTS = ('muscle_pressures', 'muscle_states', 'force_commands')
#: The node's output topics (relative names) written here: per muscle, and in combined mode.
OUTPUTS = ('force_estimate', 'pressure_command')
COMBINED_OUTPUTS = ('force_estimates', 'pressure_commands')
DIAGNOSTICS = '/diagnostics'
DIAGNOSTIC_PERIOD_NS = 1_000_000_000  # model_node's status timer [ns]
CHUNK = 100_000  # messages read, decided and written per step
_PRESSURE, _STATE, _COMMAND = range(3)
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

T = TYPESTORE.types
Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
#: rosbags' deserializers of the input types: what the wire layer's fast readers do not read.
DESERIALIZE = {
    name: (lambda data, kind=kind: TYPESTORE.deserialize_cdr(data, kind))
    for name, kind in (
        ('FluidPressure', FLUID_PRESSURE),
        ('JointState', JOINT_STATE),
        ('WrenchStamped', WRENCH_STAMPED),
    )
}


def muscle_namespace(
    reader: Reader,
    namespace: str | None = None,
    first: str = 'pressure',
    second: str = 'muscle_state',
) -> str:
    """The namespace whose ``first`` and ``second`` topics (relative names) the recording holds.

    ``namespace`` if given; else the only one found (a BagError if none or several).
    """
    if namespace is not None:
        return '/' + namespace.strip('/')
    have = {c.topic for c in reader.connections}
    suffix = f'/{first}'
    found = sorted(
        {
            t.removesuffix(suffix) or '/'
            for t in have
            if t.endswith(suffix) and topic(t.removesuffix(suffix) or '/', second) in have
        }
    )
    if len(found) != 1:
        what = (
            f'several muscles ({", ".join(found)}); choose one with --namespace'
            if found
            else (
                f'no <namespace>/{first} and <namespace>/{second} topics '
                f'(topics: {", ".join(sorted(have)) or "none"})'
            )
        )
        raise BagError(f'{reader.path}: {what}')
    return found[0]


@dataclass
class Summary:
    """What :func:`estimate_bag` read and wrote."""

    namespace: str
    messages: int = 0  #: messages read (all topics)
    estimates: int = 0  #: force estimates written (one per muscle estimated)
    commands: int = 0  #: pressure commands written (one per muscle commanded)
    diagnostics: int = 0  #: /diagnostics messages written
    #: the engine's counters at the end, summed over muscles
    counts: dict[str, int] = field(default_factory=dict)


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


class _OfflineNode:
    """The model node over a recording: its inputs decoded into arrays per topic, the engine's
    decisions made over them at once (:class:`~pma_model_ros.core.recording.Recording`), and what
    the node would publish written beside the copies, in the node's order.
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
        inputs = (
            {topic(namespace, name): (role, -1) for role, name in enumerate(COMBINED_INPUTS)}
            if combined
            else {
                topic(namespace, f'{prefix}{name}'): (role, k)
                for k, prefix in enumerate([f'{n}/' for n in names] or [''])
                for role, name in enumerate(INPUTS)
            }
        )
        types = {
            t: JOINT_STATE if combined else list(INPUTS.values())[role]
            for t, (role, _) in inputs.items()
        }
        present = {c.topic for c in reader.connections}
        connections_of(reader, [t for t in inputs if t in present], types)
        self.roles = {c.id: inputs[c.topic] for c in reader.connections if c.topic in inputs}
        replaced = (
            {topic(namespace, name) for name in COMBINED_OUTPUTS}
            if combined
            else {
                topic(namespace, f'{prefix}{name}')
                for prefix in [f'{n}/' for n in names] or ['']
                for name in OUTPUTS
            }
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
        has_commands = any(role == _COMMAND for role, _ in self.roles.values())
        if combined:
            self._estimates = [
                writer.topic(topic(namespace, 'force_estimates'), JOINT_STATE, [RELIABLE])
            ]
            self._commands = [
                writer.topic(topic(namespace, 'pressure_commands'), JOINT_STATE, [RELIABLE])
            ]
        else:
            prefixes = [f'{n}/' for n in names] or ['']
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
        self.settings, self.writer, self.rows, self.combined = settings, writer, rows, combined
        self.engine = Engine(
            [s.config for s in settings],
            hold=DIAGNOSTIC_PERIOD_NS * 1e-9,
            report_interval=REPORT_INTERVAL_PER_STATUS * len(settings),
            pairing=pairing,
            slop=slop,
        )
        self.recording = Recording(self.engine, arrays=combined)
        self.joints = [s.joint_name for s in settings]
        self._wrenches = [wrench_stamped(s.frame_id) for s in settings]
        self._pressures = [fluid_pressure(s.frame_id) for s in settings]
        self._joint_states: dict[tuple, Template] = {}  # by (names, field)
        self.summary = Summary(namespace)
        self._names = [f'model_node: {joint}' for joint in self.joints]
        ids = max(self.roles, default=0) + 1
        self._role = np.full(ids, -1)
        self._muscle = np.full(ids, -1)
        for cid, (role, k) in self.roles.items():
            self._role[cid], self._muscle[cid] = role, k
        self._copied = np.zeros(max(self.copies, default=0) + 1, bool)
        self._copied[list(self.copies)] = True

    def process(self, ids: list[int], times: list[int], data: list[bytes]) -> None:
        """A stretch of the recording, in log-time order: its messages' connection ids, log
        times [ns] and bytes.
        """
        ids, times = np.array(ids, np.int64), np.array(times, np.int64)
        first = self.summary.messages
        known = ids < len(self._role)
        roles = np.where(known, self._role[np.where(known, ids, 0)], -1)
        muscles = np.where(known, self._muscle[np.where(known, ids, 0)], -1)
        inputs = self._inputs(roles, muscles, times, data, first)
        input_at = first + np.flatnonzero(roles >= 0)
        stretch = self.recording.step(inputs, first, times, input_at)
        out = _Outputs()
        copied = ids < len(self._copied)
        copied[copied] = self._copied[ids[copied]]
        for cid in np.unique(ids[copied]).tolist():
            rows = np.flatnonzero(ids == cid)
            out.add(self.copies[cid], first + rows, out.COPY, times[rows], _pick(data, rows))
        self._answers(stretch, out, first, times)
        for report in stretch.reports:
            slot = out.CHANGE if report.after else out.TIMER
            out.add(self._diagnostics, [report.at], slot, [report.now], [self._status(report)])
        self.summary.diagnostics += len(stretch.reports)
        out.write(self.writer)
        self.summary.messages += len(data)

    def _inputs(self, roles, muscles, times, data, first) -> list[Inputs]:
        """Each muscle's inputs in the chunk, decoded."""
        n = len(self.joints)
        parts: list[list[tuple]] = [[] for _ in range(n)]  # per muscle: (rows, kind, ...)
        if self.combined:
            for role, array in (
                (_PRESSURE, 'position'),
                (_STATE, 'position'),
                (_COMMAND, 'effort'),
            ):
                rows = np.flatnonzero(roles == role)
                if not rows.size:
                    continue
                got = joint_columns(
                    _pick(data, rows), self.joints, array, DESERIALIZE['JointState']
                )
                for k in range(n):
                    mine = got.named[:, k] if role == _COMMAND else np.ones(len(rows), bool)
                    refused = {}
                    for i in np.flatnonzero(mine & ~got.present[:, k]).tolist():
                        absent = np.flatnonzero(~got.present[i]).tolist()
                        problems = got.problems[i]
                        refused[i] = problems[0] if role == _COMMAND else problems[absent.index(k)]
                    parts[k].append(
                        (rows, role, got.stamps, got.values[:, k], got.rates[:, k], refused, mine)
                    )
        else:
            for k in range(n):
                for role in (_PRESSURE, _STATE, _COMMAND):
                    rows = np.flatnonzero((roles == role) & (muscles == k))
                    if not rows.size:
                        continue
                    picked = _pick(data, rows)
                    rates, refused = np.full(len(rows), math.nan), {}
                    if role == _STATE:
                        got = joint_columns(
                            picked, [self.joints[k]], 'position', DESERIALIZE['JointState']
                        )
                        stamps, values, rates = got.stamps, got.values[:, 0], got.rates[:, 0]
                        for i in np.flatnonzero(~got.present[:, 0]).tolist():
                            refused[i] = got.problems[i][0]
                    elif role == _PRESSURE:
                        stamps, values = stamped_floats(
                            picked, DESERIALIZE['FluidPressure'], 'fluid_pressure'
                        )
                    else:
                        stamps, values = stamped_floats(
                            picked, DESERIALIZE['WrenchStamped'], 'force'
                        )
                    parts[k].append((rows, role, stamps, values, rates, refused, None))
        return [_merge(p, times, first) for p in parts]

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
        KeyValue, DiagnosticStatus = (
            T['diagnostic_msgs/msg/KeyValue'],
            T['diagnostic_msgs/msg/DiagnosticStatus'],
        )
        entries = [
            DiagnosticStatus(
                int(status.level),
                name,
                status.message,
                s.hardware_id,
                [KeyValue(key, value) for key, value in status.values.items()],
            )
            for name, s, status in zip(self._names, self.settings, report.statuses)
        ]
        time_ns = report.now
        header = Header(Time(time_ns // 10**9, time_ns % 10**9), '')
        return TYPESTORE.serialize_cdr(T[DIAGNOSTIC_ARRAY](header, entries), DIAGNOSTIC_ARRAY)


def _pick(data: Sequence[bytes], rows: np.ndarray) -> list[bytes]:
    """The items of ``data`` at ``rows``."""
    return [data[i] for i in rows.tolist()]


def _merge(parts: list[tuple], times: np.ndarray, first: int) -> Inputs:
    """One muscle's inputs from its topics' (rows, kind, stamps, values, rates, refused, which)."""
    if not parts:
        empty = np.zeros(0, np.int64)
        return Inputs(empty, empty, empty.astype(np.int8), empty, empty * 1.0, empty * 1.0)
    columns, refused, offset = [], {}, 0
    for rows, kind, stamps, values, rates, no, which in parts:
        keep = slice(None) if which is None else which
        kept = len(rows) if which is None else int(np.count_nonzero(which))
        columns.append(
            (rows[keep], np.full(kept, kind, np.int8), stamps[keep], values[keep], rates[keep])
        )
        if no:  # (refused messages are among those kept: their index among them)
            before = np.cumsum(which) - 1 if which is not None else None
            refused.update(
                {offset + (i if before is None else int(before[i])): why for i, why in no.items()}
            )
        offset += kept
    rows, kind, stamps, values, rates = (np.concatenate(c) for c in zip(*columns))
    order = np.argsort(rows, kind='stable')
    back = np.empty(len(order), np.intp)
    back[order] = np.arange(len(order))
    return Inputs(
        first + rows[order],
        times[rows[order]],
        kind[order],
        stamps[order],
        values[order],
        rates[order],
        {int(back[i]): why for i, why in refused.items()},
    )


def _stretches(
    items: Iterable[tuple[Connection, int, bytes]], size: int
) -> Iterator[tuple[list[int], list[int], list[bytes]]]:
    """The messages in stretches of ``size``: (connection ids, log times, data).  Kept as three
    lists, not as the reader's tuples: a hundred thousand tuples held make Python's cyclic garbage
    collector sweep them again and again (it cost a third of the run).
    """
    items = iter(items)
    while True:
        ids: list[int] = []
        times: list[int] = []
        data: list[bytes] = []
        add_id, add_time, add_data = ids.append, times.append, data.append
        for connection, time_ns, raw in islice(items, size):
            add_id(connection.id)
            add_time(time_ns)
            add_data(raw)
        if not data:
            return
        yield ids, times, data


@contextmanager
def _csv_rows(path: str | Path | None) -> Iterator[csv_module.writer | None]:
    """A CSV writer of the estimates to ``path`` (written beside it, renamed on success); None
    without a path.
    """
    if path is None:
        yield None
        return
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.partial', dir=path.parent)
    try:
        with os.fdopen(fd, 'w', newline='', encoding='utf-8') as out:
            rows = csv_module.writer(out)
            rows.writerow(CSV_COLUMNS)
            yield rows
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


class _Progress:
    """``n/total messages`` on stderr, rewritten at most every half second, only on a terminal."""

    def __init__(self, total: int, stream: TextIO = sys.stderr) -> None:
        self.total, self.stream, self._shown = total, stream, 0.0
        self.enabled = stream.isatty()

    def update(self, done: int, final: bool = False) -> None:
        if self.enabled and (final or time.monotonic() - self._shown > 0.5):
            self._shown = time.monotonic()
            share = done / self.total if self.total else 1.0
            bar = '#' * int(30 * share)
            self.stream.write(
                f'\r[{bar:<30}] {done}/{self.total} messages ({100 * share:.0f} %)'
                + ('\n' if final else '')
            )
            self.stream.flush()


def estimate_bag(
    bag: str | Path,
    settings: NodeSettings | list[NodeSettings],
    out: str | Path,
    *,
    names: list[str] | None = None,
    combined: bool = False,
    storage: str | None = None,
    namespace: str | None = None,
    csv: str | Path | None = None,
    progress: bool = True,
    outputs_only: bool = False,
    pairing: str = SPECS['pairing'].default,
    slop: float = SPECS['pairing_slop'].default,
    chunk: int = CHUNK,
) -> Summary:
    """Write ``out``: the recording ``bag`` plus what the model node with ``settings`` would
    publish.

    ``settings``: one muscle's, or every muscle's of a ``muscles:`` file, with their ``names`` and
    ``combined`` for ``input_mode: combined``; ``storage``: of ``out`` (default: the input's);
    ``namespace``: of the muscles' topics (default: the only one in the bag); ``csv``: also write
    the estimates there (:data:`CSV_COLUMNS`; gauge pressure, flags by name); ``outputs_only``:
    write only what the node publishes (and a recorded /diagnostics), not the inputs;
    ``pairing``, ``slop`` [s]: the node's ``pairing`` and ``pairing_slop``; ``chunk``: messages
    decided at once (the state carries over).  Raises BagError (nothing written) on bad input.
    """
    settings = [settings] if isinstance(settings, NodeSettings) else list(settings)
    names = list(names or [])
    first, second = (
        ('muscle_pressures', 'muscle_states')
        if combined
        else (
            (f'{names[0]}/pressure', f'{names[0]}/muscle_state')
            if names
            else ('pressure', 'muscle_state')
        )
    )
    with open_bag(bag) as reader:
        ns = muscle_namespace(reader, namespace, first, second)
        with BagWriter(out, storage or storage_of(bag)) as writer, _csv_rows(csv) as rows:
            node = _OfflineNode(
                settings, names, combined, ns, reader, writer, rows, outputs_only, pairing, slop
            )
            bar = _Progress(reader.message_count) if progress else None
            for stretch in _stretches(messages(reader, reader.connections), chunk):
                node.process(*stretch)
                if bar:
                    bar.update(node.summary.messages)
            if bar:
                bar.update(node.summary.messages, final=True)
    totals: dict[str, int] = {}
    for k in range(len(settings)):
        for key, n in node.recording.counts(k).items():
            totals[key] = totals.get(key, 0) + n
    node.summary.counts = totals
    return node.summary
