"""pma-model: reproduce the paper, identify muscles, judge fits on measured maps, evaluate force
and pressure, process bags, plot.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
from pathlib import Path
import sys
from typing import Sequence, TYPE_CHECKING

import numpy as np

from .bags.commands import add_bag_commands, add_fit_bag_options, bag_force_map
from .core.calibration import Calibration
from .core.flags import describe, Flag
from .core.force_map import read_force_map_csv
from .core.geometry import STANDARD_ATMOSPHERE
from .core.models import get_model, TABLE3_MODELS
from .core.param_file import held_out_band, load_muscle, read_parameters
from .core.progress import step
from .core.shipped_data import (
    dmsp_10_100_hysteresis,
    MAPPED_MUSCLES,
    shipped_force_map,
    shipped_spec,
)
from .core.units import length_hint, pressure_hint
from .core.user_files import read_spec_yaml
from .core.validation import fold_lengths, length_folds, OBJECTIVES

if TYPE_CHECKING:  # imported where used: force and pressure need no identification (scipy)
    from .core.identification import Fit, Identification, ModelReport

#: Martens & Boblan 2017, Table 3: err [%] of each model.
PAPER_TABLE3 = {
    'DMSP-10-250': {
        'mckibben': 46.1,
        'andrikopoulos': 20.05,
        'wickramatunge': 13.49,
        'hildebrandt': 10.12,
        'sarosi': 5.1,
        'martens': 4.4,
    },
    'DMSP-20-300': {
        'mckibben': 30.0,
        'andrikopoulos': 13.04,
        'wickramatunge': 8.2,
        'hildebrandt': 5.75,
        'sarosi': 3.59,
        'martens': 2.35,
    },
}


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


@functools.cache
def identify_muscle(muscle: str) -> Identification:
    """All Table 3 models identified on a shipped map, judged by nested held-out error."""
    from .core.identification import identify_all

    return identify_all(
        shipped_spec(muscle), shipped_force_map(muscle), tuple(get_model(m) for m in TABLE3_MODELS)
    )


def table3(results: dict[str, Identification]) -> dict:
    """The ``reproduce --json`` object."""
    out = {}
    for muscle, found in results.items():
        out[muscle] = {'default': found.default, 'held_out': round(_worst(found.held_out), 4)}
        for name, rep in found.reports.items():
            out[muscle][name] = {
                'paper': PAPER_TABLE3[muscle][name],
                'paper_protocol': round(rep.paper.err, 4),
                'best': round(rep.best_err, 4),
                'cv': round(rep.cv_err, 4),
            }
    return {'table3': out}


def _worst(errors: np.ndarray) -> float:
    """The worst of per-fold errors [%], NaN if no fold could be judged."""
    return float(np.nanmax(errors)) if np.any(np.isfinite(errors)) else math.nan


def _print_tables(results: dict[str, Identification]) -> None:
    for muscle, found in results.items():
        print(
            f'\n{muscle}: err (eq. 23) in %; held_out: worst nested leave-one-length-out err '
            f'(objective chosen again without each length)'
        )
        print(
            f'{"model":<14}{"paper":>8}{"paper_protocol":>16}{"best_lsq":>10}{"best_minimax":>14}'
            f'{"best":>8}{"held_out":>10}  objective (by held-out err)'
        )
        for name, rep in found.reports.items():
            print(
                f'{name:<14}{PAPER_TABLE3[muscle][name]:>8.2f}{rep.paper.err:>16.2f}'
                f'{rep.best["least_squares"].err:>10.2f}{rep.best["minimax"].err:>14.2f}'
                f'{rep.best_err:>8.2f}{rep.cv_err:>10.2f}  {rep.shipped_objective}'
            )
        print(
            f'\n{muscle}: nested held-out err in % per held-out length [m] (each length fitted '
            f'without it)'
        )
        _held_out_table(shipped_force_map(muscle).lengths, found.reports)
        print(_default_line(found))


def _default_line(found: Identification) -> str:
    """How the default model was chosen, with the nested figure of that choice."""
    picks = ', '.join(
        f'{name} x{found.chosen.count(name)}' for name in dict.fromkeys(found.chosen)
    )
    return (
        f'default model (lowest worst held-out err): {found.default}; the choice made again '
        f'without each length ({picks}) errs by {_worst(found.held_out):.2f} % at worst'
    )


def identify_shipped(muscles: Sequence[str]) -> dict[str, Identification]:
    """:func:`identify_muscle` of each muscle, one progress line each (stderr)."""
    results = {}
    for k, muscle in enumerate(muscles, 1):
        step(
            k, len(muscles), f'identifying {muscle} ({len(TABLE3_MODELS)} models, nested held-out)'
        )
        results[muscle] = identify_muscle(muscle)
    return results


def cmd_reproduce(args: argparse.Namespace) -> None:
    results = identify_shipped(MAPPED_MUSCLES)
    if args.json:
        print(json.dumps(table3(results)))
    else:
        _print_tables(results)


def cmd_make_config(args: argparse.Namespace) -> None:
    from .core.identification import domain_of
    from .core.param_writer import build_parameters, model_entry, write_parameters

    header = (
        f'Identified {args.muscle}: generated by `pma-model make-config {args.muscle} --out ...`\n'
        "from the package's shipped data; regenerate rather than edit. SI units throughout."
    )
    if args.muscle == 'DMSP-10-100':
        hyst = dmsp_10_100_hysteresis()
        models = {'sarosi_hysteresis': {'params': [float(v) for v in hyst.theta]}}
        params = build_parameters(hyst.spec, 'sarosi_hysteresis', hyst.domain, models)
        header += (
            '\nSárosi eq. 3, upper branch Table 2, lower branch Table 4 (0-600 kPa), '
            'converted to SI.'
        )
    else:
        found = identify_shipped([args.muscle])[args.muscle]
        fmap = shipped_force_map(args.muscle)
        models = {name: model_entry(rep, fmap) for name, rep in found.reports.items()}
        params = build_parameters(
            shipped_spec(args.muscle), found.default, domain_of(fmap), models
        )
        header += f'\n{_FILE_LEGEND}'
    write_parameters(args.out, params, header)
    print(f'wrote {args.out}')


_FILE_LEGEND = (
    'err: eq. 23 on the whole map [%]; cv_err: worst nested leave-one-length-out err [%] (the '
    'fit, calibration\nand choices included, re-run without each length); held_out: that err '
    'per held-out length.'
)


def cmd_scale(args: argparse.Namespace) -> None:
    from .core.param_writer import write_parameters
    from .core.transfer import scale_parameters
    from .core.user_files import load_yaml_mapping, read_user_file

    data = load_yaml_mapping(read_user_file(args.config, 'parameter file'), str(args.config))
    nodes = [k for k, v in data.items() if isinstance(v, dict) and 'ros__parameters' in v]
    if len(nodes) > 1:
        raise CliError(f"{args.config}: {len(nodes)} nodes in one file; scale one muscle's file")
    parameters = read_parameters(args.config)
    try:
        scaled, notes = scale_parameters(parameters, args.length)
    except ValueError as err:
        raise CliError(f'{args.config}: {err}') from None
    source, target = parameters['muscle'], scaled['muscle']
    ratio = args.length / source['nominal_length']
    header = (
        f'{target["name"]}: {source["name"]} of {args.config} cut to L0 = {args.length:g} m by '
        f"`pma-model scale` (s = L0' / L0 = {ratio:.6g}).\n"
        "At equal contraction (L0 - L) / L0 and pressure it serves the source's force; lengths\n"
        "are s times the source's (docs/calibration.md). err, rmse, r2, cv_err and held_out err\n"
        "are the source map's figures, at equal contraction."
    )
    write_parameters(args.out, {nodes[0]: {'ros__parameters': scaled}}, header)
    low, high = scaled['length_range']
    print(
        f'wrote {args.out}: {target["name"]} ({source["name"]} x {ratio:.6g}), length_range '
        f'[{low:.6g}, {high:.6g}] m'
    )
    for note in notes:
        print(f'  {note}')


def _held_out_table(lengths, reports: dict[str, ModelReport]) -> None:
    labels = length_headers(lengths)
    print(f'{"model":<14}' + ''.join(f'{label:>9}' for label in labels) + f'{"worst":>9}')
    for name, rep in reports.items():
        print(
            f'{name:<14}'
            + ''.join(f'{e:>9.2f}' for e in rep.nested)
            + f'{_worst(rep.nested):>9.2f}'
        )


def length_headers(lengths: Sequence[float]) -> list[str]:
    """Column headers of lengths [m]: 3 decimals, or as many more (up to 6) as make neighbouring
    ones differ (bands of a recording's lengths round alike at 3).
    """
    for digits in range(3, 7):
        texts = [f'{L:.{digits}f}' for L in lengths]
        if len(set(texts)) == len(texts):
            break
    return texts


def describe_geometry(fit: Fit, given_length: float) -> str:
    """The identified L0 and pressure offset of a calibrated fit with their uncertainty, or why
    each stayed as given.
    """
    sigma, parts = fit.sigma, []
    if fit.calibration.length:
        parts.append(
            f'L0 {fit.spec.nominal_length:.4f} ±{sigma["nominal_length"]:.4f} m (given '
            f'{given_length:.4f} m: not longer than the slack length {fit.slack_length:.4f} m)'
        )
    elif math.isinf(sigma.get('nominal_length', 0.0)):
        parts.append(
            f'L0 kept {given_length:.4f} m: not longer than the slack length '
            f'{fit.slack_length:.4f} m, but the model absorbs or ignores L0'
        )
    elif 'nominal_length' in sigma:
        parts.append(
            f'L0 kept {given_length:.4f} m: the slack length, where a threshold (the pressure '
            'offset) fits the map better than a longer L0'
        )
    elif fit.slack_length is not None:
        parts.append(
            f'L0 kept {given_length:.4f} m (longer than the slack length {fit.slack_length:.4f} m)'
        )
    if 'pressure_offset' in sigma:
        parts.append(
            f'pressure offset {fit.pressure_offset / 1e3:+.2f} '
            f'±{sigma["pressure_offset"] / 1e3:.2f} kPa'
            if fit.calibration.pressure
            else 'pressure offset kept 0: not identifiable '
            f'(1-sigma {sigma["pressure_offset"] / 1e3:.3g} kPa)'
        )
    return '; '.join(parts)


def cmd_fit(args: argparse.Namespace) -> None:
    from .core.identification import check_fit_map, identify_all
    from .core.param_writer import build_parameters, model_entry, write_parameters

    spec = read_spec_yaml(args.muscle)
    if args.model != 'all' and get_model(args.model).hysteresis:
        return _fit_branches(args, spec)
    fmap = read_force_map_csv(args.data) if args.data else bag_force_map(args, spec)
    check_fit_map(fmap, spec, folds=3)
    calibration = Calibration(not args.no_calibrate_length, not args.no_calibrate_pressure)
    print(calibration.describe() + ' (switch off: --no-calibrate-length, --no-calibrate-pressure)')
    names = TABLE3_MODELS if args.model == 'all' else (args.model,)
    found = identify_all(
        spec, fmap, tuple(get_model(m) for m in names), calibration, (args.objective,)
    )
    reports = found.reports
    print(
        f'\nin-sample err (eq. 23) [%], RMSE [N], R² ({args.objective}); held_out: worst nested '
        'leave-one-length-out err [%]\n(each length predicted by the whole fit, calibration '
        'included, re-run without it)'
    )
    print(f'{"model":<14}{"err":>8}{"rmse":>9}{"r2":>10}{"held_out":>10}')
    for name, rep in reports.items():
        fit = rep.shipped
        print(f'{name:<14}{fit.err:>8.2f}{fit.rmse:>9.3f}{fit.r2:>10.5f}{rep.cv_err:>10.2f}')
    if calibration.any:
        print('\nidentified geometry (L0 ± its profile 1-sigma; pressure offset ± 1-sigma):')
        for name, rep in reports.items():
            print(f'  {name}: {describe_geometry(rep.shipped, spec.nominal_length)}')
    print(
        '\nnested held-out err [%] per held-out length [m]'
        + (
            ' (groups of neighbouring lengths: their mean)'
            if len(length_folds(fmap)) < fmap.lengths.size
            else ''
        )
    )
    _held_out_table(fold_lengths(fmap), reports)
    chosen = reports[found.default].shipped
    write_parameters(
        args.out,
        build_parameters(
            chosen.spec,
            found.default,
            chosen.domain,
            {name: model_entry(rep, fmap) for name, rep in reports.items()},
        ),
        f'{spec.name} identified from {args.data or args.bag} by `pma-model fit` '
        f'({calibration.describe()}; given nominal_length {spec.nominal_length:g} m).\n'
        + _FILE_LEGEND,
    )
    rows = rows_to_add(found.held_out, fold_lengths(fmap), chosen.spec)
    if rows:
        print('\n' + rows)
    if len(reports) > 1:
        print('\n' + _default_line(found))
        how = f'by held-out err; {reports[found.default].cv_err:.2f} % is a selection figure'
    else:
        how = 'the one fitted'
    print(
        f'\ndefault model ({how}): {found.default}  err {chosen.err:.3f} %  rmse '
        f'{chosen.rmse:.3f} N  r2 {chosen.r2:.5f}  {held_out_parts(found.held_out)}'
        f'  -> {args.out}'
    )


#: [%, pp] An edge figure above EDGE_LARGE and above the interior one by EDGE_MARGIN is large.
EDGE_LARGE, EDGE_MARGIN = 5.0, 1.0


def rows_to_add(nested: np.ndarray, lengths: np.ndarray, spec) -> str:
    """What to measure when the fit's edge figure (nested held-out err per fold [%] at the fold
    ``lengths`` [m], longest first) is large against its interior one: the rows that make the
    lengths served there interpolation, the rest-length row (L0) and the shortest working length;
    '' when it is not large.
    """
    from .core.geometry import shortest_length
    from .core.identification import edge_err, interior_err

    edge, interior = edge_err(nested), interior_err(nested)
    if not (edge > EDGE_LARGE and edge > interior + EDGE_MARGIN):
        return ''
    rest, longest, shortest = spec.nominal_length, float(lengths[0]), float(lengths[-1])
    side = 'longest' if nested[0] >= nested[-1] else 'shortest'
    at_rest = abs(longest - rest) <= 0.005 * rest  # within a calibrated L0's reach
    return (
        f'beyond the measured lengths the fit errs by {edge:.2f} % (the {side}, predicted from '
        f'the others) against {interior:.2f} % between them; '
        'rows to measure: the rest-length row at L0 '
        + (
            f'{rest:.4g} m (measured: it is the edge; a row between {float(lengths[1]):.4g} and '
            f'{rest:.4g} m makes it less of an extrapolation)'
            if at_rest
            else f'{rest:.4g} m (not measured: the longest is {longest:.4g} m)'
        )
        + ', and the shortest working length (the shortest is '
        f'{shortest:.4g} m; the braid pulls down to {shortest_length(spec):.4g} m)'
    )


def held_out_parts(nested: np.ndarray) -> str:
    """``held-out worst X % (between measured lengths Y %, beyond them Z %)``: the worst nested
    held-out err per fold [%] (longest first), on the lengths between the map's shortest and
    longest (interpolation) and on those two (extrapolation, as served there).
    """
    from .core.identification import edge_err, interior_err

    return (
        f'held-out worst {_worst(nested):.2f} % (between measured lengths '
        f'{interior_err(nested):.2f} %, beyond them {edge_err(nested):.2f} %)'
    )


def _fit_branches(args: argparse.Namespace, spec) -> None:
    """``fit`` of a two-branch (hysteresis) model: each branch on its direction's points,
    uncalibrated.
    """
    from .core.identification import check_fit_map, fit_best, judge_branches
    from .core.param_writer import build_parameters, fit_entry, held_out_entry, write_parameters

    model = get_model(args.model)
    fmap = (
        read_force_map_csv(args.data)
        if args.data
        else bag_force_map(args, spec, two_branches=True)
    )
    check_fit_map(fmap, spec, folds=2)
    if len(length_folds(fmap)) < 3:  # no length between others to judge it on
        fit, figures = fit_best(model, spec, fmap, args.objective), ''
        entry = fit_entry(fit)
    else:
        fit, nested = judge_branches(model, spec, fmap, args.objective)
        entry = fit_entry(fit) | held_out_entry(model.name, nested, fmap)
        figures = f'  {held_out_parts(nested)}'
        print(
            'nested held-out err [%] per held-out length [m] (each point on its branch; each '
            'length predicted by the fit without it, as served)'
        )
        labels = length_headers(fold_lengths(fmap))
        print(f'{"model":<18}' + ''.join(f'{label:>9}' for label in labels) + f'{"worst":>9}')
        print(
            f'{model.name:<18}'
            + ''.join(f'{e:>9.2f}' for e in nested)
            + f'{_worst(nested):>9.2f}\n'
        )
        rows = rows_to_add(nested, fold_lengths(fmap), spec)
        if rows:
            print(rows + '\n')
    write_parameters(
        args.out,
        build_parameters(spec, model.name, fit.domain, {model.name: entry}),
        f'{spec.name} identified from {args.data or args.bag} by `pma-model fit` '
        f'({fit.objective}, '
        'one branch per direction).',
    )
    print(
        f'{model.name}: err {fit.err:.3f} %  rmse {fit.rmse:.3f} N  r2 {fit.r2:.5f}{figures}'
        f'  -> {args.out}'
    )


def cmd_evaluate(args: argparse.Namespace) -> None:
    from .core.identification import quality

    muscle = load_muscle(args.config, args.model)
    fmap = read_force_map_csv(args.data)
    # a map's direction column picks each point's hysteresis branch, as the fit's figures do
    result = muscle.force(fmap.pressure, fmap.length, fmap.direction)
    model = np.nan_to_num(result.force)
    err, rmse, r2 = quality(fmap.force, model, fmap.max_force)
    print(
        f'{muscle.model.name} of {args.config} on {args.data}: err (eq. 23) {err:.2f} %  rmse '
        f'{rmse:.3f} N  '
        f'r2 {r2:.5f}  ({fmap.force.size} points)'
    )
    print(f'{"length [m]":>10}{"points":>8}{"err [%]":>9}{"rmse [N]":>10}  flags (points)')
    for length in fmap.lengths:
        at = fmap.length == length
        e, r, _ = quality(fmap.force[at], model[at], fmap.max_force)
        names, counts = np.unique([describe(int(f)) for f in result.flags[at]], return_counts=True)
        print(
            f'{length:>10.4f}{int(at.sum()):>8}{e:>9.2f}{r:>10.3f}  '
            + ', '.join(f'{n} ({c})' for n, c in zip(names, counts))
        )
    if args.csv:
        rows = ''.join(
            f'{p:.9g},{L:.9g},{F:.9g},{f:.9g},{f - F:.9g},{describe(int(flag))}\n'
            for p, L, F, f, flag in zip(
                fmap.pressure, fmap.length, fmap.force, model, result.flags
            )
        )
        Path(args.csv).write_text(
            'pressure_pa,length_m,force_n,model_n,error_n,flags\n' + rows, encoding='utf-8'
        )
        print(f'wrote {args.csv}')


def _finite(name: str, value: float, low: float, high: float, unit: str, hint: str) -> float:
    if not (math.isfinite(value) and low <= value <= high):
        raise CliError(f'{name} {value:g} is outside {low:g}..{high:g} {unit}; {hint}')
    return value


def _pressure(name: str, value: float) -> float:
    """A gauge pressure [Pa] of the command line; refused below vacuum and where its magnitude
    says bar or kPa (no muscle works below 1 kPa).
    """
    _finite(name, value, -1e7, 1e7, 'Pa', 'gauge pressure in Pa')
    if value < -STANDARD_ATMOSPHERE:
        raise CliError(
            f'{name} {value:g} Pa gauge is below vacuum (-{STANDARD_ATMOSPHERE:g} Pa gauge = 0 Pa '
            'absolute); gauge pressure = absolute - ambient'
        )
    if 0 < abs(value) < 1e3:
        raise CliError(
            f'{name} {value:g} Pa is below 1 kPa, no working pressure of a muscle: gauge '
            f'pressure in Pa; {pressure_hint(value)}'
        )
    return value


def _length(value: float, rest_length: float) -> float:
    """A muscle length [m] of the command line; refused where its magnitude says mm or cm (the
    unit that makes it nearest to the muscle's ``rest_length`` [m]).
    """
    if math.isfinite(value) and 10 < value <= 1e4:
        raise CliError(
            f'--length {value:g} m is longer than any muscle: lengths are in metres; '
            + length_hint(value, rest_length)
        )
    return _finite('--length', value, 1e-4, 10.0, 'm', 'lengths are in metres')


def _load(args: argparse.Namespace, parameters: dict | None = None):
    return load_muscle(args.config, args.model, parameters)


def _check_geometry(flags: int, length: float, muscle) -> None:
    if flags & Flag.INVALID_INPUT:
        raise CliError(
            f'length {length:g} m is beyond what the geometry of {muscle.spec.name} allows: '
            f'0 < L < {muscle.max_length:.6g} m (L0/cos(Theta0), its fibre length)'
        )


def cmd_force(args: argparse.Namespace) -> None:
    pressure = _pressure('--pressure', args.pressure)
    parameters = read_parameters(args.config)
    muscle = _load(args, parameters)
    length = _length(args.length, muscle.spec.nominal_length)
    result = muscle.force(pressure, length, args.length_rate)
    _check_geometry(int(result.flags), length, muscle)
    print(
        f'force {float(result.force):.6g} N  raw {float(result.raw):.6g} N  flags '
        f'{describe(int(result.flags))}'
    )
    band = held_out_band(parameters, args.model)
    print(expected_error(band, muscle.domain, pressure, length, int(result.flags)))


def expected_error(band, domain, pressure: float, length: float, flags: int) -> str:
    """The ``expected error:`` line of ``force``: within the identified pressures (served as such,
    up to ``domain.pressure_max`` [Pa]), the held-out band's figure at ``length`` [m]: between the
    measured lengths the interpolation's, beyond them the extrapolation's; else why it is unknown.
    """
    if band is None:
        return 'expected error: unknown (the parameter file has no held_out errors)'
    if flags & Flag.PRESSURE_OUT_OF_RANGE or pressure > domain.pressure_max:
        return (
            f'expected error: unknown: {pressure:g} Pa is outside the identified pressures '
            f'0..{domain.pressure_max:g} Pa (the held-out errors hold within them)'
        )
    percent, inside = band.at(length)
    of = f'{percent:.2f} % of {band.max_force:.4g} N'
    lengths = f'{min(band.lengths):.4g}..{max(band.lengths):.4g} m'
    if band.slack_at(length):
        why = (
            "the map's worst held-out err: the held-out lengths that judge it measured no force, "
            'so their own 0 % says only that the model is slack where the muscle was'
        )
    elif inside:
        why = f'between the measured lengths {lengths}: the worst held-out err of those inside'
    else:
        why = (
            f'extrapolation: {length:g} m is beyond the measured lengths {lengths}; the worst '
            'held-out err of the shortest and longest, each served from a fit without it'
        )
    return f'expected error: about ±{percent * band.max_force / 100:.3g} N ({of}: {why})'


def cmd_pressure(args: argparse.Namespace) -> None:
    force = _finite('--force', args.force, -1e7, 1e7, 'N', 'force in newtons')
    muscle = _load(args)
    length = _length(args.length, muscle.spec.nominal_length)
    result = muscle.pressure(force, length, args.length_rate)
    _check_geometry(int(result.flags), length, muscle)
    print(f'pressure {float(result.pressure):.6g} Pa  flags {describe(int(result.flags))}')


def _joint(args: argparse.Namespace):
    """The joint of ``--config`` named by ``--joint`` (default: the file's only joint)."""
    from .core.joint_file import load_joints

    joints = {j.name: j for j in load_joints(args.config)}
    name = args.joint or (next(iter(joints)) if len(joints) == 1 else None)
    if name not in joints:
        raise CliError(f'--joint: choose one of {", ".join(joints)}')
    return joints[name]


def _angle(joint, angle: float) -> float:
    low, high = joint.limits
    if not (math.isfinite(angle) and low <= angle <= high):
        raise CliError(
            f'--angle {angle:g} rad is outside the joint limits [{low:g}, {high:g}] rad '
            '(radians, not degrees)'
        )
    return angle


def cmd_joint_torque(args: argparse.Namespace) -> None:
    joint = _joint(args)
    theta = _angle(joint, args.angle)
    p = [_pressure('--pressures', v) for v in args.pressures]
    velocity = args.velocity
    sign = math.copysign(1.0, velocity) if velocity and math.isfinite(velocity) else 0.0
    # one shot, no memory: muscle 0 shortens while θ rises (branch -1), muscle 1 lengthens (+1)
    result = joint.forward(theta, p[0], p[1], (-sign, sign))
    print(
        f'torque {float(result.torque):.6g} N·m  stiffness {float(result.stiffness):.6g} N·m/rad'
    )
    for k, name in enumerate(joint.muscle_names):
        print(
            f'{name}: length {float(joint.lengths(theta)[k]):.6g} m  force '
            f'{float(result.forces[k]):.6g} N  '
            f'dF/dL {float(result.slopes[k]):.6g} N/m  flags {describe(int(result.flags[k]))}'
        )


def cmd_joint_pressures(args: argparse.Namespace) -> None:
    joint = _joint(args)
    theta = _angle(joint, args.angle)
    torque = _finite('--torque', args.torque, -1e6, 1e6, 'N·m', 'torque in newton metres')
    if args.stiffness is not None:
        result = joint.pressures_one(
            theta,
            torque,
            stiffness=_finite(
                '--stiffness', args.stiffness, 0.0, 1e7, 'N·m/rad', 'stiffness in N·m/rad'
            ),
        )
    else:
        block = read_parameters(args.config)[joint.name]  # the file's defaults, as joint_node's
        level = (
            block.get('cocontraction', 0.0) if args.cocontraction is None else args.cocontraction
        )
        level = _finite(
            '--cocontraction',
            _pressure('--cocontraction', level),
            0.0,
            1e7,
            'Pa',
            'gauge pressure in Pa',
        )
        result = joint.pressures_one(
            theta, torque, level, args.mode or block.get('cocontraction_mode', 'min')
        )
    print(
        '  '.join(f'{name} {p:.6g} Pa' for name, p in zip(joint.muscle_names, result.pressures))
        + f'  (gauge)  flags {describe(result.flags)}'
    )
    print(
        f'torque {result.torque:.6g} N·m  stiffness {result.stiffness:.6g} N·m/rad  '
        f'reachable torque [{result.torque_range[0]:.6g}, {result.torque_range[1]:.6g}] N·m'
    )


def cmd_joint_envelope(args: argparse.Namespace) -> None:
    from .core.joint import envelope

    joint = _joint(args)
    if not 2 <= args.steps <= 10000:
        raise CliError(f'--steps {args.steps} is outside 2..10000')
    angles = np.linspace(*joint.limits, args.steps)
    env = envelope(joint, angles)
    print(
        f'{joint.name}: {joint.muscle_names[0]} shortens for positive angle; stiffness at both '
        f'pressures 0 '
        'and both at max_pressure'
    )
    print(
        f'{"angle_rad":>10}{"torque_min_Nm":>15}{"torque_max_Nm":>15}{"K_low_Nm/rad":>14}'
        f'{"K_high_Nm/rad":>15}'
    )
    for i, theta in enumerate(angles):
        print(
            f'{theta:>10.4f}{env["torque_min"][i]:>15.4f}{env["torque_max"][i]:>15.4f}'
            f'{env["stiffness_low"][i]:>14.4f}{env["stiffness_high"][i]:>15.4f}'
        )


def add_joint_commands(sub) -> None:
    """``pma-model joint torque|pressures|envelope``."""
    joint = sub.add_parser(
        'joint', help='antagonistic joint: torque, pressures for a torque, envelope'
    )
    jsub = joint.add_subparsers(dest='joint_command', required=True)
    commands = {
        'torque': ('torque and stiffness at an angle and two pressures', cmd_joint_torque),
        'pressures': ('the two pressures for a wanted torque', cmd_joint_pressures),
        'envelope': ('reachable torque and stiffness over the joint range', cmd_joint_envelope),
    }
    for name, (text, func) in commands.items():
        p = jsub.add_parser(name, help=text)
        p.add_argument(
            '--config', required=True, help='joint parameter file, e.g. config/example_joint.yaml'
        )
        p.add_argument('--joint', default=None, help="joint name (default: the file's only joint)")
        p.set_defaults(func=func)
        if name == 'envelope':
            p.add_argument(
                '--steps', type=int, default=11, help='number of angles over the limits'
            )
            continue
        p.add_argument(
            '--angle',
            required=True,
            type=float,
            help='joint angle [rad], positive counter-clockwise',
        )
        if name == 'torque':
            p.add_argument(
                '--pressures',
                required=True,
                nargs=2,
                type=float,
                metavar=('PA', 'PB'),
                help='gauge pressures [Pa]: the muscle shortening for positive angle first',
            )
            p.add_argument(
                '--velocity',
                type=float,
                default=None,
                help='joint velocity [rad/s]: its sign picks the hysteresis branches (absent: '
                'unknown, the mean of both)',
            )
        else:
            p.add_argument('--torque', required=True, type=float, help='wanted torque [N·m]')
            level = p.add_mutually_exclusive_group()
            level.add_argument('--stiffness', type=float, help='wanted stiffness [N·m/rad]')
            level.add_argument(
                '--cocontraction',
                type=float,
                default=None,
                help="co-contraction level [Pa gauge] (default: the file's cocontraction, else 0)",
            )
            p.add_argument(
                '--mode',
                choices=('min', 'sum'),
                default=None,
                help='co-contraction level is the lower pressure (min) or the pressure sum '
                "(default: the file's cocontraction_mode, else min)",
            )


#: Figures of ``pma-model plot`` and what each needs; ``all`` makes every one whose input is given.
PLOTS = {
    'force-map': '--config',
    'error-map': '--config',
    'models': None,
    'timeseries': '--bag',
    'joint': '--config',
}


def cmd_plot(args: argparse.Namespace) -> None:
    try:
        from . import figures
    except ImportError as err:
        raise CliError(
            f'plot needs matplotlib and rosbags (requirements-dev.txt): {err}'
        ) from None
    wanted = list(PLOTS) if args.figure == 'all' else [args.figure]
    given = {'--config': args.config, '--bag': args.bag}
    for name in [n for n in wanted if PLOTS[n] and not given[PLOTS[n]]]:
        if args.figure != 'all':
            raise CliError(f'plot {name} needs {PLOTS[name]}')
        print(f'skipped {name}: no {PLOTS[name]}')
        wanted.remove(name)
    jobs = {}  # file stem: a function drawing the figure (inputs read and checked first)
    for config in args.config or ():
        source = Path(config).stem
        if 'joints' in read_parameters(config):  # a joint file: its joint figures
            if 'joint' not in wanted:
                continue
            from .core.joint_file import load_joints

            for joint in load_joints(config):
                jobs[f'joint_{source}_{joint.name}'] = functools.partial(
                    figures.joint_figure, joint
                )
            continue
        if args.figure == 'joint':
            raise CliError(f"plot joint needs a joint file (with 'joints:'), got {config}")
        model = load_muscle(config, args.model)
        fmap = shipped_force_map(model.spec.name)
        for name, draw in (
            ('force-map', figures.force_map_figure),
            ('error-map', figures.error_map_figure),
        ):
            if name in wanted:
                stem = f'{name.replace("-", "_")}_{source}_{model.model.name}'
                jobs[stem] = functools.partial(draw, fmap, model)
    if 'timeseries' in wanted:
        name = Path(args.bag).stem
        series = figures.read_force_series(args.bag, args.namespace)
        jobs[f'timeseries_{name}'] = functools.partial(
            figures.timeseries_figure, *series, f'{name}: estimated vs measured force'
        )
    if 'models' in wanted:
        jobs['models'] = lambda: figures.models_figure(
            table3(identify_shipped(MAPPED_MUSCLES))['table3']
        )
    if not args.overwrite:
        _refuse_existing(
            [args.out_dir / f'{stem}.{fmt}' for stem in jobs for fmt in args.format], 'plot'
        )
    written = []
    for k, (stem, draw) in enumerate(jobs.items(), 1):
        step(k, len(jobs), f'plotting {stem}')
        written += figures.save(draw(), args.out_dir, stem, args.format)
    for path in written:
        print(f'wrote {path}')


def _refuse_existing(paths: Sequence[str | Path], what: str) -> None:
    """A CliError naming the first of ``paths`` that exists (outputs are overwritten only with
    ``--overwrite``).
    """
    for path in paths:
        if os.path.lexists(path):
            raise CliError(f'{what}: {path} exists; not overwriting it (--overwrite overwrites)')


#: What an output option names: a ``file``; a ``bag`` (a file or a directory, replaced whole); a
#: ``directory`` written into (created if missing; its files checked by the command).
OUTPUT_KINDS = ('file', 'bag', 'directory')
#: Options naming what a command reads: never one of its outputs, even with ``--overwrite``.
INPUT_OPTIONS = ('data', 'muscle', 'config', 'bag')


def add_overwrite_option(p: argparse.ArgumentParser, outputs: dict[str, str]) -> None:
    """``--overwrite``; ``outputs`` maps each output option to its kind (:data:`OUTPUT_KINDS`),
    checked by :func:`check_outputs` before the command runs.
    """
    p.add_argument('--overwrite', action='store_true', help='overwrite existing output files')
    p.set_defaults(outputs=outputs)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, each output the command could not write: in a missing directory,
    a directory where a file is named, an existing file without ``--overwrite``, a folder without
    write permission, or one of the command's inputs.
    """
    inputs = []
    for name in INPUT_OPTIONS:
        value = getattr(args, name, None)
        inputs += [Path(v) for v in (value if isinstance(value, list) else [value]) if v]
    for option, kind in getattr(args, 'outputs', {}).items():
        value = getattr(args, option[2:].replace('-', '_'))
        if value is None:
            continue
        path = Path(value)
        if kind == 'directory':
            if path.exists() and not path.is_dir():
                raise CliError(f'{option} {path} is not a directory')
            folder = next(p for p in (path, *path.absolute().parents) if p.exists())
        else:
            if kind == 'file' and path.is_dir():
                raise CliError(f'{option} {path} is a directory; name a file in it')
            if not args.overwrite:
                _refuse_existing([path], option)
            folder = path.parent
            if not folder.is_dir():
                raise CliError(f'{option} {path}: no directory {folder}')
            for source in inputs:
                if path.exists() and source.exists() and os.path.samefile(path, source):
                    raise CliError(f'{option} {path} is an input of this command; name a new file')
        if not os.access(folder, os.W_OK | os.X_OK):
            raise CliError(f'{option} {path}: no permission to write in {folder}')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='pma-model', description=__doc__)
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser(
        'reproduce', help="the paper's Table 3: paper, our paper protocol, our best fit, CV"
    )
    p.add_argument('--json', action='store_true', help='print one JSON object instead of tables')
    p.set_defaults(func=cmd_reproduce)
    p = sub.add_parser('make-config', help='write the ROS parameter file of a shipped muscle')
    p.add_argument('muscle', choices=(*MAPPED_MUSCLES, 'DMSP-10-100'))
    p.add_argument('--out', required=True, help='output YAML path')
    add_overwrite_option(p, {'--out': 'file'})
    p.set_defaults(func=cmd_make_config)
    p = sub.add_parser(
        'fit', help='identify a model from a force map CSV (pressure_pa,length_m,force_n) or a bag'
    )
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument('--data', help='force map CSV')
    source.add_argument('--bag', help='rosbag2 recording of pressure, length and measured force')
    p.add_argument('--muscle', required=True, help='muscle spec YAML (SI units)')
    p.add_argument(
        '--model',
        required=True,
        help="model name, e.g. martens; 'all': every Table 3 model, the default by held-out error",
    )
    p.add_argument(
        '--objective',
        choices=OBJECTIVES,
        default='least_squares',
        help="of one model (with --model all: each model's by held-out error)",
    )
    p.add_argument(
        '--no-calibrate-length',
        action='store_true',
        help="keep the spec's rest length L0 as given",
    )
    p.add_argument(
        '--no-calibrate-pressure', action='store_true', help='assume no pressure-sensor offset'
    )
    p.add_argument('--out', required=True, help='output ROS parameter YAML')
    add_overwrite_option(p, {'--out': 'file'})
    add_fit_bag_options(p)
    p.set_defaults(func=cmd_fit)
    p = sub.add_parser(
        'scale',
        help="a parameter file's muscle type cut to another rest length (equal force at equal "
        'contraction and pressure)',
    )
    p.add_argument('--config', required=True, help='parameter file of one identified muscle')
    p.add_argument('--length', required=True, type=float, help="the new rest length L0' [m]")
    p.add_argument('--out', required=True, help='output ROS parameter YAML')
    add_overwrite_option(p, {'--out': 'file'})
    p.set_defaults(func=cmd_scale)
    p = sub.add_parser(
        'evaluate',
        help='a fitted model against a measured force map: eq. 23, RMSE, per length, flags',
    )
    p.add_argument('--config', required=True, help='parameter file, e.g. of pma-model fit')
    p.add_argument('--data', required=True, help='force map CSV (pressure_pa,length_m,force_n)')
    p.add_argument('--model', default=None, help="override the file's default model")
    p.add_argument('--csv', help='write each point: measured, model, error [N] and flags')
    add_overwrite_option(p, {'--csv': 'file'})
    p.set_defaults(func=cmd_evaluate)
    add_bag_commands(sub)
    add_joint_commands(sub)
    for name, quantity, unit, func in (
        ('force', 'pressure', 'Pa gauge', cmd_force),
        ('pressure', 'force', 'N', cmd_pressure),
    ):
        p = sub.add_parser(name, help=f'{name} from {quantity} [{unit}] and length [m]')
        p.add_argument(
            '--config', required=True, help='ROS parameter file, e.g. config/dmsp_10_250.yaml'
        )
        p.add_argument(f'--{quantity}', required=True, type=float, help=f'[{unit}]')
        p.add_argument('--length', required=True, type=float, help='muscle length [m]')
        p.add_argument(
            '--length-rate',
            type=float,
            default=None,
            help='length rate [m/s]; its sign picks the hysteresis branch',
        )
        p.add_argument('--model', default=None, help="override the file's default model")
        p.set_defaults(func=func)
    p = sub.add_parser(
        'plot', help='figures: force map, error map, model comparison, bag time series, joint'
    )
    p.add_argument('figure', choices=(*PLOTS, 'all'))
    p.add_argument(
        '--config',
        nargs='+',
        help='parameter file(s) of mapped muscles, for force-map and error-map; '
        'joint files, for joint',
    )
    p.add_argument('--model', default=None, help="override the files' default model")
    p.add_argument(
        '--bag',
        help='bag with <ns>/force and <ns>/force_estimate (pma-model bag estimate), '
        'for timeseries',
    )
    p.add_argument(
        '--namespace', default=None, help="of the muscle's topics in --bag (default: the only one)"
    )
    p.add_argument(
        '--out-dir', type=Path, default=Path('.'), help='directory to write into (default: .)'
    )
    p.add_argument('--format', nargs='+', choices=('png', 'svg'), default=('png', 'svg'))
    add_overwrite_option(p, {'--out-dir': 'directory'})
    p.set_defaults(func=cmd_plot)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        check_outputs(args)
        args.func(args)
    except BrokenPipeError:  # the reader stopped early (`| head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the Python docs' idiom
        return 0
    except (CliError, ValueError, OSError) as err:
        print(f'pma-model: error: {err}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
