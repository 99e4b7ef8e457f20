"""Inverse pressure-from-force: round trips, saturation, pull start."""
import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

from conftest import CONFIGS
from pma_model_ros.core.flags import Flag
from pma_model_ros.core.param_file import muscle_model, read_parameters

MUSCLES = [muscle_model(read_parameters(path), name)
           for path in CONFIGS.values() for name in read_parameters(path)["models"]]
IDS = [f"{m.spec.name}-{m.model.name}" for m in MUSCLES]


@settings(max_examples=3000, deadline=None)
@given(st.sampled_from(MUSCLES), st.floats(0, 1), st.floats(0, 1), st.sampled_from([-0.01, 0.0, 0.01]))
def test_round_trip_force_pressure_force(muscle, u_p, u_L, rate):
    """Over the valid domain (the muscle pulls and pulls harder with pressure): 1e-9 relative."""
    p = u_p * muscle.spec.max_pressure
    L = muscle.domain.length_min + u_L * (min(muscle.domain.length_max, muscle.spec.nominal_length)
                                          - muscle.domain.length_min)
    forward = muscle.force(p, L, rate)
    q2, q1, _ = muscle.model.coefficients(muscle.theta, muscle.spec, muscle.domain, np.asarray(L), np.sign(rate))
    assume(float(forward.raw) > 1e-3 and float(q1 + 2 * q2 * p) > 0)
    back = muscle.pressure(forward.force, L, rate)
    assert not back.flags & (Flag.SATURATED | Flag.INVALID_INPUT)
    again = muscle.force(back.pressure, L, rate)
    assert float(again.force) == pytest.approx(float(forward.force), rel=1e-9)


@pytest.mark.parametrize("muscle", MUSCLES, ids=IDS)
def test_saturation_and_pull_start(muscle):
    L = (muscle.domain.length_min + min(muscle.domain.length_max, muscle.spec.nominal_length)) / 2
    top = float(muscle.force(muscle.spec.max_pressure, L).force)
    too_much = muscle.pressure(top * 1.5 + 100, L)
    assert float(too_much.pressure) == muscle.spec.max_pressure and too_much.flags & Flag.SATURATED
    start = muscle.pressure(0.0, L)
    assert not start.flags & Flag.SATURATED
    assert 0 <= float(start.pressure) <= muscle.spec.max_pressure
    raw_at_start = float(muscle.force(start.pressure, L).raw)
    if float(start.pressure) > 0:
        # The raw model force crosses zero at the pull-start pressure ...
        assert abs(raw_at_start) < 1e-6 * max(top, 1.0)
    else:
        # ... or the muscle already pulls (or is at zero) at zero gauge pressure.
        assert raw_at_start >= -1e-6 * max(top, 1.0)
    assert float(muscle.pressure(-50.0, L).pressure) == float(start.pressure)


def test_vectorised_with_invalid_entries(martens_10_250):
    res = martens_10_250.pressure(np.array([100.0, np.nan, 200.0, 100.0]), np.array([0.23, 0.23, np.inf, -0.1]))
    assert np.isfinite(res.pressure[0]) and np.all(np.isnan(res.pressure[1:]))
    assert res.flags[0] == Flag.OK and np.all(res.flags[1:] & Flag.INVALID_INPUT)
