"""A stretch of a recording's input messages decoded into each muscle's
:class:`~pma_model_ros.core.runtime.recording.Inputs`, for the offline model node
(:mod:`.offline_node`): each topic's messages at once by the wire layer's column readers
(:mod:`~pma_model_ros.wire.columns`), what they do not read by rosbags' deserializer.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .bag_io import decode_cdr, FLUID_PRESSURE, JOINT_STATE, WRENCH_STAMPED
from ..core.runtime.recording import COMMAND_IN, Inputs, LENGTH_IN, PRESSURE_IN
from ..wire.cdr import MALFORMED
from ..wire.columns import joint_columns, stamped_floats

#: rosbags' deserializers of the input types: what the wire layer's fast readers do not read.
DESERIALIZE = {
    name: (lambda data, kind=kind: decode_cdr(data, kind))
    for name, kind in (
        ('FluidPressure', FLUID_PRESSURE),
        ('JointState', JOINT_STATE),
        ('WrenchStamped', WRENCH_STAMPED),
    )
}


def decode(
    roles: np.ndarray,
    muscles: np.ndarray,
    times: np.ndarray,
    data: Sequence[bytes],
    first: int,
    joints: Sequence[str],
    combined: bool,
) -> list[Inputs]:
    """Each muscle's inputs among a stretch of messages (at positions ``first`` ...): their
    ``roles`` (the kind of input, PRESSURE_IN, LENGTH_IN or COMMAND_IN; -1: none), ``muscles``
    (the muscle of a muscle's own topic; -1: none or combined), log ``times`` [ns] and ``data``;
    ``joints``: the muscles' joint names, in the node's order; ``combined``: the inputs are
    JointStates of every muscle.
    """
    n = len(joints)
    parts: list[list[tuple]] = [[] for _ in range(n)]  # per muscle: (rows, kind, ...)
    if combined:
        for role, array in (
            (PRESSURE_IN, 'position'),
            (LENGTH_IN, 'position'),
            (COMMAND_IN, 'effort'),
        ):
            rows = np.flatnonzero(roles == role)
            if not rows.size:
                continue
            got = joint_columns(pick(data, rows), joints, array, DESERIALIZE['JointState'])
            for k in range(n):
                mine = got.named[:, k] if role == COMMAND_IN else np.ones(len(rows), bool)
                refused = {}
                for i in np.flatnonzero(mine & ~got.present[:, k]).tolist():
                    absent = np.flatnonzero(~got.present[i]).tolist()
                    problems = got.problems[i]
                    refused[i] = problems[0] if role == COMMAND_IN else problems[absent.index(k)]
                parts[k].append(
                    (rows, role, got.stamps, got.values[:, k], got.rates[:, k], refused, mine)
                )
    else:
        for k in range(n):
            for role in (PRESSURE_IN, LENGTH_IN, COMMAND_IN):
                rows = np.flatnonzero((roles == role) & (muscles == k))
                if not rows.size:
                    continue
                picked = pick(data, rows)
                rates, refused = np.full(len(rows), math.nan), {}
                if role == LENGTH_IN:
                    got = joint_columns(picked, [joints[k]], 'position', DESERIALIZE['JointState'])
                    stamps, values, rates = got.stamps, got.values[:, 0], got.rates[:, 0]
                    for i in np.flatnonzero(~got.present[:, 0]).tolist():
                        refused[i] = got.problems[i][0]
                else:
                    kind, field = (
                        ('FluidPressure', 'fluid_pressure')
                        if role == PRESSURE_IN
                        else ('WrenchStamped', 'force')
                    )
                    stamps, values, malformed = stamped_floats(picked, DESERIALIZE[kind], field)
                    refused = dict.fromkeys(np.flatnonzero(malformed).tolist(), MALFORMED)
                parts[k].append((rows, role, stamps, values, rates, refused, None))
    return [_merge(p, times, first) for p in parts]


def pick(data: Sequence[bytes], rows: np.ndarray) -> list[bytes]:
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
