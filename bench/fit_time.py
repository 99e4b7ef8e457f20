"""``pma-model fit``'s time: ``--model martens`` and ``--model all`` on each map, this checkout's
code alternated with another checkout's (``--before DIR``, e.g. ``git worktree add DIR <commit>``),
best of 3 per map.

Each run is ``python -m pma_model_ros.cli fit --data <map> --muscle <spec> --model <m>`` in a
process of its own, from a temporary working folder, with ``PYTHONPATH`` the checkout's root; both
checkouts fit the same files (this checkout's shipped maps and specs, and the fill branch of the
independent maps of ``../shared/data/independent-muscles/`` when present).  Modules are compiled
once into a cache of the benchmark's own (``PYTHONPYCACHEPREFIX``, one unmeasured run per checkout
first), as in an installed package.  Printed per map and ``--model``: the wall time [s], best of
``--repeat``, of each checkout, their ratio, and the CPU time [s] (user + sys of the command and
its worker processes) of those best runs.  The runs alternate (before, this, before, this, ...),
so a load that comes and goes falls on both.

Usage: ``.venv/bin/python bench/fit_time.py [--before DIR] [--repeat N] [--quick]``; ``--quick``:
``--model martens`` on DMSP-20-300 once (a check that the script runs).  Not a test; its times mean
something only on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
INDEPENDENT = REPO.parent / 'shared' / 'data' / 'independent-muscles'
DATA = REPO / 'pma_model_ros' / 'core' / 'data'
MAPS = {
    'DMSP-10-250': (DATA / 'dmsp_10_250_force_map.csv', REPO / 'config/muscles/dmsp_10_250.yaml'),
    'DMSP-20-300': (DATA / 'dmsp_20_300_force_map.csv', REPO / 'config/muscles/dmsp_20_300.yaml'),
    'DMSP-20-274': (INDEPENDENT / 'dmsp20_274_fill.csv', INDEPENDENT / 'dmsp20_274.yaml'),
    'DMSP-10-382': (INDEPENDENT / 'dmsp10_382_fill.csv', INDEPENDENT / 'dmsp10_382.yaml'),
}
MODELS = ('martens', 'all')
#: Counts the fits ``fit`` computes, in every process: ``identify_all`` as ``fit`` calls it, with
#: the least-squares fits and the linear solves counted in shared memory (forked workers inherit
#: the counters; a checkout that spawns its workers is counted in one process, where it computes
#: the same fits).  argv: map, spec, model, workers (0: as ``fit`` does).
COUNT = """
import multiprocessing, os, sys
from pma_model_ros.core.identification import separable, selection
from pma_model_ros.core.identification.calibration import Calibration
from pma_model_ros.core.identification.force_map import read_force_map_csv
from pma_model_ros.core.files.user_files import read_spec_yaml
from pma_model_ros.core.physics.models import get_model, TABLE3_MODELS
data, spec, model, workers = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
fits, solves = multiprocessing.Value('l', 0), multiprocessing.Value('l', 0)
def counting(counter, function):
    def counted(*args):
        with counter.get_lock():
            counter.value += 1
        return function(*args)
    return counted
S = separable.Separable
for counter, asked, computed in (
    (fits, 'fit_least_squares', '_least_squares'),
    (solves, 'linear_least_squares', '_linear_least_squares'),
):
    name = computed if hasattr(S, computed) else asked  # a checkout that remembers none
    setattr(S, name, counting(counter, getattr(S, name)))
options = {}
if 'workers' in selection.identify_all.__code__.co_varnames:
    options = {'workers': workers} if workers else {}
elif workers == 1:
    os.cpu_count = lambda: 1
