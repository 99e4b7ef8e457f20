"""The estimation engine: force estimates and pressure commands of N muscles from sensor streams
(no ROS).

The state of every muscle is held in arrays (newest valid pressure and length with their stamps,
the length-dependent force coefficients, counters, diagnostic holds), and every decision is made
here, once: input validation, pairing of the newest valid pressure with the newest valid length,
freshness, flags, diagnostic levels and their on-change report, command inversion.  ``model_node``
(both input modes) and ``pma-model bag estimate`` drive it.  Every time is in seconds on one clock
(ROS time in the node, log time offline); ``now`` is passed in, never read here.

Two entry forms share that state:

* one input of one muscle (:meth:`Engine.pressure`, :meth:`Engine.length`,
  :meth:`Engine.joint_state`): plain float arithmetic, because numpy's per-call overhead would cost
  more than the arithmetic.  The force coefficients are computed once per new length
  (:meth:`~.muscle_model.Evaluator.operating_one`) and each pressure then costs a few
  multiplications;
* one input of every muscle (:meth:`Engine.pressures`, :meth:`Engine.lengths`: a combined
  JointState): one vectorised evaluation over all muscles
  (:meth:`~.muscle_bank.MuscleBank.operating` and
  :func:`~.muscle_model.force_at`).

Both forms give the same decisions and forces (``test/test_core_engine.py`` feeds one stream both
ways).

Pairing (``pairing``): ``every_input`` (the default) answers every valid input with the newest
valid pressure and length; ``approximate_time`` answers once per pair of a new pressure and a new
length whose stamps lie within ``slop`` seconds (message_filters' ApproximateTime for two inputs):
of a pair further apart, the older input is dropped and counted ``unpaired``.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math
from typing import Sequence

import numpy as np

from .flags import describe, Flag
from .hysteresis import Follow, play
from .muscle_bank import MuscleBank
from .muscle_model import force_at, MuscleModel, Operating, served_pressure
from .node_parameters import DEFAULT_FOLLOW, SPECS

#: Absolute pressures above this [Pa] are sensor or unit errors (50 bar; muscles are rated <= 8
#: bar).
ABSURD_PRESSURE = 5e6
#: [s] Shortest time between two on-change status reports of model_node (and of its offline twin),
#: per muscle reported: building and publishing a status of 64 muscles took about 3 ms under
#: cProfile, so on-change reports stay a few percent of a core however many muscles flap (N = 64:
#: at most one every 0.1 s).
REPORT_INTERVAL_PER_MUSCLE = 0.0015
#: Flags that make an estimate or command WARN, with their diagnostic wording.
WARN_FLAGS = {
    Flag.SATURATED: 'saturated',
    Flag.LENGTH_OUT_OF_RANGE: 'outside validity domain',
    Flag.PRESSURE_OUT_OF_RANGE: 'outside validity domain',
    Flag.BRANCH_UNKNOWN: 'hysteresis branch unknown',
    Flag.EXTRAPOLATED: 'extrapolated beyond the identified data',
    Flag.BELOW_AMBIENT: (
        'pressure far below ambient: a gauge sensor read as absolute? (pressure_reference)'
    ),
}
_WARN_TEXTS = tuple(f'{text} ({flag.name})' for flag, text in WARN_FLAGS.items())
_WARN_BIT_LIST = tuple(int(flag) for flag in WARN_FLAGS)
_WARN_BITS = np.array(_WARN_BIT_LIST, np.uint16)
_WARN_MASK = int(sum(WARN_FLAGS))
_INVALID, _CLIPPED = int(Flag.INVALID_INPUT), int(Flag.CLIPPED)
#: Counters of each muscle, in the order of the engine's count array.
COUNTERS = (
    'received pressure',
    'received muscle_state',
    'received force_command',
    'rejected pressure',
    'rejected muscle_state',
    'rejected force_command',
    'stale skipped',
    'unpaired',
    'estimates',
    'pressure commands',
    'commands without fresh length',
)
_RECEIVED = {'pressure': 0, 'muscle_state': 1, 'force_command': 2}
_REJECTED = {'pressure': 3, 'muscle_state': 4, 'force_command': 5}
_STALE, _UNPAIRED, _ESTIMATES, _COMMANDS, _NO_LENGTH = 6, 7, 8, 9, 10
#: Counters whose rates [Hz] a status reports.
_RATES = (('received pressure', 0), ('received muscle_state', 1), ('estimates', _ESTIMATES))


def seconds(stamp) -> float:
    """A header stamp (``builtin_interfaces/Time``: ``sec``, ``nanosec``, of rclpy or rosbags) in
    seconds.
    """
    return stamp.sec + stamp.nanosec * 1e-9


def joint_problem(
    names: Sequence[str], positions: Sequence[float], velocities: Sequence[float], joint: str
) -> str:
    """Why a JointState's arrays give no length of ``joint`` ('' if they do)."""
    if not len(names) or not len(positions):
        return 'empty name or position array'
    if len(positions) != len(names) or (len(velocities) and len(velocities) != len(names)):
        return (
            f'mismatched arrays: {len(names)} names, {len(positions)} positions, '
            f'{len(velocities)} velocities'
        )
    if joint not in names:
        return f"joint '{joint}' not in {list(names)}"
    return ''


