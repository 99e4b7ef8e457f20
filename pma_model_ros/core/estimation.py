"""Estimation: the muscles' newest valid pressure and length, what the force at them needs, the
force and the command inversion (no ROS).

Every rule is written once, over arrays of muscles addressed by a slice ``sel`` (all of them, or
one: :func:`one`): input validation, the hysteresis branch (play operator,
:mod:`~.hysteresis`), the length-dependent coefficients (once per new length,
:meth:`~.muscle_model.Evaluator.operating`) and the force per pressure
(:func:`~.muscle_model.force_at`).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

from .flags import Flag
from .hysteresis import Follow, play
from .muscle_bank import MuscleBank
from .muscle_model import force_at, ForceResult, MuscleModel, Operating
from .node_parameters import DEFAULT_FOLLOW, SPECS

#: Absolute pressures above this [Pa] are sensor or unit errors (50 bar; muscles are rated <= 8
#: bar).
ABSURD_PRESSURE = 5e6
ALL = slice(None)  #: every muscle
_INVALID = int(Flag.INVALID_INPUT)


def one(k: int) -> slice:
    """Muscle ``k`` alone, as a slice of the muscle arrays."""
    return slice(k, k + 1)


def pressure_problem(absolute: float) -> str:
    """Why an absolute pressure [Pa] is no reading ('' if it is one)."""
    if not math.isfinite(absolute):
        return f'pressure is {absolute} Pa'
    if absolute < 0:
        return f'negative absolute pressure {absolute:g} Pa'
    if absolute > ABSURD_PRESSURE:
        return f'absurd pressure {absolute:g} Pa (> {ABSURD_PRESSURE:g} Pa absolute)'
    return ''


def length_problem(length: float, limit: float) -> str:
    """Why a length [m] is no reading of a muscle whose geometry allows (0, ``limit``) m ('' if it
    is one).
    """
    if math.isfinite(length) and 0 < length < limit:
        return ''
    return f'length {length:g} m outside the geometry (0, {limit:.4g}) m'


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

    ``sel`` is :data:`ALL` or :func:`one` muscle: every muscle goes through the bank's one call per
    model, one muscle through its own model (the same :class:`~.muscle_model.Evaluator` code).
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
        self._offset = np.array([c.reading_offset for c in configs])  # reading + it = absolute
        self._offsets = bool(self._offset.any())
        hysteresis = np.array([m.model.hysteresis for m in self.models])
        by_pressure = np.array([c.follow.input == 'pressure' for c in configs])
        self._by_length, self._by_pressure = hysteresis & ~by_pressure, hysteresis & by_pressure
        self._any_length = bool(self._by_length.any())
        self._any_pressure = bool(self._by_pressure.any())
        self._deadband = np.array([c.follow.deadband for c in configs])
        # a kept length the new geometry cannot take: INVALID_INPUT
        op = self.bank.operating(self.length, self.branch)
        self.lflags, self.q = op.flags, np.array([op.q2, op.q1, op.q0])

    def _evaluator(self, sel: slice) -> MuscleBank | MuscleModel:
        return self.bank if sel.start is None else self.models[sel.start]

    def check_pressures(self, sel: slice, readings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(absolute pressures [Pa] of ``readings`` of the muscles ``sel``, which are readings)."""
        absolute = readings + self._offset[sel] if self._offsets else readings
        return absolute, (absolute >= 0) & (absolute <= ABSURD_PRESSURE)

    def check_lengths(self, sel: slice, lengths: np.ndarray) -> np.ndarray:
        """Which ``lengths`` [m] of the muscles ``sel`` the geometry can take."""
        return (lengths > 0) & (lengths < self.bank.max_length[sel])

    def store_pressures(self, sel: slice, valid: np.ndarray | None, absolute: np.ndarray) -> None:
        """The ``valid`` (a mask; None: all) absolute pressures [Pa] of the muscles ``sel``; a
        branch that follows the pressure and turns recomputes the coefficients at the length held.
        """
        if valid is None:
            self.pressure[sel] = absolute
        else:
            self.pressure[sel][valid] = absolute[valid]
        if self._any_pressure:
            follows = self._by_pressure[sel] if valid is None else self._by_pressure[sel] & valid
            before = self.branch[sel].copy()
            gauge = np.where(follows, absolute - self.ambient[sel], math.nan)
            self.branch[sel], self.anchor[sel] = play(
                before, self.anchor[sel], gauge, self._deadband[sel]
            )
            turned = (self.branch[sel] != before) & ~np.isnan(self.length[sel])
            if turned.any():
                self._operate(sel, turned, self.length[sel])

    def store_lengths(
        self, sel: slice, valid: np.ndarray | None, lengths: np.ndarray, rates: np.ndarray
    ) -> None:
        """The ``valid`` lengths [m] and rates [m/s] (NaN: unknown) of the muscles ``sel``; a
        branch that follows the length moves by the play operator.
        """
        if self._any_length:
            follows = self._by_length[sel] if valid is None else self._by_length[sel] & valid
            self.branch[sel], self.anchor[sel] = play(
                self.branch[sel],
                self.anchor[sel],
                np.where(follows, lengths, math.nan),
                self._deadband[sel],
            )
        if valid is None:
            self.length[sel], self.rate[sel] = lengths, rates
        else:
            self.length[sel][valid], self.rate[sel][valid] = lengths[valid], rates[valid]
        self._operate(sel, valid, lengths)

    def _operate(self, sel: slice, which: np.ndarray | None, lengths: np.ndarray) -> None:
        """The coefficients and length flags of the muscles ``sel`` (``which`` of them; None:
        all) at ``lengths``, on their branches.
        """
        op = self._evaluator(sel).operating(lengths, self.branch[sel])
        if which is None:
            self.lflags[sel] = op.flags
            self.q[0, sel], self.q[1, sel], self.q[2, sel] = op.q2, op.q1, op.q0
        else:
            self.lflags[sel][which] = op.flags[which]
            for row, q in enumerate((op.q2, op.q1, op.q0)):
                self.q[row, sel][which] = q[which]

    def forces(self, sel: slice, usable: np.ndarray) -> ForceResult:
        """The force of the muscles ``sel`` at their newest inputs, where ``usable``."""
        q, lflags = self.q, self.lflags[sel]
        usable = usable & ((lflags & _INVALID) == 0)  # a length the geometry cannot take
        limits = self._evaluator(sel).limits
        op = Operating(usable, lflags, q[0, sel], q[1, sel], q[2, sel], limits)
        return force_at(op, self.pressure[sel] - self.ambient[sel])

    def command(self, k: int, force: float) -> tuple[float, int]:
        """Muscle ``k``'s pressure [Pa, absolute or gauge as its readings] giving tension
        ``force`` [N] at its newest length, on its branch, and its flags.
        """
        result = self.models[k].pressure(force, self.length.item(k), self.branch.item(k))
        reading = float(result.pressure) + self.ambient.item(k) - self._offset.item(k)
        return reading, int(result.flags)
