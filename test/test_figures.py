"""Figures: every plot function runs headless and writes PNG and SVG; the bag loader; `pma-model
plot` errors.
"""

import struct
import subprocess
import sys
import xml.etree.ElementTree as ET

import matplotlib
import numpy as np
import pytest

try:
    import rosbags  # noqa: F401
except ImportError:  # pip-only (a -pip rosdep key): colcon test on a ROS install without it
    pytest.skip(
        'needs rosbags, a pip-only library: pip install -r requirements-dev.txt',
        allow_module_level=True,
    )

from conftest import CONFIGS
from pma_model_ros import figures
from pma_model_ros.bags.bag_io import BagError
from pma_model_ros.bags.estimate import estimate_bag
from pma_model_ros.bags.synthetic import record_simulation
from pma_model_ros.cli.main import main
from pma_model_ros.core.files.param_file import muscle_model, node_settings, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map

TABLE = {
    'DMSP-10-250': {
        'default': 'martens',
        'mckibben': {'paper': 46.1, 'paper_protocol': 46.1, 'best': 46.1, 'cv': 46.1},
        'martens': {'paper': 4.4, 'paper_protocol': 4.42, 'best': 4.2, 'cv': 8.23},
    }
}


def png_size(path):
    """(width, height) [px] from the PNG's IHDR chunk."""
    data = path.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n'
    return struct.unpack('>II', data[16:24])


def assert_written(paths, stem):
    assert [p.name for p in paths] == [f'{stem}.png', f'{stem}.svg']
    width, height = png_size(paths[0])
    assert width == round(figures.WIDTH * figures.DPI)  # the README's width
    assert 300 < height < width  # landscape
    assert ET.parse(paths[1]).getroot().tag == '{http://www.w3.org/2000/svg}svg'


@pytest.fixture(scope='module')
def estimated_bag(tmp_path_factory):
    """3 s of the simulated DMSP-10-250 sweep with the shipped model's estimates beside the
    measured force.
    """
    tmp = tmp_path_factory.mktemp('bags')
    record_simulation(
        tmp / 'sim',
        3.0,
        namespace='/m1',
        period=1.0,
        sweep_period=3.0,
        noise__force_std=0.5,
        seed=1,
    )
    estimate_bag(
        tmp / 'sim',
        node_settings(read_parameters(CONFIGS['DMSP-10-250'])),
        tmp / 'est',
        progress=False,
    )
    return tmp


@pytest.mark.parametrize('draw', [figures.force_map_figure, figures.error_map_figure])
@pytest.mark.parametrize('muscle', ['DMSP-10-250', 'DMSP-20-300'])
def test_map_figures(tmp_path, draw, muscle):
    model = muscle_model(read_parameters(CONFIGS[muscle]))
    assert_written(figures.save(draw(shipped_force_map(muscle), model), tmp_path, 'map'), 'map')


def test_error_map_needs_a_full_grid(martens_10_250):
    fmap = shipped_force_map('DMSP-10-250')
    with pytest.raises(ValueError, match='full grid'):
        figures.error_map_figure(fmap.subset(np.arange(fmap.force.size) != 7), martens_10_250)


def test_models_figure(tmp_path):
    assert_written(figures.save(figures.models_figure(TABLE), tmp_path, 'models'), 'models')


def test_save_is_reproducible_and_leaves_no_global_state(tmp_path, martens_10_250):
    """Same figure, same bytes (no date, fixed SVG ids); rcParams untouched; pyplot never
    imported.
    """

    def rc():  # reading rcParams["backend"] would resolve the backend through pyplot
        return {key: matplotlib.rcParams[key] for key in matplotlib.rcParams if key != 'backend'}

    before = rc()
    fmap = shipped_force_map('DMSP-10-250')
    first = figures.save(figures.error_map_figure(fmap, martens_10_250), tmp_path / 'a', 'e')
    second = figures.save(figures.error_map_figure(fmap, martens_10_250), tmp_path / 'b', 'e')
    assert [p.read_bytes() for p in first] == [p.read_bytes() for p in second]
    assert 'matplotlib.pyplot' not in sys.modules
    assert rc() == before


def test_force_series_from_an_estimated_bag(estimated_bag, tmp_path):
    time, measured, estimated = figures.read_force_series(estimated_bag / 'est')
    assert time.size == 300 and np.allclose(np.diff(time), 0.01)  # 100 Hz, every stamp paired once
    # The shipped Martens model is within 7.87 % of max force of the map's pchip; plus 0.5 N force
    # noise.
    assert (
        np.abs(estimated - measured).max()
        < 0.0787 * shipped_force_map('DMSP-10-250').max_force + 3
    )
    assert measured.max() > 100 and estimated.min() >= 0
    assert_written(
        figures.save(figures.timeseries_figure(time, measured, estimated, 't'), tmp_path, 'ts'),
        'ts',
    )


