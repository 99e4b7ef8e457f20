"""Identification of model parameters from a measured force map.

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
    What ships: bounded multi-start fits (scipy ``least_squares``, trust region
    reflective) of the physical, clipped model on the whole map, with either
    objective ``least_squares`` (eq. 22) or ``minimax`` (eq. 23 itself, by
    SLSQP on the epigraph form, polished by Nelder-Mead).  Equal-cost
    solutions (an under-determined fit) are resolved towards Table 1's start.
    Optionally with geometry calibration (:mod:`pma_model_ros.core.calibration`):
    the rest length L0 and a pressure offset identified with the parameters.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from itertools import repeat
import multiprocessing
import os
from typing import Iterator
import warnings

import numpy as np
from scipy.optimize import least_squares, minimize

from . import calibration as cal
from .calibration import Calibration, OFF
from .force_map import ForceMap
from .geometry import MuscleSpec
from .models import Domain, force_raw, get_model, Model

OBJECTIVES = ('least_squares', 'minimax')
#: The single-branch model each branch of a hysteresis model is.
BRANCH_MODEL = {'sarosi_hysteresis': 'sarosi'}
_N_RANDOM_STARTS = 4
_TIE = 1e-6
_LENGTH_GRID = 41  #: grid points of the held-out choice of L0 over its bounds (steps of 0.25 %)
_MAX_FOLDS = 8  #: most held-out groups of a cross-validation
_LENGTH_CANDIDATES = 5  #: of these, judged by the worst held-out err of multi-start fits
#: Set in the worker processes of :func:`identify_all` (unless the user set them).  OpenBLAS's idle
#: threads spin 2^28 cycles (~0.1 s) after each threaded call before they sleep: in a worker that
#: spinning takes the shared cores from the other workers.  2^4 cycles: they sleep at once (same
#: threads, same partition of the work, so the same numbers).
_WORKER_ENVIRONMENT = {'OPENBLAS_THREAD_TIMEOUT': '4'}


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
    #: identifiable); "nominal_length": half the L0 range [m] whose held-out RMSE is within 10 % of
    #: the best (inf: no L0 in model)
    sigma: dict[str, float] = field(default_factory=dict)

    def force(self, pressure: np.ndarray, length: np.ndarray) -> np.ndarray:
        """The fitted model's physical force [N] at sensor pressure [Pa] and length [m], as
        identified (unclipped L).
        """
        model, theta = get_model(self.model), self.theta
        if self.calibration.pressure:
            model, theta = cal.shifted(model), np.r_[theta, self.pressure_offset]
        return physical_force(model, theta, self.spec, self.domain, pressure, length)


def domain_of(fmap: ForceMap) -> Domain:
    """The identified length and pressure ranges of a map (not extrapolating until judged:
    :class:`ModelReport`).
    """
    return Domain(float(fmap.length.min()), float(fmap.length.max()), float(fmap.pressure.max()))


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
    )


def fit_paper(model: Model, spec: MuscleSpec, fmap: ForceMap) -> Fit:
    """The paper's protocol (see module docstring); err over the points with force > 0."""
    domain, pulled = domain_of(fmap), fmap.force > 0
    theta = _paper_theta(model, spec, fmap.subset(pulled), domain)
    return _fit_record(
        model, 'paper', 'least_squares', theta, spec, domain, fmap, pulled, clip=False
    )


def _paper_theta(model: Model, spec: MuscleSpec, fmap: ForceMap, domain: Domain) -> np.ndarray:
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
    seed: int = 0,
    calibration: Calibration = OFF,
) -> Fit:
    """The ``best`` protocol on the whole map with the clipped model (module docstring); a
    hysteresis model is :func:`fit_branches` (uncalibrated).
    """
    if model.hysteresis:
        return fit_branches(model, spec, fmap, objective, seed)
    return fit_best_all(model, spec, fmap, (objective,), seed, calibration)[objective]


