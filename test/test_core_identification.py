"""Identification: the paper's Table 3, our best fits, nested held-out errors, shipped configs."""

import json
import math
import os
import platform
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import CONFIGS
from pma_model_ros.cli.identify import identify_muscle, PAPER_TABLE3
from pma_model_ros.cli.main import main
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import (
    dmsp_10_100_hysteresis,
    MAPPED_MUSCLES,
    shipped_force_map,
)
from pma_model_ros.core.identification.selection import _environment, _WORKER_ENVIRONMENT

#: Table 3's models (the paper's order aside).
TABLE3_MODELS = {'mckibben', 'andrikopoulos', 'wickramatunge', 'hildebrandt', 'sarosi', 'martens'}
FITTED = ('andrikopoulos', 'wickramatunge', 'hildebrandt', 'sarosi', 'martens')


@pytest.fixture(scope='module')
def results():
    return {m: identify_muscle(m) for m in MAPPED_MUSCLES}


def test_paper_protocol_reproduces_table3(results):
    misses = []
    for muscle, found in results.items():
        for name, rep in found.reports.items():
            if abs(rep.paper.err - PAPER_TABLE3[muscle][name]) > 0.05:
                misses.append((muscle, name, round(rep.paper.err, 2)))
    # One entry does not reproduce (docs/models.md: fminsearch stops at MaxFunEvals
    # mid-descent): 7.39 % vs 5.1 %.
    assert misses == [('DMSP-10-250', 'sarosi', 7.39)]


def test_paper_protocol_finds_table2(results):
    table2 = {
        'DMSP-10-250': [74.085e6, -689.20e6, 1.8370e9, -848.79e6],
        'DMSP-20-300': [93.232e6, -715.29e6, 1.5483e9, -502.95e6],
    }
    for muscle, expected in table2.items():
        theta = results[muscle].reports['martens'].paper.theta
        assert theta[:4] == pytest.approx(expected, rel=2e-4)
    assert math.degrees(results['DMSP-20-300'].reports['martens'].paper.theta[4]) == pytest.approx(
        -4.18, abs=0.01
    )
    # Table 2 prints -5.73 deg for the DMSP-10-250; the fit lands at -5.87 deg (docs/models.md).
    assert math.degrees(results['DMSP-10-250'].reports['martens'].paper.theta[4]) == pytest.approx(
        -5.87, abs=0.01
    )


def test_best_is_at_or_below_the_paper_for_every_fitted_model(results):
    for muscle, found in results.items():
        for name in FITTED:
            assert found.reports[name].best_err <= PAPER_TABLE3[muscle][name], (muscle, name)
            for fit in found.reports[name].best.values():
                assert fit.r2 > 0.9 and fit.rmse > 0


def test_held_out_figures_are_nested_and_the_default_is_the_selection(results):
    """The default is the (model, objective) with the lowest worst leave-one-length-out err; each
    report's figure is nested (the objective chosen again without each length), and so is the
    default's (the model chosen again): never below what the choice inside each fold gets.
    """
    # regression bounds, as measured at this commit (docs/calibration.md): the 0.250 m row of
    # Table A2 is the rest length, which no other row predicts better than ~8.8 %
    limits = {'DMSP-10-250': 10.5, 'DMSP-20-300': 3.1}
    for muscle, found in results.items():
        reports = found.reports
        worst = {
            (name, obj): float(rep.cv[obj].max())
            for name, rep in reports.items()
            for obj in rep.cv
        }
        assert found.default == min(worst, key=worst.get)[0]
        n = {'DMSP-10-250': 5, 'DMSP-20-300': 6}[muscle]
        assert (
            len(found.held_out) == len(found.chosen) == n == shipped_force_map(muscle).lengths.size
        )
        for k, name in enumerate(found.chosen):
            rep = reports[name]
            # the fold's figure is one of its candidate's leave-one-length-out errors on that fold
            assert any(found.held_out[k] == rep.cv[obj][k] for obj in rep.cv)
        assert found.held_out.max() <= limits[muscle], (muscle, found.held_out)


def test_held_out_edge_figure_is_what_is_served_there(results):
    """A model served held beyond its identified lengths (Sárosi: not extrapolated) is judged at a
    left-out edge by the value it serves there: the force at the nearest identified length.  On
    Table A2 without its 0.250 m row that is the 0.234 m row's force, which Sárosi fits to about
    1 % of the max force; at 650 kPa Table A2 measured 542.5 N at 0.250 m and 282.83 N at 0.234 m,
    so the held-out err at 0.250 m is about 100 (542.5 - 282.83) / 542.5 = 47.9 %, not the
    exponential's own extrapolation (over 1000 %).  Martens, served extrapolated, is judged by its
    own value there (below 10 %, docs/models.md).
    """
    reports = results['DMSP-10-250'].reports
    hand = 100 * (542.5 - 282.8333) / 542.5
    assert reports['sarosi'].nested[0] == pytest.approx(hand, abs=1.0)
    assert reports['sarosi'].edge_cv_err == pytest.approx(hand, abs=1.0)
    assert reports['martens'].edge_cv_err < 10 < hand
    for rep in reports.values():
        inner = rep.nested[1:-1]
        assert rep.interior_cv_err == inner.max() and rep.cv_err == rep.nested.max()


