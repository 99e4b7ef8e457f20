"""Antagonistic joints: torque, stiffness and the two pressures of two muscles on one transmission
(no ROS).

Muscle 0 (the *positive* one) shortens for positive θ (REP-103: counter-clockwise about the joint
axis), muscle 1 lengthens.  With the lever arm r(θ) [m] and its travel s(θ) = ∫₀^θ r dθ' [m]:

    L0(θ) = L0(0) - s(θ),   L1(θ) = L1(0) + s(θ)                          [m]
    τ = r (F0 - F1)                                                       [N·m]
    K = -dτ/dθ = -r' (F0 - F1) + r² (dF0/dL + dF1/dL)                     [N·m/rad]

dF/dL is analytic at fixed pressure
(:func:`~pma_model_ros.core.physics.models.coefficient_slopes`), and 0 where the served force does
not change with length: a clipped (slack) muscle, or a length held at the edge of the lengths
served (LENGTH_OUT_OF_RANGE, :meth:`~pma_model_ros.core.physics.muscle_model.Evaluator.operating`).

A hysteresis muscle's branch (+1 lengthening or filling, -1 shortening or venting, 0 unknown: the
mean of both, BRANCH_UNKNOWN) is an input here: joint_node keeps it per muscle with the play
operator (:mod:`~pma_model_ros.core.physics.hysteresis`, what ``follows`` says), the one-shot CLI
takes it from the sign of a velocity.

The forward model is vectorised over samples (:meth:`Joint.forward`); :class:`MuscleAt` is the
float twin of one muscle at one length, used by the inverse and by joint_node per message.  The
inverse (:meth:`Joint.pressures_one`) needs forces that do not fall with pressure (true of every
shipped model inside its identified box, with the clip at 0 N).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from .flags import Flag
from .hysteresis import DEFAULT_FOLLOW, Follow
from .models import coefficient_slopes
from .muscle_model import force_at, MuscleModel, pressure_for_one

#: Co-contraction levels of the inverse: the lower of the two pressures, or their sum [Pa gauge].
COCONTRACTION_MODES = ('min', 'sum')
#: Inverse results off the wanted torque or stiffness by more than this share of the joint's scale
#: are SATURATED.
TOLERANCE = 1e-9
_SATURATED, _INVALID = int(Flag.SATURATED), int(Flag.INVALID_INPUT)
#: Both branches unknown.
UNKNOWN = (0.0, 0.0)


@dataclass(frozen=True)
class Transmission:
    """Lever arm r(θ) = Σ_k arm[k] θ^k [m] (one coefficient: a pulley of radius arm[0])."""

    arm: tuple[float, ...]

    def radius(self, theta: ArrayLike):
        """r(θ) [m]."""
        result = 0.0
        for c in reversed(self.arm):
            result = result * theta + c
        return result

    def radius_slope(self, theta: ArrayLike):
        """dr/dθ [m/rad]."""
        result = 0.0
        for k in range(len(self.arm) - 1, 0, -1):
            result = result * theta + k * self.arm[k]
        return result

    def travel(self, theta: ArrayLike):
        """s(θ) = ∫₀^θ r dθ' [m]: how much the positive muscle has shortened at θ."""
        result = 0.0
        for k in range(len(self.arm) - 1, -1, -1):
            result = (result + self.arm[k] / (k + 1)) * theta
        return result


@dataclass(frozen=True)
class Forward:
    """Torque and stiffness at samples; ``forces``, ``slopes`` and ``flags`` stacked over the two
    muscles.
    """

    torque: np.ndarray  #: [N·m], positive counter-clockwise
    stiffness: np.ndarray  #: K = -dτ/dθ [N·m/rad]
    forces: np.ndarray  #: (2, ...) tensions [N]
    slopes: np.ndarray  #: (2, ...) dF/dL [N/m]
    flags: np.ndarray  #: (2, ...) uint16 Flag words of each muscle


