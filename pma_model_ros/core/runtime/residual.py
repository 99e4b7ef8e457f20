"""The residual of the served force against a measured one, and the drift monitor over it (no
ROS): model_node's ``residual.*`` and ``bag estimate``'s figures.

**Pairing.** A measured force [N] of a muscle is paired with the estimate of the same stamp [ns]
(:meth:`Residuals.served` keeps each muscle's last :data:`SERVED` estimates: stamp, force, gauge
pressure, length, flags; a second estimate at one stamp replaces the first, the one made of
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
(at most ``capacity`` per muscle, :data:`CAPACITY` in the node), bias (mean of measured -
served), RMS and worst (largest magnitude, signed) [%], and the band (the mean of the samples'
figures).  The level follows the RMS / band ratio with hysteresis: WARN above ``warn_ratio``,
ERROR above ``error_ratio``; a level is left only once the ratio is below its threshold times
(1 - ``hysteresis``).  With fewer than :data:`MIN_SAMPLES` samples in the window the level is OK
(nothing to judge).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
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
        self._head = [0] * n
        # the samples: a ring per muscle of time [ns], residual [%], band [%], interior
        self._capacity = capacity
        self._time = np.full((n, capacity), np.iinfo(np.int64).min, np.int64)
        self._sample = np.zeros((n, capacity, 3))
        self._next = [0] * n
        self.levels = [Level.OK] * n
        self.counts = [
            dict.fromkeys(('paired', 'rejected', 'unpaired', 'unjudged'), 0) for _ in bands
        ]
        self.last_problem = [''] * n

    def __len__(self) -> int:
        return len(self.bands)

    def use(self, bands: Sequence, pressure_max: Sequence[float], models: Sequence[str]) -> None:
        """Judge by these muscles' bands from now on (a parameter change, a re-identification);
        the window is kept.
        """
        self.bands = list(bands)
        self.pressure_max = [float(p) for p in pressure_max]
        self.models = list(models)

    # --- the estimates
    def served(self, k: int, stamp: int, force: float, gauge: float, length: float, flags: int):
        """Muscle ``k`` was served ``force`` [N] at ``gauge`` [Pa] and ``length`` [m] (its
        ``flags``) for the inputs of ``stamp`` [ns].
        """
        head = self._head[k]
        if self._stamp.item(k, head) != stamp:
            head = self._head[k] = (head + 1) % SERVED
            self._stamp[k, head] = stamp
        self._served[k, head] = force, gauge, length
        self._flags[k, head] = flags

    def served_all(self, stamp: int, which: np.ndarray | None, forces, gauges, lengths, flags):
        """:meth:`served` of the muscles ``which`` (a mask; None: all); arrays over every
        muscle.
        """
        muscles = range(len(self)) if which is None else np.flatnonzero(which).tolist()
        for k in muscles:
            self.served(k, stamp, forces.item(k), gauges.item(k), lengths.item(k), flags.item(k))

    # --- the measured forces
    def reject(self, k: int, problem: str) -> None:
        """Count a measured force of muscle ``k`` refused for ``problem`` (e.g. a malformed
        message).
        """
        self.counts[k]['rejected'] += 1
        self.last_problem[k] = problem

    def measured(
        self, k: int, stamp: int, force: float, now: int
    ) -> tuple[float, float, float] | None:
        """A measured ``force`` [N] of muscle ``k`` stamped ``stamp`` [ns], at ``now`` [ns]:
        (gauge [Pa], length [m] of its estimate, ``force``) if it entered the window, else None
        (refused, unpaired, unjudged or not monitored).
        """
        band = self.bands[k]
        if band is None:
            return None
        counts = self.counts[k]
        problem = measured_problem(force, band.max_force)
        if not problem and not fresh(stamp, now, self.max_age):
            problem = f'stale measured force: stamp {(now - stamp) * 1e-9:.3g} s from now'
        if problem:
            self.reject(k, problem)
            return None
        at = np.flatnonzero(self._stamp[k] == stamp)
        if not at.size:
            counts['unpaired'] += 1
            return None
        i = at.item(0)
        served, gauge, length = self._served[k, i].tolist()
        flags = self._flags.item(k, i)
        if flags & Flag.PRESSURE_OUT_OF_RANGE or gauge > self.pressure_max[k]:
            counts['unjudged'] += 1
            return None
        held = bool(flags & Flag.LENGTH_OUT_OF_RANGE)
        percent, inside = band.at(length, held)
        self.add(k, stamp, 100.0 * (force - served) / band.max_force, percent, inside and not held)
        counts['paired'] += 1
        return gauge, length, force

    def add(self, k: int, time: int, residual: float, band: float, interior: bool) -> None:
        """One judged sample of muscle ``k`` at ``time`` [ns]: ``residual`` and ``band`` [%]."""
        i = self._next[k]
        self._time[k, i] = time
        self._sample[k, i] = residual, band, interior
        self._next[k] = (i + 1) % self._capacity

    # --- the window
    def figures(self, k: int, now: int) -> Figures | None:
        """Muscle ``k``'s :class:`Figures` over the window ending at ``now`` [ns] (None: fewer
        than :data:`MIN_SAMPLES`).
        """
        times = self._time[k]
        inside = times >= now - self._window
        n = int(np.count_nonzero(inside))
        if n < MIN_SAMPLES:
            return None
        residual, band, interior = self._sample[k, inside].T
        worst = residual[np.argmax(np.abs(residual))]
        return Figures(
            n,
            (now - int(times[inside].min())) * 1e-9,
            float(residual.mean()),
            float(np.sqrt(np.mean(residual**2))),
            float(worst),
            float(band.mean()),
            int(np.count_nonzero(interior)),
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
        counts = self.counts[k]
        values = {
            'residual [% of max force]': (
                figures.describe() if figures is not None else 'too few samples in the window'
            ),
            'residual level': self.levels[k].name,
            'residual samples': ', '.join(f'{n} {name}' for name, n in counts.items()),
        }
        if self.last_problem[k]:
            values['residual last refused'] = self.last_problem[k]
        return values
