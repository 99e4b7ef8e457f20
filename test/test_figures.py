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
from pma_model_ros.bags.bag_io import BagError, BagWriter, DIAGNOSTIC_ARRAY, TYPESTORE
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


def test_an_error_map_of_a_map_not_on_a_grid_draws_each_point(tmp_path, martens_10_250):
    """A user's map is measured at pressures of its own per length: one dot per point."""
    fmap = shipped_force_map('DMSP-10-250')
    fmap = fmap.subset(np.arange(fmap.force.size) != 7)
    fig = figures.error_map_figure(fmap, martens_10_250)
    (dots,) = fig.axes[0].collections
    assert dots.get_offsets().shape == (fmap.force.size, 2)
    assert_written(figures.save(fig, tmp_path, 'map'), 'map')


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


def _map_csv(path, fmap, scale=1.0):
    """``fmap`` as a force map CSV, its lengths times ``scale``."""
    rows = zip(fmap.pressure, fmap.length * scale, fmap.force)
    path.write_text(
        'pressure_pa,length_m,force_n\n' + ''.join(f'{p},{float(L)!r},{F}\n' for p, L, F in rows)
    )
    return str(path)


@pytest.fixture
def titles(monkeypatch):
    """The title of every figure ``pma-model plot`` saves."""
    seen, save = [], figures.save

    def saving(fig, *args, **kwargs):
        seen.append(fig.axes[0].get_title())
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(figures, 'save', saving)
    return seen


def test_plot_draws_a_users_own_map(tmp_path, capsys, titles):
    """The shipped DMSP-10-250 cut to 0.382 m and Table A2 with its lengths cut alike (the same
    muscle type at equal contraction): drawn against the user's --data, the model's eq. 23 err is
    the file's on Table A2 (4.20 %, its identification), in both map figures.
    """
    cut = tmp_path / 'dmsp_10_382.yaml'
    argv = ['scale', '--config', str(CONFIGS['DMSP-10-250']), '--length', '0.382']
    assert main([*argv, '--out', str(cut)]) == 0
    data = _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250'), 0.382 / 0.25)
    capsys.readouterr()
    args = ['--config', str(cut), '--data', data, '--out-dir', str(tmp_path), '--format', 'png']
    assert main(['plot', 'force-map', *args]) == 0
    assert main(['plot', 'error-map', *args]) == 0
    err = read_parameters(CONFIGS['DMSP-10-250'])['models']['martens']['err']
    assert f'{err:.2f}' == '4.20'
    assert (
        titles[0]
        == f'DMSP-10-382: measured force map and the martens model (err {err:.2f} %, eq. 23)'
    )
    assert titles[1] == 'DMSP-10-382: martens model error over the measured map'
    assert capsys.readouterr().out.split()[1::2] == [
        str(tmp_path / 'force_map_dmsp_10_382_martens.png'),
        str(tmp_path / 'error_map_dmsp_10_382_martens.png'),
    ]


