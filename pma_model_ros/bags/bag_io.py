"""Reading and writing rosbag2 bags (mcap and sqlite3 storage) with ``rosbags`` and ROS 2 Jazzy
types.

The one function most tools need::

    from pma_model_ros.bags.bag_io import read
    for topic, log_time_ns, msg in read("run1", topics=["/m1/pressure"]):
        print(topic, log_time_ns, msg.fluid_pressure)

``read`` takes what ``ros2 bag record`` writes (a bag directory with ``metadata.yaml``)
or a single ``.mcap`` / ``.db3`` file, and yields messages in log-time order as the
``rosbags`` message classes of :data:`TYPESTORE` (field names as in the ``.msg``
files; ``header.stamp.sec``, ``.nanosec``).  Every user error (missing or damaged
bag, a topic that is absent or of another type, message definitions that differ from
Jazzy's) raises :class:`BagError`, whose text is one line.

:class:`BagWriter` writes a new bag atomically: a bag directory (``run1``: ``run1/run1.mcap``
and ``metadata.yaml``), or the one storage file a name ending in ``.mcap`` / ``.db3`` asks for
(``run1.mcap``).  It is written under a temporary name beside the target and renamed on
:meth:`BagWriter.close`, so an interrupted or failed run never leaves a partial bag at the target
path.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
import shutil
import struct
import tempfile
from typing import Collection, Iterable, Iterator, Sequence

import apsw  # rosbags' SQLite binding
from rosbags.interfaces import (
    Connection,
    MessageDefinitionFormat,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, ReaderError, StoragePlugin, Writer, WriterError
from rosbags.serde import SerdeError
from rosbags.typesys import (
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
    Stores,
    TypesysError,
)
import yaml

#: Message definitions of ROS 2 Jazzy: what every bag is read and written with.
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
#: Storage plugin names (as in ``ros2 bag record -s``) and their ``rosbags`` plugins.
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
_SUFFIXES = {'.mcap': 'mcap', '.db3': 'sqlite3', '.sqlite3': 'sqlite3'}
_INFINITE = QosTime(9223372036, 854775807)  # rmw's "infinite" duration, as rosbag2 records it
#: Errors ``rosbags`` raises on a damaged bag (truncated files surface as struct, EOF or SQLite
#: errors).
_DAMAGED = (
    ReaderError,
    SerdeError,
    TypesysError,
    apsw.Error,
    struct.error,
    EOFError,
    KeyError,
    IndexError,
    AssertionError,
    ValueError,
    OSError,
)


def qos(reliable: bool, depth: int) -> Qos:
    """A keep-last, volatile QoS profile as rosbag2 records it."""
    return Qos(
        QosHistory.KEEP_LAST,
        depth,
        QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        QosDurability.VOLATILE,
        _INFINITE,
        _INFINITE,
        QosLiveliness.AUTOMATIC,
        _INFINITE,
        False,
    )


#: rclpy's ``qos_profile_sensor_data`` (pressure, muscle_state, force) and the nodes' reliable
#: depth-10 outputs.
SENSOR_DATA = qos(reliable=False, depth=5)
RELIABLE = qos(reliable=True, depth=10)


#: The message types of this package's topics.
FLUID_PRESSURE, JOINT_STATE = 'sensor_msgs/msg/FluidPressure', 'sensor_msgs/msg/JointState'
WRENCH_STAMPED, DIAGNOSTIC_ARRAY = (
    'geometry_msgs/msg/WrenchStamped',
    'diagnostic_msgs/msg/DiagnosticArray',
)


def topic(namespace: str, name: str) -> str:
    """``name`` in ``namespace`` as ROS resolves a relative name (``/`` + name in the root
    namespace).
    """
    return f'{namespace.rstrip("/")}/{name}'


class BagError(ValueError):
    """A bag the tools cannot use; the message is one line for the user."""


def _one_line(err: BaseException) -> str:
    text = ' '.join(str(err).split()) or type(err).__name__
    return text if len(text) < 200 else text[:197] + '...'


def storage_of(path: str | Path) -> str:
    """Storage plugin of a bag (``mcap`` or ``sqlite3``): the directory's metadata or the file's
    suffix.
    """
    path = Path(path)
    if path.is_dir():
        try:
            info = yaml.safe_load((path / 'metadata.yaml').read_text(encoding='utf-8'))
            storage = info['rosbag2_bagfile_information']['storage_identifier']
        except (OSError, yaml.YAMLError, KeyError, TypeError) as err:
            raise BagError(f'{path}: no readable metadata.yaml ({_one_line(err)})') from None
    else:
        storage = _SUFFIXES.get(path.suffix, '')
    if storage not in STORAGES:
        raise BagError(f'{path}: storage {storage or path.suffix!r} is neither mcap nor sqlite3')
    return storage


def storage_for(out: str | Path, storage: str | None = None) -> str:
    """Storage of a new bag: ``storage`` if given, else from the suffix of ``out``, else mcap
    (Jazzy's default).
    """
    if storage is None:
        storage = _SUFFIXES.get(Path(out).suffix, 'mcap')
    if storage not in STORAGES:
        raise BagError(f'unknown storage {storage!r}; one of {", ".join(STORAGES)}')
    return storage


@contextmanager
def open_bag(path: str | Path) -> Iterator[Reader]:
    """An open ``rosbags`` reader of ``path``; a missing or unreadable bag is a BagError."""
    path = Path(path)
    if not path.exists():
        raise BagError(f'bag not found: {path}')
    try:
        reader = Reader(path)
        reader.open()
    except _DAMAGED as err:
        raise BagError(
            f'{path}: not a readable rosbag2 bag, or truncated ({_one_line(err)})'
        ) from None
    try:
        yield reader
    finally:
        reader.close()


def messages(
    reader: Reader, connections: Collection[Connection]
) -> Iterator[tuple[Connection, int, bytes]]:
    """The reader's messages of ``connections`` (log-time order); a damaged storage file is a
    BagError.
    """
    try:
        yield from reader.messages(connections)
    except _DAMAGED as err:
        raise BagError(f'{reader.path}: damaged or truncated bag ({_one_line(err)})') from None


def _definition_hash(connection: Connection) -> str | None:
    """RIHS01 hash of the definition the bag holds for the connection's type; None if it holds
    none.
    """
    definition = connection.msgdef
    if definition.format == MessageDefinitionFormat.MSG and definition.data:
        types = get_types_from_msg(definition.data, connection.msgtype)
    elif definition.format == MessageDefinitionFormat.IDL and definition.data:
        types = {}
        for part in definition.data.split('=' * 80 + '\n'):
            if part.startswith('IDL: '):
                types.update(get_types_from_idl(part.split('\n', 1)[1]))
    else:
        return connection.digest or None
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store.hash_rihs01(connection.msgtype)


def check_connection(connection: Connection, msgtype: str | None = None) -> None:
    """Raise BagError unless the connection carries ``msgtype`` (if given) with Jazzy's definition
    of it.

    A bag without definitions (old sqlite3 bags) is trusted by type name; one whose
    definitions differ (ROS 1 ``Header.seq``, another distro's changed message) is refused.
    """
    where = f'topic {connection.topic}'
    if msgtype is not None and connection.msgtype != msgtype:
        raise BagError(f'{where} has type {connection.msgtype}, expected {msgtype}')
    if connection.msgtype not in TYPESTORE.fielddefs:
        raise BagError(f'{where}: type {connection.msgtype} is not a ROS 2 Jazzy message type')
    try:
        recorded = _definition_hash(connection)
    except (TypesysError, KeyError, ValueError) as err:
        raise BagError(
            f'{where}: unreadable message definition of {connection.msgtype} ({_one_line(err)})'
        ) from None
    if recorded is not None and recorded != TYPESTORE.hash_rihs01(connection.msgtype):
        raise BagError(
            f"{where}: the bag's definition of {connection.msgtype} differs from ROS 2 Jazzy's "
            '(recorded with another ROS distro?)'
        )


def connections_of(
    reader: Reader, topics: Collection[str] | None, types: dict[str, str] | None = None
) -> list[Connection]:
    """The checked connections of ``topics`` (all if None); ``types`` maps topics to their required
    type.
    """
    present = {c.topic for c in reader.connections}
    missing = sorted(set(topics or ()) - present)
    if missing:
        raise BagError(
            f'{reader.path}: no topic {", ".join(missing)} (topics: '
            f'{", ".join(sorted(present)) or "none"})'
        )
    chosen = [c for c in reader.connections if topics is None or c.topic in topics]
    for connection in chosen:
        check_connection(connection, (types or {}).get(connection.topic))
    return chosen


def read(
    path: str | Path, topics: Collection[str] | None = None
) -> Iterator[tuple[str, int, object]]:
    """``(topic, log_time_ns, message)`` of a bag in log-time order, for ``topics`` (None: all).

    Messages are :data:`TYPESTORE` classes.  Raises BagError (one line) for a missing,
    damaged or foreign bag and for topics it does not hold.
    """
    with open_bag(path) as reader:
        connections = connections_of(reader, topics)
        for connection, time_ns, data in messages(reader, connections):
            yield connection.topic, time_ns, deserialize(data, connection)


def decode_cdr(data: bytes | memoryview, typename: str) -> object:
    """One :data:`TYPESTORE` message of ``typename`` from its CDR bytes, the bytes after its end
    ignored as rclpy's deserializer ignores them (rclpy's serializer leaves 4 or more after some
    JointStates; ``TYPESTORE.deserialize_cdr`` refuses more than 3).  Raises SerdeError,
    struct.error or ValueError for bytes it cannot read.
    """
    if len(data) < 4 or bytes(data[:2]) not in (b'\x00\x00', b'\x00\x01'):
        raise SerdeError('invalid or unsupported CDR encapsulation')
    msgdef = TYPESTORE.get_msgdef(typename)
    read = msgdef.deserialize_cdr_le if data[1] else msgdef.deserialize_cdr_be
    return read(memoryview(data)[4:], 0, msgdef.cls, TYPESTORE)[0]


def deserialize(data: bytes | memoryview, connection: Connection) -> object:
    """One message of ``connection`` from its CDR bytes."""
    try:
        return decode_cdr(data, connection.msgtype)
    except (SerdeError, struct.error, IndexError, ValueError, UnicodeDecodeError) as err:
        raise BagError(
            f'topic {connection.topic}: cannot decode a {connection.msgtype} ({_one_line(err)})'
        ) from None


class BagWriter:
    """A new rosbag2 bag at ``out``, written under a temporary name beside it; renamed by
    :meth:`close`.

    ``out`` must not exist; a name ending in ``.mcap`` or ``.db3`` gets that storage file alone,
    any other name a bag directory.  Use as a context manager (an exception aborts: nothing is
    left at ``out``) or call :meth:`close` / :meth:`abort` yourself.
    """

    def __init__(self, out: str | Path, storage: str | None = None) -> None:
        self.out = Path(out)
        self.storage = storage_for(out, storage)
        if self.out.exists() or self.out.is_symlink():
            raise BagError(f'{self.out} exists already; not overwriting it')
        if not self.out.parent.is_dir():
            raise BagError(f'directory {self.out.parent} does not exist')
        self._file = self.out.suffix in _SUFFIXES  # one storage file, not a directory
        if self._file and _SUFFIXES[self.out.suffix] != self.storage:
            raise BagError(f'{self.out}: a {self.out.suffix} file cannot hold {self.storage}')
        self._tmp = Path(
            tempfile.mkdtemp(prefix=f'.{self.out.name}.', suffix='.partial', dir=self.out.parent)
        )
        self._bag = self._tmp / (self.out.stem if self._file else self.out.name)
        self._writer = Writer(
            self._bag,
            version=Writer.VERSION_LATEST,
            storage_plugin=STORAGES[self.storage],
        )
        try:
            self._writer.open()
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise

    def topic(
        self, topic: str, msgtype: str, offered_qos: Iterable[Qos] = (RELIABLE,)
    ) -> Connection:
        """A new topic of Jazzy type ``msgtype`` (e.g. ``geometry_msgs/msg/WrenchStamped``)."""
        return self._writer.add_connection(
            topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=list(offered_qos)
        )

    def copy_topic(self, connection: Connection, topic: str | None = None) -> Connection:
        """A topic like a read bag's ``connection`` (same type, definition, hash and recorded
        QoS).
        """
        return self._writer.add_connection(
            topic or connection.topic,
            connection.msgtype,
            msgdef=connection.msgdef.data or None,
            rihs01=connection.digest or None,
            typestore=TYPESTORE,
            serialization_format=connection.ext.serialization_format,
            offered_qos_profiles=connection.ext.offered_qos_profiles,
        )

    def write(self, connection: Connection, time_ns: int, message: object) -> None:
        """Serialize and write one message at log time ``time_ns``."""
        self._writer.write(
            connection, time_ns, TYPESTORE.serialize_cdr(message, connection.msgtype)
        )

    def write_raw(self, connection: Connection, time_ns: int, data: bytes | memoryview) -> None:
        """Write one already serialized (CDR) message at log time ``time_ns``."""
        self._writer.write(connection, time_ns, data)

    def write_many(
        self, connections: Sequence[Connection], times: Sequence[int], data: Sequence[bytes]
    ) -> None:
        """Write already serialized messages, in this order: ``data[i]`` of ``connections[i]``
        at log time ``times[i]``.
        """
        write = self._writer.write
        for connection, time_ns, raw in zip(connections, times, data):
            write(connection, time_ns, raw)

    def close(self) -> Path:
        """Finish the bag and move it to ``out``; the path."""
        try:
            self._writer.close()
            storage_file = next(p for p in self._bag.iterdir() if p.name != 'metadata.yaml')
            (storage_file if self._file else self._bag).rename(self.out)
        except (WriterError, OSError) as err:
            self.abort()
            raise BagError(f'cannot write {self.out}: {_one_line(err)}') from None
        shutil.rmtree(self._tmp, ignore_errors=True)
        return self.out

    def abort(self) -> None:
        """Drop the partial bag; nothing is left at ``out``."""
        if self._writer.storage is not None:
            self._writer.abort()
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
