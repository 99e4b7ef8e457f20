"""Held-out judgement of an identification: nested leave-one-length-out cross-validation.

A fit is judged on each measured length it did not see (eq. 23 on that length, in % of the whole
map's max force).  Every choice an identification makes from the data (model parameters,
calibrated geometry, and, among several candidates, the model and objective) is made again without
that length, so the figure is what a user can expect at a length they did not measure.  A figure
that was used to choose something (the plain leave-one-length-out error of each candidate, by
which the whole map's fit is chosen) is a *selection* figure, never reported as held-out.

Choosing among candidates inside fold k needs each candidate judged without k: its fits without
{k, j} judged on j.  :class:`HeldOut` caches a candidate's fits by the set of lengths left out, so
a whole nested table of c candidates on m lengths costs c (1 + m + m (m - 1) / 2) fits.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Protocol

import numpy as np

from .force_map import ForceMap

#: The objectives of a ``best`` fit (eq. 22, eq. 23), each judged here as a candidate.
OBJECTIVES = ('least_squares', 'minimax')
_MAX_FOLDS = 8  #: most held-out groups of a map
_SAME_LENGTH = 1e-3  #: [m] lengths closer than this are one held-out length
#: Relative difference below which two costs or errors are equal: rounding (BLAS kernels, SIMD
#: paths, thread counts) moves them by about 1e-13, and must not decide a choice.
TIE = 1e-9


def beats(value: float, best: float) -> bool:
    """Whether the cost or error ``value`` (>= 0) is lower than ``best`` beyond a :data:`TIE` (any
    finite value beats an infinite ``best``).
    """
    return value < best * (1 - TIE)


def within_tie(value: float, best: float) -> bool:
    """Whether the cost or error ``value`` (>= 0) is at most ``best`` or equal to it within a
    :data:`TIE`: it does not lose to ``best``.
    """
    return value <= best * (1 + TIE)


class Predictor(Protocol):
    """A fit: its force at pressures and lengths (and, on a map with directions, on each point's
    hysteresis branch).
    """

    def force(
        self, pressure: np.ndarray, length: np.ndarray, *direction: np.ndarray
    ) -> np.ndarray: ...


def length_folds(fmap: ForceMap) -> list[np.ndarray]:
    """The held-out groups of points, longest first: each measured length, where lengths closer
    than :data:`_SAME_LENGTH` count as one (the cells of one held length of a recording); with more
    than :data:`_MAX_FOLDS` such lengths, or too few to judge (a recording that never held still),
    :data:`_MAX_FOLDS` bands of neighbouring lengths.
    """
    lengths = fmap.lengths  # descending
    cuts = np.flatnonzero(-np.diff(lengths) > _SAME_LENGTH) + 1
    groups = np.split(lengths, cuts)
    if len(groups) > _MAX_FOLDS or (len(groups) < 3 <= lengths.size):
        groups = np.array_split(lengths, min(_MAX_FOLDS, lengths.size))
    return [np.isin(fmap.length, group) for group in groups]


def fold_lengths(fmap: ForceMap) -> np.ndarray:
    """The mean length [m] of each fold of :func:`length_folds`."""
    return np.array([fmap.length[test].mean() for test in length_folds(fmap)])


class HeldOut:
    """One identification protocol's fits of a map without some of its folds, cached.

    ``identify(train)`` returns a mapping of candidates (e.g. objectives) to fits; ``truth``: the
    forces [N] at the map's points to report errors against (e.g. noise-free ones; default the
    map's own).  Choices are always made against the map's own forces.
    """

    def __init__(
        self,
        fmap: ForceMap,
        identify: Callable[[ForceMap], dict[str, Predictor]],
        truth: np.ndarray | None = None,
    ):
        self.fmap, self.identify = fmap, identify
        self.folds = length_folds(fmap)
        self.truth = fmap.force if truth is None else truth
        self._fits: dict[frozenset[int], dict[str, Predictor]] = {}

    def training_map(self, held: frozenset[int]) -> ForceMap:
        """The map without the folds ``held``."""
        return (
            self.fmap.subset(~np.any([self.folds[k] for k in held], axis=0))
            if held
            else (self.fmap)
        )

    def store(self, held: frozenset[int], fits: dict[str, Predictor] | None) -> None:
        """Keep fits made elsewhere (e.g. in a worker process) of :meth:`training_map` (held)."""
        self._fits[held] = fits

    def fits_without(self, held: frozenset[int]) -> dict[str, Predictor] | None:
        """The protocol's fits without the folds ``held``; None if what is left cannot be fitted
        (fewer than two lengths).
        """
        if held not in self._fits:
            self.store(held, fit_or_none(self.identify, self.training_map(held)))
        return self._fits[held]

    def needed(self, pairs: bool) -> list[frozenset[int]]:
        """The sets of folds left out of the fits a judgement needs: none, each fold, and (for a
        nested choice among candidates) each pair.
        """
        n = len(self.folds)
        singles = [frozenset({k}) for k in range(n)]
        return [frozenset(), *singles] + (
            [frozenset({k, j}) for k in range(n) for j in range(k + 1, n)] if pairs else []
        )

    def error(
        self, candidate: str, fold: int, held: frozenset[int], against_truth: bool = False
    ) -> float:
        """Eq. 23 [%] on ``fold`` of the candidate's fit without the folds ``held`` (NaN: none)."""
        test, fits = self.folds[fold], self.fits_without(held)
        if fits is None:
            return float('nan')
        forces = self.truth if against_truth else self.fmap.force
        at = (self.fmap.pressure[test], self.fmap.length[test])
        if self.fmap.direction is not None:  # each point on its branch
            at += (self.fmap.direction[test],)
        predicted = fits[candidate].force(*at)
        return float(100 * np.max(np.abs(forces[test] - predicted)) / forces.max())

    def errors(self, candidate: str, against_truth: bool = False) -> np.ndarray:
        """Leave-one-length-out: the candidate's error on each fold, fitted without it [%]."""
        return np.array(
            [
                self.error(candidate, k, frozenset({k}), against_truth)
                for k in range(len(self.folds))
            ]
        )

    def inner_worst(self, candidate: str, outer: int) -> float:
        """The candidate's worst leave-one-length-out error on the map without fold ``outer``
        (inf: that map is too small to judge it).
        """
        errors = [
            self.error(candidate, j, frozenset({outer, j}))
            for j in range(len(self.folds))
            if j != outer
        ]
        finite = [e for e in errors if np.isfinite(e)]
        return max(finite) if finite else np.inf


