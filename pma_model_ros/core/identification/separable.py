"""Separable fits of one force model at fixed geometry: variable projection (Golub & Pereyra).

Every model of :mod:`~pma_model_ros.core.physics.models` is affine in some of its parameters
(``Model.linear``: Martens' elastic polynomial c0..c3 of eq. 15, all of Hildebrandt's eq. 20 and
Wickramatunge's eq. 21, five of Sárosi's eq. 19).  At fixed nonlinear parameters phi (Martens'
angle correction d0 of eq. 16, Sárosi's c2, Andrikopoulos' c1, a pressure offset) the force on a
map is

    F(phi, c) = b(phi) + A(phi) c        [N],

so the best linear parameters c are a linear least-squares (or linear-programming) solution, and
only phi (0 to 2 numbers) is searched: on a grid over its bounds, then refined by scipy's bounded
``least_squares`` on the projected residual.  The ``best`` protocol fits the physical, clipped
force max(F, 0) (a muscle cannot push): at fixed phi that is linear least squares on the points
where the model pulls, iterated until that set is stable (a semismooth Newton step; the best
iterate is kept).  The grid makes the result a deterministic global search, not a random
multi-start.

Equal-cost linear parameters (an elastic polynomial the map cannot determine, e.g. three lengths
for a cubic) are resolved by the minimum-norm solution in columns scaled to unit norm
(``numpy.linalg.lstsq``), which does not depend on the data's last digits.  Equal-cost
nonlinear parameters are resolved alike: costs within :data:`~.validation.TIE` (relative) of the
best are equal, and of equal fits the one nearest the start point (least squares: Table 1's;
minimax: the least-squares fit's) is taken.  Rounding (BLAS kernels, SIMD paths, thread counts)
moves a cost by about 1e-13 relative, so without that rule a flat objective (Sárosi's c2 on three
lengths, which the exponential and the linear terms fit equally well at any value; a minimax error
set by a measured force where the model is slack) returned a different optimum on another CPU.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
import warnings

import numpy as np

from .force_map import ForceMap
from .validation import beats, TIE, within_tie
from ..physics.geometry import MuscleSpec
from ..physics.models import Domain, Model

GRID = 41  #: grid points over each model's first nonlinear parameter
_REFINED = 3  #: best grid points refined by least squares
_ACTIVE_SET_STEPS = 20  #: most active-set iterations of the clipped linear least squares
_RCOND = 1e-10  #: relative singular value below which a linear direction is undetermined
_ZERO = 1e-9  #: model force, relative to the map's largest, that counts as 0 N (not pulling)
_BISECTIONS = 30  #: halvings of the interval that bounds a minimax plateau's nearest edge


@dataclass(frozen=True)
class Solution:
    """A fit of one model: parameters and the sum of squares or worst residual it reached."""

    theta: np.ndarray  #: every parameter of the model, in its order
    cost: float  #: least squares: sum of squared residuals [N^2]; minimax: worst |residual| [N]

    def __post_init__(self) -> None:
        self.theta.setflags(write=False)  # shared by every use of a remembered fit (_SOLVED)


#: Least-squares fits made in this process, the most recently used last, by what they depend on
#: (:meth:`Separable.fit_least_squares`).  A nested judgement asks for the same fit in several
#: folds: the map without lengths j and k in fold j's search of L0 and in fold k's.
_SOLVED: OrderedDict[tuple, Solution] = OrderedDict()
_SOLVED_MAX = 4096  #: fits remembered (a few kB each)


class Separable:
    """The fit of ``model`` (possibly :func:`~.calibration.shifted`) to ``fmap`` at ``spec``."""

    def __init__(self, model: Model, spec: MuscleSpec, domain: Domain, fmap: ForceMap):
        self.model, self.spec, self.domain = model, spec, domain
        self.pressure, self.length, self.force = fmap.pressure, fmap.length, fmap.force
        n = model.n_params
        self.linear = np.array(model.linear, int)
        self.nonlinear = np.array([i for i in range(n) if i not in model.linear], int)
        start = np.array(model.start, float)
        #: each linear parameter's size (Table 1's start, else 1): the unit of its design column
        self.unit = np.where(start[self.linear] != 0, np.abs(start[self.linear]), 1.0)
        self.lower = np.array(model.lower, float)[self.nonlinear]
        self.upper = np.array(model.upper, float)[self.nonlinear]
        self.start = start[self.nonlinear]
        self._solved_at: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def design(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(b, A) at nonlinear parameters ``phi``: force with c = 0 [N] (points) and dF/dc
        (points x linear parameters), from the model's coefficients at c = 0 and at each unit.
        """
        k = self.linear.size
        theta = np.zeros((self.model.n_params, k + 1, 1))
        theta[self.nonlinear, :, 0] = phi[:, None]
        theta[self.linear, np.arange(1, k + 1), 0] = self.unit
        with np.errstate(all='ignore'):
            q2, q1, q0 = (
                np.broadcast_to(q, (k + 1, self.length.size))
                for q in self.model.coefficients(theta, self.spec, self.domain, self.length, 0.0)
            )
            p = self.pressure
            # differences of coefficients, not of forces: c enters terms that are 0 at c = 0
            slopes = [(q[1:] - q[:1]) / self.unit[:, None] for q in (q2, q1, q0)]
            return (q2[0] * p + q1[0]) * p + q0[0], ((slopes[0] * p + slopes[1]) * p + slopes[2]).T

    def theta(self, phi: np.ndarray, c: np.ndarray) -> np.ndarray:
        out = np.zeros(self.model.n_params)
        out[self.nonlinear], out[self.linear] = phi, c
        return out

    def linear_least_squares(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(c, residuals [N]) of the clipped least squares over the linear parameters at ``phi``;
        residuals inf where the model is not finite (a length beyond the fibre length).  Computed
        once per ``phi`` (a refinement starts at a grid point already solved, and its optimum is
        solved again for its linear parameters).
        """
        key = np.asarray(phi, float).tobytes()
        if key not in self._solved_at:
            solved = self._linear_least_squares(phi)
            for array in solved:
                array.setflags(write=False)
            self._solved_at[key] = solved
        return self._solved_at[key]

    def _linear_least_squares(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`linear_least_squares`, computed."""
        base, columns = self.design(phi)
        y = self.force
        if not (np.all(np.isfinite(base)) and np.all(np.isfinite(columns))):
            return np.zeros(self.linear.size), np.full(y.size, np.inf)
        if columns.shape[1] == 0:
            return np.zeros(0), y - np.maximum(base, 0.0)
        norms = np.linalg.norm(columns, axis=0)
        norms[norms == 0] = 1.0
        scaled = columns / norms
        pulling, seen = y > 0, set()
        zero = _ZERO * np.max(np.abs(y))  # a model force that counts as 0 N
        best = (np.inf, np.zeros(self.linear.size), np.full(y.size, np.inf))
        for _ in range(_ACTIVE_SET_STEPS):
            key = pulling.tobytes()
            if key in seen or not pulling.any():
                break
            seen.add(key)
            z = np.linalg.lstsq(scaled[pulling], (y - base)[pulling], rcond=_RCOND)[0]
            force = base + scaled @ z
            residuals = y - np.maximum(force, 0.0)
            cost = float(residuals @ residuals)
            if beats(cost, best[0]):  # an equal cost later is not better
                best = (cost, z / norms, residuals)
            # a force within rounding of 0 N (a fit through a measured zero) does not pull
            pulling = force > zero
        return best[1], best[2]

    def fit_least_squares(self, near: Solution | None = None) -> Solution:
        """Eq. 22 on the clipped model: grid over the first nonlinear parameter, the best
        :data:`_REFINED` points refined jointly in every nonlinear parameter; with ``near`` (the
        solution of a neighbouring problem, e.g. the next rest length) only that start is refined.

        A fit this process made already is returned again (:data:`_SOLVED`): it depends on the
        model, geometry, domain, the map's points and the start only.
        """
        key = (
            self.model,
            self.spec,
            self.domain,
            self.pressure.tobytes(),
            self.length.tobytes(),
            self.force.tobytes(),
            None if near is None else near.theta.tobytes(),
        )
        solution = _SOLVED.get(key)
        if solution is None:
            solution = _SOLVED[key] = self._least_squares(near)
            if len(_SOLVED) > _SOLVED_MAX:
                _SOLVED.popitem(last=False)
        else:
            _SOLVED.move_to_end(key)
        return solution

    def _least_squares(self, near: Solution | None) -> Solution:
        """:meth:`fit_least_squares`, computed."""
        from scipy.optimize import least_squares  # here: force and pressure need no optimizer

        if self.nonlinear.size == 0:
            c, r = self.linear_least_squares(np.zeros(0))
            return Solution(self.theta(np.zeros(0), c), float(r @ r))
        if near is not None:
            starts = [(self._sse(near.theta[self.nonlinear]), near.theta[self.nonlinear])]
        else:
            starts = self._ranked([(self._sse(phi), phi) for phi in self._grid()])[:_REFINED]
        found = []
        for cost, phi0 in starts:
            if not np.isfinite(cost):
                continue
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                result = least_squares(
                    lambda phi: self.linear_least_squares(phi)[1],
                    np.array(phi0),
                    bounds=(self.lower, self.upper),
                    x_scale=self._phi_scale(),
                    method='trf',
                    xtol=1e-12,
                    ftol=1e-12,
                    gtol=1e-12,
                    max_nfev=200,
                )
            # a refinement counts only where it lowers the cost beyond a tie: on a flat objective
            # it wanders by rounding, and the grid point stays
            refined = beats(2 * result.cost, cost)
            found.append((2 * result.cost, result.x) if refined else (cost, phi0))
        if not found:
            raise ValueError(f'model {self.model.name!r} is not finite on this map')
        phi = np.array(self._ranked(found)[0][1])
        c, r = self.linear_least_squares(phi)
        return Solution(self.theta(phi, c), float(r @ r))

    def _sse(self, phi: np.ndarray) -> float:
        r = self.linear_least_squares(phi)[1]
        return float(r @ r)

    def _ranked(self, fits: list[tuple[float, np.ndarray]]) -> list[tuple[float, np.ndarray]]:
        """``fits`` (cost, phi) best first: those within :data:`TIE` of the best cost count as
        equal and come first, nearest the start point first (distances in :meth:`_phi_scale`
        units); the rest by cost.
        """
        best = min(cost for cost, _ in fits)
        scale = self._phi_scale()

        def key(fit: tuple[float, np.ndarray]) -> tuple[bool, float]:
            cost, phi = fit
            if within_tie(cost, best):
                return False, float(np.linalg.norm((np.asarray(phi) - self.start) / scale))
            return True, cost

        return sorted(fits, key=key)

    def _grid(self) -> list[np.ndarray]:
        """Nonlinear starting points: :data:`GRID` values of the first parameter over its bounds
        (at most +-100 of a scale-free one), the others at their start (Table 1; offset 0).
        """
        low, high = max(self.lower[0], -100.0), min(self.upper[0], 100.0)
        points = []
        for value in np.linspace(low, high, GRID):
            phi = self.start.copy()
            phi[0] = value
            points.append(phi)
        return points

    def _phi_scale(self) -> np.ndarray:
        return np.maximum(np.minimum(self.upper - self.lower, 200.0) / 100, 1e-12)

    # --- minimax (eq. 23 itself) ------------------------------------------------------------

    def linear_minimax(
        self, phi: np.ndarray, near: np.ndarray | None = None
    ) -> tuple[np.ndarray, float]:
        """(c, worst |residual| [N]) of the clipped model at ``phi``.

        The linear program min t over (c, t) with F - y <= t at every point and y - F <= t at the
        pulling points (y > 0) whose force exceeds the worst error so far (below it, a model
        that does not pull errs by y <= t), repeated until that set of points is stable.  With
        ``near`` (linear parameters, e.g. the least-squares ones), of the parameters reaching that
        worst error the one nearest to ``near`` (L1, in unit-norm columns): the linear program's
        vertex is otherwise arbitrary where the map does not determine every parameter.
        """
        from scipy.optimize import linprog

        base, columns = self.design(phi)
        y = self.force
        if not (np.all(np.isfinite(base)) and np.all(np.isfinite(columns))):
            return np.zeros(self.linear.size), np.inf
        k = columns.shape[1]
        if k == 0:
            return np.zeros(0), float(np.max(np.abs(y - np.maximum(base, 0.0))))
        norms = np.linalg.norm(columns, axis=0)
        norms[norms == 0] = 1.0
        scaled = columns / norms
        best, bounded, seen = (np.inf, np.zeros(k), y > 0), y > 0, set()
        for _ in range(_ACTIVE_SET_STEPS):
            key = bounded.tobytes()
            if key in seen:
                break
            seen.add(key)
            a_ub, b_ub = _chebyshev_rows(scaled, y - base, bounded)
            result = linprog(
                np.r_[np.zeros(k), 1.0],
                A_ub=np.hstack([a_ub, -np.ones((b_ub.size, 1))]),
                b_ub=b_ub,
                bounds=[(None, None)] * k + [(0, None)],
            )
            if result.status != 0:
                break
            c = result.x[:k] / norms
            worst = float(np.max(np.abs(y - np.maximum(base + columns @ c, 0.0))))
            if beats(worst, best[0]):
                best = (worst, c, bounded)
            bounded = y > result.x[-1]
        worst, c, bounded_rows = best
        if near is None or not np.isfinite(worst):
            return c, worst
        # among the parameters within the worst error: min sum u, |z - z_near| <= u
        a_ub, b_ub = _chebyshev_rows(scaled, y - base, bounded_rows)
        eye, z_near = np.eye(k), near * norms
        result = linprog(
            np.r_[np.zeros(k), np.ones(k)],
            A_ub=np.vstack(
                [
                    np.hstack([a_ub, np.zeros((b_ub.size, k))]),
                    np.hstack([eye, -eye]),
                    np.hstack([-eye, -eye]),
                ]
            ),
            b_ub=np.r_[b_ub + worst * (1 + TIE), z_near, -z_near],
            bounds=[(None, None)] * k + [(0, None)] * k,
        )
        if result.status == 0:
            polished = result.x[:k] / norms
            error = float(np.max(np.abs(y - np.maximum(base + columns @ polished, 0.0))))
            if error <= worst * (1 + 1e-6):
                return polished, error
        return c, worst

    def fit_minimax(self, start: Solution) -> Solution:
        """Eq. 23 minimised: the linear program at fixed nonlinear parameters, the first nonlinear
        parameter searched by Brent's method within two grid steps of ``start``'s (a least-squares
        fit; other nonlinear parameters kept at its values); ties resolved towards the
        least-squares parameters: of a plateau of equal worst errors (within :data:`TIE`), its
        edge nearest the least-squares value, found by bisection.
        """
        from scipy.optimize import minimize_scalar

        phi = start.theta[self.nonlinear].copy()
        if self.nonlinear.size:

            def worst_at(value: float) -> float:
                trial = phi.copy()
                trial[0] = value
                return self.linear_minimax(trial)[1]

            low, high = max(self.lower[0], -100.0), min(self.upper[0], 100.0)
            width = 2 * (high - low) / (GRID - 1)
            at_start = worst_at(phi[0])
            result = minimize_scalar(
                worst_at,
                bounds=(max(phi[0] - width, low), min(phi[0] + width, high)),
                method='bounded',
                options={'xatol': 1e-6 * width},
            )
            if not within_tie(at_start, result.fun):
                worse, good = phi[0], float(result.x)
                for _ in range(_BISECTIONS):
                    middle = (worse + good) / 2
                    if within_tie(worst_at(middle), result.fun):
                        good = middle
                    else:
                        worse = middle
                phi[0] = good
        near = self.linear_least_squares(phi)[0]
        c, worst = self.linear_minimax(phi, near)
        return Solution(self.theta(phi, c), worst)


def _chebyshev_rows(
    scaled: np.ndarray, target: np.ndarray, bounded: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rows (A, b) of A z - t <= b: the model at most ``target`` + t everywhere and at least
    ``target`` - t where ``bounded``.
    """
    return np.vstack([scaled, -scaled[bounded]]), np.r_[target, -target[bounded]]
