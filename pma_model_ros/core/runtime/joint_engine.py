"""joint_node's decisions (no ROS): torque and stiffness estimates and pressure commands of many
joints.

Per joint it keeps the newest angle (with both muscles at it,
:meth:`~pma_model_ros.core.physics.joint.Joint.at`: coefficients and length slopes computed once
per new angle), each muscle's newest gauge pressure, and each hysteresis muscle's branch: the play
operator (:func:`~pma_model_ros.core.physics.hysteresis.play`, as model_node's engine) on the
muscle's length computed from the angle, or on its gauge pressure (the joint's ``follows``), so
that velocity noise cannot flip it and a joint held still keeps it.  A joint_states entry is
answered with the joint's torque and stiffness if its angle and both pressures are fresh (within
``max_input_age`` of ``now``).  A torque command is inverted at the newest angle, on the kept
branches, with the joint's co-contraction level or wanted stiffness.  All of it in plain floats per
message: numpy's per-call overhead would dominate one joint's arithmetic.  Counters, levels, texts
and reports are model_node's (:mod:`.health`): both nodes report alike.  Times are integer
nanoseconds on one clock (ROS time in the node); ``now`` is passed in.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math
from typing import Sequence

import numpy as np

from .estimation import pressure_problem
from .health import Health, Level, Status, WARN_MASK
from .pairing import fresh, nanoseconds, NEVER, UNSTAMPED
from ..files.node_parameters import SPECS
from ..physics.flags import describe
from ..physics.hysteresis import play
from ..physics.joint import COCONTRACTION_MODES, Joint, MuscleAt
from ..physics.muscle_model import served_pressure


class Counter(enum.IntEnum):
    """The counters of each joint; labels in :data:`LABELS`."""

    RECEIVED_JOINT_STATES = 0
    RECEIVED_PRESSURE = 1
    RECEIVED_COMMAND = 2
    REJECTED_JOINT_STATES = 3
    REJECTED_PRESSURE = 4
    REJECTED_COMMAND = 5
    STALE = 6
    ESTIMATES = 7
    COMMANDS = 8
    STALE_COMMAND = 9


LABELS = (
    'received joint_states',
    'received pressure',
    'received command',
    'rejected joint_states',
    'rejected pressure',
    'rejected command',
    'stale skipped',
    'estimates',
    'pressure commands',
    'stale command',
)
#: Inputs by kind: (received counter, rejected counter).
SOURCES = {
    'joint_states': (Counter.RECEIVED_JOINT_STATES, Counter.REJECTED_JOINT_STATES),
    'pressure': (Counter.RECEIVED_PRESSURE, Counter.REJECTED_PRESSURE),
    'command': (Counter.RECEIVED_COMMAND, Counter.REJECTED_COMMAND),
}
ANGLE = 2  #: row of the angle's stamps in :attr:`JointEngine.stamps` (0, 1: the muscles')


@dataclass(frozen=True)
class Settings:
    """What a joint's commands use besides the joint: how torque commands pick the pair of
    pressures.
    """

    cocontraction: float  #: [Pa gauge] level until a command changes it
    cocontraction_mode: str  #: ``min`` (lower pressure) or ``sum`` (pressure sum)

    def __post_init__(self) -> None:
        if self.cocontraction_mode not in COCONTRACTION_MODES:
            raise ValueError(
                f'cocontraction_mode must be one of {COCONTRACTION_MODES}, '
                f'got {self.cocontraction_mode!r}'
            )
        if not (math.isfinite(self.cocontraction) and self.cocontraction >= 0):
            raise ValueError(
                f'cocontraction must be a gauge pressure >= 0 Pa, got {self.cocontraction!r}'
            )


class _JointState:
    """The newest inputs of one joint, and its muscles' hysteresis branches."""

    def __init__(self, settings: Settings, joint: Joint) -> None:
        self.at: tuple[MuscleAt, MuscleAt, float, float] | None = None
        self.theta = math.nan
        self.gauge = [math.nan, math.nan]
        # play operator of each muscle (core.physics.hysteresis): branch (+1, -1, 0) and anchor [m
        # or Pa]
        self.branch, self.anchor = [0.0, 0.0], [math.nan, math.nan]
        follows = [f if m.model.hysteresis else None for m, f in zip(joint.muscles, joint.follows)]
        #: (muscle, deadband [m]) of each muscle whose branch follows its length
        self.by_length = tuple(
            (k, f.deadband) for k, f in enumerate(follows) if f and f.input == 'length'
        )
        #: each muscle's deadband [Pa] if its branch follows its gauge pressure, else None
        self.by_pressure = tuple(
            f.deadband if f and f.input == 'pressure' else None for f in follows
        )
        self.level, self.mode = settings.cocontraction, settings.cocontraction_mode
        self.stiffness: float | None = None
        self.flags = 0  # of the last estimate or command with a warning
        self.torque = self.stiffness_estimate = math.nan


