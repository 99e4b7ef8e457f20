"""``diagnostic_msgs/DiagnosticArray`` written as plain CDR bytes (little-endian): the bytes of
rosbags' serializer, and of rclpy's but for what rclpy leaves in the alignment padding.

model_node's 1 Hz report of 64 muscles is 64 statuses of about 35 key-values each, and it stalls
the executor while it is built: as rclpy messages (2,240 ``KeyValue`` objects converted by
``publish``) the whole report took 5.3 ms, written here 1.7-2.0 ms (``bench/node_latency.py``
prints it; docs/performance.md).  After the header every field is a string, a uint32 count
or the one-byte level, so the bytes are the strings' lengths, texts and NULs, with zeros that
align each uint32 to 4 bytes.  A text's bytes at each of the four alignments are kept: most texts
repeat from report to report.
"""

from __future__ import annotations

import struct
from typing import Iterable

from .cdr import LITTLE_ENDIAN, split

_HEADER = struct.Struct('<2s2xiI')  # encapsulation, options, stamp; then frame_id ''
_EMPTY_FRAME = b'\x01\x00\x00\x00\x00'  # frame_id '': length 1, the NUL
_U32 = struct.Struct('<I')
_PADDING = (b'', b'\x00', b'\x00\x00', b'\x00\x00\x00')
#: (text, padding before it) -> its bytes: the keys and most values (the levels' texts, settings,
#: identification results, counters at 0) repeat from report to report; cleared when full
_chunks: dict[tuple[str, int], bytes] = {}
_CHUNKS_MAX = 20_000


def _chunk(text: str, pad: int) -> bytes:
    """``pad`` zero bytes, then the CDR string ``text``: uint32 length with the NUL, UTF-8, NUL
    (kept in :data:`_chunks`).
    """
    raw = text.encode()
    chunk = _chunks[text, pad] = _PADDING[pad] + _U32.pack(len(raw) + 1) + raw + b'\x00'
    return chunk


def diagnostic_array(
    stamp_ns: int, node: str, entries: Iterable[tuple[str, str, int, str, dict[str, str]]]
) -> bytes:
    """A DiagnosticArray stamped ``stamp_ns`` [ns], frame_id empty, with a status per entry
    (name, hardware_id, level, message, values) of the node named ``node``: each status named
    ``<node>: <name>``, as diagnostic_updater names its tasks' statuses.
    """
    entries = list(entries)
    if len(_chunks) > _CHUNKS_MAX:
        _chunks.clear()
    parts = [
        _HEADER.pack(LITTLE_ENDIAN, *split(stamp_ns)),
        _EMPTY_FRAME,
        _PADDING[3],  # to the status count: 8 + 5 bytes after the origin, 3 more to 16
        _U32.pack(len(entries)),
    ]
    at = 20  # bytes after the 4 of the encapsulation (CDR's origin of alignment)
    append, cached = parts.append, _chunks.get
    for name, hardware_id, level, message, values in entries:
        append(bytes((level,)))
        at += 1
        for text in (f'{node}: {name}', message, hardware_id):
            pad = -at % 4
            chunk = cached((text, pad)) or _chunk(text, pad)
            append(chunk)
            at += len(chunk)
        pad = -at % 4
        append(_PADDING[pad] + _U32.pack(len(values)))
        at += pad + 4
        for item in values.items():
            for text in item:
                pad = -at % 4
                chunk = cached((text, pad)) or _chunk(text, pad)
                append(chunk)
                at += len(chunk)
    return b''.join(parts)
