"""Ground truth of the simulator: a pchip interpolation of the shipped measured map."""

import numpy as np
import pytest

from pma_model_ros.core.force_map import ForceMap, shipped_force_map
from pma_model_ros.core.ground_truth import GroundTruth


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


def test_needs_a_full_grid():
    with pytest.raises(ValueError, match='full grid'):
        GroundTruth(ForceMap([0, 1e5, 2e5], [0.2, 0.25, 0.25], [0, 10, 20]))
