"""What is served outside the identified data (core/physics/muscle_model.py, Domain in
core/physics/models.py).

Judged on the measured maps themselves: a model is fitted without an edge length of a map, then
served at that left-out length.  Where it extrapolates credibly (Martens) its own value is far
nearer the measurement than the clamped value; where it does not (Sárosi's exponential at L0)
clamping is.  Not the nested protocol: each fit's objective is the one make-config chose with every
length included.
"""

from dataclasses import replace
import itertools

import numpy as np
import pytest

from conftest import CONFIGS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec
from pma_model_ros.core.identification.protocols import fit_best, max_error_percent
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.models import extrapolates, get_model
from pma_model_ros.core.physics.muscle_model import MuscleModel


def served_at_left_out(muscle: str, model: str, objective: str, edge: int, extrapolates: bool):
    """Fit ``model`` without the map's edge length (0: longest, -1: shortest); serve it there.

    Returns eq. 23 on the left-out points [%] and the flags served.
    """
    fmap, spec = shipped_force_map(muscle), shipped_spec(muscle)
    left_out = fmap.length == fmap.lengths[edge]
    fit = fit_best(get_model(model), spec, fmap.subset(~left_out), objective)
    served = MuscleModel(
        spec, get_model(model), fit.theta, replace(fit.domain, extrapolates=extrapolates)
    )
    result = served.force(fmap.pressure[left_out], fmap.length[left_out])
    return max_error_percent(fmap.force[left_out], result.force, fmap.max_force), result.flags


# Bounds for the default model with an edge length left out (9 % / 3 % of max force).
@pytest.mark.parametrize(
    'muscle, objective, target',
    [('DMSP-10-250', 'minimax', 9.0), ('DMSP-20-300', 'least_squares', 3.0)],
)
def test_martens_extrapolates_to_left_out_longest_length(muscle, objective, target):
    own, flags = served_at_left_out(muscle, 'martens', objective, 0, extrapolates=True)
    clamped, clamped_flags = served_at_left_out(
        muscle, 'martens', objective, 0, extrapolates=False
    )
    assert own <= target and own < clamped / 3
    assert np.all(flags & Flag.EXTRAPOLATED) and not np.any(flags & Flag.LENGTH_OUT_OF_RANGE)
    assert np.all(clamped_flags & Flag.LENGTH_OUT_OF_RANGE) and not np.any(
        clamped_flags & Flag.EXTRAPOLATED
    )


@pytest.mark.parametrize(
    'muscle, objective', [('DMSP-10-250', 'minimax'), ('DMSP-20-300', 'least_squares')]
)
def test_martens_extrapolates_to_left_out_shortest_length(muscle, objective):
    own, _ = served_at_left_out(muscle, 'martens', objective, -1, extrapolates=True)
    clamped, _ = served_at_left_out(muscle, 'martens', objective, -1, extrapolates=False)
    assert own <= 1.0 < clamped


def test_sarosi_does_not_extrapolate_to_l0():
    own, _ = served_at_left_out('DMSP-10-250', 'sarosi', 'minimax', 0, extrapolates=True)
    clamped, _ = served_at_left_out('DMSP-10-250', 'sarosi', 'minimax', 0, extrapolates=False)
    assert own > 10 * clamped > 10 and not extrapolates('sarosi')


def test_shipped_files_serve_each_model_by_its_rule():
    for muscle in ('DMSP-10-250', 'DMSP-20-300'):
        models = read_parameters(CONFIGS[muscle])['models']
        assert models['martens']['extrapolates'] and not models['sarosi']['extrapolates']
        for name, entry in models.items():
            assert entry['extrapolates'] == extrapolates(name)


