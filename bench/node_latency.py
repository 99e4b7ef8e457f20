"""Round-trip latency and message loss of model_node and joint_node, each against a bare rclpy
relay, same run, same settings.

    scripts/netns-run .venv/bin/python bench/node_latency.py [--duration 10] [--rate 1000]
        [--muscles 1 64] [--joints 4] [--executor single events] [--profile model.prof] [--quick]
        [--code DIR] [--repeat 1] [--stall MS] [--pairing every_input|approximate_time]
        [--measured]

A pinger (this process) publishes, at ``--rate``, one pressure and one length message per cycle
stamped with the cycle's time (the stamp is the sequence number), and measures the time until the
second answer carrying that stamp (both inputs of the cycle processed).  It publishes serialized
bytes (the wire layer's templates, velocities empty), which both responders receive.  The
responder, a separate process, is model_node or a relay that subscribes the same input types and
publishes the same output type with no model.  N = 1: ``pressure``/``muscle_state`` ->
``force_estimate`` (the single-muscle file); N > 1: ``muscle_pressures``/``muscle_states`` ->
``force_estimates`` (combined mode, a homogeneous arm of DMSP-10-250).  ``--joints N``: joint_node
with N copies of the example elbow (config/example_joint.yaml, as bench/joint_node_cost.py builds
them: 2 N muscles); a cycle is each muscle's ``<muscle>/pressure`` (FluidPressure, absolute) then
one ``joint_states`` of all N angles, and the round trip runs from the joint_states publish to the
``torque_estimate`` carrying its stamp (1 answer per cycle); its relay subscribes the same inputs
(with joint_node's input QoS) and answers each joint_states with a JointState of N efforts on
``torque_estimate`` and ``stiffness_estimate``, no model.  Default: muscle rows N = 1 and 64 and
joint rows N = 4; naming only ``--muscles`` or only ``--joints`` runs only those rows.  Lost =
answers expected minus received over the measured window; Hz = the pinger's achieved cycle rate (it
publishes 2 N + 1 messages per joint cycle).  Lengths (and pressures) change every cycle.  ``--code
DIR`` runs the model's node from another checkout (PYTHONPATH and working directory DIR; e.g. a
``git worktree`` of the commit before a change), the relay and the pinger from this one:
before/after in one script.  Timings are noisy on a shared machine: read the model/relay ratios,
not the absolute times; ``--repeat K`` runs the node and its relay in turn K times and prints the
median of each ratio over the K pairs (a pair's rows run within seconds of each other, under much
the same load).  ``--stall MS`` stops each responder (SIGSTOP) for MS ms halfway through a row and
prints how long after SIGCONT its first fresh answer came (a round trip within ``FRESH``) and how
many stale answers it gave before.  ``--measured``: the pinger also publishes, after each cycle's
inputs and not timed, a measured force of every muscle at the cycle's stamp (``measured_force``
WrenchStamped; N > 1: one ``measured_forces`` JointState), and each repeat runs model_node, then
model_node with ``residual.enabled`` (row ``+measured``: the drift monitor's cost, its ratio to the
row before), then the relay (which, like model_node without the option, does not read them).
Not a pass/fail test.
"""

from __future__ import annotations

import argparse
import copy
import cProfile
from functools import partial
import gc
import os
from pathlib import Path
import pstats
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Callable

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from geometry_msgs.msg import WrenchStamped  # noqa: E402, I100  (after the sys.path line)
from joint_node_cost import arm  # noqa: E402  (bench/, this script's folder, is on sys.path)
import rclpy  # noqa: E402
from rclpy.experimental import EventsExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import qos_profile_sensor_data, QoSProfile  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from sensor_msgs.msg import FluidPressure, JointState  # noqa: E402

from pma_model_ros.core.files.param_file import read_parameters  # noqa: E402
from pma_model_ros.core.files.shipped_data import shipped_force_map  # noqa: E402
from pma_model_ros.core.physics.geometry import STANDARD_ATMOSPHERE  # noqa: E402
from pma_model_ros.core.runtime.reidentify import reidentify  # noqa: E402
from pma_model_ros.core.simulation.truth import GroundTruth  # noqa: E402
from pma_model_ros.nodes.joint_node import JointNode  # noqa: E402
from pma_model_ros.nodes.live_reidentification import idle_priority  # noqa: E402
from pma_model_ros.nodes.model_node import ModelNode  # noqa: E402
from pma_model_ros.nodes.qos import SENSOR_INPUT  # noqa: E402
from pma_model_ros.nodes.startup import run  # noqa: E402
from pma_model_ros.tools import node_process  # noqa: E402
from pma_model_ros.wire.cdr import fluid_pressure, joint_state, wrench_stamped  # noqa: E402

