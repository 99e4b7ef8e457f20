"""simulator_node: bad parameters end it with one line; --record writes what it publishes, at
its rate, to a bag.
"""

import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import lines_of_failed_start
from pma_model_ros.nodes import simulator_node

pytestmark = pytest.mark.ros
NODE = [sys.executable, '-m', 'pma_model_ros.nodes.simulator_node']


def test_a_rate_out_of_range_is_one_line_naming_it():
    lines = lines_of_failed_start([*NODE, '--ros-args', '-p', 'rate:=5000.0'])
    assert len(lines) == 1 and 'rate' in lines[0], lines


def test_record_holds_three_topics_at_the_rate(tmp_path):
    rosbag2 = pytest.importorskip(
        'rosbags.rosbag2',
        reason='needs rosbags, a pip-only library: pip install -r requirements-dev.txt',
    )
    out = tmp_path / 'sim.mcap'
    proc = subprocess.Popen(
        [*NODE, '--record', str(out), '--ros-args', '-r', '__ns:=/sim', '-p', 'rate:=50.0'],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert 'recording to' in proc.stdout.readline()
        time.sleep(2.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(10) == 0
    finally:
        proc.kill()
        proc.wait()
    stamps = {}
    with rosbag2.Reader(out) as bag:
        for connection, timestamp, _ in bag.messages():
            stamps.setdefault(connection.topic, []).append(timestamp)
    assert set(stamps) == {'/sim/pressure', '/sim/muscle_state', '/sim/force'}
    step = np.median(np.diff(stamps['/sim/force']))
    assert step == pytest.approx(1e9 / 50, abs=2e6)  # 20 ms apart at 50 Hz, within 2 ms
    assert len(stamps['/sim/force']) >= 50  # 2 s at 50 Hz, less a start-up margin


def test_record_to_an_existing_path_is_one_line_exit_1(tmp_path, capsys):
    """Refused before any node starts, naming the option and the path (not 'invalid parameters',
    and no traceback); the existing file is left as it was.
    """
    existing = tmp_path / 'run1.mcap'
    existing.write_text('an earlier recording')
    assert simulator_node.main(['simulator_node', '--record', str(existing)]) == 1
    err = capsys.readouterr().err
    assert err == (
        f'simulator_node: error: --record {existing}: exists; not overwriting it (remove it or '
        'record to another name)\n'
    )
    assert existing.read_text() == 'an earlier recording'
