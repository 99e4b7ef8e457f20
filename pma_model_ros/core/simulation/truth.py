"""The simulated muscle's true static force: a measured map, an identified model, and a drift.

:class:`GroundTruth` interpolates any measured force map, a full pressure x length grid (the
paper's Tables A1/A2) or not (maps binned by pressure per clamped length, each length with its own
pressures); :class:`ModelTruth` takes an identified muscle as the truth; :class:`Drift` changes
either over time (a force gain ramp, or another truth from a set time). Each is evaluated from
precomputed piecewise polynomials: no fit per sample.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import PchipInterpolator

from ..identification.force_map import ForceMap
from ..physics.muscle_model import MuscleModel

#: Lengths at which :class:`GroundTruth` tabulates its pressure curves, evenly from the shortest to
#: the longest measured length (the measured ones added): linear between two of them errs by at
#: most h²/8 |d²F/dL²|, about 1e-5 of the max force on the shipped maps (h = 0.1 mm).
TABLE_LENGTHS = 513


class Truth(Protocol):
    """What the simulators need of a truth."""

    pressures: np.ndarray  #: gauge pressures [Pa], ascending: the sweeps span first to last
    lengths: np.ndarray  #: lengths [m], ascending: the trajectories span first to last
    max_force: float  #: [N]

    def force(self, pressure: ArrayLike, length: ArrayLike) -> np.ndarray: ...


def _rows(force_map: ForceMap) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pressure of the map, its lengths (both ascending) and the force on that grid [N].

    Each length's points, a point measured more than once as their mean, make a pchip along the
    pressure; outside that length's own pressures it continues on the line through its two end
    points (a measured row is close to a line F = s (p - p0), and below its first point lies the
    threshold where the force falls to 0), never below 0 N. On a full grid this is the map itself.
    """
    p, L, F = force_map.pressure, force_map.length, force_map.force
    pressures, lengths = np.unique(p), np.unique(L)
    if lengths.size < 2:
        raise ValueError(f'the truth needs at least 2 measured lengths, got {lengths[0]:g} m only')
    grid = np.empty((pressures.size, lengths.size))
    for j, length in enumerate(lengths):
        at = L == length
        x, which = np.unique(p[at], return_inverse=True)
        y = np.bincount(which, F[at]) / np.bincount(which)
        if x.size < 2:
            raise ValueError(
                f'length {length:g} m has one measured pressure ({x[0]:g} Pa); the truth needs '
                'at least 2 per length'
            )
        row = PchipInterpolator(x, y)(pressures)
        below, above = pressures < x[0], pressures > x[-1]
        row[below] = y[0] + (pressures[below] - x[0]) * (y[1] - y[0]) / (x[1] - x[0])
        row[above] = y[-1] + (pressures[above] - x[-1]) * (y[-1] - y[-2]) / (x[-1] - x[-2])
        grid[:, j] = np.maximum(row, 0.0)
    return pressures, lengths, grid


class GroundTruth:
    """Force [N] over gauge pressure [Pa] and length [m] from a measured force map.

    The map is first made a full grid (every pressure it has at every length it has: see
    :func:`_rows`; a full-grid map is left as it is). Then as scipy's 2-D pchip
    (``RegularGridInterpolator(method='pchip')``) on that grid: pchip across the lengths at each
    pressure, then pchip along the pressure at the length; here the second step is precomputed at
    :data:`TABLE_LENGTHS` lengths and a length between two of them interpolated linearly. Inputs
    are clamped to the grid, the result to >= 0 N (0 where the muscle is slack).
    """

    def __init__(self, force_map: ForceMap) -> None:
        self.pressures, self.lengths, grid = _rows(force_map)
        self.max_force = force_map.max_force
        self._table = np.union1d(
            np.linspace(self.lengths[0], self.lengths[-1], TABLE_LENGTHS), self.lengths
        )
        across = PchipInterpolator(self.lengths, grid.T)(self._table)  # (table, pressures)
        # coefficients (4, pressure intervals, table lengths) of the cubics along the pressure
        self._c = PchipInterpolator(self.pressures, across.T).c

    def force(self, pressure: ArrayLike, length: ArrayLike) -> np.ndarray:
        """Tension [N] >= 0 at gauge ``pressure`` [Pa] and ``length`` [m] (clamped to the grid)."""
        p, L = np.broadcast_arrays(np.asarray(pressure, float), np.asarray(length, float))
        x, table = self.pressures, self._table
        p, L = np.clip(p, x[0], x[-1]), np.clip(L, table[0], table[-1])
        i = np.clip(np.searchsorted(x, p, 'right') - 1, 0, x.size - 2)
        k = np.clip(np.searchsorted(table, L, 'right') - 1, 0, table.size - 2)
        dx, w = p - x[i], (L - table[k]) / (table[k + 1] - table[k])
        low, high = (
            ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]
            for c in (self._c[:, i, k], self._c[:, i, k + 1])
        )
        return np.maximum(low + w * (high - low), 0.0)


class ModelTruth:
    """An identified muscle's served force (:meth:`MuscleModel.force`) as the truth, over its
    identified lengths and 0 to its identified pressure (the rated one if the file has none).
    """

    def __init__(self, model: MuscleModel) -> None:
        domain, self.model = model.domain, model
        top = (
            domain.pressure_max if math.isfinite(domain.pressure_max) else model.spec.max_pressure
        )
        self.pressures = np.array([0.0, top])
        self.lengths = np.array([domain.length_min, domain.length_max])
        p, L = np.meshgrid(np.linspace(0.0, top, 33), np.linspace(*self.lengths, 33))
        self.max_force = float(self.force(p, L).max())

    def force(self, pressure: ArrayLike, length: ArrayLike) -> np.ndarray:
        """Tension [N] >= 0 at gauge ``pressure`` [Pa] and ``length`` [m] (clamped to the box)."""
        p = np.clip(np.asarray(pressure, float), *self.pressures)
        L = np.clip(np.asarray(length, float), *self.lengths)
        return np.maximum(self.model.force(p, L).force, 0.0)


@dataclass(frozen=True)
class Drift:
    """How the truth changes over the time ``t`` [s] since the simulator started.

    The force is multiplied by a gain that ramps linearly from 1 at ``start`` to ``gain`` at
    ``start + duration`` (a step at ``start`` if ``duration`` is 0) and stays there; from ``at``
    on, the truth is ``then`` (if given).
    """

    gain: float = 1.0
    start: float = 0.0  #: [s]
    duration: float = 0.0  #: [s]
    then: Truth | None = None
    at: float = 0.0  #: [s]

    def gain_at(self, t: ArrayLike) -> np.ndarray:
        """The force gain at ``t`` [s]."""
        t = np.asarray(t, float)
        if self.duration > 0:
            share = np.clip((t - self.start) / self.duration, 0.0, 1.0)
        else:
            share = (t >= self.start).astype(float)
        return 1.0 + (self.gain - 1.0) * share

    def force(
        self, truth: Truth, t: ArrayLike, pressure: ArrayLike, length: ArrayLike
    ) -> np.ndarray:
        """Tension [N] of ``truth`` so drifted at ``t`` [s], gauge ``pressure`` [Pa], ``length``
        [m].
        """
        force = truth.force(pressure, length)
        late = np.asarray(t) >= self.at
        if self.then is not None and np.any(late):
            force = np.where(late, self.then.force(pressure, length), force)
        return force * self.gain_at(t)
