"""The engine's decisions over a whole recording at once: ``bag estimate``'s one pass (no ROS).

The node decides message by message (:class:`~.engine.Engine`).  Offline every input is known in
advance, so each rule runs once over the arrays of a muscle's inputs in log order, the log time
being the node's clock:

* validation: which readings are values (the bounds of :mod:`.estimation`), each refusal with the
  node's reason;
* the hysteresis branch: the play operator along the stream (:func:`~.hysteresis.play`);
* the length-dependent coefficients once per valid length, by the node's own path: the one-muscle
  float path (:meth:`~.muscle_model.MuscleModel.operating_one`) for a muscle's own topics, the
  bank's arrays for inputs of every muscle (combined JointStates);
* pairing and freshness: :func:`~.pairing.pair_every_input` over the stream, or
  :meth:`~.pairing.Pairing.pair_one` along it (``approximate_time``);
* the forces of every pair in one call (:func:`~.muscle_model.force_at`), the commands in one
  (:meth:`~.muscle_model.Evaluator.pressure`);
* health: counters, arrivals, rejections and warnings as arrays of events; the levels after every
  input (:func:`~.health.levels_of`); a report on change wherever :meth:`~.health.Health.due`
  would make one, and at 1 Hz, each built by :meth:`~.health.Health.report` from the state
  restored at that point.

A recording is taken in stretches; each muscle's state (newest inputs, branch, coefficients,
counters, latest rejection and warnings, the window of the next report) carries over.
``test/test_bags_estimate.py`` pins the whole to the engine, message for message.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import NamedTuple, Sequence

import numpy as np

from .engine import Counter, Engine
from .estimation import ABSURD_PRESSURE, length_problem, pressure_problem
from .flags import describe, Flag
from .health import levels_of, Status, WARN_FLAGS
from .hysteresis import play
from .muscle_model import force_at, Operating
from .pairing import fresh, NEVER, pair_every_input, Pairing, SECOND

PRESSURE_IN, LENGTH_IN, COMMAND_IN = 0, 1, 2  #: kinds of input
_WARN_BITS = tuple(int(flag) for flag in WARN_FLAGS)  # health's order
_WARN_MASK = sum(_WARN_BITS)
_INVALID = int(Flag.INVALID_INPUT)


@dataclass
class Inputs:
    """One muscle's input messages of a stretch of recording, in log order."""

    at: np.ndarray  #: int64, increasing: each message's position in the recording
    now: np.ndarray  #: int64 [ns]: its log time (the node's clock)
    kind: np.ndarray  #: int8: PRESSURE_IN, LENGTH_IN or COMMAND_IN
    stamp: np.ndarray  #: int64 [ns]: header stamp (commands: unused)
    value: np.ndarray  #: pressure reading [Pa], length [m] or wanted tension [N]
    rate: np.ndarray  #: length rate [m/s] (NaN: unknown)
    #: messages refused before they gave a value (a JointState without the muscle): index -> reason
    refused: dict[int, str] = field(default_factory=dict)


class Estimates(NamedTuple):
    """One muscle's force estimates: as the node's after each of these inputs."""

    at: np.ndarray  #: position of the input that completed the pair
    stamp: np.ndarray  #: [ns] the newer input stamp
    force: np.ndarray  #: [N]
    flags: np.ndarray  #: uint16
    gauge: np.ndarray  #: [Pa] newest valid gauge pressure
    length: np.ndarray  #: [m] newest valid length
    rate: np.ndarray  #: [m/s] its rate


class Commands(NamedTuple):
    """One muscle's pressure commands."""

    at: np.ndarray  #: position of the force command
    pressure: np.ndarray  #: [Pa, absolute or gauge as the readings]
    flags: np.ndarray  #: uint16


class Report(NamedTuple):
    """A /diagnostics report: at 1 Hz before the message at ``at``, or on change after it."""

    at: int
    after: bool
    now: int  #: [ns]
    statuses: list[Status]


