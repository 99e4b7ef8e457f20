"""Geometry calibration: the pressure shift by hand, files and muscles that apply it, and
identification on the shipped maps degraded the way a user's are.
"""

from dataclasses import replace
import functools
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pma_model_ros.core.files.param_file import muscle_model
from pma_model_ros.core.files.param_writer import build_parameters, fit_entry
from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec
from pma_model_ros.core.identification import calibration as cal
from pma_model_ros.core.identification.calibration import Calibration, OFF
from pma_model_ros.core.identification.force_map import ForceMap
from pma_model_ros.core.identification.protocols import domain_of, fit_best, max_error_percent
from pma_model_ros.core.identification.selection import identify_all
from pma_model_ros.core.physics.models import force_raw, get_model, MODELS
from pma_model_ros.core.physics.muscle_bank import MuscleBank

MARTENS = get_model('martens')


@pytest.mark.parametrize('name', ['andrikopoulos', 'wickramatunge', 'sarosi', 'martens'])
def test_shifted_model_is_the_model_at_the_true_pressure(name):
    model, spec, fmap = (
        get_model(name),
        shipped_spec('DMSP-20-300'),
        shipped_force_map('DMSP-20-300'),
    )
    theta = (
        np.array(model.start, float)
        if name != 'martens'
        else np.array([7e8, -8e9, 3e10, -3.6e10, -0.07])
    )
    offset = 12e3
    sensor = fmap.pressure + offset
    shifted = force_raw(
        cal.shifted(model), np.r_[theta, offset], spec, domain_of(fmap), sensor, fmap.length
    )
    assert shifted == pytest.approx(
        force_raw(model, theta, spec, domain_of(fmap), fmap.pressure, fmap.length),
        rel=1e-9,
        abs=1e-9 * np.abs(shifted).max(),
    )


def test_parameter_file_applies_length_and_offset_for_force_inverse_and_bank():
    spec, fmap = shipped_spec('DMSP-20-300'), shipped_force_map('DMSP-20-300')
    fit = fit_best(MARTENS, spec, fmap)
    calibrated = replace(
        fit,
        spec=replace(spec, nominal_length=0.302),
        calibration=Calibration(),
        pressure_offset=8e3,
    )
    entry = fit_entry(calibrated)
    assert entry['nominal_length'] == 0.302 and entry['pressure_offset'] == 8e3
    muscle = muscle_model(
        build_parameters(spec, 'martens', fit.domain, {'martens': entry})['/**']['ros__parameters']
    )
    assert muscle.spec.nominal_length == 0.302
    assert muscle.max_length == pytest.approx(0.302 / np.cos(spec.fiber_angle))  # eq. 3, new L0
    # the sensor reads 8 kPa more than the muscle sees: the model at (p - 8 kPa), by hand from the
    # coefficients
    p, L = 308e3, 0.26
    q2, q1, q0 = MARTENS.coefficients(
        fit.theta, replace(spec, nominal_length=0.302), fit.domain, L, 0.0
    )
    assert float(muscle.force(p, L).force) == pytest.approx(
        (q2 * 300e3 + q1) * 300e3 + q0, rel=1e-8
    )
    assert float(muscle.pressure(float(muscle.force(p, L).force), L).pressure) == pytest.approx(
        p, rel=1e-9
    )
    plain = muscle_model(
        build_parameters(spec, 'martens', fit.domain, {'martens': fit_entry(fit)})['/**'][
            'ros__parameters'
        ]
    )
    bank = MuscleBank([muscle, plain, muscle])
    assert len(bank.groups) == 2
    assert bank.force(np.full(3, p), np.full(3, L)).force == pytest.approx(
        [float(m.force(p, L).force) for m in (muscle, plain, muscle)], rel=1e-12
    )


