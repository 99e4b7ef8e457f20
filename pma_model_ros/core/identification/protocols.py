"""The fits of one model to a measured force map: the two protocols, their quality figures and the
checks of a map before any fit.

Two protocols:

``paper``
    Martens & Boblan's procedure: eq. 22 (sum of squared force errors)
    minimised by Nelder-Mead with MATLAB ``fminsearch`` defaults (TolX = TolFun
    = 1e-4, MaxIter = MaxFunEvals = 200 n, 5 % initial simplex; scipy's
    Nelder-Mead implements the same algorithm with the same defaults) from
    Table 1's start point.  Eqs. 22 and 23 run over the points with a measured
    force > 0 and the raw (unclipped) model: this is what reproduces Table 3.
    Never calibrated: the paper's geometry as given.

``best``
    What ships: the physical, clipped model fitted on the whole map by variable
    projection (:mod:`.separable`: the parameters a model is
    affine in solved exactly, the others searched on a grid and refined), with
    either objective ``least_squares`` (eq. 22) or ``minimax`` (eq. 23 itself).
    Optionally with geometry calibration (:mod:`.calibration`):
    the rest length L0 where the map proves the given one too short, a pressure
    offset where the map identifies it.

Every fit is judged by nested leave-one-length-out errors (:mod:`.selection`,
:mod:`.validation`): the whole protocol, calibration and choices included, re-run without each
measured length.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import functools
import math
from typing import Callable

import numpy as np

from . import calibration as cal
from .calibration import Calibration, OFF
from .force_map import ForceMap
from .map_checks import check_against_spec
from .separable import Separable, Solution
from .validation import HeldOut, length_folds, OBJECTIVES, within_tie
from ..physics.geometry import MuscleSpec
from ..physics.models import Domain, extrapolates, force_raw, get_model, Model
from ..physics.muscle_model import MuscleModel

#: The single-branch model each branch of a hysteresis model is.
BRANCH_MODEL = {'sarosi_hysteresis': 'sarosi'}


@dataclass(frozen=True)
class Fit:
    """One identified parameter set and its in-sample quality on the map."""

    model: str
    protocol: str  #: "paper" or "best"
    objective: str  #: "least_squares" or "minimax"
    theta: np.ndarray
    domain: Domain
    err: float  #: eq. 23 [%]
    rmse: float  #: [N]
    r2: float  #: coefficient of determination [-]
    spec: MuscleSpec  #: the geometry of the fit (L0 calibrated if ``calibration.length``)
    calibration: Calibration = OFF
    #: identified sensor offset [Pa] (0 unless ``calibration.pressure``)
    pressure_offset: float = 0.0
    #: uncertainty of the calibration: "pressure_offset": 1-sigma [Pa] from the Jacobian (inf: not
    #: identifiable); "nominal_length": half the range of L0 [m] whose sum of squares is within one
    #: residual variance of the best (present only where L0 was searched)
    sigma: dict[str, float] = field(default_factory=dict)
    #: the longest length [m] the map shows slack at low pressure, a lower bound of L0
    #: (:func:`~.calibration.slack_length`; None: none, or L0 not calibrated)
    slack_length: float | None = None

    def __getstate__(self) -> dict:
        """The fit without its :attr:`served` muscle (rebuilt on use; its prepared coefficients
        are closures, which do not pickle into worker processes).
        """
        state = dict(self.__dict__)
        state.pop('served', None)
        return state

    @functools.cached_property
    def served(self) -> MuscleModel:
        """The muscle as its parameter file serves it
        (:func:`~pma_model_ros.core.files.param_file.muscle_model` of what
        :mod:`pma_model_ros.core.files.param_writer` writes): the model's own value within the
        identified lengths, and beyond them the rule of
        :func:`~pma_model_ros.core.physics.models.extrapolates`.
        """
        model, theta = get_model(self.model), self.theta
        if self.calibration.pressure:
            model, theta = cal.shifted(model), np.r_[theta, self.pressure_offset]
        domain = replace(self.domain, extrapolates=extrapolates(self.model))
        return MuscleModel(self.spec, model, theta, domain)

    def force(
        self, pressure: np.ndarray, length: np.ndarray, direction: np.ndarray | None = None
    ) -> np.ndarray:
        """The served force [N] at sensor pressure [Pa] and length [m] (:attr:`served`: what
        ``evaluate``, ``force`` and the nodes serve from the fit's parameter file); a hysteresis
        model on the branch of ``direction`` (+1 lengthening or filling, -1 shortening or venting,
        as a map's direction column; None: unknown, the mean of both).
        """
        return np.nan_to_num(self.served.force(pressure, length, direction).force)


def domain_of(fmap: ForceMap) -> Domain:
    """The identified length and pressure ranges of a map (not extrapolating until judged:
    :class:`~.selection.ModelReport`); a fit needs at least two lengths.
    """
    if fmap.lengths.size < 2:
        raise ValueError(f'a fit needs a force map of at least two lengths, got {fmap.lengths}')
    return Domain(float(fmap.length.min()), float(fmap.length.max()), float(fmap.pressure.max()))


#: [fraction of the max force] Two measurements of one point (pressure, length, direction) that
#: differ by more than this conflict: 5 sigma of 1 % noise each (:data:`~.calibration._PULLING`).
_CONFLICT = 0.07


def check_fit_map(fmap: ForceMap, spec: MuscleSpec, folds: int) -> None:
    """Refuse (ValueError) a map no fit of ``spec`` can use, naming why, before any fitting:
    fewer than ``folds`` held-out lengths (3 to judge a fit on an interior length, 2 to fit at
    all), a map the spec's braid cannot have measured (:func:`~.map_checks.check_against_spec`),
    conflicting repeated points.
    """
    have = len(length_folds(fmap))
    if have < folds:
        lengths = ', '.join(f'{L:g}' for L in fmap.lengths)
        raise ValueError(
            f'a fit needs a map of at least {folds} lengths, got {have} ({lengths} m): '
            + (
                'with 2 no length is held out between others to judge the fit; measure one '
                f'between {fmap.lengths[-1]:g} and {fmap.lengths[0]:g} m'
                if have == 2
                else 'measure the force map at several lengths between full contraction and L0'
            )
        )
    check_against_spec(fmap, spec)
    direction = np.zeros(fmap.force.size) if fmap.direction is None else fmap.direction
    points = np.column_stack([fmap.pressure, fmap.length, direction])
    _, group = np.unique(points, axis=0, return_inverse=True)
    spread = np.zeros(group.max() + 1)
    for index in range(spread.size):
        forces = fmap.force[group == index]
        spread[index] = forces.max() - forces.min()
    conflicts = np.flatnonzero(spread > _CONFLICT * fmap.max_force)
    if conflicts.size:
        at = group == conflicts[0]
        raise ValueError(
            f'{conflicts.size} point(s) measured twice with forces more than '
            f'{100 * _CONFLICT:g} % of the max force apart, e.g. {fmap.pressure[at][0]:g} Pa, '
            f'{fmap.length[at][0]:g} m: {", ".join(f"{f:g}" for f in fmap.force[at])} N; '
            'keep one measurement per point, or tell the branches of a hysteresis apart with a '
            'direction column'
        )


def physical_force(
    model: Model,
    theta: np.ndarray,
    spec: MuscleSpec,
    domain: Domain,
    pressure: np.ndarray,
    length: np.ndarray,
) -> np.ndarray:
    """Model force clipped at 0 N (a muscle cannot push) [N]."""
    return np.maximum(force_raw(model, theta, spec, domain, pressure, length), 0.0)


def max_error_percent(measured: np.ndarray, predicted: np.ndarray, max_force: float) -> float:
    """Eq. 23: 100 max|F_meas - F_model| / max(F_meas) [%]."""
    return float(100 * np.max(np.abs(measured - predicted)) / max_force)


def quality(
    measured: np.ndarray, predicted: np.ndarray, max_force: float
) -> tuple[float, float, float]:
    """(eq. 23 [%], RMSE [N], R^2 [-]) of ``predicted`` against ``measured``."""
    resid = measured - predicted
    total = np.sum((measured - measured.mean()) ** 2)
    return (
        max_error_percent(measured, predicted, max_force),
        float(np.sqrt(np.mean(resid**2))),
        float(1 - np.sum(resid**2) / total) if total > 0 else float('nan'),
    )


def _fit_record(
    model,
    protocol,
    objective,
    theta,
    spec,
    domain,
    fmap,
    mask,
    clip,
    calibration: Calibration = OFF,
    offset: float = 0.0,
    sigma: dict | None = None,
    branch: np.ndarray | float = 0.0,
    slack: float | None = None,
) -> Fit:
    shifted = cal.shifted(model) if calibration.pressure else model
    f = force_raw(
        shifted,
        np.r_[theta, offset] if calibration.pressure else theta,
        spec,
        domain,
        fmap.pressure,
        fmap.length,
        branch,
    )
    f = np.maximum(f, 0.0) if clip else f
    return Fit(
        model.name,
        protocol,
        objective,
        np.asarray(theta, float),
        domain,
        *quality(fmap.force[mask], f[mask], fmap.max_force),
        spec,
        calibration,
        float(offset),
        sigma or {},
        slack,
    )


def fit_paper(model: Model, spec: MuscleSpec, fmap: ForceMap) -> Fit:
    """The paper's protocol (see module docstring); err over the points with force > 0."""
    domain, pulled = domain_of(fmap), fmap.force > 0
    theta = _paper_theta(model, spec, fmap.subset(pulled), domain)
    return _fit_record(
        model, 'paper', 'least_squares', theta, spec, domain, fmap, pulled, clip=False
    )


def _paper_theta(model: Model, spec: MuscleSpec, fmap: ForceMap, domain: Domain) -> np.ndarray:
    from scipy.optimize import minimize  # here: force and pressure need no optimizer

    if model.n_params == 0:
        return np.zeros(0)
    n = model.n_params

    def sse(theta: np.ndarray) -> float:
        return float(
            np.sum(
                (fmap.force - force_raw(model, theta, spec, domain, fmap.pressure, fmap.length))
                ** 2
            )
        )

    result = minimize(
        sse,
        np.array(model.start, float),
        method='Nelder-Mead',
        options={'xatol': 1e-4, 'fatol': 1e-4, 'maxiter': 200 * n, 'maxfev': 200 * n},
    )
    return result.x


def fit_best(
    model: Model,
    spec: MuscleSpec,
    fmap: ForceMap,
    objective: str = 'least_squares',
    calibration: Calibration = OFF,
) -> Fit:
    """The ``best`` protocol on the whole map with the clipped model (module docstring); a
    hysteresis model is :func:`fit_branches` (uncalibrated).
    """
    if model.hysteresis:
        return fit_branches(model, spec, fmap, objective)
    return fit_best_all(model, spec, fmap, (objective,), calibration)[objective]


def fit_branches(
    model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str = 'least_squares'
) -> Fit:
    """A two-branch model (``sarosi_hysteresis``: upper then lower Sárosi eq. 19 parameters) from a
    map whose points carry their ``direction``: the single-branch model fitted on each direction's
    points.
    """
    if fmap.direction is None or not {-1.0, 1.0} <= set(fmap.direction.tolist()):
        raise ValueError(
            f"model {model.name!r} needs a force map with a 'direction' column holding both +1 "
            '(lengthening or filling) and -1 (shortening or venting) points'
        )
    branch = get_model(BRANCH_MODEL[model.name])
    up, down = (
        fit_best(branch, spec, fmap.subset(fmap.direction == d), objective).theta
        for d in (1.0, -1.0)
    )
    theta = np.concatenate([up, down])
    return _fit_record(
        model,
        'best',
        objective,
        theta,
        spec,
        domain_of(fmap),
        fmap,
        np.ones(fmap.force.size, bool),
        True,
        branch=fmap.direction,
    )


def judge_branches(
    model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str = 'least_squares'
) -> tuple[Fit, np.ndarray]:
    """:func:`fit_branches` on the whole map and its held-out err per fold [%] (nothing is chosen
    among candidates, so leave-one-length-out is nested): each fold predicted, on its points'
    branches, by the force the fit without it serves there.
    """
    held = HeldOut(fmap, functools.partial(_branch_fits, model, spec, objective=objective))
    return held.fits_without(frozenset())[objective], held.errors(objective)


def _branch_fits(model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str) -> dict:
    return {objective: fit_branches(model, spec, fmap, objective)}


def fit_best_all(
    model: Model,
    spec: MuscleSpec,
    fmap: ForceMap,
    objectives: tuple[str, ...] = OBJECTIVES,
    calibration: Calibration = OFF,
) -> dict[str, Fit]:
    """:func:`fit_best` for several objectives (the minimax fit starts from the least-squares one),
    with the geometry calibration of :mod:`~pma_model_ros.core.identification.calibration`: L0
    first (only where the map proves the given one too short), then the pressure offset (kept where
    identified).
    """
    unknown = set(objectives) - set(OBJECTIVES)
    if unknown:
        raise ValueError(f'unknown objective {sorted(unknown)}; choose from {OBJECTIVES}')
    domain = domain_of(fmap)
    sigma: dict[str, float] = {}
    # L0 is at least the longest measured length, taut or slack (a muscle is not stretched)
    raised = calibration.length and cal.short_of_map(spec, fmap) is not None
    if raised:
        spec = cal.with_length(spec, domain.length_max)
    slack = cal.slack_length(fmap) if calibration.length else None
    offset = _offset(model, spec, domain, fmap, sigma) if calibration.pressure else None
    found = offset if offset is not None and offset[2] else None
    # A length slack at low pressure is not stretched: L0 is at least that long, and longer unless
    # a threshold (the offset) makes that length L0 itself: then the better fit of the two wins.
    # A row of cell means holds samples up to one cell above its length.
    moved = False
    if slack is not None and spec.nominal_length <= slack + fmap.length_cell:
        longer, spread, moved = _rest_length(model, spec, fmap, domain, slack)
        sigma['nominal_length'] = spread
        if moved:
            trial = Separable(model, longer, domain, fmap)
            plain = (trial, trial.fit_least_squares(), False)
            if calibration.pressure:
                again = _offset(model, longer, domain, fmap, sigma)
                plain = again if again[2] else plain
            if found is None or plain[1].cost < found[1].cost:
                spec, found = longer, plain
            else:
                moved = False
    shifted = found is not None and found[2]
    if found is not None:
        fitted, solution = found[0], found[1]
    else:
        fitted = Separable(model, spec, domain, fmap)
        solution = fitted.fit_least_squares()
    solutions = {'least_squares': solution}
    if 'minimax' in objectives:
        solutions['minimax'] = fitted.fit_minimax(solution)
    applied = Calibration(moved or raised, shifted)
    n = model.n_params
    return {
        obj: _fit_record(
            model,
            'best',
            obj,
            solutions[obj].theta[:n],
            spec,
            domain,
            fmap,
            np.ones(fmap.force.size, bool),
            True,
            applied,
            float(solutions[obj].theta[n]) if shifted else 0.0,
            dict(sigma),
            slack=slack,
        )
        for obj in objectives
    }


def _rest_length(
    model: Model, spec: MuscleSpec, fmap: ForceMap, domain: Domain, slack: float
) -> tuple[MuscleSpec, float, bool]:
    """L0 identified above the slack bound (:mod:`.calibration`) by held-out error: on the grid
    of :func:`~.calibration.length_grid`, the L0 whose least-squares fits without each length
    predict it best (least sum of squares; each fold follows its optimum along the grid).
    In-sample, the elastic terms absorb a wrong L0.  Returns (spec, 1-sigma [m],
    whether L0 moved): half the range of L0 whose held-out RMSE is within 10 % of the best (a flat
    choice says so by its spread).  L0 stays as given (inf) for a model that ignores or absorbs it
    (Hildebrandt, Wickramatunge; Sárosi, whose exp(c2 kappa) and d0 kappa take any L0) and on a
    map of fewer than three lengths.
    """
    grid = cal.length_grid(spec, slack)
    folds = length_folds(fmap)
    if len(folds) < 3 or _absorbs_length(model, spec, domain, fmap, grid[-1]):
        return spec, math.inf, False
    # every other grid point first (each fold following its optimum), then the two beside the best
    squares = np.full(grid.size, np.inf)
    trains = [fmap.subset(~test) for test in folds]
    solved: list[dict[int, Solution]] = [{} for _ in folds]

    def judge(i: int, start: Callable[[int], Solution | None]) -> None:
        trial, total = cal.with_length(spec, float(grid[i])), 0.0
        for k, (test, train) in enumerate(zip(folds, trains)):
            solution = Separable(model, trial, domain_of(train), train).fit_least_squares(start(k))
            solved[k][i] = solution
            predicted = physical_force(
                model,
                solution.theta,
                trial,
                domain_of(train),
                fmap.pressure[test],
                fmap.length[test],
            )
            total += float(np.sum((fmap.force[test] - predicted) ** 2))
        squares[i] = total

    coarse = range(0, grid.size, 2)
    for j, i in enumerate(coarse):
        judge(i, lambda k, j=j: solved[k][coarse[j - 1]] if j else None)
    middle = int(np.argmin(squares))
    for i in (middle - 1, middle + 1):
        if 0 <= i < grid.size:
            judge(i, lambda k: solved[k][middle])
    step, evaluated = grid[1] - grid[0], np.isfinite(squares)
    grid, squares = grid[evaluated], squares[evaluated]
    best = int(np.argmin(squares))
    near_best = grid[squares <= squares[best] * 1.1**2]
    spread = float(near_best.max() - near_best.min() + step) / 2
    return cal.with_length(spec, float(grid[best])), spread, True


def _absorbs_length(
    model: Model, spec: MuscleSpec, domain: Domain, fmap: ForceMap, longer: float
) -> bool:
    """Whether the model fits the map exactly as well at L0 and at ``longer`` (sums of squares
    equal within a tie): its force ignores L0, or its parameters take any L0.
    """
    costs = [
        Separable(model, cal.with_length(spec, length), domain, fmap).fit_least_squares().cost
        for length in (spec.nominal_length, longer)
    ]
    return within_tie(max(costs), min(costs))


def _offset(
    model: Model, spec: MuscleSpec, domain: Domain, fmap: ForceMap, sigma: dict[str, float]
) -> tuple[Separable, Solution, bool]:
    """The least-squares fit with a pressure offset, its 1-sigma into ``sigma``, and whether the
    offset is identified (:func:`~.calibration.offset_identifiable`).
    """
    fitted = Separable(cal.shifted(model), spec, domain, fmap)
    solution = fitted.fit_least_squares()
    sigma['pressure_offset'] = _offset_sigma(fitted, solution)
    return (
        fitted,
        solution,
        cal.offset_identifiable(float(solution.theta[-1]), sigma['pressure_offset']),
    )


def _offset_sigma(fitted: Separable, solution: Solution) -> float:
    """1-sigma [Pa] of the pressure offset (the last parameter of ``fitted``'s shifted model) from
    the Jacobian of the clipped residuals at the least-squares optimum.
    """
    model, theta = fitted.model, solution.theta
    scale = np.where(theta != 0, np.abs(theta), 1.0)
    scale[-1] = cal.PRESSURE_BOUND

    def residuals(x: np.ndarray) -> np.ndarray:
        return fitted.force - physical_force(
            model, x, fitted.spec, fitted.domain, fitted.pressure, fitted.length
        )

    with np.errstate(all='ignore'):
        errors = cal.standard_errors(cal.jacobian(residuals, theta, scale), residuals(theta))
    return float(errors[-1])