names = TABLE3_MODELS if model == 'all' else (model,)
selection.identify_all(
    read_spec_yaml(spec), read_force_map_csv(data), tuple(get_model(m) for m in names),
    Calibration(), ('least_squares',), **options
)
print(fits.value, solves.value)
"""


def fit(root: Path, data: Path, spec: Path, model: str, folder: Path) -> tuple[float, float]:
    """(wall time [s], CPU time [s] of the command and its workers) of one ``pma-model fit`` with
    the code of the checkout ``root``.
    """
    env = {k: v for k, v in os.environ.items() if k != 'PYTHONDONTWRITEBYTECODE'}
    env |= {'PYTHONPATH': str(root), 'PYTHONPYCACHEPREFIX': str(folder / 'pycache')}
    argv = [sys.executable, '-m', 'pma_model_ros.cli', 'fit', '--data', str(data)]
    argv += ['--muscle', str(spec), '--model', model, '--out', str(folder / 'fit.yaml')]
    argv += ['--overwrite']
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f'{root}: {" ".join(argv[2:])}: exit {done.returncode}\n{done.stderr}')
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def count(root: Path, data: Path, spec: Path, model: str, workers: int, folder: Path) -> str:
    """'least-squares fits / linear solves' computed by ``fit`` with the code of ``root``."""
    env = os.environ | {'PYTHONPATH': str(root)}
    argv = [sys.executable, '-c', COUNT, str(data), str(spec), model, str(workers)]
    done = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, check=True)
    return '/'.join(done.stdout.split())


def counts(codes: dict[str, Path], cases: list[tuple[str, str]], folder: Path) -> None:
    """The table of ``--count``: the work each checkout's ``fit`` does, which no load changes."""
    print('\npma-model fit, least-squares fits / linear solves computed (in one process; with the')
    print('workers fit starts, forked ones counted with it)')
    print(f'{"map":<13}{"--model":<9}{"before":>16}{"this":>16}{"this, workers":>16}')
    for muscle, model in cases:
        row = f'{muscle:<13}{model:<9}'
        for code, workers in (('before', 1), ('this', 1), ('this', 0)):
            if code in codes:
                row += f'{count(codes[code], *MAPS[muscle], model, workers, folder):>16}'
        print(row)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--before', type=Path, help='a checkout of the code to compare with')
    parser.add_argument('--repeat', type=int, default=3, help='runs per map, code and --model')
    parser.add_argument('--quick', action='store_true', help='DMSP-20-300 --model martens once')
    parser.add_argument('--count', action='store_true', help='count the fits, no times')
    args = parser.parse_args()
    codes = {'this': REPO} | ({'before': args.before.resolve()} if args.before else {})
    cases = [(m, model) for m in MAPS for model in MODELS]
    if args.quick:
        cases, args.repeat = [('DMSP-20-300', 'martens')], 1
    absent = [m for m, _ in cases if not MAPS[m][0].exists()]
    if absent:
        where = INDEPENDENT.relative_to(REPO.parent)
        print(f'skipped {", ".join(sorted(set(absent)))}: {where} is absent')
        cases = [(m, model) for m, model in cases if m not in absent]
    compared = f'; before: {args.before}' if args.before else ''
    print(f'{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}{compared}')
    best: dict[tuple[str, str, str], tuple[float, float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.count:
            return counts(codes, cases, folder)
        for root in codes.values():  # compiles the modules into the cache
            fit(root, *MAPS['DMSP-20-300'], 'martens', folder)
        for _ in range(args.repeat):
            for muscle, model in cases:
                for code in sorted(codes):  # 'before' first
                    run = fit(codes[code], *MAPS[muscle], model, folder)
                    key = (muscle, model, code)
                    best[key] = min(best.get(key, run), run)
    print(f'\npma-model fit, wall time best of {args.repeat} [s] (CPU time of that run [s])')
    header = f'{"map":<13}{"--model":<9}' + ''.join(f'{code:>16}' for code in sorted(codes))
    print(header + ('   this/before' if 'before' in codes else ''))
    for muscle, model in cases:
        row = f'{muscle:<13}{model:<9}'
        for code in sorted(codes):
            wall, cpu = best[(muscle, model, code)]
            row += f'{wall:>8.2f} ({cpu:5.2f})'
        if 'before' in codes:
            this, before = (best[(muscle, model, code)][0] for code in ('this', 'before'))
            row += f'{this / before:>14.2f}'
        print(row)


if __name__ == '__main__':
    main()
