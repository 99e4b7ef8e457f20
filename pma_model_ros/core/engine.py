"""The estimation engine: force estimates and pressure commands of N muscles from their inputs,
each decision made once (no ROS).

An input is an array of values of the muscles ``sel`` (every muscle, e.g. a combined JointState,
or :func:`~.estimation.one`) with one stamp; the engine validates it (:mod:`.estimation`), pairs
it with the other input and checks freshness (:mod:`.pairing`), estimates the force of the muscles
that pair (:mod:`.estimation`), and keeps counters, levels and reports (:mod:`.health`).
``model_node`` (both input modes) and ``pma-model bag estimate`` drive it.  Times are integer
nanoseconds on one clock (ROS time in the node, log time offline); ``now`` is passed in, never
read here.
"""

from __future__ import annotations

import enum
from typing import Sequence

import numpy as np

from .estimation import (
    ALL,
    Config,
    length_problem,
    Muscles,
    one,
    pressure_problem,
)
from .flags import describe
from .health import Health, Level, Status, WARN_MASK
from .node_parameters import SPECS
from .pairing import LENGTH, nanoseconds, Pairing, PRESSURE

__all__ = ['ALL', 'Config', 'Counter', 'Engine', 'Level', 'one', 'Status']

#: [s] Shortest time between two on-change status reports of model_node (and of its offline twin),
#: per muscle reported: building and publishing a status of 64 muscles took about 3 ms under
#: cProfile, so on-change reports stay a few percent of a core however many muscles flap (N = 64:
#: at most one every 0.1 s).
REPORT_INTERVAL_PER_MUSCLE = 0.0015


class Counter(enum.IntEnum):
    """The counters of each muscle (columns of ``health.counts``); labels in :data:`LABELS`."""

    RECEIVED_PRESSURE = 0
    RECEIVED_MUSCLE_STATE = 1
    RECEIVED_FORCE_COMMAND = 2
    REJECTED_PRESSURE = 3
    REJECTED_MUSCLE_STATE = 4
    REJECTED_FORCE_COMMAND = 5
    STALE = 6
    UNPAIRED = 7
    ESTIMATES = 8
    COMMANDS = 9
    NO_LENGTH = 10


LABELS = (
    'received pressure',
    'received muscle_state',
    'received force_command',
    'rejected pressure',
    'rejected muscle_state',
    'rejected force_command',
    'stale skipped',
    'unpaired',
    'estimates',
    'pressure commands',
    'commands without fresh length',
)
#: Inputs by topic name: (received counter, rejected counter).
SOURCES = {
    'pressure': (Counter.RECEIVED_PRESSURE, Counter.REJECTED_PRESSURE),
    'muscle_state': (Counter.RECEIVED_MUSCLE_STATE, Counter.REJECTED_MUSCLE_STATE),
    'force_command': (Counter.RECEIVED_FORCE_COMMAND, Counter.REJECTED_FORCE_COMMAND),
}


