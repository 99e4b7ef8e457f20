"""Faults around model_node: its input source stops and comes back; the nodes get SIGINT or
SIGTERM.

rclpy (Jazzy) installs handlers for both signals at init (``SignalHandlerOptions.ALL``): they shut
the context down, ``spin`` returns through ExternalShutdownException (SIGTERM) or KeyboardInterrupt
(SIGINT), and ``startup.run`` exits 0.
"""

import signal
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import pytest
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS
from node_messages import (
    AMBIENT,
    model_statuses,
    pressure,
    RELIABLE_QOS,
    SENSOR_QOS,
    stamp_key,
    state,
    status_values,
)
from pma_model_ros.tools import node_process

pytestmark = pytest.mark.ros

#: A simulator at a fixed point inside the validity domain, so that model_node is OK while it runs.
STEADY = {'trajectory': 'constant', 'length': 0.23, 'initial_pressure': 300e3}
LEVELS = {b'\x00': 'OK', b'\x01': 'WARN', b'\x02': 'ERROR'}


def test_source_stops_and_returns_without_restarting_model_node(ros, processes, namespace):
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'])
    sim = processes.node('simulator_node', namespace, **STEADY)
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    why = lambda: processes.output(node) + processes.output(sim)  # noqa: E731

    def reaches(level: str, words: str, since: int) -> int:
        """Spin until model_node reports ``level`` with ``words`` after status ``since``; that
        status's index.
        """

        def found():
            return next(
                (
                    i
                    for i, s in enumerate(model_statuses(diagnostics, namespace))
                    if i >= since and LEVELS[s.level] == level and words in s.message
                ),
                None,
            )

        ros.spin_until(
            lambda: found() is not None, 20, f'model_node {level} "{words}"', diagnose=why
        )
        return found()

    ok = reaches('OK', 'estimating', 0)
    assert node_process.stop(sim) == 0, processes.output(sim)
    stopped = ros.now().nanoseconds
    stale = reaches('ERROR', 'stale', ok + 1)
    sim = processes.node('simulator_node', namespace, **STEADY)
    reaches('OK', 'estimating', stale + 1)
    ros.spin_until(
        lambda: stamp_key(estimates[-1]) > stopped,
        20,
        'estimates from the new simulator',
        diagnose=why,
    )
    assert node.poll() is None, why()


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_ends_both_nodes_cleanly_under_load(sig, ros, processes, namespace):
    nodes = [
        processes.node('simulator_node', namespace, rate=500.0),
        processes.node('model_node', namespace, CONFIGS['DMSP-10-250']),
    ]
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    why = lambda: ''.join(processes.output(p) for p in nodes)  # noqa: E731
    ros.spin_until(lambda: len(estimates) > 100, 30, 'estimates flowing', diagnose=why)
    for proc in nodes:
        proc.send_signal(sig)
    for proc in nodes:
        assert proc.wait(10) == 0, why()
    assert 'Traceback' not in why() and 'Error' not in why(), why()


def test_a_stalled_node_skips_what_waited_and_answers_fresh_inputs(ros, processes, namespace):
    """model_node's process stopped for 0.3 s (SIGSTOP) while inputs keep coming: when it runs
    again, what was sent more than 10 ms before the SIGCONT (longer than max_queue_delay, 5 ms,
    plus the wire) is skipped, counted in /diagnostics (``skipped behind``), and the inputs sent
    after it are answered.
    """
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'])
    why = lambda: processes.output(node)  # noqa: E731
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    pressures = ros.node.create_publisher(FluidPressure, f'{namespace}/pressure', SENSOR_QOS)
    states = ros.node.create_publisher(JointState, f'{namespace}/muscle_state', SENSOR_QOS)
    sent: list[tuple[int, int]] = []  # (stamp [ns], system time after both publishes [ns])

    def publish() -> None:
        stamp = ros.now()
        pressures.publish(pressure(stamp.to_msg(), AMBIENT + 300e3))
        states.publish(state(stamp.to_msg(), 0.23, 0.0))
        sent.append((stamp.nanoseconds, time.time_ns()))

    ros.spin_until(lambda: estimates, 20, 'a first estimate', every=publish, period=0.005)
    node.send_signal(signal.SIGSTOP)
    stopped = time.monotonic()
    try:
        ros.spin_until(
            lambda: time.monotonic() - stopped > 0.3, 5, 'the stall', every=publish, period=0.005
        )
    finally:
        resumed, last = time.time_ns(), sent[-1][0]
        node.send_signal(signal.SIGCONT)
    ros.spin_until(
        lambda: estimates and stamp_key(estimates[-1]) > last,
        20,
        'an estimate of an input sent after the stall',
        every=publish,
        period=0.005,
        diagnose=why,
    )
    waited = {stamp for stamp, after in sent if resumed - after > 10_000_000}
    answered = {stamp_key(e) for e in estimates}
    stall = {stamp for stamp in waited if stamp > stamp_key(estimates[0])}
    assert stall, 'no input was sent during the stall'
    assert not answered & stall, f'{len(answered & stall)} of {len(stall)} waited inputs answered'

    def skipped() -> int:
        statuses = model_statuses(diagnostics, namespace)
        return int(status_values(statuses[-1]).get('skipped behind', 0)) if statuses else 0

    ros.spin_until(lambda: skipped() > 0, 10, 'a report of what was skipped', diagnose=why)