@dataclass(frozen=True)
class Pressures:
    """One inverse solution at one angle; pressures are gauge [Pa] in [0, max_pressure]."""

    pressures: tuple[float, float]
    flags: int  #: SATURATED if the wanted torque or stiffness was out of reach
    torque: float  #: achieved torque [N·m] (the model's)
    stiffness: float  #: achieved stiffness [N·m/rad]
    #: reachable torque [N·m] at this angle under the co-contraction asked
    torque_range: tuple[float, float]


class MuscleAt:
    """One muscle at one length [m] on one hysteresis ``branch`` (+1, -1, 0: unknown), in plain
    floats: force, its length slope, and the inverse in pressure.
    """

    __slots__ = ('flags', 'q2', 'q1', 'q0', 'd2', 'd1', 'd0', 'p_top', 'p_max')

    def __init__(
        self, model: MuscleModel, theta: tuple[float, ...], length: float, branch: float
    ) -> None:
        self.flags, self.q2, self.q1, self.q0 = model.operating_one(length, branch)
        limits = model.limits
        self.p_top, self.p_max = limits.pressure_top, limits.command_top  # served, commanded [Pa]
        if self.flags & int(Flag.LENGTH_OUT_OF_RANGE):
            self.d2 = self.d1 = self.d0 = 0.0
        else:
            d2, d1, d0 = coefficient_slopes(
                model.model, theta, model.spec, model.domain, length, branch
            )
            self.d2, self.d1, self.d0 = float(d2), float(d1), float(d0)

    def force(self, p: float) -> float:
        """Tension [N] at gauge ``p`` [Pa] held to the pressures served
        (:class:`~.muscle_model.Limits`).
        """
        p = min(max(p, 0.0), self.p_top)
        return max((self.q2 * p + self.q1) * p + self.q0, 0.0)

    def slope(self, p: float) -> float:
        """dF/dL [N/m] at gauge ``p`` [Pa]; 0 where the muscle is slack."""
        p = min(max(p, 0.0), self.p_top)
        if (self.q2 * p + self.q1) * p + self.q0 <= 0.0:
            return 0.0
        return (self.d2 * p + self.d1) * p + self.d0

    def pressure(self, force: float, low: float = 0.0) -> float:
        """The lowest gauge pressure [Pa] in [low, p_max] (the highest commanded) giving tension
        ``force`` [N], else that of the nearest reachable tension (:func:`.pressure_for_one`).
        """
        return pressure_for_one(self.q2, self.q1, self.q0, force, low, self.p_max)


