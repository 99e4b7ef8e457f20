"""Cut-to-length transfer between two labs' DMSP-20s: how far ``pma-model scale`` carries a fit.

Two directions, each with the length a user types (the target's measured rest length, in the
sense of the source's given L0: ``pma-model scale --length 0.274`` and ``--length 0.3``), judged
per measured length by eq. 23 (the worst |error| of the length, in % of the target map's max
force) on the served force:

* the shipped DMSP-20-300 (``config/dmsp_20_300.yaml``, Table A1, given L0 0.300 m) cut to
  0.274 m, on the independent DMSP-20-274 fill map;
* the independent map fitted (``pma-model fit --model martens``, its default calibration: given
  L0 0.274 m, a calibrated L0 moving by the same factor) and cut to 0.300 m, on the shipped Table
  A1 map.

A' and B' cut so that the one's given L0 meets the other's calibrated one instead (where the
independent fit calibrated its L0): how much of the two-lab gap is where the rest length is.
Each without and with a one-row recalibration: a force gain g fitted on the target's rest-length
row alone (least squares, closed form g = sum(F m) / sum(m^2), m the transferred model's force),
judged on the other rows.  Table A1 has no 0.300 m row: its longest row (0.296 m, 1.3 %
contraction) stands for it.  Rows whose contraction lies outside the source's identified
contractions (the transferred ``length_range``) are reported apart.

The independent maps are read from ``../shared/data/independent-muscles/`` (their README: never
copied into the package or its tests); without them the benchmark says so and stops.

Usage: ``.venv/bin/python bench/transfer.py [--quick]`` (``--quick``: direction B fits without
the geometry calibration, ``--no-calibrate-length --no-calibrate-pressure``, faster).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import math
from pathlib import Path
import tempfile

from _cli import run
import numpy as np

from pma_model_ros.core.files.param_file import load_muscle, read_parameters
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.identification.force_map import ForceMap, read_force_map_csv
from pma_model_ros.core.physics.muscle_model import MuscleModel

REPO = Path(__file__).resolve().parents[1]
INDEPENDENT = REPO.parent / 'shared' / 'data' / 'independent-muscles'
MAP_274 = INDEPENDENT / 'dmsp20_274_fill.csv'
SPEC_274 = INDEPENDENT / 'dmsp20_274.yaml'
SHIPPED_300 = REPO / 'config' / 'dmsp_20_300.yaml'


def _err(fmap: ForceMap, model: np.ndarray, at: np.ndarray) -> float:
    """Eq. 23 of the points ``at``: worst |error| in % of the map's max force."""
    return float(np.max(np.abs(fmap.force[at] - model[at]))) / fmap.max_force * 100


