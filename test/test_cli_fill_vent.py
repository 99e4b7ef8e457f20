"""A two-branch fit of a fill/vent map through `pma-model fit`, the parameter file it writes,
`pma-model force --branch` and the estimation engine (cli/identify.py, cli/query.py,
core/files/param_writer.py, core/runtime/engine.py).

The map is made from Sárosi's published DMSP-10-100 branches (Tables 2 and 4): the filling points
(direction +1) on Table 4's branch, the venting points (-1) on Table 2's, so filling is the lower
branch, as an isometric rig measures it (friction holds the force back while the pressure rises).
"""

import math

import numpy as np
import pytest
import yaml

from conftest import CONFIGS
from pma_model_ros.cli.main import main
from pma_model_ros.core.files.param_file import node_engine, node_settings, read_parameters
from pma_model_ros.core.files.shipped_data import dmsp_10_100_hysteresis

AMBIENT = 101325.0
PRESSURES = np.linspace(1e5, 6e5, 6)
LENGTHS = np.array([0.1, 0.095, 0.09, 0.085, 0.08])
#: Table 4's branch (the published model's -1) fills, Table 2's (+1) vents
PUBLISHED = {1.0: -1.0, -1.0: 1.0}


def _map(tmp_path, c2: float | None = None):
    """The fill/vent CSV and the spec; ``c2``: the venting branch's exp(c2 kappa) rate instead
    of Table 2's (per unit contraction).
    """
    truth = dmsp_10_100_hysteresis()
    theta = truth.theta.copy()
    if c2 is not None:
        theta[2] = c2
        truth = type(truth)(truth.spec, truth.model, theta, truth.domain)
    p, L = (a.ravel() for a in np.meshgrid(PRESSURES, LENGTHS))
    rows = [
        (pi, Li, max(float(truth.force(pi, Li, PUBLISHED[d]).force), 0.0), d)
        for d in (1.0, -1.0)
        for pi, Li in zip(p, L)
    ]
    csv = tmp_path / 'fill_vent.csv'
    csv.write_text(
        'pressure_pa,length_m,force_n,direction\n'
        + ''.join(f'{a:.9g},{b:.9g},{c:.9g},{d:+.0f}\n' for a, b, c, d in rows)
    )
    spec = tmp_path / 'spec.yaml'
    spec.write_text(yaml.safe_dump(truth.spec.to_mapping()))
    return csv, spec, rows


def _fit(tmp_path, capsys, *extra, c2=None):
    csv, spec, rows = _map(tmp_path, c2)
    out = tmp_path / 'fit.yaml'
    argv = ['fit', '--data', str(csv), '--muscle', str(spec), '--model', 'sarosi_hysteresis']
    code = main([*argv, '--out', str(out), *extra])
    return code, capsys.readouterr(), out, rows


def _force(capsys, out, pressure, length, *extra) -> tuple[int, str]:
    argv = ['force', '--config', str(out), '--pressure', f'{pressure:.9g}']
    code = main([*argv, '--length', f'{length:.9g}', *extra])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_a_fill_vent_fit_serves_filling_where_the_pressure_rises(tmp_path, capsys):
    code, printed, out, rows = _fit(tmp_path, capsys, '--hysteresis-input', 'pressure')
    assert code == 0, printed.err
    parameters = read_parameters(out)
    assert parameters['hysteresis']['input'] == 'pressure'
    entry = parameters['models']['sarosi_hysteresis']
    max_force = max(r[2] for r in rows)
    tolerance = entry['err'] / 100 * max_force  # the fit's own eq. 23 on the map
    assert tolerance < 1e-3 * max_force  # the branches are Sárosi's model: fitted exactly
    pressure, length = 4e5, 0.09
    fill, vent = (
        next(r[2] for r in rows if r[:2] == (pressure, length) and r[3] == d) for d in (1.0, -1.0)
    )
    assert fill < vent - 10.0  # the map's filling branch is the lower one
    for name, measured in (('filling', fill), ('venting', vent)):
        code, text = _force(capsys, out, pressure, length, '--branch', name)
        assert code == 0, text
        served = float(text.split()[1])  # printed to 6 significant digits
        printed_digit = 0.5 * 10 ** (math.floor(math.log10(abs(served))) - 5)
        assert served == pytest.approx(measured, abs=tolerance + printed_digit), name
    assert 'filling is the lower branch' in printed.out
    # model_node's engine, from the file: the pressure rises at a held length, so it serves the
    # filling branch; then it vents
    engine = node_engine([node_settings(parameters)])
    engine.length(0, length, math.nan, 0, 0)
    for k, gauge in enumerate((1e5, 2e5, 3e5, pressure)):
        engine.pressure(0, AMBIENT + gauge, k * 10**7, k * 10**7)
    assert engine.forces.item(0) == pytest.approx(fill, abs=tolerance)
    for k, gauge in enumerate((5e5, 6e5, 5e5, pressure), 4):
        engine.pressure(0, AMBIENT + gauge, k * 10**7, k * 10**7)
    assert engine.forces.item(0) == pytest.approx(vent, abs=tolerance)


