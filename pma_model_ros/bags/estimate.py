"""Offline force estimation: what ``model_node`` would publish for a recording, written to a new bag.

The recording's ``<ns>/pressure`` (FluidPressure), ``<ns>/muscle_state`` (JointState) and,
if present, ``<ns>/force_command`` (WrenchStamped) messages drive one
:class:`~pma_model_ros.core.estimator.Estimator` in log-time order, through the same
calls as the node's callbacks, with "now" = the message's log time (what the node's
clock reads when the bag is played with ``--clock`` into a node with ``use_sim_time``).
So the output holds, beside every original message (copied as recorded):

* ``<ns>/force_estimate`` (WrenchStamped): stamp = the newer input's header stamp,
  ``frame_id`` and force.x = tension [N], at the log time of the input that completed it;
* ``<ns>/pressure_command`` (FluidPressure, absolute Pa) for each usable force command,
  stamped with its log time;
* ``/diagnostics``: the node's status every second of bag time and on each level change.

Topics of these names already in the recording are replaced (``/diagnostics`` is kept
and merged).  The force of the candidate pair at each message (newest valid pressure
and length) is evaluated in one vectorised call per chunk; the estimator, message by
message, makes every decision and must form that same pair.
"""
from __future__ import annotations

from contextlib import contextmanager
import csv as csv_module
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import struct
import sys
import tempfile
import time
from typing import Iterable, Iterator, TextIO

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader

from ..core.estimator import Estimator, joint_problem, length_problem, pressure_problem
from ..core.flags import describe
from ..core.param_file import NodeSettings
from .bag_io import (DIAGNOSTIC_ARRAY, FLUID_PRESSURE, JOINT_STATE, RELIABLE, TYPESTORE, WRENCH_STAMPED, BagError,
                     BagWriter, connections_of, deserialize, messages, open_bag, storage_of, topic)
#: The node's input topics (relative names) and their types.
INPUTS = {"pressure": FLUID_PRESSURE, "muscle_state": JOINT_STATE, "force_command": WRENCH_STAMPED}
#: The node's output topics (relative names) written here.
OUTPUTS = ("force_estimate", "pressure_command")
DIAGNOSTICS = "/diagnostics"
DIAGNOSTIC_PERIOD_NS = 1_000_000_000   # model_node's status timer [ns]
CHUNK = 20_000                         # messages read, evaluated and written per step
_PRESSURE, _STATE, _COMMAND = range(3)
CSV_COLUMNS = ("log_time_ns", "stamp_s", "pressure_pa", "length_m", "length_rate_mps", "force_n", "flags")

T = TYPESTORE.types
Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]


def muscle_namespace(reader: Reader, namespace: str | None = None) -> str:
    """The namespace whose ``pressure`` and ``muscle_state`` topics the recording holds.

    ``namespace`` if given; else the only one found (a BagError if none or several).
    """
    if namespace is not None:
        return "/" + namespace.strip("/")
    have = {c.topic for c in reader.connections}
    found = sorted({t.removesuffix("/pressure") or "/" for t in have
                    if t.endswith("/pressure") and topic(t.removesuffix("/pressure") or "/", "muscle_state") in have})
    if len(found) != 1:
        what = f"several muscles ({', '.join(found)}); choose one with --namespace" if found else \
            f"no <namespace>/pressure and <namespace>/muscle_state topics (topics: {', '.join(sorted(have)) or 'none'})"
        raise BagError(f"{reader.path}: {what}")
    return found[0]


class WrenchStampedCdr:
    """Little-endian CDR bytes of a WrenchStamped with a fixed ``frame_id``: stamp and force.x packed in a template."""

    def __init__(self, frame_id: str) -> None:
        Wrench, Vector3 = T["geometry_msgs/msg/Wrench"], T["geometry_msgs/msg/Vector3"]
        zero = Vector3(0.0, 0.0, 0.0)
        template = TYPESTORE.serialize_cdr(T[WRENCH_STAMPED](Header(Time(0, 0), frame_id), Wrench(zero, zero)),
                                           WRENCH_STAMPED, little_endian=True)
        self._template = bytes(template)
        self._force_x = len(self._template) - 6 * 8   # force x, y, z and torque x, y, z close the message

    def __call__(self, sec: int, nanosec: int, force: float) -> bytes:
        data = bytearray(self._template)
        struct.pack_into("<iI", data, 4, sec, nanosec)
        struct.pack_into("<d", data, self._force_x, force)
        return bytes(data)


@dataclass
class Summary:
    """What :func:`estimate_bag` read and wrote."""

    namespace: str
    messages: int = 0       #: messages read (all topics)
    estimates: int = 0      #: force_estimate messages written
    commands: int = 0       #: pressure_command messages written
    diagnostics: int = 0    #: /diagnostics messages written
    counts: dict[str, int] = field(default_factory=dict)   #: the estimator's counters at the end


