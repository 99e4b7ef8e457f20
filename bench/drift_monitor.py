"""Drift monitor over DDS: model_node's ``residual.*`` and ``reidentify.*`` against simulator_node,
the three runs of their targets.

Each scenario starts model_node (``residual.enabled``, its ``measured_force`` remapped to the
simulator's ``force``) and simulator_node as processes, with the demo's sweeps (length triangle of
2 s, pressure triangle of 20 s over the map, 100 Hz) and sensor noise, the force's at 1 % of the
map's max force (a map's repeatability).  This script logs every model_node report on /diagnostics
(about 1 Hz): its residual figures, level and message, the ``reidentify`` keys, and a rolling RMS
of its own: the simulator's ``force`` minus model_node's ``force_estimate`` paired by stamp, in %
of the file's ``held_out.max_force``, over the node's window (an independent check of the node's
figure).

* ``soak``: the DMSP-10-250 map against ``config/dmsp_10_250.yaml`` (fitted on it; ``--muscle
  DMSP-20-300``: that map and ``config/dmsp_20_300.yaml``), 10 minutes:
  WARN and ERROR reports (target 0), the largest RMS / band ratio.
* ``detect``: the same with a force gain ramped from 1.00 to 0.85 over 60 s (``drift.*``): when
  the rolling RMS (this script's, and the node's) first exceeds the band, the first WARN, and the
  delay between them (target <= 10 s).
* ``reidentify``: model_node (``reidentify.enabled``) starts from ``config/dmsp_20_300.yaml`` cut
  to 0.274 m (``pma-model scale``); the simulator plays the independent DMSP-20-274 fill map.
  120 s of sweeps (from the first paired sample): when collecting started (the residual's WARN),
  the coverage was first enough, the first fit started and was served, and each fit's outcome;
  then ``save_parameters``, ``pma-model evaluate`` of
  the saved file on that map, beside a direct ``pma-model fit --model martens`` of it (target: the
  saved file's err <= 1.5 x the fit's in-sample err).  The independent maps are read from
  ``../shared/data/independent-muscles/`` (never copied into the package); without them this
  scenario says so and is skipped.

Writes into ``--out-dir`` (default: a new temporary directory) per scenario: ``<scenario>.csv``
(one row per report), ``<scenario>.mcap`` (/diagnostics as received) and
``drift_<scenario>.png|svg`` (``pma-model plot drift --diagnostics <scenario>.mcap``); for
``reidentify`` also the cut file, the saved file and the direct fit.

Usage: ``bench/run drift_monitor`` (every scenario, about 16 min; only when named) or
``scripts/netns-run .venv/bin/python bench/drift_monitor.py [--scenario soak|detect|reidentify|all]
[--quick] [--out-dir DIR]`` (DDS must stay on loopback: run it inside scripts/netns-run).
``--quick``: a 60 s soak, a 20 s ramp, 60 s of re-identification.  Not a test: it prints tables.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import re
import tempfile
import time
import uuid

from _cli import run as pma_model
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_srvs.srv import Trigger

from pma_model_ros.bags.bag_io import BagWriter, DIAGNOSTIC_ARRAY
from pma_model_ros.core.files.param_file import read_parameters
from pma_model_ros.core.identification.force_map import read_force_map_csv
from pma_model_ros.core.runtime.residual import Figures
from pma_model_ros.demo import SIMULATOR
from pma_model_ros.tools import node_process

REPO = Path(__file__).resolve().parents[1]
#: the shipped muscles --muscle chooses for soak and detect: their map, their fitted file
FITTED = {
    'DMSP-10-250': REPO / 'config' / 'dmsp_10_250.yaml',
    'DMSP-20-300': REPO / 'config' / 'dmsp_20_300.yaml',
}
CONFIG_20 = FITTED['DMSP-20-300']
INDEPENDENT = REPO.parent / 'shared' / 'data' / 'independent-muscles'
MAP_274 = INDEPENDENT / 'dmsp20_274_fill.csv'
SPEC_274 = INDEPENDENT / 'dmsp20_274.yaml'
#: the demo's sweeps: its pressure triangle spans its default 20 s run
SWEEPS = dict(SIMULATOR, sweep_period=20.0)
NOISE = 0.01  #: force noise std, in fractions of the map's max force
WINDOW = 10.0  #: [s] model_node's residual.window (its default)
SENSOR_QOS = QoSProfile(depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)
COLUMNS = (
    't_s',
    'level',
    'residual_level',
    'bias_pct',
    'rms_pct',
    'worst_pct',
    'band_pct',
    'window_samples',
    'own_rms_pct',
    'own_pairs',
    'residual_samples',
    'reidentify_state',
    'reidentify_coverage',
    'reidentify_served',
    'reidentify_last',
    'message',
)


@dataclass
class Pairs:
    """Measured force and estimate [N] by stamp [ns]; the rolling RMS of their difference."""

    measured: dict[int, float] = field(default_factory=dict)
    estimated: dict[int, float] = field(default_factory=dict)

    def on_measured(self, msg: WrenchStamped) -> None:
        self.measured[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = msg.wrench.force.x

    def on_estimate(self, msg: WrenchStamped) -> None:  # the later of one stamp: both inputs
        self.estimated[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = (
            msg.wrench.force.x
        )

    def rms(self, now: int, max_force: float) -> tuple[float, int]:
        """RMS of measured - estimated [% of ``max_force``] over the stamps of the last
        :data:`WINDOW` before ``now`` [ns], and their count; older stamps are dropped.
        """
        start = now - round(WINDOW * 1e9)
        for series in (self.measured, self.estimated):
            for stamp in [s for s in series if s < start - 10**9]:
                del series[stamp]
        both = [s for s in self.measured.keys() & self.estimated.keys() if s >= start]
        if not both:
            return math.nan, 0
        error = np.array([self.measured[s] - self.estimated[s] for s in both])
        return float(100 * np.sqrt(np.mean(error**2)) / max_force), len(both)


class Run:
    """model_node and simulator_node in their own namespace, this script's subscriptions, and the
    log of model_node's reports.
    """

    def __init__(self, name: str, out_dir: Path, max_force: float) -> None:
        self.name, self.max_force = name, max_force
        self.ns = f'/drift{uuid.uuid4().hex[:6]}'
        self.status = f'{self.ns[1:]}/model_node: '  # its muscle's status name, less the joint
        self.node = rclpy.create_node(f'drift_monitor_{name}')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.pairs = Pairs()
        self.node.create_subscription(
            WrenchStamped, f'{self.ns}/force', self.pairs.on_measured, SENSOR_QOS
        )
        self.node.create_subscription(
            WrenchStamped,
            f'{self.ns}/force_estimate',
            self.pairs.on_estimate,
            QoSProfile(depth=2000),
        )
        self.node.create_subscription(
            DiagnosticArray, '/diagnostics', self._on_diagnostics, QoSProfile(depth=100)
        )
        for path in (out_dir / f'{name}.csv', out_dir / f'{name}.mcap'):
            path.unlink(missing_ok=True)
        self.bag = BagWriter(out_dir / f'{name}.mcap')
        self.topic = self.bag.topic('/diagnostics', DIAGNOSTIC_ARRAY)
        self.csv_file = open(out_dir / f'{name}.csv', 'w', newline='')
        self.csv = csv.DictWriter(self.csv_file, COLUMNS)
        self.csv.writeheader()
        self.rows: list[dict] = []
        self.logs = {n: tempfile.TemporaryFile('w+') for n in ('model_node', 'simulator_node')}
        self.procs: dict = {}
        self.reported = False
        self.start = time.monotonic()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Log model_node's reports from the simulator's start on (before: note that one came)."""
        if 'simulator_node' not in self.procs:
            self.reported |= any(s.name.startswith(self.status) for s in msg.status)
            return
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        self.bag.write_raw(self.topic, stamp, serialize_message(msg))
        for status in msg.status:
            if not status.name.startswith(self.status):
                continue
            values = {kv.key: kv.value for kv in status.values}
            f = Figures.parse(values.get('residual [% of max force]', ''))
            own, pairs = self.pairs.rms(self.node.get_clock().now().nanoseconds, self.max_force)
            row = {
                't_s': round(time.monotonic() - self.start, 2),
                'level': ('OK', 'WARN', 'ERROR', 'STALE')[status.level[0]],
                'residual_level': values.get('residual level', ''),
                'bias_pct': f.bias if f else '',
                'rms_pct': f.rms if f else '',
                'worst_pct': f.worst if f else '',
                'band_pct': f.band if f else '',
                'window_samples': f.samples if f else 0,
                'own_rms_pct': round(own, 3),
                'own_pairs': pairs,
                'residual_samples': values.get('residual samples', ''),
                'reidentify_state': values.get('reidentify state', ''),
                'reidentify_coverage': values.get('reidentify coverage', ''),
                'reidentify_served': values.get('reidentify served', ''),
                'reidentify_last': values.get('reidentify last', ''),
                'message': status.message,
            }
            self.rows.append(row)
            self.csv.writerow(row)

    def launch(self, model_cmd: list[str], sim_params: dict) -> None:
        """Start model_node, then (once it reports) the simulator; t = 0 at the simulator's
        start.
        """
        self.procs['model_node'] = node_process.start(model_cmd, self.logs['model_node'])
        self.spin_until(lambda: self.reported, 30, 'first model_node report')
        self.start = time.monotonic()
        self.procs['simulator_node'] = node_process.start(
            node_process.command('simulator_node', self.ns, params=sim_params),
            self.logs['simulator_node'],
        )

    def spin_until(self, done, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() > end:
                self.fail(f'no {what} in {timeout:g} s')
            if any(p.poll() is not None for p in self.procs.values()):
                self.fail('a node ended early')
            self.executor.spin_once(timeout_sec=0.1)

    def fail(self, why: str) -> None:
        """Stop the nodes and end with ``why`` and their output."""
        for proc in self.procs.values():
            node_process.stop(proc)
        raise SystemExit(f'{self.name}: {why}\n{self.output()}')

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            self.executor.spin_once(timeout_sec=min(left, 0.1))

    def elapsed(self) -> float:
        return time.monotonic() - self.start

    def call_save(self, timeout: float = 30.0) -> Trigger.Response:
        """``save_parameters``, again every second until answered (a response sent before
        discovery matched it is lost).
        """
        client = self.node.create_client(Trigger, f'{self.ns}/save_parameters')
        self.spin_until(client.service_is_ready, timeout, 'save_parameters service')
        futures, end, last = [], time.monotonic() + timeout, 0.0
        while not any(f.done() for f in futures):
            if time.monotonic() > end:
                self.fail('no save_parameters response')
            if time.monotonic() - last >= 1.0:
                futures.append(client.call_async(Trigger.Request()))
                last = time.monotonic()
            self.executor.spin_once(timeout_sec=0.1)
        return next(f for f in futures if f.done()).result()

    def output(self) -> str:
        return ''.join(f'--- {n}\n' + (log.seek(0) or log.read()) for n, log in self.logs.items())

    def close(self) -> dict[str, int]:
        """Stop the simulator, then model_node; finish the files; exit codes."""
        codes = {n: node_process.stop(self.procs[n]) for n in ('simulator_node', 'model_node')}
        self.executor.shutdown()
        self.node.destroy_node()
        self.bag.close()
        self.csv_file.close()
        for log in self.logs.values():
            log.close()
        return codes


def model_command(ns: str, config: Path, **params: object) -> list[str]:
    """model_node with the drift monitor on, its measured force the simulator's ``force``."""
    params = {'residual.enabled': True, 'residual.window': WINDOW, **params}
    return [*node_process.command('model_node', ns, config, params), '-r', 'measured_force:=force']


def run_name(scenario: str, muscle: str) -> str:
    """The stem of a run's files: the scenario's name, with the muscle's file when not the
    default one.
    """
    return scenario if muscle == 'DMSP-10-250' else f'{scenario}_{FITTED[muscle].stem}'


def file_max_force(config: Path) -> float:
    """The held-out band's max force [N] of a one-muscle file's model: the node's % basis."""
    p = read_parameters(config)
    return float(p['models'][p['model']]['held_out']['max_force'])


def ratio(row: dict, rms_key: str = 'rms_pct') -> float:
    """RMS / band of a logged report (NaN without figures)."""
    rms, band = row[rms_key], row['band_pct']
    return float(rms) / float(band) if rms != '' and band not in ('', 0) else math.nan


def first(rows: list[dict], test) -> dict | None:
    return next((r for r in rows if test(r)), None)


def show(title: str, rows: list[tuple[str, str]]) -> None:
    width = max(len(name) for name, _ in rows)
    print(title)
    for name, value in rows:
        print(f'  {name:<{width}}  {value}')


def t_of(row: dict | None) -> str:
    return 'never' if row is None else f'{row["t_s"]:.1f} s'


def warned(row: dict) -> bool:
    return row['residual_level'] in ('WARN', 'ERROR')


def soak(out_dir: Path, quick: bool, duration: float, muscle: str) -> None:
    duration = 60.0 if quick else duration
    config = FITTED[muscle]
    max_force = file_max_force(config)
    run = Run(run_name('soak', muscle), out_dir, max_force)
    sim = dict(SWEEPS, muscle=muscle, **{'noise.force_std': NOISE * max_force})
    run.launch(model_command(run.ns, config), sim)
    run.spin_for(duration)
    codes = run.close()
    rows = run.rows
    judged = [r for r in rows if r['rms_pct'] != '']
    ratios = [ratio(r) for r in judged]
    own = [ratio(r, 'own_rms_pct') for r in judged if r['own_pairs']]
    levels = [r['level'] for r in rows]
    show(
        f'soak: {config.name} on its map, force noise {NOISE * max_force:g} N, '
        f'{duration:g} s, load average {os.getloadavg()[0]:.2f}',
        [
            ('model_node reports / with residual figures', f'{len(rows)} / {len(judged)}'),
            (
                'residual WARN / ERROR reports (target: 0)',
                ' / '.join(
                    str(sum(r['residual_level'] == x for r in rows)) for x in ('WARN', 'ERROR')
                ),
            ),
            (
                'status levels OK / WARN / ERROR',
                ' / '.join(str(levels.count(x)) for x in ('OK', 'WARN', 'ERROR')),
            ),
            ('RMS / band: median, largest (node)', f'{np.median(ratios):.2f}, {max(ratios):.2f}'),
            ('RMS / band: largest (this script)', f'{max(own):.2f}' if own else '-'),
            (
                'band [%]: min, max',
                f'{min(float(r["band_pct"]) for r in judged):.2f}, '
                f'{max(float(r["band_pct"]) for r in judged):.2f}',
            ),
            ('last residual samples', rows[-1]['residual_samples'] if rows else '-'),
            (
                'exit codes simulator / model_node',
                f'{codes["simulator_node"]} / {codes["model_node"]}',
            ),
        ],
    )


def detect(out_dir: Path, quick: bool, muscle: str) -> None:
    start, ramp = (15.0, 20.0) if quick else (30.0, 60.0)
    config = FITTED[muscle]
    max_force = file_max_force(config)
    run = Run(run_name('detect', muscle), out_dir, max_force)
    drift = {'drift.gain': 0.85, 'drift.start': start, 'drift.duration': ramp}
    sim = dict(SWEEPS, muscle=muscle, **{'noise.force_std': NOISE * max_force}, **drift)
    run.launch(model_command(run.ns, config), sim)

    def ramping(rows: list[dict]) -> list[dict]:  # the reports from the ramp's start on
        return [r for r in rows if r['t_s'] >= start and r['rms_pct'] != '']

    while run.elapsed() < start + ramp + 60.0 and not first(ramping(run.rows), warned):
        run.spin_for(1.0)
    run.spin_for(5.0)
    codes = run.close()
    before = sum(warned(r) for r in run.rows if r['t_s'] < start)
    rows = ramping(run.rows)
    passed_own = first(rows, lambda r: ratio(r, 'own_rms_pct') > 1.0)
    passed = first(rows, lambda r: ratio(r) > 1.0)
    warn = first(rows, warned)

    def delay(since: dict | None) -> str:
        if since is None or warn is None:
            return '-'
        return f'{warn["t_s"] - since["t_s"]:.1f} s'

    show(
        f"detect: force gain 1 -> 0.85 from {start:g} s over {ramp:g} s after the simulator's "
        f'start, {config.name}, force noise {NOISE * max_force:g} N, load average '
        f'{os.getloadavg()[0]:.2f}',
        [
            ('residual WARN or ERROR reports before the ramp', f'{before}'),
            ('rolling RMS first above the band: this script', t_of(passed_own)),
            ('rolling RMS first above the band: model_node', t_of(passed)),
            ('first residual WARN', t_of(warn)),
            ("DELAY to WARN from this script's passing (target <= 10 s)", delay(passed_own)),
            ("delay to WARN from the node's passing", delay(passed)),
            (
                'at the WARN: gain (from t)',
                '-'
                if warn is None
                else f'{1 - 0.15 * min(max(warn["t_s"] - start, 0) / ramp, 1):.3f}',
            ),
            ('at the WARN: message', '-' if warn is None else warn['message'][:100]),
            (
                'exit codes simulator / model_node',
                f'{codes["simulator_node"]} / {codes["model_node"]}',
            ),
        ],
    )


def reidentify(out_dir: Path, quick: bool) -> None:
    if not MAP_274.is_file():
        print(f'reidentify: skipped: the independent DMSP-20 map is not in {INDEPENDENT}')
        return
    limit = 60.0 if quick else 120.0
    cut = out_dir / 'dmsp_20_300_cut_274.yaml'
    saved = out_dir / 'reidentified_274.yaml'
    direct = out_dir / 'fit_274.yaml'
    saved.unlink(missing_ok=True)
    scale = ['scale', '--config', str(CONFIG_20), '--length', '0.274', '--out', str(cut)]
    pma_model([*scale, '--overwrite'])
    fmap = read_force_map_csv(MAP_274)
    params = read_parameters(cut)
    run = Run('reidentify', out_dir, file_max_force(cut))
    sim = dict(
        SWEEPS,
        map_file=str(MAP_274),
        spec_file=str(SPEC_274),
        joint_name=params.get('joint_name') or params['muscle']['name'],
        **{'noise.force_std': NOISE * fmap.max_force},
    )
    model = model_command(
        run.ns, cut, **{'reidentify.enabled': True, 'reidentify.save_file': str(saved)}
    )
    run.launch(model, sim)
    run.spin_until(lambda: first(run.rows, lambda r: r['window_samples']), 60, 'paired sample')
    paired = first(run.rows, lambda r: r['window_samples'])
    while run.elapsed() < paired['t_s'] + limit:
        run.spin_for(1.0)
    response = run.call_save()
    codes = run.close()
    rows = run.rows
    collecting = first(rows, lambda r: r['reidentify_state'] == 'collecting')
    enough = first(rows, lambda r: r['reidentify_coverage'].endswith(': enough'))
    fitting = first(rows, lambda r: r['reidentify_state'] == 'fitting')
    served = first(rows, lambda r: r['reidentify_served'] == 're-identified')
    outcomes = [  # each fit's outcome, in the report that first says it
        (f'fit ended by {t_of(row)}', row['reidentify_last'])
        for before, row in zip([None, *rows], rows)
        if row['reidentify_last'] not in ('', 'none')
        and (before is None or row['reidentify_last'] != before['reidentify_last'])
    ]
    show(
        f'reidentify: model_node from {CONFIG_20.name} cut to 0.274 m; the simulator plays '
        f'{MAP_274.name} (max force {fmap.max_force:g} N), force noise '
        f'{NOISE * fmap.max_force:g} N, at most {limit:g} s; load average '
        f'{os.getloadavg()[0]:.2f}',
        [
            ('first paired sample', t_of(paired)),
            ('collecting (the residual at WARN)', t_of(collecting)),
            ('coverage first enough', t_of(enough)),
            ('first fit started', t_of(fitting)),
            ('re-identified parameters first served', t_of(served)),
            *outcomes,
            ('last coverage', rows[-1]['reidentify_coverage']),
            ('last reidentify last', rows[-1]['reidentify_last']),
            ('residual level at the end', rows[-1]['residual_level']),
            ('save_parameters', f'{response.success}: {response.message}'),
            (
                'exit codes simulator / model_node',
                f'{codes["simulator_node"]} / {codes["model_node"]}',
            ),
        ],
    )
    if not response.success:
        return
    print(f'\n$ pma-model evaluate --config {saved.name} --data {MAP_274.name}')
    out = pma_model(['evaluate', '--config', str(saved), '--data', str(MAP_274)])
    print(out, end='')
    saved_err = float(re.search(r'err \(eq\. 23\) (\S+) %', out).group(1))
    transfer = pma_model(['evaluate', '--config', str(cut), '--data', str(MAP_274)])
    transfer_err = float(re.search(r'err \(eq\. 23\) (\S+) %', transfer).group(1))
    fit = ['fit', '--data', str(MAP_274), '--muscle', str(SPEC_274), '--model', 'martens']
    pma_model([*fit, '--out', str(direct), '--overwrite'])
    fit_err = float(read_parameters(direct)['models']['martens']['err'])
    header = saved.read_text().splitlines()[0]
    figures = read_parameters(saved)
    entry = figures['models'][figures['model']]
    show(
        '\nre-identification on the independent map (eq. 23 on the whole map, served force)',
        [
            ('saved file', header[:140]),
            (
                "saved file's own figures: err / cv_err [%]",
                f'{entry.get("err", float("nan")):.2f} / {entry.get("cv_err", float("nan")):.2f}',
            ),
            ('the cut file alone (transfer) err [%]', f'{transfer_err:.2f}'),
            ('saved file err [%]', f'{saved_err:.2f}'),
            ('direct fit --model martens in-sample err [%]', f'{fit_err:.2f}'),
            ('RATIO saved / direct (target <= 1.5)', f'{saved_err / fit_err:.2f}'),
        ],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--scenario', choices=('soak', 'detect', 'reidentify', 'all'), default='all'
    )
    parser.add_argument('--quick', action='store_true', help='shorter runs (docstring)')
    parser.add_argument(
        '--duration', type=float, default=600.0, help='soak time [s] (default 600)'
    )
    parser.add_argument(
        '--muscle',
        choices=FITTED,
        default='DMSP-10-250',
        help='the shipped muscle of soak and detect (default DMSP-10-250)',
    )
    parser.add_argument('--out-dir', type=Path, help='where the logs and plots go')
    args = parser.parse_args()
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST':
        parser.error('run inside scripts/netns-run (DDS must stay on loopback)')
    out_dir = args.out_dir or Path(tempfile.mkdtemp(prefix='drift_monitor.'))
    out_dir.mkdir(parents=True, exist_ok=True)
    scenarios = ('detect', 'reidentify', 'soak') if args.scenario == 'all' else (args.scenario,)
    rclpy.init()
    try:
        for scenario in scenarios:
            if scenario == 'soak':
                soak(out_dir, args.quick, args.duration, args.muscle)
            elif scenario == 'detect':
                detect(out_dir, args.quick, args.muscle)
            else:
                reidentify(out_dir, args.quick)
            name = scenario if scenario == 'reidentify' else run_name(scenario, args.muscle)
            bag = out_dir / f'{name}.mcap'
            if bag.exists():
                plot = ['plot', 'drift', '--diagnostics', str(bag), '--out-dir', str(out_dir)]
                print(pma_model([*plot, '--overwrite']), end='')
            print()
    finally:
        rclpy.shutdown()
    print(f'logs, bags and plots in {out_dir}')


if __name__ == '__main__':
    main()