def test_offset_and_length_recovered_where_the_model_identifies_them():
    """The McKibben model (eq. 17) has no parameters: on its own forces with a +10 kPa sensor
    offset (every row slack below 10 kPa) and the true L0, the offset is identified exactly; with
    L0 given 8 mm short (shorter than the 0.296 m row), L0 is found within 2 mm (the search does
    not model the offset), then the offset.
    """
    model, truth_spec = MODELS['mckibben'], shipped_spec('DMSP-20-300')
    grid = shipped_force_map('DMSP-20-300')

    def forces(offset: float) -> ForceMap:
        raw = force_raw(
            model, np.zeros(0), truth_spec, domain_of(grid), grid.pressure, grid.length
        )
        return ForceMap(grid.pressure + offset, grid.length, np.maximum(raw, 0))

    exact = fit_best(model, truth_spec, forces(10e3), calibration=Calibration())
    assert exact.calibration == Calibration(False, True) and exact.slack_length == 0.296
    assert exact.pressure_offset == pytest.approx(10e3, abs=1.0)
    assert exact.spec.nominal_length == 0.300 and 'nominal_length' not in exact.sigma
    short = replace(truth_spec, nominal_length=0.292)
    fit = fit_best(model, short, forces(10e3), calibration=Calibration(True, False))
    assert fit.calibration == Calibration(True, False)
    assert abs(fit.spec.nominal_length - 0.300) < 2e-3
    assert exact.err < fit.err


def test_a_quantity_the_model_does_not_depend_on_is_reported_not_identifiable():
    """Hildebrandt (eq. 20) has no L0, and its counter-force polynomial absorbs a pressure offset
    (q1 o is a quadratic in L): the offset stays 0 and L0, given shorter than the slack 0.296 m
    row, is raised to that row (a muscle is not stretched) and searched no further.
    """
    spec = replace(shipped_spec('DMSP-20-300'), nominal_length=0.29)
    fit = fit_best(
        get_model('hildebrandt'), spec, shipped_force_map('DMSP-20-300'), calibration=Calibration()
    )
    assert fit.calibration == Calibration(pressure=False) and fit.pressure_offset == 0.0
    assert fit.sigma['nominal_length'] == np.inf
    assert fit.sigma['pressure_offset'] > cal.PRESSURE_BOUND / 4
    assert fit.spec == replace(spec, nominal_length=0.296)


def test_slack_length_is_where_the_force_line_meets_zero_above_0_pa():
    """Table A1's 0.296 m row meets zero near 42 kPa (the longest slack length), Table A2's 0.250 m
    row near 37 kPa; a row that pulls at 0 Pa (a stretched muscle) is not slack.
    """
    assert cal.slack_length(shipped_force_map('DMSP-20-300')) == 0.296
    assert cal.slack_length(shipped_force_map('DMSP-10-250')) == 0.25
    p = np.linspace(0, 6e5, 7)
    stretched = ForceMap(
        np.r_[p, p],
        np.r_[[0.31] * 7, [0.29] * 7],
        np.r_[100 + 2e-3 * p, 2e-3 * np.maximum(p - 5e4, 0)],
    )
    assert cal.slack_length(stretched) == 0.29
    assert cal.slack_length(stretched.subset(stretched.length == 0.31)) is None


# --- the shipped maps degraded like a user's: L0 given wrong, +10 kPa offset, 1 % noise, a length
# missing ---
TRUE_OFFSET, NOISE, SEED = 10e3, 0.01, 7


def degraded(muscle: str, dl: float) -> tuple:
    """(spec given, the user's map, the true forces at its points)."""
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    keep = fmap.length != fmap.lengths[2]
    noisy = fmap.force + np.random.default_rng(SEED).normal(
        0, NOISE * fmap.max_force, fmap.force.size
    )
    user = ForceMap(
        fmap.pressure[keep] + TRUE_OFFSET, fmap.length[keep], np.maximum(noisy[keep], 0)
    )
    return replace(spec, nominal_length=spec.nominal_length + dl), user, fmap.force[keep]


