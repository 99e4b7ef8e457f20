"""Plain CDR (little-endian, the encapsulation every ROS 2 Jazzy publisher and rosbag2 recording
uses): the stamped messages of this package written once and patched per use, and their stamp and
first float read in place.

Alignment is counted from the end of the 4-byte encapsulation header, as CDR defines it.  Messages
with a header (``std_msgs/Header``) first: ``header.stamp`` at bytes 4..12, ``header.frame_id``
(uint32 length with its NUL, the bytes) from 12.  A reader refuses (returns None for) anything
else: another encapsulation or endianness, a truncated message; its caller then uses a full
deserializer through :func:`decode`, which turns any refusal of it into :class:`MalformedMessage`.
A reader accepts only messages that rclpy's deserializer reads to the same values.
Serializers may leave arbitrary bytes in padding and after the message: nothing here reads them.
"""

from __future__ import annotations

import struct
from typing import Callable, Sequence

import numpy as np

LITTLE_ENDIAN = b'\x00\x01'  #: encapsulation: plain CDR, little-endian (options 0)
_ORIGIN = 4  # alignment origin: after the encapsulation header
STAMP = struct.Struct('<iI')  #: a header's builtin_interfaces/Time (sec, nanosec), little-endian
_U32 = struct.Struct('<I')
_F64 = struct.Struct('<d')
_SECOND = 10**9
#: float64 fields after the header: a FluidPressure's value and variance, a WrenchStamped's six
FLOATS = {'fluid_pressure': 2, 'force': 6}
MALFORMED = 'malformed message'  #: the reason a message its deserializer refuses is rejected for


class MalformedMessage(ValueError):
    """A message that its deserializer refused (truncated, corrupt counts, unknown
    encapsulation).
    """


def decode(deserialize: Callable[[bytes], object], data: bytes) -> object:
    """``deserialize(data)``; any refusal of it (rclpy raises RMWError, rosbags its own errors)
    as :class:`MalformedMessage`.
    """
    try:
        return deserialize(data)
    except Exception as err:  # whatever the deserializer raises is a refusal
        raise MalformedMessage(f'{MALFORMED}: {err}') from err


def aligned(offset, size: int):
    """``offset`` [bytes] (an int or an int array) moved up to the next multiple of ``size``
    counted from the CDR origin.
    """
    return offset + (-(offset - _ORIGIN)) % size


def split(stamp_ns: int) -> tuple[int, int]:
    """A time [ns] as ``builtin_interfaces/Time`` (sec, nanosec), nanosec in [0, 1e9)."""
    return stamp_ns // _SECOND, stamp_ns % _SECOND


def stamp_ns(sec, nanosec):
    """A ``builtin_interfaces/Time`` in integer nanoseconds (ints, or int64 arrays)."""
    return sec * _SECOND + nanosec


def frame_end(data: bytes) -> int | None:
    """Where the header's frame_id ends (its NUL included) in a little-endian message, or None."""
    if data[:2] != LITTLE_ENDIAN or len(data) < 16:
        return None
    end = 16 + _U32.unpack_from(data, 12)[0]
    return end if end <= len(data) else None


def stamped_float(data: bytes, floats: int) -> tuple[int, float] | None:
    """(header stamp [ns], the first float64 after the header) of a little-endian message with
    ``floats`` float64 fields after its header (:data:`FLOATS`): the ``fluid_pressure`` of a
    FluidPressure, the ``wrench.force.x`` of a WrenchStamped; None if it cannot be read so (a
    message shorter than all its fields, too).
    """
    end = frame_end(data)
    if end is None:
        return None
    at = aligned(end, 8)
    if at + 8 * floats > len(data):
        return None
    return stamp_ns(*STAMP.unpack_from(data, 4)), _F64.unpack_from(data, at)[0]