class JointEngine:
    """Estimates and commands of ``joints`` (with their ``settings``); ``ambient`` [Pa absolute],
    ``max_age`` [s], ``hold`` [s]: how long a rejected input (ERROR) or a warning flag (WARN) keeps
    a joint's level up; ``report_interval`` [s]: see :meth:`~.health.Health.due`;
    ``pressure_reference``: what pressure readings and commands hold, ``absolute`` or ``gauge``
    pressure.
    """

    def __init__(
        self,
        joints: Sequence[Joint],
        settings: Sequence[Settings],
        ambient: float,
        max_age: float,
        hold: float = 1.0,
        report_interval: float = 0.0,
        pressure_reference: str = SPECS['pressure_reference'].default,
    ) -> None:
        self.joints, self.ambient = tuple(joints), ambient
        self.max_age = nanoseconds(max_age)
        SPECS['pressure_reference'].check(pressure_reference)
        #: [Pa] what a pressure reading lacks of the absolute pressure: ambient for gauge readings
        self.reading_offset = ambient if pressure_reference == 'gauge' else 0.0
        self.index = {j.name: k for k, j in enumerate(joints)}
        self.state = [_JointState(s, j) for s, j in zip(settings, self.joints)]
        #: [ns] newest valid stamp of each joint's muscle pressures (rows 0, 1) and angle (ANGLE)
        self.stamps = np.full((3, len(self.joints)), NEVER, np.int64)
        self.health = Health(
            len(self.joints),
            [
                (f'{j.muscle_names[0]} pressure', f'{j.muscle_names[1]} pressure', 'joint_states')
                for j in self.joints
            ],
            LABELS,
            self.stamps,
            self.max_age,
            nanoseconds(hold),
            nanoseconds(report_interval),
        )

    def reject(self, k: int, source: str, problem: str, now: int) -> None:
        """Count a message of ``source`` (``joint_states``, ``pressure`` or ``command``) of joint
        ``k`` refused for ``problem``.
        """
        self.health.count(SOURCES[source][0], k)
        self._invalid(k, source, problem, now)

    def _invalid(self, k: int, source: str, problem: str, now: int) -> None:
        self.health.count(SOURCES[source][1], k)
        self.health.reject(k, problem, now)

    def joint_states(
        self, names: Sequence[str], positions: Sequence[float], stamp: int, now: int
    ) -> tuple[list[str], list[float], list[float]]:
        """A joint_states message: its entries of these joints, answered (names, torques [N·m],
        stiffnesses [N·m/rad]) where their pressures are fresh; mismatched arrays are rejected.
        """
        done, torques, stiffnesses = [], [], []
        if len(positions) != len(names):
            for k in {self.index[n] for n in names if n in self.index}:
                self.reject(
                    k, 'joint_states', f'{len(names)} names, {len(positions)} positions', now
                )
            return done, torques, stiffnesses
        for name, theta in zip(names, positions):
            k = self.index.get(name)
            if k is not None and (result := self.angle(k, theta, stamp, now)) is not None:
                done.append(name)
                torques.append(result[0])
                stiffnesses.append(result[1])
        return done, torques, stiffnesses

    def angle(self, k: int, theta: float, stamp: int, now: int) -> tuple[float, float] | None:
        """Joint ``k``'s angle [rad]; its (torque [N·m], stiffness [N·m/rad]) if it and both
        pressures are fresh.
        """
        s, joint, health = self.state[k], self.joints[k], self.health
        health.count(Counter.RECEIVED_JOINT_STATES, k)
        if not math.isfinite(theta):
            return self._invalid(k, 'joint_states', f'angle is {theta} rad', now)
        lengths = joint.lengths(theta)
        for muscle, length, name in zip(joint.muscles, lengths, joint.muscle_names):
            if not 0 < length < muscle.max_length:
                return self._invalid(
                    k,
                    'joint_states',
                    f"angle {theta:g} rad puts muscle '{name}' at {length:.4g} m, outside its "
                    f'geometry (0, {muscle.max_length:.4g}) m',
                    now,
                )
        for m, deadband in s.by_length:
            s.branch[m], s.anchor[m] = play(s.branch[m], s.anchor[m], lengths[m], deadband)
        s.at, s.theta = joint.at(theta, s.branch), theta
        stamps, max_age = self.stamps, self.max_age
        stamps[ANGLE, k] = stamp
        health.arrived(ANGLE, k, stamp, now)
        if not (
            fresh(stamp, now, max_age)
            and fresh(stamps.item(0, k), now, max_age)
            and fresh(stamps.item(1, k), now, max_age)
        ):  # (a pressure never received is NEVER: never fresh)
            health.count(Counter.STALE, k)
            return None
        m0, m1, r, r_slope = s.at
        p0, p1 = s.gauge
        s.torque, s.stiffness_estimate = joint.torque_stiffness(m0, m1, r, r_slope, p0, p1)
        flags = m0.flags | m1.flags
        for muscle, p in zip(joint.muscles, s.gauge):
            flags |= served_pressure(p, muscle.limits)[0]
        self._note(k, flags, now)
        health.count(Counter.ESTIMATES, k)
        return s.torque, s.stiffness_estimate

    def pressure(self, k: int, muscle: int, reading: float, stamp: int, now: int) -> None:
        """Muscle ``muscle`` (0: the one shortening for positive θ) of joint ``k``: a pressure
        reading [Pa, absolute or gauge by ``pressure_reference``]; a branch following it changes
        for the next estimate and command.
        """
        s = self.state[k]
        self.health.count(Counter.RECEIVED_PRESSURE, k)
        absolute = reading + self.reading_offset
        problem = pressure_problem(absolute)
        if problem:
            name = self.joints[k].muscle_names[muscle]
            return self._invalid(k, 'pressure', f"muscle '{name}': {problem}", now)
        gauge = absolute - self.ambient
        s.gauge[muscle] = gauge
        self.stamps[muscle, k] = stamp
        self.health.arrived(muscle, k, stamp, now)
        deadband = s.by_pressure[muscle]
        if deadband is not None:
            before = s.branch[muscle]
            s.branch[muscle], s.anchor[muscle] = play(before, s.anchor[muscle], gauge, deadband)
            if s.branch[muscle] != before and s.at is not None:  # the muscles at the new branch
                s.at = self.joints[k].at(s.theta, s.branch)

    def cocontraction(self, k: int, level: float, now: int, stamp: int = UNSTAMPED) -> None:
        """Joint ``k``'s torque commands from now on: co-contraction ``level`` [Pa gauge] (its
        mode); a ``cocontraction_command`` stamped ``stamp`` [ns] (see :meth:`command`).
        """
        self.health.count(Counter.RECEIVED_COMMAND, k)
        if not (math.isfinite(level) and level >= 0):
            return self._invalid(
                k, 'command', f'co-contraction {level:g} Pa is no gauge pressure >= 0', now
            )
        if self.health.stale_command(
            k, 'cocontraction_command', stamp, now, Counter.STALE_COMMAND
        ):
            return None
        self.state[k].level, self.state[k].stiffness = level, None

    def stiffness(self, k: int, stiffness: float, now: int, stamp: int = UNSTAMPED) -> None:
        """Joint ``k``'s torque commands from now on: the wanted ``stiffness`` [N·m/rad]; a
        ``stiffness_command`` stamped ``stamp`` [ns] (see :meth:`command`).
        """
        self.health.count(Counter.RECEIVED_COMMAND, k)
        if not (math.isfinite(stiffness) and stiffness >= 0):
            return self._invalid(k, 'command', f'stiffness {stiffness:g} N·m/rad is not >= 0', now)
        if self.health.stale_command(k, 'stiffness_command', stamp, now, Counter.STALE_COMMAND):
            return None
        self.state[k].stiffness = stiffness

    def command(
        self, k: int, torque: float, now: int, stamp: int = UNSTAMPED
    ) -> tuple[float, float] | None:
        """A wanted ``torque`` [N·m] of joint ``k`` stamped ``stamp`` [ns]: both muscles' pressure
        commands [Pa, absolute or gauge by ``pressure_reference``], if any: none for a stamp older
        or newer than ``max_age`` (0, unstamped: taken as ``now``;
        :meth:`~.health.Health.stale_command`).
        """
        s = self.state[k]
        self.health.count(Counter.RECEIVED_COMMAND, k)
        if not math.isfinite(torque):
            return self._invalid(k, 'command', f'torque command is {torque} N·m', now)
        if self.health.stale_command(k, 'torque_command', stamp, now, Counter.STALE_COMMAND):
            return None
        if s.at is None:
            return self._invalid(
                k, 'command', 'torque command before any angle (joint_states)', now
            )
        if s.stiffness is not None:
            result = self.joints[k].pressures_at(s.at, torque, stiffness=s.stiffness)
        else:
            result = self.joints[k].pressures_at(s.at, torque, s.level, s.mode)
        self._note(k, result.flags, now)
        self.health.count(Counter.COMMANDS, k)
        offset = self.ambient - self.reading_offset  # gauge + offset: the command's reference
        return result.pressures[0] + offset, result.pressures[1] + offset

    def _note(self, k: int, flags: int, now: int) -> None:
        self.health.warn_one(k, flags, now)
        if flags & WARN_MASK:
            self.state[k].flags = flags

    def level(self, k: int, now: int) -> tuple[Level, str]:
        return self.health.level(k, now)

    def status_due(self, now: int) -> bool:
        return self.health.due(now)

    def statuses(self, now: int) -> list[Status]:
        """Every joint's status: level, reason, counters, input rates and stamp ages, then the
        newest estimate, the flags of the last warning and how torque commands are made.
        """
        return self.health.report(now, self._values)

    def _values(self, k: int) -> dict[str, str]:
        s = self.state[k]
        return {
            'torque [N·m]': f'{s.torque:.6g}',
            'stiffness [N·m/rad]': f'{s.stiffness_estimate:.6g}',
            'angle [rad]': f'{s.theta:.6g}',
            'last warning flags': describe(s.flags),
            'commands': (
                f'stiffness {s.stiffness:g} N·m/rad'
                if s.stiffness is not None
                else f'co-contraction {s.mode} {s.level:g} Pa'
            ),
        }

    def counts(self, k: int) -> dict[str, int]:
        """Joint ``k``'s non-zero counters by label."""
        return {label: n for label, n in zip(LABELS, self.health.counts(k)) if n}
