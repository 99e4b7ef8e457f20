"""``sensor_msgs/JointState`` bytes to arrays, and where this node's joints sit in them.

A stream's messages normally repeat one layout: the same frame_id, names and array lengths, only
the stamp and the numbers change.  :class:`JointStateReader` learns the layout from a message its
deserializer decoded, then reads the next ones of that layout with ``np.frombuffer`` at the cached
offsets (the header, names and array lengths compared as bytes, the alignment padding between
them masked out: rclpy's serializer leaves whatever was in memory there).  Any other message (new
names or lengths, another encapsulation or endianness) goes to the deserializer again; one it
refuses raises :class:`~.cdr.MalformedMessage`.
:class:`JointIndex` turns a layout into which of the node's joints a message gives a value of, with
the reason for each one it does not (once per layout).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np

from .cdr import CdrWriter, decode, LITTLE_ENDIAN, STAMP, stamp_ns

_FIELDS = ('position', 'velocity', 'effort')


class JointStateArrays(NamedTuple):
    """One JointState's content: stamp [ns], names and the three arrays (float64)."""

    stamp: int
    #: the names; the same list object for every message of one layout, names and array lengths
    #: (see :class:`JointIndex`)
    names: list[str]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


@dataclass(frozen=True)
class _Layout:
    names: list[str]
    key: bytes  #: bytes 12 .. end of the position count: frame_id, names, position count
    #: the same bytes as an integer with the padding bytes 0, and the mask that zeroes them
    masked_key: int
    mask: int
    counts: tuple[tuple[int, bytes], ...]  #: (offset, bytes) of the velocity and effort counts
    arrays: tuple[tuple[int, int], ...]  #: (offset, count) of position, velocity, effort values
    end: int  #: where the last value ends


class JointStateReader:
    """Reads JointState bytes; ``deserialize(data)`` (rclpy's or rosbags') decodes what the cached
    layout does not fit.  ``fast`` counts the messages read at the cached layout, ``decoded`` the
    others.
    """

    def __init__(self, deserialize: Callable[[bytes], object]) -> None:
        self._deserialize = deserialize
        self._layout: _Layout | None = None
        self.fast = self.decoded = 0

    def __call__(self, data: bytes) -> JointStateArrays:
        layout = self._layout
        if (
            layout is not None
            and len(data) >= layout.end
            and (
                (key := data[12 : 12 + len(layout.key)]) == layout.key
                or int.from_bytes(key, 'little') & layout.mask == layout.masked_key
            )
            and data[:2] == LITTLE_ENDIAN
            and all(data[at : at + 4] == raw for at, raw in layout.counts)
        ):
            self.fast += 1
            sec, nanosec = STAMP.unpack_from(data, 4)
            (p_at, p_n), (v_at, v_n), (e_at, e_n) = layout.arrays
            return JointStateArrays(
                stamp_ns(sec, nanosec),
                layout.names,
                np.frombuffer(data, np.float64, p_n, p_at),
                np.frombuffer(data, np.float64, v_n, v_at),
                np.frombuffer(data, np.float64, e_n, e_at),
            )
        self.decoded += 1
        msg = decode(self._deserialize, data)
        names = list(msg.name)
        arrays = [np.asarray(getattr(msg, f), np.float64) for f in _FIELDS]
        layout = _learn(data, msg.header.frame_id, names, arrays) or self._layout
        self._layout = layout
        if (
            layout is not None
            and layout.names == names
            and all(len(a) == n for a, (_, n) in zip(arrays, layout.arrays))
        ):
            names = layout.names  # the same layout: names, and the arrays' lengths
        stamp = msg.header.stamp
        return JointStateArrays(stamp_ns(stamp.sec, stamp.nanosec), names, *arrays)

    @property
    def names(self) -> list[str] | None:
        """The names of the cached layout (None: none yet)."""
        return None if self._layout is None else self._layout.names

    def read_many(
        self, joined: np.ndarray, starts: np.ndarray, sizes: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]] | None:
        """The messages of ``joined`` (the bytes of many messages, uint8) at ``starts``, of
        ``sizes`` bytes, read at once where they have the cached layout, as a call each would read
        them: (which have it, their stamps [ns], their position, velocity and effort rows); None
        without a layout.
        """
        layout = self._layout
        if layout is None:
            return None
        ok = sizes >= layout.end
        if not ok.any():  # (then ``joined`` may be shorter than the layout)
            none = np.zeros((0, 0))
            return ok, np.zeros(0, np.int64), [none, none, none]
        base = np.where(ok, starts, 0)
        ok &= (joined[base] == LITTLE_ENDIAN[0]) & (joined[base + 1] == LITTLE_ENDIAN[1])
        mask = layout.mask.to_bytes(len(layout.key), 'little')
        ok &= _equal_rows(joined, base + 12, layout.key, mask)
        for at, raw in layout.counts:
            ok &= _equal_rows(joined, base + at, raw)
        rows = base[ok]
        self.fast += len(rows)
        sec = gather(joined, rows + 4, 4).view('<i4').ravel()
        nanosec = gather(joined, rows + 8, 4).view('<u4').ravel()
        stamps = stamp_ns(sec.astype(np.int64), nanosec)
        arrays = [gather(joined, rows + at, 8 * n).view('<f8') for at, n in layout.arrays]
        return ok, stamps, arrays


