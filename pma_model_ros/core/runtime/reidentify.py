"""Live re-identification of one muscle from measured forces (no ROS).

Samples (gauge pressure [Pa], length [m], measured force [N]) are collected by
:class:`SampleCollector` inside the muscle's physical envelope (:func:`envelope`: 0 Pa to the
higher of its rated and identified pressures, the braid's full contraction to its rest length
plus the calibration's 5 %, whatever lengths and pressures its file was identified on: another
specimen is run over others); samples outside it, non-finite or with a negative force below
``-force_floor`` are not kept (counted in ``rejected``).

**Enough coverage** (:class:`CoverageRule`, :meth:`SampleCollector.coverage`), judged on the box
the kept samples span, the one a new fit is identified and served on: cut into ``pressure_bins`` x
``length_bins`` cells, at least ``per_cell`` samples in at least ``cell_share`` of the cells, in at
least ``lengths`` distinct length bins; and the box spans at least ``pressure_span`` of the
envelope's top pressure and ``length_span`` of the rest length (5 %: a fifth of the 25 %
contraction Festo rates a DMSP for).  ``Coverage.share`` (cells filled / cells) is the figure
/diagnostics shows.

**Identification** (:func:`reidentify`) is that of ``pma-model fit --bag``: the fit samples are
averaged in the cells of :func:`~..identification.force_map.cell_means` (each length cell a row,
negative forces set to 0 N), checked by ``check_fit_map`` and
identified by ``identify_all`` with ``fit``'s defaults (the model served, ``least_squares``,
length and pressure calibration on); the file is built by ``build_parameters`` and ``model_entry``
as ``fit`` builds it.

**Acceptance**: every ``check_every``-th sample in arrival order is a check sample, never fitted;
the candidate is served only if its eq. 23 error on the check samples is below the current
parameters' on the same samples (:class:`Outcome`).

**Serving** (:class:`Served`): the parameters and their :class:`MuscleModel` are built off the
estimation path and swapped as one reference (one attribute assignment).
"""

from __future__ import annotations

from dataclasses import dataclass
import datetime
import math
import threading

import numpy as np

from ..files.param_file import GIVEN_LENGTH, muscle_model, spec_mapping
from ..files.param_writer import build_parameters, model_entry, write_parameters
from ..identification.calibration import Calibration, LENGTH_BOUND
from ..identification.force_map import cell_means
from ..identification.protocols import check_fit_map, max_error_percent
from ..identification.selection import identify_all
from ..physics import geometry as geo
from ..physics.geometry import MuscleSpec
from ..physics.models import get_model
from ..physics.muscle_model import MuscleModel

FILE_LEGEND = (
    'err: eq. 23 on the whole map [%]; cv_err: worst nested leave-one-length-out err [%] (the '
    'fit, calibration\nand choices included, re-run without each length); held_out: that err '
    'per held-out length.'
)


@dataclass(frozen=True)
class CoverageRule:
    """When the collected samples are enough to identify (module docstring)."""

    pressure_bins: int = 8
    length_bins: int = 5
    per_cell: int = 3  #: samples for a cell to count as filled
    cell_share: float = 0.6  #: share of the cells filled
    lengths: int = 3  #: distinct length bins with a filled cell
    pressure_span: float = 0.5  #: share of the envelope's top pressure the samples span
    length_span: float = 0.05  #: share of the rest length the samples span


@dataclass(frozen=True)
class Coverage:
    share: float  #: cells with ``per_cell`` samples / cells of the samples' box
    lengths: int  #: length bins with a filled cell
    pressures: tuple[float, float]  #: [Pa] lowest and highest kept pressure
    lengths_m: tuple[float, float]  #: [m] shortest and longest kept length
    pressure_span: float  #: (highest - lowest kept pressure) / envelope's top pressure
    length_span: float  #: (longest - shortest kept length) / rest length
    samples: int
    enough: bool

    def describe(self) -> str:
        """One line for /diagnostics."""
        (p0, p1), (l0, l1) = self.pressures, self.lengths_m
        return (
            f'{100 * self.share:.0f} % of cells over {p0 / 1e3:.0f}-{p1 / 1e3:.0f} kPa x '
            f'{l0:.4g}-{l1:.4g} m, {self.lengths} lengths, pressure span '
            f'{100 * self.pressure_span:.0f} %, length span {100 * self.length_span:.1f} % of L0, '
            f'{self.samples} samples: {"enough" if self.enough else "not enough"}'
        )


