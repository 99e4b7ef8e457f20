"""MuscleBank: many muscles in one vectorised call per model equal each muscle's own
MuscleModel.
"""

import numpy as np
import pytest

from conftest import CONFIGS, with_martens_end
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.models import MODELS
from pma_model_ros.core.physics.muscle_bank import MuscleBank


def shipped_muscles() -> list:
    """Every (muscle, model) pair the shipped configs identify (3 specs, 7 models), and Martens
    with an end factor (:func:`with_martens_end`).
    """
    muscles = []
    for path in CONFIGS.values():
        params = with_martens_end(read_parameters(path))
        muscles += [muscle_model(params, name) for name in params['models']]
    assert {m.model.name for m in muscles} == set(MODELS)
    return muscles


def random_inputs(muscles, rng, shape):
    """Gauge pressures [Pa], lengths [m] and rates [m/s] around and beyond each muscle's domain,
    with some invalid entries (NaN, lengths the geometry cannot take) and unknown rates.
    """
    lo = np.array([m.domain.length_min for m in muscles])
    top = np.array([m.max_length for m in muscles])
    p = rng.uniform(-0.1, 1.2, shape) * np.array([m.spec.max_pressure for m in muscles])
    L = rng.uniform(0.8 * lo, 1.05 * top, shape)
    rate = rng.choice([-0.1, 0.0, 0.2, np.nan], shape)
    p[rng.random(shape) < 0.05] = np.nan
    return p, L, rate


@pytest.mark.parametrize('shape', [(), (5,)], ids=['one cycle', 'five cycles'])
def test_bank_force_and_pressure_equal_each_muscle(shape):
    muscles = shipped_muscles()
    rng = np.random.default_rng(7)
    order = rng.permutation(len(muscles))  # groups interleaved in the bank
    muscles = [muscles[i] for i in order]
    bank = MuscleBank(muscles)
    assert len(bank.groups) == len(MODELS)
    p, L, rate = random_inputs(muscles, rng, shape + (len(muscles),))
    force = bank.force(p, L, rate)
    wanted = rng.uniform(-50, 1500, p.shape)
    pressure = bank.pressure(wanted, L, rate)
    for i, m in enumerate(muscles):
        rate_i = np.where(np.isnan(rate[..., i]), 0.0, rate[..., i])
        one = m.force(p[..., i], L[..., i], rate_i)
        np.testing.assert_allclose(
            force.force[..., i], one.force, rtol=1e-12, atol=1e-9, err_msg=m.model.name
        )
        np.testing.assert_allclose(
            force.raw[..., i], one.raw, rtol=1e-12, atol=1e-9, err_msg=m.model.name
        )
        np.testing.assert_array_equal(force.flags[..., i], one.flags, err_msg=m.model.name)
        inverse = m.pressure(wanted[..., i], L[..., i], rate_i)
        np.testing.assert_allclose(
            pressure.pressure[..., i],
            inverse.pressure,
            rtol=1e-12,
            atol=1e-6,
            err_msg=m.model.name,
        )
        np.testing.assert_array_equal(pressure.flags[..., i], inverse.flags, err_msg=m.model.name)
    assert np.isnan(force.force).any() and (force.flags != 0).any(), (
        'inputs missed the invalid cases'
    )


def test_homogeneous_bank_is_one_group_and_equals_the_muscle(martens_10_250):
    bank = MuscleBank([martens_10_250] * 64)
    assert len(bank.groups) == 1
    L = np.linspace(0.198, 0.25, 64)
    np.testing.assert_array_equal(bank.force(300e3, L).force, martens_10_250.force(300e3, L).force)


def test_bank_rejects_a_wrong_number_of_inputs(martens_10_250):
    with pytest.raises(ValueError, match='last axis of 3 muscles'):
        MuscleBank([martens_10_250] * 3).force(np.zeros(4), np.full(4, 0.23))
    with pytest.raises(ValueError, match='at least one muscle'):
        MuscleBank([])
