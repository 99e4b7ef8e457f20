"""Health of N entities (muscles or joints): named counters, latched problems and warnings, input
rates and stamp ages, diagnostic levels with their texts, and when to report (no ROS).

One implementation for model_node's and joint_node's engines, so both nodes report alike:

* ERROR for ``hold`` after a rejected input (``invalid input: <reason>``) or a stale command
  (``stale <command>: stamp is ...``), and while an input was never received or is stale
  (``no <input> received yet``, ``stale <input>: newest stamp is ...``);
* WARN for ``hold`` after a warning flag of an estimate or command (:data:`WARN_FLAGS`), or an
  answer given longer than ``max_answer_delay`` after its input was received (``answers late``);
* else OK, ``estimating``.

A report is due when a level differs from the last report (at most every ``report_interval``);
the nodes also report every second.  Each status's values: the non-zero counters, then per input
what diagnostic_updater's FrequencyStatus and TimeStampStatus report, over the window since the
previous report, the longest time from an input's reception to its answer in that window
(``answer delay max [ms]``, where the node knows reception times), then the engine's own values and
:attr:`Health.extra` (static key-values per entity: a hook for, e.g., identification results).

An event concerns every entity (``which`` None: kept as one number, so that an input of every
muscle costs no array operation), the entities of a boolean mask, or one entity (an int).
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import functools
from typing import Callable, Sequence

import numpy as np

from .pairing import fresh, nanoseconds, NEVER, SECOND, stale_command_stamps
from ..physics.flags import Flag

Which = np.ndarray | int | None  #: every entity (None), a mask, or one entity


class Level(enum.IntEnum):
    """Diagnostic level; values equal diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2


#: Flags that make an estimate or command WARN, with their diagnostic wording.
WARN_FLAGS = {
    Flag.SATURATED: 'saturated',
    Flag.LENGTH_OUT_OF_RANGE: 'outside validity domain',
    Flag.PRESSURE_OUT_OF_RANGE: 'outside validity domain',
    Flag.BRANCH_UNKNOWN: 'hysteresis branch unknown',
    Flag.EXTRAPOLATED: 'extrapolated beyond the identified data',
    Flag.BELOW_AMBIENT: (
        'pressure far below ambient: a gauge sensor read as absolute? (pressure_reference)'
    ),
}
WARN_MASK = int(sum(WARN_FLAGS))
_WARN_TEXTS = tuple(f'{text} ({flag.name})' for flag, text in WARN_FLAGS.items())
WARN_BITS = tuple(int(flag) for flag in WARN_FLAGS)  #: the warning flags, in their order
_WARN_ARRAY = np.array(WARN_BITS, np.uint16)
OK_TEXT = 'estimating'
#: [s] Shortest time between two on-change reports of a node (model_node, joint_node and the
#: offline twin), per status reported: building and publishing the statuses of 64 muscles took
#: 5.3 ms as rclpy messages, 1.7-2.0 ms with the bytes writer (wire/diagnostics.py;
#: bench/node_latency.py), so on-change reports stay a few percent of a core however many entities
#: flap (N = 64: at most one every 0.1 s).
REPORT_INTERVAL_PER_STATUS = 0.0015
#: [s] Period of the nodes' /diagnostics reports; also how long a bad input or a warning holds the
#: level.
DIAGNOSTIC_PERIOD = 1.0
DIAGNOSTIC_PERIOD_NS = nanoseconds(DIAGNOSTIC_PERIOD)  #: the same [ns] (the offline twin's timer)


def node_timing(statuses: int) -> dict[str, float]:
    """``hold`` and ``report_interval`` [s] of the :class:`Health` of a node that reports
    ``statuses`` statuses (model_node, joint_node and the offline twin alike).
    """
    return {'hold': DIAGNOSTIC_PERIOD, 'report_interval': REPORT_INTERVAL_PER_STATUS * statuses}