def judge(config: Path, fmap: ForceMap, title: str) -> dict:
    """Print the per-length table of the parameter file ``config`` on ``fmap``; return the worst
    figures.
    """
    muscle = load_muscle(config)
    parameters = read_parameters(config)
    l0 = muscle.spec.nominal_length
    low, high = parameters['length_range']
    model = np.nan_to_num(muscle.force(fmap.pressure, fmap.length).force)
    # the model's own value outside the identified lengths, where the file holds the nearest
    wide = MuscleModel(
        muscle.spec, muscle.model, muscle.theta, replace(muscle.domain, extrapolates=True)
    )
    own = np.nan_to_num(wide.force(fmap.pressure, fmap.length).force)
    rest = fmap.lengths.max()  # descending; the row nearest the rest length
    at_rest = fmap.length == rest
    m, f = model[at_rest], fmap.force[at_rest]
    gain = float(np.dot(f, m) / np.dot(m, m))
    print(f'\n{title}')
    print(
        f'model {muscle.model.name}, L0 {l0:.4f} m, identified (transferred) lengths '
        f'[{low:.4f}, {high:.4f}] m; gain on the {rest:.3f} m row: g = {gain:.3f}'
    )
    print(
        f'{"length [m]":>10}{"kappa [%]":>10}{"points":>7}{"source":>9}'
        f'{"err [%]":>9}{"g: err [%]":>12}'
        + ('' if muscle.domain.extrapolates else f'{"own value: err, g: err [%]":>29}')
    )
    worst = dict.fromkeys(('in', 'out', 'in_g', 'out_g'), math.nan)
    for length in fmap.lengths:
        at = fmap.length == length
        err, err_g = _err(fmap, model, at), _err(fmap, gain * model, at)
        inside = low - 1e-9 <= length <= high + 1e-9
        side = 'in' if inside else 'out'
        worst[side] = np.fmax(worst[side], err)
        if length != rest:
            worst[f'{side}_g'] = np.fmax(worst[f'{side}_g'], err_g)
        print(
            f'{length:>10.4f}{(l0 - length) / l0 * 100:>10.2f}{int(at.sum()):>7}'
            f'{"inside" if inside else "OUTSIDE":>9}{err:>9.2f}'
            + (f'{"(fitted)":>12}' if length == rest else f'{err_g:>12.2f}')
            + (
                f'{_err(fmap, own, at):>17.2f}{_err(fmap, gain * own, at):>12.2f}'
                if not (inside or muscle.domain.extrapolates)
                else ''
            )
        )
    text = {k: 'no row' if math.isnan(v) else f'{v:.2f}' for k, v in worst.items()}
    print(
        f"worst err [%]: inside the source's contractions {text['in']} (with g, other rows: "
        f'{text["in_g"]}); outside {text["out"]} (with g, other rows: {text["out_g"]})'
    )
    return worst | {'gain': gain}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='fit without geometry calibration')
    args = parser.parse_args()
    if not (MAP_274.is_file() and SPEC_274.is_file()):
        print(f'skipped: the independent DMSP-20 map is not in {INDEPENDENT}')
        return 0
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        fitted, cut_300 = tmp / 'fit_274.yaml', tmp / 'dmsp_20_300.yaml'
        quick = ['--no-calibrate-length', '--no-calibrate-pressure'] if args.quick else []
        run(
            [
                'fit',
                '--data',
                str(MAP_274),
                '--muscle',
                str(SPEC_274),
                '--model',
                'martens',
                *quick,
                '--out',
                str(fitted),
            ]
        )
        block = read_parameters(fitted)['models']['martens']
        calibrated = ', '.join(
            f'{key} {block[key]:.6g}'
            for key in ('nominal_length', 'pressure_offset')
            if key in block
        )
        cut_274 = tmp / 'dmsp_20_274.yaml'
        said = run(
            ['scale', '--config', str(SHIPPED_300), '--length', '0.274', '--out', str(cut_274)]
        )
        print('\n$ pma-model scale --config config/dmsp_20_300.yaml --length 0.274')
        print(said, end='')
        judge(
            cut_274,
            read_force_map_csv(MAP_274),
            'A. shipped DMSP-20-300 (config/dmsp_20_300.yaml) cut to 0.274 m, on the independent '
            'DMSP-20-274 fill map',
        )
        if 'nominal_length' in block:
            length = block['nominal_length']
            run(
                [
                    'scale',
                    '--config',
                    str(SHIPPED_300),
                    '--length',
                    repr(length),
                    '--out',
                    str(cut_274),
                    '--overwrite',
                ]
            )
            judge(
                cut_274,
                read_force_map_csv(MAP_274),
                f"A'. the same, cut to the independent fit's calibrated L0 {length:.5g} m",
            )
        said = run(['scale', '--config', str(fitted), '--length', '0.3', '--out', str(cut_300)])
        print('\n$ pma-model scale --config <fit of DMSP-20-274> --length 0.3')
        print(said, end='')
        judge(
            cut_300,
            shipped_force_map('DMSP-20-300'),
            'B. independent DMSP-20-274 fitted (pma-model fit --model martens'
            + (' ' + ' '.join(quick) if quick else '')
            + f'; calibrated: {calibrated or "nothing"}) cut to 0.300 m, on Table A1',
        )
        if 'nominal_length' in block:
            given = read_parameters(fitted)['muscle']['given_nominal_length']
            length = 0.3 * given / block['nominal_length']
            argv = ['--length', repr(length), '--out', str(cut_300), '--overwrite']
            run(['scale', '--config', str(fitted), *argv])
            judge(
                cut_300,
                shipped_force_map('DMSP-20-300'),
                f"B'. the same, cut to --length {length:.5g} m: its calibrated L0 at 0.300 m",
            )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