SINGLE = REPO / 'config' / 'dmsp_10_250.yaml'
AMBIENT = STANDARD_ATMOSPHERE  # [Pa]
WARMUP = 1.0  # [s] after the first answer, not measured
#: ``--measured``: the row of model_node with ``residual.enabled``, run between model_node's and
#: the relay's
MEASURED = '+measured'
#: ``--fitting``: the same, while a process runs re-identification fits (:func:`fit_loop`)
FITTING = '+fitting'
DRAIN = 0.5  # [s] after the last cycle, for late answers
ANSWERS = 2  # per cycle: one per input message (muscles; joints: one per joint_states)
ANGLE = 0.2  # [rad] of every joint
REPORTS = 50  # /diagnostics reports timed per row of the callback costs
FRESH = 0.005  # [s] an answer after a stall is fresh when its round trip is within this
#: [bytes] read before each cycle of the flushed timing: it empties L1 and L2 (1 MiB per core on
#: these EPYC VMs), not the 32 MiB L3
FLUSH = 8 << 20
COLD_CYCLES = 1000  # cycles per cold-cache timing
STALE_NEVER = 3600.0  # [s] max_input_age of the callback costs
PROFILED = {'model_node': ModelNode, 'joint_node': JointNode}


def joint_muscles(joints: int) -> list[str]:
    """The muscles of :func:`joint_node_cost.arm`'s ``joints`` joints j0, j1, ..."""
    return [f'j{k}_{side}' for k in range(joints) for side in ('flexor', 'extensor')]


class Relay(Node):
    """The bare relay: the model node's input and output types and input QoS (SENSOR_INPUT), each
    input answered with its stamp, no model.
    """

    def __init__(self, **kwargs) -> None:
        super().__init__('relay', **kwargs)
        muscles = self.declare_parameter('muscles', 1).value
        joints = self.declare_parameter('joints', 0).value
        if joints:
            self.pressures: dict[str, float] = {}
            outs = [
                self.create_publisher(JointState, topic, 10)
                for topic in ('torque_estimate', 'stiffness_estimate')
            ]

            def estimates(msg: JointState) -> None:
                out = JointState(name=msg.name, effort=msg.position)
                out.header.stamp = msg.header.stamp
                for pub in outs:
                    pub.publish(out)

            for muscle in joint_muscles(joints):
                self.create_subscription(
                    FluidPressure,
                    f'{muscle}/pressure',
                    lambda m, muscle=muscle: self.pressures.__setitem__(muscle, m.fluid_pressure),
                    SENSOR_INPUT,
                )
            self.create_subscription(JointState, 'joint_states', estimates, SENSOR_INPUT)
        elif muscles == 1:
            pub = self.create_publisher(WrenchStamped, 'force_estimate', 10)

            def answer(msg, value: float) -> None:
                out = WrenchStamped()
                out.header.stamp = msg.header.stamp
                out.wrench.force.x = value
                pub.publish(out)

            self.create_subscription(
                FluidPressure, 'pressure', lambda m: answer(m, m.fluid_pressure), SENSOR_INPUT
            )
            self.create_subscription(
                JointState, 'muscle_state', lambda m: answer(m, m.position[0]), SENSOR_INPUT
            )
        else:
            pub = self.create_publisher(JointState, 'force_estimates', 10)

            def relay(msg: JointState) -> None:
                out = JointState(name=msg.name, effort=msg.position)
                out.header.stamp = msg.header.stamp
                pub.publish(out)

            for topic in ('muscle_pressures', 'muscle_states'):
                self.create_subscription(JointState, topic, relay, SENSOR_INPUT)


def multi_muscle_file(n: int, folder: Path) -> Path:
    """A combined-mode parameter file of ``n`` DMSP-10-250 muscles m00, m01, ..."""
    shipped = read_parameters(SINGLE)
    block = {key: shipped[key] for key in ('muscle', 'model', 'length_range', 'models')}
    names = [f'm{i:02d}' for i in range(n)]
    params = {
        'muscles': names,
        'input_mode': 'combined',
        **{name: copy.deepcopy(block) for name in names},
    }
    path = folder / f'arm_{n}.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': params}}, default_flow_style=None))
    return path


