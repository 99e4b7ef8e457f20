"""The simulated muscle (core/simulation/muscle.py): its ground truth is a pchip interpolation of
the shipped measured map, and its hysteresis follows model_node's play-operator rule.
"""

import math

import numpy as np
import pytest

from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.simulation.muscle import defaults, GroundTruth, SimulatedMuscle

GAP, DEADBAND = 5.0, 1e-3  # [N], [m]
LOW, HIGH, PERIOD = 0.21, 0.24, 4.0  # sine between 0.21 and 0.24 m, 4 s


def test_hysteresis_gap_changes_sign_only_after_the_length_reversed_by_the_deadband():
    """On a sine of amplitude a and angular rate w the length peaks at T/4 and has fallen by the
    deadband d once a (1 - sin(w t)) > d, i.e. after T/4 + acos(1 - d/a) / w: the gap is + until
    then (still the lengthening branch, though the rate is already negative) and - after; then the
    same around the trough at 3T/4.
    """
    params = defaults(
        trajectory='sine',
        length_min=LOW,
        length_max=HIGH,
        period=PERIOD,
        initial_pressure=4e5,
        hysteresis_gap=GAP,
        hysteresis_deadband=DEADBAND,
    )
    times = np.arange(0.001, PERIOD, 0.001)
    with_gap = SimulatedMuscle(params, 0.0).run(times)
    without = SimulatedMuscle(defaults(**{**params, 'hysteresis_gap': 0.0}), 0.0).run(times)
    sign = np.sign(np.round(with_gap.force - without.force, 9))
    amp, w = (HIGH - LOW) / 2, 2 * math.pi / PERIOD
    lag = math.acos(1 - DEADBAND / amp) / w  # 0.205 s for 1 mm on a 15 mm amplitude
    # the start at mid-length rising: unknown until the length has risen by the deadband
    # (asin(d/a)/w)
    start = math.asin(DEADBAND / amp) / w
    for t, expected in (
        (start / 2, 0),
        (start + 0.01, 1),
        (PERIOD / 4 + lag - 0.01, 1),
        (PERIOD / 4 + lag + 0.01, -1),
        (3 * PERIOD / 4 + lag - 0.01, -1),
        (3 * PERIOD / 4 + lag + 0.01, 1),
    ):
        assert sign[int(round(t / 0.001)) - 1] == expected, t
    assert np.all(np.abs(with_gap.force - without.force) <= GAP + 1e-9)
    # rate already negative, branch still +
    assert with_gap.rate[int(round((PERIOD / 4 + lag / 2) / 0.001))] < 0


def test_defaults_reject_unknown_parameters():
    with pytest.raises(ValueError, match='unknown simulator parameter'):
        defaults(hysteresis_width=1.0)


@pytest.mark.parametrize('muscle', ['DMSP-10-250', 'DMSP-20-300'])
def test_reproduces_the_measured_points(muscle):
    fmap = shipped_force_map(muscle)
    truth = GroundTruth(fmap)
    np.testing.assert_allclose(truth.force(fmap.pressure, fmap.length), fmap.force, atol=1e-9)
    assert truth.max_force == fmap.max_force


def test_clamped_nonnegative_and_monotone():
    truth = GroundTruth(shipped_force_map('DMSP-10-250'))
    assert truth.force(1e7, 1.0) == truth.force(truth.pressures[-1], truth.lengths[-1])
    assert truth.force(-1e5, 0.1) == 0.0
    p = np.linspace(0, 7e5, 200)
    for length in np.linspace(0.198, 0.25, 11):
        f = truth.force(p, length)
        assert np.all(f >= 0) and np.all(np.diff(f) >= -1e-9), length
