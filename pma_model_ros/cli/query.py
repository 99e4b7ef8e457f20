"""``pma-model force`` and ``pressure``: one muscle of a parameter file queried at one point, with
the expected error of the answer.
"""

from __future__ import annotations

import argparse
import math

from .checks import CliError, finite, gauge_pressure
from ..core.files.param_file import (
    held_out_band,
    hysteresis_follow,
    load_muscle,
    one_muscle,
    read_parameters,
)
from ..core.hints import length_hint
from ..core.physics.flags import describe, Flag
from ..core.physics.hysteresis import BRANCH_NAMES, branch_of


def _length(value: float, rest_length: float) -> float:
    """A muscle length [m] of the command line; refused where its magnitude says mm or cm (the
    unit that makes it nearest to the muscle's ``rest_length`` [m]).
    """
    if math.isfinite(value) and 10 < value <= 1e4:
        raise CliError(
            f'--length {value:g} m is longer than any muscle: lengths are in metres; '
            + length_hint(value, rest_length)
        )
    return finite('--length', value, 1e-4, 10.0, 'm', 'lengths are in metres')


def _load(args: argparse.Namespace, parameters: dict | None = None):
    return load_muscle(args.config, args.model, parameters)


def _parameters(args: argparse.Namespace) -> dict:
    """The parameters of the muscle asked for: the file's, or ``--muscle``'s of a ``muscles:``
    file; a joint file is named as such.
    """
    parameters = read_parameters(args.config)
    try:
        return one_muscle(parameters, args.muscle)
    except ValueError as err:
        raise CliError(f'{args.config}: {err}') from None


def _branch(args: argparse.Namespace, parameters: dict, muscle) -> float | None:
    """The hysteresis branch asked for (+1, -1; None: unknown): ``--branch`` by its name, or the
    sign of ``--length-rate`` where the file's branches follow the length.
    """
    if not muscle.model.hysteresis:
        if args.branch is not None:
            raise CliError(f'--branch: model {muscle.model.name} has no hysteresis branches')
        return args.length_rate
    follow = hysteresis_follow(parameters).input
    if args.branch is not None:
        try:
            return branch_of(follow, args.branch)
        except ValueError as err:
            raise CliError(f'--branch {args.branch}: {err}') from None
    if args.length_rate is not None and follow != 'length':
        first, second = BRANCH_NAMES[follow]
        raise CliError(
            f'--length-rate: the branches of {args.config} follow the {follow}, not the length: '
            f'ask for one with --branch {first} or {second}'
        )
    return args.length_rate


def _check_geometry(flags: int, length: float, muscle) -> None:
    if flags & Flag.INVALID_INPUT:
        raise CliError(
            f'length {length:g} m is beyond what the geometry of {muscle.spec.name} allows: '
            f'0 < L < {muscle.max_length:.6g} m (L0/cos(Theta0), its fibre length)'
        )


def cmd_force(args: argparse.Namespace) -> None:
    pressure = gauge_pressure('--pressure', args.pressure)
    parameters = _parameters(args)
    muscle = _load(args, parameters)
    length = _length(args.length, muscle.spec.nominal_length)
    result = muscle.force(pressure, length, _branch(args, parameters, muscle))
    _check_geometry(int(result.flags), length, muscle)
    print(
        f'force {float(result.force):.6g} N  raw {float(result.raw):.6g} N  flags '
        f'{describe(int(result.flags))}'
    )
    band = held_out_band(parameters, args.model)
    held = min(max(length, muscle.limits.length_low), muscle.limits.length_high)
    print(expected_error(band, muscle.domain, pressure, length, int(result.flags), held))


def expected_error(
    band, domain, pressure: float, length: float, flags: int, held: float | None = None
) -> str:
    """The ``expected error:`` line of ``force``: within the identified pressures (served as such,
    up to ``domain.pressure_max`` [Pa]), the held-out band's figure at ``length`` [m]: between the
    measured lengths the interpolation's, beyond them the extrapolation's, and where the force is
    held at the length ``held`` [m] (LENGTH_OUT_OF_RANGE in ``flags``) the edge figure, said to
    be no figure at ``length`` itself; else why it is unknown.
    """
    if band is None:
        return 'expected error: unknown (the parameter file has no held_out errors)'
    if flags & Flag.PRESSURE_OUT_OF_RANGE or pressure > domain.pressure_max:
        return (
            f'expected error: unknown: {pressure:g} Pa is outside the identified pressures '
            f'0..{domain.pressure_max:g} Pa (the held-out errors hold within them)'
        )
    percent, inside = band.at(length, held=bool(flags & Flag.LENGTH_OUT_OF_RANGE))
    of = f'{percent:.2f} % of {band.max_force:.4g} N'
    lengths = f'{min(band.lengths):.4g}..{max(band.lengths):.4g} m'
    if band.slack_at(length):
        why = (
            "the map's worst held-out err: the held-out lengths that judge it measured no force, "
            'so their own 0 % says only that the model is slack where the muscle was'
        )
    elif flags & Flag.LENGTH_OUT_OF_RANGE:
        why = (
            f'held: {length:g} m is beyond the lengths served, and the force is the one at '
            f'{held:g} m; the worst held-out err of the shortest and longest of the measured '
            f'lengths {lengths}, each served from a fit without it (not a figure at {length:g} m)'
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
    force = finite('--force', args.force, -1e7, 1e7, 'N', 'force in newtons')
    parameters = _parameters(args)
    muscle = _load(args, parameters)
    length = _length(args.length, muscle.spec.nominal_length)
    result = muscle.pressure(force, length, _branch(args, parameters, muscle))
    _check_geometry(int(result.flags), length, muscle)
    print(f'pressure {float(result.pressure):.6g} Pa  flags {describe(int(result.flags))}')


def add_query_commands(sub: argparse._SubParsersAction) -> None:
    """Add ``force`` and ``pressure`` to the ``pma-model`` subparsers."""
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
        branch = p.add_mutually_exclusive_group()
        branch.add_argument(
            '--length-rate',
            type=float,
            default=None,
            help='length rate [m/s]; its sign picks the hysteresis branch (branches that follow '
            'the length)',
        )
        branch.add_argument(
            '--branch',
            choices=[name for names in BRANCH_NAMES.values() for name in names],
            help="a hysteresis model's branch: filling or venting (hysteresis.input: pressure), "
            'lengthening or shortening (length)',
        )
        p.add_argument('--model', default=None, help="override the file's default model")
        p.add_argument('--muscle', help="the muscle of a file with 'muscles:' (its name)")
        p.set_defaults(func=func)