@dataclass(frozen=True)
class Joint:
    """Two identified muscles on one transmission; ``muscles[0]`` shortens for positive θ."""

    name: str
    muscles: tuple[MuscleModel, MuscleModel]
    muscle_names: tuple[str, str]
    length_at_zero: tuple[float, float]  #: each muscle's length at θ = 0 [m]
    transmission: Transmission
    limits: tuple[float, float]  #: joint range [rad]
    #: what each muscle's hysteresis branch follows in joint_node (its parameters' ``hysteresis``)
    follows: tuple[Follow, Follow] = (DEFAULT_FOLLOW, DEFAULT_FOLLOW)

    def __post_init__(self) -> None:
        low, high = self.limits
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ValueError(
                f"joint '{self.name}': limits must be finite [min, max] rad with min < max, "
                f'got {list(self.limits)}'
            )
        angles = np.linspace(low, high, 1001)
        radius = self.transmission.radius(angles)
        if not np.all(radius > 0):
            bad = float(angles[np.argmin(radius)])
            raise ValueError(
                f"joint '{self.name}': lever arm r = {float(np.min(radius)):.4g} m at θ = "
                f'{bad:.4g} rad; '
                'it must be > 0 m over the joint limits'
            )
        for k, length in enumerate(self.lengths(angles)):
            limit = self.muscles[k].max_length
            outside = ~((length > 0) & (length < limit))
            if outside.any():
                i = int(np.argmax(outside))
                raise ValueError(
                    f"joint '{self.name}': muscle '{self.muscle_names[k]}' would be "
                    f'{length[i]:.4g} m '
                    f'long at θ = {angles[i]:.4g} rad, outside its geometry (0, {limit:.4g}) m'
                )
        object.__setattr__(self, '_thetas', tuple(tuple(m.theta.tolist()) for m in self.muscles))

    def lengths(self, theta: ArrayLike) -> tuple:
        """Each muscle's length [m] at ``theta`` [rad]."""
        s = self.transmission.travel(theta)
        return self.length_at_zero[0] - s, self.length_at_zero[1] + s

    def forward(
        self,
        theta: ArrayLike,
        p0: ArrayLike,
        p1: ArrayLike,
        branches: tuple[ArrayLike, ArrayLike] = UNKNOWN,
    ) -> Forward:
        """Torque [N·m] and stiffness [N·m/rad] at angle ``theta`` [rad] and gauge pressures
        ``p0``, ``p1`` [Pa], each muscle on its hysteresis branch of ``branches`` (+1, -1, 0:
        unknown).
        """
        theta, p0, p1 = np.broadcast_arrays(*(np.asarray(x, float) for x in (theta, p0, p1)))
        r, r_slope = self.transmission.radius(theta), self.transmission.radius_slope(theta)
        forces, slopes, flags = [], [], []
        for model, length, p, branch in zip(self.muscles, self.lengths(theta), (p0, p1), branches):
            branch = np.broadcast_to(np.asarray(branch, float), theta.shape)
            op = model.operating(length, branch)
            result = force_at(op, p)
            lim = model.limits
            d2, d1, d0 = coefficient_slopes(
                model.model,
                model.theta,
                model.spec,
                model.domain,
                np.clip(length, lim.length_low, lim.length_high),
                branch,
            )
            p_op = np.clip(p, 0.0, lim.pressure_top)
            pulls = (result.raw > 0) & ((op.flags & int(Flag.LENGTH_OUT_OF_RANGE)) == 0)
            forces.append(result.force)
            slopes.append(np.where(pulls, (d2 * p_op + d1) * p_op + d0, 0.0))
            flags.append(result.flags)
        torque = r * (forces[0] - forces[1])
        stiffness = -r_slope * (forces[0] - forces[1]) + r * r * (slopes[0] + slopes[1])
        return Forward(
            torque, stiffness, np.array(forces), np.array(slopes), np.array(flags, np.uint16)
        )

    # --- float path: one angle
    # ------------------------------------------------------------------------------

    def at(
        self, theta: float, branches: Sequence[float] = UNKNOWN
    ) -> tuple[MuscleAt, MuscleAt, float, float]:
        """Both muscles at angle ``theta`` [rad], each on its hysteresis branch of ``branches``
        (+1, -1, 0: unknown); r [m], r' [m/rad].
        """
        r, r_slope = self.transmission.radius(theta), self.transmission.radius_slope(theta)
        l0, l1 = self.lengths(theta)
        return (
            MuscleAt(self.muscles[0], self._thetas[0], l0, branches[0]),
            MuscleAt(self.muscles[1], self._thetas[1], l1, branches[1]),
            r,
            r_slope,
        )

    @staticmethod
    def torque_stiffness(
        m0: MuscleAt, m1: MuscleAt, r: float, r_slope: float, p0: float, p1: float
    ) -> tuple[float, float]:
        """Torque [N·m] and stiffness [N·m/rad] of muscles at one angle (:meth:`at`) at gauge
        pressures [Pa].
        """
        difference = m0.force(p0) - m1.force(p1)
        return r * difference, -r_slope * difference + r * r * (m0.slope(p0) + m1.slope(p1))

    def torque_range(self, theta: float) -> tuple[float, float]:
        """Lowest and highest torque [N·m] at ``theta`` [rad] over every pressure pair."""
        m0, m1, r, _ = self.at(theta)
        return r * (m0.force(0.0) - m1.force(m1.p_max)), r * (m0.force(m0.p_max) - m1.force(0.0))

    def pressures_one(
        self,
        theta: float,
        torque: float,
        cocontraction: float = 0.0,
        mode: str = 'min',
        stiffness: float | None = None,
        branches: Sequence[float] = UNKNOWN,
    ) -> Pressures:
        """Gauge pressures [Pa] for the wanted ``torque`` [N·m] at ``theta`` [rad], with either a
        co-contraction level [Pa] (``mode`` 'min': the lower pressure, closed form; 'sum': the
        pressure sum, brentq) or a wanted ``stiffness`` [N·m/rad] (brentq along the pairs giving
        the torque), the muscles on their hysteresis ``branches``.  Out of reach: the nearest
        reachable level, torque, then stiffness, flagged SATURATED.
        """
        return self.pressures_at(self.at(theta, branches), torque, cocontraction, mode, stiffness)

    def pressures_at(
        self,
        at: tuple[MuscleAt, MuscleAt, float, float],
        torque: float,
        cocontraction: float = 0.0,
        mode: str = 'min',
        stiffness: float | None = None,
    ) -> Pressures:
        """:meth:`pressures_one` with both muscles already at the angle (``at``: :meth:`at`), as
        the joint engine keeps them between messages.
        """
        if mode not in COCONTRACTION_MODES:
            raise ValueError(
                f'co-contraction mode must be one of {COCONTRACTION_MODES}, got {mode!r}'
            )
        m0, m1, r, r_slope = at
        want = torque / r  # wanted F0 - F1 [N]
        if stiffness is not None:
            p0, p1, span = _for_stiffness(m0, m1, r, r_slope, want, stiffness)
            level_ok = math.isfinite(stiffness)
        elif mode == 'min':
            p0, p1, span = _for_lower(m0, m1, want, cocontraction)
            level_ok = 0.0 <= cocontraction <= min(m0.p_max, m1.p_max)
        else:
            p0, p1, span = _for_sum(m0, m1, want, cocontraction)
            level_ok = 0.0 <= cocontraction <= m0.p_max + m1.p_max
        got, k = self.torque_stiffness(m0, m1, r, r_slope, p0, p1)
        scale = r * (m0.force(m0.p_max) + m1.force(m1.p_max))
        flags = int(m0.flags | m1.flags)
        missed = abs(got - torque) > TOLERANCE * scale or (
            stiffness is not None and abs(k - stiffness) > TOLERANCE * max(abs(stiffness), 1.0)
        )
        if missed or not (math.isfinite(torque) and level_ok):
            flags |= _SATURATED
        return Pressures((p0, p1), flags, got, k, (r * span[0], r * span[1]))

    def pressures(
        self,
        theta: ArrayLike,
        torque: ArrayLike,
        cocontraction: ArrayLike = 0.0,
        mode: str = 'min',
        stiffness: ArrayLike | None = None,
    ) -> list[Pressures]:
        """:meth:`pressures_one` of each sample of the broadcast inputs (flattened)."""
        level = stiffness if stiffness is not None else cocontraction
        arrays = np.broadcast_arrays(*(np.asarray(x, float) for x in (theta, torque, level)))
        return [
            self.pressures_one(
                t,
                tau,
                None if stiffness is not None else c,
                mode,
                c if stiffness is not None else None,
            )
            for t, tau, c in zip(*(a.ravel().tolist() for a in arrays))
        ]


