"""Start-up of model_node: time from process start to the node built and ready to spin.

Usage: ``scripts/netns-run .venv/bin/python bench/startup.py [--quick] [--repeat R]`` (or
``bench/run startup``).  Not a test: it prints a table.  Each row starts R fresh Python processes
(best and median of R; ``--quick``: R = 3) that print one line when ready: ``baseline`` is bare
rclpy (``rclpy.init()`` and an empty node), ``model_node`` imports the node's module and builds it
from config/dmsp_10_250.yaml as ``ros2 run`` does.  ``x baseline`` is the median over the
baseline's median, measured in the same run; ``scipy.optimize`` says whether the process loaded it.
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
READY = "print('ready', 'scipy.optimize' in sys.modules, flush=True)"
CHILDREN = {
    'baseline': (
        'import sys, rclpy\n'
        'rclpy.init()\n'
        "node = rclpy.create_node('baseline')\n"
        f'{READY}\n'
        'node.destroy_node(); rclpy.shutdown()\n'
    ),
    'model_node': (
        'import sys, rclpy\n'
        'from pma_model_ros.nodes.model_node import ModelNode\n'
        f"rclpy.init(args=['model_node', '--ros-args', '--params-file', {str(CONFIG)!r}])\n"
        'node = ModelNode()\n'
        f'{READY}\n'
        'node.destroy_node(); rclpy.shutdown()\n'
    ),
}


def time_to_ready(code: str) -> tuple[float, bool]:
    """Seconds from starting ``python -c code`` to its ready line; whether it loaded
    scipy.optimize.
    """
    start = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, '-c', code],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        cwd=ROOT,
    )
    line = child.stdout.readline().split()
    elapsed = time.perf_counter() - start
    child.wait(30)
    if not line or line[0] != 'ready':
        raise RuntimeError(f'the child did not get ready: {line}')
    return elapsed, line[1] == 'True'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='3 processes per row')
    parser.add_argument('--repeat', type=int, default=7, help='processes per row (default 7)')
    args = parser.parse_args()
    repeat = 3 if args.quick else args.repeat
    print(f'{"process":<12}{"best s":>8}{"median s":>10}{"x baseline":>12}  scipy.optimize')
    base = None
    for name, code in CHILDREN.items():
        runs = [time_to_ready(code) for _ in range(repeat)]
        times = [t for t, _ in runs]
        median = statistics.median(times)
        base = base or median
        print(
            f'{name:<12}{min(times):>8.3f}{median:>10.3f}{median / base:>12.2f}  '
            f'{"loaded" if runs[0][1] else "not loaded"}'
        )


if __name__ == '__main__':
    main()
