"""Start-up of the nodes (nodes/startup.py): one clear line and exit 1 for bad parameters; either
executor spins until SIGINT and exits 0.
"""

import signal
import subprocess
import sys
import time

import pytest
import rclpy

from conftest import lines_of_failed_start, REPO

pytestmark = pytest.mark.ros
CONFIG = REPO / 'config' / 'dmsp_10_250.yaml'


def model_node(*ros_args: str) -> list[str]:
    return [sys.executable, '-m', 'pma_model_ros.nodes.model_node', '--ros-args', *ros_args]


def test_a_params_file_rcl_cannot_parse_is_one_line(tmp_path):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('/**:\n  ros__parameters: [\n', encoding='utf-8')
    lines = lines_of_failed_start(model_node('--params-file', str(broken)))
    assert len(lines) == 1 and 'invalid parameters' in lines[0], lines


def test_a_muscle_spec_as_params_file_is_named_so():
    """Named before rcl reads it: rcl says only 'Cannot have a value before ros__parameters'."""
    spec = REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml'
    lines = lines_of_failed_start(model_node('--params-file', str(spec)))
    assert len(lines) == 1 and lines[0].endswith(
        f"invalid parameters: {spec} is a muscle spec, not a ROS parameter file ('<node>: "
        f"ros__parameters:'); make one with pma-model fit --muscle {spec}"
    ), lines


def test_an_unknown_executor_is_one_line_naming_it():
    lines = lines_of_failed_start(
        model_node('--params-file', str(CONFIG), '-p', 'executor:=threads')
    )
    # The node is built (its INFO line) before the executor is chosen: then one FATAL line.
    errors = [line for line in lines if 'FATAL' in line]
    assert errors == lines[-1:] and "unknown executor 'threads'" in errors[0], lines


@pytest.mark.parametrize('executor', ['single', 'events'])
def test_each_executor_stops_on_sigint_with_exit_0(executor):
    cmd = model_node('--params-file', str(CONFIG), '-p', f'executor:={executor}')
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert 'DMSP-10-250 with model martens' in proc.stdout.readline()  # built: spinning next
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
    finally:
        proc.kill()
        proc.wait()


def test_a_refused_parameter_hands_the_half_built_node_to_run(ros):
    """run() logs the line first, then destroys the node before the context."""
    from pma_model_ros.nodes.startup import refusing, StartupError

    half_built = rclpy.create_node('half_built', context=ros.node.context)
    with pytest.raises(StartupError, match='^bad value$') as refused:
        with refusing(half_built):
            raise ValueError('bad value')
    assert refused.value.node is half_built
    half_built.destroy_node()


def test_a_teardown_stuck_in_c_holding_the_gil_still_exits_with_code_1():
    """A node whose destruction never returns and holds the GIL (as Fast DDS's deadlock does):
    the process prints the stacks and exits 1 about TEARDOWN_TIMEOUT later.
    """
    script = (
        'import ctypes\n'
        'from pma_model_ros.nodes import startup\n'
        'startup.TEARDOWN_TIMEOUT = 1.0\n'
        'class Stuck:\n'
        '    def destroy_node(self):\n'
        '        ctypes.PyDLL(None).sleep(60)  # libc sleep(3) without releasing the GIL\n'
        'startup.teardown(None, Stuck())\n'
    )
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=30, cwd=REPO
    )
    assert run.returncode == 1 and 'Timeout (0:00:01)!' in run.stderr, run.stderr
    assert time.monotonic() - start < 20