def pressure_problem(absolute: float) -> str:
    """Why an absolute pressure [Pa] is no reading ('' if it is one)."""
    if not math.isfinite(absolute):
        return f'pressure is {absolute} Pa'
    if absolute < 0:
        return f'negative absolute pressure {absolute:g} Pa'
    if absolute > ABSURD_PRESSURE:
        return f'absurd pressure {absolute:g} Pa (> {ABSURD_PRESSURE:g} Pa absolute)'
    return ''


def length_problem(length: float, limit: float) -> str:
    """Why a length [m] is no reading of a muscle whose geometry allows (0, ``limit``) m ('' if it
    is one).
    """
    if math.isfinite(length) and 0 < length < limit:
        return ''
    return f'length {length:g} m outside the geometry (0, {limit:.4g}) m'


class Level(enum.IntEnum):
    """Diagnostic level; values equal diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class Config:
    """One muscle's identified model and the node settings the engine needs; swapped whole at
    runtime.
    """

    model: MuscleModel
    #: [Pa] absolute; gauge = absolute - ambient
    ambient_pressure: float = SPECS['ambient_pressure'].default
    #: [s] inputs with |now - stamp| above this are stale
    max_input_age: float = SPECS['max_input_age'].default
    #: what pressure readings and commands hold
    pressure_reference: str = SPECS['pressure_reference'].default
    #: what a hysteresis model's branch follows, with the play operator's deadband
    follow: Follow = DEFAULT_FOLLOW

    def __post_init__(self) -> None:
        SPECS['ambient_pressure'].check(self.ambient_pressure)
        SPECS['max_input_age'].check(self.max_input_age)
        SPECS['pressure_reference'].check(self.pressure_reference)
        SPECS['hysteresis.input'].check(self.follow.input)
        SPECS[f'hysteresis.{self.follow.input}_deadband'].check(self.follow.deadband)

    @property
    def reading_offset(self) -> float:
        """What to add to a pressure reading [Pa] for the absolute pressure: 0, or ambient for
        gauge readings.
        """
        return self.ambient_pressure if self.pressure_reference == 'gauge' else 0.0


@dataclass(frozen=True)
class Status:
    level: Level
    message: str
    values: dict[str, str]


class Engine:
    """Force estimates and pressure commands of the muscles of ``configs`` (indices 0..N-1).

    ``hold`` [s] is how long a rejected input (ERROR) or a warning flag (WARN) keeps a muscle's
    diagnostic level up after it was seen.  After an input that gave an estimate, ``stamp``,
    ``tag`` and ``flags`` describe it (one muscle); after a vector call, ``forces``, ``flags``
    and ``estimated`` hold every muscle's.
    """

    def __init__(
        self,
        configs: Sequence[Config],
        hold: float = 1.0,
        pairing: str = 'every_input',
        slop: float = 0.0,
        report_interval: float = 0.0,
    ) -> None:
        SPECS['pairing'].check(pairing)
        SPECS['pairing_slop'].check(slop)
        n = len(configs)
        self.hold, self.approximate, self.slop = hold, pairing == 'approximate_time', slop
        self._pressure, self._p_stamp = (
            np.full(n, math.nan),
            np.full(n, math.nan),
        )  # absolute [Pa], [s]
        self._length, self._rate, self._l_stamp = (
            np.full(n, math.nan),
            np.full(n, math.nan),
            np.full(n, math.nan),
        )
        self._branch, self._anchor = (
            np.zeros(n),
            np.full(n, math.nan),
        )  # hysteresis play operator (core.hysteresis)
        self._p_tag, self._l_tag = np.full(n, None, object), np.full(n, None, object)
        self._p_new, self._l_new = (
            np.zeros(n, bool),
            np.zeros(n, bool),
        )  # not yet paired (approximate_time)
        self._counts = np.zeros((n, len(COUNTERS)), np.int64)
        self._reject_time, self._reject_reason = np.full(n, -math.inf), [''] * n
        self._warned = np.full(
            (n, len(_WARN_TEXTS)), -math.inf
        )  # when each warning was last seen [s]
        self._report_time, self._report_counts = np.full(n, math.nan), np.zeros_like(self._counts)
        self._reported = np.full(n, -1, np.int64)  # level of the last status (-1: none)
        self.stamp, self.tag, self.flags = math.nan, None, 0
        self.forces, self.estimated = np.zeros(n), np.zeros(n, bool)
        self._everyone, self._unknown_rates = np.ones(n, bool), np.full(n, math.nan)
        self._steady, self._calm = (
            False,
            None,
        )  # every level reported OK; time of an input that changed none
        self.report_interval, self._last_report = report_interval, -math.inf
        self.configure(configs)

    def __len__(self) -> int:
        return len(self.configs)

    def configure(self, configs: Sequence[Config]) -> None:
        """Use ``configs`` (one per muscle, as many as before) from now on; the inputs received are
        kept.
        """
        if not configs or (hasattr(self, 'configs') and len(configs) != len(self.configs)):
            raise ValueError('configure needs one config per muscle')
        bank = MuscleBank([c.model for c in configs])
        self._ambient = np.array([c.ambient_pressure for c in configs])
        self._offset = np.array(
            [c.reading_offset for c in configs]
        )  # reading + offset = absolute [Pa]
        self._offsets = bool(self._offset.any())
        hysteresis = np.array([c.model.model.hysteresis for c in configs])
        by_pressure = np.array([c.follow.input == 'pressure' for c in configs])
        self._follow_length, self._follow_pressure = (
            hysteresis & ~by_pressure,
            hysteresis & by_pressure,
        )
        self._deadband = np.array([c.follow.deadband for c in configs])
        self._any_length, self._any_pressure = (
            bool(self._follow_length.any()),
            bool(self._follow_pressure.any()),
        )
        self._age = np.array([c.max_input_age for c in configs])
        op = bank.operating(
            self._length, self._branch
        )  # a length the new geometry cannot take: INVALID_INPUT
        self._lflags, self._q = op.flags.astype(np.uint16), np.array([op.q2, op.q1, op.q0], float)
        self.bank, self.configs = bank, tuple(configs)  # last: the scalar path reads these

    # --- one input of one muscle
    # --------------------------------------------------------------------------

    def pressure(
        self, k: int, reading: float, stamp: float, now: float, tag: object = None
    ) -> float | None:
        """A pressure reading [Pa, absolute or gauge by the config's ``pressure_reference``] of
        muscle ``k`` stamped ``stamp`` [s]; its force estimate [N], if any.
        """
        self._counts[k, 0] += 1
        self._calm = None
        absolute = reading + self._offset.item(k)
        if not 0 <= absolute <= ABSURD_PRESSURE:  # NaN too
            return self._invalid(k, 'pressure', pressure_problem(absolute), now)
        self._pressure[k], self._p_stamp[k], self._p_tag[k], self._p_new[k] = (
            absolute,
            stamp,
            tag,
            True,
        )
        if self._any_pressure and self._follow_pressure[k]:
            self._play(k, absolute - self._ambient.item(k))
        return self._estimate(k, now)

    def _play(self, k: int, value: float) -> float:
        """Muscle ``k``'s hysteresis branch after its followed signal reads ``value``; a change of
        branch recomputes the coefficients at the length held.
        """
        before = self._branch.item(k)
        branch, self._anchor[k] = play(before, self._anchor.item(k), value, self._deadband.item(k))
        self._branch[k] = branch
        length = self._length.item(k)
        if branch != before and length == length and self._follow_pressure[k]:
            flags, q2, q1, q0 = self.configs[k].model.operating_one(length, branch)
            self._lflags[k], self._q[0, k], self._q[1, k], self._q[2, k] = flags, q2, q1, q0
        return branch

    def length(
        self,
        k: int,
        length: float,
        rate: float | None,
        stamp: float,
        now: float,
        tag: object = None,
    ) -> float | None:
        """A length [m] of muscle ``k`` with its rate [m/s] (None or NaN: unknown, kept for
        :meth:`inputs`; the hysteresis branch follows the play operator, not the rate); its force
        estimate [N], if any.
        """
        self._counts[k, 1] += 1
        self._calm = None
        model = self.configs[k].model
        if not 0 < length < model.max_length:  # NaN too
            return self._invalid(k, 'muscle_state', length_problem(length, model.max_length), now)
        rate = rate if rate is not None and math.isfinite(rate) else math.nan
        branch = (
            self._play(k, length)
            if self._any_length and self._follow_length[k]
            else self._branch.item(k)
        )
        flags, q2, q1, q0 = model.operating_one(length, branch)
        self._length[k], self._rate[k], self._l_stamp[k], self._l_tag[k], self._l_new[k] = (
            length,
            rate,
            stamp,
            tag,
            True,
        )
        self._lflags[k], self._q[0, k], self._q[1, k], self._q[2, k] = flags, q2, q1, q0
        return self._estimate(k, now)

    def joint_state(
        self,
        k: int,
        names: Sequence[str],
        positions: Sequence[float],
        velocities: Sequence[float],
        joint: str,
        stamp: float,
        now: float,
        tag: object = None,
    ) -> float | None:
        """A JointState's arrays: the entry ``joint`` gives muscle ``k``'s length [m] and rate
        [m/s].
        """
        if len(names) == 1 and len(positions) == 1 and len(velocities) <= 1 and names[0] == joint:
            i = 0  # the usual one-muscle message, checked without building the problem text
        else:
            problem = joint_problem(names, positions, velocities, joint)
            if problem:
                return self.reject(k, 'muscle_state', problem, now)
            i = names.index(joint)
        return self.length(
            k,
            float(positions[i]),
            float(velocities[i]) if len(velocities) else None,
            stamp,
            now,
            tag,
        )

    def _estimate(self, k: int, now: float) -> float | None:
        p_stamp, l_stamp = self._p_stamp.item(k), self._l_stamp.item(k)
        if p_stamp != p_stamp or l_stamp != l_stamp:  # an input never received
            return None
        if self.approximate:
            if not (self._p_new[k] and self._l_new[k]):
                return None
            if abs(p_stamp - l_stamp) > self.slop:  # the older one can no longer be paired
                self._counts[k, _UNPAIRED] += 1
                (self._p_new if p_stamp < l_stamp else self._l_new)[k] = False
                return None
            self._p_new[k] = self._l_new[k] = False
        age = self._age.item(k)
        if not (abs(now - p_stamp) <= age and abs(now - l_stamp) <= age):
            self._counts[k, _STALE] += 1
            return None
        gauge = self._pressure.item(k) - self._ambient.item(k)
        limits = self.configs[k].model.limits
        pressure_flags, gauge = served_pressure(gauge, limits)
        flags = int(self._lflags[k]) | pressure_flags
        q = self._q
        raw = (q.item(0, k) * gauge + q.item(1, k)) * gauge + q.item(2, k)
        if flags & _INVALID or not raw < math.inf:  # NaN or inf: the model gives no force here
            return self._invalid(
                k,
                'muscle_state',
                f'no force at length {self._length.item(k):g} m ({describe(flags)})',
                now,
            )
        if raw < 0:
            flags |= _CLIPPED
            raw = 0.0
        if flags & _WARN_MASK:
            self._note(k, flags, now)
        self._counts[k, _ESTIMATES] += 1
        self.flags = flags
        if l_stamp > p_stamp:
            self.stamp, self.tag = l_stamp, self._l_tag[k]
        else:
            self.stamp, self.tag = p_stamp, self._p_tag[k]
        return raw

    def command(self, k: int, force: float, now: float) -> float | None:
        """A wanted tension [N] of muscle ``k``; the pressure [Pa, absolute or gauge as the
        readings] giving it, or None without a fresh length.

        ``flags`` then holds the command's flags.
        """
        self._counts[k, 2] += 1
        if not math.isfinite(force):
            return self._invalid(k, 'force_command', f'force command is {force} N', now)
        l_stamp = self._l_stamp.item(k)
        if not abs(now - l_stamp) <= self._age.item(k):  # never received (NaN) or stale
            self._counts[k, _NO_LENGTH] += 1
            return None
        result = self.configs[k].model.pressure(force, self._length.item(k), self._branch.item(k))
        self.flags = int(result.flags)
        if self.flags & _WARN_MASK:
            self._note(k, self.flags, now)
        self._counts[k, _COMMANDS] += 1
        return float(result.pressure) + self._ambient.item(k) - self._offset.item(k)

    def reject(self, k: int, source: str, reason: str, now: float) -> None:
        """Count a message of ``source`` (``pressure``, ``muscle_state`` or ``force_command``)
        refused before it gave a value of muscle ``k``.
        """
        self._counts[k, _RECEIVED[source]] += 1
        return self._invalid(k, source, reason, now)

    def _invalid(self, k: int, source: str, reason: str, now: float) -> None:
        self._counts[k, _REJECTED[source]] += 1
        self._calm = None
        self._reject_time[k], self._reject_reason[k] = now, reason
        return None

    def _note(self, k: int, flags: int, now: float) -> None:
        self._calm = None
        for j, bit in enumerate(_WARN_BIT_LIST):
            if flags & bit:
                self._warned[k, j] = now

    # --- one input of every muscle
    # ------------------------------------------------------------------------

    def pressures(
        self,
        readings: np.ndarray,
        stamp: float,
        now: float,
        tag: object = None,
        present: np.ndarray | None = None,
    ) -> np.ndarray:
        """One pressure reading [Pa] of every muscle (of those ``present``; see :meth:`pressure`),
        all stamped ``stamp`` [s].

        Returns which muscles got an estimate (their forces in ``forces``, flags in ``flags``).
        Muscles not ``present`` are left alone (the caller rejects them with its reason).
        """
        absolute = (
            np.asarray(readings, float) + self._offset
            if self._offsets
            else np.asarray(readings, float)
        )
        received = self._everyone if present is None else present
        self._counts[:, 0] += received
        valid = self._received(
            received,
            (absolute >= 0) & (absolute <= ABSURD_PRESSURE),
            'pressure',
            lambda k: pressure_problem(absolute[k]),
            now,
        )
        store = slice(None) if valid is self._everyone else valid
        self._pressure[store], self._p_stamp[store], self._p_tag[store], self._p_new[store] = (
            absolute[store],
            stamp,
            tag,
            True,
        )
        if self._any_pressure:
            before = self._branch
            self._branch, self._anchor = play(
                before,
                self._anchor,
                np.where(valid & self._follow_pressure, absolute - self._ambient, math.nan),
                self._deadband,
            )
            changed = (self._branch != before) & ~np.isnan(self._length)
            if changed.any():
                op = self.bank.operating(self._length, self._branch)
                self._lflags[changed] = op.flags[changed]
                self._q[:, changed] = np.array([op.q2, op.q1, op.q0])[:, changed]
        return self._estimates(valid, now)

    def lengths(
        self,
        lengths: np.ndarray,
        rates: np.ndarray | None,
        stamp: float,
        now: float,
        tag: object = None,
        present: np.ndarray | None = None,
    ) -> np.ndarray:
        """One length [m] and rate [m/s] (None or NaN: unknown) of every muscle (of those
        ``present``); see
        :meth:`pressures`.
        """
        lengths = np.asarray(lengths, float)
        rates = (
            self._unknown_rates if rates is None else np.where(np.isfinite(rates), rates, math.nan)
        )
        received = self._everyone if present is None else present
        self._counts[:, 1] += received
        limits = self.bank.max_length
        valid = self._received(
            received,
            (lengths > 0) & (lengths < limits),
            'muscle_state',
            lambda k: length_problem(lengths[k], limits[k]),
            now,
        )
        if self._any_length:
            self._branch, self._anchor = play(
                self._branch,
                self._anchor,
                np.where(valid & self._follow_length, lengths, math.nan),
                self._deadband,
            )
        op = self.bank.operating(lengths, self._branch)
        store = slice(None) if valid is self._everyone else valid
        (
            self._length[store],
            self._rate[store],
            self._l_stamp[store],
            self._l_tag[store],
            self._l_new[store],
        ) = lengths[store], rates[store], stamp, tag, True
        self._lflags[store] = op.flags[store]
        self._q[0, store], self._q[1, store], self._q[2, store] = (
            op.q2[store],
            op.q1[store],
            op.q0[store],
        )
        return self._estimates(valid, now)

    def _received(
        self, received: np.ndarray, good: np.ndarray, source: str, problem, now: float
    ) -> np.ndarray:
        """Which received values are ``good`` (``self._everyone`` if all are); each other one
        rejected with ``problem(k)``.
        """
        if received is self._everyone and good.all():
            return self._everyone
        valid = received & good
        for k in np.flatnonzero(received & ~valid).tolist():
            self._invalid(k, source, problem(k), now)
        return valid

    def _estimates(self, candidates: np.ndarray, now: float) -> np.ndarray:
        p_stamp, l_stamp = self._p_stamp, self._l_stamp
        pairs = candidates & ~np.isnan(p_stamp + l_stamp)  # both inputs received
        if self.approximate:
            pairs &= self._p_new & self._l_new
            apart = pairs & ~(np.abs(p_stamp - l_stamp) <= self.slop)
            self._counts[:, _UNPAIRED] += apart
            older_p = apart & (p_stamp < l_stamp)
            self._p_new[older_p] = False
            self._l_new[apart & ~older_p] = False
            pairs &= ~apart
            self._p_new[pairs] = self._l_new[pairs] = False
        fresh = np.maximum(np.abs(now - p_stamp), np.abs(now - l_stamp)) <= self._age
        fresh_all = fresh.all()
        if not fresh_all:
            self._counts[:, _STALE] += pairs & ~fresh
            pairs &= fresh
        usable = pairs & ((self._lflags & _INVALID) == 0)
        q2, q1, q0 = self._q
        result = force_at(
            Operating(usable, self._lflags, q2, q1, q0, self.bank.limits),
            self._pressure - self._ambient,
        )
        ok = usable & (result.raw < math.inf)
        if (ok != pairs).any():
            for k in np.flatnonzero(pairs & ~ok).tolist():
                self._invalid(
                    k,
                    'muscle_state',
                    f'no force at length {self._length[k]:g} m ({describe(int(result.flags[k]))})',
                    now,
                )
        warned_any = (result.flags & _WARN_MASK).any()
        if warned_any:
            self._warned[ok[:, None] & ((result.flags[:, None] & _WARN_BITS) != 0)] = now
        self._counts[:, _ESTIMATES] += ok
        self.forces, self.flags, self.estimated = result.force, result.flags, ok
        # every muscle fresh and estimated without a warning: no level can have risen (see
        # status_due)
        self._calm = (
            now
            if candidates is self._everyone and ok.all() and fresh_all and not warned_any
            else None
        )
        return ok

    def inputs(self, k: int) -> tuple[float, float, float]:
        """Muscle ``k``'s newest valid gauge pressure [Pa], length [m] and length rate [m/s] (NaN:
        none).
        """
        return (
            self._pressure.item(k) - self._ambient.item(k),
            self._length.item(k),
            self._rate.item(k),
        )

    def newest_tag(self, muscles: np.ndarray) -> object:
        """The ``tag`` of the newest input stamp among ``muscles`` (a non-empty mask): the stamp of
        their answer.
        """
        p_stamp, l_stamp = (
            np.where(muscles, self._p_stamp, -math.inf),
            np.where(muscles, self._l_stamp, -math.inf),
        )
        k = int(np.argmax(np.maximum(p_stamp, l_stamp)))
        return self._l_tag[k] if l_stamp[k] > p_stamp[k] else self._p_tag[k]

    # --- diagnostics
    # --------------------------------------------------------------------------------------

    def level(self, k: int, now: float) -> tuple[Level, str]:
        """Muscle ``k``'s diagnostic level and its one-line reason."""
        if now - self._reject_time.item(k) < self.hold:
            return Level.ERROR, f'invalid input: {self._reject_reason[k]}'
        max_age = self._age.item(k)
        for name, stamp in (
            ('pressure', self._p_stamp.item(k)),
            ('muscle_state', self._l_stamp.item(k)),
        ):
            age = now - stamp
            if not abs(age) <= max_age:  # NaN too
                if stamp != stamp:
                    return Level.ERROR, f'no {name} received yet'
                when = f'{age:.3g} s old' if age > 0 else f'{-age:.3g} s in the future'
                return (
                    Level.ERROR,
                    f'stale {name}: newest stamp is {when} (max_input_age {max_age:g} s)',
                )
        warned = self._warned[k].tolist()
        if now - max(warned) < self.hold:
            return Level.WARN, '; '.join(
                sorted({text for text, seen in zip(_WARN_TEXTS, warned) if now - seen < self.hold})
            )
        return Level.OK, 'estimating'

    def levels(self, now: float) -> np.ndarray:
        """Every muscle's level (as :meth:`level`), vectorised."""
        error = (now - self._reject_time < self.hold) | ~(
            np.maximum(np.abs(now - self._p_stamp), np.abs(now - self._l_stamp)) <= self._age
        )
        warn = now - self._warned.max(axis=1) < self.hold
        return np.where(error, int(Level.ERROR), warn.view(np.int8))

    def status_due(self, now: float, k: int | None = None) -> bool:
        """Whether a level (muscle ``k``'s, or any) differs from the last :meth:`status` report:
        report on change.

        Not sooner than ``report_interval`` [s] after the last report (a change then waits until
        the next input after it): a node that falls behind, its inputs flapping between fresh and
        stale, must not spend its time reporting (a status of 64 muscles costs milliseconds to
        publish).
        """
        if 0 <= now - self._last_report < self.report_interval:
            return False
        if k is not None:
            return self.level(k, now)[0] != self._reported.item(k)
        if (
            self._steady and self._calm == now
        ):  # all reported OK, and the input just taken changed nothing
            return False
        levels = self.levels(now)
        due = bool((levels != self._reported).any())
        self._steady = not due and not levels.any()
        return due

    def status(self, k: int, now: float) -> Status:
        """Muscle ``k``'s level, reason, counters and message rates [Hz] since its previous
        status.
        """
        level, message = self.level(k, now)
        counts = self._counts[k].tolist()
        values = {key: str(n) for key, n in sorted(zip(COUNTERS, counts)) if n}
        since = self._report_time.item(k)
        if now > since:  # False for NaN: the first report has no rates
            before = self._report_counts[k].tolist()
            for key, i in _RATES:
                values[f'{key} rate [Hz]'] = f'{(counts[i] - before[i]) / (now - since):.1f}'
        self._report_time[k], self._report_counts[k], self._reported[k] = now, counts, level
        self._steady, self._last_report = False, now
        values['model'] = self.configs[k].model.model.name
        return Status(level, message, values)

    def counts(self, k: int) -> dict[str, int]:
        """Muscle ``k``'s non-zero counters."""
        return {key: n for key, n in zip(COUNTERS, self._counts[k].tolist()) if n}


