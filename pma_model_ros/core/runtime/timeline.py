"""Health over a whole recording: when the node reports, and what (no ROS).

:mod:`.recording` turns each muscle's inputs into health events (:class:`Events`: counters,
arrivals, rejections, warnings, at message positions).  Here the levels after every input follow
from them at once (:func:`~.health.levels_of`); the node reports on change after the inputs where
:meth:`~.health.Health.due` would say so (a level differs from the last report's, and the report
interval has passed since it: only the inputs where a level changes, and the first one the
interval lets through after a report, need looking at) and at 1 Hz of log time; each report is
built by the engine's own :meth:`~.health.Health.report` from the state restored at that point
(:meth:`~.health.Health.restore`).  The state since the last report carries over between
stretches of recording.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import NamedTuple

import numpy as np

from .engine import Counter, Engine
from .health import DIAGNOSTIC_PERIOD_NS, levels_of, Status, WARN_BITS
from .pairing import NEVER, SECOND


class Report(NamedTuple):
    """A /diagnostics report: at 1 Hz before the message at ``at``, or on change after it."""

    at: int
    after: bool
    now: int  #: [ns]
    statuses: list[Status]
    #: each muscle's newest valid length [m] (NaN: none): the node's ``engine.inputs(k)[1]``
    lengths: list[float]


class Events(NamedTuple):
    """One muscle's decisions over a stretch, as events at message positions."""

    at: np.ndarray  #: positions of its inputs
    counters: list[np.ndarray]  #: per Counter, the positions where it counts one
    arrivals: list[tuple[np.ndarray, np.ndarray]]  #: per input: (positions, now - stamp [ns])
    #: refused inputs and commands: positions, times [ns], the texts they latch (Health's)
    rejections: tuple[np.ndarray, np.ndarray, list[str]]
    warnings: list[tuple[np.ndarray, np.ndarray]]  #: per warning flag: (positions, times)
    #: before the stretch (column 0) and after each input: the newest stamps (2 x E+1), the
    #: latest rejection and warning times (E+1), the newest valid length [m] (E+1, NaN: none)
    stamps: np.ndarray
    rejected_at: np.ndarray
    warned_at: np.ndarray
    lengths: np.ndarray


@dataclass
class _Held:
    """One muscle's health state between stretches."""

    counts: np.ndarray = field(default_factory=lambda: np.zeros(len(Counter), np.int64))
    arrivals: list[int] = field(default_factory=lambda: [0, 0])
    #: per input, (min, max) of now - stamp [ns] since the last report (None: no arrival)
    window: list = field(default_factory=lambda: [None, None])
    rejected: tuple[int, str] = (NEVER, '')
    warned_at: np.ndarray = field(default_factory=lambda: np.full(len(WARN_BITS), NEVER))


