"""The nested judgement of every model of a map and the choice of the default model.

Each model is identified by the ``best`` protocol (:mod:`.protocols`) and judged by nested
leave-one-length-out errors (:mod:`.validation`): the whole protocol, calibration and choices
included, re-run without each measured length.  Each model's objective is chosen by the worst
held-out error and the default model by the mean (:data:`MODEL_RULE`), and every such choice is
made again inside each fold.  The fits run in worker processes, one per core
(:func:`_fit_everything`); the judgement made from them is the same to the bit.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import functools
import math
import os
import signal
import sys
import threading
import time
from typing import Iterator

import numpy as np

from .calibration import Calibration, OFF
from .force_map import ForceMap
from .progress import Meter
from .protocols import Fit, fit_best_all, fit_paper
from .validation import fit_or_none, HeldOut, OBJECTIVES, RULES, select
from ..physics.geometry import MuscleSpec
from ..physics.models import Model

#: Set in the worker processes of :func:`identify_all` (unless the user set them).  OpenBLAS's idle
#: threads spin 2^28 cycles (~0.1 s) after each threaded call before they sleep: in a worker that
#: spinning takes the shared cores from the other workers.  2^4 cycles: they sleep at once (same
#: threads, same partition of the work, so the same numbers).
_WORKER_ENVIRONMENT = {'OPENBLAS_THREAD_TIMEOUT': '4'}


#: The rule by which the default model is chosen among several (:data:`~.validation.RULES`),
#: chosen leave-one-muscle-out on four maps (docs/calibration.md).
MODEL_RULE = 'mean held-out'


@dataclass(frozen=True)
class ModelReport:
    """Everything the paper's Table 3 and the held-out judgement say about one model."""

    paper: Fit  #: the paper protocol
    best: dict[str, Fit]  #: best protocol on the whole map, per objective
    #: leave-one-length-out err per fold [%], per objective: the whole protocol (calibration
    #: included) re-run without each fold
    cv: dict[str, np.ndarray]
    #: the objective with the lower worst ``cv`` err (a selection: its figure is ``nested``'s)
    shipped_objective: str
    #: nested held-out err per fold [%]: the objective chosen again without each fold
    nested: np.ndarray

    @property
    def shipped(self) -> Fit:
        return self.best[self.shipped_objective]

    @property
    def best_err(self) -> float:
        """Lowest in-sample err of the best protocol [%]."""
        return min(fit.err for fit in self.best.values())

    @property
    def cv_err(self) -> float:
        """Worst nested held-out err [%]."""
        return float(np.nanmax(self.nested))

    @property
    def edge_cv_err(self) -> float:
        """Worst nested held-out err on the map's shortest and longest length [%]: beyond the
        lengths it was fitted on, what the fit serves there (:attr:`.Fit.served`).
        """
        return edge_err(self.nested)

    @property
    def interior_cv_err(self) -> float:
        """Worst nested held-out err on the lengths between the shortest and the longest [%]."""
        return interior_err(self.nested)


def edge_err(nested: np.ndarray) -> float:
    """The worst of nested held-out errors per fold [%] (longest first) on the map's shortest and
    longest length: an extrapolation's figure.
    """
    return float(max(nested[0], nested[-1]))


def interior_err(nested: np.ndarray) -> float:
    """The worst of nested held-out errors per fold [%] (longest first) on the lengths between the
    map's shortest and longest: an interpolation's figure (NaN for fewer than 3 folds).
    """
    inner = nested[1:-1]
    return float(np.nanmax(inner)) if inner.size and np.any(np.isfinite(inner)) else math.nan


@dataclass(frozen=True)
class Identification:
    """Every model of a map identified and judged, and the default model."""

    reports: dict[str, ModelReport]
    #: the model chosen by :data:`MODEL_RULE` (a selection on the whole map)
    default: str
    #: nested held-out err per fold of the whole protocol [%]: the model chosen again without
    #: each fold, judged on it (the honest figure of ``default``)
    held_out: np.ndarray
    #: the model chosen in each fold
    chosen: tuple[str, ...]
    #: (default, held_out, chosen) under each candidate rule of choice
    #: (:data:`~.validation.RULES`; the default's is :data:`MODEL_RULE`)
    by_rule: dict[str, tuple[str, np.ndarray, tuple[str, ...]]]


