"""Inverse pressure-from-force: saturation, pull start, every model shape (round trips:
test_core_properties.py).
"""

import math
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from budget import examples
from conftest import CONFIGS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.models import MODELS
from pma_model_ros.core.physics.muscle_model import MuscleModel, pressure_for_one

MUSCLES = [
    muscle_model(read_parameters(path), name)
    for path in CONFIGS.values()
    for name in read_parameters(path)['models']
]
IDS = [f'{m.spec.name}-{m.model.name}' for m in MUSCLES]


@pytest.mark.parametrize('muscle', MUSCLES, ids=IDS)
def test_saturation_and_pull_start(muscle):
    L = (muscle.domain.length_min + min(muscle.domain.length_max, muscle.spec.nominal_length)) / 2
    # The inverse commands up to the rated pressure, or the identified one where the model does not
    # extrapolate.
    highest = (
        muscle.spec.max_pressure
        if muscle.domain.extrapolates
        else min(muscle.spec.max_pressure, muscle.domain.pressure_max)
    )
    top = float(muscle.force(highest, L).force)
    too_much = muscle.pressure(top * 1.5 + 100, L)
    assert float(too_much.pressure) == highest and too_much.flags & Flag.SATURATED
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
    res = martens_10_250.pressure(
        np.array([100.0, np.nan, 200.0, 100.0]), np.array([0.23, 0.23, np.inf, -0.1])
    )
    assert np.isfinite(res.pressure[0]) and np.all(np.isnan(res.pressure[1:]))
    assert res.flags[0] == Flag.OK and np.all(res.flags[1:] & Flag.INVALID_INPUT)


# --- every model shape, not only the shipped fits
# ----------------------------------------------

EXAMPLES = Path(__file__).resolve().parents[1] / 'docs' / 'examples'
L_EXAMPLE = 0.228  # the examples' stated length: 0.03 m above the map's shortest 0.198 m


def _example(name: str) -> MuscleModel:
    return muscle_model(read_parameters(EXAMPLES / f'{name}_wickramatunge.yaml'))


def test_concave_model_above_its_peak_gets_the_peak():
    """F = -3.125e-9 p^2 + 0.0025 p (the file's comment): peak 500 N at 400 kPa; 800 kPa would give
    0 N.
    """
    muscle = _example('concave')
    above = muscle.pressure(550.0, L_EXAMPLE)
    assert (
        float(above.pressure) == pytest.approx(400e3, rel=1e-12) and above.flags & Flag.SATURATED
    )
    assert float(muscle.force(above.pressure, L_EXAMPLE).force) == pytest.approx(500.0, rel=1e-12)
    # 300 N: smallest root of -3.125e-9 p^2 + 0.0025 p - 300 = 0, by hand: (0.0025 - sqrt(0.0025^2
    # - 3.75e-6)) / 6.25e-9
    reachable = muscle.pressure(300.0, L_EXAMPLE)
    assert float(reachable.pressure) == pytest.approx(
        (0.0025 - math.sqrt(0.0025**2 - 3.75e-6)) / 6.25e-9, rel=1e-9
    )
    assert reachable.flags == Flag.OK


def test_falling_model_gets_its_smallest_root():
    """F = 1e-9 p^2 - 0.003 p + 1000: 550 N at (0.003 - sqrt(9e-6 - 1.8e-6)) / 2e-9 = 158.36 kPa,
    not 800 kPa.
    """
    muscle = _example('falling')
    for wanted in (550.0, 300.0):
        result = muscle.pressure(wanted, L_EXAMPLE)
        by_hand = (0.003 - math.sqrt(9e-6 - 4e-9 * (1000 - wanted))) / 2e-9
        assert (
            float(result.pressure) == pytest.approx(by_hand, rel=1e-9) and result.flags == Flag.OK
        )
    too_much = muscle.pressure(1200.0, L_EXAMPLE)  # the most it gives is 1000 N, at 0 Pa
    assert float(too_much.pressure) == 0.0 and too_much.flags & Flag.SATURATED


