"""The live demo (demo.py): both nodes start, the estimates are compared, both stop cleanly."""

import subprocess
import sys

import pytest

DEMO = [sys.executable, '-m', 'pma_model_ros.demo']


@pytest.mark.ros
def test_a_short_demo_compares_and_stops_both_nodes():
    run = subprocess.run(
        [*DEMO, '--duration', '3'], capture_output=True, text=True, timeout=60, check=False
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert 'compared ' in run.stdout
    assert 'model_node (its last /diagnostics report) in: ' in run.stdout  # its statuses found
    assert 'nodes stopped: simulator_node exit 0, model_node exit 0' in run.stdout


def test_a_duration_must_be_positive():
    run = subprocess.run([*DEMO, '--duration', '0'], capture_output=True, text=True, check=False)
    assert run.returncode == 2 and '--duration must be > 0' in run.stderr
