"""Start-up of one ``pma-model force`` and ``pma-model pressure`` query against a bare import of
numpy and yaml (what every query needs), measured in one run.

Usage: ``.venv/bin/python bench/cli_startup.py [--quick] [--repeat R]`` (or ``bench/run
cli_startup``).  Not a test: it prints a table.  The processes run in turn, alternating (baseline,
force, pressure, baseline, ...), R of each (``--quick``: R = 5), so a load that comes and goes
falls on all of them alike; ``x baseline`` is each median over the baseline's median of the
same run.  ``scipy`` says whether the query loaded it (it needs no optimizer).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import statistics
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'config' / 'dmsp_10_250.yaml'
#: The console script beside this interpreter (what a user runs), else the module.
CLI = (
    [str(Path(sys.executable).with_name('pma-model'))]
    if Path(sys.executable).with_name('pma-model').exists()
    else [sys.executable, '-m', 'pma_model_ros.cli']
)
COMMANDS = {
    'baseline': [sys.executable, '-c', 'import numpy, yaml'],
    'force': [*CLI, 'force', '--config', str(CONFIG), '--pressure', '300000', '--length', '0.23'],
    'pressure': [*CLI, 'pressure', '--config', str(CONFIG), '--force', '200', '--length', '0.23'],
}
#: Whether a query loads scipy: the same query with the check appended.
SCIPY_CHECK = (
    'import sys; from pma_model_ros.cli.main import main; main({argv!r}); '
    "print('scipy' in sys.modules, file=sys.stderr)"
)


def elapsed(command: list[str]) -> float:
    """Seconds from starting ``command`` to its exit (exit code 0 asserted)."""
    start = time.perf_counter()
    subprocess.run(command, stdout=subprocess.DEVNULL, check=True, cwd=ROOT)
    return time.perf_counter() - start


def loads_scipy(command: list[str]) -> bool:
    argv = command[len(CLI) :]
    code = SCIPY_CHECK.format(argv=argv)
    run = subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    return run.stderr.split()[-1] == 'True'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='5 processes per row')
    parser.add_argument('--repeat', type=int, default=15, help='processes per row (default 15)')
    args = parser.parse_args()
    repeat = 5 if args.quick else args.repeat
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(repeat):
        for name, command in COMMANDS.items():
            times[name].append(elapsed(command))
    base = statistics.median(times['baseline'])
    print(f'{"process":<10}{"best s":>8}{"median s":>10}{"x baseline":>12}  scipy')
    for name, runs in times.items():
        scipy = '' if name == 'baseline' else 'loaded' if loads_scipy(COMMANDS[name]) else 'no'
        median = statistics.median(runs)
        print(f'{name:<10}{min(runs):>8.3f}{median:>10.3f}{median / base:>12.2f}  {scipy}')


if __name__ == '__main__':
    main()