def envelope(model: MuscleModel) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where samples of the muscle of ``model`` are kept: gauge pressures [Pa] from 0 to the
    higher of the rated and the identified one, lengths [m] from the braid's full contraction to
    the rest length plus :data:`~..identification.calibration.LENGTH_BOUND` of it (how far the
    calibration moves a given L0 that the samples prove too short: a rest length measured 1 cm
    short is within it) or the longest identified length, if longer.
    """
    spec, domain = model.spec, model.domain
    known = domain.pressure_max if math.isfinite(domain.pressure_max) else 0.0
    top = max(spec.max_pressure, known)
    longest = max(spec.nominal_length * (1 + LENGTH_BOUND), domain.length_max)
    return (0.0, top), (geo.shortest_length(spec), longest)


class SampleCollector:
    """The measured samples of one muscle inside its envelope (:func:`envelope`, :meth:`of`);
    the length span is judged in shares of ``rest_length`` [m] (default: the longest length kept).
    """

    def __init__(
        self,
        pressure_range: tuple[float, float],
        length_range: tuple[float, float],
        rule: CoverageRule = CoverageRule(),
        capacity: int = 50_000,
        force_floor: float = 5.0,
        rest_length: float | None = None,
    ) -> None:
        self.p_range = (float(pressure_range[0]), float(pressure_range[1]))
        self.l_range = (float(length_range[0]), float(length_range[1]))
        self.rest_length = float(rest_length or self.l_range[1])
        if not (self.p_range[1] > self.p_range[0] and self.l_range[1] > self.l_range[0]):
            raise ValueError(f'empty range: pressure {pressure_range}, length {length_range}')
        self.rule, self.capacity, self.force_floor = rule, capacity, force_floor
        self._data = np.empty((capacity, 3))
        self._n = 0
        self.rejected = 0
        self._lock = threading.Lock()

    @classmethod
    def of(cls, model: MuscleModel, rule: CoverageRule = CoverageRule()) -> SampleCollector:
        """The collector of the muscle of ``model``: its envelope, spans in shares of its L0."""
        return cls(*envelope(model), rule, rest_length=model.spec.nominal_length)

    def __len__(self) -> int:
        return self._n

    def add(self, gauge: float, length: float, force: float) -> bool:
        """Keep one sample (False: rejected, or the collector is full)."""
        if not (
            np.isfinite(gauge + length + force)
            and self.p_range[0] <= gauge <= self.p_range[1]
            and self.l_range[0] <= length <= self.l_range[1]
            and force >= -self.force_floor
        ):
            self.rejected += 1
            return False
        with self._lock:
            if self._n >= self.capacity:
                return False
            self._data[self._n] = (gauge, length, force)
            self._n += 1
        return True

    def samples(self) -> np.ndarray:
        """A copy of the kept samples, (n, 3): gauge [Pa], length [m], force [N]."""
        with self._lock:
            return self._data[: self._n].copy()

    def clear(self) -> None:
        with self._lock:
            self._n = 0
            self.rejected = 0

    def coverage(self) -> Coverage:
        """The coverage of the kept samples and whether it is enough (module docstring)."""
        s, r = self.samples(), self.rule
        if not len(s):
            return Coverage(0.0, 0, (0.0, 0.0), (0.0, 0.0), 0.0, 0.0, 0, False)
        low, high = s[:, :2].min(axis=0), s[:, :2].max(axis=0)
        bins = np.array([r.pressure_bins, r.length_bins])
        width = np.where(high > low, high - low, 1.0)
        cell = np.minimum(((s[:, :2] - low) / width * bins).astype(int), bins - 1)
        counts = np.zeros(bins, int)
        np.add.at(counts, (cell[:, 0], cell[:, 1]), 1)
        filled = counts >= r.per_cell
        share = float(filled.mean())
        lengths = int(filled.any(axis=0).sum())
        p_span = float((high[0] - low[0]) / self.p_range[1])
        l_span = float((high[1] - low[1]) / self.rest_length)
        enough = (
            share >= r.cell_share
            and lengths >= r.lengths
            and p_span >= r.pressure_span
            and l_span >= r.length_span
        )
        return Coverage(
            share,
            lengths,
            (float(low[0]), float(high[0])),
            (float(low[1]), float(high[1])),
            p_span,
            l_span,
            len(s),
            enough,
        )


def split(samples: np.ndarray, check_every: int) -> tuple[np.ndarray, np.ndarray]:
    """(fit, check): every ``check_every``-th sample in arrival order is a check sample."""
    check = np.zeros(len(samples), bool)
    check[::check_every] = True
    return samples[~check], samples[check]


def check_err(parameters: dict, samples: np.ndarray) -> float:
    """Eq. 23 [%] of the parameters' default model on the samples."""
    model = muscle_model(parameters)
    predicted = model.force(samples[:, 0], samples[:, 1]).force
    return max_error_percent(samples[:, 2], predicted, float(np.max(samples[:, 2])))


