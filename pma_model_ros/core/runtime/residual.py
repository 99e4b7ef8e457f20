"""The residual of the served force against a measured one, and the drift monitor over it (no
ROS): model_node's ``residual.*`` and ``bag estimate``'s figures.

**Pairing.** A measured force [N] of a muscle is paired with its newest estimate of the same stamp
[ns] (:meth:`Residuals.served` keeps each muscle's last :data:`SERVED` estimates: stamp, force,
gauge pressure, length, flags; a second estimate at one stamp replaces the first, the one made of
both inputs of that stamp).  A measured force with no estimate of its stamp is ``unpaired``.

**Checks** (:func:`measured_problem`): a measured force is refused (``rejected``, with the reason
of the newest) if it is not finite, outside :data:`MEASURED_RANGE` of the muscle's max force, or
stale (its stamp more than ``max_input_age`` from now, :func:`~.pairing.fresh`).  A refused or
unpaired force never enters the window.

**Band.** Each paired sample is judged against the fit's nested held-out band at its length, as
``pma-model force`` reports it (:meth:`~pma_model_ros.core.identification.validation.HeldOutBand.
at`): the interior figure between the measured lengths, the edge figure beyond them or where the
force is held (``LENGTH_OUT_OF_RANGE``).  Beyond the identified pressures there is no figure: the
sample is ``unjudged`` and kept out of the window.  Residuals are in % of the band's
``max_force`` (the map's, eq. 23's); a muscle whose parameter file has no ``held_out`` is not
monitored.

**Window and level** (:meth:`Residuals.report`): over the samples of the last ``window`` [s]
(at most ``capacity`` per muscle, :data:`CAPACITY` in the node; in arrival order from the first
one stamped inside the window, so a sample stamped earlier that arrives after it, at most
``max_input_age`` old, is in too), bias (mean of measured -
served), RMS and worst (largest magnitude, signed) [%], and the band (the mean of the samples'
figures).  The level follows the RMS / band ratio with hysteresis: WARN above ``warn_ratio``,
ERROR above ``error_ratio``; a level is left only once the ratio is below its threshold times
(1 - ``hysteresis``).  With fewer than :data:`MIN_SAMPLES` samples in the window the level is OK
(nothing to judge).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import re
from typing import Sequence

import numpy as np

from .health import Level
from .pairing import fresh
from ..physics.flags import Flag

#: estimates kept per muscle for pairing (1 kHz inputs: a measured force may arrive 60 ms late)
SERVED = 64
#: samples kept per muscle (the window holds at most these: 10 s at 3 kHz)
CAPACITY = 1 << 15
#: samples in the window below which nothing is judged
MIN_SAMPLES = 10
#: the measured forces taken, in fractions of the muscle's max force
MEASURED_RANGE = (-0.1, 2.0)
#: the counts of :attr:`Residuals.counts`, in the order /diagnostics lists them
COUNTS = ('paired', 'rejected', 'unpaired', 'unjudged')
_PAIRED, _REJECTED, _UNPAIRED, _UNJUDGED = range(len(COUNTS))
_SLOTS = np.arange(SERVED)
_PRESSURE_OUT = int(Flag.PRESSURE_OUT_OF_RANGE)
_LENGTH_OUT = int(Flag.LENGTH_OUT_OF_RANGE)
#: what :meth:`Residuals.measured_all` returns: the muscles whose samples entered the window, and
#: each one's gauge pressure [Pa], length [m] and measured force [N]
Taken = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
_NOTHING: Taken = (np.empty(0, np.intp), np.empty(0), np.empty(0), np.empty(0))
#: the command that identifies a muscle again from a recording of its measured force
REFIT = 'pma-model fit --bag <recording> --muscle <spec.yaml> --model {} --out <parameters.yaml>'


def measured_problem(force: float, max_force: float) -> str:
    """Why a measured force [N] of a muscle of ``max_force`` [N] is no measurement ('' if it is
    one).
    """
    if not math.isfinite(force):
        return f'measured force is {force} N'
    low, high = (f * max_force for f in MEASURED_RANGE)
    if not low <= force <= high:
        return f'measured force {force:g} N outside [{low:g}, {high:g}] N'
    return ''


def next_level(level: Level, ratio: float, warn: float, error: float, hysteresis: float) -> Level:
    """The level after ``level`` at an RMS / band ``ratio`` (module docstring)."""
    keep = 1.0 - hysteresis
    if ratio > error or level == Level.ERROR and ratio >= error * keep:
        return Level.ERROR
    if ratio > warn or level >= Level.WARN and ratio >= warn * keep:
        return Level.WARN
    return Level.OK


@dataclass(frozen=True)
class Figures:
    """The residual of one muscle over a window [% of max force]."""

    samples: int
    span: float  #: [s] from the oldest sample in the window to now
    bias: float
    rms: float
    worst: float
    band: float  #: the mean of the samples' held-out figures
    interior: int  #: samples judged by the interior figure (the others: by the edge figure)

    def describe(self) -> str:
        return (
            f'bias {self.bias:.3g} %, RMS {self.rms:.3g} %, worst {self.worst:.3g} % over '
            f'{self.samples} samples in {self.span:.3g} s; band {self.band:.3g} % '
            f'({self.interior} interior, {self.samples - self.interior} edge)'
        )

    @classmethod
    def parse(cls, text: str) -> Figures | None:
        """The figures of a :meth:`describe` line (to its 3 digits), as /diagnostics carries
        them; None for any other text (e.g. ``too few samples in the window``).
        """
        match = _DESCRIBED.fullmatch(text)
        if match is None:
            return None
        bias, rms, worst, samples, span, band, interior, _ = match.groups()
        numbers = (float(v) for v in (span, bias, rms, worst, band))
        return cls(int(samples), *numbers, int(interior))


_NUMBER = r'(\S+)'
#: a :meth:`Figures.describe` line
_DESCRIBED = re.compile(
    rf'bias {_NUMBER} %, RMS {_NUMBER} %, worst {_NUMBER} % over (\d+) samples in {_NUMBER} s; '
    rf'band {_NUMBER} % \((\d+) interior, (\d+) edge\)'
)


@dataclass(frozen=True)
class Thresholds:
    window: float = 10.0  #: [s]
    warn_ratio: float = 1.0
    error_ratio: float = 2.0
    hysteresis: float = 0.2


class Residuals:
    """Measured - served of each muscle of ``bands`` (a muscle's ``HeldOutBand``, or None: not
    monitored) and its level (module docstring); ``pressure_max`` [Pa]: each muscle's identified
    gauge pressures' top; ``models``: each one's model, named in the refit command.
    ``max_age`` [ns]: older measured forces are stale; ``capacity``: samples kept per muscle.
    """

    def __init__(
        self,
        bands: Sequence,
        pressure_max: Sequence[float],
        models: Sequence[str],
        max_age: int,
        thresholds: Thresholds = Thresholds(),
        capacity: int = CAPACITY,
    ) -> None:
        n = len(bands)
        self.max_age, self.thresholds = max_age, thresholds
        if not thresholds.error_ratio >= thresholds.warn_ratio:
            raise ValueError(
                f'residual.error_ratio ({thresholds.error_ratio:g}) must be >= '
                f'residual.warn_ratio ({thresholds.warn_ratio:g})'
            )
        self.use(bands, pressure_max, models)
        self._window = round(thresholds.window * 1e9)
        # the estimates: a ring per muscle
        self._stamp = np.full((n, SERVED), -1, np.int64)
        self._served = np.zeros((n, SERVED, 3))  # force [N], gauge [Pa], length [m]
        self._flags = np.zeros((n, SERVED), np.uint16)
        self._head = np.zeros(n, np.intp)
        self._column_stamp: int | None = None  # served_all's newest stamp (None: not fed by it)
        self._all = np.arange(n)
        # the samples: a ring per muscle, in arrival order, of stamp [ns], the newest stamp so
        # far [ns] (never decreasing: where the window starts is found by bisection), residual
        # [%], band [%], whether judged by the interior figure; samples written per muscle
        self._capacity = capacity
        self._time = np.zeros((n, capacity), np.int64)
        self._reach = np.zeros((n, capacity), np.int64)
        self._residuals = np.zeros((n, capacity))
        self._bands = np.zeros((n, capacity))
        self._inside = np.zeros((n, capacity), bool)
        self._written = np.zeros(n, np.int64)
        self._newest = np.full(n, np.iinfo(np.int64).min, np.int64)
        self.levels = [Level.OK] * n
        self._counts = np.zeros((n, len(COUNTS)), np.int64)
        self.last_problem = [''] * n

    def __len__(self) -> int:
        return len(self.bands)

    @property
    def counts(self) -> list[dict[str, int]]:
        """Each muscle's measured forces by outcome (:data:`COUNTS`)."""
        return [dict(zip(COUNTS, row)) for row in self._counts.tolist()]

    def use(self, bands: Sequence, pressure_max: Sequence[float], models: Sequence[str]) -> None:
        """Judge by these muscles' bands from now on (a parameter change, a re-identification);
        the window is kept.
        """
        self.bands = list(bands)
        self.pressure_max = np.array(pressure_max, float)
        self.models = list(models)
        # each band's figures as arrays over the muscles, NaN where not monitored: shortest and
        # longest held-out length [m], interior and edge figure [%] (HeldOutBand.at), max force [N]
        figures = [
            (min(b.lengths), max(b.lengths), b.interior, b.edge, b.max_force)
            if b is not None
            else (np.nan,) * 5
            for b in self.bands
        ]
        self._shortest, self._longest, self._interior, self._edge, self._max_force = (
            (np.array(column, float) for column in zip(*figures))
            if figures
            else (np.empty(0),) * 5
        )
        #: [N] the measured forces taken (:data:`MEASURED_RANGE`), NaN where not monitored
        self._low, self._high = (f * self._max_force for f in MEASURED_RANGE)
        self._every_monitored = bool(np.isfinite(self._max_force).all())

    # --- the estimates
    def served(self, k: int, stamp: int, force: float, gauge: float, length: float, flags: int):
        """Muscle ``k`` was served ``force`` [N] at ``gauge`` [Pa] and ``length`` [m] (its
        ``flags``) for the inputs of ``stamp`` [ns].
        """
        # :meth:`_keep` of one muscle in scalars (the single-muscle inputs' path, per message)
        head = self._head.item(k)
        if self._stamp.item(k, head) != stamp:
            head = self._head[k] = (head + 1) % SERVED
        self._stamp[k, head] = stamp
        self._served[k, head] = (force, gauge, length)
        self._flags[k, head] = flags

    def served_all(self, stamp: int, which: np.ndarray | None, forces, gauges, lengths, flags):
        """:meth:`served` of the muscles ``which`` (a mask; None: all), arrays over every muscle:
        a combined input's, whose muscles share each message's stamp, so every ring keeps a stamp
        in one slot, at one head (a muscle not estimated at a stamp keeps an older one there).  A
        monitor is fed by :meth:`served` or by this, never both.
        """
        head = self._head.item(0)
        if stamp != self._column_stamp:  # (the same stamp again: its slot, the first replaced)
            head = (head + 1) % SERVED
            self._head[:] = head
            self._column_stamp = stamp
            if which is not None:
                self._stamp[:, head] = -1  # no estimate of this stamp (yet) for the others
        rows = slice(None) if which is None else np.flatnonzero(which)
        self._stamp[rows, head] = stamp
        self._served[rows, head, 0] = forces[rows]
        self._served[rows, head, 1] = gauges[rows]
        self._served[rows, head, 2] = lengths[rows]
        self._flags[rows, head] = flags[rows]

    # --- the measured forces
    def reject(self, k: int, problem: str) -> None:
        """Count a measured force of muscle ``k`` refused for ``problem`` (e.g. a malformed
        message).
        """
        self._counts[k, _REJECTED] += 1
        self.last_problem[k] = problem

    def measured(
        self, k: int, stamp: int, force: float, now: int
    ) -> tuple[float, float, float] | None:
        """A measured ``force`` [N] of muscle ``k`` stamped ``stamp`` [ns], at ``now`` [ns]:
        (gauge [Pa], length [m] of its estimate, ``force``) if it entered the window, else None
        (refused, unpaired, unjudged or not monitored).
        """
        # :meth:`measured_all` of one muscle in scalars (the single-muscle inputs' path, per
        # message; test_many_muscles_at_once_are_judged_as_one_at_a_time holds them equal)
        max_force = self._max_force.item(k)
        if not math.isfinite(max_force):
            return None
        if not self._low.item(k) <= force <= self._high.item(k):  # NaN too
            self.reject(k, measured_problem(force, max_force))
            return None
        if not fresh(stamp, now, self.max_age):
            self.reject(k, f'stale measured force: stamp {(now - stamp) * 1e-9:.3g} s from now')
            return None
        at = self._head.item(k)
        if self._stamp.item(k, at) != stamp:  # not the newest estimate's: the newest of its stamp
            same = np.flatnonzero(self._stamp[k] == stamp)
            if not same.size:
                self._counts[k, _UNPAIRED] += 1
                return None
            at = same[np.argmin((at - same) % SERVED)].item()
        served, gauge, length = self._served[k, at].tolist()
        flags = self._flags.item(k, at)
        if flags & _PRESSURE_OUT or gauge > self.pressure_max.item(k):
            self._counts[k, _UNJUDGED] += 1
            return None
        interior = (
            self._shortest.item(k) <= length <= self._longest.item(k) and not flags & _LENGTH_OUT
        )
        band = self._interior.item(k) if interior else self._edge.item(k)
        self._store(k, stamp, 100.0 * (force - served) / max_force, band, interior)
        return gauge, length, force

    def measured_all(self, ks: np.ndarray, stamp: int, forces: np.ndarray, now: int) -> Taken:
        """Measured ``forces`` [N] of the muscles ``ks`` (ascending), all stamped ``stamp`` [ns],
        at ``now`` [ns]: the muscles, gauge pressures [Pa], lengths [m] and forces [N] of those
        that entered the window (:data:`Taken`); the others are counted refused, unpaired or
        unjudged (muscles not monitored: neither).
        """
        if ks.size == len(self) and self._every_monitored and self._column_stamp is not None:
            taken = self._measured_every(stamp, forces, now)
            if taken is not None:
                return taken
        monitored = np.isfinite(self._max_force[ks])
        ks, forces = ks[monitored], forces[monitored]
        if not ks.size:
            return _NOTHING
        bad = ~((forces >= self._low[ks]) & (forces <= self._high[ks]))  # NaN too
        for k, force in zip(ks[bad].tolist(), forces[bad].tolist()):
            self.reject(k, measured_problem(force, self._max_force.item(k)))
        ks, forces = ks[~bad], forces[~bad]
        if ks.size and not fresh(stamp, now, self.max_age):
            for k in ks.tolist():
                self.reject(
                    k, f'stale measured force: stamp {(now - stamp) * 1e-9:.3g} s from now'
                )
            return _NOTHING
        same = self._stamp[ks] == stamp
        paired = same.any(axis=1)
        self._counts[ks[~paired], _UNPAIRED] += 1
        ks, forces, same = ks[paired], forces[paired], same[paired]
        # each one's newest estimate of the stamp: the fewest slots behind its ring's head
        at = np.where(same, (self._head[ks, None] - _SLOTS) % SERVED, SERVED).argmin(axis=1)
        served, gauge, length = self._served[ks, at].T
        flags = self._flags[ks, at]
        unjudged = (flags & _PRESSURE_OUT).astype(bool) | (gauge > self.pressure_max[ks])
        self._counts[ks[unjudged], _UNJUDGED] += 1
        judged = ~unjudged
        ks, forces, served, gauge, length, flags = (
            a[judged] for a in (ks, forces, served, gauge, length, flags)
        )
        return self._judge(ks, stamp, forces, served, gauge, length, flags)

    def _measured_every(self, stamp: int, forces: np.ndarray, now: int) -> Taken | None:
        """:meth:`measured_all` of a combined message measuring every muscle, all monitored,
        when each force is taken, fresh, paired with the estimate of the newest stamp or of the
        one before (:meth:`served_all`; a measured force arriving after the next inputs' estimate)
        and judged (a combined input's every message in a run); None, with nothing counted,
        otherwise.
        """
        head = self._head.item(0)
        if self._stamp.item(0, head) != stamp:
            head = (head - 1) % SERVED
        if not (
            fresh(stamp, now, self.max_age)
            and ((forces >= self._low) & (forces <= self._high)).all()  # NaN: False
            and (self._stamp[:, head] == stamp).all()
        ):
            return None
        flags = self._flags[:, head]
        served, gauge, length = self._served[:, head].T
        if (flags & _PRESSURE_OUT).any() or (gauge > self.pressure_max).any():
            return None
        return self._judge(self._all, stamp, forces, served, gauge, length, flags)

    def _judge(self, ks, stamp: int, forces, served, gauge, length, flags) -> Taken:
        """Paired samples of the muscles ``ks`` judged (measured ``forces`` and ``served`` [N]
        at ``gauge`` [Pa] and ``length`` [m], ``flags``): each against its band at its length,
        the interior figure inside the held-out lengths and not held, else the edge figure
        (:meth:`~pma_model_ros.core.identification.validation.HeldOutBand.at`); stored.
        """
        inside = (self._shortest[ks] <= length) & (length <= self._longest[ks])
        interior = inside & ((flags & _LENGTH_OUT) == 0)
        band = np.where(interior, self._interior[ks], self._edge[ks])
        self._store(ks, stamp, 100.0 * (forces - served) / self._max_force[ks], band, interior)
        return ks, gauge, length, forces

    def _store(self, ks, stamp: int, residuals, bands, interior) -> None:
        """Paired samples of the muscles ``ks`` (an index or an array of them; ``self._all``:
        every muscle, by whole-array updates) stamped ``stamp`` [ns]: residual and band [%],
        judged by the interior figure; into their rings.
        """
        if ks is self._all:
            slots, newest = self._written % self._capacity, self._newest
            np.maximum(newest, stamp, out=newest)
        else:
            slots = self._written[ks] % self._capacity
            newest = self._newest[ks] = np.maximum(self._newest[ks], stamp)
        self._time[ks, slots] = stamp
        self._reach[ks, slots] = newest
        self._residuals[ks, slots] = residuals
        self._bands[ks, slots] = bands
        self._inside[ks, slots] = interior
        if ks is self._all:
            self._written += 1
            self._counts[:, _PAIRED] += 1
        else:
            self._written[ks] += 1
            self._counts[ks, _PAIRED] += 1

    # --- the window
    def figures(self, k: int, now: int) -> Figures | None:
        """Muscle ``k``'s :class:`Figures` over the window ending at ``now`` [ns] (None: fewer
        than :data:`MIN_SAMPLES`): the samples from the first one, in arrival order, stamped
        within the window (module docstring), found by bisection; a few array reductions over
        them, however many muscles and samples the monitor holds.
        """
        cap, written = self._capacity, int(self._written[k])
        reach, cutoff = self._reach[k], now - self._window
        low, high = max(written - cap, 0), written
        while low < high:  # the first sample (by arrival) whose newest stamp so far is inside
            middle = (low + high) // 2
            if reach[middle % cap] >= cutoff:
                high = middle
            else:
                low = middle + 1
        n = written - low
        if n < MIN_SAMPLES:
            return None
        first, end = low % cap, written % cap
        parts = [slice(first, end)] if first < end else [slice(first, cap), slice(0, end)]

        def window(a: np.ndarray) -> np.ndarray:
            return a[parts[0]] if len(parts) == 1 else np.concatenate([a[p] for p in parts])

        residual = window(self._residuals[k])
        worst = residual[np.argmax(np.abs(residual))]
        return Figures(
            n,
            (now - int(window(self._time[k]).min())) * 1e-9,
            float(residual.mean()),
            float(np.sqrt(np.dot(residual, residual) / n)),
            float(worst),
            float(window(self._bands[k]).mean()),
            int(np.count_nonzero(window(self._inside[k]))),
        )

    def report(self, k: int, now: int) -> tuple[Level, str, Figures | None]:
        """Muscle ``k``'s level after the window ending at ``now`` [ns], its message ('' when OK)
        and figures.
        """
        figures = self.figures(k, now)
        t = self.thresholds
        ratio = figures.rms / figures.band if figures is not None and figures.band > 0 else 0.0
        level = self.levels[k] = next_level(
            self.levels[k], ratio, t.warn_ratio, t.error_ratio, t.hysteresis
        )
        if level == Level.OK:
            return level, '', figures
        return (
            level,
            f'model drift: residual {figures.rms:.3g} % over the last {figures.span:.3g} s '
            f'against a band of {figures.band:.3g} %: refit: {REFIT.format(self.models[k])}',
            figures,
        )

    def values(self, k: int, figures: Figures | None) -> dict[str, str]:
        """Muscle ``k``'s /diagnostics keys of the residual."""
        if self.bands[k] is None:
            return {'residual': 'unknown: the parameter file has no held_out errors'}
        counts = self._counts[k].tolist()
        values = {
            'residual [% of max force]': (
                figures.describe() if figures is not None else 'too few samples in the window'
            ),
            'residual level': self.levels[k].name,
            'residual samples': ', '.join(f'{n} {name}' for name, n in zip(COUNTS, counts)),
        }
        if self.last_problem[k]:
            values['residual last refused'] = self.last_problem[k]
        return values
