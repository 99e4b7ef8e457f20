"""Offline estimation throughput: ``pma-model bag estimate`` against a bare rosbags
read-and-deserialize pass.

Usage: ``.venv/bin/python bench/bag_estimate.py [--quick] [--bag PATH] [--repeat N]
[--profile N]`` (or ``bench/run bag_estimate``).  Not a test: it prints a table.  For each storage
(mcap, sqlite3) it writes a recording of the simulator (``--duration`` s at 1 kHz, with sensor
noise: pressure, muscle_state and force, 3000 messages/s of bag time) without DDS, then
alternates, ``--repeat`` times, the bare pass (rosbags ``Reader`` + ``deserialize_cdr`` of every
message), ``estimate_bag`` with the shipped DMSP-10-250 config (as ``pma-model bag estimate``,
without the progress bar) writing only the outputs (``--outputs-only``) and copying the recording
beside them, and the I/O floor: the same read, and one template WrenchStamped written per input
message with rosbags' writer (what any estimator writing through rosbags pays with
``--outputs-only``).  It prints messages/s of each (best run, in CPU time of this process) and the
ratios to the bare pass (the targets: outputs-only >= 1.0, copying >= 0.6).  Absolute rates
depend on the machine's load; the ratios, taken within one run, are what to compare.
``--profile N``: then the N entries of most own time of each estimate under cProfile.
"""

from __future__ import annotations

import argparse
import cProfile
from pathlib import Path
import pstats
import shutil
import tempfile
import time

from rosbags.rosbag2 import Reader

from pma_model_ros.bags.bag_io import (
    BagWriter,
    FLUID_PRESSURE,
    JOINT_STATE,
    storage_of,
    TYPESTORE,
    WRENCH_STAMPED,
)
from pma_model_ros.bags.estimate import estimate_bag
from pma_model_ros.bags.synthetic import record_simulation
from pma_model_ros.core.files.param_file import node_settings, read_parameters
from pma_model_ros.wire.cdr import wrench_stamped

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'dmsp_10_250.yaml'
NOISE = {'noise__pressure_std': 200.0, 'noise__length_std': 2e-5, 'noise__force_std': 0.5}


def bare_pass(bag: Path) -> int:
    """Read and deserialize every message; the count."""
    count = 0
    with Reader(bag) as reader:
        for connection, _, data in reader.messages():
            TYPESTORE.deserialize_cdr(data, connection.msgtype)
            count += 1
    return count


def timed(run) -> tuple[float, int]:
    """CPU time [s] of this process for ``run()`` (the other processes on a shared machine do not
    count), and what it returned.
    """
    start = time.process_time()
    count = run()
    return time.process_time() - start, count


def floor_pass(bag: Path, out: Path) -> int:
    """Read every message and write one WrenchStamped per input (pressure, muscle_state); the
    count.
    """
    wrench, inputs, count = wrench_stamped('m'), (FLUID_PRESSURE, JOINT_STATE), 0
    data = wrench(0)
    with Reader(bag) as reader, BagWriter(out, storage_of(bag)) as writer:
        estimates = writer.topic('/bench/force_estimate', WRENCH_STAMPED)
        for connection, time_ns, _ in reader.messages():
            if connection.msgtype in inputs:
                writer.write_raw(estimates, time_ns, data)
            count += 1
    return count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='10 s recordings, one repeat')
    parser.add_argument(
        '--duration', type=float, default=60.0, help='recording length [s] of bag time'
    )
    parser.add_argument(
        '--repeat', type=int, default=3, help='alternating runs of each pass; the best counts'
    )
    parser.add_argument('--bag', type=Path, help='use this bag instead of simulated recordings')
    parser.add_argument(
        '--profile',
        type=int,
        metavar='N',
        help='after the table, the N entries of most own time in a cProfile of each estimate',
    )
    args = parser.parse_args()
    duration, repeat = (10.0, 1) if args.quick else (args.duration, args.repeat)
    settings = node_settings(read_parameters(CONFIG))
    with tempfile.TemporaryDirectory() as tmp:
        bags = {'given': args.bag} if args.bag else {}
        for storage in () if args.bag else ('mcap', 'sqlite3'):
            start = time.perf_counter()
            bags[storage] = record_simulation(
                Path(tmp) / f'sim_{storage}',
                duration,
                '/bench',
                storage,
                rate=1000.0,
                seed=1,
                **NOISE,
            )
            print(
                f'wrote {duration:g} s of the simulator at 1 kHz ({storage}) in '
                f'{time.perf_counter() - start:.1f} s'
            )
        print(
            f'\n{"bag":<9}{"messages":>10}{"bare [msg/s]":>14}{"outputs-only":>14}{"ratio":>7}'
            f'{"copying":>11}{"ratio":>7}{"I/O floor":>11}{"ratio":>7}'
        )
        for name, bag in bags.items():
            runs: dict[str, list[tuple[float, int]]] = {
                'bare': [],
                'outputs': [],
                'copying': [],
                'floor': [],
            }
            for i in range(repeat):
                runs['bare'].append(timed(lambda: bare_pass(bag)))
                for what, only in (('outputs', True), ('copying', False)):
                    out = Path(tmp) / f'out_{name}_{what}_{i}'
                    runs[what].append(
                        timed(
                            lambda: (
                                estimate_bag(
                                    bag, settings, out, progress=False, outputs_only=only
                                ).messages
                            )
                        )
                    )
                    shutil.rmtree(out)
                floor = Path(tmp) / f'floor_{name}_{i}'
                runs['floor'].append(timed(lambda: floor_pass(bag, floor)))
                shutil.rmtree(floor)
            best = {what: min(t for t, _ in r) for what, r in runs.items()}
            n = runs['bare'][0][1]
            cells = ''.join(
                f'{n / best[what]:>{width},.0f}{best["bare"] / best[what]:>7.2f}'
                for what, width in (('outputs', 14), ('copying', 11), ('floor', 11))
            )
            print(f'{name:<9}{n:>10}{n / best["bare"]:>14,.0f}{cells}', flush=True)
        for name, bag in bags.items() if args.profile else ():
            for what, only in (('outputs-only', True), ('copying', False)):
                out = Path(tmp) / f'profile_{name}_{what}'
                profile = cProfile.Profile()
                profile.runcall(
                    estimate_bag, bag, settings, out, progress=False, outputs_only=only
                )
                shutil.rmtree(out)
                print(f'\n{name}, {what}, under cProfile:')
                pstats.Stats(profile).sort_stats('tottime').print_stats(args.profile)


if __name__ == '__main__':
    main()