def nested(spec, fmap, calibration, truth=None) -> np.ndarray:
    """Martens' nested held-out err per length [%] (least squares, the calibration re-run without
    each length).
    """
    return identify_all(spec, fmap, (MARTENS,), calibration, ('least_squares',), truth).held_out


@functools.cache
def clean(muscle: str) -> tuple[float, np.ndarray]:
    """In-sample err and held-out err per length [%] of the uncalibrated least-squares fit with
    the paper's geometry.
    """
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    return fit_best(MARTENS, spec, fmap).err, nested(spec, fmap, OFF)


@pytest.mark.parametrize('muscle', ['DMSP-20-300', 'DMSP-10-250'])
def test_l0_given_too_short_is_recovered_where_the_map_has_rows_near_it(muscle):
    """L0 given 6 mm short of the truth, so shorter than the map's longest (slack) length: L0 is
    found within 2 mm and the in-sample err against the true forces is within 0.5 pp of the clean
    fit's.  Held out (nested), every length but the longest errs less than uncalibrated; the
    longest is predicted without the rows that prove L0 wrong, so with the given L0.
    """
    spec, user, truth = degraded(muscle, -0.006)
    fit = fit_best(MARTENS, spec, user, calibration=Calibration())
    # Table A2's effective L0 for Martens is 0.2517 m (the clean map's own, docs/calibration.md)
    assert (
        fit.calibration.length
        and abs(fit.spec.nominal_length - (spec.nominal_length + 0.006)) <= 2e-3
    )
    clean_in, _ = clean(muscle)
    in_sample = max_error_percent(truth, fit.force(user.pressure, user.length), truth.max())
    assert in_sample <= clean_in + 0.5
    held_out, plain = (nested(spec, user, c, truth) for c in (Calibration(), OFF))
    assert np.all(held_out[1:] <= plain[1:] + 0.05) and held_out[1:].max() < plain[1:].max() / 2
    assert held_out[0] == pytest.approx(plain[0])


@pytest.mark.parametrize(
    ('muscle', 'given'), [('DMSP-10-250', 0.24), ('DMSP-20-300', 0.29), ('DMSP-20-300', 0.2959)]
)
def test_l0_given_shorter_than_a_measured_row_is_raised_to_it(muscle, given):
    """A muscle is not stretched: L0 given 1 cm (or 0.1 mm) short of the map's longest row (Table
    A2: 0.250 m, Table A1: 0.296 m) ends at least there, whatever the pressure offset does.  Raised
    to exactly the row, the fit is the one of the paper's L0 when that equals the row (Table A2).
    """
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    short = replace(spec, nominal_length=given)
    for calibration in (Calibration(), Calibration(pressure=False)):
        fit = fit_best(MARTENS, short, fmap, calibration=calibration)
        assert fit.calibration.length and fit.spec.nominal_length >= fmap.lengths[0]
    assert cal.short_of_map(short, fmap) == fmap.lengths[0]
    assert cal.short_of_map(replace(spec, nominal_length=fmap.lengths[0]), fmap) is None
    if spec.nominal_length == fmap.lengths[0]:
        paper = fit_best(MARTENS, spec, fmap, calibration=Calibration())
        raised = fit_best(MARTENS, short, fmap, calibration=Calibration())
        assert raised.spec == paper.spec and raised.theta == pytest.approx(paper.theta, rel=1e-12)


def test_a_slack_row_of_cell_means_reaches_one_cell_above_its_length():
    """Table A1's longest row, 0.296 m, is slack.  With L0 given 0.2963 m, a measured row proves
    nothing (0.296 < 0.2963 m: L0 kept); the same row as cell means (``length_cell`` 0.5 mm, as
    ``fit --bag`` and live re-identification make them) holds samples up to 0.2965 m, so L0 may be
    shorter than the slack samples and is searched above the row, as for a given L0 at the row.
    """
    spec, fmap = shipped_spec('DMSP-20-300'), shipped_force_map('DMSP-20-300')
    given = replace(spec, nominal_length=0.2963)
    measured = fit_best(MARTENS, given, fmap, calibration=Calibration(True, False))
    assert not measured.calibration.length and measured.spec.nominal_length == 0.2963
    cells = replace(fmap, length_cell=0.5e-3)
    fit = fit_best(MARTENS, given, cells, calibration=Calibration(True, False))
    assert fit.calibration.length and fit.spec.nominal_length > 0.296


