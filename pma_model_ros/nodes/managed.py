"""The managed (lifecycle) shell of model_node and joint_node.

States and transitions are ROS 2's (``rclpy.lifecycle``), driven through the standard
``lifecycle_msgs`` services ``<node>/change_state``, ``<node>/get_state``, ... (``ros2 lifecycle
set <node> configure``):

* ``configure``: the node reads and checks its parameters, builds its engine, and creates its
  publishers, subscriptions and status timer (:meth:`ManagedNode.configure`).  A bad parameter
  fails the transition (FAILURE), logged as one line ``invalid parameters: <reason>``, and leaves
  the node unconfigured with nothing of it built.
* ``activate``: inputs are answered with estimates, commands with pressure commands, and
  ``/diagnostics`` is published.
* ``deactivate``: no output any more.  Every input callback starts with the gate
  ``if not self.active: return`` (one attribute check): a message that arrives while inactive is
  dropped unread, so neither an estimate nor a pressure command nor a change of the command
  settings comes of it, and the status timer publishes nothing.  The engine is then rebuilt fresh
  (:meth:`ManagedNode.reset`): the next activation starts as after configure (no input known,
  hysteresis branches unknown, counters at zero), since the node cannot know what happened while
  it did not listen.
* ``cleanup`` (back to unconfigured) and ``shutdown`` (finalized, from any state) destroy what
  configure created and drop the engine.  The parameters stay declared, as in any ROS node: a
  configure after a cleanup reads their current values.

``autostart`` (read-only, default true): the constructor configures and activates the node, so
``ros2 run`` behaves as before the nodes were managed; a configure failure then raises
:class:`~.startup.StartupError`, which :func:`~.startup.run` logs as one FATAL line before exit
code 1.  ``false``: the node waits unconfigured for a lifecycle manager.
"""

from __future__ import annotations

from functools import partial
import traceback

