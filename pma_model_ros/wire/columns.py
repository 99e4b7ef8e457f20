"""Many messages of one topic into arrays at once: ``bag estimate``'s reading of a recording.

The readers of :mod:`.cdr` and :mod:`.joint_state` over a list of messages: the bytes of all of
them are joined and their fields gathered with numpy at the offsets a message's layout gives.  A
message that the gathering does not fit (another encapsulation or endianness, a truncated one, a
JointState of a layout not seen before) is read by the per-message reader, or its deserializer,
with the same result; a JointState of a new layout then teaches the reader that layout for the
rest.  A message its deserializer refuses gives no value (``malformed message``, as the node
rejects it).  What the node does with each value is :mod:`.muscle_inputs`' (the engine's calls);
these give the values and which joints a message holds, with the reasons for those it does not.
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple, Sequence

import numpy as np

from .cdr import aligned, FLOATS, LITTLE_ENDIAN, MALFORMED, MalformedMessage, stamp_ns
from .joint_state import gather, JointIndex, JointStateArrays, JointStateReader
from .muscle_inputs import stamped_value

_PAD = bytes(16)  # after the last message: offsets of a refused message stay in the buffer


def joined(datas: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the messages' bytes joined, uint8, 16 bytes of padding after; where each starts; its
    size).
    """
    sizes = np.fromiter(map(len, datas), np.int64, len(datas))
    starts = np.zeros(len(datas), np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    return np.frombuffer(b''.join([*datas, _PAD]), np.uint8), starts, sizes


def stamped_floats(
    datas: Sequence[bytes], deserialize: Callable[[bytes], object], field: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(header stamps [ns], values, which are malformed) of FluidPressure (``field``
    ``fluid_pressure``) or WrenchStamped (``force``) messages: what
    :func:`.muscle_inputs.stamped_value` gives each (a malformed one: stamp 0, value NaN).
    """
    buf, starts, sizes = joined(datas)
    ok = sizes >= 16
    base = np.where(ok, starts, 0)
    ok &= (buf[base] == LITTLE_ENDIAN[0]) & (buf[base + 1] == LITTLE_ENDIAN[1])
    end = 16 + gather(buf, base + 12, 4).view('<u4').ravel().astype(np.int64)
    at = aligned(end, 8)  # the first float64 after the header
    ok &= at + 8 * FLOATS[field] <= sizes
    base = np.where(ok, base, 0)
    sec = gather(buf, base + 4, 4).view('<i4').ravel().astype(np.int64)
    stamps = stamp_ns(sec, gather(buf, base + 8, 4).view('<u4').ravel())
    values = gather(buf, np.where(ok, base + at, 0), 8).view('<f8').ravel().copy()
    malformed = np.zeros(len(datas), bool)
    for i in np.flatnonzero(~ok).tolist():
        try:
            stamps[i], values[i] = stamped_value(datas[i], deserialize, field)
        except MalformedMessage:
            stamps[i], values[i], malformed[i] = 0, math.nan, True
    return stamps, values, malformed


class JointColumns(NamedTuple):
    """n JointStates read for N joints (the node's, in its order)."""

    stamps: np.ndarray  #: (n,) [ns]
    values: np.ndarray  #: (n, N) each joint's value of the field (NaN where not present)
    #: (n, N) each joint's velocity (NaN: none, not finite, or not present); field ``position``
    rates: np.ndarray
    present: np.ndarray  #: (n, N) bool: the message gives a value of the joint
    named: np.ndarray  #: (n, N) bool: the joint is among the message's names
    #: per message, the reasons of the joints not present, in joint order (empty: all present)
    problems: list[list[str]]


def joint_columns(
    datas: Sequence[bytes],
    joints: Sequence[str],
    field: str,
    deserialize: Callable[[bytes], object],
) -> JointColumns:
    """Read JointState messages as :class:`~.joint_state.JointStateReader` and
    :class:`~.joint_state.JointIndex` read each (the joints' ``field`` array: ``position`` or
    ``effort``); the messages of a layout seen before are gathered at once.  A malformed message
    names every joint and gives none (each joint's problem: ``malformed message``).
    """
    n, count = len(datas), len(joints)
    out = JointColumns(
        np.zeros(n, np.int64),
        np.full((n, count), math.nan),
        np.full((n, count), math.nan),
        np.zeros((n, count), bool),
        np.zeros((n, count), bool),
        [[]] * n,
    )
    reader, index = JointStateReader(deserialize), JointIndex(joints, field)
    buf, starts, sizes = joined(datas)
    rows = np.arange(n)
    while rows.size:
        first = rows.item(0)
        try:
            msg = reader(datas[first])
        except MalformedMessage:
            out.named[first], out.problems[first] = True, [MALFORMED] * count
            rows = rows[1:]
            continue
        _fill(out, rows[:1], index, msg, msg.stamp, getattr(msg, field)[None], msg.velocity[None])
        rows = rows[1:]
        got = reader.read_many(buf, starts[rows], sizes[rows]) if rows.size else None
        if got is None or not got[0].any():
            continue
        matched, stamps, (position, velocity, effort) = got
        like = JointStateArrays(0, reader.names, position[0], velocity[0], effort[0])
        values = position if field == 'position' else effort
        _fill(out, rows[matched], index, like, stamps, values, velocity)
        rows = rows[~matched]
    return out


def _fill(
    out: JointColumns,
    rows: np.ndarray,
    index: JointIndex,
    like: JointStateArrays,
    stamps: np.ndarray | int,
    values: np.ndarray,
    velocity: np.ndarray,
) -> None:
    """Rows ``rows`` of ``out`` from messages of one layout (``like``: one of them) with these
    stamps, field values and velocities (one row per message).
    """
    take, present, problems = index.of(like)
    out.stamps[rows] = stamps
    out.present[rows] = True if present is None else present
    out.named[rows] = [joint in like.names for joint in index.joints]
    if problems:
        for row in rows.tolist():
            out.problems[row] = problems
    if present is not None and not present.any():
        return  # (then the arrays may not hold the joints' indices)
    out.values[rows] = values[:, take]
    if index.field == 'position' and velocity.shape[1]:
        rates = velocity[:, take]
        out.rates[rows] = np.where(np.isfinite(rates), rates, math.nan)
