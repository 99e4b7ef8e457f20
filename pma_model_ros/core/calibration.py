"""Geometry calibration: what a user cannot measure precisely, identified with the model
parameters.

Two quantities, each switchable (:class:`Calibration`) and bounded, identified by the ``best``
protocol (:func:`pma_model_ros.core.identification.fit_best_all`):

* the pressure-sensor offset o [Pa], within +-:data:`PRESSURE_BOUND`: the sensor reads p = p_true +
  o, and every model is evaluated at p_true = p - o (:func:`shifted`); identified by least squares
  jointly with the model parameters, with a 1-sigma from the Jacobian at the optimum
  (:func:`standard_errors`);
* the effective rest length L0 (``muscle.nominal_length``), within +-:data:`LENGTH_BOUND` of the
  given value: a tape between two clamps is not the length at which the membrane is stress-free,
  and the Martens model (eq. 14) pins its force line at L0.  In-sample, the elastic terms absorb a
  wrong L0, so L0 is chosen by held-out (leave-one-length-out) error, with the range of L0 within
  10 % of the best held-out RMSE as its uncertainty.

A quantity the map cannot identify (the offset's 1-sigma above a quarter of its bound, an L0 the
model does not depend on or whose held-out range spans more than half its bounds) stays as given,
and is reported so.  A parameter file stores them per model (``models.<name>.nominal_length``,
``.pressure_offset``); :func:`pma_model_ros.core.param_file.muscle_model` builds the model node's,
the inverse's and the bag tools' muscle from them, so every consumer applies them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import functools

import numpy as np

from .geometry import MuscleSpec
from .models import Coefficients, Model

LENGTH_BOUND = 0.05  #: largest relative correction of the given rest length L0 [-]
PRESSURE_BOUND = 2e4  #: largest pressure-sensor offset [Pa]


@dataclass(frozen=True)
class Calibration:
    """Which geometry quantities the ``best`` identification calibrates (module docstring)."""

    length: bool = True  #: the effective rest length L0
    pressure: bool = True  #: the pressure-sensor offset

    @property
    def any(self) -> bool:
        return self.length or self.pressure

    def identifiable(self, sigma: dict[str, float]) -> 'Calibration':
        """What a joint least-squares fit's 1-sigma (``sigma``: "nominal_length" [m],
        "pressure_offset" [Pa]) says the map can identify: the offset if its 1-sigma is at most a
        quarter of its bound (a 95 % interval within half the bound), L0 if the model depends on it
        at all (finite 1-sigma; its value and range are then chosen by held-out error,
        :mod:`pma_model_ros.core.identification`).
        """
        return Calibration(
            self.length and bool(np.isfinite(sigma['nominal_length'])),
            self.pressure and sigma['pressure_offset'] <= PRESSURE_BOUND / 4,
        )

    def describe(self) -> str:
        parts = [f'rest length L0 (+-{100 * LENGTH_BOUND:g} %)'] * self.length + [
            f'pressure offset (+-{PRESSURE_BOUND / 1e3:g} kPa)'
        ] * self.pressure
        return (
            'geometry calibration ON: ' + ', '.join(parts) if parts else 'geometry calibration OFF'
        )


OFF = Calibration(False, False)


@functools.cache
def shifted(model: Model) -> Model:
    """``model`` fed the sensor's pressure p with an offset o as its last parameter: F(p) =
    F_model(p - o).

    At fixed L every model is q2 p^2 + q1 p + q0, so the shift is one of coefficients:
    q1' = q1 - 2 q2 o, q0' = q0 - (q1 - q2 o) o.  Cached: one Model object per model (muscle banks
    group by it).
    """
    base = model.coefficients

    def coefficients(theta, spec, domain, length, branch) -> Coefficients:
        q2, q1, q0 = base(theta[:-1], spec, domain, length, branch)
        offset = theta[-1]
        return q2, q1 - 2 * q2 * offset, q0 - (q1 - q2 * offset) * offset

    return replace(
        model,
        param_names=(*model.param_names, 'pressure_offset'),
        start=(*model.start, 0.0),
        lower=(*model.lower, -PRESSURE_BOUND),
        upper=(*model.upper, PRESSURE_BOUND),
        coefficients=coefficients,
    )


def with_length(spec: MuscleSpec, nominal_length: float) -> MuscleSpec:
    """``spec`` with the rest length L0 [m] replaced (the fibre length and turns follow, eq. 3)."""
    return (
        spec
        if nominal_length == spec.nominal_length
        else replace(spec, nominal_length=float(nominal_length))
    )


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