def levels_of(
    now: np.ndarray | int,
    rejected_at: np.ndarray,
    stamps: np.ndarray,
    warned_at: np.ndarray,
    hold: int,
    max_age: int,
) -> np.ndarray:
    """Levels (int8) at ``now`` [ns] of entities whose latest rejection was at ``rejected_at``,
    whose inputs' newest stamps are ``stamps`` (one row per input) and whose latest warning was at
    ``warned_at`` [ns; NEVER: none] (arrays that broadcast: entities, or one entity at many times).
    """
    error = (now - rejected_at < hold) | ~fresh(stamps, now, max_age).all(axis=0)
    warn = now - warned_at < hold
    return np.where(error, np.int8(Level.ERROR), warn.view(np.int8))


def invalid_text(reason: str) -> str:
    """``invalid input: <reason>``: what a refused input latches for ``hold``."""
    return f'invalid input: {reason}'


def stale_text(name: str, which: str, age: int, max_age: int) -> str:
    """``stale <name>: <which> is <age> s old (max_input_age <max_age> s)`` (ages [ns]; a negative
    age: ``in the future``).
    """
    seconds = age / SECOND
    when = f'{seconds:.3g} s old' if seconds > 0 else f'{-seconds:.3g} s in the future'
    return f'stale {name}: {which} is {when} (max_input_age {max_age / SECOND:g} s)'


def late_text(delay: int, bound: int) -> str:
    """``answers late: <delay> ms after their input arrived (max_answer_delay <bound> ms)``
    (``delay``, ``bound`` [ns]).
    """
    return (
        f'answers late: {delay / 1e6:.3g} ms after their input arrived (max_answer_delay '
        f'{bound / 1e6:g} ms)'
    )


@dataclass(frozen=True)
class Status:
    level: Level
    message: str
    values: dict[str, str]


