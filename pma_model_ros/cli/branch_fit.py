"""``pma-model fit`` of a two-branch (hysteresis) model: each branch fitted on its direction's
points, printed in the layout of every fit, the file recording the input the branches follow.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

import numpy as np

from .bags import bag_force_map
from .checks import CliError
from .fit_output import (
    FILE_LEGEND,
    print_in_sample,
    print_nested,
    rows_to_add,
    worst,
    written_line,
)
from ..core.identification.force_map import read_force_map_csv
from ..core.identification.validation import fold_lengths, length_folds
from ..core.physics.models import get_model

if TYPE_CHECKING:
    from ..core.identification.protocols import Fit


def fit_branches(args: argparse.Namespace, spec) -> None:
    """``fit`` of a two-branch (hysteresis) model: each branch on its direction's points,
    uncalibrated, in the layout of every fit; the file records the input the branches follow.
    """
    from ..core.files.param_writer import (
        build_parameters,
        fit_entry,
        held_out_entry,
        write_parameters,
    )
    from ..core.identification.bounds import at_bounds
    from ..core.identification.map_checks import unsolvable
    from ..core.identification.protocols import check_fit_map, fit_best, judge_branches
    from ..core.physics.hysteresis import DEFAULT_DEADBANDS, Follow

    model = get_model(args.model)
    follow = branch_input(args)
    follow = Follow(follow, DEFAULT_DEADBANDS[follow])
    fmap = (
        read_force_map_csv(args.data)
        if args.data
        else bag_force_map(args, spec, two_branches=True)
    )
    check_fit_map(fmap, spec, folds=2)
    given = f'L0 {spec.nominal_length:g} m and no pressure offset, as given'
    print(f'geometry: {given} (a two-branch fit is not calibrated)')
    nested = None
    try:
        if len(length_folds(fmap)) < 3:  # no length between others to judge it on
            fit = fit_best(model, spec, fmap, args.objective)
            entry = fit_entry(fit)
        else:
            fit, nested = judge_branches(model, spec, fmap, args.objective)
            entry = fit_entry(fit) | held_out_entry(model.name, nested, fmap)
    except np.linalg.LinAlgError as err:
        raise CliError(unsolvable(spec, err)) from None
    print_in_sample(
        args.objective, {model.name: (fit, worst(nested) if nested is not None else math.nan)}
    )
    notes = [
        branch_sides(fit, fmap, follow.input),
        *at_bounds(model, fit.theta, spec, fmap, follow.input),
    ]
    print('\n' + '\n'.join(notes))
    if nested is not None:
        print_nested(fmap, {model.name: nested})
        rows = rows_to_add(nested, fold_lengths(fmap), spec)
        if rows:
            print('\n' + rows)
    write_parameters(
        args.out,
        build_parameters(spec, model.name, fit.domain, {model.name: entry}, follow=follow),
        f'{spec.name} identified from {args.data or args.bag} by `pma-model fit` '
        f'({fit.objective}, one branch per direction; {given}).\n'
        + '\n'.join(notes)
        + '\n'
        + FILE_LEGEND,
    )
    print('\n' + written_line('the one fitted', model.name, fit, nested, args.out))


def branch_input(args: argparse.Namespace) -> str:
    """What the map's directions follow: ``--hysteresis-input`` (a CSV's ``direction`` column
    says only +1 or -1), the length for a recording (its samples' branches are the length's).
    """
    if args.bag:
        if args.hysteresis_input not in (None, 'length'):
            raise CliError(
                "--hysteresis-input pressure: a recording's branches are those of its length's "
                'motion (lengthening or shortening); leave it out with --bag'
            )
        return 'length'
    if args.hysteresis_input is None:
        raise CliError(
            f"--model {args.model}: say what the map's direction column follows: "
            '--hysteresis-input pressure (filled +1 and vented -1 at held lengths) or '
            '--hysteresis-input length (lengthened +1 and shortened -1 at held pressures)'
        )
    return args.hysteresis_input


def branch_sides(fit: Fit, fmap, follow: str) -> str:
    """Which branch of a two-branch fit is the upper, at the map's points: the difference of the
    two branches' served forces [N] there (where a muscle is slack both serve 0 N).
    """
    from ..core.physics.hysteresis import branch_name

    ones = np.ones(fmap.force.size)
    gap = fit.force(fmap.pressure, fmap.length, ones) - fit.force(
        fmap.pressure, fmap.length, -ones
    )
    below, above = gap[gap < 0], gap[gap > 0]
    rising, falling = branch_name(follow, 1.0), branch_name(follow, -1.0)
    head = f'branches (hysteresis.input: {follow}): '
    if not above.size or not below.size:
        side = above if above.size else -below
        return head + (
            f'{rising} is the {"upper" if above.size else "lower"} branch (direction +1), '
            f'{"above" if above.size else "below"} {falling} (-1) at every pulling point of the '
            f'map, by {side.min():.3g} to {side.max():.3g} N'
        )
    return head + (
        f"{rising} (direction +1) is below {falling} (-1) at {below.size} of the map's points "
        f'(by up to {-below.min():.3g} N) and above it at {above.size} (by up to '
        f'{above.max():.3g} N): neither is the upper branch everywhere'
    )