@pytest.mark.parametrize(
    'edit, message',
    [
        # a fit of another map whose spec kept the name: the map's lengths, not Table A2's
        (
            ('length_range: [0.198, 0.25]', 'length_range: [0.331, 0.382]'),
            "length_range [0.331, 0.382] m, the map's [0.198, 0.25] m",
        ),
        (
            ('inner_diameter: 0.01,', 'inner_diameter: 0.02,'),
            "inner_diameter 0.02, the map's 0.01",
        ),
    ],
)
def test_plot_never_draws_another_muscles_dots(tmp_path, capsys, edit, message):
    text = CONFIGS['DMSP-10-250'].read_text()
    assert edit[0] in text
    mine = tmp_path / 'mine.yaml'
    mine.write_text(text.replace(*edit))
    for figure in ('force-map', 'error-map', 'all'):
        argv = ['plot', figure, '--config', str(mine), '--out-dir', str(tmp_path)]
        assert main(argv) == 2
        assert capsys.readouterr().err == (
            f'pma-model: error: {mine}: its DMSP-10-250 is not the shipped one of its map '
            f'({message}); give the map it was fitted on: --data <csv>\n'
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ['mine.yaml']


def test_plot_asks_for_the_map_of_a_muscle_without_a_shipped_one(tmp_path, capsys):
    cut = tmp_path / 'cut.yaml'
    argv = ['scale', '--config', str(CONFIGS['DMSP-10-250']), '--length', '0.3']
    assert main([*argv, '--out', str(cut)]) == 0
    capsys.readouterr()
    assert main(['plot', 'force-map', '--config', str(cut), '--out-dir', str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"pma-model: error: {cut}: no shipped force map for 'DMSP-10-300' (maps: DMSP-10-250, "
        'DMSP-20-300); give the map it was fitted on: --data <csv>\n'
    )
    data = _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250'))
    argv = ['plot', 'joint', '--config', str(cut), '--data', data, '--out-dir', str(tmp_path)]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        'pma-model: error: --data is the measured map of force-map and error-map (with --config); '
        'plot joint draws none\n'
    )


def diagnostics_bag(path, reports):
    """A bag of /diagnostics: one model_node status per ``reports`` entry (stamp [s], residual
    line, level, reidentify served), and a status of another node beside it.
    """
    types = TYPESTORE.types
    Array, Status = (
        types['diagnostic_msgs/msg/DiagnosticArray'],
        types['diagnostic_msgs/msg/DiagnosticStatus'],
    )
    KeyValue, Header = types['diagnostic_msgs/msg/KeyValue'], types['std_msgs/msg/Header']
    Time = types['builtin_interfaces/msg/Time']
    with BagWriter(path) as writer:
        topic = writer.topic('/diagnostics', DIAGNOSTIC_ARRAY)
        for stamp, line, level, served in reports:
            values = {
                'residual [% of max force]': line,
                'residual level': level,
                'reidentify served': served,
            }
            statuses = [
                Status(
                    level=1 if level == 'WARN' else 0,
                    name=name,
                    message='',
                    hardware_id='',
                    values=[KeyValue(key=k, value=v) for k, v in (kv if keys else {}).items()],
                )
                for name, kv, keys in (
                    ('model_node: DMSP-10-250', values, True),
                    ('other_node: x', values, False),
                )
            ]
            msg = Array(
                header=Header(stamp=Time(sec=stamp, nanosec=0), frame_id=''), status=statuses
            )
            writer.write(topic, stamp * 10**9, msg)
    return path


def line(rms, band):
    """A window's /diagnostics line of a constant residual ``rms`` [%]."""
    return (
        f'bias {rms} %, RMS {rms} %, worst {rms} % over 900 samples in 10 s; band {band} % '
        '(900 interior, 0 edge)'
    )


def test_drift_series_and_plot_from_a_diagnostics_bag(tmp_path, capsys):
    bag = diagnostics_bag(
        tmp_path / 'run.mcap',
        [
            (100, 'too few samples in the window', 'OK', 'file'),
            (101, line(2.5, 4.66), 'OK', 'file'),
            (102, line(5.12, 4.66), 'WARN', 'file'),
            (104, line(1.5, 3.2), 'OK', 're-identified'),
        ],
    )
    series = figures.read_drift_series(bag)
    assert series.name == 'model_node: DMSP-10-250'
    np.testing.assert_array_equal(series.time, [0, 1, 2, 4])
    np.testing.assert_array_equal(series.rms, [np.nan, 2.5, 5.12, 1.5])
    np.testing.assert_array_equal(series.band, [np.nan, 4.66, 4.66, 3.2])
    np.testing.assert_array_equal(series.level, [0, 0, 1, 0])
    np.testing.assert_array_equal(series.reidentified, [False, False, False, True])
    assert main(['plot', 'drift', '--diagnostics', str(bag), '--out-dir', str(tmp_path)]) == 0
    assert capsys.readouterr().out.split()[1::2] == [
        str(tmp_path / 'drift_run.png'),
        str(tmp_path / 'drift_run.svg'),
    ]
    assert_written([tmp_path / 'drift_run.png', tmp_path / 'drift_run.svg'], 'drift_run')
    with pytest.raises(BagError, match='named elbow .*muscles with residual keys: DMSP-10-250'):
        figures.read_drift_series(bag, 'elbow')
