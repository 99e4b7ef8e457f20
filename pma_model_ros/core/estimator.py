"""Force estimation from sensor streams, independent of ROS messages.

One implementation of input validation, pairing of the newest pressure with
the newest length, freshness, counters and the diagnostic level, shared by the
model node and offline tools.  Every time is in seconds on one clock (ROS time
in the node, bag time offline); ``now`` is passed in, never read here.

An input that completes a fresh pair returns a :class:`Pair`; the force of a
pair is computed apart from the decisions (:meth:`Estimator.evaluate`, or one
vectorised call over many pairs of many muscles or of a whole recording) and
handed back to :meth:`Estimator.accept`, which makes the :class:`Estimate`.
The per-message records are NamedTuples: an offline pass makes millions of them.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
import enum
import math
from typing import NamedTuple, Sequence

from .flags import Flag, describe
from .muscle_model import MuscleModel

#: Absolute pressures above this [Pa] are sensor or unit errors (50 bar; muscles are rated <= 8 bar).
ABSURD_PRESSURE = 5e6
#: Flags that make an estimate or command WARN, with their diagnostic wording.
WARN_FLAGS = {
    Flag.SATURATED: "saturated",
    Flag.LENGTH_OUT_OF_RANGE: "outside validity domain",
    Flag.PRESSURE_OUT_OF_RANGE: "outside validity domain",
    Flag.BRANCH_UNKNOWN: "hysteresis branch unknown",
}
_WARN_BITS = tuple((int(flag), f"{text} ({flag.name})") for flag, text in WARN_FLAGS.items())
_WARN_MASK = sum(bit for bit, _ in _WARN_BITS)
_INVALID = int(Flag.INVALID_INPUT)


def joint_problem(names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                  joint: str) -> str:
    """Why a JointState's arrays give no length of ``joint`` ('' if they do)."""
    if not len(names) or not len(positions):
        return "empty name or position array"
    if len(positions) != len(names) or (len(velocities) and len(velocities) != len(names)):
        return (f"mismatched arrays: {len(names)} names, {len(positions)} positions, "
                f"{len(velocities)} velocities")
    if joint not in names:
        return f"joint '{joint}' not in {list(names)}"
    return ""


def pressure_problem(absolute: float) -> str:
    """Why an absolute pressure [Pa] is no reading ('' if it is one)."""
    if not math.isfinite(absolute):
        return f"pressure is {absolute} Pa"
    if absolute < 0:
        return f"negative absolute pressure {absolute:g} Pa"
    if absolute > ABSURD_PRESSURE:
        return f"absurd pressure {absolute:g} Pa (> {ABSURD_PRESSURE:g} Pa absolute)"
    return ""


def length_problem(length: float, limit: float) -> str:
    """Why a length [m] is no reading of a muscle whose geometry allows (0, ``limit``) m ('' if it is one)."""
    if math.isfinite(length) and 0 < length < limit:
        return ""
    return f"length {length:g} m outside the geometry (0, {limit:.4g}) m"


