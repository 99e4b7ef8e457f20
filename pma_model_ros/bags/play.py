"""``pma-model bag play``: publish a recording's messages with their recorded timing, like ``ros2
bag play``.

Each message is published, as its recorded CDR bytes (no conversion), on its topic (or
its ``--remap`` target) at start + (log time - first log time) / rate, with the
offered QoS recorded in the bag; without one, sensor-data QoS for ``pressure`` and
``muscle_state`` topics and reliable depth 10 otherwise.  With ``clock``, ``/clock``
(rosgraph_msgs/Clock) carries the bag time: before every message (so a node with
``use_sim_time`` sees "now" = the log time of what it receives, as ``pma-model bag
estimate`` assumes) and at ``clock`` Hz in between.  Only this module needs rclpy.
"""

from __future__ import annotations

import importlib
import sys
import time
from typing import Collection

from rosbags.interfaces import Connection

from .bag_io import BagError, connections_of, messages, open_bag

_SENSOR_TOPICS = ('pressure', 'muscle_state')
_FLUSH_TIMEOUT = 2.0  # [s] to wait for reliable subscribers' acks at the end
_LINGER = 1.0  # [s] the player stays after its last message (best effort has no acknowledgement)
_SETTLE = 1.0  # [s] with --wait-for-subscribers: no new subscriber for this long, the rest unread


def _message_class(msgtype: str) -> type:
    package, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        raise BagError(
            f'message type {msgtype} is not installed (ROS package {package})'
        ) from None


def _qos(connection: Connection):
    """The rclpy QoS profile to publish ``connection`` with (module docstring)."""
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        qos_profile_sensor_data,
        QoSProfile,
        ReliabilityPolicy,
    )

    offered = connection.ext.offered_qos_profiles
    if offered:
        q = offered[0]
        known = {
            'SYSTEM_DEFAULT',
            'RELIABLE',
            'BEST_EFFORT',
            'VOLATILE',
            'TRANSIENT_LOCAL',
            'KEEP_LAST',
            'KEEP_ALL',
        }
        if {q.reliability.name, q.durability.name, q.history.name} <= known:
            return QoSProfile(
                history=HistoryPolicy[q.history.name],
                depth=max(q.depth, 1),
                reliability=ReliabilityPolicy[q.reliability.name],
                durability=DurabilityPolicy[q.durability.name],
            )
    if connection.topic.rsplit('/', 1)[-1] in _SENSOR_TOPICS:
        return qos_profile_sensor_data
    return QoSProfile(depth=10)


def play(
    bag,
    rate: float = 1.0,
    clock: float | None = None,
    topics: Collection[str] | None = None,
    remaps: dict[str, str] | None = None,
    delay: float = 0.0,
    wait_for_subscribers: float = 0.0,
) -> int:
    """Publish the recording ``bag`` (module docstring); the number of messages published.

    ``rate``: speed factor; ``clock``: /clock frequency [Hz] between messages (None: no /clock);
    ``topics``: only these; ``remaps``: recorded topic -> published topic; ``delay`` [s] before the
    first message; ``wait_for_subscribers``: first wait up to this long [s] until every played
    topic has a subscriber (BagError if not).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rosgraph_msgs.msg import Clock

    remaps = remaps or {}
    with open_bag(bag) as reader:
        connections = connections_of(reader, topics)
        unknown = sorted(set(remaps) - {c.topic for c in connections})
        if unknown:
            raise BagError(f'--remap of topics not played: {", ".join(unknown)}')
        classes = {c.msgtype: _message_class(c.msgtype) for c in connections}
        rclpy.init()
        node = rclpy.create_node('pma_model_bag_player')
        try:
            publishers = {}
            for c in connections:
                name = remaps.get(c.topic, c.topic)
                if name not in publishers:
                    publishers[name] = node.create_publisher(classes[c.msgtype], name, _qos(c))
            routes = {c.id: publishers[remaps.get(c.topic, c.topic)] for c in connections}
            clock_pub = node.create_publisher(Clock, '/clock', 1) if clock else None
            _wait_for_subscribers(publishers, wait_for_subscribers)
            count = _publish(
                messages(reader, connections),
                routes,
                clock_pub,
                clock,
                rate,
                delay,
                reader.start_time,
            )
            time.sleep(_LINGER)  # samples in flight reach their readers before the publishers go
            return count
        except (KeyboardInterrupt, ExternalShutdownException):
            return 0
        finally:
            node.destroy_node()
            rclpy.try_shutdown()


def _wait_for_subscribers(publishers: dict, timeout: float) -> None:
    """Wait until every played topic has a subscriber, or, once some have, until no new one has
    matched for :data:`_SETTLE` s: a node subscribes what it reads, not every recorded topic
    (model_node reads no ``force``), and the topics without one are named on stderr.  BagError if
    none has a subscriber after ``timeout`` [s].
    """
    if timeout <= 0:
        return
    deadline, matched, since = time.monotonic() + timeout, set(), time.monotonic()
    while True:
        now = {name for name, pub in publishers.items() if pub.get_subscription_count() >= 1}
        if now == set(publishers):
            return
        if now != matched:
            matched, since = now, time.monotonic()
        if matched and (time.monotonic() - since >= _SETTLE or time.monotonic() > deadline):
            unread = ', '.join(sorted(set(publishers) - matched))
            print(f'bag play: no subscriber on {unread}; played all the same', file=sys.stderr)
            return
        if time.monotonic() > deadline:
            raise BagError(
                f'no subscriber after {timeout:g} s on any of {", ".join(sorted(publishers))} '
                '(a node in another network namespace? see scripts/netns-run --shell)'
            )
        time.sleep(0.01)


def _publish(
    stream,
    routes: dict,
    clock_pub,
    clock_hz: float | None,
    rate: float,
    delay: float,
    start_ns: int,
) -> int:
    """Publish ``stream`` on ``routes`` in recorded time; the count."""
    from builtin_interfaces.msg import Time
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock

    last_clock = -1

    def tick(bag_ns: int) -> None:
        nonlocal last_clock
        if clock_pub is not None and bag_ns > last_clock:
            clock_pub.publish(Clock(clock=Time(sec=bag_ns // 10**9, nanosec=bag_ns % 10**9)))
            last_clock = bag_ns

    period = 1.0 / clock_hz if clock_hz else None
    tick(start_ns)
    wall0 = time.monotonic() + delay
    while clock_pub is not None and time.monotonic() < wall0:  # the start time, during the delay
        time.sleep(min(period, max(wall0 - time.monotonic(), 0.0)))
        clock_pub.publish(Clock(clock=Time(sec=start_ns // 10**9, nanosec=start_ns % 10**9)))
    if clock_pub is None and delay:
        time.sleep(delay)
    count = 0
    for connection, time_ns, data in stream:
        due = wall0 + (time_ns - start_ns) * 1e-9 / rate
        while (wait := due - time.monotonic()) > 0:
            time.sleep(min(wait, period) if period else wait)
            if period:
                tick(min(time_ns, start_ns + int((time.monotonic() - wall0) * rate * 1e9)))
        tick(time_ns)
        routes[connection.id].publish(bytes(data))
        count += 1
    for pub in set(routes.values()):
        pub.wait_for_all_acked(Duration(seconds=_FLUSH_TIMEOUT))
    return count
