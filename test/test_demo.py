"""The live demo (demo.py): both nodes start, the estimates are compared, both stop cleanly."""

from pathlib import Path
import subprocess
import sys

import pytest

from conftest import REPO

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


@pytest.mark.parametrize(
    'config, message',
    [
        (
            'config/example_joint.yaml',
            "config/example_joint.yaml is a joint file ('joints:', for joint_node); the demo runs "
            'one muscle: --config config/dmsp_10_250.yaml or config/dmsp_20_300.yaml',
        ),
        (
            'config/example_multi_muscle.yaml',
            "config/example_multi_muscle.yaml has several muscles ('muscles:'); the demo runs one "
            'muscle: --config config/dmsp_10_250.yaml or config/dmsp_20_300.yaml',
        ),
        ('config/missing.yaml', 'parameter file not found: config/missing.yaml'),
        (
            'MODLE',
            "MODLE: unknown key 'modle' (did you mean 'model'?)",
        ),
        (
            'config/dmsp_10_100.yaml',
            'config/dmsp_10_100.yaml: muscle.name DMSP-10-100: the simulator needs a shipped '
            'force map (DMSP-10-250, DMSP-20-300)',
        ),
    ],
)
def test_a_config_the_demo_cannot_run_is_one_line_exit_2(
    capsys, monkeypatch, tmp_path, config, message
):
    """Refused before any node starts (no DDS): the file, the key or value, what to pass."""
    from pma_model_ros.demo import main

    monkeypatch.chdir(REPO)
    if config == 'MODLE':
        config = str(tmp_path / 'modle.yaml')
        text = (REPO / 'config' / 'dmsp_10_250.yaml').read_text()
        Path(config).write_text(text.replace('    model: martens', '    modle: martens'))
        message = message.replace('MODLE', config)
    assert main(['--config', config]) == 2
    assert capsys.readouterr().err == f'scripts/demo: error: {message}\n'