class Level(enum.IntEnum):
    """Diagnostic level; values equal diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class Config:
    """What the estimator needs besides the inputs; swapped whole at runtime."""

    model: MuscleModel
    ambient_pressure: float = 101325.0  #: [Pa] absolute; gauge = absolute - ambient
    max_input_age: float = 0.1          #: [s] inputs with |now - stamp| above this are stale

    def __post_init__(self) -> None:
        if not 0 <= self.ambient_pressure < ABSURD_PRESSURE:
            raise ValueError(f"ambient_pressure must be in [0, {ABSURD_PRESSURE:g}) Pa absolute, "
                             f"got {self.ambient_pressure:g}")
        if not 0 < self.max_input_age < math.inf:
            raise ValueError(f"max_input_age must be > 0 s, got {self.max_input_age:g}")


class Sample(NamedTuple):
    value: float           #: absolute pressure [Pa] or length [m]
    rate: float | None     #: length rate [m/s]; None if unknown
    stamp: float           #: [s]
    tag: object = None     #: the caller's own form of the stamp, handed back unchanged


class Pair(NamedTuple):
    """The newest valid pressure and length, both fresh: what one estimate is computed from."""

    gauge: float          #: gauge pressure [Pa]
    length: float         #: [m]
    rate: float | None    #: length rate [m/s]; None if unknown
    stamp: float          #: newest stamp of the two inputs [s]
    tag: object           #: ``tag`` of the newest input


class Estimate(NamedTuple):
    force: float   #: tension [N], finite and >= 0
    stamp: float   #: newest stamp of the two inputs [s]
    flags: int     #: :class:`Flag` word
    tag: object    #: ``tag`` of the newest input (e.g. its exact header stamp)


class Command(NamedTuple):
    pressure: float  #: absolute pressure [Pa] giving the wanted tension at the current length
    flags: int       #: :class:`Flag` word


@dataclass(frozen=True)
class Status:
    level: Level
    message: str
    values: dict[str, str]


class Estimator:
    """Pairs the newest valid pressure and length; estimates force and inverts commands.

    ``hold`` [s] is how long a rejected input (ERROR) or a warning flag (WARN)
    keeps the diagnostic level up after it was seen.
    """

    def __init__(self, config: Config, hold: float = 1.0) -> None:
        self.config = config
        self.hold = hold
        self.counts: Counter[str] = Counter()
        self._pressure: Sample | None = None
        self._length: Sample | None = None
        self._last_reject: tuple[float, str] | None = None
        self._warned: dict[str, float] = {}
        self._report: tuple[float, Counter[str]] | None = None
        self._reported_level: Level | None = None

    def pressure(self, absolute: float, stamp: float, now: float, tag: object = None) -> Pair | None:
        """A pressure reading [Pa absolute] stamped ``stamp`` [s]; the pair to estimate from, if any."""
        self.counts["received pressure"] += 1
        problem = pressure_problem(absolute)
        if problem:
            return self._invalid("pressure", problem, now)
        self._pressure = Sample(absolute, None, stamp, tag)
        return self._pair(now)

    def length(self, length: float, rate: float | None, stamp: float, now: float,
               tag: object = None) -> Pair | None:
        """A length reading [m] with its rate [m/s] (None or NaN: unknown); the pair to estimate from, if any."""
        self.counts["received muscle_state"] += 1
        problem = length_problem(length, self.config.model.max_length)
        if problem:
            return self._invalid("muscle_state", problem, now)
        known_rate = rate if rate is not None and math.isfinite(rate) else None
        self._length = Sample(length, known_rate, stamp, tag)
        return self._pair(now)

    def joint_state(self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                    joint: str, stamp: float, now: float, tag: object = None) -> Pair | None:
        """A JointState's arrays: the entry ``joint`` gives length [m] (position) and rate [m/s] (velocity)."""
        problem = joint_problem(names, positions, velocities, joint)
        if problem:
            self.reject("muscle_state", problem, now)
            return None
        i = list(names).index(joint)
        return self.length(positions[i], velocities[i] if len(velocities) else None, stamp, now, tag)

    def command(self, force: float, now: float) -> Command | None:
        """A wanted tension [N]; returns the pressure command, or None without a fresh length."""
        self.counts["received force_command"] += 1
        if not math.isfinite(force):
            return self._invalid("force_command", f"force command is {force} N", now)
        cfg, length = self.config, self._length
        if length is None or not self._fresh(length, now):
            self.counts["commands without fresh length"] += 1
            return None
        result = cfg.model.pressure(force, length.value, length.rate)
        flags = int(result.flags)
        self._note(flags, now)
        self.counts["pressure commands"] += 1
        return Command(float(result.pressure) + cfg.ambient_pressure, flags)

    def reject(self, source: str, reason: str, now: float) -> None:
        """Count a message of ``source`` (``pressure``, ``muscle_state`` or ``force_command``) refused before it gave a value."""
        self.counts[f"received {source}"] += 1
        self._invalid(source, reason, now)

    def level(self, now: float) -> tuple[Level, str]:
        """Current diagnostic level and its one-line reason."""
        if self._last_reject is not None and now - self._last_reject[0] < self.hold:
            return Level.ERROR, f"invalid input: {self._last_reject[1]}"
        for name, sample in (("pressure", self._pressure), ("muscle_state", self._length)):
            if sample is None:
                return Level.ERROR, f"no {name} received yet"
            if not self._fresh(sample, now):
                age = now - sample.stamp
                when = f"{age:.3g} s old" if age > 0 else f"{-age:.3g} s in the future"
                return Level.ERROR, (f"stale {name}: newest stamp is {when} "
                                     f"(max_input_age {self.config.max_input_age:g} s)")
        if self._warned:
            warnings = sorted({text for text, seen in self._warned.items() if now - seen < self.hold})
            if warnings:
                return Level.WARN, "; ".join(warnings)
        return Level.OK, "estimating"

    def status(self, now: float) -> Status:
        """Level, reason, counters and message rates [Hz] since the previous call."""
        level, message = self.level(now)
        values = {key: str(n) for key, n in sorted(self.counts.items())}
        if self._report is not None and now > self._report[0]:
            since, before = self._report
            for key in ("received pressure", "received muscle_state", "estimates"):
                values[f"{key} rate [Hz]"] = f"{(self.counts[key] - before[key]) / (now - since):.1f}"
        self._report = (now, Counter(self.counts))
        self._reported_level = level
        values["model"] = self.config.model.model.name
        return Status(level, message, values)

    def status_due(self, now: float) -> bool:
        """Whether the level differs from the last :meth:`status` (or there was none): report it on change."""
        return self.level(now)[0] != self._reported_level

    def _fresh(self, sample: Sample, now: float) -> bool:
        return abs(now - sample.stamp) <= self.config.max_input_age

    def _pair(self, now: float) -> Pair | None:
        cfg, pressure, length = self.config, self._pressure, self._length
        if pressure is None or length is None:
            return None
        age = self.config.max_input_age
        if not (abs(now - pressure.stamp) <= age and abs(now - length.stamp) <= age):   # both fresh
            self.counts["stale skipped"] += 1
            return None
        newest = length if length.stamp > pressure.stamp else pressure
        return Pair(pressure.value - cfg.ambient_pressure, length.value, length.rate, newest.stamp, newest.tag)

    def evaluate(self, pair: Pair) -> tuple[float, int]:
        """Force [N] and :class:`Flag` word of one pair (scalar; batch callers use the model directly)."""
        result = self.config.model.force(pair.gauge, pair.length, pair.rate)
        return float(result.force), int(result.flags)

    def accept(self, pair: Pair, force: float, flags: int, now: float) -> Estimate | None:
        """The estimate of ``pair`` from its evaluated force [N] and flags; None (and ERROR) if unusable."""
        if flags & _INVALID or not math.isfinite(force):
            return self._invalid("muscle_state", f"no force at length {pair.length:g} m ({describe(flags)})", now)
        self._note(flags, now)
        self.counts["estimates"] += 1
        return Estimate(force, pair.stamp, flags, pair.tag)

    def estimate(self, pair: Pair | None, now: float) -> Estimate | None:
        """:meth:`evaluate` then :meth:`accept` one pair (None passes through)."""
        return None if pair is None else self.accept(pair, *self.evaluate(pair), now)

    def _note(self, flags: int, now: float) -> None:
        if flags & _WARN_MASK:
            for bit, text in _WARN_BITS:
                if flags & bit:
                    self._warned[text] = now

    def _invalid(self, source: str, reason: str, now: float) -> None:
        self.counts[f"rejected {source}"] += 1
        self._last_reject = (now, reason)
        return None