class _OfflineNode:
    """The model node's callbacks over a recording, writing what it would publish."""

    def __init__(self, settings: NodeSettings, namespace: str, reader: Reader, writer: BagWriter,
                 rows: csv_module.writer | None) -> None:
        names = {role: topic(namespace, name) for role, name in zip((_PRESSURE, _STATE, _COMMAND), INPUTS)}
        wanted = [t for t in names.values() if t in {c.topic for c in reader.connections}]
        connections_of(reader, wanted, {topic(namespace, n): typ for n, typ in INPUTS.items()})
        self.roles = {c.id: role for c in reader.connections for role, name in names.items() if c.topic == name}
        replaced = {topic(namespace, name) for name in OUTPUTS}
        self.copies: dict[int, Connection] = {}
        self._diagnostics = None
        for c in reader.connections:
            if c.topic in replaced:
                continue
            self.copies[c.id] = writer.copy_topic(c)
            if c.topic == DIAGNOSTICS and c.msgtype == DIAGNOSTIC_ARRAY:
                self._diagnostics = self.copies[c.id]
        if self._diagnostics is None:
            self._diagnostics = writer.topic(DIAGNOSTICS, DIAGNOSTIC_ARRAY, [RELIABLE])
        self._estimates = writer.topic(topic(namespace, "force_estimate"), WRENCH_STAMPED, [RELIABLE])
        self._commands = (writer.topic(topic(namespace, "pressure_command"), FLUID_PRESSURE, [RELIABLE])
                          if names[_COMMAND] in wanted else None)
        self.settings, self.writer, self.rows = settings, writer, rows
        self.estimator = Estimator(settings.config, hold=DIAGNOSTIC_PERIOD_NS * 1e-9)
        self.summary = Summary(namespace)
        self._name = f"{namespace.rstrip('/')}/model_node: {settings.joint_name}"
        self._wrench = WrenchStampedCdr(settings.frame_id)
        self._carry = (math.nan, math.nan, math.nan)   # newest valid (absolute pressure, length, rate) so far
        self._next_status_ns: int | None = None

    def _parse(self, chunk: list[tuple[Connection, int, bytes]]) -> tuple[list, list[int], np.ndarray, np.ndarray]:
        """Deserialized inputs (None for other topics), and per message: role (-1: other), usable, value, rate."""
        joint, limit, roles_of = self.settings.joint_name, self.settings.config.model.max_length, self.roles
        parsed, roles, values = [], [], []
        none = (math.nan, math.nan, False)
        for connection, _, data in chunk:
            role = roles_of.get(connection.id, -1)
            roles.append(role)
            if role < 0:
                parsed.append(None)
                values.append(none)
                continue
            msg = deserialize(data, connection)
            parsed.append(msg)
            if role == _PRESSURE:
                values.append((msg.fluid_pressure, math.nan, not pressure_problem(msg.fluid_pressure)))
            elif role == _STATE and not joint_problem(msg.name, msg.position, msg.velocity, joint):
                i = msg.name.index(joint)
                length = float(msg.position[i])
                values.append((length, msg.velocity[i] if len(msg.velocity) else math.nan,
                               not length_problem(length, limit)))
            else:
                values.append(none)
        value, rate, usable = np.array(values, float).T if values else np.empty((3, 0))
        return parsed, roles, usable.astype(bool), np.column_stack([value, rate])

    def _candidates(self, role_list: list[int], usable: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per message: gauge pressure [Pa], length [m], rate [m/s], force [N] and flags of the newest usable
        pressure and length (NaN where there is none), forces evaluated in one call."""
        roles = np.array(role_list, int)
        n = roles.size
        index = np.arange(1, n + 1)
        table = np.vstack([[self._carry[0], math.nan], [self._carry[1], self._carry[2]], values])
        newest_p = np.maximum.accumulate(np.where(usable & (roles == _PRESSURE), index + 1, 0))
        newest_l = np.maximum.accumulate(np.where(usable & (roles == _STATE), index + 1, 1))
        absolute, (length, rate) = table[newest_p, 0], table[newest_l].T
        self._carry = (absolute[-1], length[-1], rate[-1]) if n else self._carry
        gauge = absolute - self.settings.config.ambient_pressure
        force, flags = np.full(n, math.nan), np.zeros(n, np.uint16)
        todo = usable & np.isfinite(gauge) & np.isfinite(length)
        if todo.any():
            result = self.settings.config.model.force(gauge[todo], length[todo], rate[todo])
            force[todo], flags[todo] = result.force, result.flags
        return gauge, length, rate, force, flags

    def process(self, chunk: list[tuple[Connection, int, bytes]]) -> None:
        """One chunk of the recording, in log-time order."""
        parsed, roles, usable, values = self._parse(chunk)
        gauge, length, rate, force, flags = (a.tolist() for a in self._candidates(roles, usable, values))
        est, write, copies, joint = self.estimator, self.writer.write_raw, self.copies, self.settings.joint_name
        estimates, wrench, rows, summary = self._estimates, self._wrench, self.rows, self.summary
        if self._next_status_ns is None and chunk:
            self._next_status_ns = chunk[0][1] + DIAGNOSTIC_PERIOD_NS
        next_status = self._next_status_ns
        for i, (connection, time_ns, data) in enumerate(chunk):
            while time_ns >= next_status:   # the node's status timer
                self._status(next_status)
                next_status += DIAGNOSTIC_PERIOD_NS
            copy = copies.get(connection.id)
            if copy is not None:
                write(copy, time_ns, data)
            role = roles[i]
            if role < 0:
                continue
            msg, now = parsed[i], time_ns * 1e-9
            stamp = msg.header.stamp
            if role == _PRESSURE:
                pair = est.pressure(msg.fluid_pressure, stamp.sec + stamp.nanosec * 1e-9, now, stamp)
            elif role == _STATE:
                pair = est.joint_state(msg.name, msg.position, msg.velocity, joint,
                                       stamp.sec + stamp.nanosec * 1e-9, now, stamp)
            else:
                pair = None
                self._command(est.command(msg.wrench.force.x, now), time_ns)
            if pair is not None:
                if pair.gauge != gauge[i] or pair.length != length[i]:
                    raise AssertionError(f"estimator paired {pair}, vectorised candidate {gauge[i]}, {length[i]}")
                estimate = est.accept(pair, force[i], flags[i], now)
                if estimate is not None:
                    tag = estimate.tag
                    write(estimates, time_ns, wrench(tag.sec, tag.nanosec, estimate.force))
                    summary.estimates += 1
                    if rows is not None:
                        rows.writerow((time_ns, f"{tag.sec}.{tag.nanosec:09d}", pair.gauge, float(pair.length),
                                       rate[i], estimate.force, describe(estimate.flags)))
            if est.status_due(now):
                self._status(time_ns)
        self._next_status_ns = next_status
        self.summary.messages += len(chunk)

    def _command(self, command, time_ns: int) -> None:
        if command is None or self._commands is None:
            return
        header = Header(Time(time_ns // 10**9, time_ns % 10**9), self.settings.frame_id)
        self.writer.write(self._commands, time_ns, T[FLUID_PRESSURE](header, command.pressure, 0.0))
        self.summary.commands += 1

    def _status(self, time_ns: int) -> None:
        status = self.estimator.status(time_ns * 1e-9)
        KeyValue, DiagnosticStatus = T["diagnostic_msgs/msg/KeyValue"], T["diagnostic_msgs/msg/DiagnosticStatus"]
        entry = DiagnosticStatus(int(status.level), self._name, status.message, self.settings.config.model.spec.name,
                                 [KeyValue(k, v) for k, v in status.values.items()])
        header = Header(Time(time_ns // 10**9, time_ns % 10**9), "")
        self.writer.write(self._diagnostics, time_ns, T[DIAGNOSTIC_ARRAY](header, [entry]))
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
    """A CSV writer of the estimates to ``path`` (written beside it, renamed on success); None without a path."""
    if path is None:
        yield None
        return
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(fd, "w", newline="", encoding="utf-8") as out:
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
            bar = "#" * int(30 * share)
            self.stream.write(f"\r[{bar:<30}] {done}/{self.total} messages ({100 * share:.0f} %)"
                              + ("\n" if final else ""))
            self.stream.flush()


def estimate_bag(bag: str | Path, settings: NodeSettings, out: str | Path, *, storage: str | None = None,
                 namespace: str | None = None, csv: str | Path | None = None, progress: bool = True) -> Summary:
    """Write ``out``: the recording ``bag`` plus what the model node with ``settings`` would publish.

    ``storage``: of ``out`` (default: the input's); ``namespace``: of the muscle's topics
    (default: the only one in the bag); ``csv``: also write the estimates there
    (:data:`CSV_COLUMNS`; gauge pressure, flags by name).  Raises BagError (nothing written) on bad input.
    """
    with open_bag(bag) as reader:
        ns = muscle_namespace(reader, namespace)
        with BagWriter(out, storage or storage_of(bag)) as writer, _csv_rows(csv) as rows:
            node = _OfflineNode(settings, ns, reader, writer, rows)
            bar = _Progress(reader.message_count) if progress else None
            for chunk in _chunks(messages(reader, reader.connections), CHUNK):
                node.process(chunk)
                if bar:
                    bar.update(node.summary.messages)
            if bar:
                bar.update(node.summary.messages, final=True)
    node.summary.counts = dict(node.estimator.counts)
    return node.summary
