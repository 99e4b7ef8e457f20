"""Soak: simulator_node at 1 kHz into model_node for 10 minutes; losses, memory growth,
diagnostics.

Usage: ``bench/run soak`` or ``scripts/netns-run .venv/bin/python bench/soak.py [--duration 600]
[--quick]`` (DDS must stay on loopback: run it inside scripts/netns-run).  Not a test: it prints a
table.

Losses are counted two ways. Totals, by DDS publication sequence numbers (rmw MessageInfo): the
last ``pressure`` and ``muscle_state`` sequence numbers are what the simulator published,
model_node's counters (its last /diagnostics, after the simulator's stop) what it received; this
includes the first messages, sent before DDS discovery matched the simulator to model_node. In the
soak window (from model_node's first OK to 0.1 s before the simulator's stop): model_node publishes
one estimate per valid fresh input, stamped with the newest input's tick, so the window's ticks
must come back as twice as many estimates stamped in the window (+-1 at its edges), less the inputs
the node skipped on purpose (``skipped behind``: a newer input waited behind them,
``max_queue_delay``; its counter's growth from the report that opens the window to the last one, so
a few skips just outside the window count too: the row may read a few below 0); each other missing
one is a lost (or stale, or rejected) input. This holds when this script itself missed no tick and
no estimate: its own sequence gaps are printed too. Resident memory of model_node (VmRSS) is
sampled every second; growth is counted after ``--warm-up``. Every /diagnostics ERROR of model_node
in the soak window is listed.
"""

from __future__ import annotations

import argparse
from array import array
from collections import Counter
import math
import os
from pathlib import Path
import tempfile
import time
import uuid

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

from pma_model_ros.tools import node_process

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'dmsp_10_250.yaml'
# subscriber queues: this script may lag behind 4 kHz of callbacks, never drop for that
DEPTH = 10000