class Health:
    """Diagnostics of ``count`` entities fed by ``inputs`` (names, e.g. ``pressure``; or one tuple
    of names per entity), with the ``counters`` (labels) counted by :meth:`count`.

    ``stamps`` (inputs x count, [ns]) is the newest valid stamp of each input, written by its
    owner (:meth:`arrived`; NEVER: none); ``max_age`` [ns]: freshness; ``hold`` [ns]: how long a
    rejection or warning keeps the level up; ``max_answer_delay`` [ns]: :meth:`answered`.
    """

    def __init__(
        self,
        count: int,
        inputs: Sequence[str] | Sequence[Sequence[str]],
        counters: Sequence[str],
        stamps: np.ndarray,
        max_age: int,
        hold: int = SECOND,
        report_interval: int = 0,
        max_answer_delay: float = np.inf,
    ) -> None:
        names = [tuple(inputs)] * count if isinstance(inputs[0], str) else list(map(tuple, inputs))
        shape = (len(names[0]), count)
        self.inputs, self.labels, self.stamps = names, tuple(counters), stamps
        self.max_age, self.hold, self.report_interval = max_age, hold, report_interval
        # per entity in Python lists (one entity's event costs no numpy call); every entity's as
        # one number
        self._counts = [[0] * len(counters) for _ in range(count)]
        self._counts_all = [0] * len(counters)
        #: static key-values added to each entity's status (e.g. identification results)
        self.extra: list[dict[str, str]] = [{} for _ in range(count)]
        self._arrivals = [[0] * count for _ in range(shape[0])]  # valid inputs, [input][entity]
        self._arrivals_all = [0] * shape[0]
        self._delay_min = [[np.inf] * count for _ in range(shape[0])]  # [s]
        self._delay_max = [[-np.inf] * count for _ in range(shape[0])]
        self._delay_all = [[np.inf, -np.inf] for _ in range(shape[0])]  # (min, max) [s]
        self._late, self._early, self._zero = (np.zeros(shape, np.int64) for _ in range(3))
        # when each entity last refused an input or command, and the text of it
        self._rejected_at, self._latched = np.full(count, NEVER, np.int64), [''] * count
        self._warned_at = np.full((count, len(WARN_FLAGS)), NEVER, np.int64)
        # the longest reception-to-answer delay [ns] of this window (-1: none known), and when
        # each entity last answered later than max_answer_delay, how late [ns]
        self.max_answer_delay = max_answer_delay
        self._answer_max, self._answer_max_all = [-1] * count, -1
        self._late_at, self._late_by = np.full(count, NEVER, np.int64), [0] * count
        #: each entity's level in the last report (-1: none), and its time [ns] (NEVER: none)
        self.reported = np.full(count, -1, np.int64)
        self._window_start = np.full(count, NEVER, np.int64)
        self._window_arrivals = np.zeros(shape, np.int64)
        self.last_report = NEVER
        #: every level was reported OK and no event changed one since (rejections, warnings and
        #: stale inputs clear it): then only time raises one, after _fresh_until [ns], when an
        #: input is older than max_age (or if the clock went back before _checked_at [ns])
        self._steady, self._checked_at, self._fresh_until = False, NEVER, NEVER

    # --- events
    def count(self, counter: int, which: Which = None) -> None:
        """Add 1 to ``counter`` of the entities ``which``."""
        if which is None:
            self._counts_all[counter] += 1
        elif isinstance(which, int):
            self._counts[which][counter] += 1
        else:
            for k in np.flatnonzero(which).tolist():
                self._counts[k][counter] += 1

    def counts(self, k: int) -> list[int]:
        """Entity ``k``'s counters, in the order of the labels."""
        return [n + m for n, m in zip(self._counts[k], self._counts_all)]

    def arrived(self, i: int, which: Which, stamp: int, now: int) -> None:
        """Input ``i`` of the entities ``which`` was valid, stamped ``stamp`` (its owner writes
        :attr:`stamps`).
        """
        delay = (now - stamp) / SECOND
        if not fresh(stamp, now, self.max_age):  # a stale input: the levels may have changed
            self._steady = False
        elif self._steady:  # a fresh one stays fresh while now lies within max_age of it
            self._checked_at = max(self._checked_at, stamp - self.max_age)
            self._fresh_until = min(self._fresh_until, stamp + self.max_age)
        if which is None:
            self._arrivals_all[i] += 1
            low_high = self._delay_all[i]
            low_high[0], low_high[1] = min(low_high[0], delay), max(low_high[1], delay)
        else:
            arrivals, low, high = self._arrivals[i], self._delay_min[i], self._delay_max[i]
            for k in [which] if isinstance(which, int) else np.flatnonzero(which).tolist():
                arrivals[k] += 1
                if delay < low[k]:
                    low[k] = delay
                if delay > high[k]:
                    high[k] = delay

    def answered(self, which: Which, delay: int, now: int) -> None:
        """The entities ``which`` were answered ``delay`` [ns] after their input was received;
        past ``max_answer_delay`` that holds their level at WARN for ``hold``.
        """
        if which is None:
            self._answer_max_all = max(self._answer_max_all, delay)
            late = range(len(self._answer_max))
        else:
            late = [which] if isinstance(which, int) else np.flatnonzero(which).tolist()
            for k in late:
                if delay > self._answer_max[k]:
                    self._answer_max[k] = delay
        if delay > self.max_answer_delay:
            for k in late:
                self._late_at[k], self._late_by[k] = now, delay
            self._steady = False

    def reject(self, k: int, reason: str, now: int) -> None:
        """Entity ``k`` refused an input for ``reason`` (counted by the caller)."""
        self._refuse(k, invalid_text(reason), now)

    def _refuse(self, k: int, text: str, now: int) -> None:
        """Entity ``k``'s level ERROR for ``hold`` from ``now``, with ``text``."""
        self._rejected_at[k], self._latched[k], self._steady = now, text, False

    def stale_command(self, k: int, name: str, stamp: int, now: int, counter: int) -> bool:
        """Whether a command ``name`` of entity ``k`` stamped ``stamp`` [ns] is stale: its stamp
        differs from ``now`` by more than ``max_age``, as a stale input's (a zero stamp,
        :data:`~.pairing.UNSTAMPED`, is taken as ``now``).  A stale command is refused: counted
        in ``counter``, its text holds the level at ERROR for ``hold``, as a rejection.
        """
        if not stale_command_stamps(stamp, now, self.max_age):
            return False
        self._refuse(k, stale_text(name, 'stamp', now - stamp, self.max_age), now)
        self.count(counter, k)
        return True

    def warn(self, which: np.ndarray | None, flags: np.ndarray, now: int) -> None:
        """The entities ``which`` (a mask, None: all) gave results with ``flags`` (one word per
        entity): their warning flags hold the level at WARN.
        """
        hit = (flags[:, None] & _WARN_ARRAY) != 0
        if which is not None:
            hit &= which[:, None]
        if hit.any():
            self._warned_at[hit] = now
            self._steady = False

    def warn_one(self, k: int, flags: int, now: int) -> None:
        """:meth:`warn` of entity ``k``'s result with ``flags``."""
        if flags & WARN_MASK:
            for j, bit in enumerate(WARN_BITS):
                if flags & bit:
                    self._warned_at[k, j] = now
            self._steady = False

    # --- levels and reports
    def levels(self, now: int) -> np.ndarray:
        """Every entity's level."""
        warned = np.maximum(self._warned_at.max(axis=1), self._late_at)
        return levels_of(now, self._rejected_at, self.stamps, warned, self.hold, self.max_age)

    def level(self, k: int, now: int) -> tuple[Level, str]:
        """Entity ``k``'s level and its one-line reason."""
        if now - self._rejected_at.item(k) < self.hold:
            return Level.ERROR, self._latched[k]
        for name, stamp in zip(self.inputs[k], self.stamps[:, k].tolist()):
            if stamp == NEVER:
                return Level.ERROR, f'no {name} received yet'
            if not fresh(stamp, now, self.max_age):
                return Level.ERROR, stale_text(name, 'newest stamp', now - stamp, self.max_age)
        warned = self._warned_at[k].tolist()
        texts = {text for text, at in zip(_WARN_TEXTS, warned) if now - at < self.hold}
        if now - self._late_at.item(k) < self.hold:
            texts.add(late_text(self._late_by[k], self.max_answer_delay))
        if texts:
            return Level.WARN, '; '.join(sorted(texts))
        return Level.OK, OK_TEXT

    def restore(
        self,
        k: int,
        counts: Sequence[int],
        arrivals: Sequence[int],
        delays: Sequence[tuple[float, float]],
        rejected: tuple[int, str],
        warned_at: Sequence[int],
    ) -> None:
        """Set entity ``k``'s events as counted elsewhere (``bag estimate``'s pass over a whole
        recording), before :meth:`report`: its ``counts`` (in the order of the labels), valid
        ``arrivals`` of each input since start-up, the (earliest, latest) delay [s] of each input
        since the last report ((inf, -inf): none), its latest refused input or command (time [ns],
        the text it latches: :func:`invalid_text` or :func:`stale_text`) and the latest time [ns]
        each warning flag was raised (NEVER: never).  :attr:`stamps` is its owner's.
        """
        self._counts[k][:] = counts
        for i, (n, (low, high)) in enumerate(zip(arrivals, delays)):
            self._arrivals[i][k], self._delay_min[i][k], self._delay_max[i][k] = n, low, high
        self._rejected_at[k], self._latched[k] = rejected
        self._warned_at[k] = warned_at
        self._steady = False

    def due(self, now: int) -> bool:
        """Whether a level differs from the last report, and ``report_interval`` has passed since
        it (a node that falls behind, its inputs flapping between fresh and stale, must not spend
        its time reporting).
        """
        if 0 <= now - self.last_report < self.report_interval:
            return False
        if self._steady and self._checked_at <= now <= self._fresh_until:
            return False  # every level was reported OK and nothing happened since
        levels = self.levels(now)
        due = bool((levels != self.reported).any())
        self._steady = not due and not levels.any()
        if self._steady:  # until an input goes stale, only an event can change a level
            self._checked_at, self._fresh_until = now, int(self.stamps.min()) + self.max_age
        return due

    def report(self, now: int, own: Callable[[int], dict[str, str]] | None = None) -> list[Status]:
        """Every entity's status; ``own(k)``: the engine's values of entity ``k``."""
        arrivals = np.array(self._arrivals) + np.array(self._arrivals_all)[:, None]
        low = np.minimum(self._delay_min, np.array([d[0] for d in self._delay_all])[:, None])
        high = np.maximum(self._delay_max, np.array([d[1] for d in self._delay_all])[:, None])
        events = arrivals - self._window_arrivals
        limit = self.max_age / SECOND
        self._zero += events == 0
        self._late += high > limit
        self._early += low < -limit
        start = self._window_start
        window = np.where(start != NEVER, (now - start) / SECOND, 0.0)  # [s] per entity
        # one input's numbers of every entity as lists (a report formats ~22 per entity)
        columns = [
            a.tolist() for a in (events, arrivals, low, high, self._late, self._early, self._zero)
        ]
        windows, statuses = window.tolist(), []
        for k in range(len(self.reported)):
            level, message = self.level(k, now)
            values = {label: str(n) for label, n in zip(self.labels, self.counts(k)) if n}
            for i, name in enumerate(self.inputs[k]):
                values |= _input_values(name, windows[k], limit, *(c[i][k] for c in columns))
            answer = max(self._answer_max[k], self._answer_max_all)
            if answer >= 0:
                values['answer delay max [ms]'] = f'{answer / 1e6:.3f}'
            values |= own(k) if own else {}
            values |= self.extra[k]
            statuses.append(Status(level, message, values))
            self.reported[k], self._window_start[k] = level, now
        self._window_arrivals[:] = arrivals
        for row in self._delay_min:
            row[:] = [np.inf] * len(row)
        for row in self._delay_max:
            row[:] = [-np.inf] * len(row)
        self._delay_all = [[np.inf, -np.inf] for _ in self._delay_all]
        self._answer_max[:], self._answer_max_all = [-1] * len(self._answer_max), -1
        self._steady, self.last_report = False, now
        return statuses


