"""Identification of model parameters from a measured force map.

Two protocols:

``paper``
    Martens & Boblan's procedure: eq. 22 (sum of squared force errors)
    minimised by Nelder-Mead with MATLAB ``fminsearch`` defaults (TolX = TolFun
    = 1e-4, MaxIter = MaxFunEvals = 200 n, 5 % initial simplex; scipy's
    Nelder-Mead implements the same algorithm with the same defaults) from
    Table 1's start point.  Eqs. 22 and 23 run over the points with a measured
    force > 0 and the raw (unclipped) model: this is what reproduces Table 3.

``best``
    What ships: bounded multi-start fits (scipy ``least_squares``, trust region
    reflective) of the physical, clipped model on the whole map, with either
    objective ``least_squares`` (eq. 22) or ``minimax`` (eq. 23 itself, by
    SLSQP on the epigraph form, polished by Nelder-Mead).  Equal-cost
    solutions (an under-determined fit) are resolved towards Table 1's start.
"""
from __future__ import annotations

from dataclasses import dataclass
import warnings

import numpy as np
from scipy.optimize import least_squares, minimize

from .force_map import ForceMap
from .models import Domain, Model, force_raw, get_model
from .muscle import MuscleSpec

OBJECTIVES = ("least_squares", "minimax")
#: The single-branch model each branch of a hysteresis model is.
BRANCH_MODEL = {"sarosi_hysteresis": "sarosi"}
_N_RANDOM_STARTS = 4
_TIE = 1e-6


@dataclass(frozen=True)
class Fit:
    """One identified parameter set and its in-sample quality on the map."""

    model: str
    protocol: str          #: "paper" or "best"
    objective: str         #: "least_squares" or "minimax"
    theta: np.ndarray
    domain: Domain
    err: float             #: eq. 23 [%]
    rmse: float            #: [N]
    r2: float              #: coefficient of determination [-]


def domain_of(fmap: ForceMap) -> Domain:
    """The identified length and pressure ranges of a map (not extrapolating until judged: :class:`ModelReport`)."""
    return Domain(float(fmap.length.min()), float(fmap.length.max()), float(fmap.pressure.max()))


