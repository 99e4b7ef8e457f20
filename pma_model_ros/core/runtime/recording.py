"""The engine's decisions over a whole recording at once: ``bag estimate``'s one pass (no ROS).

The node decides message by message (:class:`~.engine.Engine`).  Offline every input is known in
advance, so each rule runs once over the arrays of a muscle's inputs in log order, the log time
being the node's clock:

* validation: which readings are values (the bounds of :mod:`.estimation`), each refusal with the
  node's reason;
* the hysteresis branch: the play operator along the stream
  (:func:`~pma_model_ros.core.physics.hysteresis.play`);
* the length-dependent coefficients once per valid length, by the node's own path: the one-muscle
  float path (:meth:`~pma_model_ros.core.physics.muscle_model.MuscleModel.operating_one`) for a
  muscle's own topics, the bank's arrays for inputs of every muscle (combined JointStates);
* pairing and freshness: :func:`~.pairing.pair_every_input` over the stream, or
  :meth:`~.pairing.Pairing.pair_one` along it (``approximate_time``);
* the forces of every pair in one call (:func:`~pma_model_ros.core.physics.muscle_model.force_at`),
  the commands in one (:meth:`~pma_model_ros.core.physics.muscle_model.Evaluator.pressure`);
* health: counters, arrivals, rejections and warnings as arrays of events, whose reports
  :mod:`.timeline` makes where the node makes them.

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
from .estimation import (
    command_problem,
    commands_ok,
    length_problem,
    lengths_ok,
    no_force_problem,
    pressure_problem,
    pressures_ok,
)
from .health import invalid_text, stale_text, WARN_BITS, WARN_MASK
from .pairing import fresh, NEVER, pair_every_input, Pairing, stale_command_stamps
from .timeline import Events, Report, Timeline
from ..physics.flags import Flag
from ..physics.hysteresis import play
from ..physics.muscle_model import force_at, Operating

PRESSURE_IN, LENGTH_IN, COMMAND_IN = 0, 1, 2  #: kinds of input
_INVALID = int(Flag.INVALID_INPUT)


@dataclass
class Inputs:
    """One muscle's input messages of a stretch of recording, in log order."""

    at: np.ndarray  #: int64, increasing: each message's position in the recording
    now: np.ndarray  #: int64 [ns]: its log time (the node's clock)
    kind: np.ndarray  #: int8: PRESSURE_IN, LENGTH_IN or COMMAND_IN
    stamp: np.ndarray  #: int64 [ns]: header stamp (UNSTAMPED, 0: a command taken as sent now)
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


@dataclass
class Stretch:
    """What the node publishes for a stretch of recording."""

    estimates: list[Estimates]  #: per muscle
    commands: list[Commands]  #: per muscle
    reports: list[Report]  #: in order


@dataclass
class _Carry:
    """One muscle's inputs' state between stretches."""

    pairing: Pairing  #: the newest valid stamps (and, approximate_time, which are new)
    pressure: float = math.nan  #: newest valid absolute pressure [Pa]
    length: float = math.nan  #: newest valid length [m]
    rate: float = math.nan
    coefficients: tuple = (_INVALID, math.nan, math.nan, math.nan)  #: (flags, q2, q1, q0)
    branch: float = 0.0
    anchor: float = math.nan


class _Prepared(NamedTuple):
    """One muscle's inputs validated, with the hysteresis branch along them."""

    ok: tuple[np.ndarray, np.ndarray, np.ndarray]  #: valid pressures, lengths, commands
    absolute: np.ndarray  #: [Pa] absolute pressures (of the pressure readings)
    branch: np.ndarray  #: the branch after each input that moved it (NaN: it did not)
    #: where the coefficients change: (input index, length [m], branch)
    epochs: tuple[np.ndarray, np.ndarray, np.ndarray]
    end: tuple[float, float]  #: (branch, anchor) after the stretch