class FaultLog:
    """Which faults a node logs: one line per cause (a status message's words before its first
    colon: ``invalid input``, ``stale pressure``, ``answers late``, ...) at most every ``period``
    [ns], naming the entities that have it; /diagnostics carries every report.
    """

    #: entities named in one line, at most
    NAMES = 5

    def __init__(self, period: int = SECOND) -> None:
        self.period = period
        self._logged: dict[str, int] = {}  # cause -> when it was last logged [ns]

    def lines(
        self, entries: Sequence[tuple[str, Level, str]], now: int
    ) -> list[tuple[Level, str]]:
        """The lines to log now of the (name, level, message) ``entries`` of a report, each with
        the highest level of its cause: ``<names>: <the first entity's message>``.
        """
        causes: dict[str, tuple[Level, list[str], str]] = {}
        for name, level, message in entries:
            if level == Level.OK:
                continue
            cause = message.split(':', 1)[0]
            top, names, first = causes.get(cause, (level, [], message))
            causes[cause] = (max(top, level), [*names, name], first)
        out = []
        for cause, (level, names, message) in causes.items():
            if 0 <= now - self._logged.get(cause, NEVER) < self.period:
                continue
            self._logged[cause] = now
            shown = ', '.join(names[: self.NAMES]) + (
                f' and {len(names) - self.NAMES} more' if len(names) > self.NAMES else ''
            )
            out.append((Level(level), f'{shown}: {message}'))
        return out


