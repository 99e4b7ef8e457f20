"""The estimation engine: force estimates and pressure commands of N muscles from their inputs,
each decision made once (no ROS).

An input is an array of values of every muscle (a combined JointState: :meth:`Engine.pressures`,
:meth:`Engine.lengths`) or one muscle's value (:meth:`Engine.pressure`, :meth:`Engine.length`: the
one-muscle fast path in plain floats), with one stamp; the engine validates it
(:mod:`.estimation`), pairs it with the other input and checks freshness (:mod:`.pairing`),
estimates the force of the muscles that pair (:mod:`.estimation`), and keeps counters, levels and
reports (:mod:`.health`).  ``model_node`` (both input modes) and ``pma-model bag estimate`` drive
it.  Times are integer nanoseconds on one clock (ROS time in the node, log time offline); ``now``
is passed in, never read here.
"""

from __future__ import annotations

import enum
from typing import Sequence

import numpy as np

from .estimation import (
    command_problem,
    commands_ok,
    Config,
    length_problem,
    Muscles,
    no_force_problem,
    pressure_problem,
    pressures_ok,
)
from .health import Health, Level, Status, WARN_MASK
from .pairing import fresh, LENGTH, nanoseconds, Pairing, PRESSURE, UNSTAMPED
from ..files.node_parameters import SPECS

