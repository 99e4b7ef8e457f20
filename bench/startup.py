"""Start-up of the nodes: time from process start to the node built and ready to spin, and how
many parameters it shows.

Usage: ``scripts/netns-run .venv/bin/python bench/startup.py [--quick] [--repeat R]`` (or
``bench/run startup``).  Not a test: it prints a table.  Each row starts R fresh Python processes
(best and median of R; ``--quick``: R = 3) that print one line when ready: ``baseline`` is bare
rclpy (``rclpy.init()`` and an empty node); the others import a node's module and build it from a
parameter file as ``ros2 run`` does, with the ``executor`` parameter that :func:`startup.run`
declares: model_node of config/dmsp_10_250.yaml (1 muscle) and of 64 DMSP-10-250 (combined),
``model_node 64+`` the same 64 with three node-wide keys copied into each muscle's block (192
unknown parameters, each warned about), joint_node of 4 example elbows (8 muscles), the two
simulators with their defaults.  ``params``
is what ``ros2 param list`` would list (``list_parameters`` of the node, every depth).
``x baseline`` is the median over the baseline's median, measured in the same run;
``scipy.optimize`` says whether the process loaded it.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

from joint_node_cost import arm  # bench/, this script's folder, is on sys.path
from node_latency import multi_muscle_file
import yaml

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'config' / 'dmsp_10_250.yaml'
READY = (
    "print('ready', 'scipy.optimize' in sys.modules, flush=True)\n"
    'print(len(node.list_parameters([], 0).names), flush=True)\n'
    'node.destroy_node(); rclpy.shutdown()\n'
)


def child(module: str, cls: str, params_file: Path | None, *ros_args: str) -> str:
    """The code of a process that builds node ``cls`` of ``module`` from ``params_file``."""
    args = ['node', '--ros-args', *ros_args]
    args += ['--params-file', str(params_file)] if params_file else []
    return (
        'import sys, rclpy\n'
        f'from pma_model_ros.nodes.{module} import {cls}\n'
        f'rclpy.init(args={args!r})\n'
        f'node = {cls}()\n'
        'from pma_model_ros.nodes.startup import executor\n'
        'executor([node])\n' + READY
    )


def misplaced_keys_file(n: int, folder: Path) -> Path:
    """:func:`multi_muscle_file` with three node-wide keys copied into each muscle's block: 3 n
    unknown parameters, each warned about at start-up.
    """
    data = yaml.safe_load(multi_muscle_file(n, folder).read_text())
    params = data['/**']['ros__parameters']
    for name in params['muscles']:
        params[name].update(
            ambient_pressure=101325.0, max_input_age=0.1, pressure_reference='absolute'
        )
    path = folder / f'arm_{n}_misplaced.yaml'
    path.write_text(yaml.safe_dump(data, default_flow_style=None))
    return path


def children(folder: Path) -> dict[str, str]:
    arm(joints := folder / 'arm_4.yaml', 4)
    return {
        'baseline': (
            "import sys, rclpy\nrclpy.init()\nnode = rclpy.create_node('baseline')\n" + READY
        ),
        'model_node 1': child('model_node', 'ModelNode', CONFIG),
        'model_node 64': child('model_node', 'ModelNode', multi_muscle_file(64, folder)),
        'model_node 64+': child('model_node', 'ModelNode', misplaced_keys_file(64, folder)),
        'joint_node 4x2': child(
            'joint_node', 'JointNode', joints, '-p', f'config_dir:={ROOT / "config"}'
        ),
        'simulator_node': child('simulator_node', 'SimulatorNode', None),
        'joint_sim_node': child('joint_simulator_node', 'JointSimulatorNode', None),
    }


def time_to_ready(code: str) -> tuple[float, bool, int]:
    """Seconds from starting ``python -c code`` to its ready line; whether it loaded
    scipy.optimize; its number of parameters.
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
    count = child.stdout.readline()
    child.wait(30)
    if not line or line[0] != 'ready':
        raise RuntimeError(f'the child did not get ready: {line}')
    return elapsed, line[1] == 'True', int(count)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='3 processes per row')
    parser.add_argument('--repeat', type=int, default=7, help='processes per row (default 7)')
    args = parser.parse_args()
    repeat = 3 if args.quick else args.repeat
    print(
        f'{"process":<16}{"params":>8}{"best s":>8}{"median s":>10}{"x baseline":>12}'
        '  scipy.optimize'
    )
    base = None
    medians = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, code in children(Path(folder)).items():
            runs = [time_to_ready(code) for _ in range(repeat)]
            times = [t for t, _, _ in runs]
            median = medians[name] = statistics.median(times)
            base = base or median
            print(
                f'{name:<16}{runs[0][2]:>8}{min(times):>8.3f}{median:>10.3f}'
                f'{median / base:>12.2f}  {"loaded" if runs[0][1] else "not loaded"}'
            )
    print(
        'model_node 64+ (three node-wide keys in each block: 192 unknown parameters) / '
        f'model_node 64: {medians["model_node 64+"] / medians["model_node 64"]:.2f} (target < 2)'
    )


if __name__ == '__main__':
    main()
