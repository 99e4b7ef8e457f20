"""``pma-model reproduce``, ``make-config``, ``fit``, ``scale`` and ``evaluate``: the paper's
Table 3, shipped and identified parameter files, and a fit judged on a measured map.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
from pathlib import Path
from typing import Sequence, TYPE_CHECKING

import numpy as np

from .bags import add_fit_bag_options, bag_force_map
from .branch_fit import fit_branches
from .checks import add_overwrite_option, CliError
from .fit_output import (
    FILE_LEGEND,
    held_out_table,
    print_in_sample,
    print_nested,
    rows_to_add,
    worst,
    written_line,
)
from ..core.files.param_file import load_muscle, read_parameters
from ..core.files.shipped_data import (
    dmsp_10_100_hysteresis,
    MAPPED_MUSCLES,
    shipped_force_map,
    shipped_spec,
)
from ..core.files.user_files import read_spec_yaml
from ..core.identification.calibration import Calibration, short_of_map
from ..core.identification.force_map import read_force_map_csv
from ..core.identification.progress import step
from ..core.identification.validation import fold_lengths, OBJECTIVES
from ..core.physics.flags import describe
from ..core.physics.hysteresis import INPUTS as HYSTERESIS_INPUTS
from ..core.physics.models import get_model, TABLE3_MODELS

if TYPE_CHECKING:  # imported where used: force and pressure need no identification (scipy)
    from ..core.identification.protocols import Fit
    from ..core.identification.selection import Identification


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


@functools.cache
def identify_muscle(muscle: str) -> Identification:
    """All Table 3 models identified on a shipped map, judged by nested held-out error."""
    from ..core.identification.selection import identify_all

    return identify_all(
        shipped_spec(muscle), shipped_force_map(muscle), tuple(get_model(m) for m in TABLE3_MODELS)
    )


def table3(results: dict[str, Identification]) -> dict:
    """The ``reproduce --json`` object."""
    out = {}
    for muscle, found in results.items():
        out[muscle] = {'default': found.default, 'held_out': round(worst(found.held_out), 4)}
        for name, rep in found.reports.items():
            out[muscle][name] = {
                'paper': PAPER_TABLE3[muscle][name],
                'paper_protocol': round(rep.paper.err, 4),
                'best': round(rep.best_err, 4),
                'cv': round(rep.cv_err, 4),
            }
    return {'table3': out}


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
        held_out_table(
            shipped_force_map(muscle).lengths, {n: r.nested for n, r in found.reports.items()}
        )
        print(_default_line(found))


def _default_line(found: Identification) -> str:
    """How the default model was chosen, with the nested figure of that choice."""
    from ..core.identification.selection import MODEL_RULE

    picks = ', '.join(
        f'{name} x{found.chosen.count(name)}' for name in dict.fromkeys(found.chosen)
    )
    return (
        f'default model (lowest {MODEL_RULE} err): {found.default}; the choice made again '
        f'without each length ({picks}) errs by {worst(found.held_out):.2f} % at worst (the '
        "whole protocol's figure, not the default model's own)"
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
    from ..core.files.param_writer import build_parameters, model_entry, write_parameters
    from ..core.identification.protocols import domain_of

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
        spec = shipped_spec(args.muscle)
        models = {
            name: model_entry(rep, fmap, spec.nominal_length)
            for name, rep in found.reports.items()
        }
        params = build_parameters(spec, found.default, domain_of(fmap), models)
        header += f'\n{FILE_LEGEND}'
    write_parameters(args.out, params, header)
    print(f'wrote {args.out}')


def cmd_scale(args: argparse.Namespace) -> None:
    from ..core.files.param_writer import write_parameters
    from ..core.files.user_files import load_yaml_mapping, read_user_file
    from ..core.identification.transfer import check_rest_length, given_length, scale_parameters

    text = read_user_file(args.config, 'parameter file')
    data = load_yaml_mapping(text, str(args.config))
    nodes = [k for k, v in data.items() if isinstance(v, dict) and 'ros__parameters' in v]
    if len(nodes) > 1:
        raise CliError(f"{args.config}: {len(nodes)} nodes in one file; scale one muscle's file")
    parameters = read_parameters(args.config)
    comments = ''.join(line for line in text.splitlines(True) if line.startswith('#'))
    try:
        given, note = given_length(parameters, comments)
    except ValueError as err:
        raise CliError(f'{args.config}: {err}') from None
    try:
        check_rest_length(args.length, given)
    except ValueError as err:
        raise CliError(f'--length {args.length:g}: {err}') from None
    try:
        scaled, notes = scale_parameters(parameters, args.length, given)
    except ValueError as err:
        raise CliError(f'{args.config}: {err}') from None
    source, target = parameters['muscle'], scaled['muscle']
    ratio = args.length / given
    calibrated = [
        f'{name} {block["nominal_length"]:.6g} m'
        for name, block in scaled['models'].items()
        if 'nominal_length' in block
    ]
    header = (
        f'{target["name"]}: {source["name"]} of {args.config} cut to the given rest length '
        f"L0' = {args.length:g} m by `pma-model scale` (s = L0' / L0 = {args.length:g} / "
        f'{given:g} = {ratio:.6g}; a calibrated L0 moves by s).\n'
        "At equal contraction (L0 - L) / L0 and pressure it serves the source's force; lengths\n"
        "are s times the source's (docs/calibration.md). err, rmse, r2, cv_err and held_out err\n"
        "are the source map's figures, at equal contraction."
    )
    write_parameters(args.out, {nodes[0]: {'ros__parameters': scaled}}, header)
    low, high = scaled['length_range']
    print(
        f'wrote {args.out}: {target["name"]} ({source["name"]} x {ratio:.6g}: given L0 '
        f'{given:g} -> {args.length:g} m), length_range [{low:.6g}, {high:.6g}] m'
    )
    if calibrated:
        print(f'  calibrated L0: {", ".join(calibrated)}')
    for line in ([note] if note else []) + notes:
        print(f'  {line}')


def describe_geometry(fit: Fit, given_length: float) -> str:
    """The identified L0 and pressure offset of a calibrated fit with their uncertainty, or why
    each stayed as given.
    """
    sigma, parts = fit.sigma, []
    longest, length = fit.domain.length_max, fit.spec.nominal_length
    if fit.calibration.length and given_length < longest:
        parts.append(
            f'L0 {length:.4f} '
            + (f'±{sigma["nominal_length"]:.4f} ' if length > longest else '')
            + f'm (given {given_length:.4f} m: raised to the longest measured row {longest:.4g} m'
            + (
                f', identified above it where the map is slack (slack length '
                f'{fit.slack_length:.4f} m)'
                if length > longest
                else '; the model absorbs or ignores a longer L0'
                if math.isinf(sigma.get('nominal_length', 0.0))
                else '; the slack length, where a threshold (the pressure offset) fits the map '
                'better than a longer L0'
                if 'nominal_length' in sigma
                else ''
            )
            + ')'
        )
    elif fit.calibration.length:
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
    from ..core.files.param_writer import build_parameters, model_entry, write_parameters
    from ..core.identification.bounds import at_bounds
    from ..core.identification.map_checks import unsolvable
    from ..core.identification.protocols import check_fit_map
    from ..core.identification.selection import identify_all, MODEL_RULE

    spec = read_spec_yaml(args.muscle)
    if args.model != 'all' and get_model(args.model).hysteresis:
        return fit_branches(args, spec)
    if args.hysteresis_input is not None:
        raise CliError(f'--hysteresis-input: --model {args.model} has no hysteresis branches')
    fmap = read_force_map_csv(args.data) if args.data else bag_force_map(args, spec)
    check_fit_map(fmap, spec, folds=3)
    calibration = Calibration(not args.no_calibrate_length, not args.no_calibrate_pressure)
    longest = None if calibration.length else short_of_map(spec, fmap)
    if longest is not None:
        raise CliError(
            f'{args.muscle}: nominal_length {spec.nominal_length:g} m is shorter than the '
            f'longest measured length {longest:g} m, and a muscle is not stretched beyond its '
            'rest length: measure L0 again, or leave out --no-calibrate-length to have it '
            'raised to what the map shows'
        )
    print(calibration.describe() + ' (switch off: --no-calibrate-length, --no-calibrate-pressure)')
    names = TABLE3_MODELS if args.model == 'all' else (args.model,)
    try:
        found = identify_all(
            spec, fmap, tuple(get_model(m) for m in names), calibration, (args.objective,)
        )
    except np.linalg.LinAlgError as err:
        raise CliError(unsolvable(spec, err)) from None
    reports = found.reports
    print_in_sample(args.objective, {name: (r.shipped, r.cv_err) for name, r in reports.items()})
    if calibration.any:
        print('\nidentified geometry (L0 ± its profile 1-sigma; pressure offset ± 1-sigma):')
        for name, rep in reports.items():
            print(f'  {name}: {describe_geometry(rep.shipped, spec.nominal_length)}')
    bounded = [
        f'{name}: {line}'
        for name, rep in reports.items()
        for line in at_bounds(get_model(name), rep.shipped.theta, rep.shipped.spec, fmap)
    ]
    if bounded:
        print('\nparameters at a bound of the search:\n' + '\n'.join(f'  {b}' for b in bounded))
    print_nested(fmap, {name: rep.nested for name, rep in reports.items()})
    chosen = reports[found.default].shipped
    write_parameters(
        args.out,
        build_parameters(
            chosen.spec,
            found.default,
            chosen.domain,
            {
                name: model_entry(rep, fmap, chosen.spec.nominal_length)
                for name, rep in reports.items()
            },
            given_length=spec.nominal_length,
        ),
        f'{spec.name} identified from {args.data or args.bag} by `pma-model fit` '
        f'({calibration.describe()}; given nominal_length {spec.nominal_length:g} m).\n'
        + FILE_LEGEND
        + ''.join(f'\n{line}' for line in bounded),
    )
    # the written model's own figures: the file's, the force band's and /diagnostics'
    written = reports[found.default].nested
    rows = rows_to_add(written, fold_lengths(fmap), chosen.spec, spec.nominal_length)
    if rows:
        print('\n' + rows)
    if len(reports) > 1:
        print('\n' + _default_line(found))
        how = f'by {MODEL_RULE} err; its own figures, as its file serves them'
    else:
        how = 'the one fitted'
    print('\n' + written_line(how, found.default, chosen, written, args.out))


def cmd_evaluate(args: argparse.Namespace) -> None:
    from ..core.identification.protocols import quality

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


def add_identify_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``reproduce``, ``make-config``, ``fit``, ``scale`` and ``evaluate`` to the
    ``pma-model`` subparsers.
    """
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
        help="model name, e.g. martens; 'all': every Table 3 model, the default by mean held-out "
        'error',
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
    p.add_argument(
        '--hysteresis-input',
        choices=HYSTERESIS_INPUTS,
        help="what a map's direction column follows (a two-branch model): pressure (filling "
        '+1, venting -1) or length (lengthening +1, shortening -1)',
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
    p.add_argument(
        '--length',
        required=True,
        type=float,
        help="the new cut's measured rest length L0' [m], as the source's given L0 (0.04..9)",
    )
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