def identify_all(
    spec: MuscleSpec,
    fmap: ForceMap,
    models: tuple[Model, ...],
    calibration: Calibration = OFF,
    objectives: tuple[str, ...] = OBJECTIVES,
    truth: np.ndarray | None = None,
    workers: int | None = None,
) -> Identification:
    """Identify every model, judge each by nested held-out error and pick the default.

    Each model's objective (among ``objectives``) is chosen by the worst leave-one-length-out
    error, the default model by :data:`MODEL_RULE` (each rule's choice is in ``by_rule``), and
    every such choice is made again inside each fold for the
    held-out figures (:func:`~pma_model_ros.core.identification.validation.select`).
    ``calibration`` applies to the ``best`` protocol only; the paper protocol keeps the given
    geometry.  ``truth``: forces [N] at the map's points to report held-out errors against (choices
    use the map's own).  ``workers``: processes the fits run in (default: one per core there is;
    the result does not depend on it, :func:`_fit_everything`).
    """
    held = {
        model.name: HeldOut(
            fmap,
            functools.partial(
                fit_best_all, model, spec, objectives=objectives, calibration=calibration
            ),
            truth,
        )
        for model in models
    }
    pairs = len(models) * len(objectives) > 1
    jobs = [(name, s) for name, h in held.items() for s in h.needed(pairs)]
    papers = _fit_everything(held, jobs, models, spec, fmap, workers)
    reports, candidates = {}, {}
    against = truth is not None
    for model, paper in zip(models, papers):
        h = held[model.name]
        shipped, nested, _ = select({obj: (h, obj) for obj in objectives}, against)
        reports[model.name] = ModelReport(
            paper,
            h.fits_without(frozenset()),
            {obj: h.errors(obj, against) for obj in objectives},
            shipped,
            nested,
        )
        candidates |= {(model.name, obj): (h, obj) for obj in objectives}
    by_rule = {}
    for rule, score in RULES.items():
        (default, _), held_out, chosen = select(candidates, against, score)
        by_rule[rule] = (default, held_out, tuple(name for name, _ in chosen))
    return Identification(reports, *by_rule[MODEL_RULE], by_rule)