class Recording:
    """The decisions of ``engine`` (built as the node builds it: configs, hold, pairing, report
    interval) over a recording; ``arrays``: the inputs are JointStates of every muscle (the node
    evaluates them with the bank's arrays).  Feed it stretch by stretch (:meth:`step`).
    """

    def __init__(self, engine: Engine, arrays: bool = False) -> None:
        self.engine, self.arrays = engine, arrays
        pairing = engine.pairing
        self.approximate, self.max_age = pairing.approximate, pairing.max_age
        self._carry = [
            _Carry(Pairing(1, 'approximate_time', pairing.slop, pairing.max_age))
            for _ in range(len(engine))
        ]
        self.timeline = Timeline(engine)
        self._reasons: list[dict[str, list]] = [{} for _ in range(len(engine))]

    def counts(self, k: int) -> dict[str, int]:
        """Muscle ``k``'s counters so far (non-zero, by label), as :meth:`Engine.counts`."""
        return self.timeline.counts(k)

    def reasons(self, k: int) -> dict[str, tuple[int, str]]:
        """Muscle ``k``'s rejections so far by reason (a refused message's text, else the check
        that failed: ``pressure``, ``length``, ``no force``, ``force_command``, ``stale
        force_command``): (how many, the text of the first).
        """
        return {key: (n, text) for key, (n, text) in self._reasons[k].items()}

    # --- one stretch
    def step(
        self, inputs: Sequence[Inputs], first: int, times: np.ndarray, input_at: np.ndarray
    ) -> Stretch:
        """The inputs of each muscle among the messages at positions ``first`` ... (``times``:
        the log times [ns] of all of them, in order; ``input_at``: the positions of the node's
        input messages among them).
        """
        prepared = [self._prepare(k, ev) for k, ev in enumerate(inputs)]
        coefficients = self._coefficients(prepared)
        decided = [
            self._decide(k, ev, prep, coeff)
            for k, (ev, prep, coeff) in enumerate(zip(inputs, prepared, coefficients))
        ]
        reports = self.timeline.reports([h for _, _, h in decided], first, times, input_at)
        return Stretch([e for e, _, _ in decided], [c for _, c, _ in decided], reports)

    def _prepare(self, k: int, ev: Inputs) -> _Prepared:
        """Validation and the hysteresis branch along muscle ``k``'s inputs."""
        config, carry = self.engine.configs[k], self._carry[k]
        model = config.model
        kind, value = ev.kind, ev.value
        refused = np.zeros(len(kind), bool)
        refused[list(ev.refused)] = True
        absolute = value + config.reading_offset
        ok_p = (kind == PRESSURE_IN) & ~refused & pressures_ok(absolute)
        ok_l = (kind == LENGTH_IN) & ~refused & lengths_ok(value, model.max_length)
        ok_c = (kind == COMMAND_IN) & ~refused & commands_ok(value)
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
                rows = np.array(list(map(one, lengths.tolist(), branches.tolist())), float)
                rows = rows.reshape(-1, 4)  # (flags, q2, q1, q0) per length
                out.append((rows[:, 0].astype(np.uint16), rows[:, 1], rows[:, 2], rows[:, 3]))
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
    ) -> tuple[Estimates, Commands, Events]:
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

        length_before = carry.length
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
        stale_c = ok_c & stale_command_stamps(stamp, now, self.max_age)
        wanted = np.flatnonzero(ok_c & ~stale_c)
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
        rejected = (is_p & ~ok_p) | (is_l & ~ok_l) | (is_c & ~ok_c) | no_force | stale_c
        masks = {
            Counter.RECEIVED_PRESSURE: is_p,
            Counter.RECEIVED_MUSCLE_STATE: is_l,
            Counter.RECEIVED_FORCE_COMMAND: is_c,
            Counter.REJECTED_PRESSURE: is_p & ~ok_p,
            Counter.REJECTED_MUSCLE_STATE: (is_l & ~ok_l) | no_force,
            Counter.REJECTED_FORCE_COMMAND: is_c & ~ok_c,
            Counter.STALE: stale,
            Counter.UNPAIRED: unpaired,
            Counter.STALE_COMMAND: stale_c,
        }
        positions = {
            Counter.ESTIMATES: estimates.at,
            Counter.COMMANDS: commands.at,
            Counter.NO_LENGTH: at[wanted[~with_length]],
            Counter.BEHIND: at[:0],  # offline nothing waits in a queue
        }
        counters = [at[masks[c]] if c in masks else positions[c] for c in Counter]
        texts = []  # what each rejection latches, as Health.reject and Health.stale_command
        reasons = self._reasons[k]
        for i in np.flatnonzero(rejected).tolist():
            if stale_c[i]:
                age = now.item(i) - stamp.item(i)
                key, text = (
                    'stale force_command',
                    stale_text('force_command', 'stamp', age, self.max_age),
                )
            else:
                if i in ev.refused:
                    key = reason = ev.refused[i]
                elif i in why_not:
                    key, reason = 'no force', no_force_problem(length.item(i), why_not[i])
                elif is_p[i]:
                    key, reason = 'pressure', pressure_problem(prep.absolute.item(i))
                elif is_l[i]:
                    key, reason = 'length', length_problem(value.item(i), model.max_length)
                else:
                    key, reason = 'force_command', command_problem(value.item(i))
                text = invalid_text(reason)
            texts.append(text)
            reasons.setdefault(key, [0, text])[0] += 1
        flagged_at = np.concatenate([estimates.at, commands.at])
        flagged = np.concatenate([estimates.flags, commands.flags]).astype(np.int64)
        order = np.argsort(flagged_at, kind='stable')
        flagged_at, flagged = flagged_at[order], flagged[order]
        times = now[np.searchsorted(at, flagged_at)]
        warnings = [
            (flagged_at[flagged & bit != 0], times[flagged & bit != 0]) for bit in WARN_BITS
        ]
        warned = np.full(len(at), NEVER)
        warned[np.searchsorted(at, flagged_at[flagged & WARN_MASK != 0])] = times[
            flagged & WARN_MASK != 0
        ]
        rejected_before, warned_before = self.timeline.latest(k)
        events = Events(
            at,
            counters,
            [(at[ok], (now - stamp)[ok]) for ok in (ok_p, ok_l)],
            (at[rejected], now[rejected], texts),
            warnings,
            np.vstack(
                [np.concatenate([[before[0]], p_stamp]), np.concatenate([[before[1]], l_stamp])]
            ),
            np.maximum.accumulate(
                np.concatenate([[rejected_before], np.where(rejected, now, NEVER)])
            ),
            np.maximum.accumulate(np.concatenate([[warned_before], warned])),
            np.concatenate([[length_before], length]),
        )
        return estimates, commands, events
