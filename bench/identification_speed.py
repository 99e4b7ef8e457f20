"""Identification speed: the ``best`` protocol for every model of the paper's Table 3 on both
shipped maps, and the ``pma-model fit`` commands a user runs, with the nested held-out table.

Usage: ``.venv/bin/python bench/identification_speed.py [--quick]`` (or ``bench/run``).  Not a
test: it prints tables.  Absolute times depend on the machine's load; the ratios, each taken within
one row of one run, are what to compare.  The command table's baseline is the same interpreter
importing the CLI (what every command pays before fitting).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from pma_model_ros.core.files.shipped_data import MAPPED_MUSCLES, shipped_force_map, shipped_spec
from pma_model_ros.core.identification.protocols import fit_best_all, physical_force
from pma_model_ros.core.identification.selection import identify_all
from pma_model_ros.core.identification.validation import OBJECTIVES
from pma_model_ros.core.physics.models import get_model, TABLE3_MODELS

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
        f'\nbest protocol, one fit = fit_best_all (variable projection, least_squares + minimax; '
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
        '\nidentify_all (= pma-model reproduce): per model and both objectives the paper '
        'protocol and best fits\nwithout no, one and each pair of lengths (the nested choice of '
        'objective and model). fits =\nfit_best_all calls; x fits = identify_all time / that '
        "muscle's six fits in the table above (same run)."
    )
    print(f'{"muscle":<13}{"lengths":>8}{"fits":>6}{"total s":>9}{"s per fit":>11}{"x fits":>8}')
    grand = 0.0
    for muscle in MAPPED_MUSCLES:
        spec, fmap = shipped_spec(muscle), shipped_force_map(muscle)
        _, t_all = timed(lambda: identify_all(spec, fmap, MODELS))
        m = fmap.lengths.size
        n_fits = len(MODELS) * (1 + m + m * (m - 1) // 2)
        grand += t_all
        print(
            f'{muscle:<13}{m:>8d}{n_fits:>6d}{t_all:>9.1f}{t_all / n_fits:>11.3f}'
            f'{t_all / fit_totals[muscle]:>8.1f}'
        )
    print(f'total {grand:.1f} s')


def command_table(repeat: int) -> None:
    """Wall time of ``pma-model fit`` as a user runs it (nested held-out table included), best of
    ``repeat``, next to the same interpreter importing the CLI.
    """
    data = Path(__file__).resolve().parents[1] / 'pma_model_ros' / 'core' / 'data'
    python = sys.executable

    def best(argv: list[str]) -> float:
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            subprocess.run(argv, check=True, capture_output=True)
            times.append(time.perf_counter() - start)
        return min(times)

    base = best([python, '-c', 'import pma_model_ros.cli.main'])
    print(
        f'\npma-model fit, wall time best of {repeat} [s]; import of the CLI alone: {base:.2f} s'
    )
    print(f'{"muscle":<13}{"--model":<9}{"fit s":>7}{"x import":>10}')
    with tempfile.TemporaryDirectory() as tmp:
        for muscle in MAPPED_MUSCLES:
            stem = muscle.lower().replace('-', '_')
            for model in ('martens', 'all'):
                argv = [
                    python, '-m', 'pma_model_ros.cli', 'fit',
                    '--data', str(data / f'{stem}_force_map.csv'),
                    '--muscle', str(data / f'{stem}.yaml'),
                    '--model', model, '--out', str(Path(tmp) / 'fit.yaml'), '--overwrite',
                ]  # fmt: skip
                t = best(argv)
                print(f'{muscle:<13}{model:<9}{t:>7.2f}{t / base:>10.1f}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--quick', action='store_true', help='only the per-fit and command tables (one run each)'
    )
    args = parser.parse_args()
    print('identification speed: pma_model_ros.core.identification, best protocol, Table 3 models')
    fit_totals = per_fit_table()
    if not args.quick:
        identify_all_table(fit_totals)
    command_table(1 if args.quick else 3)


if __name__ == '__main__':
    main()