#: Expected fitting time [s] above which spawned worker processes (each importing the package,
#: about 1 s) are worth starting; forked ones start in milliseconds.
_PARALLEL_ABOVE = 1.0


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform reports it)."""
    count = getattr(os, 'process_cpu_count', None)  # Python >= 3.13
    if count is not None:
        return count() or 1
    if hasattr(os, 'sched_getaffinity'):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _start_method() -> str:
    """``fork`` where the platform forks safely and this process runs no other Python thread
    (a forked child gets only the calling thread, and another thread's locks stay held); else
    ``spawn``.  (OpenBLAS's native threads stop around a fork by its own handlers.)
    """
    import multiprocessing
    import threading

    forks = 'fork' in multiprocessing.get_all_start_methods() and sys.platform != 'darwin'
    return 'fork' if forks and threading.active_count() == 1 else 'spawn'


def _fit_everything(
    held: dict[str, HeldOut],
    jobs: list[tuple[str, frozenset[int]]],
    models: tuple[Model, ...],
    spec: MuscleSpec,
    fmap: ForceMap,
    workers: int | None = None,
) -> list[Fit]:
    """Every fit the judgement needs, into each model's :class:`HeldOut`; returns the paper fits.

    Each fit depends on its training map alone, so the fits run in any process and any order and
    the judgement made from them afterwards, here, in its fixed order, is the same to the bit.
    With ``workers`` (default: :func:`available_cores`) above 1, they run in that many worker
    processes, the largest training maps first.  Forked workers (:func:`_start_method`) take
    every fit; spawned ones only the fits without held-out lengths, and only if the whole-map fits,
    run here first, announce more than :data:`_PARALLEL_ABOVE` of work for them (as long, per
    model, times the fits left).  The fits of a worker that ends while fitting (the out-of-memory
    killer, a signal) and those left run here afterwards, with a line on stderr.
    """
    workers = available_cores() if workers is None else workers
    method = _start_method()
    first = [] if method == 'fork' else [(name, frozenset()) for name in held]
    started = time.perf_counter()
    for name, s in first:
        held[name].fits_without(s)
    # whole maps, then one length out, then two: the longest fits first
    rest = sorted([job for job in jobs if job not in first], key=lambda job: len(job[1]))
    expected = (time.perf_counter() - started) * len(rest) / len(held)
    tasks = [(fit_or_none, (held[n].identify, held[n].training_map(s))) for n, s in rest]
    tasks += [(fit_paper, (model, spec, fmap)) for model in models]
    results: list = [None] * len(tasks)
    left = set(range(len(tasks)))  # the tasks without a result yet
    meter = Meter(len(tasks), f'{len(held)} model(s), fits with and without each length')
    workers = min(workers, len(tasks))
    if workers > 1 and (method == 'fork' or expected > _PARALLEL_ABOVE):
        from concurrent.futures import as_completed, ProcessPoolExecutor
        from concurrent.futures.process import BrokenProcessPool
        import multiprocessing
        import warnings

        context = multiprocessing.get_context(method)
        pool = ProcessPoolExecutor(workers, context, _ignore_interrupts)
        started_workers: list = []
        try:
            with warnings.catch_warnings(), _environment(_WORKER_ENVIRONMENT), _held_interrupt():
                # Python >= 3.12 warns of a fork beside OpenBLAS's threads (_start_method)
                warnings.filterwarnings(
                    'ignore', 'This process .* is multi-threaded', DeprecationWarning
                )
                futures = {pool.submit(f, *args): i for i, (f, args) in enumerate(tasks)}
            started_workers = list((pool._processes or {}).values())  # shutdown forgets them
            for future in as_completed(futures):
                results[futures[future]] = future.result()
                left.discard(futures[future])
                meter.update(len(tasks) - len(left))
        except BrokenProcessPool:
            pool.shutdown()  # the pool's own thread reaps every worker, so each has its exit code
            sys.stderr.write(_lost_worker(started_workers, len(left)))
        except BaseException:  # an error, Ctrl-C: no running fit is waited for
            _terminate(pool)
            raise
        finally:
            pool.shutdown(cancel_futures=True)
    for i in sorted(left):
        function, args = tasks[i]
        results[i] = function(*args)
        meter.update(len(tasks) - len(left) + 1)
        left.discard(i)
    for (name, s), fits in zip(rest, results):
        held[name].store(s, fits)
    return results[len(rest) :]


def _terminate(pool) -> None:
    """End the workers of the ``ProcessPoolExecutor`` ``pool`` now, their fits unfinished."""
    if hasattr(pool, 'terminate_workers'):  # Python >= 3.14
        return pool.terminate_workers()
    for process in list((pool._processes or {}).values()):
        process.terminate()


def _lost_worker(workers: list, left: int) -> str:
    """The line for a process of ``workers`` (ended, reaped) that ended while fitting (killed by
    the kernel's out-of-memory killer or a signal, a crash): its fits and the ``left`` unfinished
    ones run in this process, to the same result.
    """
    ended = [
        p.exitcode
        for p in workers
        if p.exitcode not in (None, 0, -signal.SIGTERM)  # SIGTERM: the pool ends the others
    ]
    how = ', '.join(
        f'killed by {signal.Signals(-code).name}'
        if code < 0 and -code in signal.valid_signals()
        else f'exit code {code}'
        for code in ended
    )
    return (
        f'fit: a worker process ended ({how or "exit code unknown"}); the {left} fit(s) left run '
        'in this process\n'
    )


def _ignore_interrupts() -> None:
    """A worker's start: Ctrl-C (SIGINT, sent to the whole process group) is the parent's to
    handle; the parent then terminates the workers.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _held_interrupt() -> Iterator[None]:
    """Ctrl-C (SIGINT) while the workers are forked is held, then raised as it would have been:
    raised inside a fork's hooks (logging's lock release), it is printed and lost.  Only in the
    main thread, where Python runs signal handlers.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, _frame: held.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held:
            signal.raise_signal(signal.SIGINT)


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