@dataclass(frozen=True)
class Outcome:
    """A re-identification: the candidate's file mapping and both errors on the check samples."""

    parameters: dict | None  #: ``ros__parameters`` of the candidate (None: none could be fitted)
    candidate_err: float  #: eq. 23 [%] on the check samples (NaN: no candidate)
    current_err: float  #: the current parameters' on the same samples
    fit_samples: int
    check_samples: int
    reason: str = ''  #: why there is no candidate

    @property
    def accepted(self) -> bool:
        return self.parameters is not None and self.candidate_err < self.current_err

    def describe(self) -> str:
        """One line for /diagnostics."""
        if self.parameters is None:
            return f'refused: {self.reason}'
        verdict = 'served' if self.accepted else 'refused'
        return (
            f'{verdict}: check err {self.candidate_err:.2f} % against {self.current_err:.2f} % '
            f'of the current parameters on {self.check_samples} check samples '
            f'({self.fit_samples} fitted)'
        )


def reidentify(current: dict, samples: np.ndarray, check_every: int = 4) -> Outcome:
    """Identify the current parameters' muscle and model again from ``samples`` (n, 3) as
    ``pma-model fit --bag`` does, and judge the candidate against ``current`` (``ros__parameters``)
    on the check samples (module docstring).
    """
    fit, check = split(samples, check_every)
    current_err = check_err(current, check)
    muscle = current['muscle']
    # the spec as given (a calibrated file keeps the given rest length beside its own)
    spec = MuscleSpec.from_mapping(
        spec_mapping(muscle)
        | {'nominal_length': muscle.get(GIVEN_LENGTH, muscle['nominal_length'])}
    )
    model = get_model(current['model'])
    fmap = cell_means(fit[:, 0], fit[:, 1], fit[:, 2])
    try:
        check_fit_map(fmap, spec, folds=3)
        found = identify_all(
            spec, fmap, (model,), Calibration(True, True), ('least_squares',), workers=1
        )
    except (ValueError, np.linalg.LinAlgError) as err:
        return Outcome(None, float('nan'), current_err, len(fit), len(check), str(err))
    report = found.reports[found.default]
    chosen = report.shipped
    parameters = build_parameters(
        chosen.spec,
        found.default,
        chosen.domain,
        {found.default: model_entry(report, fmap, chosen.spec.nominal_length)},
        given_length=spec.nominal_length,
    )['/**']['ros__parameters']
    # the node's own settings stay as they were (topics, ranges of inputs, ...)
    parameters = {**current, **{k: parameters[k] for k in _MODEL_KEYS if k in parameters}}
    return Outcome(parameters, check_err(parameters, check), current_err, len(fit), len(check))


#: the keys a re-identification replaces; every other key is the node's and kept
_MODEL_KEYS = ('muscle', 'model', 'length_range', 'pressure_range', 'models')


@dataclass(frozen=True)
class Snapshot:
    """Parameters served together with their model and where they came from."""

    parameters: dict
    model: object  #: the MuscleModel of ``parameters``
    header: str


class Served:
    """The parameters being served; :meth:`swap` replaces them as one reference."""

    def __init__(self, parameters: dict, source: str) -> None:
        self.file = Snapshot(
            parameters, muscle_model(parameters), f'{source} (not re-identified).\n' + FILE_LEGEND
        )
        self.current = self.file

    def swap(self, outcome: Outcome, samples: int, source: str, when: float) -> Snapshot:
        """Serve an accepted outcome's parameters (built here, then one assignment)."""
        if not outcome.accepted:
            raise ValueError(f'not accepted: {outcome.describe()}')
        stamp = datetime.datetime.fromtimestamp(when, datetime.timezone.utc).isoformat()
        name = outcome.parameters['muscle'].get('name', '')
        header = (
            f'{name} re-identified live by model_node from {samples} measured samples at {stamp} '
            f'(as `pma-model fit --bag`), starting from {source}; check err '
            f'{outcome.candidate_err:.3g} % against {outcome.current_err:.3g} % of the previous '
            f'parameters on {outcome.check_samples} samples not fitted '
            f'({outcome.fit_samples} fitted).\n' + FILE_LEGEND
        )
        snapshot = Snapshot(outcome.parameters, muscle_model(outcome.parameters), header)
        self.current = snapshot
        return snapshot

    def revert(self) -> Snapshot:
        """Serve the file's parameters again."""
        self.current = self.file
        return self.current

    def save(self, path: str) -> None:
        """Write the served parameters as ``fit`` writes a file, whole or not at all."""
        snapshot = self.current
        write_parameters(path, {'/**': {'ros__parameters': snapshot.parameters}}, snapshot.header)
