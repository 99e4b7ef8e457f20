"""Node processes for the demo, tests and benchmarks (tools/node_process.py)."""

import signal
import sys
import time

import pytest

from pma_model_ros.tools import node_process


def test_command_line_of_a_node():
    cmd = node_process.command('model_node', '/m1', 'a.yaml', {'model': 'martens'})
    assert cmd == [
        sys.executable,
        '-m',
        'pma_model_ros.nodes.model_node',
        '--ros-args',
        '-r',
        '__ns:=/m1',
        '--params-file',
        'a.yaml',
        '-p',
        'model:=martens',
    ]
    with pytest.raises(ValueError, match="unknown node 'modelnode'"):
        node_process.command('modelnode', '/m1')


def test_stop_sends_sigint_then_kills(tmp_path):
    with open(tmp_path / 'log', 'w') as log:
        ready = 'import signal, sys, time; {} print("up", flush=True); time.sleep(30)'
        # a node handles SIGINT whatever it inherited (rclpy.init installs its handler); a bare
        # Python inherits SIG_IGN when the suite runs as a background job of a script
        handle = 'signal.signal(signal.SIGINT, signal.{});'
        polite = node_process.start(
            [sys.executable, '-c', ready.format(handle.format('default_int_handler'))], log
        )
        deaf = node_process.start(
            [sys.executable, '-c', ready.format(handle.format('SIG_IGN'))], log
        )
        deadline = time.monotonic() + 10
        while (tmp_path / 'log').read_text().count('up') < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert node_process.stop(polite) == -signal.SIGINT  # KeyboardInterrupt ends by SIGINT
        assert node_process.stop(deaf, timeout=0.5) == -signal.SIGKILL