@pytest.mark.parametrize('muscle', ['DMSP-20-300', 'DMSP-10-250'])
def test_l0_given_too_long_is_kept_and_said_so(muscle):
    """L0 given 8 mm too long: nothing in the map proves it wrong (every row may be contracted), so
    it is kept, and the fit reports the slack length that bounds it.
    """
    spec, user, _ = degraded(muscle, +0.008)
    fit = fit_best(MARTENS, spec, user, calibration=Calibration())
    assert not fit.calibration.length and fit.spec.nominal_length == spec.nominal_length
    assert fit.slack_length == user.lengths[0] < spec.nominal_length


@pytest.mark.parametrize('muscle', ['DMSP-20-300', 'DMSP-10-250'])
def test_calibration_with_the_true_geometry_never_hurts_held_out(muscle):
    """With the paper's geometry, the worst nested held-out err of the calibrated fit is no worse
    than the uncalibrated one's (0.05 pp); in-sample no worse either.
    """
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    clean_in, clean_out = clean(muscle)
    assert nested(spec, fmap, Calibration()).max() <= clean_out.max() + 0.05
    assert fit_best(MARTENS, spec, fmap, calibration=Calibration()).err <= clean_in


@pytest.mark.parametrize('muscle', ['DMSP-20-300', 'DMSP-10-250'])
def test_the_chosen_geometry_stays_put_when_the_data_move_by_1e_9(muscle):
    """Relative perturbations of 1e-9 of every force (far below any measurement) leave the
    calibration decisions and the identified L0 and offset where they were (L0 to 1 um, offset to
    1 Pa), for the true geometry and for L0 given too short.
    """
    rng = np.random.default_rng(11)
    for dl in (0.0, -0.006):
        spec, user, _ = degraded(muscle, dl)
        base = fit_best(MARTENS, spec, user, calibration=Calibration())
        for _ in range(2):
            moved = ForceMap(
                user.pressure,
                user.length,
                user.force * (1 + 1e-9 * rng.standard_normal(user.force.size)),
            )
            fit = fit_best(MARTENS, spec, moved, calibration=Calibration())
            assert fit.calibration == base.calibration
            assert fit.spec.nominal_length == pytest.approx(base.spec.nominal_length, abs=1e-6)
            assert fit.pressure_offset == pytest.approx(base.pressure_offset, abs=1.0)


def test_the_fit_does_not_depend_on_blas_threads():
    """The same calibrated fit of Table A2 (offset identified, L0 searched then kept) with
    OpenBLAS on 1 and on 2 threads, in fresh processes: the same geometry and parameters to 1e-12.
    """
    script = (
        'from pma_model_ros.core.identification.protocols import fit_best\n'
        'from pma_model_ros.core.identification.calibration import Calibration\n'
        'from pma_model_ros.core.physics.models import get_model\n'
        'from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec\n'
        "m = 'DMSP-10-250'\n"
        "f = fit_best(get_model('martens'), shipped_spec(m), shipped_force_map(m), "
        'calibration=Calibration())\n'
        'import json\n'
        'print(json.dumps([*f.theta.tolist(), f.pressure_offset, f.spec.nominal_length]))\n'
    )
    runs = [
        subprocess.run(
            [sys.executable, '-c', script],
            env=os.environ | {'OPENBLAS_NUM_THREADS': threads},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for threads in ('1', '2')
    ]
    one, two = (np.array(json.loads(run)) for run in runs)
    assert one == pytest.approx(two, rel=1e-12, abs=0)
    assert one[-2] == pytest.approx(39.7e3, abs=1e3)  # the threshold at L0, 39.7 kPa