def physical_force(model: Model, theta: np.ndarray, spec: MuscleSpec, domain: Domain,
                   pressure: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Model force clipped at 0 N (a muscle cannot push) [N]."""
    return np.maximum(force_raw(model, theta, spec, domain, pressure, length), 0.0)


def max_error_percent(measured: np.ndarray, predicted: np.ndarray, max_force: float) -> float:
    """Eq. 23: 100 max|F_meas - F_model| / max(F_meas) [%]."""
    return float(100 * np.max(np.abs(measured - predicted)) / max_force)


def _fit_record(model, protocol, objective, theta, spec, domain, fmap, mask, clip, branch=0.0) -> Fit:
    f = force_raw(model, theta, spec, domain, fmap.pressure, fmap.length, branch)
    f = np.maximum(f, 0.0) if clip else f
    resid = fmap.force[mask] - f[mask]
    total = np.sum((fmap.force[mask] - fmap.force[mask].mean()) ** 2)
    return Fit(model.name, protocol, objective, np.asarray(theta, float), domain,
               max_error_percent(fmap.force[mask], f[mask], fmap.max_force),
               float(np.sqrt(np.mean(resid**2))), float(1 - np.sum(resid**2) / total))


def fit_paper(model: Model, spec: MuscleSpec, fmap: ForceMap) -> Fit:
    """The paper's protocol (see module docstring); err over the points with force > 0."""
    domain, pulled = domain_of(fmap), fmap.force > 0
    theta = _paper_theta(model, spec, fmap.subset(pulled), domain)
    return _fit_record(model, "paper", "least_squares", theta, spec, domain, fmap, pulled, clip=False)


def _paper_theta(model: Model, spec: MuscleSpec, fmap: ForceMap, domain: Domain) -> np.ndarray:
    if model.n_params == 0:
        return np.zeros(0)
    n = model.n_params

    def sse(theta: np.ndarray) -> float:
        return float(np.sum((fmap.force - force_raw(model, theta, spec, domain, fmap.pressure, fmap.length)) ** 2))

    result = minimize(sse, np.array(model.start, float), method="Nelder-Mead",
                      options={"xatol": 1e-4, "fatol": 1e-4, "maxiter": 200 * n, "maxfev": 200 * n})
    return result.x


def fit_best(model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str = "least_squares",
             seed: int = 0) -> Fit:
    """The ``best`` protocol on the whole map with the clipped model (module docstring); a hysteresis model
    is :func:`fit_branches`."""
    if model.hysteresis:
        return fit_branches(model, spec, fmap, objective, seed)
    return fit_best_all(model, spec, fmap, (objective,), seed)[objective]


def fit_branches(model: Model, spec: MuscleSpec, fmap: ForceMap, objective: str = "least_squares",
                 seed: int = 0) -> Fit:
    """A two-branch model (``sarosi_hysteresis``: upper then lower Sárosi eq. 19 parameters) from a map whose
    points carry their ``direction``: the single-branch model fitted on each direction's points."""
    if fmap.direction is None or not {-1.0, 1.0} <= set(fmap.direction.tolist()):
        raise ValueError(f"model {model.name!r} needs a force map with a 'direction' column holding both +1 "
                         "(lengthening or filling) and -1 (shortening or venting) points")
    branch = get_model(BRANCH_MODEL[model.name])
    up, down = (fit_best(branch, spec, fmap.subset(fmap.direction == d), objective, seed).theta for d in (1.0, -1.0))
    theta = np.concatenate([up, down])
    return _fit_record(model, "best", objective, theta, spec, domain_of(fmap), fmap,
                       np.ones(fmap.force.size, bool), True, fmap.direction)


def fit_best_all(model: Model, spec: MuscleSpec, fmap: ForceMap, objectives: tuple[str, ...] = OBJECTIVES,
                 seed: int = 0) -> dict[str, Fit]:
    """:func:`fit_best` for several objectives; the least-squares multi-start runs once for all."""
    unknown = set(objectives) - set(OBJECTIVES)
    if unknown:
        raise ValueError(f"unknown objective {sorted(unknown)}; choose from {OBJECTIVES}")
    domain = domain_of(fmap)
    thetas = _best_thetas(model, spec, fmap, domain, objectives, seed)
    everywhere = np.ones(fmap.force.size, bool)
    return {obj: _fit_record(model, "best", obj, thetas[obj], spec, domain, fmap, everywhere, True)
            for obj in objectives}


def _best_thetas(model, spec, fmap, domain, objectives, seed) -> dict[str, np.ndarray]:
    if model.n_params == 0:
        return {obj: np.zeros(0) for obj in objectives}
    lower, upper = np.array(model.lower), np.array(model.upper)
    start = np.array(model.start, float)
    scale = np.where(start != 0, np.abs(start), 1.0)

    def residuals(theta: np.ndarray) -> np.ndarray:
        return fmap.force - physical_force(model, theta, spec, domain, fmap.pressure, fmap.length)

    def inside(x: np.ndarray) -> np.ndarray:
        span = upper - lower
        return np.clip(x, lower + 1e-9 * span, upper - 1e-9 * span)

    rng = np.random.default_rng(seed)
    paper = _paper_theta(model, spec, fmap.subset(fmap.force > 0), domain)
    starts = [start, paper] + [paper * 10 ** rng.uniform(-0.5, 0.5, paper.size) for _ in range(_N_RANDOM_STARTS)]
    candidates = []
    for x0 in starts:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = least_squares(residuals, inside(x0), bounds=(lower, upper), x_scale="jac", method="trf",
                                   xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=5000)
        cost = float(np.sum(result.fun**2))
        if np.isfinite(cost):
            candidates.append((cost, result.x))
    tied = _ties(candidates, start, scale)
    thetas = {"least_squares": tied[0][1]}
    if "minimax" in objectives:
        thetas["minimax"] = _ties([_minimax(residuals, theta, lower, upper) for _, theta in tied], start, scale)[0][1]
    return thetas


def _ties(candidates: list, start: np.ndarray, scale: np.ndarray) -> list:
    """Candidates within a relative _TIE of the best cost, nearest to ``start`` first."""
    best = min(cost for cost, _ in candidates)
    tied = [c for c in candidates if c[0] <= best * (1 + _TIE) + 1e-12]
    return sorted(tied, key=lambda c: float(np.linalg.norm((c[1] - start) / scale)))


def _minimax(residuals, theta0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[float, np.ndarray]:
    """Minimise max|r(theta)| from theta0 in variables scaled by theta0; returns (cost, theta)."""
    scale = np.where(theta0 != 0, np.abs(theta0), 1.0)
    z0 = theta0 / scale

    def worst(z: np.ndarray) -> float:
        theta = z * scale
        if np.any(theta < lower) or np.any(theta > upper):
            return np.inf
        return float(np.max(np.abs(residuals(theta))))

    t0 = worst(z0)
    constraints = [{"type": "ineq", "fun": lambda y: y[-1] - residuals(y[:-1] * scale)},
                   {"type": "ineq", "fun": lambda y: y[-1] + residuals(y[:-1] * scale)}]
    bounds = [(lo / s, hi / s) if s > 0 else (None, None) for lo, hi, s in zip(lower, upper, scale)] + [(0, None)]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        slsqp = minimize(lambda y: y[-1], np.r_[z0, t0], method="SLSQP", constraints=constraints,
                         bounds=bounds, options={"maxiter": 500, "ftol": 1e-12})
        z1 = slsqp.x[:-1] if worst(slsqp.x[:-1]) < t0 else z0
        polish = minimize(worst, z1, method="Nelder-Mead",
                          options={"xatol": 1e-10, "fatol": 1e-10, "maxiter": 4000, "maxfev": 4000})
    best = min((z0, z1, polish.x), key=worst)
    return worst(best) ** 2, best * scale


def cross_validate(model: Model, spec: MuscleSpec, fmap: ForceMap,
                   objectives: tuple[str, ...] = OBJECTIVES) -> dict[str, np.ndarray]:
    """Leave-one-length-out: eq. 23 on each held-out length, normalised by the whole map's max force [%].

    Returns, per objective, one error per measured length in the order of ``fmap.lengths``.
    """
    errors: dict[str, list[float]] = {obj: [] for obj in objectives}
    for held_out in fmap.lengths:
        test = fmap.length == held_out
        for obj, fit in fit_best_all(model, spec, fmap.subset(~test), objectives).items():
            predicted = physical_force(model, fit.theta, spec, fit.domain, fmap.pressure[test], fmap.length[test])
            errors[obj].append(max_error_percent(fmap.force[test], predicted, fmap.max_force))
    return {obj: np.array(errs) for obj, errs in errors.items()}


@dataclass(frozen=True)
class ModelReport:
    """Everything the paper's Table 3 and our cross-validation say about one model."""

    paper: Fit                       #: the paper protocol
    best: dict[str, Fit]             #: best protocol, per objective
    cv: dict[str, np.ndarray]        #: held-out err per length [%], per objective
    shipped_objective: str           #: the objective with the lower worst held-out err

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
        """Worst held-out err of the shipped objective on the map's shortest and longest length [%]."""
        errors = self.cv[self.shipped_objective]
        return float(max(errors[0], errors[-1]))


def identify_all(spec: MuscleSpec, fmap: ForceMap, models: tuple[Model, ...]) -> tuple[dict[str, ModelReport], str]:
    """Identify every model both ways, cross-validate, and pick the default model.

    The shipped objective of each model and the default model are chosen by the
    worst leave-one-length-out error, not by in-sample error.
    """
    reports = {}
    for model in models:
        best = fit_best_all(model, spec, fmap)
        cv = cross_validate(model, spec, fmap)
        shipped = min(OBJECTIVES, key=lambda obj: cv[obj].max())
        reports[model.name] = ModelReport(fit_paper(model, spec, fmap), best, cv, shipped)
    default = min(reports, key=lambda name: reports[name].cv_err)
    return reports, default