def _for_lower(
    m0: MuscleAt, m1: MuscleAt, want: float, level: float
) -> tuple[float, float, tuple[float, float]]:
    """The pair whose lower pressure is ``level`` [Pa] and whose F0 - F1 is ``want`` [N] (closed
    form).
    """
    level = min(max(level, 0.0), m0.p_max, m1.p_max) if math.isfinite(level) else 0.0
    span = (m0.force(level) - m1.force(m1.p_max), m0.force(m0.p_max) - m1.force(level))
    if want >= m0.force(level) - m1.force(level):  # muscle 0 pulls more: muscle 1 at the level
        return m0.pressure(m1.force(level) + want, level), level, span
    return level, m1.pressure(m0.force(level) - want, level), span


def _for_sum(
    m0: MuscleAt, m1: MuscleAt, want: float, total: float
) -> tuple[float, float, tuple[float, float]]:
    """The pair with p0 + p1 = ``total`` [Pa] and F0 - F1 = ``want`` [N] (brentq on p0)."""
    total = min(max(total, 0.0), m0.p_max + m1.p_max) if math.isfinite(total) else 0.0
    low, high = max(0.0, total - m1.p_max), min(total, m0.p_max)

    def gap(p0: float) -> float:
        return m0.force(p0) - m1.force(total - p0) - want

    g_low, g_high = gap(low), gap(high)
    span = (g_low + want, g_high + want)
    if g_low >= 0:
        p0 = low
    elif g_high <= 0:
        p0 = high
    else:
        p0 = brentq(gap, low, high, xtol=1e-9, rtol=4 * np.finfo(float).eps)
    return p0, total - p0, span