__all__ = ['Config', 'Counter', 'Engine', 'Level', 'Status']


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
    STALE_COMMAND = 11
    BEHIND = 12


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
    'stale force_command',
    'skipped behind',
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
    :meth:`~.health.Health.due`; ``max_answer_delay`` [s]: an answer given later than this after
    its input was received holds the level at WARN (:meth:`answered`).  After an input, until
    the next one: ``estimated`` (a mask over the input's muscles: N, or 1 for one muscle's
    input; ``every``: all N of an input of every muscle), ``forces`` [N] and ``flags`` (over the
    same muscles) describe the answer, ``stamp`` [ns] is its stamp (the newest input stamp among
    the muscles estimated).
    """

    def __init__(
        self,
        configs: Sequence[Config],
        hold: float = 1.0,
        pairing: str = 'every_input',
        slop: float = 0.0,
        report_interval: float = 0.0,
        max_answer_delay: float = SPECS['max_answer_delay'].default,
    ) -> None:
        SPECS['pairing'].check(pairing)
        SPECS['pairing_slop'].check(slop)
        SPECS['max_answer_delay'].check(max_answer_delay)
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
            nanoseconds(max_answer_delay),
        )
        self.muscles = Muscles(configs)
        self.configs = tuple(configs)
        self._all, self._none = np.ones(n, bool), np.zeros(n, bool)
        self._yes, self._no = np.ones(1, bool), np.zeros(1, bool)
        for constant in (self._all, self._none, self._yes, self._no):
            constant.flags.writeable = False
        self._force, self._flag = np.zeros(1), np.zeros(1, np.uint16)  # one muscle's answer
        self.stamp, self.estimated, self.every = 0, self._none, False
        self.forces, self.flags = np.zeros(n), np.zeros(n, np.uint16)

    def __len__(self) -> int:
        return len(self.configs)

    def configure(self, configs: Sequence[Config]) -> None:
        """Use ``configs`` (one per muscle, as many as before) from now on; the inputs are kept."""
        if len(configs) != len(self.configs):
            raise ValueError('configure needs one config per muscle')
        self.muscles.configure(configs)
        self.configs = tuple(configs)

    # --- every muscle
    def pressures(
        self, readings: np.ndarray, stamp: int, now: int, present: np.ndarray | None = None
    ) -> np.ndarray:
        """Pressure readings [Pa, absolute or gauge by each config's ``pressure_reference``] of
        every muscle (those ``present``; the caller rejects the others), stamped ``stamp`` [ns];
        which got an estimate.
        """
        absolute, good, span = self.muscles.take_pressures(readings)
        valid = self._take(
            'pressure', good, present, lambda k: pressure_problem(absolute.item(k)), now
        )
        self.muscles.store_pressures(valid, absolute, span)
        return self._answer(PRESSURE, valid, stamp, now)

    def lengths(
        self,
        lengths: np.ndarray,
        rates: np.ndarray,
        stamp: int,
        now: int,
        present: np.ndarray | None = None,
    ) -> np.ndarray:
        """Lengths [m] and rates [m/s] (NaN: unknown; the hysteresis branch follows the play
        operator, not the rate) of every muscle; see :meth:`pressures`.
        """
        good, span = self.muscles.take_lengths(lengths)
        limits = self.muscles.max_length
        valid = self._take(
            'muscle_state',
            good,
            present,
            lambda k: length_problem(lengths.item(k), limits.item(k)),
            now,
        )
        self.muscles.store_lengths(valid, lengths, rates, span)
        return self._answer(LENGTH, valid, stamp, now)

    def _take(self, source, good, present, problem, now) -> np.ndarray | None:
        """Count the input, reject its bad values (``problem(k)``); which are valid (None: all)."""
        self.health.count(SOURCES[source][0], present)
        if good is None:
            return present
        valid = good if present is None else good & present
        for k in np.flatnonzero(valid ^ (self._all if present is None else present)).tolist():
            self._invalid(k, source, problem(k), now)
        return valid

    def _answer(self, side: int, valid: np.ndarray | None, stamp: int, now: int) -> np.ndarray:
        pairing, health, muscles = self.pairing, self.health, self.muscles
        pairing.store(side, valid, stamp)
        health.arrived(side, valid, stamp, now)
        pairs, stale, unpaired = pairing.pair(valid, now)
        if stale is not pairing.none:
            health.count(Counter.STALE, stale)
        if unpaired is not pairing.none:
            health.count(Counter.UNPAIRED, unpaired)
        if pairs is not None:
            paired = np.count_nonzero(pairs)
            if not paired:
                self.estimated, self.every = self._none, False
                return self._none
            if paired == pairs.size:
                pairs = None
        self.forces, self.flags, ok = muscles.forces(pairs)
        if ok is not None:
            asked = self._all if pairs is None else pairs
            for k in np.flatnonzero(asked & ~ok).tolist():
                reason = no_force_problem(muscles.length.item(k), self.flags.item(k))
                self._invalid(k, 'muscle_state', reason, now)
            pairs = None if ok.all() else ok
        health.count(Counter.ESTIMATES, pairs)
        if (
            muscles.length_warns
            if self.flags is muscles.lflags
            else np.count_nonzero(self.flags & WARN_MASK)
        ):
            health.warn(pairs, self.flags, now)
        common = pairing.common()
        if common is not None:
            self.stamp = common
        else:
            newest = pairing.stamps.max(axis=0)
            self.stamp = int(newest.max() if pairs is None else newest[pairs].max())
        self.estimated, self.every = (self._all, True) if pairs is None else (pairs, False)
        return self.estimated

    # --- one muscle (the fast path)
    def pressure(self, k: int, reading: float, stamp: int, now: int) -> bool:
        """:meth:`pressures` of muscle ``k``'s reading [Pa] alone; whether it got an estimate."""
        self.health.count(Counter.RECEIVED_PRESSURE, k)
        absolute = self.muscles.pressure_one(k, reading)
        if not pressures_ok(absolute):
            self._invalid(k, 'pressure', pressure_problem(absolute), now)
            return self._one(False)
        self.muscles.store_pressure_one(k, absolute)
        return self._answer_one(PRESSURE, k, stamp, now)

    def length(self, k: int, length: float, rate: float, stamp: int, now: int) -> bool:
        """:meth:`lengths` of muscle ``k``'s length [m] and rate [m/s] (NaN: unknown) alone."""
        self.health.count(Counter.RECEIVED_MUSCLE_STATE, k)
        if not self.muscles.length_valid_one(k, length):
            limit = self.muscles.max_length.item(k)
            self._invalid(k, 'muscle_state', length_problem(length, limit), now)
            return self._one(False)
        self.muscles.store_length_one(k, length, rate)
        return self._answer_one(LENGTH, k, stamp, now)

    def _answer_one(self, side: int, k: int, stamp: int, now: int) -> bool:
        pairing, health = self.pairing, self.health
        pairing.store_one(side, k, stamp)
        health.arrived(side, k, stamp, now)
        pair, stale, unpaired = pairing.pair_one(k, now)
        if stale:
            health.count(Counter.STALE, k)
        if unpaired:
            health.count(Counter.UNPAIRED, k)
        if not pair:
            return self._one(False)
        force, flags, ok = self.muscles.force_one(k)
        self._force[0], self._flag[0] = force, flags
        if not ok:
            reason = no_force_problem(self.muscles.length.item(k), flags)
            self._invalid(k, 'muscle_state', reason, now)
            return self._one(False)
        health.count(Counter.ESTIMATES, k)
        health.warn_one(k, flags, now)
        self.stamp = max(pairing.stamps.item(PRESSURE, k), pairing.stamps.item(LENGTH, k))
        return self._one(True)

    def _one(self, estimated: bool) -> bool:
        self.estimated = self._yes if estimated else self._no
        self.forces, self.flags = self._force, self._flag
        return estimated

    # --- commands, rejections, reports
    def command(self, k: int, force: float, now: int, stamp: int = UNSTAMPED) -> float | None:
        """A wanted tension [N] of muscle ``k`` stamped ``stamp`` [ns]; the pressure [Pa, absolute
        or gauge as the readings] giving it, or None: a stamp older or newer than ``max_input_age``
        (0, unstamped: taken as ``now``; :meth:`~.health.Health.stale_command`), or no fresh
        length.  ``flags`` then holds its flags.
        """
        health = self.health
        health.count(Counter.RECEIVED_FORCE_COMMAND, k)
        if not commands_ok(force):
            return self._invalid(k, 'force_command', command_problem(force), now)
        if health.stale_command(k, 'force_command', stamp, now, Counter.STALE_COMMAND):
            return None
        if not fresh(self.pairing.stamps.item(LENGTH, k), now, self.pairing.max_age):
            health.count(Counter.NO_LENGTH, k)
            return None
        pressure, flags = self.muscles.command(k, force)
        self._flag[0] = flags
        self.flags = self._flag
        health.warn_one(k, flags, now)
        health.count(Counter.COMMANDS, k)
        return pressure

    def behind(self, source: str, which: int | None) -> None:
        """Count an input of ``source`` (``pressure`` or ``muscle_state``) of muscle ``which``
        (None: every muscle, a combined message) skipped unread: the node took it from its queue
        longer than ``max_queue_delay`` after DDS received it (a node that fell behind skips to
        its newest inputs; offline, nothing waits in a queue).
        """
        self.health.count(SOURCES[source][0], which)
        self.health.count(Counter.BEHIND, which)

    def answered(self, k: int | None, delay: int, now: int) -> None:
        """The answer to an input went out ``delay`` [ns] after the input was received: an input
        of muscle ``k``, or (None) of every muscle, whose answer holds the muscles
        :attr:`estimated`.
        """
        self.health.answered(k if k is not None or self.every else self.estimated, delay, now)

    def reject(self, k: int, source: str, reason: str, now: int) -> None:
        """Count a message of ``source`` (``pressure``, ``muscle_state`` or ``force_command``)
        refused before it gave a value of muscle ``k``.
        """
        self.health.count(SOURCES[source][0], k)
        return self._invalid(k, source, reason, now)

    def _invalid(self, k: int, source: str, reason: str, now: int) -> None:
        self.health.count(SOURCES[source][1], k)
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
        return {label: n for label, n in zip(LABELS, self.health.counts(k)) if n}