def test_a_map_with_directions_needs_what_they_follow(tmp_path, capsys):
    code, printed, out, _ = _fit(tmp_path, capsys)
    assert code == 2 and not out.exists()
    assert '--hysteresis-input' in printed.err and len(printed.err.strip().splitlines()) == 1


def test_force_refuses_a_branch_the_file_does_not_have(tmp_path, capsys):
    code, printed, out, _ = _fit(tmp_path, capsys, '--hysteresis-input', 'pressure')
    assert code == 0, printed.err
    for extra in (('--branch', 'lengthening'), ('--length-rate', '0.01')):
        code, text = _force(capsys, out, 4e5, 0.09, *extra)
        assert code == 2 and 'filling or venting' in text and len(text.strip().splitlines()) == 1
    code, text = _force(capsys, CONFIGS['DMSP-10-250'], 4e5, 0.23, '--branch', 'filling')
    assert code == 2 and 'no hysteresis branches' in text and len(text.strip().splitlines()) == 1


def test_the_fit_prints_the_layout_of_every_fit(tmp_path, capsys):
    code, printed, out, _ = _fit(tmp_path, capsys, '--hysteresis-input', 'pressure')
    assert code == 0, printed.err
    lines = printed.out.splitlines()
    assert any(line.split() == ['model', 'err', 'rmse', 'r2', 'held_out'] for line in lines)
    assert any(line.startswith('nested held-out err [%] per held-out length') for line in lines)
    entry = read_parameters(out)['models']['sarosi_hysteresis']
    assert lines[-1].startswith(
        f'default model (the one fitted): sarosi_hysteresis  err {entry["err"]:.3f} %'
    )
    assert 'not calibrated' in printed.out


def test_a_parameter_at_its_bound_is_named_with_what_it_means(tmp_path, capsys):
    # venting with exp(-400 kappa): gone 1 % of contraction beyond L0, past the bound -100
    code, printed, out, _ = _fit(tmp_path, capsys, '--hysteresis-input', 'pressure', c2=-400.0)
    assert code == 0, printed.err
    theta = read_parameters(out)['models']['sarosi_hysteresis']['params']
    assert theta[8] == -100.0  # venting's c2 (-1: the second six) at the search's bound
    said = [line for line in printed.out.splitlines() if 'at its bound' in line]
    assert len(said) == 1 and 'c2 (venting)' in said[0] and 'the longest row (0.1 m)' in said[0]
    header = [line for line in out.read_text().splitlines() if line.startswith('#')]
    assert any('c2 (venting)' in line and 'at its bound' in line for line in header)
    code, printed, out, _ = _fit(tmp_path, capsys, '--hysteresis-input', 'pressure', '--overwrite')
    assert code == 0 and 'at its bound' not in printed.out + out.read_text()


def test_a_one_branch_fit_names_a_parameter_at_its_bound(tmp_path, capsys):
    """Sárosi's one-branch model on Table 2's branch with exp(-400 kappa): c2 ends at the search's
    bound -100, and fit says so (its output and the file's header).
    """
    csv, spec, rows = _map(tmp_path, c2=-400.0)
    single = tmp_path / 'single.csv'
    single.write_text(
        'pressure_pa,length_m,force_n\n'
        + ''.join(f'{a:.9g},{b:.9g},{c:.9g}\n' for a, b, c, d in rows if d < 0)
    )
    out = tmp_path / 'fit.yaml'
    argv = ['fit', '--data', str(single), '--muscle', str(spec), '--model', 'sarosi']
    argv += ['--no-calibrate-length', '--no-calibrate-pressure', '--out', str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert read_parameters(out)['models']['sarosi']['params'][2] == -100.0
    said = [line for line in printed.splitlines() if 'at its bound' in line]
    assert len(said) == 1 and said[0].strip().startswith('sarosi: c2 at its bound -100: ')
    assert any('c2 at its bound -100' in line for line in out.read_text().splitlines())