class CdrWriter:
    """A message written field by field (little-endian plain CDR), for the templates below."""

    def __init__(self) -> None:
        self.data = bytearray(LITTLE_ENDIAN + b'\x00\x00')
        #: where the alignment padding is [bytes]: serializers may leave anything there
        self.padding: list[int] = []

    def _align(self, size: int) -> None:
        end = aligned(len(self.data), size)
        self.padding += range(len(self.data), end)
        self.data += bytes(end - len(self.data))

    def header(self, frame_id: str) -> None:
        """``std_msgs/Header`` with stamp 0 (patched later) and ``frame_id``."""
        self.data += bytes(8)
        self.string(frame_id)

    def string(self, text: str) -> None:
        raw = text.encode() + b'\x00'
        self.count(len(raw))
        self.data += raw

    def count(self, n: int) -> None:
        """A uint32: a sequence's or a string's length."""
        self._align(4)
        self.data += _U32.pack(n)

    def float64(self, value: float = 0.0) -> int:
        """One float64; where it sits [bytes]."""
        self._align(8)
        at = len(self.data)
        self.data += _F64.pack(value)
        return at

    def floats(self, n: int) -> tuple[int, int]:
        """A float64 sequence of ``n`` zeros; where its count and its values start [bytes]."""
        self.count(n)
        count_at = len(self.data) - 4
        if n:
            self._align(8)
        at = len(self.data)
        self.data += bytes(8 * n)
        return count_at, at


class Template:
    """A serialized message whose stamp and ``values`` (consecutive float64 fields, a view into its
    bytes: write into it) change per use; every other field is fixed.
    """

    def __init__(self, writer: CdrWriter, at: int, count: int) -> None:
        self._buffer, self._at = writer.data, at
        self.values = np.frombuffer(self._buffer, np.float64, count, at)

    def __call__(self, stamp: int) -> bytes:
        """The message bytes stamped ``stamp`` [ns], with the current ``values``."""
        STAMP.pack_into(self._buffer, 4, *split(stamp))
        return bytes(self._buffer)

    def batch(self, stamps: np.ndarray, values: np.ndarray) -> list[bytes]:
        """The messages stamped ``stamps`` [ns] (n) with ``values`` (n x len(values)): what n
        calls give, written at once.
        """
        size, at = len(self._buffer), self._at
        rows = np.empty((len(stamps), size), np.uint8)
        rows[:] = np.frombuffer(self._buffer, np.uint8)
        sec, nanosec = np.divmod(np.asarray(stamps, np.int64), _SECOND)
        rows[:, 4:8] = sec.astype('<i4').view(np.uint8).reshape(-1, 4)
        rows[:, 8:12] = nanosec.astype('<u4').view(np.uint8).reshape(-1, 4)
        width = 8 * self.values.size
        flat = np.ascontiguousarray(values, '<f8').reshape(len(stamps), self.values.size)
        rows[:, at : at + width] = flat.view(np.uint8).reshape(-1, width)
        data = rows.tobytes()
        return [data[i : i + size] for i in range(0, len(data), size)]

    def unstamped(self) -> bytes:
        """The bytes of a message without a header, with the current ``values``."""
        return bytes(self._buffer)


def wrench_stamped(frame_id: str) -> Template:
    """``geometry_msgs/WrenchStamped``: ``values`` = [force.x]; the rest 0."""
    writer = CdrWriter()
    writer.header(frame_id)
    at = writer.float64()
    for _ in range(5):
        writer.float64()
    return Template(writer, at, 1)


def fluid_pressure(frame_id: str) -> Template:
    """``sensor_msgs/FluidPressure``: ``values`` = [fluid_pressure]; variance 0 (unknown)."""
    writer = CdrWriter()
    writer.header(frame_id)
    at = writer.float64()
    writer.float64()
    return Template(writer, at, 1)


def joint_state(names: Sequence[str], field: str, frame_id: str = '') -> Template:
    """``sensor_msgs/JointState`` of ``names``: ``values`` = the ``field`` array (``position``,
    ``velocity`` or ``effort``), one per name; the other two arrays empty.
    """
    writer = CdrWriter()
    writer.header(frame_id)
    writer.count(len(names))
    for name in names:
        writer.string(name)
    at = 0
    for which in ('position', 'velocity', 'effort'):
        if which == field:
            at = writer.floats(len(names))[1]
        else:
            writer.floats(0)
    return Template(writer, at, len(names))


def float64_multi_array(count: int) -> Template:
    """``std_msgs/Float64MultiArray`` of ``count`` values (``values`` = ``data``), its layout
    empty (no dimensions, data_offset 0): bytes by :meth:`Template.unstamped` (it has no header).
    """
    writer = CdrWriter()
    writer.count(0)  # layout.dim: no dimensions
    writer.count(0)  # layout.data_offset (uint32)
    return Template(writer, writer.floats(count)[1], count)
