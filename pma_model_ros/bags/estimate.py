"""Offline force estimation: what ``model_node`` would publish for a recording, written to a new
bag.

The model node's decisions over the recording in one pass, with "now" = each message's log time
(what the node's clock reads when the bag is played with ``--clock`` into a node with
``use_sim_time``): the recording is read in stretches; each input topic's messages are decoded into
arrays at once (:mod:`~pma_model_ros.wire.columns`), the engine's rules run over each muscle's
arrays (:class:`~pma_model_ros.core.runtime.recording.Recording`), and the answers are written from
templates, in the order the node publishes them (:class:`.offline_node.OfflineNode`).
``test/test_bags_estimate.py`` pins the output to the node's callbacks driven message by message
(the wire layer and :class:`~pma_model_ros.core.runtime.engine.Engine`), byte for byte. The topics
are those of the parameter file's muscles, under the recording's namespace:

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
  change (the engine's: not the identification values and expected error model_node adds).

A recording that holds a measured force (``<ns>/measured_force``, for one muscle else
``<ns>/force``; ``<ns>/<name>/measured_force``; combined ``<ns>/measured_forces``) is judged as
model_node judges it with ``residual.enabled``, over the whole recording: the
:attr:`~.offline_node.Summary.residual` figures (no topic is written for them).

Topics of these names already in the recording are replaced (``/diagnostics`` is kept and merged).
"""

from __future__ import annotations

from contextlib import contextmanager
import csv as csv_module
from itertools import islice
import os
from pathlib import Path
import sys
import tempfile
import time
from typing import Iterable, Iterator, TextIO

from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader

from .bag_io import (
    BagError,
    BagWriter,
    messages,
    open_bag,
    storage_of,
    topic,
)
from .offline_node import (
    CSV_COLUMNS,
    OfflineNode,
    Summary,
)
from ..core.files.node_parameters import SPECS
from ..core.files.param_file import NodeSettings
from ..core.runtime.residual import Residuals

CHUNK = 100_000  # messages read, decided and written per step


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
            node = OfflineNode(
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
    node.summary.reasons = {
        s.joint_name: node.recording.reasons(k) for k, s in enumerate(settings)
    }
    if node.residual is not None:
        node.summary.residual = {
            s.joint_name: residual_line(node.residual, k, node.last_time)
            for k, s in enumerate(settings)
        }
    return node.summary


def residual_line(residual: Residuals, k: int, now: int) -> str:
    """Muscle ``k``'s residual over the whole recording ending at ``now`` [ns]: the figures, the
    level model_node would give them and the samples' counts.
    """
    level, message, figures = residual.report(k, now)
    values = residual.values(k, figures)
    if 'residual' in values:  # not judged
        return values['residual']
    return (
        f'measured - served: {values["residual [% of max force]"]}; {level.name}'
        + (f' ({message})' if message else '')
        + f'; samples: {values["residual samples"]}'
        + (
            f'; last refused: {values["residual last refused"]}'
            if residual.last_problem[k]
            else ''
        )
    )
