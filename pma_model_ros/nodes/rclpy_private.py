"""Every private rclpy name this package uses, in one place: Jazzy's rclpy (7.1) has no public
equivalent of any of them, and an rclpy update may rename each (test/test_nodes_rclpy_private.py
fails then).

* :data:`RCLError`: what rclpy raises from its C layer (``rclpy.init`` with a parameter file rcl
  cannot parse, a lifecycle transition the current state does not have, a context shut down
  under the executor); ``rclpy.exceptions`` does not export it.
* :func:`parameter_overrides`: what the node's parameter files and ``-p`` set, declared or not
  (``Node._parameter_overrides``, since Dashing).
* :func:`clock_handle`: the C clock behind an rclpy ``Clock`` (``Clock.handle``, "not to be used
  outside of rclpy"): ``handle.get_now().nanoseconds`` reads the time without building an rclpy
  ``Time`` (:meth:`.managed.ManagedNode.now`, on every input).
* :func:`with_message_info`: a subscription whose callback, with a second parameter of default
  None, gets the message info (reception time) as well (``Subscription._callback_type``: rclpy
  decides by whether the callback can be called with one argument); for the
  SingleThreadedExecutor only: this rclpy's EventsExecutor fails on it.
* :func:`take`: the next message waiting in a subscription's queue, with its info
  (``Subscription.handle.take_message``, what the executor calls): a node that fell behind takes
  what waits behind a stale input to answer the newest.
* :func:`lifecycle_state`: a lifecycle node's state and the transitions it has
  (``LifecycleNode._state_machine``; the public ``get_available_transitions`` is a service),
  to say why a ``change_state`` call is refused.
"""

from __future__ import annotations

from rclpy._rclpy_pybind11 import RCLError  # noqa: F401 (re-exported)
from rclpy.clock import Clock
from rclpy.lifecycle import LifecycleNode
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription


def parameter_overrides(node: Node) -> dict[str, Parameter]:
    """The parameters the node's files and ``-p`` set, by name, declared or not."""
    return node._parameter_overrides


def clock_handle(clock: Clock):
    """The C clock of ``clock``: ``.get_now().nanoseconds`` [ns]."""
    return clock.handle


def lifecycle_state(node: LifecycleNode) -> tuple[str, list[tuple[int, str]]]:
    """The label of ``node``'s current state and the (id, label) of each transition it has."""
    machine = node._state_machine
    return machine.current_state[1], [(t[0], t[1]) for t in machine.available_transitions]


def with_message_info(subscription: Subscription) -> Subscription:
    """``subscription``, its callback called with the message and its info
    (``info['received_timestamp']``: when DDS received it [ns, system clock]).
    """
    subscription._callback_type = Subscription.CallbackType.WithMessageInfo
    return subscription


def take(subscription: Subscription) -> tuple[object, dict] | None:
    """The next message waiting in ``subscription``'s queue (bytes for a raw one) and its info, or
    None when none waits.
    """
    with subscription.handle:
        return subscription.handle.take_message(subscription.msg_type, subscription.raw)