def rss_kib(pid: int) -> int:
    """Resident memory of process ``pid`` [KiB]."""
    with open(f'/proc/{pid}/status') as status:
        return next(int(line.split()[1]) for line in status if line.startswith('VmRSS:'))


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` [s]."""
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class Stream:
    """One topic as this script receives it: header stamps [ns] and DDS publication sequence
    numbers.
    """

    def __init__(self, check=None) -> None:
        self.stamps = array('q')
        self.first = self.last = self.bad = 0
        self.check = check

    def __call__(self, msg, info) -> None:
        seq = info['publication_sequence_number']
        self.first = self.first or seq
        self.last = max(self.last, seq)
        self.stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
        self.bad += self.check is not None and not self.check(msg)

    def missed(self) -> int:
        """Sequence numbers this script never received, after its first one."""
        return self.last - self.first + 1 - len(self.stamps) if self.first else 0


def _is_model_node(status) -> bool:
    """Whether ``status`` is model_node's (named ``<ns>/model_node: <joint>``)."""
    return status.name.rsplit('/', 1)[-1].startswith('model_node: ')


def model_status(diagnostics: list) -> object:
    """The newest model_node status (named ``<ns>/model_node: <joint>``; None before any); this
    run's domain holds only its own nodes.
    """
    return next(
        (s for d in reversed(diagnostics) for s in d.status if _is_model_node(s)),
        None,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--duration', type=float, default=600.0, help='soak time [s] (default 600)'
    )
    parser.add_argument('--quick', action='store_true', help='60 s instead of --duration')
    parser.add_argument('--rate', type=float, default=1000.0, help='simulator rate [Hz]')
    parser.add_argument(
        '--warm-up', type=float, default=10.0, help='time [s] before the memory baseline'
    )
    args = parser.parse_args()
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST':
        parser.error('run inside scripts/netns-run (DDS must stay on loopback)')
    duration = 60.0 if args.quick else args.duration
    ns = f'/soak{uuid.uuid4().hex[:6]}'

    rclpy.init()
    node = rclpy.create_node('soak_counter')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    deep_sensor = QoSProfile(depth=DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
    seen = {
        'pressure': Stream(),
        'muscle_state': Stream(),
        'force_estimate': Stream(
            lambda m: math.isfinite(m.wrench.force.x) and m.wrench.force.x >= 0
        ),
    }
    node.create_subscription(FluidPressure, f'{ns}/pressure', seen['pressure'], deep_sensor)
    node.create_subscription(JointState, f'{ns}/muscle_state', seen['muscle_state'], deep_sensor)
    node.create_subscription(
        WrenchStamped, f'{ns}/force_estimate', seen['force_estimate'], QoSProfile(depth=DEPTH)
    )
    diagnostics: list = []
    node.create_subscription(
        DiagnosticArray, '/diagnostics', diagnostics.append, QoSProfile(depth=DEPTH)
    )

    def spin_for(seconds: float, sample=None) -> None:
        end = next_sample = time.monotonic()
        end += seconds
        while (now := time.monotonic()) < end:
            if sample is not None and now >= next_sample:
                sample(now)
                next_sample += 1.0
            executor.spin_once(timeout_sec=min(end, next_sample) - now if sample else end - now)

    with tempfile.TemporaryDirectory() as tmp:
        logs = {name: open(Path(tmp) / f'{name}.log', 'w+') for name in node_process.NODES}
        model = node_process.start(
            node_process.command('model_node', ns, CONFIG), logs['model_node']
        )
        while model_status(diagnostics) is None and model.poll() is None:
            spin_for(0.1)
        sim = node_process.start(
            node_process.command('simulator_node', ns, params={'rate': args.rate}),
            logs['simulator_node'],
        )
        while not (s := model_status(diagnostics)) or s.level == b'\x02':  # first non-ERROR
            spin_for(0.1)
            if model.poll() is not None or sim.poll() is not None:
                raise SystemExit(
                    'a node ended early:\n'
                    + ''.join(log.seek(0) or log.read() for log in logs.values())
                )
        first_ok = len(diagnostics)
        at_start = {kv.key: kv.value for kv in s.values}
        window = [diagnostics[-1].header.stamp.sec * 10**9 + diagnostics[-1].header.stamp.nanosec]
        start, cpu0 = time.monotonic(), cpu_seconds(model.pid)
        rss: list[tuple[float, int]] = []
        spin_for(duration, lambda now: rss.append((now - start, rss_kib(model.pid))))
        cpu = cpu_seconds(model.pid) - cpu0
        soaked = len(diagnostics)
        window.append(node.get_clock().now().nanoseconds - 10**8)
        sim_exit = node_process.stop(sim)
        spin_for(2.5)  # two /diagnostics reports after the simulator's stop: final counters
        final = {kv.key: kv.value for kv in model_status(diagnostics).values}
        model_exit = node_process.stop(model)
        errors = Counter(
            s.message.split(':')[0]
            for d in diagnostics[first_ok:soaked]
            for s in d.status
            if _is_model_node(s) and s.level == b'\x02'
        )
        for log in logs.values():
            log.close()
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()

    base = next(kib for t, kib in rss if t >= args.warm_up)
    received = {
        topic: int(final.get(f'received {topic}', 0)) for topic in ('pressure', 'muscle_state')
    }
    ticks = np.union1d(seen['pressure'].stamps, seen['muscle_state'].stamps)
    ticks = ticks[(ticks >= window[0]) & (ticks <= window[1])]
    estimates = np.asarray(seen['force_estimate'].stamps)
    # inputs the node chose not to answer (a newer one waited behind them): counted, not lost
    skipped = int(final.get('skipped behind', 0)) - int(at_start.get('skipped behind', 0))
    in_window = int(((estimates >= window[0]) & (estimates <= window[1])).sum())
    rows = [
        ('soak time [s]', f'{duration:g} at {args.rate:g} Hz'),
        (
            'simulator published pressure / muscle_state (seq)',
            f'{seen["pressure"].last} / {seen["muscle_state"].last}',
        ),
        (
            'model_node received pressure / muscle_state',
            f'{received["pressure"]} / {received["muscle_state"]}',
        ),
        (
            'lost simulator -> model_node, in all',
            f'{seen["pressure"].last - received["pressure"]} / '
            f'{seen["muscle_state"].last - received["muscle_state"]}',
        ),
        (
            "  of which before this script's first message",
            f'{seen["pressure"].first - 1} / {seen["muscle_state"].first - 1}',
        ),
        (
            'simulator ticks in the soak window (rate)',
            f'{len(ticks)} ({len(ticks) / ((window[1] - window[0]) * 1e-9):.0f} Hz)',
        ),
        (
            'model_node skipped behind in the window (max_queue_delay)',
            f'{skipped}',
        ),
        (
            'LOST in the window: 2 x ticks - estimates - skipped behind',
            f'{2 * len(ticks) - in_window - skipped}',
        ),
        (
            'model_node rejected / stale skipped',
            f'{sum(int(v) for k, v in final.items() if k.startswith("rejected "))} / '
            f'{final.get("stale skipped", 0)}',
        ),
        (
            'model_node published estimates (seq)',
            f'{final.get("estimates", "?")} ({seen["force_estimate"].last})',
        ),
        (
            'this script missed pressure / muscle_state / estimates',
            ' / '.join(
                str(seen[t].missed()) for t in ('pressure', 'muscle_state', 'force_estimate')
            ),
        ),
        ('non-finite or negative estimates', f'{seen["force_estimate"].bad}'),
        (
            'model_node RSS start / after warm-up / end [KiB]',
            f'{rss[0][1]} / {base} / {rss[-1][1]}',
        ),
        (
            f'RSS GROWTH after {args.warm_up:g} s [KiB]',
            f'{max(kib for t, kib in rss if t >= args.warm_up) - base}',
        ),
        ('model_node CPU [% of one core]', f'{100 * cpu / duration:.0f}'),
        (
            'diagnostics ERROR during the soak',
            ', '.join(f'{n} x {m}' for m, n in errors.items()) or '0',
        ),
        ('exit codes simulator / model_node', f'{sim_exit} / {model_exit}'),
    ]
    width = max(len(name) for name, _ in rows)
    print(
        f'soak: simulator_node {args.rate:g} Hz -> model_node ({CONFIG.name}), {os.cpu_count()} '
        f'cores, '
        f'load average {os.getloadavg()[0]:.2f}'
    )
    for name, value in rows:
        print(f'  {name:<{width}}  {value}')


if __name__ == '__main__':
    main()
