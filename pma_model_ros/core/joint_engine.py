"""joint_node's decisions (no ROS): torque and stiffness estimates and pressure commands of many
joints.

Per joint it keeps the newest angle (with both muscles at it, :meth:`~.joint.Joint.at`:
coefficients and length slopes computed once per new angle), each muscle's newest gauge pressure,
and each hysteresis muscle's branch: the play operator (:func:`~.hysteresis.play`, as model_node's
engine) on the muscle's length computed from the angle, or on its gauge pressure (the joint's
``follows``), so that velocity noise cannot flip it and a joint held still keeps it.  A
joint_states entry is answered with the joint's torque and stiffness if both pressures are fresh
(within ``max_input_age`` of ``now``).  A torque command is inverted at the newest angle, on the
kept branches, with the joint's co-contraction level or wanted stiffness.  All of it in plain
floats per message: numpy's per-call overhead would dominate one joint's arithmetic.  Every time is
in seconds on one clock (ROS time in the node); ``now`` is passed in.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

from .estimation import pressure_problem
from .flags import describe
from .health import Level, WARN_FLAGS
from .hysteresis import play
from .joint import COCONTRACTION_MODES, Joint, MuscleAt
from .muscle_model import served_pressure

COUNTERS = (
    'joint_states',
    'pressures',
    'torque commands',
    'rejected',
    'stale skipped',
    'estimates',
    'pressure commands',
)
_WARN_MASK = int(sum(WARN_FLAGS))


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
        self.theta, self.theta_stamp = math.nan, math.nan
        self.gauge, self.p_stamps = [math.nan, math.nan], [math.nan, math.nan]
        # play operator of each muscle (core.hysteresis): branch (+1, -1, 0) and anchor [m or Pa]
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
        self.level, self.mode, self.stiffness = (
            settings.cocontraction,
            settings.cocontraction_mode,
            None,
        )
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.problem, self.problem_time = '', -math.inf
        self.flags, self.flags_time = 0, -math.inf
        self.torque = self.stiffness_estimate = math.nan


class JointEngine:
    """Estimates and commands of ``joints`` (with their ``settings``); ``ambient`` [Pa absolute],
    ``max_age`` [s], ``hold`` [s]: how long a rejected input (ERROR) or a warning flag (WARN) keeps
    a joint's level up.
    """

    def __init__(
        self,
        joints: Sequence[Joint],
        settings: Sequence[Settings],
        ambient: float,
        max_age: float,
        hold: float = 1.0,
    ) -> None:
        self.joints, self.ambient, self.max_age, self.hold = tuple(joints), ambient, max_age, hold
        self.index = {j.name: k for k, j in enumerate(joints)}
        self.state = [_JointState(s, j) for s, j in zip(settings, self.joints)]

    def reject(self, k: int, problem: str, now: float) -> None:
        s = self.state[k]
        s.counts['rejected'] += 1
        s.problem, s.problem_time = problem, now

    def angle(self, k: int, theta: float, stamp: float, now: float) -> tuple[float, float] | None:
        """Joint ``k``'s angle [rad]; its (torque [N·m], stiffness [N·m/rad]) if both pressures
        are fresh.
        """
        s, joint = self.state[k], self.joints[k]
        s.counts['joint_states'] += 1
        if not math.isfinite(theta):
            return self.reject(k, f'angle is {theta} rad', now)
        lengths = joint.lengths(theta)
        for muscle, length, name in zip(joint.muscles, lengths, joint.muscle_names):
            if not 0 < length < muscle.max_length:
                return self.reject(
                    k,
                    f"angle {theta:g} rad puts muscle '{name}' at {length:.4g} m, outside its "
                    f'geometry (0, {muscle.max_length:.4g}) m',
                    now,
                )
        for m, deadband in s.by_length:
            s.branch[m], s.anchor[m] = play(s.branch[m], s.anchor[m], lengths[m], deadband)
        s.at, s.theta, s.theta_stamp = joint.at(theta, s.branch), theta, stamp
        if not (
            abs(now - stamp) <= self.max_age
            and abs(now - s.p_stamps[0]) <= self.max_age
            and abs(now - s.p_stamps[1]) <= self.max_age
        ):  # False for NaN: a pressure never received
            s.counts['stale skipped'] += 1
            return None
        m0, m1, r, r_slope = s.at
        p0, p1 = s.gauge
        s.torque, s.stiffness_estimate = joint.torque_stiffness(m0, m1, r, r_slope, p0, p1)
        flags = m0.flags | m1.flags
        for muscle, p in zip(joint.muscles, s.gauge):
            flags |= served_pressure(p, muscle.limits)[0]
        self._note(s, flags, now)
        s.counts['estimates'] += 1
        return s.torque, s.stiffness_estimate

    def pressure(self, k: int, muscle: int, absolute: float, stamp: float, now: float) -> None:
        """Muscle ``muscle`` (0: the one shortening for positive θ) of joint ``k``: a pressure [Pa
        absolute]; a branch following it changes for the next estimate and command.
        """
        s = self.state[k]
        s.counts['pressures'] += 1
        problem = pressure_problem(absolute)
        if problem:
            return self.reject(
                k, f"muscle '{self.joints[k].muscle_names[muscle]}': {problem}", now
            )
        gauge = absolute - self.ambient
        s.gauge[muscle], s.p_stamps[muscle] = gauge, stamp
        deadband = s.by_pressure[muscle]
        if deadband is not None:
            before = s.branch[muscle]
            s.branch[muscle], s.anchor[muscle] = play(before, s.anchor[muscle], gauge, deadband)
            if s.branch[muscle] != before and s.at is not None:  # the muscles at the new branch
                s.at = self.joints[k].at(s.theta, s.branch)

    def cocontraction(self, k: int, level: float, now: float) -> None:
        """Joint ``k``'s torque commands from now on: co-contraction ``level`` [Pa gauge] (its
        mode).
        """
        if not (math.isfinite(level) and level >= 0):
            return self.reject(k, f'co-contraction {level:g} Pa is no gauge pressure >= 0', now)
        self.state[k].level, self.state[k].stiffness = level, None

    def stiffness(self, k: int, stiffness: float, now: float) -> None:
        """Joint ``k``'s torque commands from now on: the wanted ``stiffness`` [N·m/rad]."""
        if not (math.isfinite(stiffness) and stiffness >= 0):
            return self.reject(k, f'stiffness {stiffness:g} N·m/rad is not >= 0', now)
        self.state[k].stiffness = stiffness

    def command(self, k: int, torque: float, now: float) -> tuple[float, float] | None:
        """A wanted ``torque`` [N·m] of joint ``k``: both muscles' pressure commands [Pa absolute],
        if any.
        """
        s = self.state[k]
        s.counts['torque commands'] += 1
        if not math.isfinite(torque):
            return self.reject(k, f'torque command is {torque} N·m', now)
        if s.at is None:
            return self.reject(k, 'torque command before any angle (joint_states)', now)
        if s.stiffness is not None:
            result = self.joints[k].pressures_at(s.at, torque, stiffness=s.stiffness)
        else:
            result = self.joints[k].pressures_at(s.at, torque, s.level, s.mode)
        self._note(s, result.flags, now)
        s.counts['pressure commands'] += 1
        return result.pressures[0] + self.ambient, result.pressures[1] + self.ambient

    def _note(self, s: _JointState, flags: int, now: float) -> None:
        if flags & _WARN_MASK:
            s.flags, s.flags_time = flags, now

    def status(self, k: int, now: float) -> tuple[Level, str, dict[str, str]]:
        """Joint ``k``'s level, reason and values: counters, newest estimate, how torque commands
        are made.
        """
        s = self.state[k]
        if now - s.problem_time <= self.hold:
            level, message = Level.ERROR, s.problem
        elif s.counts['joint_states'] and s.counts['estimates'] == 0:
            level, message = Level.ERROR, 'no estimate yet: pressures missing or stale'
        elif now - s.flags_time <= self.hold:
            texts = sorted(
                {f'{text} ({flag.name})' for flag, text in WARN_FLAGS.items() if s.flags & flag}
            )
            level, message = Level.WARN, '; '.join(texts)
        else:
            level, message = Level.OK, 'OK'
        values = {key: str(n) for key, n in s.counts.items() if n}
        values |= {
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
        return level, message, values