def _input_values(
    name: str,
    window: float,
    limit: float,
    events: int,
    total: int,
    early: float,
    late: float,
    late_count: int,
    early_count: int,
    zero_count: int,
) -> dict[str, str]:
    """The FrequencyStatus and TimeStampStatus values of input ``name`` of an entity: ``events``
    valid inputs in its ``window`` [s] (``total`` since start-up), their ``early`` and ``late``
    delays [s] against ``limit`` [s], and its counts of late, early and empty windows.
    """
    return dict(
        zip(
            _input_keys(name),
            (
                str(events),
                str(total),
                f'{window:f}',
                f'{events / window if window > 0 else 0.0:f}',
                f'{early if events else 0.0:f}',
                f'{late if events else 0.0:f}',
                f'{-limit:f}',
                f'{limit:f}',
                str(late_count),
                str(early_count),
                str(zero_count),
            ),
        )
    )


@functools.cache
def _input_keys(name: str) -> tuple[str, ...]:
    """The keys of input ``name``'s FrequencyStatus and TimeStampStatus values, in
    diagnostic_updater's order and words (a report writes them for every entity and input).
    """
    return tuple(
        f'{name}: {key}'
        for key in (
            'Events in window',
            'Events since startup',
            'Duration of window (s)',
            'Actual frequency (Hz)',
            'Earliest timestamp delay:',
            'Latest timestamp delay:',
            'Earliest acceptable timestamp delay:',
            'Latest acceptable timestamp delay:',
            'Late diagnostic update count:',
            'Early diagnostic update count:',
            'Zero seen diagnostic update count:',
        )
    )
