"""Live demo: the model node estimates the force of a simulated DMSP-10-250.

Starts ``simulator_node`` (a slow sweep over the measured map, small sensor noise)
and ``model_node`` (the identified muscle of ``config/dmsp_10_250.yaml``) as
separate processes, compares the estimate with the simulator's measured force
at equal stamps, prints a few lines per second and a summary, then stops both.
``--config`` names another identified muscle; ``--map`` and ``--spec`` the measured map
the simulator plays (a user's muscle: any map ``pma-model fit --data`` reads).
Run with ``scripts/demo`` (it provides the loopback-only network namespace).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path
import sys
import tempfile
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

from .core.files.param_file import muscle_model, read_parameters
from .core.files.shipped_data import MAPPED_MUSCLES, share_directory, shipped_force_map
from .core.files.user_files import read_spec_yaml
from .core.identification.force_map import ForceMap, read_force_map_csv
from .core.physics.geometry import STANDARD_ATMOSPHERE
from .core.physics.muscle_model import MuscleModel
from .core.simulation.truth import GroundTruth
from .tools import node_process

NAMESPACE = '/pma_demo'
SIMULATOR = {
    'trajectory': 'sweep',
    'period': 2.0,
    'noise.pressure_std': 200.0,
    'noise.length_std': 2e-5,
    'noise.force_std': 0.5,
    'seed': 1,
}
SETTLE = 0.3  # [s] a stamp is compared once it is this old (both messages of it have arrived)
#: [s] Longest wait for the first measured force and estimate before the run's clock starts.
DISCOVERY_TIMEOUT = 15.0
#: Sensor-data QoS with a deep queue: spin_once takes one message at a time.
SENSOR_QOS = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT)


def default_config() -> Path:
    """config/dmsp_10_250.yaml of the package's share directory (in development: the source)."""
    return share_directory() / 'config' / 'dmsp_10_250.yaml'


@dataclass
class Comparison:
    """Estimate vs measured force per stamp [ns]; errors in % of ``max_force`` [N]."""

    max_force: float
    samples: dict[int, dict[str, float]] = field(default_factory=dict)
    count: int = 0
    max_error: float = 0.0
    worst: dict[str, float] = field(default_factory=dict)
    last: dict[str, float] = field(default_factory=dict)
    error_sum: float = 0.0

    def add(self, stamp: int, key: str, value: float) -> None:
        """Record ``key`` (measured, estimate, pressure, length) at ``stamp``; a later estimate
        replaces.
        """
        self.samples.setdefault(stamp, {})[key] = value

    def settle(self, before: int) -> None:
        """Compare and forget every stamp older than ``before`` [ns]."""
        for stamp in sorted(s for s in self.samples if s < before):
            sample = self.samples.pop(stamp)
            if 'measured' in sample and 'estimate' in sample:
                sample['error'] = (
                    abs(sample['estimate'] - sample['measured']) / self.max_force * 100
                )
                self.count += 1
                self.error_sum += sample['error']
                self.last = sample
                if sample['error'] >= self.max_error:
                    self.max_error, self.worst = sample['error'], sample


class Monitor(Node):
    """Subscribes the simulator's measurements, the estimates and the model node's diagnostics."""

    def __init__(self, comparison: Comparison, ambient: float) -> None:
        super().__init__('pma_demo', namespace=NAMESPACE)
        self.comparison, self.ambient = comparison, ambient
        self.received = {'force': 0, 'force_estimate': 0}
        self.diagnostics: dict[str, str] = {}
        self.create_subscription(WrenchStamped, 'force', self._on_force, SENSOR_QOS)
        self.create_subscription(WrenchStamped, 'force_estimate', self._on_estimate, 200)
        self.create_subscription(FluidPressure, 'pressure', self._on_pressure, SENSOR_QOS)
        self.create_subscription(JointState, 'muscle_state', self._on_state, SENSOR_QOS)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)

    @staticmethod
    def _ns(msg) -> int:
        return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec

    def _on_force(self, msg: WrenchStamped) -> None:
        self.received['force'] += 1
        self.comparison.add(self._ns(msg), 'measured', msg.wrench.force.x)

    def _on_estimate(self, msg: WrenchStamped) -> None:
        self.received['force_estimate'] += 1
        self.comparison.add(self._ns(msg), 'estimate', msg.wrench.force.x)

    def _on_pressure(self, msg: FluidPressure) -> None:
        self.comparison.add(self._ns(msg), 'pressure', msg.fluid_pressure - self.ambient)

    def _on_state(self, msg: JointState) -> None:
        if msg.position:
            self.comparison.add(self._ns(msg), 'length', msg.position[0])

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            # '<namespace>/model_node: <joint>': the node's fully qualified name, then the joint
            if status.name.partition(': ')[0].rsplit('/', 1)[-1] == 'model_node':
                self.diagnostics = {kv.key: kv.value for kv in status.values}
                self.diagnostics['level'] = ('OK', 'WARN', 'ERROR', 'STALE')[status.level[0]]
                self.diagnostics['message'] = status.message


