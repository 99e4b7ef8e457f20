"""A stamped message serialized once, then patched per use: its stamp and its trailing float64
fields.

Serializing a ROS message field by field costs more than the estimate it carries (about 10 us for
a WrenchStamped in rclpy, 14 us for a JointState of 64 muscles).  The nodes and the bag tools
publish or write the same message over and over with a new stamp and new numbers at fixed places,
so they serialize it once, with every other field final, and patch those bytes.  Works for any
little-endian CDR message whose header (``std_msgs/Header``) comes first, as in every stamped
message, and whose patched float64 values are consecutive (``WrenchStamped`` force.x,
``JointState`` effort).
"""

from __future__ import annotations

import struct

import numpy as np

_CDR_LE = b'\x00\x01'  # encapsulation: plain CDR, little-endian
_STAMP = struct.Struct('<iI')


#: Placeholder values of the patched fields while the template is serialized: found in its bytes
#: afterwards.
SENTINEL = 1.2345678901234567e-300


class StampedTemplate:
    """``data``: the serialized message, with the patched float64 fields set to ``SENTINEL * (1 +
    i)``, i = 0 .. ``count`` - 1, consecutive (rclpy's serializer may append bytes after the
    message, so they are searched for).
    """

    def __init__(self, data: bytes, count: int) -> None:
        if bytes(data[:2]) != _CDR_LE:
            raise ValueError(f'not little-endian CDR (encapsulation {bytes(data[:4])!r})')
        self._buffer = bytearray(data)
        at = self._buffer.find(sentinels(count).tobytes())  # the first: stale bytes may follow
        if at < 0:
            raise ValueError(f'the {count} sentinel values are not in the serialized message')
        #: The patched float64 fields, a view into the message bytes: write into it.
        self.values = np.frombuffer(self._buffer, np.float64, count, at)
        self.values[:] = 0.0

    def __call__(self, sec: int, nanosec: int) -> bytes:
        """The message bytes with header stamp ``sec``.``nanosec`` and the current ``values``."""
        _STAMP.pack_into(self._buffer, 4, sec, nanosec)
        return bytes(self._buffer)


def sentinels(count: int) -> np.ndarray:
    """The values to give the patched fields of a message before serializing it into a template."""
    return SENTINEL * np.arange(1, count + 1)
