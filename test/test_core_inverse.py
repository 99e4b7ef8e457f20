"""Inverse pressure-from-force: saturation, pull start (round trips: test_core_properties.py)."""
import numpy as np
import pytest

from conftest import CONFIGS
from pma_model_ros.core.flags import Flag
from pma_model_ros.core.param_file import muscle_model, read_parameters

MUSCLES = [muscle_model(read_parameters(path), name)
           for path in CONFIGS.values() for name in read_parameters(path)["models"]]
IDS = [f"{m.spec.name}-{m.model.name}" for m in MUSCLES]


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