def test_dmsp_20_300_at_nominal_length_and_675_kpa():
    """At L0 = 0.300 m the model's own 1620.7 N (not the 0.296 m 1446.8 N), flagged;
    the measured 675 kPa points are inside the identified data (served the 675 kPa force, not the
    600 kPa one).
    """
    m = muscle_model(read_parameters(CONFIGS['DMSP-20-300']))
    at_l0 = m.force(600e3, 0.300)
    assert (
        float(at_l0.force) == pytest.approx(1620.7, abs=0.1) and at_l0.flags == Flag.EXTRAPOLATED
    )
    measured = shipped_force_map('DMSP-20-300')
    top = (measured.pressure == 675e3) & (measured.length == 0.296)
    served = m.force(675e3, 0.296)
    assert served.flags == Flag.OK and float(served.force) == pytest.approx(
        float(measured.force[top][0]), rel=0.02
    )
    rated = m.spec.max_pressure  # never commands above the rated 6 bar
    assert float(m.pressure(1e6, 0.296).pressure) == rated


def test_dmsp_10_250_above_its_map():
    """The map stops at 650 kPa; 800 kPa at L0 is the model's own 639.6 N, flagged
    EXTRAPOLATED.
    """
    m = muscle_model(read_parameters(CONFIGS['DMSP-10-250']))
    assert m.force(650e3, 0.25).flags == Flag.OK
    above = m.force(800e3, 0.25)
    assert float(above.force) == pytest.approx(639.6, abs=0.1) and above.flags == Flag.EXTRAPOLATED
    sarosi = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'sarosi')
    held = sarosi.force(800e3, 0.25)
    assert held.flags == Flag.PRESSURE_OUT_OF_RANGE and float(held.force) == float(
        sarosi.force(650e3, 0.25).force
    )


def test_envelope_ends_at_the_braids_shortest_length_and_l0(martens_10_250):
    m = martens_10_250
    shortest = m.spec.nominal_length / np.cos(m.spec.fiber_angle) / np.sqrt(3)  # Theta = 54.7 deg
    assert (
        m.limits.length_low == pytest.approx(shortest, rel=1e-12) and m.limits.length_high == 0.25
    )
    below = m.force(3e5, shortest * 0.9)
    assert below.flags & Flag.LENGTH_OUT_OF_RANGE
    assert float(below.raw) == float(m.force(3e5, shortest).raw)
    assert m.force(3e5, 0.26).flags & Flag.LENGTH_OUT_OF_RANGE


@pytest.mark.parametrize('path', sorted(CONFIGS.values()), ids=lambda p: p.stem)
def test_lengths_served_as_identified_take_the_same_values_as_the_clamping_path(path):
    """operating() of lengths that all lie in every muscle's identified and served lengths skips
    the clamping and flagging (the usual message): it gives what the full path gives for the same
    lengths, reached by adding one length outside (flags, usable and coefficients bit for bit).
    Lengths drawn in the identified range take the short path; drawn in the whole range served
    (EXTRAPOLATED outside the identified one, where the model extrapolates), mostly not.
    """
    parameters = read_parameters(path)
    rng = np.random.default_rng(7)
    for name in parameters['models']:
        m = muscle_model(parameters, name)
        lim = m.limits
        ranges = ((m.domain.length_min, m.domain.length_max), (lim.length_low, lim.length_high))
        for (low, high), valid in itertools.product(ranges, (True, False)):
            inside = rng.uniform(low, high, 12)
            for rate in (None, np.sign(rng.normal(size=13))):
                alone = m.operating(inside, None if rate is None else rate[:12], valid)
                if (low, high) == ranges[0] and not valid:  # the short path was taken: its
                    assert np.ndim(alone.usable) == 0  # usable is one True, the full path's not
                beside = m.operating(np.r_[inside, lim.length_high + 0.001], rate, valid)
                assert beside.flags[-1] != 0  # the full path: the last length is flagged
                for field in ('flags', 'q2', 'q1', 'q0'):
                    want = np.broadcast_to(getattr(beside, field), (13,))[:12]
                    got = np.broadcast_to(getattr(alone, field), (12,))
                    assert np.array_equal(got, want), (name, field)
                assert np.all(np.broadcast_to(beside.usable, (13,))[:12]) and np.all(alone.usable)
