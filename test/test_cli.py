"""The pma-model command line: outputs and one-line errors with exit code 2."""

from dataclasses import replace
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import CONFIGS, REPO
from pma_model_ros.cli.fit_output import length_headers, rows_to_add
from pma_model_ros.cli.main import main
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec

TABLE3_MODELS = {'mckibben', 'andrikopoulos', 'wickramatunge', 'hildebrandt', 'sarosi', 'martens'}


@pytest.mark.parametrize(
    'argv',
    [
        ['fit', '--data', 'MAP', '--muscle', 'SPEC', '--model', 'martens', '--out', 'OUT'],
        ['make-config', 'DMSP-10-250', '--out', 'OUT'],
        ['evaluate', '--config', 'CONFIG', '--data', 'MAP', '--csv', 'OUT'],
    ],
)
def test_outputs_are_never_overwritten_without_overwrite(tmp_path, capsys, argv):
    """Refused before any work, the file untouched; the option is named."""
    out = tmp_path / 'out'
    out.write_text('mine')
    paths = {
        'MAP': REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250_force_map.csv',
        'SPEC': REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml',
        'CONFIG': CONFIGS['DMSP-10-250'],
        'OUT': out,
    }
    assert main([str(paths.get(a, a)) for a in argv]) == 2
    option = argv[argv.index('OUT') - 1]
    assert capsys.readouterr().err == (
        f'pma-model: error: {option}: {out} exists; not overwriting it (--overwrite overwrites)\n'
    )
    assert out.read_text() == 'mine'


SPEC_10_250 = REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml'
MAP_10_250 = REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250_force_map.csv'


@pytest.mark.parametrize(
    'argv, message',
    [
        (
            ['fit', '--data', 'MAP', '--muscle', 'SPEC', '--model', 'all', '--out', 'MISSING'],
            '--out MISSING: no directory TMP/no/such',
        ),
        (
            ['fit', '--data', 'MAP', '--muscle', 'SPEC', '--model', 'all', '--out', 'TMP'],
            '--out TMP is a directory; name a file in it',
        ),
        (
            ['make-config', 'DMSP-10-250', '--out', 'MISSING'],
            '--out MISSING: no directory TMP/no/such',
        ),
        (
            ['evaluate', '--config', 'CONFIG', '--data', 'MAP', '--csv', 'TMP'],
            '--csv TMP is a directory; name a file in it',
        ),
        (
            ['evaluate', '--config', 'CONFIG', '--data', 'MAP', '--csv', 'MAP', '--overwrite'],
            '--csv MAP is an input of this command; name a new file',
        ),
        (
            ['bag', 'estimate', 'TMP', '--config', 'CONFIG', '--out', 'MISSING'],
            '--out MISSING: no directory TMP/no/such',
        ),
        (
            ['plot', 'force-map', '--config', 'CONFIG', '--out-dir', 'MAP'],
            '--out-dir MAP is not a directory',
        ),
    ],
)
def test_an_output_that_cannot_be_written_is_refused_before_any_work(
    tmp_path, capsys, argv, message
):
    """A missing directory, a directory named as a file, an input named as an output: one line,
    nothing done (no calibration line of fit, no progress line).
    """
    paths = {
        'MAP': str(MAP_10_250),
        'SPEC': str(SPEC_10_250),
        'CONFIG': str(CONFIGS['DMSP-10-250']),
        'MISSING': str(tmp_path / 'no' / 'such' / 'p.yaml'),
        'TMP': str(tmp_path),
    }
    assert main([paths.get(a, a) for a in argv]) == 2
    out, err = capsys.readouterr()
    for key in ('MISSING', 'TMP', 'MAP'):  # longest first: MISSING holds TMP
        message = message.replace(key, paths[key])
    assert (out, err) == ('', f'pma-model: error: {message}\n')


def test_pressure_for_no_force_is_where_the_muscle_starts_to_pull(capsys):
    """``--force 0``: Table A2 has the DMSP-10-250 slack at 260 kPa at 0.234 m, so at the shorter
    0.23 m too; and pulling at 402.187 kPa at 0.219 m, so at the longer 0.23 m too.
    """
    cfg = str(CONFIGS['DMSP-10-250'])
    assert main(['pressure', '--config', cfg, '--force', '0', '--length', '0.23']) == 0
    pressure = float(capsys.readouterr().out.split()[1])
    assert 260e3 < pressure < 402.187e3


@pytest.mark.parametrize(
    'query',
    [['force', '--pressure', '300000'], ['pressure', '--force', '200']],
)
def test_a_query_imports_no_optimizer(query):
    """The force and pressure queries need no scipy: its import was most of a query's start-up
    (0.7 of 0.85 s; bench/cli_startup.py measures the whole).
    """
    argv = [*query, '--config', str(CONFIGS['DMSP-10-250']), '--length', '0.23']
    code = (
        f'import sys; from pma_model_ros.cli.main import main; code = main({argv!r}); '
        "print(code, sorted(m for m in sys.modules if m.split('.')[0] == 'scipy')[:3])"
    )
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert run.stdout.splitlines()[-1] == '0 []', run.stdout + run.stderr


def test_force_and_pressure_round_trip(capsys):
    cfg = str(CONFIGS['DMSP-10-250'])
    assert main(['pressure', '--config', cfg, '--force', '200', '--length', '0.23']) == 0
    pressure = float(capsys.readouterr().out.split()[1])
    assert 0 < pressure < 8e5
    assert main(['force', '--config', cfg, '--pressure', str(pressure), '--length', '0.23']) == 0
    out = capsys.readouterr().out
    assert float(out.split()[1]) == pytest.approx(200, rel=1e-5) and 'flags OK' in out


def test_fit_from_csv(tmp_path, capsys):
    fmap = shipped_force_map('DMSP-20-300')
    csv = tmp_path / 'map.csv'
    csv.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(f'{p},{L},{F}\n' for p, L, F in zip(fmap.pressure, fmap.length, fmap.force))
    )
    spec = REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_20_300.yaml'
    out = tmp_path / 'fit.yaml'
    assert (
        main(
            [
                'fit',
                '--data',
                str(csv),
                '--muscle',
                str(spec),
                '--model',
                'martens',
                '--out',
                str(out),
            ]
        )
        == 0
    )
    assert 'default model (the one fitted): martens  err' in capsys.readouterr().out
    assert main(['force', '--config', str(out), '--pressure', '450000', '--length', '0.25']) == 0
    assert float(capsys.readouterr().out.split()[1]) == pytest.approx(252.1, abs=0.03 * 1653.5)


