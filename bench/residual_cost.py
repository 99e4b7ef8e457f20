"""The drift monitor's own work per message and per /diagnostics report, in-process (no ROS).

Usage: ``.venv/bin/python bench/residual_cost.py [--samples 10000] [--repeat 5] [--quick]``;
another checkout's: ``PYTHONPATH=DIR .venv/bin/python bench/residual_cost.py`` (before/after).
Not a test: it prints a table.

``Residuals`` (``core/runtime/residual.py``) of 1 and 64 muscles with the DMSP-10-250 file's band,
fed at 1 kHz: per call, ``served`` (one muscle) or ``served_all`` (64), then that and ``measured``
or ``measured_all`` of the same stamp (a message's work; ``--samples`` calls per run, stamps 1 ms
apart); then, with the window (10 s) full, the report's ``figures`` of every muscle.  Each time is
the best of ``--repeat``, next to a bare baseline timed in the same run: one numpy ufunc call on as
many floats (``np.add``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import time
from typing import Callable

import numpy as np

from pma_model_ros.core.files.param_file import held_out_band, muscle_model, read_parameters
from pma_model_ros.core.runtime.residual import Residuals

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'dmsp_10_250.yaml'
MS = 1_000_000  # [ns]


def best(fn: Callable[[int], object], calls: int, repeat: int) -> float:
    """[us] per call of ``fn(i)``, the best of ``repeat`` runs of ``calls`` calls; i counts on
    over the runs (0 .. repeat * calls - 1: a new stamp each call).
    """
    times = []
    for run in range(repeat):
        start = time.perf_counter()
        for i in range(run * calls, (run + 1) * calls):
            fn(i)
        times.append((time.perf_counter() - start) / calls * 1e6)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--samples', type=int, default=10_000, help='calls per run (1 ms apart: window samples)'
    )
    parser.add_argument('--repeat', type=int, default=5, help='runs per row, the best kept')
    parser.add_argument('--quick', action='store_true', help='2 runs per row (bench/run --quick)')
    args = parser.parse_args()
    if args.quick:
        args.repeat = 2
    parameters = read_parameters(CONFIG)
    model, band = muscle_model(parameters), held_out_band(parameters)
    top = float(model.domain.pressure_max)
    gauge, length = 3e5, 0.23
    served = float(model.force(gauge, length).force)
    print(f'drift monitor cost, best of {args.repeat} runs; baseline: one np.add on n floats')
    print(f'{"muscles":>7} {"call":<38} {"us":>9} {"x baseline":>10}')
    for n in (1, 64):
        r = Residuals([band] * n, [top] * n, ['martens'] * n, 100 * MS)
        ks, forces = np.arange(n), np.full(n, served)
        gauges, lengths, flags = np.full(n, gauge), np.full(n, length), np.zeros(n, np.uint16)
        measured = np.full(n, served + 5.0)
        a, b = np.ones(n), np.ones(n)
        base = best(lambda i: np.add(a, b), 20_000, args.repeat)
        if n == 1:
            alone = Residuals([band], [top], ['martens'], 100 * MS)

            def cycle(i: int) -> None:
                r.served(0, i * MS, served, gauge, length, 0)
                r.measured(0, i * MS, served + 5.0, i * MS)

            calls = {
                'served': lambda i: alone.served(0, i * MS, served, gauge, length, 0),
                'served + measured': cycle,
            }
        else:
            alone = Residuals([band] * n, [top] * n, ['martens'] * n, 100 * MS)

            def cycle(i: int) -> None:
                r.served_all(i * MS, None, forces, gauges, lengths, flags)
                r.measured_all(ks, i * MS, measured, i * MS)

            def serve(i: int) -> None:
                alone.served_all(i * MS, None, forces, gauges, lengths, flags)

            calls = {'served_all': serve, 'served_all + measured_all': cycle}
        rows = {name: best(fn, args.samples, args.repeat) for name, fn in calls.items()}
        # paired samples 1 ms apart, the newest at now: the default 10 s window holds 10,000
        now = (args.repeat * args.samples - 1) * MS
        held = r.figures(0, now).samples
        report = best(lambda i: [r.figures(k, now) for k in range(n)], 20, args.repeat)
        rows[f'figures of all ({held} samples each)'] = report
        for name, us in {'np.add (baseline)': base, **rows}.items():
            print(f'{n:>7} {name:<38} {us:>9.2f} {us / base:>10.1f}')


if __name__ == '__main__':
    main()