@dataclass
class Stretch:
    """What the node publishes for a stretch of recording."""

    estimates: list[Estimates]  #: per muscle
    commands: list[Commands]  #: per muscle
    reports: list[Report]  #: in order


@dataclass
class _Carry:
    """One muscle's state between stretches."""

    pairing: Pairing  #: the newest valid stamps (and, approximate_time, which are new)
    pressure: float = math.nan  #: newest valid absolute pressure [Pa]
    length: float = math.nan  #: newest valid length [m]
    rate: float = math.nan
    coefficients: tuple = (_INVALID, math.nan, math.nan, math.nan)  #: (flags, q2, q1, q0)
    branch: float = 0.0
    anchor: float = math.nan
    counts: np.ndarray = field(default_factory=lambda: np.zeros(len(Counter), np.int64))
    arrivals: list[int] = field(default_factory=lambda: [0, 0])
    #: per input, (min, max) of now - stamp [ns] since the last report (None: no arrival)
    window: list = field(default_factory=lambda: [None, None])
    rejected: tuple[int, str] = (NEVER, '')
    warned_at: np.ndarray = field(default_factory=lambda: np.full(len(_WARN_BITS), NEVER))


class _Prepared(NamedTuple):
    """One muscle's inputs validated, with the hysteresis branch along them."""

    ok: tuple[np.ndarray, np.ndarray, np.ndarray]  #: valid pressures, lengths, commands
    absolute: np.ndarray  #: [Pa] absolute pressures (of the pressure readings)
    branch: np.ndarray  #: the branch after each input that moved it (NaN: it did not)
    #: where the coefficients change: (input index, length [m], branch)
    epochs: tuple[np.ndarray, np.ndarray, np.ndarray]
    end: tuple[float, float]  #: (branch, anchor) after the stretch


class _Events(NamedTuple):
    """One muscle's decisions over a stretch, as events at message positions."""

    at: np.ndarray  #: positions of its inputs
    counters: list[np.ndarray]  #: per Counter, the positions where it counts one
    arrivals: list[tuple[np.ndarray, np.ndarray]]  #: per input: (positions, now - stamp [ns])
    rejections: tuple[np.ndarray, np.ndarray, list[str]]  #: positions, times [ns], reasons
    warnings: list[tuple[np.ndarray, np.ndarray]]  #: per warning flag: (positions, times)
    #: before the stretch (column 0) and after each input: the newest stamps (2 x E+1), the
    #: latest rejection and warning times (E+1)
    stamps: np.ndarray
    rejected_at: np.ndarray
    warned_at: np.ndarray