class Timeline:
    """The reports of ``engine``'s node over a recording, stretch by stretch."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.hold, self.interval = engine.health.hold, engine.health.report_interval
        self.max_age = engine.pairing.max_age
        self._held = [_Held() for _ in range(len(engine))]
        self._next_status: int | None = None
        self._windows: list[list[int]] = []

    def counts(self, k: int) -> dict[str, int]:
        """Muscle ``k``'s counters so far (non-zero, by label), as :meth:`Engine.counts`."""
        labels = self.engine.health.labels
        return {label: n for label, n in zip(labels, self._held[k].counts.tolist()) if n}

    def latest(self, k: int) -> tuple[int, int]:
        """Muscle ``k``'s latest rejection and warning [ns] before the stretch (NEVER: none)."""
        held = self._held[k]
        return held.rejected[0], int(held.warned_at.max())

    def reports(
        self, events: list[Events], first: int, times: np.ndarray, input_at: np.ndarray
    ) -> list[Report]:
        """The node's /diagnostics reports over a stretch (messages at positions ``first`` ...,
        log times ``times``, the node's inputs at ``input_at``), in order.
        """
        if self._next_status is None and len(times):
            self._next_status = int(times[0]) + DIAGNOSTIC_PERIOD_NS  # the node's status timer
        out = self._reports(events, first, times, input_at)
        for k, h in enumerate(events):
            self._carry(k, h)
        return out

    def _reports(
        self, events: list[Events], first: int, times: np.ndarray, input_at: np.ndarray
    ) -> list[Report]:
        """The node's /diagnostics reports over the stretch: at 1 Hz (before the first message
        at or after each second) and on change (after an input whose levels differ from the last
        report's, once ``report_interval`` has passed since it).
        """
        inputs_now = times[input_at - first]
        count = len(input_at)
        levels = np.empty((count, len(events)), np.int8)
        for k, h in enumerate(events):
            j = (
                np.arange(1, count + 1)
                if len(h.at) == count
                else np.searchsorted(h.at, input_at, 'right')
            )
            levels[:, k] = levels_of(
                inputs_now,
                h.rejected_at[j],
                h.stamps[:, j],
                h.warned_at[j],
                self.hold,
                self.max_age,
            )
        changes = np.flatnonzero((levels[1:] != levels[:-1]).any(axis=1)) + 1
        timers = []
        while len(times) and self._next_status <= times[-1]:
            timers.append(self._next_status)
            self._next_status += DIAGNOSTIC_PERIOD_NS
        timer_at = first + np.searchsorted(times, timers, 'left')
        windows = [[0, 0] for _ in events]  # per muscle and input: first arrival in the window
        reports: list[Report] = []
        health = self.engine.health  # its report sets the levels and time of the last report

        def report(at: int, after: bool, now: int) -> None:
            lengths = self._restore(events, windows, at, 'right' if after else 'left')
            reports.append(Report(at, after, now, self.engine.statuses(now), lengths))

        def passed(start: int) -> int:
            """The first input from ``start`` on that the report interval lets through."""
            gate = np.searchsorted(inputs_now, health.last_report + self.interval, 'left')
            return max(start, int(gate))

        i, t = passed(0), 0
        while True:
            if t < len(timers) and (i >= count or timer_at[t] <= input_at[i]):
                report(int(timer_at[t]), False, timers[t])
                i = passed(int(np.searchsorted(input_at, timer_at[t], 'left')))
                t += 1
            elif i >= count:
                break
            elif (levels[i] != health.reported).any():
                report(int(input_at[i]), True, int(inputs_now[i]))
                i = passed(i + 1)
            else:
                later = np.searchsorted(changes, i, 'right')
                i = int(changes[later]) if later < len(changes) else count
        self._windows = windows
        return reports

    def _restore(self, events: list[Events], windows: list, at: int, side: str) -> list[float]:
        """Set the engine's health to each muscle's state at position ``at`` (``side`` 'right':
        after the message there, 'left': before it), for a report; the report starts a new window
        of arrivals.  Each muscle's newest valid length [m] there (NaN: none).
        """
        health, lengths = self.engine.health, []
        for k, h in enumerate(events):
            carry = self._held[k]
            counts = [
                n + np.searchsorted(c, at, side) for n, c in zip(carry.counts.tolist(), h.counters)
            ]
            arrivals, delays = [], []
            for s, (positions, delay) in enumerate(h.arrivals):
                end = int(np.searchsorted(positions, at, side))
                arrivals.append(carry.arrivals[s] + end)
                window = _widened(carry.window[s], delay[windows[k][s] : end])
                delays.append(
                    (math.inf, -math.inf)
                    if window is None
                    else (window[0] / SECOND, window[1] / SECOND)
                )
                carry.window[s], windows[k][s] = None, end
            positions, when, texts = h.rejections
            r = int(np.searchsorted(positions, at, side)) - 1
            rejected = (int(when[r]), texts[r]) if r >= 0 else carry.rejected
            warned = []
            for held, (positions, when) in zip(carry.warned_at.tolist(), h.warnings):
                w = int(np.searchsorted(positions, at, side)) - 1
                warned.append(int(when[w]) if w >= 0 else held)
            health.restore(k, counts, arrivals, delays, rejected, warned)
            j = np.searchsorted(h.at, at, side)
            health.stamps[:, k] = h.stamps[:, j]
            lengths.append(h.lengths.item(j))
        return lengths

    def _carry(self, k: int, h: Events) -> None:
        """Muscle ``k``'s health state after the stretch."""
        carry = self._held[k]
        carry.counts += [len(c) for c in h.counters]
        for s, (positions, delay) in enumerate(h.arrivals):
            carry.arrivals[s] += len(positions)
            carry.window[s] = _widened(carry.window[s], delay[self._windows[k][s] :])
        positions, when, texts = h.rejections
        if len(positions):
            carry.rejected = (int(when[-1]), texts[-1])
        for j, (positions, when) in enumerate(h.warnings):
            if len(positions):
                carry.warned_at[j] = when[-1]


def _widened(window: tuple[int, int] | None, delays: np.ndarray) -> tuple[int, int] | None:
    """``window`` (min, max) of now - stamp [ns] (None: no arrival), widened by ``delays``."""
    if not len(delays):
        return window
    low, high = int(delays.min()), int(delays.max())
    return (low, high) if window is None else (min(window[0], low), max(window[1], high))