def test_force_series_needs_estimates(estimated_bag):
    with pytest.raises(BagError, match='pma-model bag estimate'):
        figures.read_force_series(estimated_bag / 'sim')


def test_plot_cli_writes_the_files(tmp_path, capsys, estimated_bag):
    for args, stem in (
        (
            ['force-map', '--config', str(CONFIGS['DMSP-20-300']), '--model', 'hildebrandt'],
            'force_map_dmsp_20_300_hildebrandt',
        ),
        (['timeseries', '--bag', str(estimated_bag / 'est')], 'timeseries_est'),
    ):
        assert main(['plot', *args, '--out-dir', str(tmp_path)]) == 0
        assert capsys.readouterr().out.split() == [
            'wrote',
            str(tmp_path / f'{stem}.png'),
            'wrote',
            str(tmp_path / f'{stem}.svg'),
        ]


def test_plot_all_makes_what_its_inputs_allow(tmp_path, capsys, monkeypatch):
    """Without --bag: both map figures per config and the model comparison (its identification
    stubbed: Table 3 itself is tested in test_cli).
    """
    monkeypatch.setattr('pma_model_ros.cli.identify.identify_muscle', lambda muscle: None)
    monkeypatch.setattr('pma_model_ros.cli.plot.table3', lambda results: {'table3': TABLE})
    assert (
        main(
            [
                'plot',
                'all',
                '--config',
                str(CONFIGS['DMSP-10-250']),
                '--out-dir',
                str(tmp_path),
                '--format',
                'svg',
            ]
        )
        == 0
    )
    assert capsys.readouterr().out.splitlines()[0] == 'skipped timeseries: no --bag'
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'error_map_dmsp_10_250_martens.svg',
        'force_map_dmsp_10_250_martens.svg',
        'models.svg',
    ]


@pytest.mark.parametrize(
    'args, message',
    [
        (['timeseries', '--bag', '/no/such/bag'], 'bag not found'),
        (['timeseries', '--bag', 'BAG/sim'], 'pma-model bag estimate'),
        (['timeseries'], 'needs --bag'),
        (
            ['error-map', '--config', str(CONFIGS['DMSP-10-100'])],
            "no shipped force map for 'DMSP-10-100'",
        ),
        (
            ['force-map', '--config', str(CONFIGS['DMSP-10-250']), '--model', 'hill'],
            'unknown model',
        ),
    ],
)
def test_plot_cli_errors_are_one_line_exit_2(tmp_path, estimated_bag, args, message):
    args = [a.replace('BAG', str(estimated_bag)) for a in args]
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'pma_model_ros.cli',
            'plot',
            *args,
            '--out-dir',
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr and proc.stderr.count('\n') == 1
    assert not list(tmp_path.iterdir())


def test_plot_joint_writes_the_joint_figure(tmp_path, capsys):
    joint_file = str(CONFIGS['DMSP-10-250'].parent / 'example_joint.yaml')
    assert main(['plot', 'joint', '--config', joint_file, '--out-dir', str(tmp_path)]) == 0
    assert capsys.readouterr().out.split() == [
        'wrote',
        str(tmp_path / 'joint_example_joint_elbow.png'),
        'wrote',
        str(tmp_path / 'joint_example_joint_elbow.svg'),
    ]
    assert_written(
        [tmp_path / 'joint_example_joint_elbow.png', tmp_path / 'joint_example_joint_elbow.svg'],
        'joint_example_joint_elbow',
    )
    assert (
        main(
            ['plot', 'joint', '--config', str(CONFIGS['DMSP-10-250']), '--out-dir', str(tmp_path)]
        )
        == 2
    )
    assert 'plot joint needs a joint file' in capsys.readouterr().err


def test_plot_names_carry_the_input_and_never_overwrite_without_overwrite(tmp_path, capsys):
    """A user's fit of the DMSP-10-250 plotted next to the shipped figures keeps its own name; an
    existing figure is refused (nothing drawn) unless --overwrite.
    """
    mine = tmp_path / 'mine.yaml'
    mine.write_bytes(CONFIGS['DMSP-10-250'].read_bytes())
    args = ['plot', 'force-map', '--config', str(mine), '--out-dir', str(tmp_path)]
    (tmp_path / 'force_map_mine_martens.svg').write_text('mine')
    assert main([*args, '--format', 'png']) == 0
    assert capsys.readouterr().out.split() == [
        'wrote',
        str(tmp_path / 'force_map_mine_martens.png'),
    ]
    assert main(args) == 2
    assert capsys.readouterr().err == (
        f'pma-model: error: plot: {tmp_path / "force_map_mine_martens.png"} exists; not '
        'overwriting it (--overwrite overwrites)\n'
    )
    assert (tmp_path / 'force_map_mine_martens.svg').read_text() == 'mine'
    assert main([*args, '--overwrite']) == 0
    assert (tmp_path / 'force_map_mine_martens.svg').read_text() != 'mine'
