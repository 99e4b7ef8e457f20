"""Ground-truth force of a simulated muscle: a smooth interpolation of a measured map.

Not one of the models: the simulator's truth is the measurement itself, so a
model is judged against data it was identified on (and, between the measured
points, against a shape-preserving interpolation of them).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import RegularGridInterpolator

from .force_map import ForceMap


class GroundTruth:
    """Force [N] over gauge pressure [Pa] and length [m] from a full-grid force map.

    Piecewise cubic Hermite (``pchip``, monotone between measured points) on the
    (pressure, length) grid; inputs are clamped to the grid and the result to
    >= 0 N, so the force is 0 where the map's muscle is slack.
    """

    def __init__(self, force_map: ForceMap) -> None:
        self.pressures = np.unique(force_map.pressure)
        self.lengths = np.unique(force_map.length)
        grid = np.full((self.pressures.size, self.lengths.size), np.nan)
        grid[
            np.searchsorted(self.pressures, force_map.pressure),
            np.searchsorted(self.lengths, force_map.length),
        ] = force_map.force
        if np.isnan(grid).any() or grid.size != force_map.force.size:
            raise ValueError(
                'ground truth needs a full grid: every pressure measured at every length, once'
            )
        self.max_force = force_map.max_force
        self._interp = RegularGridInterpolator(
            (self.pressures, self.lengths), grid, method='pchip'
        )

    def force(self, pressure: ArrayLike, length: ArrayLike) -> np.ndarray:
        """Tension [N] >= 0 at gauge ``pressure`` [Pa] and ``length`` [m] (clamped to the grid)."""
        p, L = np.broadcast_arrays(np.asarray(pressure, float), np.asarray(length, float))
        points = np.column_stack(
            [
                np.clip(p.ravel(), self.pressures[0], self.pressures[-1]),
                np.clip(L.ravel(), self.lengths[0], self.lengths[-1]),
            ]
        )
        return np.maximum(self._interp(points), 0.0).reshape(p.shape)
