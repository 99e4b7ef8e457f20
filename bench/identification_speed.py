"""Identification speed: the ``best`` protocol for every model of the paper's Table 3, on both
shipped maps.

Usage: ``.venv/bin/python bench/identification_speed.py [--quick]`` (or ``bench/run``).  Not a
test: it prints tables.  Absolute times depend on the machine's load; the ratios, each taken within
one row of one run, are what to compare.
"""

from __future__ import annotations

import argparse
import time

from pma_model_ros.core.identification import (
    fit_best_all,
    identify_all,
    OBJECTIVES,
    physical_force,
)
from pma_model_ros.core.models import get_model, TABLE3_MODELS
from pma_model_ros.core.shipped_data import MAPPED_MUSCLES, shipped_force_map, shipped_spec

MODELS = tuple(get_model(name) for name in TABLE3_MODELS)


def timed(fn):
    """(result, wall time [s]) of one call."""
    start = time.perf_counter()
    result = fn()
    return result, time.perf_counter() - start


def per_fit_table() -> dict[str, float]:
    """One ``fit_best_all`` per model and muscle; returns the time of all models' fits per muscle
    [s].
    """
    print(
        f'\nbest protocol, one fit = fit_best_all (multi-start least_squares + minimax; '
        f'objectives {OBJECTIVES}).'
    )
    print(
        'ref = one evaluation of the clipped model on the whole map (the residual of every fit '
        'step);'
    )
    print("x ref = fit time / ref time: the fit's cost in model evaluations.")
    print(
        f'{"muscle":<13}{"model":<15}{"points":>7}{"fit s":>8}{"ref us":>8}{"x ref":>9}'
        f'{"err %":>7}'
    )
    totals = dict.fromkeys(MAPPED_MUSCLES, 0.0)
    for muscle in MAPPED_MUSCLES:
        spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
        for model in MODELS:
            fits, t_fit = timed(lambda: fit_best_all(model, spec, fmap))
            fit = fits['minimax']
            calls = 1000
            _, t_ref = timed(
                lambda: [
                    physical_force(model, fit.theta, spec, fit.domain, fmap.pressure, fmap.length)
                    for _ in range(calls)
                ]
            )
            t_ref /= calls
            totals[muscle] += t_fit
            print(
                f'{muscle:<13}{model.name:<15}{fmap.force.size:>7d}{t_fit:>8.2f}'
                f'{t_ref * 1e6:>8.1f}'
                f'{t_fit / t_ref:>9.0f}{fit.err:>7.2f}'
            )
    n_fits, total = len(MAPPED_MUSCLES) * len(MODELS), sum(totals.values())
    print(f'total {total:.1f} s for {n_fits} fits, {total / n_fits:.2f} s per fit')
    return totals


def identify_all_table(fit_totals: dict[str, float]) -> None:
    """``identify_all`` per muscle: what ``pma-model reproduce`` computes."""
    print(
        '\nidentify_all (= pma-model reproduce): per model the paper protocol, one best fit on '
        'the map and'
    )
    print(
        'one per held-out length (cross-validation). fits = fit_best_all calls; s per fit '
        'includes the paper'
    )
    print(
        "protocol. x fits = identify_all time / that muscle's six fits in the table above (same "
        'run); about'
    )
    print(
        '1 + lengths if a fit on a map with one length held out costs as much as one on the whole '
        'map.'
    )
    print(f'{"muscle":<13}{"lengths":>8}{"fits":>6}{"total s":>9}{"s per fit":>11}{"x fits":>8}')
    grand = 0.0
    for muscle in MAPPED_MUSCLES:
        spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
        _, t_all = timed(lambda: identify_all(spec, fmap, MODELS))
        n_fits = len(MODELS) * (1 + fmap.lengths.size)
        grand += t_all
        print(
            f'{muscle:<13}{fmap.lengths.size:>8d}{n_fits:>6d}{t_all:>9.1f}{t_all / n_fits:>11.2f}'
            f'{t_all / fit_totals[muscle]:>8.1f}'
        )
    print(f'total {grand:.1f} s')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--quick', action='store_true', help='only the per-fit table (skips identify_all, ~30 s)'
    )
    args = parser.parse_args()
    print('identification speed: pma_model_ros.core.identification, best protocol, Table 3 models')
    fit_totals = per_fit_table()
    if not args.quick:
        identify_all_table(fit_totals)


if __name__ == '__main__':
    main()
