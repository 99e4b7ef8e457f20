"""Faults around model_node: its input source stops and comes back; the nodes get SIGINT or
SIGTERM.

rclpy (Jazzy) installs handlers for both signals at init (``SignalHandlerOptions.ALL``): they shut
the context down, ``spin`` returns through ExternalShutdownException (SIGTERM) or KeyboardInterrupt
(SIGINT), and ``startup.run`` exits 0.
"""

import signal

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import pytest

from conftest import CONFIGS
from node_messages import model_statuses, RELIABLE_QOS, stamp_key
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