def fit_branches(
    model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str = 'least_squares', seed: int = 0
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
        fit_best(branch, spec, fmap.subset(fmap.direction == d), objective, seed).theta
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


def fit_best_all(
    model: Model,
    spec: MuscleSpec,
    fmap: ForceMap,
    objectives: tuple[str, ...] = OBJECTIVES,
    seed: int = 0,
    calibration: Calibration = OFF,
) -> dict[str, Fit]:
    """:func:`fit_best` for several objectives; the least-squares multi-start runs once for all."""
    unknown = set(objectives) - set(OBJECTIVES)
    if unknown:
        raise ValueError(f'unknown objective {sorted(unknown)}; choose from {OBJECTIVES}')
    domain = domain_of(fmap)
    problem = _Problem(model, spec, fmap, domain, calibration)
    sigma, applied = {}, calibration
    if calibration.any:  # identify only what the map can; the others stay as given
        joint = _best_solutions(problem, ('least_squares',), seed)['least_squares']
        sigma = problem.sigma(joint)
        applied = calibration.identifiable(sigma)
        if applied.length:
            correction, low, high = _held_out_length(model, spec, fmap, applied, seed)
            sigma['nominal_length'] = (high - low) / 2 * spec.nominal_length
            if high - low <= cal.LENGTH_BOUND:  # a held-out optimum narrower than half the bounds
                spec = cal.with_length(spec, spec.nominal_length * (1 + correction))
            else:
                applied = Calibration(False, applied.pressure)
        problem = _Problem(model, spec, fmap, domain, Calibration(False, applied.pressure))
    solutions = _best_solutions(problem, objectives, seed)
    everywhere = np.ones(fmap.force.size, bool)
    fits = {}
    for obj in objectives:
        theta, offset = problem.unpack(solutions[obj])
        fits[obj] = _fit_record(
            model,
            'best',
            obj,
            theta,
            spec,
            domain,
            fmap,
            everywhere,
            True,
            applied,
            offset,
            sigma | problem.sigma(solutions[obj]),
        )
    return fits


def _held_out_length(
    model: Model, spec: MuscleSpec, fmap: ForceMap, calibration: Calibration, seed: int
) -> tuple[float, float, float]:
    """The relative correction of L0 [-] chosen by leave-one-length-out error of least-squares
    fits, and the range [low, high] of corrections whose held-out RMSE is within 10 % of the
    lowest.

    In-sample, the elastic terms of a model absorb a wrong L0 (the sum of squares keeps falling
    towards a bound); the force at a length left out does not, so L0 is chosen by held-out error,
    on a grid of
    :data:`_LENGTH_GRID` corrections over the bounds.  Each fold starts from its multi-start fit at
    the given L0 and follows its optimum along the grid (one least-squares run from the
    neighbouring grid point).  Of the :data:`_LENGTH_CANDIDATES` corrections with the lowest
    held-out RMSE, the one whose multi-start fits (:func:`cross_validate`, least squares) have the
    lowest worst held-out err (eq. 23) is chosen.
    """
    within = Calibration(False, calibration.pressure)
    folds = [(test, fmap.subset(~test)) for test in length_folds(fmap)]
    grid = np.linspace(-cal.LENGTH_BOUND, cal.LENGTH_BOUND, _LENGTH_GRID)
    given = int(np.argmin(np.abs(grid)))

    def problem(correction: float, train: ForceMap) -> _Problem:
        trial = cal.with_length(spec, spec.nominal_length * (1 + correction))
        return _Problem(model, trial, train, domain_of(train), within)

    starts = [
        _best_solutions(problem(grid[given], train), ('least_squares',), seed)['least_squares']
        for _, train in folds
    ]
    squares = np.full(grid.size, np.inf)
    for path in (range(given, grid.size), range(given, -1, -1)):
        x = list(starts)
        for i in path:
            total = 0.0
            for k, (test, train) in enumerate(folds):
                fold = problem(grid[i], train)
                cost, x_k = min(_solve(fold, x[k]), _solve(fold, fold.start), key=lambda c: c[0])
                if not np.isfinite(cost):
                    total = np.inf
                    break
                x[k] = x_k
                predicted = physical_force(
                    fold.evaluated,
                    x_k,
                    fold.spec,
                    fold.domain,
                    fmap.pressure[test],
                    fmap.length[test],
                )
                total += float(np.sum((fmap.force[test] - predicted) ** 2))
            squares[i] = total
    near = grid[squares <= squares.min() * 1.1**2]
    step = grid[1] - grid[0]  # the range of a grid point is its cell
    low, high = float(near.min() - step / 2), float(near.max() + step / 2)
    if high - low > cal.LENGTH_BOUND:  # not identifiable (fit_best_all keeps L0): no need to judge
        return float(grid[np.argmin(squares)]), low, high
    candidates = grid[np.argsort(squares)[:_LENGTH_CANDIDATES]]
    worst = [
        cross_validate(model, problem(c, fmap).spec, fmap, ('least_squares',), within)[
            'least_squares'
        ].max()
        for c in candidates
    ]
    return float(candidates[int(np.argmin(worst))]), low, high


def _solve(problem: '_Problem', x0: np.ndarray) -> tuple[float, np.ndarray]:
    """One bounded least-squares run (trust region reflective) from ``x0``: (sum of squares [N^2],
    x); inf if the model is not finite there (a length beyond the fibre length).
    """
    span = problem.upper - problem.lower
    x0 = np.clip(x0, problem.lower + 1e-9 * span, problem.upper - 1e-9 * span)
    with np.errstate(all='ignore'):
        residuals = problem.residuals(x0)
    if not np.all(np.isfinite(residuals)):
        return np.inf, x0
    if x0.size == 0:
        return float(np.sum(residuals**2)), x0
    with np.errstate(all='ignore'), warnings.catch_warnings():
        warnings.simplefilter('ignore')
        result = least_squares(
            problem.residuals,
            x0,
            bounds=(problem.lower, problem.upper),
            x_scale='jac',
            method='trf',
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=5000,
        )
    return float(np.sum(result.fun**2)), result.x


class _Problem:
    """The ``best`` fit's unknowns x = [model parameters, pressure offset [Pa]?, relative L0
    correction?].

    The L0 correction is an unknown of the joint fit only, whose Jacobian tells whether the model
    depends on L0; its value is chosen by held-out error (:func:`_held_out_length`) and then fixed
    in ``spec``.
    """

    def __init__(
        self,
        model: Model,
        spec: MuscleSpec,
        fmap: ForceMap,
        domain: Domain,
        calibration: Calibration,
    ):
        self.model, self.spec, self.fmap, self.domain, self.calibration = (
            model,
            spec,
            fmap,
            domain,
            calibration,
        )
        self.evaluated = cal.shifted(model) if calibration.pressure else model
        extra = [cal.LENGTH_BOUND] * calibration.length
        self.lower = np.r_[self.evaluated.lower, [-b for b in extra]]
        self.upper = np.r_[self.evaluated.upper, extra]
        self.start = np.r_[self.evaluated.start, [0.0] * len(extra)]
        n = model.n_params
        #: size of each unknown for tie-breaking and difference steps: Table 1's start, else the
        #: bound
        self.scale = np.r_[
            np.where(self.start[:n] != 0, np.abs(self.start[:n]), 1.0), self.upper[n:]
        ]

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """(model parameters, pressure offset [Pa]) of a solution with L0 fixed."""
        n = self.model.n_params
        return x[:n], float(x[n]) if self.calibration.pressure else 0.0

    def residuals(self, x: np.ndarray) -> np.ndarray:
        spec = (
            cal.with_length(self.spec, self.spec.nominal_length * (1 + x[-1]))
            if self.calibration.length
            else self.spec
        )
        theta = x[:-1] if self.calibration.length else x
        return self.fmap.force - physical_force(
            self.evaluated, theta, spec, self.domain, self.fmap.pressure, self.fmap.length
        )

    def random_start(self, paper: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The paper fit times 10^U(-0.5, 0.5); the calibrated quantities as given (the nearest
        optimum is found).
        """
        return np.r_[
            paper * 10 ** rng.uniform(-0.5, 0.5, paper.size),
            [0.0] * (self.start.size - paper.size),
        ]

    def sigma(self, x: np.ndarray) -> dict[str, float]:
        """1-sigma of the calibrated L0 [m] and pressure offset [Pa]
        (:func:`calibration.standard_errors`).
        """
        if not self.calibration.any:
            return {}
        with np.errstate(all='ignore'):
            errors = cal.standard_errors(
                cal.jacobian(self.residuals, x, self.scale), self.residuals(x)
            )
        out = {}
        if self.calibration.pressure:
            out['pressure_offset'] = float(errors[self.model.n_params])
        if self.calibration.length:
            out['nominal_length'] = float(errors[-1] * self.spec.nominal_length)
        return out


def _best_solutions(
    problem: _Problem, objectives: tuple[str, ...], seed: int
) -> dict[str, np.ndarray]:
    model, fmap, domain = problem.model, problem.fmap, problem.domain
    if problem.start.size == 0:
        return {obj: np.zeros(0) for obj in objectives}
    lower, upper, start, scale = problem.lower, problem.upper, problem.start, problem.scale
    n_extra = start.size - model.n_params
    rng = np.random.default_rng(seed)
    paper = _paper_theta(model, problem.spec, fmap.subset(fmap.force > 0), domain)
    starts = [start, np.r_[paper, [0.0] * n_extra]] + [
        problem.random_start(paper, rng) for _ in range(_N_RANDOM_STARTS)
    ]
    candidates = [c for c in (_solve(problem, x0) for x0 in starts) if np.isfinite(c[0])]
    tied = _ties(candidates, start, scale)
    solutions = {'least_squares': tied[0][1]}
    if 'minimax' in objectives:
        solutions['minimax'] = _ties(
            [_minimax(problem.residuals, x, lower, upper) for _, x in tied], start, scale
        )[0][1]
    return solutions


def _ties(candidates: list, start: np.ndarray, scale: np.ndarray) -> list:
    """Candidates within a relative _TIE of the best cost, nearest to ``start`` first."""
    best = min(cost for cost, _ in candidates)
    tied = [c for c in candidates if c[0] <= best * (1 + _TIE) + 1e-12]
    return sorted(tied, key=lambda c: float(np.linalg.norm((c[1] - start) / scale)))


def _minimax(
    residuals, theta0: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> tuple[float, np.ndarray]:
    """Minimise max|r(theta)| from theta0 in variables scaled by theta0; returns (cost, theta)."""
    scale = np.where(theta0 != 0, np.abs(theta0), 1.0)
    z0 = theta0 / scale

    def worst(z: np.ndarray) -> float:
        theta = z * scale
        if np.any(theta < lower) or np.any(theta > upper):
            return np.inf
        return float(np.max(np.abs(residuals(theta))))

    t0 = worst(z0)

    def within(y: np.ndarray) -> np.ndarray:
        """Both sides of |r| <= t, [t - r, t + r] >= 0 at y = [z, t] [N]: r evaluated once."""
        r = residuals(y[:-1] * scale)
        return np.r_[y[-1] - r, y[-1] + r]

    constraints = [{'type': 'ineq', 'fun': within}]
    bounds = [
        (lo / s, hi / s) if s > 0 else (None, None) for lo, hi, s in zip(lower, upper, scale)
    ] + [(0, None)]
    with np.errstate(all='ignore'), warnings.catch_warnings():
        warnings.simplefilter('ignore')
        slsqp = minimize(
            lambda y: y[-1],
            np.r_[z0, t0],
            method='SLSQP',
            constraints=constraints,
            bounds=bounds,
            options={'maxiter': 500, 'ftol': 1e-12},
        )
        z1 = slsqp.x[:-1] if worst(slsqp.x[:-1]) < t0 else z0
        polish = minimize(
            worst,
            z1,
            method='Nelder-Mead',
            options={'xatol': 1e-10, 'fatol': 1e-10, 'maxiter': 4000, 'maxfev': 4000},
        )
    best = min((z0, z1, polish.x), key=worst)
    return worst(best) ** 2, best * scale


def length_folds(fmap: ForceMap) -> list[np.ndarray]:
    """The held-out groups of points: each measured length, or, with more than :data:`_MAX_FOLDS`
    lengths (the cells of a recording), :data:`_MAX_FOLDS` bands of neighbouring lengths, longest
    first.
    """
    lengths = fmap.lengths
    groups = (
        [[length] for length in lengths]
        if lengths.size <= _MAX_FOLDS
        else np.array_split(lengths, _MAX_FOLDS)
    )
    return [np.isin(fmap.length, group) for group in groups]


def fold_lengths(fmap: ForceMap) -> np.ndarray:
    """The mean length [m] of each fold of :func:`length_folds`."""
    return np.array([fmap.length[test].mean() for test in length_folds(fmap)])


def cross_validate(
    model: Model,
    spec: MuscleSpec,
    fmap: ForceMap,
    objectives: tuple[str, ...] = OBJECTIVES,
    calibration: Calibration = OFF,
    truth: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Leave-one-length-out: eq. 23 on each held-out length, normalised by the whole map's max
    force [%].

    Returns, per objective, one error per fold of :func:`length_folds` (per measured length, in the
    order of ``fmap.lengths``, on a table's map).  ``truth``: the forces [N] at the map's points to
    judge against (e.g. noise-free ones); default the map's own.
    """
    truth = fmap.force if truth is None else truth
    errors: dict[str, list[float]] = {obj: [] for obj in objectives}
    for test in length_folds(fmap):
        for obj, fit in fit_best_all(
            model, spec, fmap.subset(~test), objectives, calibration=calibration
        ).items():
            predicted = fit.force(fmap.pressure[test], fmap.length[test])
            errors[obj].append(max_error_percent(truth[test], predicted, truth.max()))
    return {obj: np.array(errs) for obj, errs in errors.items()}


def cross_validate_fit(
    fit: Fit,
    fmap: ForceMap,
    objectives: tuple[str, ...] = OBJECTIVES,
    truth: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """:func:`cross_validate` of a fit's model with its geometry: its calibrated L0 (chosen on the
    whole map by held-out error, :func:`_held_out_length`), the pressure offset identified again in
    each fold.
    """
    return cross_validate(
        get_model(fit.model),
        fit.spec,
        fmap,
        objectives,
        Calibration(False, fit.calibration.pressure),
        truth,
    )


@dataclass(frozen=True)
class ModelReport:
    """Everything the paper's Table 3 and our cross-validation say about one model."""

    paper: Fit  #: the paper protocol
    best: dict[str, Fit]  #: best protocol, per objective
    cv: dict[str, np.ndarray]  #: held-out err per length [%], per objective
    shipped_objective: str  #: the objective with the lower worst held-out err

    @property
    def shipped(self) -> Fit:
        return self.best[self.shipped_objective]

    @property
    def best_err(self) -> float:
        """Lowest in-sample err of the best protocol [%]."""
        return min(fit.err for fit in self.best.values())

    @property
    def cv_err(self) -> float:
        """Worst held-out err of the shipped objective [%]."""
        return float(self.cv[self.shipped_objective].max())

    @property
    def edge_cv_err(self) -> float:
        """Worst held-out err of the shipped objective on the map's shortest and longest length
        [%].
        """
        errors = self.cv[self.shipped_objective]
        return float(max(errors[0], errors[-1]))


def identify_all(
    spec: MuscleSpec, fmap: ForceMap, models: tuple[Model, ...], calibration: Calibration = OFF
) -> tuple[dict[str, ModelReport], str]:
    """Identify every model both ways, cross-validate, and pick the default model.

    The shipped objective of each model and the default model are chosen by the
    worst leave-one-length-out error, not by in-sample error.  ``calibration``
    applies to the ``best`` protocol only (held out: :func:`cross_validate_fit`); the paper
    protocol keeps the given geometry.
    """
    # The models are independent: one process each, as many at once as there are cores (spawned,
    # not forked: the caller may hold threads).
    workers = min(len(models), os.cpu_count() or 1)
    if workers > 1:
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context('spawn'))
        with _environment(_WORKER_ENVIRONMENT), pool:
            done = list(pool.map(_report, models, repeat(spec), repeat(fmap), repeat(calibration)))
    else:
        done = [_report(model, spec, fmap, calibration) for model in models]
    reports = {model.name: report for model, report in zip(models, done)}
    default = min(reports, key=lambda name: reports[name].cv_err)
    return reports, default


@contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` where unset, for the processes started inside; restored on
    exit.
    """
    added = {key: value for key, value in values.items() if key not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            del os.environ[key]


def _report(
    model: Model, spec: MuscleSpec, fmap: ForceMap, calibration: Calibration
) -> ModelReport:
    """One model of :func:`identify_all`: both protocols, cross-validated."""
    best = fit_best_all(model, spec, fmap, calibration=calibration)
    cv = cross_validate_fit(best['least_squares'], fmap)
    shipped = min(OBJECTIVES, key=lambda obj: cv[obj].max())
    return ModelReport(fit_paper(model, spec, fmap), best, cv, shipped)