def test_two_branch_model_from_a_map_with_directions(tmp_path, capsys):
    """Sárosi's published DMSP-10-100 branches (Tables 2 and 4) sampled on 0-600 kPa x 0-25 %
    contraction with their direction; fitting sarosi_hysteresis to that CSV gives both branches
    back (0.5 % of max force).
    """
    truth = dmsp_10_100_hysteresis()
    p, L = np.meshgrid(np.linspace(0, 6e5, 7), np.linspace(0.075, 0.1, 6))
    rows = [
        (pi, Li, float(truth.force(pi, Li, d).force), d)
        for d in (1.0, -1.0)
        for pi, Li in zip(p.ravel(), L.ravel())
    ]
    csv = tmp_path / 'map.csv'
    csv.write_text(
        'pressure_pa,length_m,force_n,direction\n'
        + ''.join(f'{a},{b},{c},{d:+.0f}\n' for a, b, c, d in rows)
    )
    spec = tmp_path / 'spec.yaml'
    spec.write_text(yaml.safe_dump(truth.spec.to_mapping()))
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
                'sarosi_hysteresis',
                '--hysteresis-input',
                'length',
                '--out',
                str(out),
            ]
        )
        == 0
    )
    fitted = muscle_model(read_parameters(out))
    forces = np.array([r[2] for r in rows])
    # held out, each point on its branch: Sarosi's branches are served held beyond the identified
    # lengths, so without 0.1 m (0.075 m) the fit serves the 0.095 m (0.08 m) force there, which
    # the published branches give by hand; between them it interpolates the exact branches
    entry = read_parameters(out)['models']['sarosi_hysteresis']
    lengths = np.linspace(0.075, 0.1, 6)
    pressures = np.linspace(0, 6e5, 7)

    def held_edge(edge: float, served: float) -> float:
        return max(
            float(
                np.max(
                    np.abs(
                        truth.force(pressures, edge, d).force
                        - truth.force(pressures, served, d).force
                    )
                )
            )
            for d in (1.0, -1.0)
        )

    hand = 100 * max(held_edge(0.1, 0.095), held_edge(0.075, 0.08)) / forces.max()
    assert entry['held_out']['lengths'] == pytest.approx(lengths[::-1])
    assert entry['edge_cv_err'] == pytest.approx(hand, abs=0.5)
    assert entry['interior_cv_err'] < 0.5 and entry['extrapolates'] is False
    last = capsys.readouterr().out.splitlines()[-1]
    assert (
        last.startswith('default model (the one fitted): sarosi_hysteresis  err ')
        and (
            f'held-out worst {entry["cv_err"]:.2f} % (between measured lengths '
            f'{entry["interior_cv_err"]:.2f} %, beyond them {entry["edge_cv_err"]:.2f} %)'
        )
        in last
    )
    for d in (1.0, -1.0):
        got = fitted.force(p.ravel(), L.ravel(), d).force
        assert (
            np.max(np.abs(got - truth.force(p.ravel(), L.ravel(), d).force)) <= 5e-3 * forces.max()
        ), d
    single = tmp_path / 'single.csv'
    single.write_text(
        'pressure_pa,length_m,force_n\n' + ''.join(f'{a},{b},{c}\n' for a, b, c, _ in rows)
    )
    argv = ['fit', '--data', str(single), '--muscle', str(spec), '--model', 'sarosi_hysteresis']
    argv += ['--hysteresis-input', 'length']
    assert main([*argv, '--out', str(out)]) == 2  # no direction column: one line, exit 2


def test_worker_environment_is_set_for_the_workers_only(monkeypatch):
    """The workers' OpenBLAS setting is in ``os.environ`` while the pool starts them, a user's own
    value is kept, and the caller's environment is as before afterwards.
    """
    monkeypatch.delenv('OPENBLAS_THREAD_TIMEOUT', raising=False)
    with _environment(_WORKER_ENVIRONMENT):
        assert os.environ['OPENBLAS_THREAD_TIMEOUT'] == '4'
    assert 'OPENBLAS_THREAD_TIMEOUT' not in os.environ
    monkeypatch.setenv('OPENBLAS_THREAD_TIMEOUT', '20')
    with _environment(_WORKER_ENVIRONMENT):
        assert os.environ['OPENBLAS_THREAD_TIMEOUT'] == '20'
    assert os.environ['OPENBLAS_THREAD_TIMEOUT'] == '20'


