"""numpy's elementwise functions with a plain-float path.

The models and the geometry take arrays (many points, many muscles) or one float (one message of
one muscle, :meth:`~pma_model_ros.core.physics.muscle_model.Evaluator.operating_one`).  On a float,
a numpy function costs about 1 us of call overhead, more than the arithmetic; these use :mod:`math`
there, with numpy's results at the edges (NaN for a negative square root, inf for an overflowing
exp).
"""

from __future__ import annotations

import math

import numpy as np


def asarray(x):
    """``x`` as is if a float, else as a float array."""
    return x if type(x) is float else np.asarray(x, float)


def sqrt(x):
    if type(x) is float:
        return math.sqrt(x) if x >= 0 else math.nan
    return np.sqrt(x)


def exp(x):
    if type(x) is float:
        try:
            return math.exp(x)
        except OverflowError:
            return math.inf
    return np.exp(x)


def cbrt(x):
    return math.cbrt(x) if type(x) is float else np.cbrt(x)


def cos(x):
    return math.cos(x) if type(x) is float else np.cos(x)


def sin(x):
    return math.sin(x) if type(x) is float else np.sin(x)


def tan(x):
    return math.tan(x) if type(x) is float else np.tan(x)


def zeros_like(x):
    """Float zeros of ``x``'s shape (np.zeros: a third of np.zeros_like's cost on 64 values)."""
    return 0.0 if type(x) is float else np.zeros(np.shape(x))


def clip(x, low, high):
    return min(max(x, low), high) if type(x) is float else np.clip(x, low, high)


def lowest(x: np.ndarray):
    """``x.min()`` of an array (NaN if any is NaN), without ndarray.min's Python layer (a
    third of its cost on a message's 64 values).
    """
    return np.minimum.reduce(x, axis=None)


def highest(x: np.ndarray):
    """``x.max()`` of an array (NaN if any is NaN); see :func:`lowest`."""
    return np.maximum.reduce(x, axis=None)