#: A rule of choice: the score (lower is better) of a candidate (its :class:`HeldOut`, its key
#: there) on the map without fold ``outer`` (None: the whole map).
Score = Callable[[HeldOut, str, 'int | None'], float]


def errors_without(held: HeldOut, key: str, outer: int | None) -> np.ndarray:
    """The candidate's leave-one-length-out errors [%] on the map without fold ``outer`` (None:
    the whole map), longest first.
    """
    if outer is None:
        return held.errors(key)
    others = (j for j in range(len(held.folds)) if j != outer)
    return np.array([held.error(key, j, frozenset({outer, j})) for j in others])


def worst_score(held: HeldOut, key: str, outer: int | None) -> float:
    """The worst leave-one-length-out error [%] (inf: none could be judged)."""
    if outer is not None:
        return held.inner_worst(key, outer)
    errors = held.errors(key)
    return float(np.nanmax(errors)) if np.any(np.isfinite(errors)) else np.inf


def interior_score(held: HeldOut, key: str, outer: int | None) -> float:
    """The worst leave-one-length-out error [%] on the lengths between the shortest and the
    longest (interpolation); the worst of all where there are none.
    """
    inner = errors_without(held, key, outer)[1:-1]
    inner = inner[np.isfinite(inner)]
    return float(inner.max()) if inner.size else worst_score(held, key, outer)


def mean_score(held: HeldOut, key: str, outer: int | None) -> float:
    """The mean leave-one-length-out error [%] (inf: none could be judged): every length counts,
    and no one of them (an edge no candidate predicts) decides alone.
    """
    errors = errors_without(held, key, outer)
    errors = errors[np.isfinite(errors)]
    return float(errors.mean()) if errors.size else np.inf


def in_sample_score(held: HeldOut, key: str, outer: int | None) -> float:
    """The in-sample err [%] of the candidate's fit (inf: no fit)."""
    fits = held.fits_without(frozenset() if outer is None else frozenset({outer}))
    return float(fits[key].err) if fits is not None else np.inf


#: Candidate rules by which a model is chosen among several (``pma-model fit --model all``), each
#: judged nested; ``bench/generalisation.py --selection`` compares them leave-one-muscle-out.
RULES: dict[str, Score] = {
    'worst held-out': worst_score,
    'interior held-out': interior_score,
    'mean held-out': mean_score,
    'in-sample': in_sample_score,
}


def select(
    candidates: dict[str, tuple[HeldOut, str]],
    against_truth: bool = False,
    score: Score = worst_score,
) -> tuple[str, np.ndarray, list[str]]:
    """Choose among candidates (name -> (its :class:`HeldOut`, its key there)) by the lowest
    ``score`` (default the worst leave-one-length-out error), and judge that choice honestly.

    Returns the whole map's choice, the nested errors per fold [%] (in fold k the choice is made by
    each candidate's score without k, then judged on k) and the candidate chosen per fold.
    """
    names = list(candidates)
    chosen = _first_best(names, lambda n: score(*candidates[n], None))
    n_folds = len(next(iter(candidates.values()))[0].folds)
    per_fold, errors = [], []
    for k in range(n_folds):
        name = _first_best(names, lambda n: score(*candidates[n], k))
        held, key = candidates[name]
        per_fold.append(name)
        errors.append(held.error(key, k, frozenset({k}), against_truth))
    return chosen, np.array(errors), per_fold


