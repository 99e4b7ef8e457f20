"""Estimation: the muscles' newest valid pressure and length, what the force at them needs, the
force and the command inversion (no ROS).

Each rule is written once over the arrays of every muscle: input validation, the hysteresis branch
(play operator, :mod:`~pma_model_ros.core.physics.hysteresis`), the length-dependent coefficients
(once per new length, :meth:`~pma_model_ros.core.physics.muscle_bank.MuscleBank.operating`: one
call per model) and the force per pressure
(:func:`~pma_model_ros.core.physics.muscle_model.force_at`, with a shortcut, equal by construction,
for the usual message: every pressure inside the identified range, every force finite).  An input
of every muscle is first tested on its lowest and highest value: two reductions decide the usual
message (every value a reading, every pressure served as it is, every length identified) and are
reused for each of these decisions, where the elementwise rules cost three operations and a count
each (``test_core_engine.py`` pins them to the rules at every bound).  One muscle's input takes a
measured fast path in plain floats (:meth:`Muscles.pressure_one`, :meth:`length_one`,
:meth:`force_one`, over :meth:`~pma_model_ros.core.physics.muscle_model.MuscleModel.operating_one`
and :func:`~pma_model_ros.core.physics.muscle_model.served_pressure`): on one value numpy's
per-call overhead costs more than the arithmetic.  ``test/test_core_engine.py`` pins both paths
equal.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

from .health import WARN_MASK
from ..files.node_parameters import SPECS
from ..physics import elementwise as ew
from ..physics.flags import describe, Flag
from ..physics.hysteresis import DEFAULT_FOLLOW, Follow, play
from ..physics.muscle_bank import MuscleBank
from ..physics.muscle_model import force_at, MuscleModel, Operating, served_pressure

#: Absolute pressures above this [Pa] are sensor or unit errors (50 bar; muscles are rated <= 8
#: bar).
ABSURD_PRESSURE = 5e6
_INVALID, _CLIPPED = int(Flag.INVALID_INPUT), int(Flag.CLIPPED)
_CLIPPED16 = np.uint16(_CLIPPED)


def pressures_ok(absolute):
    """Which absolute pressures [Pa] (a float or an array) are readings: in [0,
    :data:`ABSURD_PRESSURE`] (not NaN).
    """
    return (absolute >= 0) & (absolute <= ABSURD_PRESSURE)


def pressure_problem(absolute: float) -> str:
    """Why an absolute pressure [Pa] is no reading ('' if it is one)."""
    if not math.isfinite(absolute):
        return f'pressure is {absolute} Pa'
    if absolute < 0:
        return f'negative absolute pressure {absolute:g} Pa'
    if absolute > ABSURD_PRESSURE:
        return f'absurd pressure {absolute:g} Pa (> {ABSURD_PRESSURE:g} Pa absolute)'
    return ''


def lengths_ok(lengths, limit):
    """Which lengths [m] (a float or an array) a geometry allowing (0, ``limit``) m takes (not
    NaN).
    """
    return (lengths > 0) & (lengths < limit)


def length_problem(length: float, limit: float) -> str:
    """Why a length [m] is no reading of a muscle whose geometry allows (0, ``limit``) m ('' if it
    is one).
    """
    if lengths_ok(length, limit):
        return ''
    return f'length {length:g} m outside the geometry (0, {limit:.4g}) m'


def no_force_problem(length: float, flags: int) -> str:
    """Why a valid pair of inputs gave no force: the model has none at ``length`` [m]
    (``flags``: the result's).
    """
    return f'no force at length {length:g} m ({describe(flags)})'


def commands_ok(force):
    """Which wanted tensions [N] (a float or an array) are commands: the finite ones."""
    return np.isfinite(force)


def command_problem(force: float) -> str:
    """Why a wanted tension [N] is no command ('' if it is one)."""
    return '' if commands_ok(force) else f'force command is {force} N'


@dataclass(frozen=True)
class Config:
    """One muscle's identified model and the node settings the engine needs; swapped whole at
    runtime.
    """

    model: MuscleModel
    #: [Pa] absolute; gauge = absolute - ambient
    ambient_pressure: float = SPECS['ambient_pressure'].default
    #: [s] inputs with |now - stamp| above this are stale
    max_input_age: float = SPECS['max_input_age'].default
    #: what pressure readings and commands hold
    pressure_reference: str = SPECS['pressure_reference'].default
    #: what a hysteresis model's branch follows, with the play operator's deadband
    follow: Follow = DEFAULT_FOLLOW

    def __post_init__(self) -> None:
        SPECS['ambient_pressure'].check(self.ambient_pressure)
        SPECS['max_input_age'].check(self.max_input_age)
        SPECS['pressure_reference'].check(self.pressure_reference)
        SPECS['hysteresis.input'].check(self.follow.input)
        SPECS[f'hysteresis.{self.follow.input}_deadband'].check(self.follow.deadband)

    @property
    def reading_offset(self) -> float:
        """What to add to a pressure reading [Pa] for the absolute pressure: 0, or ambient for
        gauge readings.
        """
        return self.ambient_pressure if self.pressure_reference == 'gauge' else 0.0


class Muscles:
    """N muscles: their newest valid inputs, hysteresis branches and force coefficients.

    An input of every muscle is an array of N (a mask ``valid`` says which values to take; None:
    all); the ``_one`` methods take muscle ``k``'s value as a float.
    """

    def __init__(self, configs: Sequence[Config]) -> None:
        n = len(configs)
        self.pressure = np.full(n, math.nan)  #: newest valid absolute pressure [Pa]
        self.length, self.rate = np.full(n, math.nan), np.full(n, math.nan)  #: [m], [m/s]
        #: hysteresis play operator: branch (+1, -1, 0) and anchor [m or Pa]
        self.branch, self.anchor = np.zeros(n), np.full(n, math.nan)
        self.configure(configs)

    def configure(self, configs: Sequence[Config]) -> None:
        """Use ``configs`` from now on; the inputs are kept (their coefficients recomputed)."""
        self.models = [c.model for c in configs]
        self.bank = MuscleBank(self.models)
        self.ambient = np.array([c.ambient_pressure for c in configs])
        self.offset = np.array([c.reading_offset for c in configs])  # reading + it = absolute
        self._offsets = bool(self.offset.any())
        self.max_length = self.bank.max_length
        self._known = self.bank.limits.pressure_known
        self._linear = not any(m.model.quadratic for m in self.models)  # q2 = 0
        self._gauge: tuple[np.ndarray, bool] | None = None  # forces' view of the pressures
        #: the usual message's tests on its lowest and highest value (two reductions, where the
        #: elementwise rules cost more; equal where they pass): every length below _length_top
        #: [m] is one the geometry takes (None: some muscle serves lengths above it, as in an arm
        #: of different sizes: the rule decides); every absolute pressure [Pa] in _served is
        #: served as it is (in [0, known] as a gauge pressure)
        top = float(self.max_length.min())
        self._length_top = top if top > float(self.bank.limits.length_high.max()) else None
        self._served = float(self.ambient.max()), float((self.ambient + self._known).min())
        #: the lowest and highest absolute pressure stored, if one message's (None: not known)
        self._span: tuple[float, float] | None = None
        # what the play operator follows, per muscle: (length?, deadband) or None
        self._follows = [
            (c.follow.input == 'length', c.follow.deadband) if m.model.hysteresis else None
            for c, m in zip(configs, self.models)
        ]
        by_length = [f is not None and f[0] for f in self._follows]
        self._by_length = np.array(by_length)
        self._by_pressure = np.array([f is not None and not f[0] for f in self._follows])
        self._any_length, self._any_pressure = any(by_length), bool(self._by_pressure.any())
        self._deadband = np.array([c.follow.deadband for c in configs])
        # the per-muscle numbers of the fast path, as floats
        self._floats = [
            (c.ambient_pressure, c.reading_offset, m.max_length, m.limits)
            for c, m in zip(configs, self.models)
        ]
        self._operate(None, self.length)  # a kept length the new geometry cannot take: INVALID

    # --- every muscle
    def take_pressures(
        self, readings: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None, tuple | None]:
        """(absolute pressures [Pa] of ``readings`` of every muscle, which are readings: None if
        all, their lowest and highest if all are, else None).
        """
        absolute = readings + self.offset if self._offsets else readings
        span = ew.lowest(absolute), ew.highest(absolute)
        if span[0] >= 0 and span[1] <= ABSURD_PRESSURE:  # pressures_ok for all (False for NaN)
            return absolute, None, span
        return absolute, pressures_ok(absolute), None  # (one is not a reading)

    def take_lengths(self, lengths: np.ndarray) -> tuple[np.ndarray | None, tuple | None]:
        """(Which ``lengths`` [m] of every muscle the geometry can take: None if all; their
        lowest and highest if they are all taken, else None).
        """
        if self._length_top is not None:
            span = ew.lowest(lengths), ew.highest(lengths)
            if span[0] > 0 and span[1] < self._length_top:  # lengths_ok for all (False for NaN)
                return None, span
        ok = lengths_ok(lengths, self.max_length)
        return (None, None) if np.count_nonzero(ok) == ok.size else (ok, None)

    def store_pressures(
        self,
        valid: np.ndarray | None,
        absolute: np.ndarray,
        span: tuple[float, float] | None = None,
    ) -> None:
        """The ``valid`` absolute pressures [Pa]; a branch that follows the pressure and turns
        recomputes the coefficients at the length held.  ``span``: :meth:`take_pressures`' lowest
        and highest.
        """
        if valid is None:
            self.pressure[:] = absolute
        else:
            self.pressure[valid] = absolute[valid]
        self._gauge, self._span = None, span if valid is None else None
        if self._any_pressure:
            follows = self._by_pressure if valid is None else self._by_pressure & valid
            before = self.branch.copy()
            gauge = np.where(follows, absolute - self.ambient, math.nan)
            self.branch, self.anchor = play(before, self.anchor, gauge, self._deadband)
            turned = (self.branch != before) & ~np.isnan(self.length)
            if turned.any():
                self._operate(turned, self.length)

    def store_lengths(
        self,
        valid: np.ndarray | None,
        lengths: np.ndarray,
        rates: np.ndarray,
        span: tuple[float, float] | None = None,
    ) -> None:
        """The ``valid`` lengths [m] and rates [m/s] (NaN: unknown); a branch that follows the
        length moves by the play operator.  ``span``: :meth:`take_lengths`' lowest and highest.
        """
        if self._any_length:
            follows = self._by_length if valid is None else self._by_length & valid
            self.branch, self.anchor = play(
                self.branch, self.anchor, np.where(follows, lengths, math.nan), self._deadband
            )
        if valid is None:  # (the copy is aligned, a message's view of its bytes is not: numpy
            # takes 0.2-0.3 us more per operation on an unaligned array)
            self.length[:], self.rate[:] = lengths, rates
            lengths = self.length
        else:
            self.length[valid], self.rate[valid] = lengths[valid], rates[valid]
        self._operate(valid, lengths, plain=valid is None, span=span)

    def _operate(
        self,
        which: np.ndarray | None,
        lengths: np.ndarray,
        plain: bool = False,
        span: tuple[float, float] | None = None,
    ) -> None:
        """The coefficients and length flags of the muscles ``which`` (None: all) at ``lengths``,
        on their branches (``plain``: every length is one the geometry takes; ``span``: their
        lowest and highest, if known).  New arrays: a result handed out before stays as it was.
        """
        op = self.bank.operating(lengths, self.branch, plain, span)
        if which is None:  # (new and writeable: the fast path writes into them)
            self.lflags, self.q2, self.q1, self.q0 = op.flags, op.q2, op.q1, op.q0
        else:
            self.lflags, self.q2, self.q1, self.q0 = (
                np.where(which, new, old)
                for new, old in zip(
                    (op.flags, op.q2, op.q1, op.q0), (self.lflags, self.q2, self.q1, self.q0)
                )
            )
        flags = int(np.bitwise_or.reduce(self.lflags, axis=None))  # every flag raised
        self._plain = plain or not flags & _INVALID  # each kept is one
        #: whether the length flags alone make a result WARN
        self.length_warns = bool(flags & WARN_MASK)

    def forces(self, which: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(force [N], flags, which have a force: None if all) of every muscle at its newest
        inputs, where ``which`` (a mask; None: all).
        """
        if self._gauge is None:  # new pressures (a length message reuses the pressures')
            gauge, span = self.pressure - self.ambient, self._span
            if span is not None:  # one message's: no muscle's out of [0, known] as gauge
                served = span[0] >= self._served[0] and span[1] <= self._served[1]
            else:
                served = ew.lowest(gauge) >= 0 and not np.count_nonzero(gauge > self._known)
            self._gauge = gauge, served
        gauge, served = self._gauge
        if which is None and self._plain and served:
            # force_at's rule where no pressure is moved or flagged
            if self._linear:  # q2 = 0: the same numbers, two operations fewer
                raw = self.q1 * gauge + self.q0
            else:
                raw = (self.q2 * gauge + self.q1) * gauge + self.q0
            low = ew.lowest(raw)
            if low == low and ew.highest(raw) < math.inf:  # no force NaN or inf
                if low >= 0:
                    return raw, self.lflags, None
                return np.maximum(raw, 0.0), self.lflags | (raw < 0) * _CLIPPED16, None
        usable = (self.lflags & _INVALID) == 0
        op = Operating(
            usable if which is None else usable & which,
            self.lflags,
            self.q2,
            self.q1,
            self.q0,
            self.bank.limits,
        )
        result = force_at(op, gauge)
        asked = np.ones(len(gauge), bool) if which is None else which
        return result.force, result.flags, asked & (result.raw < math.inf)  # NaN: no force

    # --- one muscle, in floats
    def pressure_one(self, k: int, reading: float) -> float:
        """Muscle ``k``'s reading [Pa] as an absolute pressure [Pa]."""
        return reading + self._floats[k][1]

    def store_pressure_one(self, k: int, absolute: float) -> None:
        """:meth:`store_pressures` of muscle ``k``'s valid absolute pressure [Pa]."""
        self.pressure[k] = absolute
        self._gauge = self._span = None
        follow = self._follows[k]
        if follow is not None and not follow[0]:
            before = self.branch.item(k)
            gauge = absolute - self._floats[k][0]
            branch, self.anchor[k] = play(before, self.anchor.item(k), gauge, follow[1])
            self.branch[k] = branch
            length = self.length.item(k)
            if branch != before and length == length:  # a length is held (not NaN)
                self._operate_one(k, length)

    def length_valid_one(self, k: int, length: float) -> bool:
        """Whether muscle ``k``'s geometry can take ``length`` [m]."""
        return lengths_ok(length, self._floats[k][2])

    def store_length_one(self, k: int, length: float, rate: float) -> None:
        """:meth:`store_lengths` of muscle ``k``'s valid length [m] and rate [m/s]."""
        follow = self._follows[k]
        if follow is not None and follow[0]:
            branch, anchor = play(self.branch.item(k), self.anchor.item(k), length, follow[1])
            self.branch[k], self.anchor[k] = branch, anchor
        self.length[k], self.rate[k] = length, rate
        self._operate_one(k, length)

    def _operate_one(self, k: int, length: float) -> None:
        flags, q2, q1, q0 = self.models[k].operating_one(length, self.branch.item(k))
        self.lflags[k], self.q2[k], self.q1[k], self.q0[k] = flags, q2, q1, q0

    def force_one(self, k: int) -> tuple[float, int, bool]:
        """:meth:`forces` of muscle ``k``: (force [N], flags, has a force)."""
        lflags = self.lflags.item(k)
        ambient, _, _, limits = self._floats[k]
        pflags, p = served_pressure(self.pressure.item(k) - ambient, limits)
        if lflags & _INVALID:
            return math.nan, lflags, False
        raw = (self.q2.item(k) * p + self.q1.item(k)) * p + self.q0.item(k)
        flags = lflags | pflags | (_CLIPPED if raw < 0 else 0)
        return max(raw, 0.0), flags, raw < math.inf

    # --- commands
    def command(self, k: int, force: float) -> tuple[float, int]:
        """Muscle ``k``'s pressure [Pa, absolute or gauge as its readings] giving tension
        ``force`` [N] at its newest length, on its branch, and its flags.
        """
        result = self.models[k].pressure(force, self.length.item(k), self.branch.item(k))
        ambient, offset, _, _ = self._floats[k]
        return float(result.pressure) + ambient - offset, int(result.flags)
