"""A simulated antagonistic joint whose muscle forces are their measured force maps (no ROS).

Two muscles on a lever arm r(θ) (:class:`~pma_model_ros.core.physics.joint.Transmission`), muscle 0
shortening for positive θ; each muscle's tension is the ground truth of its shipped map
(:class:`~.muscle.GroundTruth`, a pchip of the measurement, pressures held to the measured
5..650 kPa for DMSP-10-250) and its gauge pressure follows the command with a first-order lag.  The
angle is either held (a test bench: it moves only when told, :meth:`SimulatedJoint.hold`) or driven
by a link, I θ'' = τ - c θ', stopped at the limits. None of the identified models is used: what
joint_node estimates is judged against data.
"""

from __future__ import annotations

from dataclasses import replace
import math
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .muscle import GroundTruth, PRESSURE_TIME_CONSTANT
from ..files.node_parameters import ParameterSpec, read_only, SPECS
from ..files.shipped_data import MAPPED_MUSCLES, shipped_force_map
from ..physics.joint import Transmission

MODES = ('held', 'link')
#: joint_simulator_node's parameters, read at start-up (read-only).
PARAMETERS: tuple[ParameterSpec, ...] = read_only(
    ParameterSpec('joint_name', 'string', 'elbow', 'JointState entry of the joint'),
    ParameterSpec(
        'muscles',
        'string[]',
        ['flexor', 'extensor'],
        "the two muscles' topic namespaces; the first shortens for positive θ",
    ),
    ParameterSpec(
        'maps',
        'string[]',
        ['DMSP-10-250', 'DMSP-10-250'],
        f"each muscle's measured map, the truth: {', '.join(MAPPED_MUSCLES)}",
    ),
    ParameterSpec('radius', 'double[]', [0.015], 'lever arm r(θ) = Σ radius[k] θ^k', 'm'),
    ParameterSpec(
        'length_at_zero', 'double[]', [0.234, 0.234], "each muscle's length at θ = 0", 'm'
    ),
    ParameterSpec('limits', 'double[]', [-1.0, 1.0], 'joint range: the link stops there', 'rad'),
    ParameterSpec(
        'mode',
        'string',
        'held',
        f"angle: {' or '.join(MODES)} (held: set by angle_command; link: I θ'' = τ - c θ')",
        choices=MODES,
    ),
    ParameterSpec('angle', 'double', 0.0, 'initial angle', 'rad', (-10.0, 10.0)),
    ParameterSpec(
        'inertia',
        'double',
        0.01,
        'link inertia about the joint axis; at least K_max / rate^2 (start-up checks it)',
        'kg m^2',
        (1e-6, 1e3),
    ),
    ParameterSpec('damping', 'double', 0.1, 'link viscous damping', 'N·m·s/rad', (0.0, 1e3)),
    ParameterSpec(
        'rate',
        'double',
        200.0,
        'publishing and integration rate (each step evaluates two pchip maps, about 0.9 ms)',
        'Hz',
        (1.0, 1000.0),
    ),
    replace(SPECS['ambient_pressure'], description='ambient pressure'),
    PRESSURE_TIME_CONSTANT,
)


