"""An identified muscle: spec + model + parameters + validity domain.

Forward force (physical value, clipped at 0 N) and the inverse pressure, both vectorised over numpy
arrays and both returning per-sample :class:`Flag` words.  They are written once, in
:class:`Evaluator`, for one muscle (:class:`MuscleModel`) and for a group of muscles sharing a
model whose numbers are arrays (:mod:`pma_model_ros.core.physics.muscle_bank`).  The force is split
in two: the length-dependent :class:`Operating` (coefficients and flags, once per new length) and
:func:`force_at` (per pressure); :meth:`MuscleModel.operating_one` is the float twin of the first
for one message of one muscle.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, fields
from functools import cached_property
import math
from typing import Callable, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from . import elementwise as ew
from . import geometry as geo
from .flags import Flag
from .geometry import MuscleSpec
from .models import Coefficients, Domain, Model


class ForceResult(NamedTuple):
    force: np.ndarray  #: physical tension [N], >= 0; NaN only where INVALID_INPUT
    raw: np.ndarray  #: model value [N] at the operating point, before clipping at 0 N
    flags: np.ndarray  #: uint16 Flag words


@dataclass(frozen=True)
class PressureResult:
    pressure: np.ndarray  #: gauge pressure [Pa] in [0, max_pressure]; NaN only where INVALID_INPUT
    flags: np.ndarray  #: uint16 Flag words


(
    _INVALID,
    _LENGTH_OUT,
    _PRESSURE_OUT,
    _CLIPPED,
    _SATURATED,
    _BRANCH_UNKNOWN,
    _EXTRAPOLATED,
    _BELOW_AMBIENT,
) = (
    int(f)
    for f in (
        Flag.INVALID_INPUT,
        Flag.LENGTH_OUT_OF_RANGE,
        Flag.PRESSURE_OUT_OF_RANGE,
        Flag.CLIPPED,
        Flag.SATURATED,
        Flag.BRANCH_UNKNOWN,
        Flag.EXTRAPOLATED,
        Flag.BELOW_AMBIENT,
    )
)

#: where every length is identified: no NaN or overflow to silence (np.errstate costs 1 us)
_QUIET = nullcontext()
_EVERY = np.bool_(True)  #: ``usable`` of lengths known to be lengths of the muscle
_LENGTH_OUT16, _EXTRAPOLATED16, _INVALID16, _BRANCH_UNKNOWN16, _NONE16 = (
    np.uint16(f) for f in (_LENGTH_OUT, _EXTRAPOLATED, _INVALID, _BRANCH_UNKNOWN, 0)
)

#: [Pa] Gauge pressures this far below 0 are a vented muscle or sensor noise: served as 0 Pa,
#: unflagged.
VENTED_BAND = 10e3


@dataclass(frozen=True)
class Limits:
    """Where a muscle is served (:class:`~.models.Domain`): floats for one muscle, arrays of n for
    a group.
    """

    #: shortest length served [m]: the braid's shortest if it extrapolates
    length_low: np.ndarray | float
    length_high: np.ndarray | float  #: longest length served [m] (at most L0)
    #: highest identified gauge pressure [Pa]; EXTRAPOLATED above
    pressure_known: np.ndarray | float
    pressure_top: np.ndarray | float  #: highest gauge pressure served [Pa]
    #: highest gauge pressure the inverse commands [Pa]: never above the rated
    command_top: np.ndarray | float


def limits_of(spec, domain, shortest) -> Limits:
    """:class:`Limits` of a spec and domain (numbers or arrays) whose braid's shortest length is
    ``shortest``.
    """
    wide = np.asarray(domain.extrapolates, bool)
    rated = np.asarray(spec.max_pressure, float)
    known = np.where(np.isfinite(domain.pressure_max), domain.pressure_max, rated)
    top = np.where(wide, np.maximum(rated, known), known)
    return Limits(
        np.where(wide, shortest, domain.length_min),
        np.where(wide, spec.nominal_length, np.minimum(domain.length_max, spec.nominal_length)),
        known,
        top,
        np.minimum(rated, top),
    )


class Operating(NamedTuple):
    """What the force at given lengths needs besides the pressure: F_raw = (q2 p + q1) p + q0 at
    the operating length (a NamedTuple: built once per message of every muscle).

    ``usable`` is False where the length is no length of the muscle (INVALID_INPUT in ``flags``);
    ``flags`` also holds LENGTH_OUT_OF_RANGE, EXTRAPOLATED (of the length) and BRANCH_UNKNOWN.
    """

    usable: np.ndarray
    flags: np.ndarray  #: uint16 Flag words of the length and branch
    q2: np.ndarray  #: [N/Pa^2]
    q1: np.ndarray  #: [N/Pa]
    q0: np.ndarray  #: [N]
    limits: Limits  #: pressures served and commanded


def force_at(op: Operating, pressure: ArrayLike) -> ForceResult:
    """Tension [N] at gauge ``pressure`` [Pa] (broadcast against ``op``).

    The pressure is held to [0, pressure_top] (PRESSURE_OUT_OF_RANGE where that moved it, except
    within ``VENTED_BAND`` below 0: a vented muscle; BELOW_AMBIENT below that band); EXTRAPOLATED
    above the identified pressures.  Written for few numpy calls: the engines call it per message.
    """
    p = np.asarray(pressure, float)
    lim = op.limits
    p_op = np.minimum(np.maximum(p, 0.0), lim.pressure_top)  # NaN stays NaN
    raw = (op.q2 * p_op + op.q1) * p_op + op.q0
    below = p < -VENTED_BAND
    flags = (
        op.flags
        | (p > lim.pressure_top) * _PRESSURE_OUT
        | below * (_PRESSURE_OUT | _BELOW_AMBIENT)
        | (raw < 0) * _CLIPPED
        | (p_op > lim.pressure_known) * _EXTRAPOLATED
    )
    usable = op.usable & np.isfinite(p)
    if not usable.all():
        raw = np.where(usable, raw, np.nan)
        flags = np.where(usable, flags, op.flags | _INVALID)
    return ForceResult(np.maximum(raw, 0.0), raw, np.asarray(flags, np.uint16))


class Evaluator:
    """Force and inverse of ``model`` with ``theta``, ``spec``, ``domain`` and ``max_length``.

    For one muscle these are scalars (:class:`MuscleModel`); for a group of n
    muscles sharing one model they are arrays over the last input axis.
    """

    spec: MuscleSpec
    model: Model
    theta: np.ndarray
    domain: Domain
    max_length: float

    @cached_property
    def limits(self) -> Limits:
        """Lengths and pressures served and commanded (:class:`Limits`)."""
        return limits_of(self.spec, self.domain, geo.shortest_length(self.spec))

    @cached_property
    def _coefficients(self) -> Callable[..., Coefficients]:
        """The model's coefficients of these muscles as ``f(length, branch)``
        (:meth:`Model.prepare`).
        """
        return self.model.prepare(self.theta, self.spec, self.domain)

    @cached_property
    def _unflagged(self) -> tuple[float, float]:
        """[m] The lengths that every one of these muscles serves as identified, with no flag:
        within its lengths served and its identified ones.
        """
        lim, domain = self.limits, self.domain
        return (
            float(max(np.max(lim.length_low), np.max(domain.length_min))),
            float(min(np.min(lim.length_high), np.min(domain.length_max))),
        )

    @cached_property
    def _extrapolates(self) -> bool:
        """Whether any of the muscles serves lengths outside its identified ones."""
        return bool(np.any(self.domain.extrapolates))

    def operating(
        self,
        length: ArrayLike,
        length_rate: ArrayLike | None = None,
        valid: bool = False,
        span: tuple[float, float] | None = None,
    ) -> Operating:
        """The length-dependent part of the force at ``length`` [m]: coefficients and flags (see
        :class:`Operating`), new arrays.

        The geometry needs 0 < L < max_length (else INVALID_INPUT).  The model is evaluated at the
        length held inside the lengths served (LENGTH_OUT_OF_RANGE where that moved it): the
        identified range, or, if the model extrapolates credibly, the physical envelope
        (EXTRAPOLATED outside the identified range; :class:`~.models.Domain`).  ``length_rate``
        [m/s] picks the hysteresis branch (+1 lengthening, -1 shortening, 0 unknown:
        BRANCH_UNKNOWN).  Computed once per new length and reused for every pressure at it
        (:func:`force_at`).  ``valid``: the caller checked that the geometry takes every length;
        ``span``: the lowest and highest of ``length``, if the caller has them.
        """
        L, lim = np.asarray(length, float), self.limits
        # written for few numpy calls: the engines call it per message of every muscle
        low, high = self._unflagged
        span = span or ((ew.lowest(L), ew.highest(L)) if L.size else (math.nan, math.nan))
        if inside := span[0] >= low and span[1] <= high:  # (False for NaN)
            # the usual message: every length served as it is, none flagged (two reductions
            # instead of the nine operations below; test_core_muscle_model pins it to them)
            at, flags, usable = L, np.zeros(L.shape, np.uint16), _EVERY
        else:
            at = np.minimum(np.maximum(L, lim.length_low), lim.length_high)  # NaN stays NaN
            flags = (at != L) * _LENGTH_OUT16
            if self._extrapolates:  # else the lengths served lie inside the identified ones
                domain = self.domain
                flags |= ((at < domain.length_min) | (at > domain.length_max)) * _EXTRAPOLATED16
            usable = _EVERY if valid else (L > 0) & (L < self.max_length)  # False for NaN
            if not valid and np.count_nonzero(usable) < usable.size:
                at = np.where(usable, at, lim.length_high)
                flags = np.where(usable, flags, _INVALID16)
        branch = 0.0
        if self.model.hysteresis:
            if length_rate is not None:
                rate = np.asarray(length_rate, float)
                branch = np.where(np.isfinite(rate), np.sign(rate), 0.0)
            flags = flags | np.where(branch == 0, _BRANCH_UNKNOWN16, _NONE16)
        with _QUIET if inside else np.errstate(invalid='ignore', over='ignore'):
            q2, q1, q0 = self._coefficients(at, branch)
        if not q2.shape == q1.shape == q0.shape == flags.shape:  # (broadcast: copied, writeable)
            q2, q1, q0, flags = (a.copy() for a in np.broadcast_arrays(q2, q1, q0, flags))
        return Operating(usable, flags, q2, q1, q0, lim)

    def force(
        self, pressure: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None
    ) -> ForceResult:
        """Tension [N] at gauge pressure [Pa] and length [m]; ``length_rate`` [m/s] picks the
        hysteresis branch.

        Outside the identified data the model's own value where it extrapolates credibly
        (EXTRAPOLATED), else the value at the nearest point served (LENGTH_OUT_OF_RANGE,
        PRESSURE_OUT_OF_RANGE): :meth:`operating` and :func:`force_at`.
        """
        p, L = np.broadcast_arrays(np.asarray(pressure, float), np.asarray(length, float))
        rate = None if length_rate is None else np.broadcast_to(length_rate, L.shape)
        return force_at(self.operating(L, rate), p)

    def pressure(
        self, force: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None
    ) -> PressureResult:
        """Gauge pressure [Pa] that gives tension ``force`` [N] at ``length`` [m]
        (:func:`pressure_for`).
        """
        F, L = np.broadcast_arrays(np.asarray(force, float), np.asarray(length, float))
        rate = None if length_rate is None else np.broadcast_to(length_rate, L.shape)
        return pressure_for(self.operating(L, rate), F)


def served_pressure(gauge: float, limits: Limits) -> tuple[int, float]:
    """The pressure rule of :func:`force_at` for one gauge pressure [Pa] in plain floats (the
    engines' per-message path): (its flags, the pressure served [Pa]).
    """
    flags = 0
    if gauge < 0:
        if gauge < -VENTED_BAND:
            flags = _PRESSURE_OUT | _BELOW_AMBIENT
        gauge = 0.0
    elif gauge > limits.pressure_top:
        flags = _PRESSURE_OUT
        gauge = limits.pressure_top
    if gauge > limits.pressure_known:
        flags |= _EXTRAPOLATED
    return flags, gauge


def pressure_for(op: Operating, force: ArrayLike) -> PressureResult:
    """The inverse of :func:`force_at`: gauge pressure [Pa] in [0, p_max] giving tension ``force``
    [N].

    p_max is the rated pressure (or the highest identified one, for a model that does not
    extrapolate; :class:`Limits`); above the identified pressures the answer is flagged
    EXTRAPOLATED.  At fixed length every model is f(p) = q2 p^2 + q1 p + q0, of either sign of q2
    and q1.  The answer is the smallest root of f(p) = max(force, 0) in [0, p_max] (so a force
    <= 0 gives the pressure at which the muscle starts to pull).  Where no root lies there, it is
    the pressure of the nearest reachable force, flagged SATURATED: a bound or the vertex -q1 /
    (2 q2) (the peak of a concave model, the trough of a convex one), whichever has the model
    force nearest the target (the smaller pressure on a tie).
    """
    F = np.asarray(force, float)
    p_max = op.limits.command_top
    usable = op.usable & np.isfinite(F)
    target = np.where(usable, np.maximum(F, 0.0), 0.0)
    q2, q1, c = op.q2, op.q1, op.q0 - target
    slack = 1e-9 * p_max  # round-off at the bounds is not out of reach
    with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
        # both roots without cancellation (Numerical Recipes 5.6): Q = -(q1 + sgn(q1) sqrt(disc))/2
        disc = q1 * q1 - 4 * q2 * c
        big = -0.5 * (q1 + np.copysign(np.sqrt(disc), q1))
        roots = np.stack(np.broadcast_arrays(big / q2, c / big))
        inside = (disc >= 0) & (roots >= -slack) & (roots <= p_max + slack)
        smallest = np.min(np.where(inside, roots, np.inf), axis=0)
        vertex = np.clip(np.where(q2 != 0, -q1 / (2 * q2), 0.0), 0.0, p_max)
        candidates = np.stack(np.broadcast_arrays(0.0 * vertex, vertex, p_max + 0.0 * vertex))
        miss = np.abs((q2 * candidates + q1) * candidates + c)
        nearest = np.take_along_axis(candidates, np.argmin(miss, axis=0)[None], axis=0)[0]
        reached = np.isfinite(smallest)
        p = np.clip(np.where(reached, smallest, nearest), 0.0, p_max)
        served = np.maximum((q2 * p + q1) * p + op.q0, 0.0)
        short = ~reached & (np.abs(served - target) > 1e-9 * np.maximum(target, 1.0))
        beyond = p > op.limits.pressure_known
    flags = np.where(
        usable,
        op.flags | np.where(short, _SATURATED, 0) | np.where(beyond, _EXTRAPOLATED, 0),
        op.flags | _INVALID,
    ).astype(np.uint16)
    return PressureResult(np.where(usable, p, np.nan), flags)


def pressure_for_one(
    q2: float, q1: float, q0: float, force: float, low: float, high: float
) -> float:
    """:func:`pressure_for`'s rule in plain floats, on [``low``, ``high``] [Pa] (the joint's
    per-message inverse): the smallest root of q2 p^2 + q1 p + q0 = max(``force``, 0) [N] there,
    else the pressure of the nearest reachable force (a bound or the vertex; the smaller on a tie).
    """
    c = q0 - max(force, 0.0)
    disc = q1 * q1 - 4 * q2 * c
    if disc >= 0:
        big = -0.5 * (q1 + math.copysign(math.sqrt(disc), q1))
        bottom, top = low - 1e-9 * high, high * (1 + 1e-9)  # round-off at a bound is in reach
        smallest = math.inf
        if q2 and bottom <= big / q2 <= top:
            smallest = big / q2
        if big and bottom <= c / big <= top:
            smallest = min(smallest, c / big)
        if smallest < math.inf:
            return min(max(smallest, low), high)
    vertex = [min(max(-q1 / (2 * q2), low), high)] if q2 else []
    return min([low, *vertex, high], key=lambda p: (abs((q2 * p + q1) * p + c), p))


@dataclass(frozen=True)
class MuscleModel(Evaluator):
    """A muscle with one identified static force model."""

    spec: MuscleSpec
    model: Model
    theta: np.ndarray
    domain: Domain

    def __post_init__(self) -> None:
        object.__setattr__(self, 'theta', self.model.check_params(self.theta))

    @cached_property
    def max_length(self) -> float:
        """Longest length the geometry can take, the fibre length L0 / cos(Theta0) [m] (eq. 3)."""
        return float(geo.fiber_length(self.spec))

    @cached_property
    def limits(self) -> Limits:
        """:class:`Limits` as plain floats."""
        lim = limits_of(self.spec, self.domain, geo.shortest_length(self.spec))
        return Limits(*(float(getattr(lim, f.name)) for f in fields(Limits)))

    @cached_property
    def _coefficients_one(self) -> Callable[..., Coefficients]:
        """:attr:`_coefficients` on the parameters as plain floats (for :meth:`operating_one`)."""
        return self.model.prepare(tuple(self.theta.tolist()), self.spec, self.domain)

    def operating_one(self, length: float, branch: float) -> tuple[int, float, float, float]:
        """:meth:`operating` of one valid length [m] (0 < L < max_length) in plain floats: (flags,
        q2, q1, q0).

        The float twin of the vector rule, for one message at a time, where numpy's per-call
        overhead would cost more than the arithmetic.  ``branch``: the hysteresis branch from the
        play operator (:mod:`.hysteresis`), +1 or -1 (only its sign counts; 0 or NaN: unknown).
        """
        lim, domain = self.limits, self.domain
        operating = min(max(length, lim.length_low), lim.length_high)
        flags = _LENGTH_OUT if operating != length else 0
        if operating < domain.length_min or operating > domain.length_max:
            flags |= _EXTRAPOLATED
        branch = math.copysign(1.0, branch) if branch and math.isfinite(branch) else 0.0
        if branch == 0.0 and self.model.hysteresis:
            flags |= _BRANCH_UNKNOWN
        q2, q1, q0 = self._coefficients_one(operating, branch)
        return flags, float(q2), float(q1), float(q0)
