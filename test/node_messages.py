"""Message builders shared by the node tests, and :func:`record` of what a node publishes."""

import copy

from geometry_msgs.msg import WrenchStamped
import numpy as np
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import FluidPressure, JointState

AMBIENT = 101325.0  # [Pa], the config's ambient_pressure
JOINT = 'DMSP-10-250'  # the config's joint_name
#: Deep queues for the test's subscriptions: its executor takes one message per spin_once,
#: so at a few hundred messages per second a shallow queue would drop some.
SENSOR_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
RELIABLE_QOS = QoSProfile(depth=1000)


def record(publisher) -> list:
    """What ``publisher`` publishes from now on, as messages (the nodes publish most of theirs
    serialized).
    """
    sent = []
    publisher.publish = lambda msg: sent.append(
        deserialize_message(msg, publisher.msg_type)
        if isinstance(msg, bytes)
        else copy.deepcopy(msg)
    )
    return sent


def raw(msg) -> bytes:
    """``msg`` serialized by rclpy: what a raw subscription's callback receives."""
    return serialize_message(msg)


def pressure(stamp, absolute: float) -> FluidPressure:
    msg = FluidPressure(fluid_pressure=absolute)
    msg.header.stamp = stamp
    return msg


def state(stamp, length: float, rate: float = 0.0, name: str = JOINT) -> JointState:
    msg = JointState(name=[name], position=[length], velocity=[rate])
    msg.header.stamp = stamp
    return msg


def force_command(force: float) -> WrenchStamped:
    msg = WrenchStamped()
    msg.wrench.force.x = force
    return msg


def stamped(kind, frame: str, stamp: tuple[int, int], value: float):
    """A FluidPressure or WrenchStamped (``kind``) with ``frame``, ``stamp`` (sec, nanosec) and
    its float (``fluid_pressure``, ``wrench.force.x``).
    """
    msg = kind()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    if kind is FluidPressure:
        msg.fluid_pressure = value
    else:
        msg.wrench.force.x = value
    return msg


def stamp_key(msg) -> int:
    """A header stamp in integer nanoseconds."""
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def status_prefix(namespace: str, node: str = 'model_node') -> str:
    """What the names of the statuses of ``node`` in ``namespace`` start with: its fully
    qualified name without the leading slash, then ``': '`` (as diagnostic_updater names them).
    """
    return f'{namespace.strip("/")}/{node}: '.lstrip('/')


def model_statuses(diagnostics: list, namespace: str) -> list:
    """The DiagnosticStatus entries of model_node in ``namespace`` (named ``<namespace>/model_node:
    <joint>``), oldest first.
    """
    ours = status_prefix(namespace)
    return [s for d in diagnostics for s in d.status if s.name.startswith(ours)]


def status_values(status) -> dict[str, str]:
    """A DiagnosticStatus's key/value pairs as a dict."""
    return {kv.key: kv.value for kv in status.values}


#: Values a damaged sequence or string count takes (:func:`damage`): empty, small, one past the
#: data, huge.
COUNTS = (0, 1, 2, 3, 7, 64, 2**16, 2**31 - 1, 2**32 - 1)
#: The ways :func:`damage` harms a message.
HARMS = ('truncate', 'flip', 'insert', 'count', 'append', 'garbage')


def damage(data: bytes, harms: list[tuple[str, int, bytes]]) -> bytes:
    """``data`` (a serialized message) harmed by each (how, where, bytes) of ``harms`` in turn:
    cut at ``where``, one bit flipped, ``bytes`` inserted, a 4-byte count (4-aligned from the
    CDR origin) set to one of :data:`COUNTS`, ``bytes`` appended, or the whole replaced by
    ``bytes``.
    """
    out = bytearray(data)
    for how, where, junk in harms:
        if how == 'truncate':
            del out[where % (len(out) + 1) :]
        elif how == 'flip' and out:
            out[where % len(out)] ^= 1 << (where % 8)
        elif how == 'insert':
            at = where % (len(out) + 1)
            out[at:at] = junk
        elif how == 'count' and len(out) >= 8:
            at = 4 + 4 * (where % ((len(out) - 4) // 4))
            out[at : at + 4] = COUNTS[where % len(COUNTS)].to_bytes(4, 'little')
        elif how == 'append':
            out += junk
        elif how == 'garbage':
            out = bytearray(junk)
    return bytes(out)


def random_harms(rng) -> list[tuple[str, int, bytes]]:
    """One to three harms for :func:`damage`, drawn from ``rng`` (a numpy Generator)."""
    return [
        (
            HARMS[int(rng.integers(len(HARMS)))],
            int(rng.integers(2**16)),
            rng.bytes(int(rng.integers(1, 48))),
        )
        for _ in range(int(rng.integers(1, 4)))
    ]


def refused(data: bytes, kind) -> bool:
    """Whether rclpy's deserializer refuses ``data`` as a ``kind`` message."""
    try:
        deserialize_message(data, kind)
    except Exception:  # rclpy raises RMWError: any exception is a refusal
        return True
    return False


def malformed(rng, good: bytes, kind, count: int) -> list[bytes]:
    """``count`` harmed copies of ``good`` (a serialized ``kind`` message) that rclpy's
    deserializer refuses, drawn from ``rng`` (a numpy Generator).
    """
    out = []
    while len(out) < count:
        data = damage(good, random_harms(rng))
        if refused(data, kind):
            out.append(data)
    return out


def big_endian(msg) -> bytes:
    """``msg`` (an rclpy JointState, FluidPressure or WrenchStamped) as big-endian CDR, which the
    fast readers leave to the deserializer.
    """
    from pma_model_ros.bags.bag_io import JOINT_STATE, TYPESTORE  # rosbags: a test library

    T = TYPESTORE.types
    header = T['std_msgs/msg/Header'](
        T['builtin_interfaces/msg/Time'](msg.header.stamp.sec, msg.header.stamp.nanosec),
        msg.header.frame_id,
    )
    if isinstance(msg, JointState):
        kind = JOINT_STATE
        arrays = [np.array(getattr(msg, f), float) for f in ('position', 'velocity', 'effort')]
        ours = T[kind](header, list(msg.name), *arrays)
    elif isinstance(msg, FluidPressure):
        kind = 'sensor_msgs/msg/FluidPressure'
        ours = T[kind](header, msg.fluid_pressure, msg.variance)
    else:
        kind = 'geometry_msgs/msg/WrenchStamped'
        vector = T['geometry_msgs/msg/Vector3']
        wrench = T['geometry_msgs/msg/Wrench'](
            vector(msg.wrench.force.x, 0.0, 0.0), vector(0.0, 0.0, 0.0)
        )
        ours = T[kind](header, wrench)
    return bytes(TYPESTORE.serialize_cdr(ours, kind, little_endian=False))