class SimulatedJoint:
    """The simulated joint; ``params`` as :data:`PARAMETERS`, times in s, pressures gauge [Pa]
    inside.
    """

    def __init__(self, params: dict[str, object], start: float) -> None:
        if params['mode'] not in MODES:
            raise ValueError(f"parameter 'mode' must be one of {MODES}, got {params['mode']!r}")
        for name in ('muscles', 'maps', 'length_at_zero', 'limits'):
            if len(params[name]) != 2:
                raise ValueError(f"parameter '{name}' needs two entries, got {list(params[name])}")
        if not params['radius']:
            raise ValueError("parameter 'radius' needs at least one coefficient [m]")
        low, high = (float(x) for x in params['limits'])
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ValueError(
                "parameter 'limits' must be finite [min, max] rad with min < max, got "
                f'{list(params["limits"])}'
            )
        if not low <= params['angle'] <= high:
            raise ValueError(
                f"parameter 'angle' {params['angle']:g} rad is outside 'limits' "
                f'[{low:g}, {high:g}]'
            )
        self.truths = tuple(GroundTruth(shipped_force_map(str(m))) for m in params['maps'])
        self.transmission = Transmission(tuple(float(c) for c in params['radius']))
        angles = np.linspace(low, high, 1001)
        radius = self.transmission.radius(angles)
        if not np.all(radius > 0):
            i = int(np.argmin(radius))
            raise ValueError(
                f"parameter 'radius': lever arm r = {radius[i]:.4g} m at θ = {angles[i]:.4g} rad; "
                'it must be > 0 m over the limits'
            )
        self.params = params
        self._check_lengths(angles)
        if params['mode'] == 'link':
            self._check_stable(angles)
        self.angle, self.velocity = float(params['angle']), 0.0
        self.pressures = [0.0, 0.0]  # gauge [Pa]
        self._targets = [0.0, 0.0]
        self._last = start

    def _lengths(self, angle: ArrayLike) -> tuple:
        """Each muscle's length [m] at ``angle`` [rad] (the first shortens for positive θ)."""
        s = self.transmission.travel(angle)
        zero = self.params['length_at_zero']
        return zero[0] - s, zero[1] + s

    def _check_lengths(self, angles: np.ndarray) -> None:
        """Each muscle stays within its map's measured lengths over the limits: the truth is known
        only there (the map would hold a longer or shorter muscle at its edge, silently).
        """
        for name, truth, lengths in zip(
            self.params['muscles'], self.truths, self._lengths(angles)
        ):
            outside = (lengths < truth.lengths[0]) | (lengths > truth.lengths[-1])
            if outside.any():
                i = int(np.argmax(outside))
                raise ValueError(
                    f"parameter 'length_at_zero': muscle '{name}' is {lengths[i]:.4g} m at "
                    f"θ = {angles[i]:.4g} rad, outside its map's lengths "
                    f'[{truth.lengths[0]:g}, {truth.lengths[-1]:g}] m'
                )

    def _check_stable(self, angles: np.ndarray) -> None:
        """The link's explicit step in angle is stable and resolves its oscillation: ω dt ≤ 1 with
        ω² = K_max / I, K_max the stiffest point of the range with both muscles at their maps' top
        pressure, dt = 1 / rate.
        """
        torque = self.torque_at(angles, [t.pressures[-1] for t in self.truths])
        k_max = float(np.max(-np.gradient(torque, angles)))
        least = k_max / self.params['rate'] ** 2
        if self.params['inertia'] < least:
            raise ValueError(
                f"parameter 'inertia' {self.params['inertia']:g} kg m^2 is too small for 'rate' "
                f'{self.params["rate"]:g} Hz: the link (stiffness up to {k_max:.3g} N·m/rad) '
                f'needs at least {least:.3g} kg m^2 (ω dt ≤ 1), or a higher rate'
            )

    def command(self, k: int, absolute: float) -> None:
        """Muscle ``k``'s pressure command [Pa absolute]; non-finite values are ignored."""
        if math.isfinite(absolute):
            self._targets[k] = absolute - float(self.params['ambient_pressure'])

    def hold(self, angle: float) -> None:
        """Move the held joint to ``angle`` [rad] (kept within the limits; ignored by a link or if
        non-finite).
        """
        if self.params['mode'] == 'held' and math.isfinite(angle):
            low, high = self.params['limits']
            self.angle = min(max(angle, low), high)

    def torque_at(self, angle: ArrayLike, pressures: Sequence[float]) -> np.ndarray:
        """The torque [N·m] of the measured-map forces at ``angle`` [rad] (array or float) and the
        muscles' gauge ``pressures`` [Pa].
        """
        f0, f1 = (t.force(p, L) for t, p, L in zip(self.truths, pressures, self._lengths(angle)))
        return self.transmission.radius(angle) * (f0 - f1)

    def torque(self) -> float:
        """The joint torque [N·m] at the present angle and pressures."""
        return float(self.torque_at(self.angle, self.pressures))

    def step(self, now: float) -> float:
        """Advance to ``now`` [s]; the torque [N·m] there."""
        dt, self._last = max(now - self._last, 0.0), now
        tau = self.params['pressure_time_constant']
        share = 1.0 - math.exp(-dt / tau) if tau > 0 else 1.0
        for k in (0, 1):
            self.pressures[k] += (self._targets[k] - self.pressures[k]) * share
        torque = self.torque()
        if self.params['mode'] == 'link' and dt > 0:
            # Semi-implicit Euler, the damping implicit (stable for any c):
            # v' = (v + τ dt / I) / (1 + c dt / I), θ' = θ + v' dt.
            inertia = self.params['inertia']
            self.velocity = (self.velocity + torque * dt / inertia) / (
                1.0 + self.params['damping'] * dt / inertia
            )
            self.angle += self.velocity * dt
            low, high = self.params['limits']
            if not low <= self.angle <= high:
                self.angle, self.velocity = min(max(self.angle, low), high), 0.0
            torque = self.torque()
        return torque
