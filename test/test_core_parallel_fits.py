"""The nested judgement's fits in worker processes: the same identification, to the bit, as in
one process, whatever the number of workers.
"""

import multiprocessing
import os
from pathlib import Path
import signal
import sys

import numpy as np
import pytest

from pma_model_ros.core.files.shipped_data import shipped_force_map, shipped_spec
from pma_model_ros.core.identification import selection, separable
from pma_model_ros.core.identification.calibration import Calibration
from pma_model_ros.core.identification.protocols import domain_of, fit_paper
from pma_model_ros.core.identification.selection import identify_all
from pma_model_ros.core.identification.validation import fit_or_none
from pma_model_ros.core.physics.models import get_model

#: (muscle, models, objectives): both objectives (the objective chosen again in each fold: fits
#: without every pair of lengths), and Martens' calibrated fit (L0 searched, pressure offset
#: identified).
CASES = [
    ('DMSP-10-250', ('mckibben',), ('least_squares', 'minimax')),
    ('DMSP-20-300', ('martens',), ('least_squares',)),
]

_PIDS = Path()  #: where :func:`_recorded_paper_fit` leaves its process ids (set by the test)


def _recorded_paper_fit(model, spec, fmap):
    """``fit_paper``, leaving the id of the process it ran in as a file in ``_PIDS``."""
    (_PIDS / str(os.getpid())).touch()
    return fit_paper(model, spec, fmap)


def _fit_or_ending_worker(identify, training_map):
    """``fit_or_none`` here; in a worker process, the worker's end (exit code 3) instead."""
    if multiprocessing.parent_process() is not None:
        os._exit(3)
    return fit_or_none(identify, training_map)


def _figures(found: selection.Identification) -> list:
    """Every number and choice of an identification, flat: fits, per-fold errors, choices."""
    out = [found.default, found.chosen, found.held_out]
    for name, rep in found.reports.items():
        out += [name, rep.shipped_objective, rep.nested, *rep.cv.values()]
        for fit in (rep.paper, *rep.best.values()):
            out += [fit.theta, fit.err, fit.rmse, fit.r2, fit.spec, fit.calibration]
            out += [fit.pressure_offset, sorted(fit.sigma.items()), fit.slack_length]
    return out


def _same(a: list, b: list) -> bool:
    """Element by element equal; arrays bit for bit (NaN equal to NaN)."""
    return len(a) == len(b) and all(
        np.array_equal(x, y, equal_nan=True) if isinstance(x, np.ndarray) else x == y
        for x, y in zip(a, b)
    )


@pytest.mark.parametrize('muscle, names, objectives', CASES)
def test_workers_give_the_serial_identification(muscle, names, objectives, tmp_path, monkeypatch):
    """Serial, two and three workers: every fit, error and choice identical (exact), and the
    parallel runs fitted in processes other than this one.
    """
    monkeypatch.setattr(sys.modules[__name__], '_PIDS', tmp_path)  # workers fork with it
    monkeypatch.setattr(selection, 'fit_paper', _recorded_paper_fit)
    spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
    models = tuple(get_model(name) for name in names)
    runs = {}
    for workers in (1, 2, 3):
        for pid in tmp_path.iterdir():
            pid.unlink()
        found = identify_all(spec, fmap, models, Calibration(), objectives, None, workers)
        runs[workers] = _figures(found)
        pids = {int(p.name) for p in tmp_path.iterdir()}
        if workers == 1:
            assert pids == {os.getpid()}
        elif selection._start_method() == 'fork':
            assert pids and os.getpid() not in pids
    assert _same(runs[1], runs[2])
    assert _same(runs[1], runs[3])


def test_no_fit_is_computed_twice(monkeypatch):
    """The L0 search of the fold without length j and of the fold without k both fit the map
    without {j, k}: each such fit is computed once in a process and asked for again.
    """
    monkeypatch.setattr(separable, '_SOLVED', separable.OrderedDict())
    compute, asked = separable.Separable._least_squares, separable.Separable.fit_least_squares
    counts = {'computed': 0, 'asked': 0}

    def computed(self, near):
        counts['computed'] += 1
        return compute(self, near)

    def asked_for(self, near=None):
        counts['asked'] += 1
        return asked(self, near)

    monkeypatch.setattr(separable.Separable, '_least_squares', computed)
    monkeypatch.setattr(separable.Separable, 'fit_least_squares', asked_for)
    spec, fmap = shipped_spec('DMSP-10-250'), shipped_force_map('DMSP-10-250')
    identify_all(spec, fmap, (get_model('mckibben'),), Calibration(), ('least_squares',), None, 1)
    assert counts['computed'] == len(separable._SOLVED) < counts['asked']


def test_a_fit_solves_each_nonlinear_point_once(monkeypatch):
    """A refinement starts at a grid point already solved and solves its optimum again: each
    point's linear least squares is computed once and asked for again.
    """
    monkeypatch.setattr(separable, '_SOLVED', separable.OrderedDict())
    compute, asked = separable.Separable._linear_least_squares, []
    points = []

    def computed(self, phi):
        points.append(np.asarray(phi, float).tobytes())
        return compute(self, phi)

    monkeypatch.setattr(separable.Separable, '_linear_least_squares', computed)
    spec, fmap = shipped_spec('DMSP-10-250'), shipped_force_map('DMSP-10-250')
    fitted = separable.Separable(get_model('martens'), spec, domain_of(fmap), fmap)
    solve = fitted.linear_least_squares
    monkeypatch.setattr(fitted, 'linear_least_squares', lambda phi: asked.append(1) or solve(phi))
    fitted.fit_least_squares()
    assert len(points) == len(set(points)) < len(asked)


def test_fits_of_a_worker_that_ends_run_here(monkeypatch, capsys):
    """A worker that ends while fitting (the out-of-memory killer, a crash) costs its speed, not
    the result: every fit runs here afterwards, to the serial identification, and one stderr line
    names how the worker ended.
    """
    if selection._start_method() != 'fork':
        pytest.skip('spawned workers would not run the replaced fit_or_none (pytest-xdist forks)')
    spec, fmap = shipped_spec('DMSP-10-250'), shipped_force_map('DMSP-10-250')
    models = (get_model('mckibben'),)
    serial = identify_all(spec, fmap, models, Calibration(), ('least_squares',), None, 1)
    monkeypatch.setattr(selection, 'fit_or_none', _fit_or_ending_worker)
    capsys.readouterr()
    found = identify_all(spec, fmap, models, Calibration(), ('least_squares',), None, 2)
    assert _same(_figures(found), _figures(serial))
    lines = [line for line in capsys.readouterr().err.splitlines() if 'worker' in line]
    assert len(lines) == 1 and 'a worker process ended (exit code 3' in lines[0], lines


def test_ctrl_c_while_workers_start_is_raised_once_they_have():
    """SIGINT while the workers are forked is held (raised inside a fork's hooks it would be
    printed and lost) and raised as KeyboardInterrupt right after.
    """
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        reached = False
        with pytest.raises(KeyboardInterrupt):
            with selection._held_interrupt():
                signal.raise_signal(signal.SIGINT)
                reached = True  # not interrupted inside
        assert reached
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)
