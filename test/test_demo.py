"""The live demo (demo.py): both nodes start, the estimates are compared, both stop cleanly."""

from pathlib import Path
import subprocess
import sys

import pytest
from test_core_simulation_truth import sparse_table_a2, SPEC, write_map

from conftest import edited_copy, REPO

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


@pytest.mark.ros
def test_a_demo_of_a_muscle_without_a_shipped_map_plays_its_map(tmp_path):
    """--map and --spec: the simulator plays a user's map for a muscle the package ships no map
    of: config/dmsp_10_250.yaml's fit renamed MY-DMSP-10, its map Table A2 thinned to no
    pressure x length grid (what an isometric rig records).
    """
    rename = ('name: DMSP-10-250', 'name: MY-DMSP-10')
    config = edited_copy(REPO / 'config' / 'dmsp_10_250.yaml', tmp_path, *rename)
    (tmp_path / 'muscles').mkdir()
    spec = edited_copy(SPEC, tmp_path / 'muscles', *rename)
    data = write_map(tmp_path / 'my_map.csv', sparse_table_a2())
    run = subprocess.run(
        [*DEMO, '--duration', '3', '--config', config, '--map', data, '--spec', spec],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.startswith(
        f'pma_model_ros demo: simulated MY-DMSP-10 (truth = the measured map {data}) vs '
        # errors in % of the played map's max force: Table A2's 515.833 N at 619.688 kPa, 0.25 m
        "model_node (martens, identification err 4.20 % of its map's max force); errors in % of "
        "this map's max force (515.833 N), 3 s"
    ), run.stdout
    assert 'compared ' in run.stdout
    assert 'rejected: 0;' in run.stdout  # model_node found its joint in every muscle_state
    assert 'nodes stopped: simulator_node exit 0, model_node exit 0' in run.stdout


@pytest.mark.parametrize(
    'options, message',
    [
        (['--map', 'my_map.csv'], '--map and --spec go together'),
        (
            ['--map', 'missing.csv', '--spec', str(SPEC)],
            'scripts/demo: error: force map file not found: missing.csv\n',
        ),
        (
            ['--map', 'one.csv', '--spec', str(SPEC)],
            'scripts/demo: error: one.csv: the truth needs at least 2 measured lengths',
        ),
    ],
)
def test_a_map_the_demo_cannot_play_is_one_line_exit_2(
    capsys, monkeypatch, tmp_path, options, message
):
    """Refused before any node starts (no DDS), as a bad --config."""
    from pma_model_ros.demo import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / 'one.csv').write_text(
        'pressure_pa,length_m,force_n\n1e5,0.2,1\n2e5,0.2,2\n3e5,0.2,3\n'
    )
    try:
        code = main(options)
    except SystemExit as stop:  # argparse's error
        code = stop.code
    err = capsys.readouterr().err
    assert code == 2 and message in err, err
    assert err.splitlines()[-1].startswith('scripts/demo: error: '), err


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
            'force map (DMSP-10-250, DMSP-20-300) or its measured map: --map CSV --spec YAML',
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
