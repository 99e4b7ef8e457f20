"""Many identified muscles evaluated together: one vectorised call per model.

A robot arm or hand has tens of muscles, each with its own spec, model,
parameters and validity domain.  :class:`MuscleBank` groups them by model and
stacks each group's numbers as arrays (one entry per muscle), so the force or
the inverse of all muscles is one :class:`~pma_model_ros.core.muscle_model.Evaluator`
call per model (one call for a homogeneous arm).  The results equal those of
each muscle's own :class:`MuscleModel`; the arithmetic is the same code.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .models import Model
from .muscle_model import Evaluator, ForceResult, MuscleModel, PressureResult


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
    """Identified length ranges of n muscles as arrays of n [m]."""

    length_min: np.ndarray
    length_max: np.ndarray


@dataclass(frozen=True)
class ModelGroup(Evaluator):
    """The muscles of a bank that share one model; their numbers stacked over the last axis."""

    index: np.ndarray        #: positions of these muscles in the bank
    spec: SpecColumns
    model: Model
    theta: np.ndarray        #: (n_params, n)
    domain: DomainColumns
    max_length: np.ndarray   #: (n,) [m]

    @classmethod
    def of(cls, index: Sequence[int], muscles: Sequence[MuscleModel]) -> "ModelGroup":
        def column(get: Callable[[MuscleModel], float]) -> np.ndarray:
            return np.array([get(m) for m in muscles], dtype=float)

        spec = SpecColumns(*(column(lambda m, f=f.name: getattr(m.spec, f))
                             for f in fields(SpecColumns)))
        domain = DomainColumns(column(lambda m: m.domain.length_min), column(lambda m: m.domain.length_max))
        theta = np.stack([m.theta for m in muscles], axis=1)
        return cls(np.asarray(index, dtype=np.intp), spec, muscles[0].model, theta, domain,
                   column(lambda m: m.max_length))


class MuscleBank:
    """N identified muscles; force and inverse of all of them in one vectorised call per model.

    Inputs are arrays whose last axis has length N, in the order of ``muscles``
    (other leading axes broadcast, e.g. (T, N) for T samples of each muscle).
    """

    def __init__(self, muscles: Sequence[MuscleModel]) -> None:
        if not muscles:
            raise ValueError("a muscle bank needs at least one muscle")
        self.muscles = tuple(muscles)
        by_model: dict[str, list[int]] = {}
        for i, muscle in enumerate(self.muscles):
            by_model.setdefault(muscle.model.name, []).append(i)
        self.groups = tuple(ModelGroup.of(index, [self.muscles[i] for i in index]) for index in by_model.values())

    def __len__(self) -> int:
        return len(self.muscles)

    def force(self, pressure: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None) -> ForceResult:
        """Tension [N] of every muscle at gauge pressure [Pa] and length [m]; see :meth:`MuscleModel.force`."""
        p, L, rate = self._inputs(pressure, length, length_rate)
        results = [(g.index, g.force(p[..., g.index], L[..., g.index], rate[..., g.index])) for g in self.groups]
        if len(results) == 1:
            return results[0][1]
        out = ForceResult(np.empty(p.shape), np.empty(p.shape), np.empty(p.shape, np.uint16))
        for index, result in results:
            out.force[..., index], out.raw[..., index], out.flags[..., index] = result.force, result.raw, result.flags
        return out

    def pressure(self, force: ArrayLike, length: ArrayLike, length_rate: ArrayLike | None = None) -> PressureResult:
        """Gauge pressure [Pa] giving tension ``force`` [N] at ``length`` [m]; see :meth:`MuscleModel.pressure`."""
        F, L, rate = self._inputs(force, length, length_rate)
        results = [(g.index, g.pressure(F[..., g.index], L[..., g.index], rate[..., g.index])) for g in self.groups]
        if len(results) == 1:
            return results[0][1]
        out = PressureResult(np.empty(F.shape), np.empty(F.shape, np.uint16))
        for index, result in results:
            out.pressure[..., index], out.flags[..., index] = result.pressure, result.flags
        return out

    def _inputs(self, value: ArrayLike, length: ArrayLike,
                length_rate: ArrayLike | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rate = np.nan if length_rate is None else length_rate
        v, L, r = np.broadcast_arrays(np.asarray(value, float), np.asarray(length, float), np.asarray(rate, float))
        if v.shape[-1:] != (len(self),):
            raise ValueError(f"inputs need a last axis of {len(self)} muscles, got shape {v.shape}")
        return v, L, r
