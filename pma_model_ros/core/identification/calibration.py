"""Geometry calibration: what a user cannot measure precisely, identified with the model
parameters only where the map proves the given value wrong or identifies it.

The given geometry is the default, and a calibration must never make the held-out error worse
(docs/calibration.md has the nested leave-one-length-out numbers behind each rule):

* the pressure offset o [Pa], within +-:data:`PRESSURE_BOUND`: the sensor reads p = p_true + o, or
  the membrane takes o before the braid pulls (a threshold pressure, which Martens' eq. 14 lacks at
  L0).  Every model is evaluated at p - o (:func:`shifted`).  It is identified by least squares
  jointly with the model parameters and kept only if the map determines it: its 1-sigma from the
  Jacobian at the optimum (:func:`standard_errors`) at most :data:`OFFSET_SIGMA`.  A map with its
  rest-length row (Table A2) identifies it; elsewhere the elastic terms absorb it.
* the rest length L0 (``muscle.nominal_length``): kept as given unless the map proves it too short.
  A muscle is not stretched, so L0 is at least the longest measured length: a shorter given L0 is
  raised to it first (:func:`short_of_map`).  A muscle that is slack at low pressure (its force
  line meets zero at a positive pressure) is not stretched either, so L0 is at least the longest
  such length (:func:`slack_length`).  (At that length
  exactly, Martens' force line, eq. 14, meets zero at 0 Pa: a threshold there is the offset's.)
  Only if the given L0 is shorter is L0 identified, on
  (bound, bound (1 + :data:`LENGTH_BOUND`)], by the held-out error of fits without each length
  (in-sample, the elastic terms absorb a wrong L0).  A held-out choice of L0 from the whole range
  is not made: without the rows near L0 it picks a wrong one (20 % errors on the shipped maps,
  nested; docs/calibration.md).

A parameter file stores them per model (``models.<name>.nominal_length``, ``.pressure_offset``);
:func:`pma_model_ros.core.files.param_file.muscle_model` builds the model node's, the inverse's and
the bag tools' muscle from them, so every consumer applies them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import functools
from typing import Callable

import numpy as np

from .force_map import ForceMap
from ..physics.geometry import MuscleSpec
from ..physics.models import Coefficients, Model

LENGTH_BOUND = 0.05  #: L0 searched up to this fraction above the slack bound [-]
PRESSURE_BOUND = 5e4  #: largest pressure offset [Pa]
OFFSET_SIGMA = 1.5e3  #: largest 1-sigma [Pa] of an identified offset (+-3 kPa at 95 %)
_LENGTH_STEP = 0.002  #: grid step of the L0 search, relative [-]
#: a point pulls if its force exceeds this fraction of the map's max force (3 sigma of 1 % noise)
_PULLING = 0.03


@dataclass(frozen=True)
class Calibration:
    """Which geometry quantities the ``best`` identification may calibrate (module docstring)."""

    length: bool = True  #: the effective rest length L0
    pressure: bool = True  #: the pressure offset

    @property
    def any(self) -> bool:
        return self.length or self.pressure

    def describe(self) -> str:
        parts = ['rest length L0 (if the map proves the given one too short)'] * self.length + [
            f'pressure offset (+-{PRESSURE_BOUND / 1e3:g} kPa, if the map identifies it)'
        ] * self.pressure
        return (
            'geometry calibration ON: ' + ', '.join(parts) if parts else 'geometry calibration OFF'
        )


OFF = Calibration(False, False)


def offset_identifiable(offset: float, sigma: float) -> bool:
    """An offset [Pa] inside its bounds with a 1-sigma of at most :data:`OFFSET_SIGMA` is
    identified; any other stays 0.  A looser offset sits in a flat valley of the sum of squares
    (Martens' elastic polynomial absorbs most of it), where its value moves by kPa with the data's
    last digits; one at a bound is what the map wants beyond physics, not a measurement.
    """
    return bool(sigma <= OFFSET_SIGMA and abs(offset) < 0.99 * PRESSURE_BOUND)


@functools.cache
def shifted(model: Model) -> Model:
    """``model`` fed the sensor's pressure p with an offset o as its last parameter: F(p) =
    F_model(p - o).

    At fixed L every model is q2 p^2 + q1 p + q0, so the shift is one of coefficients:
    q1' = q1 - 2 q2 o, q0' = q0 - (q1 - q2 o) o.  Cached: one Model object per model (muscle banks
    group by it).
    """

    def shift(q: Coefficients, offset) -> Coefficients:
        q2, q1, q0 = q
        return q2, q1 - 2 * q2 * offset, q0 - (q1 - q2 * offset) * offset

    def coefficients(theta, spec, domain, length, branch) -> Coefficients:
        return shift(model.coefficients(theta[:-1], spec, domain, length, branch), theta[-1])

    def prepared(theta, spec, domain) -> Callable[..., Coefficients]:
        inner, offset = model.prepare(theta[:-1], spec, domain), theta[-1]
        return lambda length, branch: shift(inner(length, branch), offset)

    return replace(
        model,
        param_names=(*model.param_names, 'pressure_offset'),
        start=(*model.start, 0.0),
        lower=(*model.lower, -PRESSURE_BOUND),
        upper=(*model.upper, PRESSURE_BOUND),
        coefficients=coefficients,
        prepared=prepared,
    )


def with_length(spec: MuscleSpec, nominal_length: float) -> MuscleSpec:
    """``spec`` with the rest length L0 [m] replaced (the fibre length and turns follow, eq. 3)."""
    return (
        spec
        if nominal_length == spec.nominal_length
        else replace(spec, nominal_length=float(nominal_length))
    )


def short_of_map(spec: MuscleSpec, fmap: ForceMap) -> float | None:
    """The map's longest measured length [m] if the given L0 is shorter, else None.  A muscle is
    not stretched beyond its rest length, taut or slack, so such an L0 is wrong: the calibration
    raises it to this length (and on, if the map is slack there), and a fit that keeps L0 as given
    refuses it.
    """
    longest = float(fmap.length.max())
    return longest if spec.nominal_length < longest else None


def slack_length(fmap: ForceMap) -> float | None:
    """The longest measured length [m] at which the muscle is slack at low pressure: its force line
    (least squares over the pulling points of that length) meets zero at a positive pressure.  A
    stretched muscle (L > L0) pulls at 0 Pa, so L0 is at least this length.  None: no length has
    two pulling points and a positive zero-force pressure.
    """
    pulling = fmap.force > _PULLING * fmap.max_force
    for length in fmap.lengths:  # descending
        at = pulling & (fmap.length == length)
        if np.unique(fmap.pressure[at]).size < 2:
            continue
        slope, intercept = np.polyfit(fmap.pressure[at], fmap.force[at], 1)
        if slope > 0 and intercept < 0:
            return float(length)
    return None


def length_grid(spec: MuscleSpec, bound: float) -> np.ndarray:
    """The L0 candidates [m] above a slack bound: steps of :data:`_LENGTH_STEP` of the given L0
    from half a step above ``bound`` to ``bound`` (1 + :data:`LENGTH_BOUND`).
    """
    step = _LENGTH_STEP * spec.nominal_length
    count = int(round(LENGTH_BOUND / _LENGTH_STEP)) + 1
    return bound + step / 2 + step * np.arange(count)


def standard_errors(jac: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """1-sigma of each parameter from the Jacobian at the optimum: s^2 (J^T J)^-1, s^2 = sum r^2 /
    (n - k).

    inf for a parameter the data cannot identify: a zero column, or a share in a direction of
    (column-normalised) J whose singular value is below 1e-8 of the largest (a degenerate
    combination).
    """
    n, k = jac.shape
    norms = np.linalg.norm(jac, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    _, sv, vt = np.linalg.svd(jac / safe, full_matrices=False)
    keep = sv > 1e-8 * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, bool)
    s2 = float(np.sum(residuals**2)) / max(n - k, 1)
    var = s2 * np.sum((vt[keep] / sv[keep, None]) ** 2, axis=0) / safe**2
    degenerate = (norms == 0) | np.any(np.abs(vt[~keep]) > 1e-3, axis=0)
    return np.where(degenerate, np.inf, np.sqrt(var))


def jacobian(fun, x: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of the vector function ``fun`` at ``x``; steps 1e-6 of
    ``scale``.
    """
    steps = 1e-6 * scale
    columns = []
    for i, h in enumerate(steps):
        e = np.zeros_like(x)
        e[i] = h
        columns.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.stack(columns, axis=1)