class _JointIndex:
    """Where each joint sits in the arrays of a JointState; the last complete name layout is
    cached.
    """

    def __init__(self, joints: Sequence[str]) -> None:
        self.joints = list(joints)
        self._names: list[str] | None = None
        self._take = np.zeros(0, np.intp)

    def of(
        self, names: list[str], values: Sequence[float], velocities: Sequence[float]
    ) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
        """(index of each joint in ``values`` (0 where absent), which joints are present (None:
        all), why each absent one is absent (:func:`joint_problem`)).
        """
        if (
            names == self._names
        ):  # same layout as before: every joint is there; only array sizes can differ
            problem = joint_problem(names, values, velocities, self.joints[0])
            if not problem:
                return self._take, None, []
            return self._take, np.zeros(len(self.joints), bool), [problem] * len(self.joints)
        found = [
            joint_problem(names, values, velocities, joint) or names.index(joint)
            for joint in self.joints
        ]
        present = np.array([isinstance(i, int) for i in found])
        take = np.array([i if isinstance(i, int) else 0 for i in found], np.intp)
        if present.all():
            self._names, self._take = list(names), take
            return take, None, []
        return take, present, [i for i in found if isinstance(i, str)]


class CombinedInputs:
    """The combined input mode's JointStates (every muscle in one message) into one
    :class:`Engine`.

    ``joints`` are the muscles' JointState names, in the engine's order.  A message that lacks a
    muscle, or whose arrays do not match, rejects only the muscles it gives no value for; the
    others are one vectorised engine call.  ``model_node`` and ``bag estimate`` both use this.
    """

    def __init__(self, engine: Engine, joints: Sequence[str]) -> None:
        self.engine, self.joints = engine, list(joints)
        self._index = {'pressure': _JointIndex(joints), 'muscle_state': _JointIndex(joints)}

    def pressures(
        self, names: list[str], positions: Sequence[float], stamp, now: float
    ) -> np.ndarray:
        """A ``muscle_pressures`` message: absolute pressures [Pa] in ``positions``, header
        ``stamp`` (``sec``, ``nanosec``); which muscles got an estimate (see
        :meth:`Engine.pressures`).
        """
        take, present = self._take('pressure', names, positions, (), now)
        return self.engine.pressures(
            np.asarray(positions, float)[take] if take is not None else np.zeros(len(self.joints)),
            seconds(stamp),
            now,
            stamp,
            present,
        )

    def lengths(
        self,
        names: list[str],
        positions: Sequence[float],
        velocities: Sequence[float],
        stamp,
        now: float,
    ) -> np.ndarray:
        """A ``muscle_states`` message: lengths [m] in ``positions``, rates [m/s] in ``velocities``
        (may be empty).
        """
        take, present = self._take('muscle_state', names, positions, velocities, now)
        if take is None:
            return self.engine.lengths(
                np.zeros(len(self.joints)), None, seconds(stamp), now, stamp, present
            )
        rates = np.asarray(velocities, float)[take] if len(velocities) else None
        return self.engine.lengths(
            np.asarray(positions, float)[take], rates, seconds(stamp), now, stamp, present
        )

    def _take(
        self,
        source: str,
        names: list[str],
        values: Sequence[float],
        velocities: Sequence[float],
        now: float,
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(where each muscle's value sits, None if no muscle has one; which are present, None:
        all); the absent ones rejected with their reason.
        """
        take, present, problems = self._index[source].of(names, values, velocities)
        if present is None:
            return take, None
        for k, problem in zip(np.flatnonzero(~present).tolist(), problems):
            self.engine.reject(k, source, problem, now)
        return (take if present.any() else None), present

    def commands(
        self, names: list[str], efforts: Sequence[float], now: float
    ) -> tuple[list[str], list[float]]:
        """A ``force_commands`` message (wanted tensions [N] in ``efforts``): the joints commanded
        and their absolute pressures [Pa]; muscles not named are not commanded.
        """
        problem = (
            ''
            if len(efforts) == len(names)
            else f'mismatched arrays: {len(names)} names, {len(efforts)} efforts'
        )
        joints, pressures = [], []
        for k, joint in enumerate(self.joints):
            if joint not in names:
                continue
            if problem:
                self.engine.reject(k, 'force_command', problem, now)
            elif (
                pressure := self.engine.command(k, float(efforts[names.index(joint)]), now)
            ) is not None:
                joints.append(joint)
                pressures.append(pressure)
        return joints, pressures
