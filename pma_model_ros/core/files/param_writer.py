"""Writing ROS 2 parameter files of identified muscles (layout: :mod:`.param_file`)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import yaml

from .node_parameters import frame_of
from .param_file import GIVEN_LENGTH, NODE_DEFAULTS
from ..identification.force_map import ForceMap
from ..identification.protocols import Fit
from ..identification.selection import edge_err, interior_err, ModelReport
from ..identification.validation import fold_lengths
from ..physics.geometry import MuscleSpec
from ..physics.hysteresis import Follow
from ..physics.models import Domain, extrapolates

_ROUND = 12  # significant digits written; far below any fit's resolution


def _num(value: float) -> float:
    return float(f'{value:.{_ROUND}g}')


def fit_entry(fit: Fit) -> dict:
    """The ``models.<name>`` mapping of one fit: params (if any), the calibrated nominal_length [m]
    and pressure_offset [Pa] (if calibrated), objective, err, rmse, r2.
    """
    entry = {'params': [_num(v) for v in fit.theta]} if fit.theta.size else {}
    if fit.calibration.length:
        entry['nominal_length'] = _num(fit.spec.nominal_length)
    if fit.calibration.pressure:
        entry['pressure_offset'] = _num(fit.pressure_offset)
    entry.update(objective=fit.objective, err=_num(fit.err), rmse=_num(fit.rmse), r2=_num(fit.r2))
    return entry


def model_entry(report: ModelReport, fmap: ForceMap, nominal_length: float) -> dict:
    """:func:`fit_entry` of the shipped fit, with its rest length [m] wherever it differs from
    the file's ``nominal_length`` (the muscle's: else the model would be served at another
    model's calibrated L0), plus its worst nested held-out errors, overall
    (``cv_err``), on the lengths between the map's shortest and longest (``interior_cv_err``,
    interpolation) and on those two (``edge_cv_err``, extrapolation), whether it is served beyond
    the identified lengths by its own value
    (:func:`~pma_model_ros.core.physics.models.extrapolates`, the rule those figures judge), and
    the error per held-out length (``held_out``: ``lengths`` [m], ``err`` [%] and the ``max_force``
    [N] they are a share of), when every length was judged.
    """
    entry = fit_entry(report.shipped)
    if report.shipped.spec.nominal_length != nominal_length:
        entry['nominal_length'] = _num(report.shipped.spec.nominal_length)
    return entry | held_out_entry(report.shipped.model, report.nested, fmap)


def held_out_entry(model: str, nested: np.ndarray, fmap: ForceMap) -> dict:
    """The held-out keys of a model entry from its nested held-out err per fold [%] of ``fmap``
    (:func:`model_entry`).
    """
    interior, edge = interior_err(nested), edge_err(nested)
    entry = {
        'cv_err': _num(float(np.nanmax(nested))),
        **({'interior_cv_err': _num(interior)} if math.isfinite(interior) else {}),
        'edge_cv_err': _num(edge),
        'extrapolates': extrapolates(model),
    }
    if nested.size and np.all(np.isfinite(nested)):
        entry['held_out'] = {
            'lengths': [_num(v) for v in fold_lengths(fmap)],
            'err': [_num(v) for v in nested],
            'max_force': _num(fmap.max_force),
        }
    return entry


def build_parameters(
    spec: MuscleSpec,
    default: str,
    domain: Domain,
    models: dict[str, dict],
    given_length: float | None = None,
    follow: Follow | None = None,
) -> dict:
    """The full parameter-file mapping for one muscle; ``given_length`` [m]: the spec's rest
    length as given, beside a calibrated ``spec.nominal_length`` (``muscle.given_nominal_length``,
    :mod:`.param_file`); ``follow``: what a hysteresis model's branches were identified on
    (``hysteresis.input`` and its deadband).
    """
    muscle = {k: (v if isinstance(v, str) else _num(v)) for k, v in spec.to_mapping().items()}
    if given_length is not None:
        muscle[GIVEN_LENGTH] = _num(given_length)
    return {
        '/**': {
            'ros__parameters': {
                'muscle': muscle,
                'model': default,
                'length_range': [_num(domain.length_min), _num(domain.length_max)],
                **(
                    {'pressure_range': [0.0, _num(domain.pressure_max)]}
                    if math.isfinite(domain.pressure_max)
                    else {}
                ),
                'models': models,
                **(
                    {
                        'hysteresis': {
                            'input': follow.input,
                            f'{follow.input}_deadband': _num(follow.deadband),
                        }
                    }
                    if follow is not None
                    else {}
                ),
                **NODE_DEFAULTS,
                'joint_name': spec.name,
                'frame_id': frame_of(spec.name),
            }
        }
    }


def write_parameters(path: str | Path, parameters: dict, header: str) -> None:
    """Write a parameter file whole or not at all: into a new file beside ``path`` (a link's
    target), renamed over it once written; interrupted or failed, ``path`` is as it was.
    """
    text = yaml.safe_dump(parameters, sort_keys=False, default_flow_style=None, width=120)
    target = os.path.realpath(path)
    folder, name = os.path.split(target)
    partial = os.path.join(folder, f'.{name}.{os.getpid()}.partial')
    try:
        with open(partial, 'x', encoding='utf-8') as out:
            out.write(''.join(f'# {line}\n' for line in header.splitlines()) + text)
        os.replace(partial, target)
    finally:
        if os.path.exists(partial):
            os.unlink(partial)