def _line(t: float, c: Comparison) -> str:
    s = c.last
    return (
        f'{t:6.1f} {s.get("pressure", float("nan")) / 1e3:8.1f} '
        f'{s.get("length", float("nan")) * 1e3:7.1f} '
        f'{s["estimate"]:10.1f} {s["measured"]:10.1f} {s["error"]:7.2f} {c.max_error:8.2f}'
    )


@dataclass(frozen=True)
class UserMap:
    """A measured map the simulator plays instead of a shipped one: ``--map`` and ``--spec``."""

    map_file: Path
    spec_file: Path

    def read(self) -> tuple[str, ForceMap]:
        """The muscle's name and its map; ValueError (one line, naming the file) for a file that
        cannot be the simulator's truth.
        """
        name = read_spec_yaml(self.spec_file).name
        fmap = read_force_map_csv(self.map_file)
        try:
            GroundTruth(fmap)
        except ValueError as err:
            raise ValueError(f'{self.map_file}: {err}') from None
        return name, fmap


def demo_muscle(config: Path, user_map: UserMap | None = None) -> tuple[dict, MuscleModel]:
    """The parameters and muscle of ``config``; ValueError (one line, naming the file) for a file
    the demo cannot run: a joint file, several muscles, a muscle without a shipped map and no
    ``user_map``.
    """
    params = read_parameters(config)
    one = 'the demo runs one muscle: --config config/dmsp_10_250.yaml or config/dmsp_20_300.yaml'
    if 'joints' in params:
        raise ValueError(f"{config} is a joint file ('joints:', for joint_node); {one}")
    if params.get('muscles'):
        raise ValueError(f"{config} has several muscles ('muscles:'); {one}")
    try:
        model = muscle_model(params)
    except ValueError as err:
        raise ValueError(f'{config}: {err}') from None
    if model.spec.name not in MAPPED_MUSCLES and user_map is None:
        raise ValueError(
            f'{config}: muscle.name {model.spec.name}: the simulator needs a shipped force map '
            f'({", ".join(MAPPED_MUSCLES)}) or its measured map: --map CSV --spec YAML'
        )
    return params, model