def _for_stiffness(
    m0: MuscleAt, m1: MuscleAt, r: float, r_slope: float, want: float, stiffness: float
) -> tuple[float, float, tuple[float, float]]:
    """The pair with F0 - F1 = ``want`` [N] whose stiffness is nearest ``stiffness`` [N·m/rad]
    (brentq along the follower's pressure s; the leader, the muscle pulling more, takes the
    pressure giving the torque).
    """
    span = (m0.force(0.0) - m1.force(m1.p_max), m0.force(m0.p_max) - m1.force(0.0))
    leader, follower = (m0, m1) if want >= 0 else (m1, m0)
    need = abs(want)
    if want > span[1] or want < span[0] or not math.isfinite(want):  # out of reach: nearest bound
        ends = (leader.p_max, 0.0) if math.isfinite(want) else (0.0, 0.0)
        return (ends if want >= 0 else ends[::-1]) + (span,)
    s_low = follower.pressure(leader.force(0.0) - need)
    s_high = (
        follower.pressure(leader.force(leader.p_max) - need)
        if follower.force(follower.p_max) + need > leader.force(leader.p_max)
        else follower.p_max
    )

    def pair(s: float) -> tuple[float, float]:
        lead = leader.pressure(follower.force(s) + need)
        return (lead, s) if want >= 0 else (s, lead)

    def miss(s: float) -> float:
        return Joint.torque_stiffness(m0, m1, r, r_slope, *pair(s))[1] - stiffness

    k_low, k_high = miss(s_low), miss(s_high)
    if k_low * k_high < 0:
        s = brentq(miss, s_low, s_high, xtol=1e-9, rtol=4 * np.finfo(float).eps)
    else:
        s = s_low if abs(k_low) <= abs(k_high) else s_high
    return pair(s) + (span,)


def envelope(
    joint: Joint, angles: Sequence[float], levels: Sequence[float] = ()
) -> dict[str, np.ndarray]:
    """Over ``angles`` [rad]: the reachable torque range [N·m] (``torque_min``/``torque_max``), the
    stiffness [N·m/rad] with both muscles unpressurised and both at max_pressure, and the torque
    range at each lower-pressure co-contraction level [Pa] of ``levels``
    (``level_min``/``level_max``, shape (levels, angles)).
    """
    out = {
        key: np.empty(len(angles))
        for key in ('torque_min', 'torque_max', 'stiffness_low', 'stiffness_high')
    }
    out['level_min'], out['level_max'] = (
        np.empty((len(levels), len(angles))),
        np.empty((len(levels), len(angles))),
    )
    for i, theta in enumerate(angles):
        m0, m1, r, r_slope = joint.at(float(theta))
        out['torque_min'][i], out['torque_max'][i] = joint.torque_range(float(theta))
        out['stiffness_low'][i] = joint.torque_stiffness(m0, m1, r, r_slope, 0.0, 0.0)[1]
        out['stiffness_high'][i] = joint.torque_stiffness(m0, m1, r, r_slope, m0.p_max, m1.p_max)[
            1
        ]
        for j, level in enumerate(levels):
            low, high = _for_lower(m0, m1, 0.0, level)[2]
            out['level_min'][j, i], out['level_max'][j, i] = r * low, r * high
    return out