class Recording:
    """The decisions of ``engine`` (built as the node builds it: configs, hold, pairing, report
    interval) over a recording; ``arrays``: the inputs are JointStates of every muscle (the node
    evaluates them with the bank's arrays).  Feed it stretch by stretch (:meth:`step`).
    """

    def __init__(self, engine: Engine, arrays: bool = False) -> None:
        self.engine, self.arrays = engine, arrays
        pairing, health = engine.pairing, engine.health
        self.approximate, self.max_age = pairing.approximate, pairing.max_age
        self.hold, self.interval = health.hold, health.report_interval
        self._carry = [
            _Carry(Pairing(1, 'approximate_time', pairing.slop, pairing.max_age))
            for _ in range(len(engine))
        ]
        self._next_status: int | None = None
        self._last_report = NEVER
        self._reported = bytes([255]) * len(engine)  # levels of the last report (255: none)

    def counts(self, k: int) -> dict[str, int]:
        """Muscle ``k``'s counters so far (non-zero, by label), as :meth:`Engine.counts`."""
        return {
            label: int(n)
            for label, n in zip(self.engine.health.labels, self._carry[k].counts.tolist())
            if n
        }

    # --- one stretch
    def step(
        self, inputs: Sequence[Inputs], first: int, times: np.ndarray, input_at: np.ndarray
    ) -> Stretch:
        """The inputs of each muscle among the messages at positions ``first`` ... (``times``:
        the log times [ns] of all of them, in order; ``input_at``: the positions of the node's
        input messages among them).
        """
        if self._next_status is None and len(times):
            self._next_status = int(times[0]) + SECOND  # the node's 1 Hz status timer
        prepared = [self._prepare(k, ev) for k, ev in enumerate(inputs)]
        coefficients = self._coefficients(prepared)
        decided = [
            self._decide(k, ev, prep, coeff)
            for k, (ev, prep, coeff) in enumerate(zip(inputs, prepared, coefficients))
        ]
        events = [h for _, _, h in decided]
        reports = self._reports(events, first, times, input_at)
        for k, h in enumerate(events):
            self._carry_health(k, h)
        return Stretch([e for e, _, _ in decided], [c for _, c, _ in decided], reports)

    def _prepare(self, k: int, ev: Inputs) -> _Prepared:
        """Validation and the hysteresis branch along muscle ``k``'s inputs."""
        config, carry = self.engine.configs[k], self._carry[k]
        model = config.model
        kind, value = ev.kind, ev.value
        refused = np.zeros(len(kind), bool)
        refused[list(ev.refused)] = True
        absolute = value + config.reading_offset
        ok_p = (kind == PRESSURE_IN) & ~refused & (absolute >= 0) & (absolute <= ABSURD_PRESSURE)
        ok_l = (kind == LENGTH_IN) & ~refused & (value > 0) & (value < model.max_length)
        ok_c = (kind == COMMAND_IN) & ~refused & np.isfinite(value)
        lengths = np.flatnonzero(ok_l)
        branch = np.full(len(kind), math.nan)
        b, anchor, deadband = carry.branch, carry.anchor, config.follow.deadband
        if not model.model.hysteresis:
            epochs = (lengths, value[lengths], np.zeros(len(lengths)))
        elif config.follow.input == 'length':
            moved = []
            for length in value[lengths].tolist():
                b, anchor = play(b, anchor, length, deadband)
                moved.append(b)
            branch[lengths] = moved
            epochs = (lengths, value[lengths], np.array(moved, float))
        else:  # the branch follows the pressure: a turn recomputes at the length held
            held, ambient, moved, turns = carry.length, config.ambient_pressure, [], []
            is_length = ok_l.tolist()
            for i in np.flatnonzero(ok_p | ok_l).tolist():
                if is_length[i]:
                    held = value.item(i)
                    turns.append((i, held, b))
                    continue
                before = b
                b, anchor = play(b, anchor, absolute.item(i) - ambient, deadband)
                moved.append((i, b))
                if b != before and held == held:  # (a length is held: not NaN)
                    turns.append((i, held, b))
            if moved:
                where, to = zip(*moved)
                branch[list(where)] = to
            rows = list(zip(*turns)) or [(), (), ()]
            epochs = (
                np.array(rows[0], np.intp),
                np.array(rows[1], float),
                np.array(rows[2], float),
            )
        return _Prepared((ok_p, ok_l, ok_c), absolute, branch, epochs, (b, anchor))

    def _coefficients(self, prepared: Sequence[_Prepared]) -> list[tuple[np.ndarray, ...]]:
        """(flags, q2, q1, q0) of each muscle's epochs, by the node's path: the one-muscle float
        path, or the bank's arrays over every muscle (padded with a length each can take).
        """
        configs = self.engine.configs
        if not self.arrays:
            out = []
            for config, prep in zip(configs, prepared):
                _, lengths, branches = prep.epochs
                one = config.model.operating_one
                rows = [one(L, b) for L, b in zip(lengths.tolist(), branches.tolist())]
                flags, q2, q1, q0 = zip(*rows) if rows else ((), (), (), ())
                out.append(
                    (np.array(flags, np.uint16), *(np.array(q, float) for q in (q2, q1, q0)))
                )
            return out
        counts = [len(prep.epochs[0]) for prep in prepared]
        rows = max(counts, default=0)
        lengths = np.array([c.model.limits.length_high for c in configs]) * np.ones((rows, 1))
        branches = np.zeros((rows, len(configs)))
        for k, (prep, n) in enumerate(zip(prepared, counts)):
            lengths[:n, k], branches[:n, k] = prep.epochs[1], prep.epochs[2]
        op = self.engine.muscles.bank.operating(lengths, branches, True)
        return [
            (op.flags[:n, k], op.q2[:n, k], op.q1[:n, k], op.q0[:n, k])
            for k, n in enumerate(counts)
        ]

    def _decide(
        self, k: int, ev: Inputs, prep: _Prepared, coefficients: tuple[np.ndarray, ...]
    ) -> tuple[Estimates, Commands, _Events]:
        """Muscle ``k``'s pairs, forces, commands and health events over the stretch."""
        config, carry = self.engine.configs[k], self._carry[k]
        model, ambient = config.model, config.ambient_pressure
        at, now, kind, stamp, value = ev.at, ev.now, ev.kind, ev.stamp, ev.value
        ok_p, ok_l, ok_c = prep.ok
        index = np.arange(len(at))
        before = carry.pairing.stamps[:, 0].copy()  # newest valid stamps before the stretch

        def newest(valid: np.ndarray, *columns: tuple[np.ndarray, object]) -> list[np.ndarray]:
            """Each column's value at the newest valid input, after each input (else the
            carried one).
            """
            last = np.maximum.accumulate(np.where(valid, index, -1)) if len(index) else index
            return [np.append(column, held)[last] for column, held in columns]

        p_stamp, pressure = newest(ok_p, (stamp, before[0]), (prep.absolute, carry.pressure))
        l_stamp, length, rate = newest(
            ok_l, (stamp, before[1]), (value, carry.length), (ev.rate, carry.rate)
        )
        epoch = np.full(len(at), -1)
        epoch[prep.epochs[0]] = np.arange(len(prep.epochs[0]))
        epoch = np.maximum.accumulate(epoch) if len(epoch) else epoch
        lflags, q2, q1, q0 = (
            np.append(c, held)[epoch] for c, held in zip(coefficients, carry.coefficients)
        )
        (branch,) = newest(~np.isnan(prep.branch), (prep.branch, carry.branch))

        # pairing and freshness
        attempts = np.flatnonzero(ok_p | ok_l)
        paired, stale, unpaired = (np.zeros(len(at), bool) for _ in range(3))
        if not self.approximate:
            paired[attempts], stale[attempts] = pair_every_input(
                p_stamp[attempts], l_stamp[attempts], now[attempts], self.max_age
            )
        else:
            pairing = carry.pairing
            for i, side, s, t in zip(
                attempts.tolist(),
                ok_l[attempts].tolist(),
                stamp[attempts].tolist(),
                now[attempts].tolist(),
            ):
                pairing.store_one(int(side), 0, s)
                paired[i], stale[i], unpaired[i] = pairing.pair_one(0, t)
        if len(at):
            carry.pairing.stamps[:, 0] = p_stamp[-1], l_stamp[-1]
            carry.pressure, carry.length, carry.rate = (
                pressure.item(-1),
                length.item(-1),
                rate.item(-1),
            )
            carry.coefficients = (int(lflags[-1]), q2.item(-1), q1.item(-1), q0.item(-1))
        carry.branch, carry.anchor = prep.end

        # forces of every pair, in one call
        pairs = np.flatnonzero(paired)
        gauge = pressure[pairs] - ambient
        op = Operating(True, lflags[pairs], q2[pairs], q1[pairs], q0[pairs], model.limits)
        result = force_at(op, gauge)
        has_force = result.raw < math.inf  # (NaN: no force)
        done = pairs[has_force]
        estimates = Estimates(
            at[done],
            np.maximum(p_stamp, l_stamp)[done],
            result.force[has_force],
            result.flags[has_force],
            gauge[has_force],
            length[done],
            rate[done],
        )
        no_force = np.zeros(len(at), bool)
        no_force[pairs[~has_force]] = True
        why_not = dict(zip(pairs[~has_force].tolist(), result.flags[~has_force].tolist()))

        # commands, in one call
        wanted = np.flatnonzero(ok_c)
        with_length = fresh(l_stamp[wanted], now[wanted], self.max_age)
        sent = wanted[with_length]
        result = model.pressure(value[sent], length[sent], branch[sent])
        commands = Commands(
            at[sent],
            result.pressure + ambient - config.reading_offset,
            result.flags.astype(np.uint16),
        )

        # health events
        is_p, is_l, is_c = kind == PRESSURE_IN, kind == LENGTH_IN, kind == COMMAND_IN
        rejected = (is_p & ~ok_p) | (is_l & ~ok_l) | (is_c & ~ok_c) | no_force
        masks = {
            Counter.RECEIVED_PRESSURE: is_p,
            Counter.RECEIVED_MUSCLE_STATE: is_l,
            Counter.RECEIVED_FORCE_COMMAND: is_c,
            Counter.REJECTED_PRESSURE: is_p & ~ok_p,
            Counter.REJECTED_MUSCLE_STATE: (is_l & ~ok_l) | no_force,
            Counter.REJECTED_FORCE_COMMAND: is_c & ~ok_c,
            Counter.STALE: stale,
            Counter.UNPAIRED: unpaired,
        }
        counters = [
            at[masks[c]]
            if c in masks
            else estimates.at
            if c == Counter.ESTIMATES
            else commands.at
            if c == Counter.COMMANDS
            else at[wanted[~with_length]]
            for c in Counter
        ]
        reasons = []
        for i in np.flatnonzero(rejected).tolist():
            if i in ev.refused:
                reasons.append(ev.refused[i])
            elif i in why_not:
                reasons.append(f'no force at length {length.item(i):g} m ({describe(why_not[i])})')
            elif is_p[i]:
                reasons.append(pressure_problem(prep.absolute.item(i)))
            elif is_l[i]:
                reasons.append(length_problem(value.item(i), model.max_length))
            else:
                reasons.append(f'force command is {value.item(i)} N')
        flagged_at = np.concatenate([estimates.at, commands.at])
        flagged = np.concatenate([estimates.flags, commands.flags]).astype(np.int64)
        order = np.argsort(flagged_at, kind='stable')
        flagged_at, flagged = flagged_at[order], flagged[order]
        times = now[np.searchsorted(at, flagged_at)]
        warnings = [
            (flagged_at[flagged & bit != 0], times[flagged & bit != 0]) for bit in _WARN_BITS
        ]
        warned = np.full(len(at), NEVER)
        warned[np.searchsorted(at, flagged_at[flagged & _WARN_MASK != 0])] = times[
            flagged & _WARN_MASK != 0
        ]
        events = _Events(
            at,
            counters,
            [(at[ok], (now - stamp)[ok]) for ok in (ok_p, ok_l)],
            (at[rejected], now[rejected], reasons),
            warnings,
            np.vstack(
                [np.concatenate([[before[0]], p_stamp]), np.concatenate([[before[1]], l_stamp])]
            ),
            np.maximum.accumulate(
                np.concatenate([[carry.rejected[0]], np.where(rejected, now, NEVER)])
            ),
            np.maximum.accumulate(np.concatenate([[carry.warned_at.max()], warned])),
        )
        return estimates, commands, events

    # --- reports
    def _reports(
        self, events: list[_Events], first: int, times: np.ndarray, input_at: np.ndarray
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
            self._next_status += SECOND
        timer_at = first + np.searchsorted(times, timers, 'left')
        windows = [[0, 0] for _ in events]  # per muscle and input: first arrival in the window
        reports: list[Report] = []

        def report(at: int, after: bool, now: int) -> None:
            self._restore(events, windows, at, 'right' if after else 'left')
            statuses = self.engine.statuses(now)
            reports.append(Report(at, after, now, statuses))
            self._reported = bytes(int(s.level) for s in statuses)
            self._last_report = now

        def passed(start: int) -> int:
            """The first input from ``start`` on that the report interval lets through."""
            gate = np.searchsorted(inputs_now, self._last_report + self.interval, 'left')
            return max(start, int(gate))

        i, t = passed(0), 0
        while True:
            if t < len(timers) and (i >= count or timer_at[t] <= input_at[i]):
                report(int(timer_at[t]), False, timers[t])
                i = passed(int(np.searchsorted(input_at, timer_at[t], 'left')))
                t += 1
            elif i >= count:
                break
            elif levels[i].tobytes() != self._reported:
                report(int(input_at[i]), True, int(inputs_now[i]))
                i = passed(i + 1)
            else:
                later = np.searchsorted(changes, i, 'right')
                i = int(changes[later]) if later < len(changes) else count
        self._windows = windows
        return reports

    def _restore(self, events: list[_Events], windows: list, at: int, side: str) -> None:
        """Set the engine's health to each muscle's state at position ``at`` (``side`` 'right':
        after the message there, 'left': before it), for a report; the report starts a new window
        of arrivals.
        """
        health = self.engine.health
        for k, h in enumerate(events):
            carry = self._carry[k]
            counts = [
                n + np.searchsorted(c, at, side) for n, c in zip(carry.counts.tolist(), h.counters)
            ]
            arrivals, delays = [], []
            for s, (positions, delay) in enumerate(h.arrivals):
                end = int(np.searchsorted(positions, at, side))
                arrivals.append(carry.arrivals[s] + end)
                window, start = carry.window[s], windows[k][s]
                if end > start:
                    low, high = int(delay[start:end].min()), int(delay[start:end].max())
                    window = (
                        (low, high)
                        if window is None
                        else (min(window[0], low), max(window[1], high))
                    )
                delays.append(
                    (math.inf, -math.inf)
                    if window is None
                    else (window[0] / SECOND, window[1] / SECOND)
                )
                carry.window[s], windows[k][s] = None, end
            positions, when, reasons = h.rejections
            r = int(np.searchsorted(positions, at, side)) - 1
            rejected = (int(when[r]), reasons[r]) if r >= 0 else carry.rejected
            warned = []
            for held, (positions, when) in zip(carry.warned_at.tolist(), h.warnings):
                w = int(np.searchsorted(positions, at, side)) - 1
                warned.append(int(when[w]) if w >= 0 else held)
            health.restore(k, counts, arrivals, delays, rejected, warned)
            health.stamps[:, k] = h.stamps[:, np.searchsorted(h.at, at, side)]

    def _carry_health(self, k: int, h: _Events) -> None:
        """Muscle ``k``'s health state after the stretch."""
        carry = self._carry[k]
        carry.counts += [len(c) for c in h.counters]
        for s, (positions, delay) in enumerate(h.arrivals):
            carry.arrivals[s] += len(positions)
            start = self._windows[k][s]
            if start < len(delay):
                low, high = int(delay[start:].min()), int(delay[start:].max())
                window = carry.window[s]
                carry.window[s] = (
                    (low, high) if window is None else (min(window[0], low), max(window[1], high))
                )
        positions, when, reasons = h.rejections
        if len(positions):
            carry.rejected = (int(when[-1]), reasons[-1])
        for j, (positions, when) in enumerate(h.warnings):
            if len(positions):
                carry.warned_at[j] = when[-1]