class Engine:
    """Force estimates and pressure commands of the muscles of ``configs`` (indices 0..N-1).

    ``hold`` [s]: how long a rejected input (ERROR) or a warning flag (WARN) keeps a muscle's
    level up; ``pairing``, ``slop`` [s]: :mod:`.pairing`; ``report_interval`` [s]: see
    :meth:`~.health.Health.due`.  After an input, ``estimated`` (over its muscles), ``forces``
    [N] and ``flags`` describe the answer, ``stamp`` [ns] is its stamp (the newest input stamp
    among the muscles estimated).
    """

    def __init__(
        self,
        configs: Sequence[Config],
        hold: float = 1.0,
        pairing: str = 'every_input',
        slop: float = 0.0,
        report_interval: float = 0.0,
    ) -> None:
        SPECS['pairing'].check(pairing)
        SPECS['pairing_slop'].check(slop)
        ages = {c.max_input_age for c in configs}
        if len(ages) != 1:
            raise ValueError(f'max_input_age is node-wide: got {sorted(ages)}')
        n, max_age = len(configs), nanoseconds(ages.pop())
        self.pairing = Pairing(n, pairing, nanoseconds(slop), max_age)
        self.health = Health(
            n,
            ('pressure', 'muscle_state'),
            LABELS,
            self.pairing.stamps,
            max_age,
            nanoseconds(hold),
            nanoseconds(report_interval),
        )
        self.muscles = Muscles(configs)
        self.configs = tuple(configs)
        self._everyone = np.ones(n, bool)
        self.stamp, self.estimated = 0, np.zeros(0, bool)
        self.forces, self.flags = np.zeros(0), np.zeros(0, np.uint16)

    def __len__(self) -> int:
        return len(self.configs)

    def configure(self, configs: Sequence[Config]) -> None:
        """Use ``configs`` (one per muscle, as many as before) from now on; the inputs are kept."""
        if len(configs) != len(self.configs):
            raise ValueError('configure needs one config per muscle')
        self.muscles.configure(configs)
        self.configs = tuple(configs)

    def pressures(
        self,
        readings: np.ndarray,
        stamp: int,
        now: int,
        sel: slice = ALL,
        present: np.ndarray | None = None,
    ) -> np.ndarray:
        """Pressure readings [Pa, absolute or gauge by each config's ``pressure_reference``] of the
        muscles ``sel`` (those ``present``; the caller rejects the others), stamped ``stamp``
        [ns]; which of them got an estimate.
        """
        absolute, good = self.muscles.check_pressures(sel, readings)
        valid = self._take(
            'pressure', sel, good, present, lambda i: pressure_problem(absolute[i]), now
        )
        self.muscles.store_pressures(sel, valid, absolute)
        return self._answer(PRESSURE, sel, valid, stamp, now)

    def lengths(
        self,
        lengths: np.ndarray,
        rates: np.ndarray,
        stamp: int,
        now: int,
        sel: slice = ALL,
        present: np.ndarray | None = None,
    ) -> np.ndarray:
        """Lengths [m] and rates [m/s] (NaN: unknown; the hysteresis branch follows the play
        operator, not the rate) of the muscles ``sel``; see :meth:`pressures`.
        """
        good = self.muscles.check_lengths(sel, lengths)
        limits = self.muscles.bank.max_length[sel]
        valid = self._take(
            'muscle_state',
            sel,
            good,
            present,
            lambda i: length_problem(lengths[i], limits[i]),
            now,
        )
        self.muscles.store_lengths(sel, valid, lengths, rates)
        return self._answer(LENGTH, sel, valid, stamp, now)

    def _take(self, source, sel, good, present, problem, now) -> np.ndarray | None:
        """Count the input, reject its bad values (``problem(i)``); which are valid (None: all)."""
        counts = self.health.counts[sel, SOURCES[source][0]]
        counts += 1 if present is None else present
        if present is None and good.all():
            return None
        valid = good if present is None else good & present
        start = sel.start or 0
        for i in np.flatnonzero(~good if present is None else present & ~good).tolist():
            self._invalid(start + i, source, problem(i), now)
        return valid

    def _answer(
        self, side: int, sel: slice, valid: np.ndarray | None, stamp: int, now: int
    ) -> np.ndarray:
        pairing, health, counts = self.pairing, self.health, self.health.counts
        pairing.store(side, sel, valid, stamp)
        start = sel.start or 0
        health.arrived(side, sel if valid is None else start + np.flatnonzero(valid), stamp, now)
        candidates = self._everyone[sel] if valid is None else valid
        pairs, stale, unpaired = pairing.pair(sel, candidates, now)
        counts[sel, Counter.STALE] += stale
        if unpaired is not None:
            counts[sel, Counter.UNPAIRED] += unpaired
        result = self.muscles.forces(sel, pairs)
        ok = pairs & (result.raw < np.inf)  # NaN or inf: the model gives no force there
        if (ok != pairs).any():
            length = self.muscles.length[sel]
            for i in np.flatnonzero(pairs & ~ok).tolist():
                reason = f'no force at length {length[i]:g} m ({describe(int(result.flags[i]))})'
                self._invalid(start + i, 'muscle_state', reason, now)
        counts[sel, Counter.ESTIMATES] += ok
        if (result.flags & WARN_MASK).any():
            health.warn(sel, ok, result.flags, now)
        elif ok.size == len(self.configs) and ok.all():
            health.quiet(now)
        self.estimated, self.forces, self.flags = ok, result.force, result.flags
        if ok.any():
            stamps = pairing.stamps[:, sel]
            self.stamp = int(stamps.max(axis=0)[ok].max())
        return ok

    def command(self, k: int, force: float, now: int) -> float | None:
        """A wanted tension [N] of muscle ``k``; the pressure [Pa, absolute or gauge as the
        readings] giving it, or None without a fresh length.  ``flags`` then holds its flags.
        """
        counts = self.health.counts
        counts[k, Counter.RECEIVED_FORCE_COMMAND] += 1
        if not np.isfinite(force):
            return self._invalid(k, 'force_command', f'force command is {force} N', now)
        if not abs(now - self.pairing.stamps.item(LENGTH, k)) <= self.pairing.max_age:
            counts[k, Counter.NO_LENGTH] += 1
            return None
        pressure, flags = self.muscles.command(k, force)
        self.flags = np.array([flags], np.uint16)
        self.health.warn(one(k), np.ones(1, bool), self.flags, now)
        counts[k, Counter.COMMANDS] += 1
        return pressure

    def reject(self, k: int, source: str, reason: str, now: int) -> None:
        """Count a message of ``source`` (``pressure``, ``muscle_state`` or ``force_command``)
        refused before it gave a value of muscle ``k``.
        """
        self.health.counts[k, SOURCES[source][0]] += 1
        return self._invalid(k, source, reason, now)

    def _invalid(self, k: int, source: str, reason: str, now: int) -> None:
        self.health.counts[k, SOURCES[source][1]] += 1
        self.health.reject(k, reason, now)

    def inputs(self, k: int) -> tuple[float, float, float]:
        """Muscle ``k``'s newest valid gauge pressure [Pa], length [m] and rate [m/s] (NaN:
        none).
        """
        m = self.muscles
        return m.pressure.item(k) - m.ambient.item(k), m.length.item(k), m.rate.item(k)

    def level(self, k: int, now: int) -> tuple[Level, str]:
        return self.health.level(k, now)

    def levels(self, now: int) -> np.ndarray:
        return self.health.levels(now)

    def status_due(self, now: int) -> bool:
        return self.health.due(now)

    def statuses(self, now: int) -> list[Status]:
        """Every muscle's status (level, reason, counters, input rates and stamp ages, model)."""
        return self.health.report(now, lambda k: {'model': self.configs[k].model.model.name})

    def counts(self, k: int) -> dict[str, int]:
        """Muscle ``k``'s non-zero counters by label."""
        return {label: n for label, n in zip(LABELS, self.health.counts[k].tolist()) if n}