def _scaled(model_name: str, shipped: np.ndarray, factors: list[float]) -> np.ndarray:
    """Shipped parameters times factors in [-3, 3] (either sign), held inside the model's own
    bounds.
    """
    model, theta = MODELS[model_name], shipped * np.asarray(factors[: shipped.size])
    return np.clip(theta, model.lower, model.upper) if model.lower else theta


SHAPES = sorted({(m.model.name, m.spec.name) for m in MUSCLES})
_SHIPPED = {(m.model.name, m.spec.name): m for m in MUSCLES}
GRID = np.linspace(0.0, 1.0, 4001)


@examples(1500)
@given(
    st.sampled_from(SHAPES),
    st.lists(st.floats(-3.0, 3.0), min_size=12, max_size=12),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(-0.2, 1.5),
    st.sampled_from((-1.0, 1.0)),
)
def test_inverse_of_random_parameter_sets(shape, factors, u_length, u_pressure, u_target, rate):
    """Any parameter set within the fitter's bounds, any sign of q2 and q1 (1,500 examples); the
    float twin (pressure_for_one) agrees.

    A force the model reaches in [0, max_pressure] comes back unflagged, at the smallest pressure
    that gives it; any other force gives a pressure whose force is at least as near the target as
    on a grid of 4,001 pressures, flagged SATURATED.
    """
    shipped = _SHIPPED[shape]
    muscle = MuscleModel(
        shipped.spec, shipped.model, _scaled(shape[0], shipped.theta, factors), shipped.domain
    )
    L = muscle.domain.length_min + u_length * (
        min(muscle.domain.length_max, muscle.spec.nominal_length) - muscle.domain.length_min
    )
    p_max = muscle.spec.max_pressure
    grid = muscle.force(GRID * p_max, L, rate)
    scale = max(float(np.max(np.abs(grid.raw))), 1.0)
    # A reachable target: the physical force at a random pressure.
    p_true = u_pressure * p_max
    wanted = float(muscle.force(p_true, L, rate).force)
    if wanted > 1e-6 * scale:
        back = muscle.pressure(wanted, L, rate)
        assert not back.flags & Flag.SATURATED
        assert float(muscle.force(back.pressure, L, rate).force) == pytest.approx(
            wanted, abs=1e-9 * scale
        )
        if np.ptp(grid.raw) > 1e-3 * scale:  # (on a flat line, every pressure gives it)
            assert float(back.pressure) <= p_true + 1e-6 * p_max
            # no smaller pressure gives it
            below = GRID * p_max < float(back.pressure) - 1e-6 * p_max
            assert not np.any(np.abs(grid.force[below] - wanted) < 1e-12 * scale)
    # Any target: never further from it than the grid's best.
    target = u_target * scale
    answer = muscle.pressure(target, L, rate)
    served = float(muscle.force(answer.pressure, L, rate).force)
    best = float(np.min(np.abs(grid.force - max(target, 0.0))))
    assert abs(served - max(target, 0.0)) <= best + 1e-9 * scale
    if answer.flags & Flag.SATURATED:
        assert best > 0.0
    elif target > 0:
        assert served == pytest.approx(target, abs=1e-9 * scale)
    # The float twin of the joints' inverse gives the same pressures (its q's differ from the
    # vector's in the last bits: 1e-6 of p_max, and the same force to round-off; on a flat line a
    # last-bit difference of the force moves the pressure anywhere, so there only the force).
    _, q2, q1, q0 = muscle.operating_one(L, rate)
    for force in (wanted, target):
        twin = pressure_for_one(q2, q1, q0, force, 0.0, muscle.limits.command_top)
        vector = float(muscle.pressure(force, L, rate).pressure)
        if np.ptp(grid.raw) > 1e-3 * scale:
            assert twin == pytest.approx(vector, abs=1e-6 * p_max)
        assert float(muscle.force(twin, L, rate).force) == pytest.approx(
            float(muscle.force(vector, L, rate).force), abs=1e-9 * scale
        )
