"""simulator_node: bad parameters end it with one line; --record writes what it publishes, at
its rate, to a bag; a user's map CSV with its spec is the truth of what it publishes.
"""

import signal
import subprocess
import sys
import time

from geometry_msgs.msg import WrenchStamped
import numpy as np
import pytest
from sensor_msgs.msg import FluidPressure, JointState
from test_core_simulation_truth import sparse_table_a2, SPEC, write_map

from conftest import lines_of_failed_start
from node_messages import AMBIENT, SENSOR_QOS, stamp_key
from pma_model_ros.core.simulation.truth import GroundTruth
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


def test_a_map_file_that_cannot_be_a_truth_is_one_fatal_line(tmp_path):
    lines = lines_of_failed_start(
        [*NODE, '--ros-args', '-p', f'map_file:={tmp_path / "no.csv"}', '-p', f'spec_file:={SPEC}']
    )
    missing = tmp_path / 'no.csv'
    assert len(lines) == 1 and 'FATAL' in lines[0], lines
    assert lines[0].endswith(
        f"invalid parameters: parameter 'map_file': force map file not found: {missing}"
    )


def test_a_user_map_without_a_full_grid_is_what_it_publishes(ros, processes, namespace, tmp_path):
    """simulator_node on a map CSV (Table A2 thinned to no pressure x length grid) and its spec:
    each published force (force and muscle_state's effort, noise 0) is the core's truth of that map
    at the pressure and length published with the same stamp, to float rounding.
    """
    fmap = sparse_table_a2()
    truth = GroundTruth(fmap)
    sim = processes.node(
        'simulator_node',
        namespace,
        map_file=write_map(tmp_path / 'sparse.csv', fmap),
        spec_file=SPEC,
        trajectory='sweep',
        period=0.5,
        sweep_period=1.0,
        rate=200.0,
    )
    forces = ros.collect(WrenchStamped, f'{namespace}/force', SENSOR_QOS)
    states = ros.collect(JointState, f'{namespace}/muscle_state', SENSOR_QOS)
    pressures = ros.collect(FluidPressure, f'{namespace}/pressure', SENSOR_QOS)

    def rows() -> np.ndarray:
        """(gauge [Pa], length [m], force [N], effort [N]) of the stamps all three carry."""
        state = {stamp_key(m): m for m in states}
        gauge = {stamp_key(m): m.fluid_pressure - AMBIENT for m in pressures}
        return np.array(
            [
                (gauge[k], state[k].position[0], f.wrench.force.x, state[k].effort[0])
                for f in forces
                if (k := stamp_key(f)) in state and k in gauge
            ]
        ).reshape(-1, 4)

    ros.spin_until(
        lambda: len(rows()) >= 200 and np.ptp(rows()[:, 2]) > 0.5 * fmap.max_force,
        30,
        '200 samples over half the map',
        diagnose=lambda: processes.output(sim),
    )
    assert states[0].name == ['DMSP-10-250']  # the spec's muscle
    p, L, force, effort = rows().T
    np.testing.assert_array_equal(force, effort)
    np.testing.assert_allclose(force, truth.force(p, L), rtol=0, atol=1e-6)
    assert L.min() >= fmap.lengths.min() and L.max() <= fmap.lengths.max()
