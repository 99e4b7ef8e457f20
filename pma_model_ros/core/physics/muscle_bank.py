"""Many identified muscles evaluated together: one vectorised call per model.

A robot arm or hand has tens of muscles, each with its own spec, model, parameters and validity
domain.  :class:`MuscleBank` groups them by model (a model with a calibrated pressure offset,
:func:`~pma_model_ros.core.identification.calibration.shifted`, is a model of its own) and stacks
each group's numbers as arrays (one entry per muscle), so the force or the inverse of all muscles
is one :class:`~pma_model_ros.core.physics.muscle_model.Evaluator` call per model (one call for a
homogeneous arm).  The results equal those of each muscle's own :class:`MuscleModel`; the
arithmetic is the same code.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .models import Model
from .muscle_model import (
    Evaluator,
    force_at,
    ForceResult,
    Limits,
    MuscleModel,
    Operating,
    pressure_for,
    PressureResult,
)


@dataclass(frozen=True)
class SpecColumns:
    """The numbers of n :class:`MuscleSpec` as arrays of n (m, m, m, rad, Pa)."""

    nominal_length: np.ndarray
    inner_diameter: np.ndarray
    membrane_thickness: np.ndarray
    fiber_angle: np.ndarray
    max_pressure: np.ndarray


@dataclass(frozen=True)
class DomainColumns:
    """The :class:`~.models.Domain` of n muscles as arrays of n (m, m, Pa, bool)."""

    length_min: np.ndarray
    length_max: np.ndarray
    pressure_max: np.ndarray
    extrapolates: np.ndarray


@dataclass(frozen=True)
class ModelGroup(Evaluator):
    """The muscles of a bank that share one model; their numbers stacked over the last axis."""

    index: np.ndarray  #: positions of these muscles in the bank
    spec: SpecColumns
    model: Model
    theta: np.ndarray  #: (n_params, n)
    domain: DomainColumns
    max_length: np.ndarray  #: (n,) [m]

    @classmethod
    def of(cls, index: Sequence[int], muscles: Sequence[MuscleModel]) -> 'ModelGroup':
        def column(get: Callable[[MuscleModel], float]) -> np.ndarray:
            return np.array([get(m) for m in muscles], dtype=float)

        spec = SpecColumns(
            *(column(lambda m, f=f.name: getattr(m.spec, f)) for f in fields(SpecColumns))
        )
        domain = DomainColumns(
            *(column(lambda m, f=f.name: getattr(m.domain, f)) for f in fields(DomainColumns))
        )
        theta = np.stack([m.theta for m in muscles], axis=1)
        return cls(
            np.asarray(index, dtype=np.intp),
            spec,
            muscles[0].model,
            theta,
            domain,
            column(lambda m: m.max_length),
        )


class MuscleBank:
    """N identified muscles; force and inverse of all of them in one vectorised call per model.

    Inputs are arrays whose last axis has length N, in the order of ``muscles``
    (other leading axes broadcast, e.g. (T, N) for T samples of each muscle).
    """

    def __init__(self, muscles: Sequence[MuscleModel]) -> None:
        if not muscles:
            raise ValueError('a muscle bank needs at least one muscle')
        self.muscles = tuple(muscles)
        by_model: dict[Model, list[int]] = {}
        for i, muscle in enumerate(self.muscles):
            by_model.setdefault(muscle.model, []).append(i)
        self.groups = tuple(
            ModelGroup.of(index, [self.muscles[i] for i in index]) for index in by_model.values()
        )
        #: (N,) lengths and pressures served and commanded
        self.limits = Limits(
            *(np.array([getattr(m.limits, f.name) for m in self.muscles]) for f in fields(Limits))
        )
        #: (N,) fibre lengths [m] (eq. 3)
        self.max_length = np.array([m.max_length for m in self.muscles])

    def __len__(self) -> int:
        return len(self.muscles)

    def operating(
        self,
        length: ArrayLike,
        length_rate: ArrayLike | None = None,
        valid: bool = False,
        span: tuple[float, float] | None = None,
    ) -> Operating:
        """Length-dependent coefficients and flags of every muscle (one call per model); see
        :meth:`Evaluator.operating` (``span``: of all lengths; each model's own if several).
        """
        L, _, rate = self._inputs(length, length, length_rate)
        if len(self.groups) == 1:  # every muscle, in bank order
            return self.groups[0].operating(L, rate, valid, span)
        parts = [
            (g.index, g.operating(L[..., g.index], rate[..., g.index], valid)) for g in self.groups
        ]
        out = Operating(
            np.empty(L.shape, bool),
            np.empty(L.shape, np.uint16),
            np.empty(L.shape),
            np.empty(L.shape),
            np.empty(L.shape),
            self.limits,
        )
        for index, part in parts:
            for name in ('usable', 'flags', 'q2', 'q1', 'q0'):
                getattr(out, name)[..., index] = getattr(part, name)  # (broadcast: valid)
        return out

    def force(
        self, pressure: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None
    ) -> ForceResult:
        """Tension [N] of every muscle at gauge pressure [Pa] and length [m]; see
        :meth:`MuscleModel.force`.
        """
        p, L, rate = self._inputs(pressure, length, length_rate)
        return force_at(self.operating(L, rate), p)

    def pressure(
        self, force: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None
    ) -> PressureResult:
        """Gauge pressure [Pa] giving tension ``force`` [N] at ``length`` [m]; see
        :meth:`MuscleModel.pressure`.
        """
        F, L, rate = self._inputs(force, length, length_rate)
        return pressure_for(self.operating(L, rate), F)

    def _inputs(
        self, value: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        v, L = np.asarray(value, float), np.asarray(length, float)
        r = np.full(L.shape, np.nan) if length_rate is None else np.asarray(length_rate, float)
        if not v.shape == L.shape == r.shape:
            v, L, r = np.broadcast_arrays(v, L, r)
        if v.shape[-1:] != (len(self),):
            raise ValueError(
                f'inputs need a last axis of {len(self)} muscles, got shape {v.shape}'
            )
        return v, L, r