class Pinger(Node):
    """Publishes the inputs of N muscles (or N joints) at a fixed rate; records the round trip of
    each cycle.
    """

    def __init__(
        self,
        namespace: str,
        muscles: int,
        context: rclpy.Context,
        joints: bool = False,
        answers: int = ANSWERS,
        measured: bool = False,
    ) -> None:
        super().__init__('pinger', context=context)
        self.sent: dict[int, float] = {}  # stamp [ns] -> perf_counter at publish [s]
        self.answers: dict[int, list[float]] = {}
        reliable = QoSProfile(depth=1000)
        self.n, self.joints = muscles, joints
        self.per_cycle = 1 if joints else answers  # answers per cycle
        self._timed = 2 * muscles if joints else 0  # the first answered message: sent from there
        if joints:
            self._pubs = tuple(
                self.create_publisher(
                    FluidPressure, f'{namespace}/{muscle}/pressure', qos_profile_sensor_data
                )
                for muscle in joint_muscles(muscles)
            ) + (
                self.create_publisher(
                    JointState, f'{namespace}/joint_states', qos_profile_sensor_data
                ),
            )
            self.create_subscription(
                JointState, f'{namespace}/torque_estimate', self._on_answer, reliable
            )
        elif muscles == 1:
            self._pubs = (
                self.create_publisher(
                    FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data
                ),
                self.create_publisher(
                    JointState, f'{namespace}/muscle_state', qos_profile_sensor_data
                ),
            )
            self.create_subscription(
                WrenchStamped, f'{namespace}/force_estimate', self._on_answer, reliable
            )
        else:
            self._pubs = (
                self.create_publisher(
                    JointState, f'{namespace}/muscle_pressures', qos_profile_sensor_data
                ),
                self.create_publisher(
                    JointState, f'{namespace}/muscle_states', qos_profile_sensor_data
                ),
            )
            self.create_subscription(
                JointState, f'{namespace}/force_estimates', self._on_answer, reliable
            )
        self._names = [f'j{k}' if joints else f'm{k:02d}' for k in range(muscles)]
        if joints:
            self._templates = (fluid_pressure(''), joint_state(self._names, 'position'))
        elif muscles == 1:
            self._templates = (fluid_pressure(''), joint_state(['DMSP-10-250'], 'position'))
        else:
            self._templates = tuple(joint_state(self._names, 'position') for _ in range(2))
        #: (publisher, template) of the measured forces (``--measured``), else None
        self._measured = None
        if measured and not joints:
            self._measured = (
                (
                    self.create_publisher(
                        WrenchStamped, f'{namespace}/measured_force', qos_profile_sensor_data
                    ),
                    wrench_stamped(''),
                )
                if muscles == 1
                else (
                    self.create_publisher(
                        JointState, f'{namespace}/measured_forces', qos_profile_sensor_data
                    ),
                    joint_state(self._names, 'effort'),
                )
            )
            self._measured[1].values[:] = 100.0  # [N]

    def _on_answer(self, msg) -> None:
        t = time.perf_counter()
        key = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        self.answers.setdefault(key, []).append(t)

    def messages(self, k: int, stamp: int) -> tuple[bytes, ...]:
        """Cycle ``k``'s pressure and length (or angle) messages stamped ``stamp`` [ns], as bytes,
        in their order (the wire layer's templates: a pinger of 33 messages per cycle at 16 joints
        must not be the bottleneck).
        """
        gauge = 300e3 + 100e3 * np.sin(k * 1e-3)
        first, second = self._templates
        if self.joints:
            first.values[0], second.values[:] = AMBIENT + gauge, ANGLE
            return (first(stamp),) * (2 * self.n) + (second(stamp),)
        if self.n == 1:
            first.values[0] = AMBIENT + gauge
            second.values[0] = 0.23 + 0.005 * np.sin(k * 1e-3)
        else:
            first.values[:] = AMBIENT + gauge
            second.values[:] = 0.23 + 0.005 * np.sin(k * 1e-3 + 0.1 * np.arange(self.n))
        return first(stamp), second(stamp)

    def cycle(self, k: int) -> int:
        """Publish one cycle's messages, all with one stamp; the stamp [ns]."""
        stamp = self.get_clock().now().nanoseconds
        for i, (pub, data) in enumerate(zip(self._pubs, self.messages(k, stamp))):
            if i == self._timed:
                self.sent[stamp] = time.perf_counter()
            pub.publish(data)
        if self._measured is not None:
            pub, template = self._measured
            pub.publish(template(stamp))
        return stamp


def publish_loop(
    pinger: Pinger, rate: float, until: float, first_measured: list[int], warm_end: float
) -> None:
    """Publish cycles at ``rate`` [Hz] on the perf_counter clock until ``until``."""
    period, k = 1.0 / rate, 0
    next_t = time.perf_counter()
    while next_t < until:
        delay = next_t - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        stamp = pinger.cycle(k)
        if not first_measured and next_t >= warm_end:
            first_measured.append(stamp)
        k += 1
        next_t += period


