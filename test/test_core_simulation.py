"""The simulated muscle (core/simulation.py): its hysteresis follows model_node's play-operator
rule.
"""

import math

import numpy as np
import pytest

from pma_model_ros.core.simulation import SimulatedMuscle, defaults

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
    assert (
        with_gap.rate[int(round((PERIOD / 4 + lag / 2) / 0.001))] < 0
    )  # rate already negative, branch still +


def test_defaults_reject_unknown_parameters():
    with pytest.raises(ValueError, match='unknown simulator parameter'):
        defaults(hysteresis_width=1.0)
