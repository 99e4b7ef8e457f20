"""Start-up of the nodes: a bad parameter file or value ends the process with one clear line.

Every node spins on the executor named by its read-only ROS parameter ``executor``:
``single`` (rclpy's SingleThreadedExecutor, the default) or ``events``
(``rclpy.experimental.EventsExecutor``); docs/performance.md compares them.  Several nodes in one
process (``pma_composed``, :mod:`.composed`) share one executor: their ``executor`` parameters must
agree.
"""

from __future__ import annotations

from contextlib import contextmanager
import faulthandler
import gc
import re
import signal
import sys
import threading
from typing import Callable, Iterator, Sequence

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.logging import get_logger_level, LoggingSeverity, set_logger_level
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .parameters import check_given_types, declare
from .rclpy_private import RCLError
from ..core.files.node_parameters import SPECS
from ..core.files.param_file import check_params_file

#: [s] Longest wait of one spin; bounded because this rclpy build's EventsExecutor may never return
#: from ``spin()`` or an unbounded ``spin_once()`` (seen: busy-waiting, deaf to SIGINT and
#: SIGTERM).
SPIN_TIMEOUT = 0.5
#: [s] Longest wait for the node and DDS to shut down (:func:`teardown`); ros2 launch sends
#: SIGTERM 5 s after SIGINT.
TEARDOWN_TIMEOUT = 5.0
#: The executors of the ``executor`` parameter
#: (:data:`~pma_model_ros.core.files.node_parameters.EXECUTORS`).
EXECUTORS: dict[str, Callable[..., Executor]] = {
    'single': SingleThreadedExecutor,
    'events': EventsExecutor,
}


class StartupError(Exception):
    """A node that cannot start: logged as one line ``<what>: <message>``, then exit code 1.

    ``what`` is ``invalid parameters`` for a bad parameter, ``configure failed`` for an
    unexpected error in a managed node's configure (a bug, its traceback logged before).
    ``node`` is the half-built node (set by :func:`refusing`), which :func:`run` destroys after
    logging the line.
    """

    def __init__(
        self, message: str, node: Node | None = None, what: str = 'invalid parameters'
    ) -> None:
        super().__init__(message)
        self.node, self.what = node, what


def init(args: list[str] | None) -> None:
    """Initialise rclpy with ``args``; a params file rcl cannot parse raises StartupError.

    rcl's own "Failed to parse global arguments" line is muted during init so the
    caller's single line is the only one.  A muscle spec given as ``--params-file`` is named so
    before rcl reads it (:func:`~..core.files.param_file.check_params_file`).
    """
    given = sys.argv if args is None else args
    try:
        for option, path in zip(given, given[1:]):
            if option == '--params-file':
                check_params_file(path)
        check_given_types(given)
    except ValueError as err:
        raise StartupError(str(err)) from None
    level = get_logger_level('rcl')
    set_logger_level('rcl', LoggingSeverity.FATAL)
    try:
        # run() handles the signals
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as err:
        text = re.sub(r', at \S+:\d+', '', str(err)).removeprefix('failed to initialize rcl: ')
        raise StartupError(text) from None
    if get_logger_level('rcl') == LoggingSeverity.FATAL:  # not set by --log-level: restore
        set_logger_level('rcl', level)


@contextmanager
def refusing(node: Node) -> Iterator[None]:
    """Wrap the part of ``node.__init__`` that reads its parameters: a bad value raises
    :class:`StartupError` carrying the half-built ``node``, so that :func:`run` destroys it before
    the context (left to the garbage collector, it went after the context's shutdown).
    """
    try:
        yield
    except (ParameterException, ValueError) as err:
        raise StartupError(str(err), node) from None


def executor(nodes: Sequence[Node]) -> Executor:
    """The executor named by the ``executor`` parameter of ``nodes`` (declared here on each,
    read-only; they must name the same one).
    """
    spec = SPECS['executor']
    names = [declare(node, spec).value for node in nodes]
    try:
        for name in names:
            spec.check(name)
    except ValueError as err:
        raise StartupError(str(err)) from None
    if len(set(names)) > 1:
        raise StartupError(
            f"parameter 'executor': the nodes of one process share one executor, got "
            f'{", ".join(f"{n.get_name()}: {e}" for n, e in zip(nodes, names))}'
        )
    return EXECUTORS[names[0]](context=nodes[0].context)


def run(
    node_name: str,
    make_node: Callable[[], Node] | Sequence[Callable[[], Node]],
    args: list[str] | None,
) -> int:
    """Init, build the node (or each of a sequence of nodes, in order), spin until SIGINT, SIGTERM
    or shutdown; the exit code (1: bad parameters, logged as one FATAL line by ``node_name``'s
    logger).

    The Jazzy idiom, with one change: a signal stops the spin loop, and the executor and the nodes
    are shut down before the context.  With rclpy's own signal handler the context went first, and
    the EventsExecutor could still run a callback whose ``publish`` then failed
    (docs/reliability.md).
    """
    makers = [make_node] if callable(make_node) else list(make_node)
    nodes: list[Node] = []
    spinner = None
    stop = threading.Event()
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda *_: stop.set())
    try:
        try:
            init(args)
            for make in makers:
                nodes.append(make())
            spinner = executor(nodes)
        except (StartupError, ParameterException) as err:  # also use_sim_time, read by Node()
            what = getattr(err, 'what', 'invalid parameters')
            rclpy.logging.get_logger(node_name).fatal(f'{what}: {err}')
            if getattr(err, 'node', None) is not None:
                nodes.append(err.node)
            return 1
        for node in nodes:
            spinner.add_node(node)
        # start-up's objects (modules, the nodes, their models) to the permanent generation: a
        # full collection then scans only what came since (one of 90,000 objects took 19 ms, a
        # stall of 19 cycles at 1 kHz; docs/performance.md)
        gc.collect()
        gc.freeze()
        context = nodes[0].context
        while context.ok() and not stop.is_set():
            spinner.spin_once(timeout_sec=SPIN_TIMEOUT)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:  # a signal shut the context down while the executor built its wait set
        if nodes[0].context.ok():
            raise
    finally:
        teardown(spinner, *nodes)
    return 0


def teardown(spinner: Executor | None, *nodes: Node) -> None:
    """Shut down the executor, destroy the nodes, shut down the context; at most
    :data:`TEARDOWN_TIMEOUT`.

    Fast DDS 2.14 can deadlock in discovery, and destroying the participant then waits for it
    forever, holding the GIL: in 2 of 3,360 start-ups, 16 at once, the main thread spun
    in ``DomainParticipant::set_listener`` while an event thread waited for a lock in
    ``PDP::check_remote_participant_liveliness`` (eProsima/Fast-DDS#6502, #6513).
    faulthandler's watchdog thread needs no GIL: past the bound it prints every thread's stack and
    exits with code 1.
    """
    faulthandler.dump_traceback_later(TEARDOWN_TIMEOUT, exit=True)
    try:
        if spinner is not None:
            spinner.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    finally:
        faulthandler.cancel_dump_traceback_later()