def gather(joined: np.ndarray, at: np.ndarray, width: int) -> np.ndarray:
    """The ``width`` bytes at each offset ``at`` of ``joined`` (uint8): rows of a new array."""
    return joined[at[:, None] + np.arange(width)] if width else np.zeros((len(at), 0), np.uint8)


#: Bytes compared per step in :func:`_equal_rows` (bounds its temporary arrays).
_BLOCK_BYTES = 1 << 22


def _equal_rows(joined: np.ndarray, at: np.ndarray, expected: bytes, mask: bytes | None = None):
    """Which of the byte strings at offsets ``at`` of ``joined`` equal ``expected``, on the bytes
    where ``mask`` (as long, 0 or 0xff each; None: all) is set.
    """
    want = np.frombuffer(expected, np.uint8)
    keep = np.ones(len(want), bool) if mask is None else np.frombuffer(mask, np.uint8) != 0
    columns = np.arange(len(want))[keep]
    want = want[keep]
    out = np.empty(len(at), bool)
    step = max(1, _BLOCK_BYTES // max(1, len(columns)))
    for start in range(0, len(at), step):
        rows = at[start : start + step]
        out[start : start + step] = (joined[rows[:, None] + columns] == want).all(axis=1)
    return out


def _learn(
    data: bytes, frame_id: str, names: list[str], arrays: list[np.ndarray]
) -> _Layout | None:
    """The layout of a little-endian message with this content (offsets as CDR places them), if
    its bytes agree; None otherwise (another encapsulation: it is decoded every time).
    """
    if data[:2] != LITTLE_ENDIAN:
        return None
    writer = CdrWriter()
    writer.header(frame_id)
    writer.count(len(names))
    for name in names:
        writer.string(name)
    places, counts = [], []
    for values in arrays:
        count_at, at = writer.floats(len(values))
        counts.append((count_at, bytes(writer.data[count_at : count_at + 4])))
        places.append((at, len(values)))
    end = len(writer.data)
    if len(data) < end or any(data[at : at + 4] != raw for at, raw in counts):
        return None
    key_end = counts[0][0] + 4
    mask = bytearray(b'\xff' * (key_end - 12))
    for at in writer.padding:
        if 12 <= at < key_end:
            mask[at - 12] = 0
    key, mask_int = bytes(data[12:key_end]), int.from_bytes(mask, 'little')
    return _Layout(
        names,
        key,
        int.from_bytes(key, 'little') & mask_int,
        mask_int,
        tuple(counts[1:]),
        tuple(places),
        end,
    )


class JointIndex:
    """Where each of ``joints`` (this node's joint names, in its order) sits in a JointState's
    ``field`` array, per layout: the index of each joint (0 where absent), which are present (None:
    all) and why each absent one is absent.
    """

    def __init__(self, joints: Sequence[str], field: str = 'position') -> None:
        self.joints, self.field = list(joints), field
        self._names: list[str] | None = None
        self._verdict: tuple[np.ndarray, np.ndarray | None, list[str]] = (
            np.zeros(0, np.intp),
            None,
            [],
        )
        self._in_order = False

    def of(self, msg: JointStateArrays) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
        if msg.names is not self._names:
            self._names, self._verdict = msg.names, self._find(msg)
            take, present, _ = self._verdict
            self._in_order = present is None and take.tolist() == list(range(len(msg.names)))
        return self._verdict

    def in_order(self, msg: JointStateArrays) -> bool:
        """Whether ``msg`` holds the joints, and only them, in this index's order."""
        self.of(msg)
        return self._in_order

    def _find(self, msg: JointStateArrays) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
        values = getattr(msg, self.field)
        rates = msg.velocity if self.field == 'position' else ()
        found = [
            joint_problem(msg.names, values, rates, joint, self.field) or msg.names.index(joint)
            for joint in self.joints
        ]
        present = np.array([isinstance(i, int) for i in found])
        take = np.array([i if isinstance(i, int) else 0 for i in found], np.intp)
        problems = [i for i in found if isinstance(i, str)]
        return take, (None if present.all() else present), problems


def joint_problem(
    names: Sequence[str],
    values: Sequence[float],
    rates: Sequence[float],
    joint: str,
    field: str = 'position',
) -> str:
    """Why a JointState's ``names``, ``field`` array (``values``) and velocities (``rates``, may be
    empty) give no value of ``joint`` ('' if they do).
    """
    if not len(names) or not len(values):
        return f'empty name or {field} array'
    if len(values) != len(names) or (len(rates) and len(rates) != len(names)):
        velocities = f', {len(rates)} velocities' if field == 'position' else ''
        return f'mismatched arrays: {len(names)} names, {len(values)} {field}s{velocities}'
    if joint not in names:
        return f"joint '{joint}' not in {list(names)}"
    return ''