def test_reproduce_json(capsys):
    assert main(['reproduce', '--json']) == 0
    table = json.loads(capsys.readouterr().out)['table3']
    assert set(table) == {'DMSP-10-250', 'DMSP-20-300'}
    for muscle, rows in table.items():
        assert rows['default'] == 'martens'
        assert set(rows) - {'default', 'held_out'} == TABLE3_MODELS
        # the default's nested figure, model choice included, is a figure of one of the models
        assert any(rows[m]['cv'] <= rows['held_out'] + 1e-9 for m in TABLE3_MODELS)
        for row in (rows[m] for m in TABLE3_MODELS):
            assert set(row) == {'paper', 'paper_protocol', 'best', 'cv'}
            assert row['best'] <= row['paper'] + 0.05
    assert table['DMSP-20-300']['martens']['paper_protocol'] == pytest.approx(2.35, abs=0.05)


#: A number in a parameter file (YAML plain scalar).
NUMBER = re.compile(r'-?\d+(?:\.\d*)?(?:e[-+]?\d+)?')


def assert_same_config(fresh: str, committed: str, muscle: str) -> None:
    """``fresh`` (a make-config output) is ``committed``, but for the rounding of the numbers.

    Every character outside the numbers is equal (keys, order, models, objectives, verdicts,
    comments).  Each identified model's ``params`` serve the same force on the map to 1e-6 of its
    max force (without a map, DMSP-10-100's published parameters: equal to 1e-5); every other
    number is equal to 1e-5 (relative).  Measured between OpenBLAS kernels
    (Haswell, SkylakeX, Prescott) and numpy's SIMD paths (AVX-512 or not): statistics to 3e-6,
    parameters to 1e-4 where the map hardly determines one (Sárosi's c0 on Table A1), served forces
    to 1e-9 of the max force.
    """
    assert NUMBER.sub('#', fresh) == NUMBER.sub('#', committed)
    ours, theirs = (yaml.safe_load(text)['/**']['ros__parameters'] for text in (fresh, committed))
    fmap = shipped_force_map(muscle) if muscle in ('DMSP-10-250', 'DMSP-20-300') else None
    for name, entry in theirs['models'].items():
        if fmap is not None and 'params' in entry:
            served = [
                muscle_model(p, name).force(fmap.pressure, fmap.length).force
                for p in (ours, theirs)
            ]
            assert np.max(np.abs(served[0] - served[1])) <= 1e-6 * fmap.max_force, name
    numbers = [  # params compared by their forces above, where there is a map
        [
            float(x)
            for x in NUMBER.findall(
                text if fmap is None else re.sub(r'params: \[[^]]*\]', '', text)
            )
        ]
        for text in (fresh, committed)
    ]
    assert numbers[0] == pytest.approx(numbers[1], rel=1e-5, abs=1e-12)


@pytest.mark.parametrize('muscle', list(CONFIGS))
def test_make_config_writes_the_shipped_config(tmp_path, muscle):
    """config/*.yaml are what make-config writes (identification is cached, :func:`results`:
    this costs a file write), to the rounding of :func:`assert_same_config`.
    """
    out = tmp_path / 'config.yaml'
    assert main(['make-config', muscle, '--out', str(out)]) == 0
    assert_same_config(out.read_text(), CONFIGS[muscle].read_text(), muscle)


#: OpenBLAS kernels that every CPU of the architecture runs (the default picks the CPU's own).
PORTABLE_KERNEL = {'x86_64': 'Prescott', 'aarch64': 'ARMV8'}


@pytest.mark.skipif(platform.machine() not in PORTABLE_KERNEL, reason='no portable kernel known')
def test_make_config_does_not_depend_on_the_cpu_kernels(tmp_path):
    """make-config in fresh processes with OpenBLAS's most portable kernels (SSE3 on x86-64) writes
    the shipped configs, to the rounding of :func:`assert_same_config`: no choice of L0, offset,
    objective or model hops with the kernels (the shipped files were written with another).
    """
    env = os.environ | {'OPENBLAS_CORETYPE': PORTABLE_KERNEL[platform.machine()]}
    runs = {
        muscle: subprocess.Popen(
            [
                sys.executable,
                '-m',
                'pma_model_ros.cli',
                'make-config',
                muscle,
                '--out',
                str(tmp_path / f'{muscle}.yaml'),
            ],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for muscle in ('DMSP-10-250', 'DMSP-20-300')
    }
    for muscle, run in runs.items():
        assert run.wait(timeout=300) == 0, run.stderr.read()
        assert_same_config(
            (tmp_path / f'{muscle}.yaml').read_text(), CONFIGS[muscle].read_text(), muscle
        )
