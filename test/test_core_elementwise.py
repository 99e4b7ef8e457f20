"""numpy's elementwise functions with a plain-float path (core/physics/elementwise.py): the same
values as numpy, floats for floats.
"""

import math

import numpy as np
import pytest

from pma_model_ros.core.physics import elementwise as ew


@pytest.mark.parametrize('name', ['sqrt', 'exp', 'cbrt', 'cos', 'sin', 'tan'])
@pytest.mark.parametrize('x', [0.0, 0.5, 2.0, 27.0])
def test_floats_give_numpys_value_as_a_float(name, x):
    got = getattr(ew, name)(x)
    assert type(got) is float
    assert got == pytest.approx(float(getattr(np, name)(x)), rel=1e-15)


def test_numpys_results_at_the_edges():
    assert math.isnan(ew.sqrt(-1.0))
    assert ew.exp(1000.0) == math.inf
    assert ew.cbrt(-27.0) == pytest.approx(-3.0, rel=1e-15)  # real cube root of a negative
    assert ew.clip(5.0, 0.0, 2.0) == 2.0
    np.testing.assert_array_equal(ew.clip(np.array([-1.0, 1.0, 5.0]), 0.0, 2.0), [0, 1, 2])