def run(duration: float, config: Path, user_map: UserMap | None = None) -> int:
    params, model = demo_muscle(config, user_map)
    identified = params['models'][model.model.name].get('err', float('nan'))
    if user_map is None:
        name, truth = model.spec.name, 'its measured map'
        fmap = shipped_force_map(name)
        sim_params = dict(SIMULATOR, sweep_period=duration, muscle=name)
    else:
        (name, fmap), truth = user_map.read(), f'the measured map {user_map.map_file}'
        sim_params = dict(
            SIMULATOR,
            sweep_period=duration,
            map_file=user_map.map_file.resolve(),
            spec_file=user_map.spec_file.resolve(),
            joint_name=params.get('joint_name') or model.spec.name,  # the entry model_node reads
        )
    comparison = Comparison(fmap.max_force)
    scale = f'{comparison.max_force:g} N'
    if user_map is not None:  # the fit's err is in % of its own map's max force
        scale = f"its map's max force); errors in % of this map's max force ({scale}"
    print(
        f'pma_model_ros demo: simulated {name} (truth = {truth}) vs model_node '
        f'({model.model.name}, identification err {identified:.2f} % of {scale}), '
        f'{duration:g} s\n'
    )
    with tempfile.TemporaryDirectory(prefix='pma_demo_') as tmp:
        logs = {
            name: open(Path(tmp) / f'{name}.log', 'w+')
            for name in ('simulator_node', 'model_node')
        }
        procs = {
            'simulator_node': node_process.start(
                node_process.command('simulator_node', NAMESPACE, params=sim_params),
                logs['simulator_node'],
            ),
            'model_node': node_process.start(
                node_process.command('model_node', NAMESPACE, params_file=config),
                logs['model_node'],
            ),
        }
        rclpy.init()
        monitor = Monitor(comparison, float(params.get('ambient_pressure', STANDARD_ATMOSPHERE)))
        try:
            # the run starts once both nodes are heard from (DDS discovery can take a while)
            heard = time.monotonic() + DISCOVERY_TIMEOUT
            while (
                not all(monitor.received.values())
                and time.monotonic() < heard
                and all(p.poll() is None for p in procs.values())
            ):
                rclpy.spin_once(monitor, timeout_sec=0.05)
            start = time.monotonic()
            print(
                '   t/s    p/kPa    L/mm  estimate/N measured/N  err/%  max err/% (of max force)'
            )
            next_print = start + 1.0
            while time.monotonic() - start < duration and all(
                p.poll() is None for p in procs.values()
            ):
                rclpy.spin_once(monitor, timeout_sec=0.05)
                if time.monotonic() >= next_print:
                    next_print += 0.25
                    comparison.settle(monitor.get_clock().now().nanoseconds - int(SETTLE * 1e9))
                    if comparison.last:
                        print(_line(time.monotonic() - start, comparison), flush=True)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            monitor.destroy_node()
            rclpy.try_shutdown()
            codes = {name: node_process.stop(proc) for name, proc in procs.items()}
        comparison.settle(2**63)
        ok = _summary(comparison, monitor, codes, identified)
        if not ok:
            for name, log in logs.items():
                log.seek(0)
                print(f'--- {name} output ---\n{log.read()}', file=sys.stderr)
        for log in logs.values():
            log.close()
    return 0 if ok else 1


def _summary(c: Comparison, monitor: Monitor, codes: dict[str, int], identified: float) -> bool:
    d = monitor.diagnostics
    print('\nsummary')
    if c.count:
        w = c.worst
        print(
            f'  compared {c.count} stamps: max error {c.max_error:.2f} % of max force '
            f'({c.max_error * c.max_force / 100:.1f} N) at p = '
            f'{w.get("pressure", float("nan")) / 1e3:.0f} kPa, L = '
            f'{w.get("length", float("nan")):.4f} m;'
            f' mean {c.error_sum / c.count:.2f} %  (identification err on the map points: '
            f'{identified:.2f} %)'
        )
    print(
        f'  demo received: {monitor.received["force"]} measured forces, '
        f'{monitor.received["force_estimate"]} force estimates'
    )
    if d:
        print(
            f'  model_node (its last /diagnostics report) in: {d.get("received pressure", "0")} '
            f'pressure, '
            f'{d.get("received muscle_state", "0")} muscle_state; out: {d.get("estimates", "0")} '
            f'estimates;'
            f' rejected: {sum(int(v) for k, v in d.items() if k.startswith("rejected"))};'
            f' last diagnostics {d["level"]}: {d["message"]}'
        )
    print('  nodes stopped: ' + ', '.join(f'{name} exit {code}' for name, code in codes.items()))
    return c.count > 0 and all(code == 0 for code in codes.values())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='scripts/demo', description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=20.0, help='run time [s] (default 20)')
    parser.add_argument(
        '--config',
        type=Path,
        default=None,
        help='model_node parameter file (default config/dmsp_10_250.yaml)',
    )
    parser.add_argument(
        '--map',
        type=Path,
        metavar='CSV',
        help="the measured force map the simulator plays (pma-model fit --data's format; with "
        '--spec)',
    )
    parser.add_argument(
        '--spec', type=Path, metavar='YAML', help="the muscle spec of --map's muscle"
    )
    args = parser.parse_args(argv)
    if args.duration <= 0:
        parser.error('--duration must be > 0')
    if (args.map is None) != (args.spec is None):
        parser.error('--map and --spec go together: a force map CSV and the spec of its muscle')
    config = args.config or default_config()
    user_map = None if args.map is None else UserMap(args.map, args.spec)
    try:  # a file the demo cannot run: one line, before any node starts
        demo_muscle(config, user_map)
        if user_map is not None:
            user_map.read()
    except (ValueError, OSError) as err:
        print(f'{parser.prog}: error: {err}', file=sys.stderr)
        return 2
    return run(args.duration, config, user_map)


if __name__ == '__main__':
    sys.exit(main())