def _first_best(names: list[str], score: Callable[[str], float]) -> str:
    """The first of ``names`` whose score is within :data:`TIE` of the lowest.
    Equal errors are common (a held-out length that two fits both predict slack errs by its
    measured force), and rounding must not decide between them.
    """
    if len(names) == 1:
        return names[0]
    scores = [score(name) for name in names]
    best = min(scores)
    return next(n for n, s in zip(names, scores) if within_tie(s, best))


@dataclass(frozen=True)
class HeldOutBand:
    """How far to trust a fit at a length: the nested held-out err of each held-out length, in two
    figures.  Between the map's shortest and longest length (interpolation) the worst err of the
    lengths between them; beyond them (extrapolation,
    :func:`~pma_model_ros.core.physics.models.extrapolates`) the worst err of those two, each
    served from a fit without it.

    ``lengths`` [m] (descending, as :func:`fold_lengths`), ``errors`` [% of ``max_force``], the
    map's ``max_force`` [N].  An error of exactly 0 is a length where no force was measured: eq. 23
    there says only that the clipped model is slack where the muscle was, not how far to trust it;
    a figure of 0 gives way to the map's worst (:meth:`at`).  With fewer than three lengths both
    figures are the map's worst.
    """

    lengths: tuple[float, ...]
    errors: tuple[float, ...]
    max_force: float

    def __post_init__(self) -> None:
        if not (
            len(self.lengths) == len(self.errors) >= 1
            and all(np.isfinite(self.lengths))
            and all(np.isfinite(self.errors))
            and all(e >= 0 for e in self.errors)
            and np.isfinite(self.max_force)
            and self.max_force > 0
        ):
            raise ValueError(
                'held_out needs as many finite lengths as errors (>= 0) and a max_force > 0, got '
                f'{self.lengths}, {self.errors}, {self.max_force}'
            )

    @cached_property
    def _figures(self) -> tuple[float, float, float, float]:
        """(shortest length [m], longest [m], the interior figure [%], the edge figure [%]) before
        a figure of 0 gives way (model_node asks :meth:`at` for every muscle at each status
        report).
        """
        order = np.argsort(self.lengths)
        lengths, errors = np.asarray(self.lengths)[order], np.asarray(self.errors)[order]
        worst = float(errors.max())
        if errors.size < 3:
            return float(lengths[0]), float(lengths[-1]), worst, worst
        return (
            float(lengths[0]),
            float(lengths[-1]),
            float(errors[1:-1].max()),
            float(max(errors[0], errors[-1])),
        )

    @property
    def interior(self) -> float:
        """The worst held-out err [%] between the shortest and longest length (interpolation)."""
        return self._figures[2] or max(self.errors)

    @property
    def edge(self) -> float:
        """The worst held-out err [%] of the shortest and longest length (extrapolation)."""
        return self._figures[3] or max(self.errors)

    def inside(self, length: float) -> bool:
        """Whether ``length`` [m] lies within the held-out lengths (interpolation)."""
        return self._figures[0] <= length <= self._figures[1]

    def slack_at(self, length: float) -> bool:
        """Whether the figure that judges ``length`` [m] is 0: no force was measured at any of its
        held-out lengths (:meth:`at` gives the map's worst instead).
        """
        return self._figures[2 if self.inside(length) else 3] == 0

    def at(self, length: float, held: bool = False) -> tuple[float, bool]:
        """(expected worst error [%] at ``length`` [m], whether it lies within the held-out
        lengths): :attr:`interior` within them, :attr:`edge` beyond them (an extrapolation) or
        where the force is ``held`` at the nearest length served (``LENGTH_OUT_OF_RANGE``).
        """
        inside = self.inside(length)
        return (self.interior if inside and not held else self.edge), inside

    def values_at(self, length: float) -> dict[str, str]:
        """The expected error at ``length`` [m] as diagnostic key-values (model_node's status of a
        muscle at its newest length): in N and in % of the map's max force (:meth:`at`), beyond
        the held-out lengths saying that it is an extrapolation's figure; ``unknown`` before a
        length.
        """
        keys = ('expected error [N]', 'expected error [% of max force]')
        if not np.isfinite(length):
            return dict(zip(keys, ('unknown', 'unknown: no length yet')))
        percent, inside = self.at(length)
        newtons = f'{percent * self.max_force / 100:.3g}'
        if not inside:
            return dict(
                zip(
                    keys,
                    (
                        newtons,
                        f'{percent:.3g} ({length:.4g} m is beyond the measured lengths '
                        f'{min(self.lengths):.4g}..{max(self.lengths):.4g} m: the worst of the '
                        'shortest and longest, extrapolated or held there as served)',
                    ),
                )
            )
        return dict(zip(keys, (newtons, f'{percent:.3g}')))


def fit_or_none(
    identify: Callable[[ForceMap], dict[str, Predictor]], train: ForceMap
) -> dict[str, Predictor] | None:
    """``identify(train)``, or None for a map of fewer than two lengths, or a branch of fewer than
    two lengths on a map with directions (nothing to fit).
    """
    maps = (
        [train]
        if train.direction is None
        else [train.subset(train.direction == d) for d in np.unique(train.direction)]
    )
    return identify(train) if all(m.lengths.size >= 2 for m in maps) else None