@pytest.mark.parametrize(
    'content, message',
    [
        (None, 'not found'),
        ('pressure,length,force\n1,2,3\n', 'header'),
        ('pressure_pa,length_m,force_n\n100000,0.25,abc\n', 'not 3 numbers'),
        ('pressure_pa,length_m,force_n\n100000,0.25,nan\n', 'NaN'),
        ('pressure_pa,length_m,force_n\n100000,250,10\n200000,230,5\n300000,250,30\n', 'metres'),
    ],
)
def test_bad_csv_is_one_line_exit_2(tmp_path, capsys, content, message):
    csv = tmp_path / 'map.csv'
    if content is not None:
        csv.write_text(content)
    spec = REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250.yaml'
    code = main(
        [
            'fit',
            '--data',
            str(csv),
            '--muscle',
            str(spec),
            '--model',
            'martens',
            '--out',
            str(tmp_path / 'o'),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count('\n') == 1


@pytest.mark.parametrize(
    'args, message',
    [
        (['force', '--pressure', '300000', '--length', '230'], 'metres'),
        (['force', '--pressure', 'nan', '--length', '0.23'], 'Pa'),
        (
            ['force', '--pressure', '300000', '--length', '0.23', '--model', 'hill'],
            'unknown model',
        ),
        (['pressure', '--force', '200', '--length', '0.4'], 'geometry'),
    ],
)
def test_bad_queries_exit_2_without_traceback(args, message):
    cmd = [
        sys.executable,
        '-m',
        'pma_model_ros.cli',
        *args[:1],
        '--config',
        str(CONFIGS['DMSP-10-250']),
        *args[1:],
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and message in proc.stderr
    assert 'Traceback' not in proc.stderr and proc.stderr.count('\n') == 1


@pytest.mark.parametrize(
    'args, message',
    [
        (
            ['--pressure', '3'],
            '--pressure 3 Pa is below 1 kPa, no working pressure of a muscle: '
            'gauge pressure in Pa; bar? 3 bar = 300000 Pa',
        ),
        (
            ['--pressure', '450'],
            '--pressure 450 Pa is below 1 kPa, no working pressure of a muscle: gauge pressure '
            'in Pa; kPa? 450 kPa = 450000 Pa',
        ),
        (
            ['--pressure', '-300000'],
            '--pressure -300000 Pa gauge is below vacuum (-101325 Pa '
            'gauge = 0 Pa absolute); gauge pressure = absolute - ambient',
        ),
        (
            ['--length', '23'],
            '--length 23 m is longer than any muscle: lengths are in metres; cm? 23 cm = 0.23 m',
        ),
        (
            ['--length', '0.3'],
            'length 0.3 m is beyond what the geometry of DMSP-10-250 allows: '
            '0 < L < 0.284744 m (L0/cos(Theta0), its fibre length)',
        ),
    ],
)
def test_a_value_in_the_wrong_unit_is_refused_with_the_hint_of_its_case(capsys, args, message):
    """L0/cos(Theta0) of the DMSP-10-250: 0.25 m / cos(28.6 deg) = 0.284744 m."""
    values = {'--pressure': '300000', '--length': '0.23'} | dict([args])
    argv = ['force', '--config', str(CONFIGS['DMSP-10-250'])]
    assert main(argv + [a for kv in values.items() for a in kv]) == 2
    assert capsys.readouterr().err == f'pma-model: error: {message}\n'


@pytest.mark.parametrize(
    'path, message',
    [
        ('/dev/zero', 'not a regular file'),
        ('/tmp', 'not a regular file'),
        ('/no/such/file.yaml', 'not found'),
    ],
)
def test_config_must_be_the_named_regular_file(capsys, path, message):
    """A device, a directory or a missing path is refused before any byte is read."""
    assert main(['force', '--config', path, '--pressure', '300000', '--length', '0.23']) == 2
    err = capsys.readouterr().err
    assert message in err and err.count('\n') == 1


JOINT = str(REPO / 'config' / 'example_joint.yaml')


def test_joint_torque_prints_the_worked_example(capsys):
    """docs/joints.md's worked example, checked by hand in test/test_core_joint.py."""
    assert (
        main(
            [
                'joint',
                'torque',
                '--config',
                JOINT,
                '--angle',
                '0.5',
                '--pressures',
                '400000',
                '300000',
            ]
        )
        == 0
    )
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == 'torque -0.691819 N·m  stiffness 3.83797 N·m/rad'
    assert lines[1].startswith('flexor: length 0.2265 m') and lines[2].startswith(
        'extensor: length 0.2415 m'
    )


@pytest.mark.parametrize(
    'velocity, branches, flags',
    [(['--velocity', '0.5'], (-1, 1), 'OK'), ([], (0, 0), 'BRANCH_UNKNOWN')],
)
def test_joint_torque_takes_the_branches_from_the_velocity_sign(
    tmp_path, capsys, velocity, branches, flags
):
    """One shot, no memory: θ rising shortens muscle a (branch -1) and lengthens b (+1); no
    velocity, both unknown: the mean of the branches.  Two DMSP-10-100 on a 10 mm pulley at
    0.2 rad: 0.0855 and 0.0895 m.
    """
    muscle = {'file': str(CONFIGS['DMSP-10-100']), 'length_at_zero': 0.0875}
    finger = {
        'radius': [0.01],
        'limits': [-1.0, 1.0],
        'muscles': ['a', 'b'],
        'positive': 'a',
        'a': muscle,
        'b': dict(muscle),
    }
    path = tmp_path / 'finger.yaml'
    path.write_text(
        yaml.safe_dump({'/**': {'ros__parameters': {'joints': ['finger'], 'finger': finger}}})
    )
    args = [
        'joint',
        'torque',
        '--config',
        str(path),
        '--angle',
        '0.2',
        '--pressures',
        '600000',
        '500000',
    ]
    assert main(args + velocity) == 0
    lines = capsys.readouterr().out.splitlines()
    sarosi = muscle_model(read_parameters(CONFIGS['DMSP-10-100']))
    for line, p, length, branch in zip(lines[1:], (600e3, 500e3), (0.0855, 0.0895), branches):
        up, down = (float(sarosi.force(p, length, rate).force) for rate in (1.0, -1.0))
        expected = {1: up, -1: down, 0: (up + down) / 2}[branch]
        assert float(line.split('force ')[1].split()[0]) == pytest.approx(expected, rel=1e-5)
        assert line.endswith(f'flags {flags}')


def test_joint_pressures_round_trip_through_torque(capsys):
    assert (
        main(
            [
                'joint',
                'pressures',
                '--config',
                JOINT,
                '--angle',
                '-0.3',
                '--torque',
                '2.5',
                '--cocontraction',
                '150000',
            ]
        )
        == 0
    )
    first = capsys.readouterr().out.split()
    flexor, extensor = float(first[1]), float(first[4])
    assert extensor == 150000.0 and flexor > extensor
    assert (
        main(
            [
                'joint',
                'torque',
                '--config',
                JOINT,
                '--angle',
                '-0.3',
                '--pressures',
                repr(flexor),
                repr(extensor),
            ]
        )
        == 0
    )
    assert float(capsys.readouterr().out.split()[1]) == pytest.approx(
        2.5, rel=1e-5
    )  # printed to 6 digits


def test_joint_pressures_for_a_stiffness_and_out_of_reach(capsys):
    assert (
        main(
            [
                'joint',
                'pressures',
                '--config',
                JOINT,
                '--angle',
                '0',
                '--torque',
                '0',
                '--stiffness',
                '4.5',
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert 'flags OK' in out and 'stiffness 4.5 N·m/rad' in out
    assert main(['joint', 'pressures', '--config', JOINT, '--angle', '0', '--torque', '50']) == 0
    out = capsys.readouterr().out
    assert (
        'flags SATURATED' in out and 'flexor 800000 Pa' in out
    )  # the rated pressure: hildebrandt is served extrapolated beyond the map's 650 kPa


def test_joint_envelope_is_symmetric_for_a_symmetric_joint(capsys):
    assert main(['joint', 'envelope', '--config', JOINT, '--steps', '5']) == 0
    rows = [list(map(float, line.split())) for line in capsys.readouterr().out.splitlines()[2:]]
    assert [r[0] for r in rows] == [-1.0, -0.5, 0.0, 0.5, 1.0]
    for row, mirror in zip(
        rows, rows[::-1]
    ):  # two equal muscles at equal lengths: τ(-θ) ranges mirror τ(θ)
        assert row[1] == pytest.approx(-mirror[2], rel=1e-9) and row[3:] == pytest.approx(
            mirror[3:], rel=1e-9
        )


@pytest.mark.parametrize(
    'args, message',
    [
        (['torque', '--angle', '30', '--pressures', '1e5', '1e5'], 'radians, not degrees'),
        (['torque', '--angle', '0', '--pressures', '3e5', 'nan'], '--pressures nan is outside'),
        (['torque', '--angle', '0', '--pressures', '4', '3'], '--pressures 4 Pa is below 1 kPa'),
        (
            ['pressures', '--angle', '0', '--torque', '1', '--cocontraction', '-5'],
            '--cocontraction',
        ),
        (['pressures', '--angle', '0', '--torque', '1', '--joint', 'knee'], 'choose one of elbow'),
        (['envelope', '--steps', '1'], '--steps 1'),
    ],
)
def test_bad_joint_queries_exit_2_without_traceback(args, message):
    cmd = [
        sys.executable,
        '-m',
        'pma_model_ros.cli',
        'joint',
        args[0],
        '--config',
        JOINT,
        *args[1:],
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and message in proc.stderr
    assert 'Traceback' not in proc.stderr and proc.stderr.count('\n') == 1


def test_bad_joint_file_exits_2(tmp_path, capsys):
    bad = tmp_path / 'joint.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    joints: [elbow]\n')
    assert main(['joint', 'envelope', '--config', str(bad)]) == 2
    err = capsys.readouterr().err
    assert "joint 'elbow': no parameters under 'elbow:'" in err and err.count('\n') == 1


def _map_csv(path, fmap) -> str:
    path.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(f'{p},{L},{F}\n' for p, L, F in zip(fmap.pressure, fmap.length, fmap.force))
    )
    return str(path)


def test_fit_calibrates_a_wrong_rest_length_and_prints_the_held_out_table(tmp_path, capsys):
    """A user's case: DMSP-20-300 with L0 given 4 mm short (err 5.29 %, against 1.32 % with 0.300
    m): 0.296 m, the map's longest length, slack below 42 kPa, so L0 is longer (a 38 kPa threshold
    at 0.296 m fits worse).
    """
    spec_text = (REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_20_300.yaml').read_text()
    spec = tmp_path / 'spec.yaml'
    spec.write_text(spec_text.replace('nominal_length: 0.30 ', 'nominal_length: 0.296 '))
    assert 'nominal_length: 0.296' in spec.read_text()
    csv, out = (
        _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-20-300')),
        tmp_path / 'fit.yaml',
    )
    assert (
        main(
            ['fit', '--data', csv, '--muscle', str(spec), '--model', 'martens', '--out', str(out)]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert text.startswith('geometry calibration ON')
    assert '0.296    0.282    0.267    0.250    0.237    0.222    worst' in text
    params = read_parameters(out)
    entry = params['models']['martens']
    assert entry['err'] <= 1.32 + 0.5
    assert abs(entry['nominal_length'] - 0.300) <= 0.001
    assert params['muscle']['nominal_length'] == entry['nominal_length']
    assert params['muscle']['given_nominal_length'] == 0.296  # for pma-model scale
    assert 'pressure_offset' not in entry and 'pressure offset kept 0: not identifiable' in text


def test_every_model_of_a_fit_all_file_is_served_as_it_was_fitted(tmp_path, capsys):
    """DMSP-20-300 with L0 given 4 mm short, ``--model all``: martens (the default) moves L0 to
    0.2993 m, sarosi keeps 0.296 m.  Each model the file holds, served from the file (what
    model_node does when ``model`` is switched), reproduces its own in-sample err (eq. 23) on the
    map: sarosi is not served at martens' L0 (10.21 % against its 1.11 %).
    """
    from pma_model_ros.core.identification.protocols import quality

    spec = tmp_path / 'spec.yaml'
    spec.write_text(
        (REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_20_300.yaml')
        .read_text()
        .replace('nominal_length: 0.30 ', 'nominal_length: 0.296 ')
    )
    fmap = shipped_force_map('DMSP-20-300')
    csv, out = _map_csv(tmp_path / 'map.csv', fmap), tmp_path / 'all.yaml'
    argv = ['fit', '--data', csv, '--muscle', str(spec), '--model', 'all', '--out', str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    params = read_parameters(out)
    for name, entry in params['models'].items():
        served = muscle_model(params, name).force(fmap.pressure, fmap.length).force
        err = quality(fmap.force, np.nan_to_num(served), fmap.max_force)[0]
        assert err == pytest.approx(entry['err'], abs=1e-6), name


def test_fit_raises_an_l0_shorter_than_the_longest_row_and_says_so(tmp_path, capsys):
    """Table A2 with L0 given 0.24 m (a tape measure 1 cm off): the map has a 0.250 m row, so L0
    is at least 0.250 m, and the line says it was raised.  With --no-calibrate-length the given L0
    cannot be kept: one line, exit 2, no file.
    """
    spec = tmp_path / 'spec.yaml'
    spec.write_text(
        SPEC_10_250.read_text().replace('nominal_length: 0.25 ', 'nominal_length: 0.24 ')
    )
    assert 'nominal_length: 0.24 ' in spec.read_text()
    csv, out = (
        _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250')),
        tmp_path / 'f.yaml',
    )
    argv = ['fit', '--data', csv, '--muscle', str(spec), '--model', 'martens', '--out', str(out)]
    assert main([*argv, '--no-calibrate-length']) == 2
    text, err = capsys.readouterr()
    assert 'nominal_length 0.24 m is shorter than the longest measured length 0.25 m' in err
    assert err.count('\n') == 1 and text == '' and not out.exists()
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert 'L0 0.2500 m (given 0.2400 m: raised to the longest measured row 0.25 m' in text
    assert 'L0 kept' not in text
    params = read_parameters(out)
    assert params['muscle']['nominal_length'] >= 0.25
    assert params['models']['martens']['nominal_length'] >= 0.25


def test_fit_all_models_defaults_to_the_best_held_out_error(tmp_path, capsys):
    spec = REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250.yaml'
    csv, out = (
        _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250')),
        tmp_path / 'all.yaml',
    )
    assert (
        main(
            [
                'fit',
                '--data',
                csv,
                '--muscle',
                str(spec),
                '--model',
                'all',
                '--no-calibrate-length',
                '--no-calibrate-pressure',
                '--out',
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert text.startswith('geometry calibration OFF')
    params = read_parameters(out)
    models = params['models']
    assert set(models) == TABLE3_MODELS
    # the lowest mean of the nested held-out errors per length the file keeps
    assert params['model'] == min(models, key=lambda m: np.mean(models[m]['held_out']['err']))
    assert params['model'] != min(
        models, key=lambda m: models[m]['err']
    )  # Hildebrandt fits best in-sample
    assert all('nominal_length' not in e and 'pressure_offset' not in e for e in models.values())
    assert 'default model (by mean held-out err; ' in text
    assert f'): {params["model"]}  err' in text
    # one figure for one thing: the last line's are the written model's, as its file and the
    # force band serve them (the whole protocol's is on the line above, labelled so)
    entry = models[params['model']]
    assert (
        f'held-out worst {entry["cv_err"]:.2f} % (between measured lengths '
        f'{entry["interior_cv_err"]:.2f} %, beyond them {entry["edge_cv_err"]:.2f} %)'
        in text.splitlines()[-1]
    )
    assert "(the whole protocol's figure, not the default model's own)" in text
    for length, figure in ((0.23, entry['interior_cv_err']), (0.19, entry['edge_cv_err'])):
        argv = ['force', '--config', str(out), '--pressure', '300000', '--length', str(length)]
        assert main(argv) == 0
        assert f'({figure:.2f} % of 542.5 N: ' in capsys.readouterr().out


def test_fit_all_prints_the_written_models_figures_where_the_folds_chose_others(
    tmp_path, capsys, monkeypatch
):
    """Chosen by the interior figure, Table A2 (calibration off) writes Sárosi while the folds
    choose Martens and Hildebrandt: the whole protocol's figure then differs from Sárosi's own.
    The last line, the file and the force band give Sárosi's own; the protocol's is labelled.
    """
    from pma_model_ros.core.identification import selection

    monkeypatch.setattr(selection, 'MODEL_RULE', 'interior held-out')
    csv, out = (
        _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250')),
        tmp_path / 'a.yaml',
    )
    flags = ['--no-calibrate-length', '--no-calibrate-pressure', '--out', str(out)]
    assert (
        main(['fit', '--data', csv, '--muscle', str(SPEC_10_250), '--model', 'all', *flags]) == 0
    )
    lines = capsys.readouterr().out.splitlines()
    params = read_parameters(out)
    entry = params['models'][params['model']]
    assert params['model'] == 'sarosi'
    own = (entry['cv_err'], entry['interior_cv_err'], entry['edge_cv_err'])
    assert (
        lines[-1]
        .split('held-out worst ')[1]
        .startswith(
            f'{own[0]:.2f} % (between measured lengths {own[1]:.2f} %, beyond them {own[2]:.2f} %)'
        )
    )
    protocol = next(line for line in lines if line.startswith('default model (lowest'))
    assert 'x' in protocol and "(the whole protocol's figure, not the default model's own)" in (
        protocol
    )
    assert f'errs by {own[0]:.2f} % at worst' not in protocol  # the folds chose other models
    argv = ['force', '--config', str(out), '--pressure', '300000', '--length', '0.23']
    assert main(argv) == 0
    assert f'({own[1]:.2f} % of 542.5 N: ' in capsys.readouterr().out


def test_fit_held_out_column_is_what_holding_each_length_back_gives(tmp_path, capsys):
    """The fit's per-length held-out column, checked the way a user would: for each length, fit the
    map without it (the same command), then evaluate that fit on the one held-back length. The
    pressure offset is calibrated (Table A2 identifies 39.7 kPa, but only with its 0.250 m row), so
    the folds differ in what they calibrate, and the column must still match to its 2 decimals.
    """
    spec = str(REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250.yaml')
    fmap = shipped_force_map('DMSP-10-250')
    flags = ['--no-calibrate-length', '--model', 'martens', '--muscle', spec, '--overwrite']
    out = tmp_path / 'all.yaml'
    assert (
        main(['fit', '--data', _map_csv(tmp_path / 'map.csv', fmap), *flags, '--out', str(out)])
        == 0
    )
    lines = capsys.readouterr().out.splitlines()
    column = [
        float(v)
        for v in next(
            ln for ln in lines if ln.startswith('martens ') and len(ln.split()) == 7
        ).split()[1:6]
    ]
    assert (
        lines[-1]
        .split('held-out worst ')[1]
        .startswith(
            f'{max(column):.2f} % (between measured lengths {max(column[1:4]):.2f} %, beyond them '
            f'{max(column[0], column[4]):.2f} %)'
        )
    )
    held_out = read_parameters(out)['models']['martens']['held_out']
    assert held_out['lengths'] == list(fmap.lengths) and held_out['err'] == pytest.approx(
        column[:5], abs=0.005
    )
    for length, printed in zip(fmap.lengths, column):
        if fmap.force[fmap.length == length].max() == 0:  # 0.198 m: slack, no eq. 23 of its own
            continue
        rest, held = (
            _map_csv(tmp_path / name, fmap.subset(mask))
            for name, mask in (
                ('rest.csv', fmap.length != length),
                ('held.csv', fmap.length == length),
            )
        )
        assert main(['fit', '--data', rest, *flags, '--out', str(out)]) == 0
        points = tmp_path / 'points.csv'
        assert (
            main(
                [
                    'evaluate',
                    '--config',
                    str(out),
                    '--data',
                    held,
                    '--csv',
                    str(points),
                    '--overwrite',
                ]
            )
            == 0
        )
        capsys.readouterr()
        errors = [float(row.split(',')[4]) for row in points.read_text().splitlines()[1:]]
        assert 100 * max(map(abs, errors)) / fmap.max_force == pytest.approx(printed, abs=0.006)


def test_fit_names_the_rows_to_measure_when_the_edge_figure_is_large(tmp_path, capsys):
    """Table A2's rest-length row (0.250 m) is the fit's worst held-out length, an extrapolation
    from the shorter rows: fit names the rows that would make it less of one.  The braid pulls down
    to L_F / sqrt(3) = 0.25 / cos(28.6 deg) / sqrt(3) = 0.1644 m (eq. 4).
    """
    spec = str(REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250.yaml')
    fmap = shipped_force_map('DMSP-10-250')
    out = tmp_path / 'fit.yaml'
    data = _map_csv(tmp_path / 'map.csv', fmap)
    argv = ['fit', '--data', data, '--muscle', spec, '--model', 'martens', '--out', str(out)]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    advice = next(line for line in lines if line.startswith('beyond the measured lengths'))
    assert '(the longest, predicted from the others)' in advice
    assert (
        'rows to measure: one between 0.234 and 0.25 m (the rest-length row, 0.25 m, is '
        'measured: it is the edge, and a row beside it makes it less of an extrapolation)'
        in advice
    )
    # a calibrated L0 just above the longest row names the row measured, not L0
    calibrated = rows_to_add(
        np.array([8.81, 2.9, 0.81, 0.53, 0.56]),
        fmap.lengths,
        replace(shipped_spec('DMSP-10-250'), nominal_length=0.2512),
    )
    assert '(the rest-length row, 0.25 m, L0 0.2512 m as calibrated, is measured' in calibrated
    # calibrated 1.5 % above the longest row, which is at the given L0 (0.25 m): still measured
    far = rows_to_add(
        np.array([8.81, 2.9, 0.81, 0.53, 0.56]),
        fmap.lengths,
        replace(shipped_spec('DMSP-10-250'), nominal_length=0.2538),
        0.25,
    )
    assert '(the rest-length row, 0.25 m, L0 0.2538 m as calibrated, is measured' in far
    assert 'the shortest is 0.198 m; the braid pulls down to 0.1644 m' in advice
    assert lines[-1].startswith('default model')  # the last line stays the figures' line
    # not large: an edge within 5 %, or within 1 pp of the lengths between the edges
    lengths = np.array([0.3, 0.28, 0.26, 0.24])
    assert rows_to_add(np.array([2.69, 0.64, 1.44, 4.9]), lengths, None) == ''
    assert rows_to_add(np.array([9.0, 8.5, 3.0, 6.0]), lengths, None) == ''


def test_force_prints_the_expected_error_at_the_length(tmp_path, capsys):
    """Between the measured lengths the worst held-out err of the lengths inside (interpolation),
    from the file; beyond them the worse of the shortest's and longest's, said to be
    extrapolation where the model is extrapolated and held where the force is held.
    """
    config = str(CONFIGS['DMSP-10-250'])
    held = read_parameters(config)['models']['martens']['held_out']
    interior, edge = max(held['err'][1:-1]), max(held['err'][0], held['err'][-1])
    for length in (0.23, 0.219, 0.198, 0.25):
        assert (
            main(['force', '--config', config, '--pressure', '300000', '--length', str(length)])
            == 0
        )
        band = capsys.readouterr().out.splitlines()[1]
        assert band.startswith(
            f'expected error: about ±{interior * 542.5 / 100:.3g} N ({interior:.2f} % of 542.5 N: '
            'between the measured lengths 0.198..0.25 m'
        )
    # 0.19 m: Martens extrapolated below the shortest; 0.26 m: beyond L0 = 0.25 m, held at L0
    for length, why in (
        (0.19, 'extrapolation: 0.19 m is beyond the measured lengths 0.198..0.25 m'),
        (0.26, 'held: 0.26 m is beyond the lengths served, and the force is the one at 0.25 m'),
    ):
        assert (
            main(['force', '--config', config, '--pressure', '300000', '--length', str(length)])
            == 0
        )
        force, band = capsys.readouterr().out.splitlines()[:2]
        assert ('LENGTH_OUT_OF_RANGE' in force) == (length == 0.26)
        assert band.startswith(
            f'expected error: about ±{edge * 542.5 / 100:.3g} N ({edge:.2f} % of 542.5 N: {why}'
        )
        assert ('extrapolation' in band) == (length == 0.19)
    # a file whose L0 (0.24 m) is shorter than its measured lengths: 0.245 m lies between them
    # but beyond L0, so the force is held at L0 and the band says so, with the edge figure
    short = tmp_path / 'short.yaml'
    text = CONFIGS['DMSP-10-250'].read_text()
    short.write_text(text.replace('nominal_length: 0.25,', 'nominal_length: 0.24,', 1))
    assert short.read_text() != text
    argv = ['force', '--config', str(short), '--pressure', '300000', '--length', '0.245']
    assert main(argv) == 0
    force, band = capsys.readouterr().out.splitlines()[:2]
    assert 'LENGTH_OUT_OF_RANGE' in force and 'between the measured lengths' not in band
    assert f'({edge:.2f} % of 542.5 N: held: 0.245 m is beyond the lengths served' in band
    assert 'the force is the one at 0.24 m' in band


def test_force_where_no_force_was_measured_has_no_band_of_zero(capsys):
    """Table A1 measured 0 N at 0.222 m at every pressure (the DMSP-20-300 fully contracted): its
    held-out err (0 %) is no band of ±0 N; the figure of the lengths inside stands for it.
    """
    fmap = shipped_force_map('DMSP-20-300')
    assert fmap.force[fmap.length == 0.222].max() == 0
    config = str(CONFIGS['DMSP-20-300'])
    held = read_parameters(config)['models']['martens']['held_out']
    assert held['err'][-1] == 0
    assert main(['force', '--config', config, '--pressure', '300000', '--length', '0.222']) == 0
    band = capsys.readouterr().out.splitlines()[1]
    interior = max(held['err'][1:-1])
    assert interior > 0 and band.startswith(
        f'expected error: about ±{interior * 1653.5 / 100:.3g} N ({interior:.2f} % of 1654 N: '
        'between the measured lengths'
    )


@pytest.mark.parametrize('pressure', ['700000', '900000'])
def test_force_outside_the_identified_pressures_has_no_band(capsys, pressure):
    """Table A2 reaches 650 kPa: above it (extrapolated, or beyond the rated 800 kPa: out of
    range) the held-out errors of the identified lengths do not hold.
    """
    config = str(CONFIGS['DMSP-10-250'])
    assert main(['force', '--config', config, '--pressure', pressure, '--length', '0.23']) == 0
    assert capsys.readouterr().out.splitlines()[1] == (
        f'expected error: unknown: {pressure} Pa is outside the identified pressures 0..650000 Pa '
        '(the held-out errors hold within them)'
    )


def test_a_length_in_millimetres_of_a_short_muscle_is_named_so(capsys):
    """95 on a DMSP-10-100 (L0 0.1 m): 95 mm, not 95 cm (0.95 m, nine rest lengths)."""
    config = str(CONFIGS['DMSP-10-100'])
    assert main(['force', '--config', config, '--pressure', '300000', '--length', '95']) == 2
    assert capsys.readouterr().err.endswith('lengths are in metres; mm? 95 mm = 0.095 m\n')


def test_a_force_map_with_a_byte_order_mark_is_read(tmp_path, capsys):
    csv = tmp_path / 'map.csv'
    csv.write_text(MAP_10_250.read_text(), encoding='utf-8-sig')
    assert main(['evaluate', '--config', str(CONFIGS['DMSP-10-250']), '--data', str(csv)]) == 0
    assert capsys.readouterr().out.split('\n')[0].endswith('(85 points)')  # Table A2: 17 x 5


def _table_a2(**change):
    """Table A2 (DMSP-10-250) with ``pressure``, ``length`` or ``force`` mapped by a function, and
    ``keep``: a mask of the points kept.
    """
    fmap = shipped_force_map('DMSP-10-250')
    keep = change.get('keep', lambda m: np.ones(m.force.size, bool))(fmap)
    same = lambda a: a  # noqa: E731
    return (
        change.get('pressure', same)(fmap.pressure[keep]),
        change.get('length', same)(fmap.length[keep]),
        change.get('force', same)(fmap.force[keep]),
    )


@pytest.mark.parametrize(
    'change, message',
    [
        (  # absolute pressures: Table A2's first step, 5 kPa gauge, at 101325 Pa ambient
            {'pressure': lambda p: p + 101325},
            'pressure_pa starts at 106325 Pa with no force at any length: about ambient '
            '(101325 Pa), so absolute pressures; the map takes gauge pressure = absolute - '
            'ambient (e.g. 5000 Pa)',
        ),
        (  # 542.5 N, Table A2's largest force, in kN, against the braid's pull there:
            # pi (D0 + 2 H0)^2 / 4 (3 cos^2 Theta0 - 1) / sin^2 Theta0 x 650 kPa = 540.9 N at L0
            {'force': lambda f: f / 1e3},
            'force_n reaches 0.5425 at 650000 Pa, 0.25 m: 0.001003 x the 540.9 N the ideal braid '
            'of DMSP-10-250 (D0 10 mm + 2 H0, Theta0 28.6 deg, L0 0.25 m) pulls there, the whole '
            'map alike: force in newtons; kN? 0.5425 kN = 542.5 N (the map x 1000)',
        ),
        ({'force': lambda f: f * 1e3}, 'N·mm or mN? 542500 mN = 542.5 N (the map x 0.001)'),
        ({'force': lambda f: f / 9.80665}, ' = 542.5 N (the map x 9.80665)'),  # kgf
        ({'force': lambda f: f / 4.4482216152605}, ' = 542.5 N (the map x 4.44822)'),  # lbf
        (
            {'keep': lambda m: np.isin(m.length, (0.25, 0.219))},
            'a fit needs a map of at least 3 lengths, got 2 (0.25, 0.219 m): with 2 no length '
            'is held out between others to judge the fit; measure one between 0.219 and 0.25 m',
        ),
        (
            {'keep': lambda m: m.length == 0.25},
            'a fit needs a map of at least 3 lengths, got 1 (0.25 m): measure the force map at '
            'several lengths',
        ),
        (  # the DMSP-10-250, L0 0.25 m: its fibre length 0.25 / cos(28.6 deg) = 0.284744 m
            {'length': lambda L: np.where(L == 0.25, 0.29, L)},
            'the map and the spec DMSP-10-250 do not belong together: length_m reaches 0.29 m, '
            '16.0 % beyond its L0 0.25 m, beyond the 0.284744 m a braid of the spec reaches (its '
            'fibre length L0/cos(Theta0))',
        ),
    ],
)
def test_fit_names_a_map_it_cannot_identify_before_fitting(tmp_path, capsys, change, message):
    """One line, exit 2, before any fitting (not even the calibration line) and no file."""
    csv, out = tmp_path / 'map.csv', tmp_path / 'fit.yaml'
    csv.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(f'{p:.9g},{L:.9g},{F:.9g}\n' for p, L, F in zip(*_table_a2(**change)))
    )
    argv = ['fit', '--data', str(csv), '--muscle', str(SPEC_10_250), '--model', 'martens']
    assert main([*argv, '--out', str(out)]) == 2
    out_text, err = capsys.readouterr()
    assert out_text == '' and err.startswith('pma-model: error: ') and message in err, err
    assert err.count('\n') == 1 and not out.exists()


def _refused(tmp_path, capsys, text: str, spec, before_fit: bool = True) -> str:
    """The one error line of ``fit --model martens`` of the map ``text`` with ``spec``; no file,
    and nothing printed if refused ``before_fit``.
    """
    csv, out = tmp_path / 'map.csv', tmp_path / 'fit.yaml'
    csv.write_text(text)
    argv = ['fit', '--data', str(csv), '--muscle', str(spec), '--model', 'martens']
    assert main([*argv, '--out', str(out)]) == 2
    out_text, err = capsys.readouterr()
    assert err.startswith('pma-model: error: ') and err.count('\n') == 1
    assert out_text == '' or not before_fit
    assert not out.exists()
    return err


def test_fit_names_an_outlying_row_by_its_line(tmp_path, capsys):
    """5000 N typed at 196250 Pa, 0.25 m in Table A2 (139.5 N measured there) is that row's
    mistake, not the map's unit: named by its file line (header line 2 after a comment).
    """
    fmap = shipped_force_map('DMSP-10-250')
    row = int(np.flatnonzero((fmap.pressure == 196250) & (fmap.length == 0.25))[0])
    force = np.where(np.arange(fmap.force.size) == row, 5000, fmap.force)
    text = '# Table A2, one force mistyped\npressure_pa,length_m,force_n\n' + ''.join(
        f'{p:.9g},{L:.9g},{F:.9g}\n' for p, L, F in zip(fmap.pressure, fmap.length, force)
    )
    err = _refused(tmp_path, capsys, text, SPEC_10_250)
    assert (
        f'1 row(s) of force_n far above the rest of the map: line {row + 3}: 5000 at 196250 '
        in err
    )
    assert 'mN' not in err and 'unit' not in err


def test_fit_names_absolute_pressures_above_ambient(tmp_path, capsys):
    """Table A1 with 101325 Pa added: its first step (35 kPa gauge) is no ambient, but its rest-
    length row (0.296 m) pulls nothing at 136325 Pa, where the gauge map pulls from 35..60 kPa.
    """
    fmap = shipped_force_map('DMSP-20-300')
    text = 'pressure_pa,length_m,force_n\n' + ''.join(
        f'{p + 101325:.9g},{L:.9g},{F:.9g}\n'
        for p, L, F in zip(fmap.pressure, fmap.length, fmap.force)
    )
    err = _refused(tmp_path, capsys, text, REPO / 'config' / 'muscles' / 'dmsp_20_300.yaml')
    threshold = float(err.split('the map pulls only from about ')[1].split()[0])
    assert 136.325 <= threshold <= 161.325  # no force at 136325 Pa, 54.9 N at 161325 Pa
    assert 'absolute' in err and 'gauge pressure = absolute - ambient' in err


def test_fit_blames_a_wrong_fiber_angle_on_the_spec(tmp_path, capsys):
    """fiber_angle 0.9 rad: the braid contracts fully at 0.25 / cos(0.9) / sqrt(3) = 0.2322 m,
    but Table A2 pulls at 0.219 and 0.204 m.
    """
    spec = tmp_path / 'spec.yaml'
    spec.write_text(
        SPEC_10_250.read_text().replace('fiber_angle: 0.4991641660703783', 'fiber_angle: 0.9')
    )
    err = _refused(tmp_path, capsys, MAP_10_250.read_text(), spec)
    contracted = 'the braid of the spec DMSP-10-250 is fully contracted at 0.2322 m'
    assert f'pulls 46 N at 0.204 m, but {contracted}' in err
    assert 'the spec is the suspect' in err and 'mN' not in err


def test_fit_names_a_map_of_another_muscle(tmp_path, capsys):
    """Table A1 (DMSP-20-300, 0.296 m) with the DMSP-10-250 spec: 0.296 / 0.25 = 18.4 % beyond
    L0; 1653.5 N at 675 kPa against pi (13.6 mm)^2 / 4 x 5.744 x 675 kPa = 561.7 N at L0.
    """
    err = _refused(
        tmp_path,
        capsys,
        MAP_10_250.parent.joinpath('dmsp_20_300_force_map.csv').read_text(),
        SPEC_10_250,
    )
    assert 'the map and the spec DMSP-10-250 do not belong together' in err
    assert '18.4 % beyond its L0 0.25 m' in err and 'against 561.7 N' in err


def test_fit_names_a_failed_least_squares(tmp_path, capsys, monkeypatch):
    """A LinAlgError in the fit (SVD did not converge) is one line naming the likely cause."""
    from pma_model_ros.core.identification import selection

    def fail(*args, **kwargs):
        raise np.linalg.LinAlgError('SVD did not converge')

    monkeypatch.setattr(selection, 'identify_all', fail)
    err = _refused(tmp_path, capsys, MAP_10_250.read_text(), SPEC_10_250, before_fit=False)
    assert "the fit's least squares found no solution (SVD did not converge): the map and" in err


def test_fit_names_points_measured_twice_at_other_forces(tmp_path, capsys):
    """Table A2 appended once more with every force 30 % higher: 260 kPa at 0.25 m measured
    195.667 N and 254.367 N.
    """
    p, L, F = _table_a2()
    csv = tmp_path / 'map.csv'
    csv.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(f'{a:.9g},{b:.9g},{c:.9g}\n' for a, b, c in zip(p, L, F))
        + ''.join(f'{a:.9g},{b:.9g},{c * 1.3:.9g}\n' for a, b, c in zip(p, L, F))
    )
    argv = ['fit', '--data', str(csv), '--muscle', str(SPEC_10_250), '--model', 'martens']
    assert main([*argv, '--out', str(tmp_path / 'fit.yaml')]) == 2
    err = capsys.readouterr().err
    pulling = int(np.count_nonzero(0.3 * F > 0.07 * 1.3 * 542.5))  # 7 % of the max, 1.3 x 542.5
    assert err.startswith(f'pma-model: error: {pulling} point(s) measured twice with forces more')
    assert 'e.g. 260000 Pa, 0.25 m: 195.667, 254.367 N' in err


def test_evaluate_a_map_of_one_length(tmp_path, capsys):
    """A length held back to check a fit is a map of one length: evaluated, per-length table."""
    fmap = shipped_force_map('DMSP-20-300')
    one = _map_csv(tmp_path / 'one.csv', fmap.subset(fmap.length == 0.267))
    assert main(['evaluate', '--config', str(CONFIGS['DMSP-20-300']), '--data', one]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith(f'({int((fmap.length == 0.267).sum())} points)')
    assert [ln.split()[0] for ln in lines[2:]] == ['0.2670']


def test_evaluate_a_config_on_a_measured_map(tmp_path, capsys):
    fmap = shipped_force_map('DMSP-20-300')
    config, csv, out = (
        str(CONFIGS['DMSP-20-300']),
        _map_csv(tmp_path / 'map.csv', fmap),
        tmp_path / 'points.csv',
    )
    assert main(['evaluate', '--config', config, '--data', csv, '--csv', str(out)]) == 0
    text = capsys.readouterr().out
    rows = [line.split(',') for line in out.read_text().splitlines()[1:]]
    assert len(rows) == fmap.force.size
    force, model, error = (np.array([float(r[i]) for r in rows]) for i in (2, 3, 4))
    assert error == pytest.approx(model - force, abs=1e-4)  # 9 significant digits written
    printed = float(text.split('err (eq. 23) ')[1].split()[0])
    assert printed == pytest.approx(100 * np.abs(error).max() / force.max(), abs=0.006)
    flags = [r[5] for r in rows]
    # the 675 kPa points lie above the rated 600 kPa but inside the identified data: served as
    # identified
    over = fmap.pressure > read_parameters(config)['muscle']['max_pressure']
    assert over.any() and not any('OUT_OF_RANGE' in f or 'EXTRAPOLATED' in f for f in flags)
    # where nothing is flagged the served model is the fitted one: within its in-sample err (eq.
    # 23)
    served = np.array([f in ('OK', 'CLIPPED') for f in flags])
    err = read_parameters(config)['models'][read_parameters(config)['model']]['err']
    assert 100 * np.abs(error[served]).max() / fmap.max_force <= err + 1e-6
    assert (
        sum(line.startswith(f'{L:>10.4f}') for line in text.splitlines() for L in fmap.lengths)
        == 6
    )


@pytest.mark.parametrize(
    'data, config, message',
    [('/no/such.csv', None, 'not found'), (None, '/no/such.yaml', 'not found')],
)
def test_evaluate_bad_input_is_one_line_exit_2(tmp_path, capsys, data, config, message):
    data = data or _map_csv(tmp_path / 'map.csv', shipped_force_map('DMSP-10-250'))
    assert (
        main(['evaluate', '--config', config or str(CONFIGS['DMSP-10-250']), '--data', data]) == 2
    )
    err = capsys.readouterr().err
    assert message in err and err.count('\n') == 1


def test_length_headers_differ_where_lengths_do():
    assert length_headers([0.25, 0.234, 0.219]) == ['0.250', '0.234', '0.219']
    assert length_headers([0.23271, 0.23268, 0.215]) == ['0.23271', '0.23268', '0.21500']


def test_scale_writes_the_muscle_cut_to_another_length_and_back(tmp_path, capsys):
    """DMSP-20-300 cut to 0.274 m: the same force at equal contraction and pressure, the domain
    moved in contraction, and cut back to 0.3 m the source's parameters to 1e-9.
    """
    cut, back = tmp_path / 'cut.yaml', tmp_path / 'back.yaml'
    source = CONFIGS['DMSP-20-300']
    assert main(['scale', '--config', str(source), '--length', '0.274', '--out', str(cut)]) == 0
    assert capsys.readouterr().out == (
        f'wrote {cut}: DMSP-20-274 (DMSP-20-300 x 0.913333: given L0 0.3 -> 0.274 m), '
        'length_range [0.20276, 0.270347] m\n'
    )
    assert cut.read_text().startswith(
        f"# DMSP-20-274: DMSP-20-300 of {source} cut to the given rest length L0' = 0.274 m"
    )
    assert main(['scale', '--config', str(cut), '--length', '0.3', '--out', str(back)]) == 0
    theirs, ours, cut_params = (read_parameters(p) for p in (source, back, cut))
    assert ours['muscle'] == theirs['muscle']
    assert ours['joint_name'] == 'DMSP-20-300' and cut_params['frame_id'] == 'dmsp_20_274'
    for name, entry in theirs['models'].items():
        got, want = (np.asarray(e.get('params', []), float) for e in (ours['models'][name], entry))
        assert np.all(np.abs(got - want) <= 1e-9 * np.abs(want)), name
    capsys.readouterr()
    for kappa in (0.02, 0.1, 0.2):
        forces = []
        for config, l0 in ((source, 0.3), (cut, 0.274)):
            argv = ['force', '--config', str(config), '--pressure', '4e5']
            assert main([*argv, '--length', repr((1 - kappa) * l0)]) == 0
            forces.append(float(capsys.readouterr().out.split()[1]))
        # printed to 6 digits
        assert forces[0] == pytest.approx(forces[1], rel=2e-6) and forces[0] > 0


def test_scale_refuses_an_existing_output_before_any_work(tmp_path, capsys):
    out = tmp_path / 'out.yaml'
    out.write_text('mine')
    config = str(CONFIGS['DMSP-20-300'])
    assert main(['scale', '--config', config, '--length', '0', '--out', str(out)]) == 2
    assert capsys.readouterr() == (
        '',
        f'pma-model: error: --out: {out} exists; not overwriting it (--overwrite overwrites)\n',
    )
    assert out.read_text() == 'mine'
    argv = ['scale', '--config', config, '--length', '0.5', '--out', str(out)]
    assert main([*argv, '--overwrite']) == 0
    assert read_parameters(out)['muscle']['name'] == 'DMSP-20-500'
    argv = ['scale', '--config', str(out), '--length', '0.4', '--out', str(out), '--overwrite']
    assert main(argv) == 2
    assert 'is an input of this command' in capsys.readouterr().err


@pytest.mark.parametrize(
    'length, message',
    [
        ('0', 'got 0.0'),
        ('-0.3', 'got -0.3'),
        ('nan', 'got nan'),
        ('0.01', 'got 0.01'),  # a 1 cm DMSP-20: no such cut
        ('274', 'got 274.0; mm? 274 mm = 0.274 m'),
        ('30', 'got 30.0; cm? 30 cm = 0.3 m'),  # nearer the source's 0.3 m than 30 mm
    ],
)
def test_scale_refuses_a_length_festo_does_not_cut(tmp_path, capsys, length, message):
    """The length is the user's, not the file's: named as --length, one line, no file."""
    out = tmp_path / 'out.yaml'
    config = CONFIGS['DMSP-20-300']
    assert main(['scale', '--config', str(config), '--length', length, '--out', str(out)]) == 2
    assert capsys.readouterr() == (
        '',
        f'pma-model: error: --length {float(length):g}: rest length must be in [0.04, 9] m (the '
        f'lengths Festo cuts a DMSP to), {message}\n',
    )
    assert not out.exists()


def test_scale_takes_the_given_rest_length_of_a_fit(tmp_path, capsys):
    """A fit's file with a calibrated L0 (0.305 m, given 0.3 m; the header as fit writes it, the
    key absent as in a file without it): --length is the new cut's measured rest length, the
    calibrated L0 moves by the same factor, and the output keeps the given length as its key.
    """
    text = CONFIGS['DMSP-20-300'].read_text()
    assert 'muscle: {name: DMSP-20-300, nominal_length: 0.3,' in text
    source, cut = tmp_path / 'fit.yaml', tmp_path / 'cut.yaml'
    source.write_text(
        '# DMSP-20-300 identified from map.csv by `pma-model fit` (geometry calibration ON; '
        'given nominal_length 0.3 m).\n'
        + text.replace('nominal_length: 0.3,', 'nominal_length: 0.305,', 1)
    )
    argv = ['scale', '--config', str(source), '--length', '0.398', '--out', str(cut)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert out.startswith(f'wrote {cut}: DMSP-20-398 (DMSP-20-300 x 1.32667: given L0 0.3 -> ')
    assert 'given L0 0.3 m read from the header' in out
    muscle = read_parameters(cut)['muscle']
    assert muscle['given_nominal_length'] == 0.398
    assert muscle['nominal_length'] == pytest.approx(0.305 * 0.398 / 0.3, rel=1e-11)


@pytest.mark.parametrize(
    'config, message',
    [
        ('example_multi_muscle.yaml', "a file with 'muscles:' has no one muscle to cut"),
        ('example_composed.yaml', "2 nodes in one file; scale one muscle's file"),
        ('example_joint.yaml', "a file with 'joints:' has no one muscle to cut"),
    ],
)
def test_scale_takes_one_muscle(tmp_path, capsys, config, message):
    path = REPO / 'config' / config
    argv = ['scale', '--config', str(path), '--length', '0.2', '--out', str(tmp_path / 'o.yaml')]
    assert main(argv) == 2
    assert capsys.readouterr().err.startswith(f'pma-model: error: {path}: {message}')