def stall(pid: int, at: float, seconds: float, resumed: list[float]) -> None:
    """Stop process ``pid`` (SIGSTOP) at ``at`` [perf_counter s] for ``seconds``, then SIGCONT;
    the time it was resumed into ``resumed``.
    """
    time.sleep(max(0.0, at - time.perf_counter()))
    os.kill(pid, signal.SIGSTOP)
    time.sleep(seconds)
    resumed.append(time.perf_counter())
    os.kill(pid, signal.SIGCONT)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` [s] (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def measure(
    responder: list[str],
    muscles: int,
    duration: float,
    rate: float,
    namespace: str,
    joints: bool = False,
    code: Path | None = None,
    stalled: float = 0.0,
    answers: int = ANSWERS,
    measured: bool = False,
) -> dict:
    """Start ``responder`` (from checkout ``code``, if given), ping it, stop it; round trips [ms],
    loss, its CPU use and the achieved cycle rate.  ``stalled`` [s]: the responder is stopped that
    long halfway through; then also how long after it runs again its answers are fresh (a round
    trip within :data:`FRESH`) and how many stale answers it gave meanwhile.  ``measured``: the
    pinger also publishes measured forces (``--measured``).
    """
    env = None if code is None else os.environ | {'PYTHONPATH': str(code)}
    # the pinger must not stall either: what the rows before left (the in-process callback cost
    # builds a 64-muscle node) to the permanent generation, as the nodes do (nodes/startup.py);
    # else a full collection during a row stalled it ~98 ms, losing ~640 answers of model_node
    gc.collect()
    gc.freeze()
    with tempfile.TemporaryFile('w+') as log:
        proc = node_process.start(responder, log, env, code)
        context = rclpy.Context()
        rclpy.init(context=context)
        pinger = Pinger(namespace, muscles, context, joints, answers, measured)
        executor = EventsExecutor(context=context)
        executor.add_node(pinger)
        try:
            deadline = time.monotonic() + 30
            while not pinger.answers:  # discovery: ping slowly until the responder answers
                if time.monotonic() > deadline or proc.poll() is not None:
                    log.seek(0)
                    raise SystemExit(f'no answer from {responder[:4]}...:\n{log.read()}')
                pinger.cycle(0)
                executor.spin_once(timeout_sec=0.05)
            start = time.perf_counter()
            cpu0, first = cpu_seconds(proc.pid), []
            thread = threading.Thread(
                target=publish_loop,
                args=(pinger, rate, start + WARMUP + duration, first, start + WARMUP),
                daemon=True,
            )
            thread.start()
            resumed: list[float] = []
            if stalled:
                at = start + WARMUP + duration / 2
                threading.Thread(
                    target=stall, args=(proc.pid, at, stalled, resumed), daemon=True
                ).start()
            while thread.is_alive() or time.perf_counter() < start + WARMUP + duration + DRAIN:
                executor.spin_once(timeout_sec=0.01)
            cpu = (cpu_seconds(proc.pid) - cpu0) / (WARMUP + duration)
        finally:
            node_process.stop(proc)
            executor.shutdown()
            pinger.destroy_node()
            rclpy.shutdown(context=context)
    measured = [s for s in pinger.sent if s >= first[0]]
    per_cycle = pinger.per_cycle
    trips = [
        pinger.answers[s][per_cycle - 1] - pinger.sent[s]
        for s in measured
        if len(pinger.answers.get(s, ())) >= per_cycle
    ]
    received = sum(min(len(pinger.answers.get(s, ())), per_cycle) for s in measured)
    ms = np.array(trips) * 1e3 if trips else np.array([np.nan])
    span = pinger.sent[measured[-1]] - pinger.sent[measured[0]]
    after = {}
    if resumed:  # (answer time, round trip) of every answer after the stall, in time order
        late = sorted(
            (t, t - pinger.sent[s])
            for s in measured
            for t in pinger.answers.get(s, ())
            if t > resumed[0]
        )
        fresh = next((t for t, trip in late if trip <= FRESH), np.nan)
        after = {
            'recovery': (fresh - resumed[0]) * 1e3,
            'stale': sum(trip > FRESH for t, trip in late if t <= fresh or np.isnan(fresh)),
        }
    return after | {
        'cycles': len(measured),
        'hz': (len(measured) - 1) / span if span > 0 else np.nan,
        'lost': per_cycle * len(measured) - received,
        'p50': np.percentile(ms, 50),
        'p99': np.percentile(ms, 99),
        'max': ms.max(),
        'cpu': 100 * cpu,
    }


def responders(
    muscles: int,
    executor: str,
    folder: Path,
    profile: Path | None,
    joints: bool = False,
    pairing: str = 'every_input',
    measured: bool = False,
    fitting: bool = False,
) -> dict[str, list[str]]:
    """The command lines of the model's node (model_node with ``pairing``; or joint_node with
    ``muscles`` joints), with ``measured`` also model_node with ``residual.enabled``
    (:data:`MEASURED`; with ``fitting`` again, :data:`FITTING`), and of its relay, by name, in the
    order they run.
    """
    params, name = {'executor': executor}, 'joint_node' if joints else 'model_node'
    if not joints:
        params['pairing'] = pairing
    if joints:  # N copies of the example elbow; their muscle files are in config/
        arm(path := folder / f'joints_{muscles}.yaml', muscles)
        model = node_process.command(
            name, '/bench', path, params | {'config_dir': REPO / 'config'}
        )
    elif muscles == 1:
        model = node_process.command(name, '/bench', SINGLE, params)
    else:
        model = node_process.command(name, '/bench', multi_muscle_file(muscles, folder), params)
    if profile is not None:  # this script as the node, profiled once it is built
        model[1:3] = [__file__, f'--profiled-{name}={profile}']
    nodes = {name: model}
    if measured and not joints:
        nodes[MEASURED] = [*model, '-p', 'residual.enabled:=true']
        if fitting:
            nodes[FITTING] = nodes[MEASURED]
    relay = [
        sys.executable,
        __file__,
        '--relay',
        '--ros-args',
        '-r',
        '__ns:=/bench',
        '-p',
        f'executor:={executor}',
        '-p',
        f'{"joints" if joints else "muscles"}:={muscles}',
    ]
    return nodes | {'relay': relay}


def fit_loop(busy: bool = False) -> int:
    """Re-identification fits, one after the other until terminated, as model_node's worker
    runs them (:func:`~pma_model_ros.core.runtime.reidentify.reidentify`, every thread in the
    SCHED_IDLE class): the DMSP-10-250 file on 3 noisy samples at 40 pressures at each length
    of Table A2 scaled by 0.85.  ``busy`` (``--busy``): a loop that only spins, in the same
    class, instead: what any busy neighbour costs, the fit's own work (memory, caches) aside.
    """
    idle_priority()
    while busy:
        pass
    parameters = read_parameters(SINGLE)
    fmap, rng = shipped_force_map('DMSP-10-250'), np.random.default_rng(1)
    truth = GroundTruth(fmap)
    rows = [
        (p, L, 0.85 * float(truth.force(p, L)) + rng.normal(0, 0.01 * fmap.max_force))
        for L in np.unique(fmap.length)
        for p in np.linspace(0, parameters['pressure_range'][1], 40)
        for _ in range(3)
    ]
    samples = np.array(rows)
    while True:
        reidentify(parameters, samples)


def profiled_node(name: str, out: Path, args: list[str]) -> int:
    """Node ``name`` (model_node or joint_node) with cProfile from the end of its construction (its
    spinning only) to its exit, into ``out``.
    """
    profiler = cProfile.Profile()

    def make() -> Node:
        node = PROFILED[name]()
        profiler.enable()
        return node

    code = run(name, make, args)
    profiler.disable()
    profiler.dump_stats(out)
    return code


def callback_cost(
    muscles: int, folder: Path, cycles: int = 2000, measured: bool = False
) -> dict[str, float]:
    """CPU time of model_node's callbacks per cycle (``cycle``: both inputs as bytes, called
    directly: no executor, no wait) and of the engine's share of it (``engine``: its two calls per
    cycle) [us]; answers go nowhere.  Then the CPU time of one /diagnostics report of every muscle
    (``report``: publish_status, the 1 Hz timer's work, a stall of the executor), each after 20 new
    cycles [ms], and the baseline: the bare relay's callbacks per cycle of the same inputs, each
    deserialized by rclpy first as its executor does (``relay`` [us]).  ``cold`` and
    ``cold_relay`` [us]: the same per cycle with L1 and L2 flushed before each cycle (a
    :data:`FLUSH` read, not timed), as in a node whose core also runs the DDS threads and other
    processes between two messages.  ``measured``: also model_node with ``residual.enabled``, a
    measured force of every muscle after each cycle's inputs (``measured_cycle``,
    ``measured_cold`` [us], ``measured_report`` [ms]; every force paired, else it stops).
    """
    params = SINGLE if muscles == 1 else multi_muscle_file(muscles, folder)
    # the inputs are built first, stamped then, and taken over up to ~0.2 s: an input age of an
    # hour keeps them fresh (else the later ones are stale, and their cost is a stale input's)
    rclpy.init(
        args=[
            '--ros-args',
            '-r',
            '__ns:=/cost',
            '--params-file',
            str(params),
            '-p',
            f'max_input_age:={STALE_NEVER}',
        ]
    )
    try:
        # the pinger builds the input messages
        node = Pinger('/unused', muscles, rclpy.get_default_context(), measured=measured)
        model = ModelNode()
        model_cycle = node_cycle(model, muscles)

        def check_estimated(since: int, inputs: list[tuple[bytes, ...]]) -> None:
            """Stop unless every input of ``inputs`` gave an estimate after the first ``since``
            (the first cycle's pressure may not).
            """
            counts = model.engine.counts(0)
            if counts.get('estimates', 0) - since < 2 * len(inputs) - 1:
                raise SystemExit(f'callback cost: inputs refused: {counts}')

        inputs = stamped_cycles(node, model, cycles)
        per_cycle = hot(model_cycle, inputs)
        check_estimated(0, inputs)
        engine, now = model.engine, model.now()
        pressures, rates = np.full(muscles, AMBIENT + 300e3), np.zeros(muscles)
        lengths = [0.23 + 0.005 * np.sin(k * 1e-3 + 0.1 * rates) for k in range(cycles)]
        start = time.process_time()
        for k in range(cycles):
            t = now + k * 1000
            if muscles == 1:
                engine.pressure(0, pressures.item(0), t, t)
                engine.length(0, lengths[k].item(0), 0.0, t, t)
            else:
                engine.pressures(pressures, t, t)
                engine.lengths(lengths[k], rates, t, t)
        own = (time.process_time() - start) / cycles
        report = report_time(model, model_cycle, partial(stamped_cycles, node, model))
        costs = measured_cost(node, muscles) if measured else {}
        relay = Relay(parameter_overrides=[Parameter('muscles', value=muscles)])
        subscriptions = list(relay.subscriptions)  # the pressure's, then the length's

        def relay_cycle(cycle: tuple[bytes, ...]) -> None:
            for subscription, data in zip(subscriptions, cycle):
                subscription.callback(deserialize_message(data, subscription.msg_type))

        relayed = hot(relay_cycle, inputs)
        fresh = stamped_cycles(node, model, COLD_CYCLES)
        since = model.engine.counts(0)['estimates']
        cold = {'model': flushed(model_cycle, fresh), 'relay': flushed(relay_cycle, fresh)}
        check_estimated(since, fresh * 5)  # flushed() runs the inputs 5 times
        for made in (relay, model, node):
            made.destroy_node()
    finally:
        rclpy.shutdown()
    return costs | {
        'cycle': per_cycle * 1e6,
        'engine': own * 1e6,
        'report': report * 1e3,
        'relay': relayed * 1e6,
        'cold': cold['model'] * 1e6,
        'cold_relay': cold['relay'] * 1e6,
    }


def node_cycle(model: ModelNode, muscles: int) -> Callable[[tuple[bytes, ...]], None]:
    """One cycle's messages (:meth:`Pinger.messages`, with a measured force third) handed to
    ``model``'s callbacks as its executor would.
    """
    handlers = (
        (partial(model._on_pressure, 0), partial(model._on_state, 0))
        if muscles == 1
        else (model._on_pressures, model._on_states)
    )
    if len(handlers) < 3 and model.residual is not None:
        handlers += (
            partial(model._on_measured_force, 0) if muscles == 1 else model._on_measured_forces,
        )

    def cycle(messages: tuple[bytes, ...]) -> None:
        for handler, data in zip(handlers, messages):
            handler(data)

    return cycle


def stamped_cycles(
    pinger: Pinger, model: ModelNode, count: int, measured: bool = False
) -> list[tuple[bytes, ...]]:
    """``count`` cycles' messages stamped by ``model``'s clock as they are built, with a measured
    force of every muscle third if ``measured``.
    """
    cycles = []
    for k in range(count):
        stamp = model.now()
        messages = pinger.messages(k, stamp)
        cycles.append(messages + (pinger._measured[1](stamp),) if measured else messages)
    return cycles


def hot(run: Callable[[tuple[bytes, ...]], None], inputs: list[tuple[bytes, ...]]) -> float:
    """CPU time [s] per cycle of ``run`` over ``inputs``, one after the other."""
    start = time.process_time()
    for cycle in inputs:
        run(cycle)
    return (time.process_time() - start) / len(inputs)


def report_time(
    model: ModelNode,
    run: Callable[[tuple[bytes, ...]], None],
    inputs: Callable[[int], list[tuple[bytes, ...]]],
) -> float:
    """CPU time [s] of one /diagnostics report of ``model`` (publish_status), the mean of
    :data:`REPORTS`, each after 20 new cycles of ``run``: new counters, rates and delays to write.
    """
    report = 0.0
    for _ in range(REPORTS):
        for cycle in inputs(20):
            run(cycle)
        start = time.process_time()
        model.publish_status(model.now())
        report += (time.process_time() - start) / REPORTS
    return report


def measured_cost(pinger: Pinger, muscles: int, cycles: int = 2000) -> dict[str, float]:
    """:func:`callback_cost`'s figures of model_node with ``residual.enabled`` [us, ms]."""
    model = ModelNode(parameter_overrides=[Parameter('residual.enabled', value=True)])
    model_cycle = node_cycle(model, muscles)
    inputs = partial(stamped_cycles, pinger, model, measured=True)
    per_cycle = hot(model_cycle, inputs(cycles))
    cold = flushed(model_cycle, inputs(COLD_CYCLES))
    report = report_time(model, model_cycle, inputs)
    sent = cycles + 5 * COLD_CYCLES + 20 * REPORTS
    paired = sum(c['paired'] for c in model.residual.counts)
    if paired != sent * muscles:
        raise SystemExit(f'callback cost: measured forces not paired: {model.residual.counts}')
    model.destroy_node()
    return {
        'measured_cycle': per_cycle * 1e6,
        'measured_cold': cold * 1e6,
        'measured_report': report * 1e3,
    }


def flushed(run: Callable[[tuple[bytes, ...]], None], inputs: list[tuple[bytes, ...]]) -> float:
    """CPU time [s] per cycle of ``run`` over ``inputs`` with L1 and L2 flushed before each
    cycle (reading :data:`FLUSH`), each cycle timed on its own (the thread's CPU clock, not the
    flush); the median of 5 runs.
    """
    flush, clock = np.ones(FLUSH, np.uint8), time.thread_time_ns
    times = []
    for _ in range(5):
        total = 0
        for cycle in inputs:
            flush.sum()
            start = clock()
            run(cycle)
            total += clock() - start
        times.append(total * 1e-9 / len(inputs))
    return sorted(times)[2]


def print_rows(
    joints: bool, counts: list[int], args: argparse.Namespace, folder: Path, last: tuple
) -> None:
    """Measure and print the rows of ``counts`` muscles (or joints) x ``args.executor``: the node
    and its relay in turn, ``args.repeat`` times, then the median of each ratio over the pairs.
    """
    node = 'joint_node' if joints else 'model_node'
    what = (
        '2 N pressures + 1 joint_states per cycle, 1 answer (torque_estimate); N = joints'
        if joints
        else '2 answers per cycle; N = muscles'
        + (
            ', a measured force of each muscle per cycle (residual.enabled)'
            if args.measured
            else ''
        )
        + (f'; {FITTING} beside a process that only spins (--busy)' if args.busy else '')
    )
    print(
        f'\n{node}: round trip at {args.rate:g} Hz, {args.duration:g} s per row, {what} (times '
        f"in ms; ratio = {node} / relay on the relay's row"
        + (
            f', {MEASURED} and {FITTING} / {node} on theirs)'
            if args.measured and not joints
            else ')'
        )
    )
    print(
        f'{"N":>3} {"executor":<8} {"responder":<11} {"cycles":>7} {"Hz":>6} {"lost":>5} '
        f'{"p50":>7} {"p99":>7} {"max":>7} {"cpu %":>6} {"p50 ratio":>9} {"p99 ratio":>9} '
        f'{"cpu ratio":>9}'
    )
    for n in counts:
        for executor in args.executor:
            ratios: dict[str, list] = {}
            for repeat in range(args.repeat):
                profile = args.profile if (joints, n, executor) == last and not repeat else None
                result = {}
                commands = responders(
                    n, executor, folder, profile, joints, args.pairing, args.measured, args.fitting
                )
                loop = '--busy-loop' if args.busy else '--fit-loop'
                for name, cmd in commands.items():
                    code = args.code if name != 'relay' else None
                    once = name == node and args.pairing == 'approximate_time'
                    fits = (
                        subprocess.Popen([sys.executable, __file__, loop])
                        if (name == FITTING)
                        else None
                    )
                    result[name] = r = measure(
                        cmd,
                        n,
                        args.duration,
                        args.rate,
                        '/bench',
                        joints,
                        code,
                        args.stall / 1e3,
                        1 if once else ANSWERS,
                        args.measured,
                    )
                    if fits is not None:
                        fits.terminate()
                        fits.wait()
                    ratio = ''
                    if name != node:  # the node / its relay; the option / the node without it
                        top, bottom = (result[node], r) if name == 'relay' else (r, result[node])
                        pair = [top[k] / bottom[k] for k in ('p50', 'p99', 'cpu')]
                        ratios.setdefault(name, []).append(pair)
                        ratio = ' '.join(f'{x:>9.2f}' for x in pair)
                    stalled = (
                        f'  after the stall: fresh in {r["recovery"]:.1f} ms, {r["stale"]} stale '
                        'answers before'
                        if 'recovery' in r
                        else ''
                    )
                    print(
                        f'{n:>3} {executor:<8} {name:<11} {r["cycles"]:>7} {r["hz"]:>6.0f} '
                        f'{r["lost"]:>5} {r["p50"]:>7.3f} {r["p99"]:>7.3f} {r["max"]:>7.2f} '
                        f'{r["cpu"]:>6.1f} {ratio}{stalled}',
                        flush=True,
                    )
            for name, pairs in ratios.items() if args.repeat > 1 else ():
                medians = ' '.join(f'{x:>9.2f}' for x in np.median(pairs, axis=0))
                what = f'median of {args.repeat}: ' + (
                    f'{node} / relay' if name == 'relay' else f'{name} / {node}'
                )
                print(f'{n:>3} {executor:<8} {what:<59} {medians}')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--duration', type=float, default=10.0, help='measured seconds per row (default 10)'
    )
    parser.add_argument(
        '--rate', type=float, default=1000.0, help='cycles per second (default 1000)'
    )
    parser.add_argument(
        '--muscles', type=int, nargs='+', help='model_node rows: N muscles (default 1 64)'
    )
    parser.add_argument(
        '--joints', type=int, nargs='+', help='joint_node rows: N joints (default 4)'
    )
    parser.add_argument(
        '--executor',
        nargs='+',
        default=['single', 'events'],
        choices=['single', 'events'],
        help='executor of the responders (default: both)',
    )
    parser.add_argument(
        '--profile',
        type=Path,
        help='cProfile the node (model_node or joint_node) of the last row into this file',
    )
    parser.add_argument(
        '--quick', action='store_true', help='2 s per row (what bench/run --quick passes)'
    )
    parser.add_argument(
        '--repeat',
        type=int,
        default=1,
        help='node and relay rows in turn, this many times, and the median ratios (default 1)',
    )
    parser.add_argument(
        '--pairing',
        choices=['every_input', 'approximate_time'],
        default='every_input',
        help="model_node's pairing; approximate_time: one answer per cycle, the round trip to it "
        '(the relay still answers each input)',
    )
    parser.add_argument(
        '--stall',
        type=float,
        default=0.0,
        help='stop each responder this many ms halfway (SIGSTOP/SIGCONT); print how soon its '
        f'answers are fresh again (a round trip within {FRESH * 1e3:g} ms)',
    )
    parser.add_argument(
        '--measured',
        action='store_true',
        help='model_node with residual.enabled, and a measured force of every muscle per cycle',
    )
    parser.add_argument(
        '--fitting',
        action='store_true',
        help='with --measured, a row more: the same node while a process runs re-identification '
        "fits as model_node's worker does (SCHED_IDLE)",
    )
    parser.add_argument(
        '--busy',
        action='store_true',
        help='with --fitting, the process beside the node spins in the same class instead of '
        'fitting',
    )
    parser.add_argument(
        '--code',
        type=Path,
        help="run the model's node from this checkout (before/after); skips the callback costs",
    )
    if sys.argv[1:] in (['--fit-loop'], ['--busy-loop']):
        return fit_loop(busy=sys.argv[1] == '--busy-loop')
    if '--relay' in sys.argv:
        return run('relay', Relay, [a for a in sys.argv if a != '--relay'])
    if sys.argv[1:2] and sys.argv[1].startswith('--profiled-'):
        name, _, out = sys.argv[1].removeprefix('--profiled-').partition('=')
        return profiled_node(name, Path(out), sys.argv[2:])
    args = parser.parse_args()
    if args.quick:
        args.duration = 2.0
    if args.muscles is None and args.joints is None:
        args.muscles, args.joints = [1, 64], [4]
    muscles, joints = args.muscles or [], args.joints or []
    last = (
        (True, joints[-1], args.executor[-1])
        if joints
        else (False, muscles[-1], args.executor[-1])
    )
    with tempfile.TemporaryDirectory() as tmp:
        if muscles and not args.code:
            print(
                'model_node callbacks called directly (no executor, no DDS), CPU per cycle (both '
                'inputs):'
            )
        for n in muscles if not args.code else []:
            cost = callback_cost(n, Path(tmp), measured=args.measured)
            print(
                f"{n:>3} muscles: {cost['cycle']:5.0f} us, of which the engine's two calls "
                f'{cost["engine"]:.0f} us'
                + (
                    ' (one vectorised call per message)'
                    if n > 1
                    else ' (its one-muscle float path)'
                )
                + f'; a /diagnostics report {cost["report"]:.2f} ms; the bare relay '
                f'{cost["relay"]:.0f} us; L1 and L2 flushed before each cycle: {cost["cold"]:.0f} '
                f'us, the relay {cost["cold_relay"]:.0f} us'
            )
            if args.measured:
                print(
                    f'{"":>12} with residual.enabled and a measured force of each muscle: '
                    f'{cost["measured_cycle"]:5.0f} us, flushed {cost["measured_cold"]:.0f} us; '
                    f'a report {cost["measured_report"]:.2f} ms'
                )
        if muscles:
            print_rows(False, muscles, args, Path(tmp), last)
        if joints:
            print_rows(True, joints, args, Path(tmp), last)
    if args.profile:
        node = 'joint_node' if last[0] else 'model_node'
        print(f'\ncProfile of {node} while spinning (N={last[1]}, {last[2]}), top 15 by own time:')
        pstats.Stats(str(args.profile)).sort_stats('tottime').print_stats(15)
    return 0


if __name__ == '__main__':
    sys.exit(main())
