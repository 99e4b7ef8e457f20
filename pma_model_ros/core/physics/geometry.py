"""Muscle specification and braid geometry (Martens & Boblan 2017, eqs. 1-4).

All quantities are SI: lengths in m, angles in rad, pressures in Pa (gauge).
The geometry functions take a :class:`MuscleSpec` or any object with its numeric
fields as arrays (one entry per muscle, see :mod:`pma_model_ros.core.physics.muscle_bank`), and
lengths as arrays or one float (:mod:`pma_model_ros.core.physics.elementwise`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
import math
import sys
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from . import elementwise as ew
from ..hints import missing_key, pressure_hint, unknown_keys

#: Standard atmosphere [Pa absolute]: the default ambient pressure (gauge = absolute - ambient).
STANDARD_ATMOSPHERE = 101325.0


@dataclass(frozen=True)
class MuscleSpec:
    """Geometry and rating of one pneumatic muscle.

    Parameters
    ----------
    name : str
        Catalogue name, e.g. ``"DMSP-10-250"``.
    nominal_length : float
        Initial (unpressurised, unstretched) length L0 [m].
    inner_diameter : float
        Initial inner diameter D0 [m].
    membrane_thickness : float
        Initial membrane thickness H0 [m].
    fiber_angle : float
        Initial braid angle Theta0 between fibre and muscle axis [rad].
    max_pressure : float
        Highest rated gauge pressure [Pa].

    """

    name: str
    nominal_length: float
    inner_diameter: float
    membrane_thickness: float
    fiber_angle: float
    max_pressure: float

    def __post_init__(self) -> None:
        for field in ('nominal_length', 'inner_diameter', 'membrane_thickness', 'max_pressure'):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and 0 < value < _FLOAT_MAX):
                raise ValueError(f'muscle.{field} must be a positive finite number, got {value!r}')
        angle = self.fiber_angle
        if not (isinstance(angle, (int, float)) and 0 < angle < math.pi / 2):
            degrees = isinstance(angle, (int, float)) and 1.6 < angle < 90
            raise ValueError(
                f'muscle.fiber_angle must be in (0, pi/2) rad, got {angle!r}'
                + ('; degrees? multiply by pi/180' if degrees else '')
            )
        if angle >= _NEUTRAL_ANGLE:
            raise ValueError(
                f'muscle.fiber_angle {angle:g} rad ({math.degrees(angle):.1f} deg) is at or '
                f'beyond arctan(sqrt(2)) = {_NEUTRAL_ANGLE:.4f} rad (54.7 deg), where the braid '
                'pulls nothing at L0 (eq. 4: dV/dL = 0); a contracting muscle has a smaller angle '
                '(Festo DMSP: 0.4992 rad = 28.6 deg)'
            )
        for field, most in _LARGEST.items():
            if getattr(self, field) > most:
                raise ValueError(
                    f'muscle.{field} must be in metres (at most {most:g} m), got '
                    f'{getattr(self, field)!r}; millimetres? divide by 1000'
                )
        if self.max_pressure < 1e3:
            raise ValueError(
                f'muscle.max_pressure must be a gauge pressure in Pa, got {self.max_pressure:g}; '
                + pressure_hint(self.max_pressure)
            )
        if not isinstance(self.name, str) or not self.name:
            raise ValueError('muscle.name must be a non-empty string')

    @classmethod
    def from_mapping(cls, data: object, where: str = 'muscle.') -> 'MuscleSpec':
        """Build a spec from a mapping with exactly the dataclass's keys (``where`` prefixes them
        in errors).
        """
        if not isinstance(data, dict):
            raise ValueError(
                f"muscle spec (key 'muscle') must be a mapping, got {type(data).__name__}"
            )
        expected = list(cls.__dataclass_fields__)
        problems = unknown_keys(data, expected, where) + [
            missing_key(k, data, expected, where) for k in expected if k not in data
        ]
        if problems:
            raise ValueError('; '.join(dict.fromkeys(problems)))
        values = {k: data[k] if k == 'name' else _as_float(k, data[k]) for k in expected}
        return cls(**values)

    def to_mapping(self) -> dict:
        return asdict(self)


#: [rad] The braid angle of full contraction, arctan(sqrt(2)): there dV/dL = 0 (eq. 4).
_NEUTRAL_ANGLE = math.atan(math.sqrt(2))
_FLOAT_MAX = sys.float_info.max  # an int above it (YAML reads 400 digits as int) is no float
#: [m] Largest dimensions a muscle spec takes: beyond them, millimetres were meant.
_LARGEST = {'nominal_length': 10.0, 'inner_diameter': 1.0, 'membrane_thickness': 0.1}


def _as_float(key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'muscle.{key} must be a number, got {value!r}')
    try:
        return float(value)
    except OverflowError:
        raise ValueError(f'muscle.{key} is too large for a float') from None


class BraidConstants(NamedTuple):
    """The length-independent numbers of :func:`braid` (floats, or arrays of n muscles)."""

    fiber_length_sq: float  #: L_Fiber^2 [m^2]
    turns_pi: float  #: n pi [-]
    four_pi_turns_sq: float  #: 4 pi n^2 [-]


def fiber_length(spec: MuscleSpec, fiber_angle: float | None = None) -> float:
    """Constant fibre length L_Fiber = L0 / cos(Theta0) [m] (eq. 3)."""
    theta = spec.fiber_angle if fiber_angle is None else fiber_angle
    return spec.nominal_length / ew.cos(theta)


def turns(spec: MuscleSpec, fiber_angle: float | None = None) -> float:
    """Number of fibre turns n = L0 tan(Theta0) / (pi D0) [-] (eq. 3)."""
    theta = spec.fiber_angle if fiber_angle is None else fiber_angle
    return spec.nominal_length * ew.tan(theta) / (math.pi * spec.inner_diameter)


def braid_constants(spec: MuscleSpec, fiber_angle: float | None = None) -> BraidConstants:
    """What :func:`braid` needs of the muscle: L_Fiber^2 [m^2], n pi [-] and 4 pi n^2 [-] (eq. 3);
    Martens' prepared forms (:mod:`~pma_model_ros.core.physics.models`) compute them once per
    muscle.
    """
    lf, n = fiber_length(spec, fiber_angle), turns(spec, fiber_angle)
    return BraidConstants(lf**2, n * math.pi, 4 * math.pi * n**2)


def braid(spec: MuscleSpec, length: ArrayLike, fiber_angle: float | None = None) -> tuple:
    """Inner diameter D(L) = sqrt(L_Fiber^2 - L^2) / (n pi) [m] (eq. 2), its slope dD/dL [-], and
    the volume slope dV/dL = (L_Fiber^2 - 3 L^2) / (4 pi n^2) [m^2] (derivative of eq. 4), sharing
    one root.
    """
    lf_sq, n_pi, four_pi_n_sq = braid_constants(spec, fiber_angle)
    length = ew.asarray(length)
    length_sq = length**2
    root = ew.sqrt(lf_sq - length_sq)
    return root / n_pi, -length / (n_pi * root), (lf_sq - 3 * length_sq) / four_pi_n_sq


def diameter(spec: MuscleSpec, length: ArrayLike, fiber_angle: float | None = None) -> np.ndarray:
    """Inner diameter D(L) [m] (eq. 2); see :func:`braid`."""
    return braid(spec, length, fiber_angle)[0]


def volume(spec: MuscleSpec, length: ArrayLike, fiber_angle: float | None = None) -> np.ndarray:
    """Cylinder volume V(L) = (L L_Fiber^2 - L^3) / (4 pi n^2) [m^3] (eqs. 1 and 4)."""
    lf, n = fiber_length(spec, fiber_angle), turns(spec, fiber_angle)
    length = ew.asarray(length)
    return (length * lf**2 - length**3) / (4 * math.pi * n**2)


def volume_slope(
    spec: MuscleSpec, length: ArrayLike, fiber_angle: float | None = None
) -> np.ndarray:
    """dV/dL [m^2], derivative of eq. 4; see :func:`braid`."""
    return braid(spec, length, fiber_angle)[2]


def diameter_slope(
    spec: MuscleSpec, length: ArrayLike, fiber_angle: float | None = None
) -> np.ndarray:
    """dD/dL [-], derivative of eq. 2; see :func:`braid`."""
    return braid(spec, length, fiber_angle)[1]


def braid_pull(spec: MuscleSpec, length: ArrayLike) -> np.ndarray:
    """[m^2] F = p * this: the ideal braid's pull at ``length`` [m] (Chou and Hannaford), -dV/dL
    (eq. 4) = pi D^2/4 (3 cos^2 Theta - 1) / sin^2 Theta at the braid's diameter D(L) and angle
    Theta(L) (cos Theta = L / L_Fiber), scaled to the outer diameter by ((D0 + 2 H0) / D0)^2;
    <= 0 at and below full contraction (:func:`shortest_length`).  Measured maps pull up to
    about this much (Tables A1/A2: 1.03 / 1.00 of it at their rest-length rows).
    """
    outer = (spec.inner_diameter + 2 * spec.membrane_thickness) / spec.inner_diameter
    return -(outer**2) * volume_slope(spec, length)


def shortest_length(spec: MuscleSpec) -> float:
    """Shortest length of the ideal braid, L_Fiber / sqrt(3) [m]: there dV/dL = 0 (eq. 4), Theta =
    54.7 deg, and the muscle pulls no more at any pressure (its full contraction).
    """
    return fiber_length(spec) / math.sqrt(3)
