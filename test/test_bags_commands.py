"""The pma-model bag subcommands' arguments (cli/bags.py).

What a user mistypes gets one line and exit code 2.
"""

import subprocess
import sys

import pytest

from conftest import CONFIGS, REPO
from pma_model_ros.cli.main import main

SPEC = REPO / 'pma_model_ros/core/data/dmsp_10_250.yaml'


@pytest.mark.parametrize(
    'argv, words',
    [
        (
            ['bag', 'estimate', '/no/such/bag', '--out', '/tmp/x'],
            'the following arguments are required: --config',
        ),
        (
            [
                'bag',
                'estimate',
                '/no/such/bag',
                '--config',
                str(CONFIGS['DMSP-10-250']),
                '--out',
                '/tmp/x',
                '--pressure-reference',
                'psi',
            ],
            "invalid choice: 'psi'",
        ),
        (['bag', 'play', '/no/such/bag', '--remap', 'a'], 'expected FROM:=TO'),
        (['bag', 'play', '/no/such/bag', '--rate', '0'], '--rate and --clock must be > 0'),
    ],
)
def test_bad_arguments_one_line_exit_2(capsys, argv, words):
    try:
        code = main(argv)
    except SystemExit as stop:  # argparse's own refusals
        code = stop.code
    err = capsys.readouterr().err  # argparse prints its usage above the last line
    assert code == 2 and words in err.strip().splitlines()[-1], err


def test_missing_bag_is_one_line_exit_2(capsys, tmp_path):
    code = main(
        [
            'bag',
            'estimate',
            str(tmp_path / 'none'),
            '--config',
            str(CONFIGS['DMSP-10-250']),
            '--out',
            str(tmp_path / 'out'),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1 and not (tmp_path / 'out').exists()


def test_estimate_replaces_an_existing_output_only_with_force(tmp_path):
    """In a process of its own: estimate_bag's progress bar holds the sys.stderr of its import."""
    pytest.importorskip(
        'rosbags', reason='needs rosbags, a pip-only library: pip install -r requirements-dev.txt'
    )
    from pma_model_ros.bags.bag_io import read
    from pma_model_ros.bags.synthetic import record_simulation

    bag = record_simulation(tmp_path / 'run', 1.0, '/m1', rate=50.0)
    out = tmp_path / 'est.mcap'
    out.write_text('an older result')
    argv = [sys.executable, '-m', 'pma_model_ros.cli', 'bag', 'estimate', str(bag)]
    argv += ['--config', str(CONFIGS['DMSP-10-250']), '--out', str(out)]
    refused = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2 and refused.stderr == (
        f'pma-model: error: --out: {out} exists; not overwriting it (--overwrite overwrites)\n'
    )
    assert subprocess.run([*argv, '--overwrite'], timeout=60).returncode == 0
    assert (
        sum(1 for topic, *_ in read(out) if topic == '/m1/force_estimate') == 99
    )  # 2 x 50 inputs, the first unpaired
    assert sorted(p.name for p in tmp_path.iterdir()) == ['est.mcap', 'run']


@pytest.mark.parametrize(
    'argv',
    [
        ['bag', 'estimate', 'run1', '--config', str(CONFIGS['DMSP-10-250']), '--out', 'out'],
        ['bag', 'play', 'run1'],
        ['fit', '--bag', 'run1', '--muscle', str(SPEC), '--model', 'martens', '--out', 'p.yaml'],
    ],
)
def test_without_rosbags_a_bag_command_is_one_line_exit_2(capsys, monkeypatch, tmp_path, argv):
    """Rosbags is pip-only (a -pip rosdep key): a ROS install may lack it."""
    monkeypatch.setitem(sys.modules, 'rosbags', None)  # import rosbags: ImportError
    monkeypatch.chdir(tmp_path)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1 and 'pip install rosbags' in err, err
    assert not list(tmp_path.iterdir())