from lifecycle_msgs.srv import ChangeState
from rclpy.exceptions import ParameterException
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from .diagnostics import diagnostic_array
from .parameters import declare
from .rclpy_private import clock_handle, lifecycle_state, RCLError
from .startup import refusing, StartupError
from ..core.files.node_parameters import SPECS
from ..core.runtime.health import DIAGNOSTIC_PERIOD, FaultLog, Level

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class ManagedNode(LifecycleNode):
    """A lifecycle node whose subclass builds itself in :meth:`configure` and answers inputs only
    while :attr:`active`.

    A subclass sets its own attributes before calling this constructor (with ``autostart`` it
    configures the node), and provides :meth:`configure`, :meth:`reset`, :meth:`release` and
    :meth:`publish_status`; its engine has ``status_due(now)``.
    """

    def __init__(self, node_name: str, **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        service = next(s for s in self.services if s.srv_type is ChangeState)
        service.callback = partial(_refuse_unknown_transitions, self, service.callback)
        self.active = False  #: the gate of every input callback
        #: the node's fully qualified name: default hardware_id prefix of its statuses
        self.instance = self.get_fully_qualified_name()
        self.refusal = ''  #: why the last configure failed
        self._ros_clock = clock_handle(self.get_clock())  # see now()
        self._built: list = []  # the publishers, subscriptions and timer of configure
        self._faults = FaultLog()  # what publish_entries logs
        self._starting = False
        with refusing(self):
            self.autostart = declare(self, SPECS['autostart']).value
            #: its executor hands subscriptions each message's reception time (``single``)
            self.reception_times = declare(self, SPECS['executor']).value == 'single'
        try:  # so that they can be listed and set while unconfigured
            self.declare_all()
        except (ParameterException, ValueError):
            pass  # configure declares them again, and fails with the reason
        if self.autostart:
            self._starting = True
            try:
                if (result := self.trigger_configure()) != SUCCESS:
                    what = 'invalid parameters' if result == FAILURE else 'configure failed'
                    raise StartupError(self.refusal, self, what)
            finally:
                self._starting = False
            self.trigger_activate()

    # --- what a node provides
    def declare_all(self) -> None:
        """Declare every parameter of the node (again: those not declared yet); rclpy parameter
        exceptions or ValueError for a bad override.
        """
        raise NotImplementedError

    def status_names(self) -> list[tuple[str, str]]:
        """(name, hardware_id) of each status :meth:`publish_status` publishes."""
        raise NotImplementedError

    def configure(self) -> None:
        """Read and check the parameters, build the engine, create publishers and subscriptions;
        ValueError or an rclpy ParameterException for a bad parameter.
        """
        raise NotImplementedError

    def reset(self) -> None:
        """Replace the engine by a fresh one of the same settings."""
        raise NotImplementedError

    def release(self) -> None:
        """Drop what :meth:`configure` built besides its ROS entities (the engine)."""
        raise NotImplementedError

    def publish_status(self, now: int) -> None:
        """Publish every status of the engine on /diagnostics."""
        raise NotImplementedError

    # --- shared by the nodes
    def publish_entries(self, entries: list[tuple], now: int) -> None:
        """Publish the statuses ``entries`` (name, hardware_id, level, message, values) on
        /diagnostics, and log their faults: one WARN line per cause at most every second
        (:class:`~pma_model_ros.core.runtime.health.FaultLog`).
        """
        self._diag_pub.publish(diagnostic_array(self, entries))
        for _, line in self._faults.lines([(e[0], e[2], e[3]) for e in entries], now):
            self.get_logger().warning(line)

    def now(self) -> int:
        """The node clock (ROS time; sim time with use_sim_time) [ns], read without building an
        rclpy Time.
        """
        return self._ros_clock.get_now().nanoseconds

    def report(self, now: int) -> None:
        """After an input: publish the statuses if a level changed (:meth:`Health.due`)."""
        if self.engine.status_due(now):
            self.publish_status(now)

    def _on_timer(self) -> None:
        """Every :data:`DIAGNOSTIC_PERIOD`: the statuses while active; while inactive, each status
        at level OK with the message ``inactive`` (an aggregator sees the node alive, not stale).
        """
        if self.active:
            self.publish_status(self.now())
        else:
            entries = [(name, hw, Level.OK, 'inactive', {}) for name, hw in self.status_names()]
            self._diag_pub.publish(diagnostic_array(self, entries))

    # --- transitions
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        before = {id(e) for e in self._entities()}
        self.refusal = ''
        try:
            self.configure()
            self.create_timer(DIAGNOSTIC_PERIOD, self._on_timer)
        except (ParameterException, ValueError) as err:
            self.refusal = str(err)
        except Exception as err:  # a bug: rclpy would swallow it (ERROR, then on_error)
            self.refusal = f'configure raised {type(err).__name__}: {err} (traceback logged)'
            self.get_logger().error(f'configure raised:\n{traceback.format_exc()}')
            raise
        finally:
            self._built = [e for e in self._entities() if id(e) not in before]
        if not self.refusal:
            return SUCCESS
        self._release()
        if not self._starting:  # at start-up, run() logs it, as FATAL
            self.get_logger().error(f'invalid parameters: {self.refusal}')
        return FAILURE

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = True
        return SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self.reset()
        return SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._release()
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self._release()
        return SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """After an exception in a transition (ERROR): release everything, back to unconfigured."""
        self.active = False
        self._release()
        return SUCCESS

    def _entities(self) -> list:
        return [*self.publishers, *self.subscriptions, *self.timers]

    def _release(self) -> None:
        destroy = {
            Publisher: self.destroy_publisher,
            Subscription: self.destroy_subscription,
            Timer: self.destroy_timer,
        }
        for entity in self._built:
            destroy[next(t for t in destroy if isinstance(entity, t))](entity)
        self._built = []
        self.release()


def _refuse_unknown_transitions(
    node: ManagedNode,
    change_state,
    request: ChangeState.Request,
    response: ChangeState.Response,
) -> ChangeState.Response:
    """Rclpy's ``change_state`` service callback, answering ``success: false`` to a transition the
    current state does not have (e.g. ``activate`` while unconfigured), as rclcpp does: rclpy
    raises RCLError there, out of the executor, which ended the node's process.  Such a refusal
    is logged as one WARN line with the state and the transitions it has (a manager's caller
    sees only ``false``).
    """
    state, transitions = lifecycle_state(node)
    try:
        response = change_state(request, response)
    except RCLError:
        response.success = False
    asked = request.transition.label or request.transition.id
    if not response.success and all(asked not in t for t in transitions):
        node.get_logger().warning(refused_transition(asked, state, transitions, node.autostart))
    return response


def refused_transition(
    asked: str | int, state: str, transitions: list[tuple[int, str]], autostart: bool
) -> str:
    """Why ``change_state`` refused the transition ``asked`` (a label or an id) in ``state``."""
    text = (
        f'change_state {asked!r} refused: the node is {state}, whose transitions are '
        + ', '.join(f'{label} ({id_})' for id_, label in transitions)
    )
    if autostart and asked in ('configure', 1):
        text += (
            '; autostart is true, so the node configured and activated itself at start-up: '
            'under a lifecycle manager start it with autostart: false (docs/nodes.md)'
        )
    return text
