"""The play operator (core/physics/hysteresis.py) on hand-traced series."""

import math

import numpy as np

from pma_model_ros.core.physics.hysteresis import branches, play


def test_a_branch_changes_only_after_a_reversal_beyond_the_deadband():
    # deadband 1: unknown until the signal moved by more than 1; then kept through a 0.5 dip; flips
    # to -1 once the signal is 1.5 below its peak 4; back to +1 after rising 1.5 above its low 1.
    values = [0, 0.5, 2, 4, 3.5, 4, 2.5, 1, 1.2, 2.5]
    assert branches(values, 1.0).tolist() == [0, 0, 1, 1, 1, 1, -1, -1, -1, 1]


def test_nan_changes_nothing_and_arrays_match_floats():
    assert play(1.0, 4.0, math.nan, 1.0) == (1.0, 4.0)
    state = (np.array([0.0, 1.0, -1.0]), np.array([math.nan, 4.0, 1.0]))
    value = np.array([3.0, 2.0, 2.5])
    vector = play(*state, value, 1.0)
    for k in range(3):
        one = play(float(state[0][k]), float(state[1][k]), float(value[k]), 1.0)
        assert (vector[0][k], vector[1][k]) == one
