"""Offline force estimation: what ``model_node`` would publish for a recording, written to a new
bag.

The recording's input topics drive one :class:`~pma_model_ros.core.engine.Engine` in log-time
order, through the same calls as the node's callbacks, with "now" = the message's log time (what
the node's clock reads when the bag is played with ``--clock`` into a node with ``use_sim_time``).
The topics are those of the parameter file's muscles, under the recording's namespace:

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
import os
from pathlib import Path
import sys
import tempfile
import time
from typing import Iterable, Iterator, TextIO

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
from ..core.param_file import NodeSettings
from ..wire.cdr import fluid_pressure
from ..wire.muscle_inputs import MuscleInputs

#: The node's input topics of one muscle (relative names) and their types.
INPUTS = {'pressure': FLUID_PRESSURE, 'muscle_state': JOINT_STATE, 'force_command': WRENCH_STAMPED}
#: The node's input topics in combined mode, all JointStates.
COMBINED_INPUTS = ('muscle_pressures', 'muscle_states', 'force_commands')
#: The node's output topics (relative names) written here: per muscle, and in combined mode.
OUTPUTS = ('force_estimate', 'pressure_command')
COMBINED_OUTPUTS = ('force_estimates', 'pressure_commands')
DIAGNOSTICS = '/diagnostics'
DIAGNOSTIC_PERIOD_NS = 1_000_000_000  # model_node's status timer [ns]
CHUNK = 20_000  # messages read and written per step
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


class _OfflineNode:
    """The model node's callbacks over a recording, writing what it would publish."""

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
        )
        self.joints = [s.joint_name for s in settings]
        self._inputs = MuscleInputs(
            self.engine, self.joints, [s.frame_id for s in settings], DESERIALIZE
        )
        self._commands_out = [fluid_pressure(s.frame_id) for s in settings]
        self.summary = Summary(namespace)
        self._names = [f'model_node: {joint}' for joint in self.joints]
        self._next_status_ns: int | None = None

    def process(self, chunk: list[tuple[Connection, int, bytes]]) -> None:
        """One chunk of the recording, in log-time order."""
        engine, write, copies, roles = self.engine, self.writer.write_raw, self.copies, self.roles
        inputs = self._inputs
        if self._next_status_ns is None and chunk:
            self._next_status_ns = chunk[0][1] + DIAGNOSTIC_PERIOD_NS
        next_status = self._next_status_ns
        for connection, now, data in chunk:
            while now >= next_status:  # the node's status timer
                self._status(next_status)
                next_status += DIAGNOSTIC_PERIOD_NS
            copy = copies.get(connection.id)
            if copy is not None:
                write(copy, now, data)
            role, k = roles.get(connection.id, (None, 0))
            if role is None:
                continue
            if role == _COMMAND:
                self._command(k, data, now)
            elif self.combined:
                out = (
                    inputs.pressures(data, now) if role == _PRESSURE else inputs.states(data, now)
                )
                self._estimate(None, out, now)
            else:
                out = (
                    inputs.pressure(k, data, now)
                    if role == _PRESSURE
                    else inputs.muscle_state(k, data, now)
                )
                self._estimate(k, out, now)
            if engine.status_due(now):
                self._status(now)
        self._next_status_ns = next_status
        self.summary.messages += len(chunk)

    def _estimate(self, k: int | None, out: bytes | None, time_ns: int) -> None:
        if out is None:
            return
        self.writer.write_raw(self._estimates[k or 0], time_ns, out)
        engine = self.engine
        if self.rows is None:
            self.summary.estimates += (
                1
                if k is not None
                else len(self.joints)
                if engine.every
                else int(np.count_nonzero(engine.estimated))
            )
            return
        estimated = np.flatnonzero(engine.estimated).tolist()
        self.summary.estimates += len(estimated)
        stamp = f'{engine.stamp // 10**9}.{engine.stamp % 10**9:09d}'
        for i in estimated:
            muscle = i if k is None else k
            gauge, length, rate = engine.inputs(muscle)
            self.rows.writerow(
                (
                    time_ns,
                    stamp,
                    gauge,
                    length,
                    rate,
                    engine.forces.item(i),
                    describe(int(engine.flags[i])),
                    self.joints[muscle],
                )
            )

    def _command(self, k: int, data: bytes, time_ns: int) -> None:
        if self.combined:
            out = self._inputs.force_commands(data, time_ns)
            if out is not None:
                self.writer.write_raw(self._commands[0], time_ns, out(time_ns))
                self.summary.commands += len(out.values)
            return
        pressure = self._inputs.force_command(k, data, time_ns)
        if pressure is None or not self._commands:
            return
        template = self._commands_out[k]
        template.values[0] = pressure
        self.writer.write_raw(self._commands[k], time_ns, template(time_ns))
        self.summary.commands += 1

    def _status(self, time_ns: int) -> None:
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
            for name, s, status in zip(self._names, self.settings, self.engine.statuses(time_ns))
        ]
        header = Header(Time(time_ns // 10**9, time_ns % 10**9), '')
        self.writer.write(self._diagnostics, time_ns, T[DIAGNOSTIC_ARRAY](header, entries))
        self.summary.diagnostics += 1


def _chunks(items: Iterable, size: int) -> Iterator[list]:
    chunk = []
    for item in items:
        chunk.append(item)
        if len(chunk) == size:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


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
) -> Summary:
    """Write ``out``: the recording ``bag`` plus what the model node with ``settings`` would
    publish.

    ``settings``: one muscle's, or every muscle's of a ``muscles:`` file, with their ``names`` and
    ``combined`` for ``input_mode: combined``; ``storage``: of ``out`` (default: the input's);
    ``namespace``: of the muscles' topics (default: the only one in the bag); ``csv``: also write
    the estimates there (:data:`CSV_COLUMNS`; gauge pressure, flags by name); ``outputs_only``:
    write only what the node publishes (and a recorded /diagnostics), not the inputs.  Raises
    BagError (nothing written) on bad input.
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
            node = _OfflineNode(settings, names, combined, ns, reader, writer, rows, outputs_only)
            bar = _Progress(reader.message_count) if progress else None
            for chunk in _chunks(messages(reader, reader.connections), CHUNK):
                node.process(chunk)
                if bar:
                    bar.update(node.summary.messages)
            if bar:
                bar.update(node.summary.messages, final=True)
    totals: dict[str, int] = {}
    for k in range(len(settings)):
        for key, n in node.engine.counts(k).items():
            totals[key] = totals.get(key, 0) + n
    node.summary.counts = totals
    return node.summary
