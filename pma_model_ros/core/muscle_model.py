"""An identified muscle: spec + model + parameters + validity domain.

Forward force (physical value, clipped at 0 N) and the inverse pressure, both
vectorised over numpy arrays and both returning per-sample :class:`Flag` words.
They are written once, in :class:`Evaluator`, for one muscle
(:class:`MuscleModel`) and for a group of muscles sharing a model whose
numbers are arrays (:mod:`pma_model_ros.core.muscle_bank`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from . import muscle as geo
from .flags import Flag
from .models import Domain, Model, force_raw
from .muscle import MuscleSpec


@dataclass(frozen=True)
class ForceResult:
    force: np.ndarray      #: physical tension [N], >= 0; NaN only where INVALID_INPUT
    raw: np.ndarray        #: model value [N] at the operating point, before clipping at 0 N
    flags: np.ndarray      #: uint16 Flag words


@dataclass(frozen=True)
class PressureResult:
    pressure: np.ndarray   #: gauge pressure [Pa] in [0, max_pressure]; NaN only where INVALID_INPUT
    flags: np.ndarray      #: uint16 Flag words


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

    def _length_flags(self, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(usable mask, flags) for lengths: geometry needs 0 < L < max_length."""
        usable = np.isfinite(length) & (length > 0) & (length < self.max_length)
        flags = np.where(usable, 0, Flag.INVALID_INPUT).astype(np.uint16)
        outside = usable & ((length < self.domain.length_min) | (length > self.domain.length_max)
                            | (length > self.spec.nominal_length))
        flags[outside] |= np.uint16(Flag.LENGTH_OUT_OF_RANGE)
        return usable, flags

    def _operating_length(self, length: np.ndarray, usable: np.ndarray) -> np.ndarray:
        """Length [m] the model is evaluated at: held inside the identified range, never extrapolated."""
        top = np.minimum(self.domain.length_max, self.spec.nominal_length)
        return np.where(usable, np.clip(length, self.domain.length_min, top), top)

    def _branch(self, length_rate: ArrayLike | None, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Hysteresis branch (+1 lengthening, -1 shortening, 0 unknown) and its flags."""
        rate = np.zeros(shape) if length_rate is None else np.broadcast_to(np.asarray(length_rate, float), shape)
        branch = np.where(np.isfinite(rate), np.sign(rate), 0.0)
        unknown = (branch == 0) if self.model.hysteresis else np.zeros(shape, bool)
        return branch, np.where(unknown, Flag.BRANCH_UNKNOWN, 0).astype(np.uint16)

    def force(self, pressure: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None) -> ForceResult:
        """Tension [N] at gauge pressure [Pa] and length [m]; ``length_rate`` [m/s] picks the hysteresis branch.

        Never extrapolated: outside the identified length range (LENGTH_OUT_OF_RANGE)
        or the rated pressures (PRESSURE_OUT_OF_RANGE) the force is the model's
        at the nearest point of the domain, so it stays within the muscle's own bounds.
        """
        p, L = np.broadcast_arrays(np.asarray(pressure, float), np.asarray(length, float))
        usable, flags = self._length_flags(L)
        usable &= np.isfinite(p)
        branch, branch_flags = self._branch(length_rate, p.shape)
        flags |= branch_flags
        flags[~usable] |= np.uint16(Flag.INVALID_INPUT)
        flags[usable & ((p < 0) | (p > self.spec.max_pressure))] |= np.uint16(Flag.PRESSURE_OUT_OF_RANGE)
        p_op = np.where(usable, np.clip(p, 0.0, self.spec.max_pressure), 0.0)
        with np.errstate(invalid="ignore", over="ignore"):
            raw = force_raw(self.model, self.theta, self.spec, self.domain, p_op, self._operating_length(L, usable),
                            branch)
        raw = np.where(usable, raw, np.nan)
        flags[usable & (raw < 0)] |= np.uint16(Flag.CLIPPED)
        return ForceResult(np.where(usable, np.maximum(raw, 0.0), np.nan), raw, flags)

    def pressure(self, force: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None) -> PressureResult:
        """Gauge pressure [Pa] that gives tension ``force`` [N] at ``length`` [m].

        Closed form: every model is F = q2 p^2 + q1 p + q0 at fixed L, and the
        root where F rises with p is p = 2 (F - q0) / (q1 + sqrt(q1^2 - 4 q2 (q0 - F))),
        valid for q2 = 0 too.  A force <= 0 gives the pressure at which the
        muscle starts to pull; a force out of reach gives the bound, flagged SATURATED.
        """
        F, L = np.broadcast_arrays(np.asarray(force, float), np.asarray(length, float))
        usable, flags = self._length_flags(L)
        usable &= np.isfinite(F)
        branch, branch_flags = self._branch(length_rate, F.shape)
        flags |= branch_flags
        flags[~usable] |= np.uint16(Flag.INVALID_INPUT)
        safe_L = self._operating_length(L, usable)
        target = np.where(usable, np.maximum(F, 0.0), 0.0)
        p_max = self.spec.max_pressure
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            q2, q1, q0 = self.model.coefficients(self.theta, self.spec, self.domain, safe_L, branch)
            q2, q1, q0 = np.broadcast_arrays(q2, q1, q0)
            disc = q1**2 - 4 * q2 * (q0 - target)
            denom = q1 + np.sqrt(np.maximum(disc, 0.0))
            p = 2 * (target - q0) / denom
            reachable = (disc >= 0) & (denom > 0) & np.isfinite(p)
            f_at_max = (q2 * p_max + q1) * p_max + q0
        p = np.where(reachable, p, np.where(f_at_max < target, p_max, 0.0))
        wants_pull = usable & (F > 0)
        slack = 1e-9 * p_max  # round-off at the bounds is not saturation
        too_high = p > p_max + slack
        too_low = (p < -slack) & wants_pull
        flags[usable & (~reachable | too_high | too_low)] |= np.uint16(Flag.SATURATED)
        p = np.clip(p, 0.0, p_max)
        return PressureResult(np.where(usable, p, np.nan), flags)


@dataclass(frozen=True)
class MuscleModel(Evaluator):
    """A muscle with one identified static force model."""

    spec: MuscleSpec
    model: Model
    theta: np.ndarray
    domain: Domain

    def __post_init__(self) -> None:
        object.__setattr__(self, "theta", self.model.check_params(self.theta))

    @cached_property
    def max_length(self) -> float:
        """Longest length the geometry can take, the fibre length L0 / cos(Theta0) [m] (eq. 3)."""
        return float(geo.fiber_length(self.spec))
