"""30 s (15 s outside CI) of random messages over DDS on every input topic of a live model_node.

The fuzz mixes plausible readings (so that estimates and commands flow) with garbage: NaN,
infinities, huge and tiny magnitudes, negative values, random and unset stamps, JointStates with
random names and array lengths, long and non-ASCII strings.  One run (module fixture) feeds the
tests below; ``-s`` prints its figures (docs/reliability.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import time

import numpy as np
import pytest

from budget import FULL
from conftest import CONFIGS
from node_messages import (
    AMBIENT,
    JOINT,
    model_statuses,
    pressure,
    RELIABLE_QOS,
    state,
    status_values,
)
from pma_model_ros.core.files.param_file import node_settings, read_parameters

pytestmark = pytest.mark.ros

DURATION = 30.0 if FULL else 15.0  # [s] of fuzzing (test/budget.py)
RATE = 300.0  # [Hz] messages per input topic (900 messages/s in all)
WARM_UP = 10.0 if FULL else 5.0  # [s] before the resident-memory baseline
RSS_BOUND = 1024  # [KiB] allowed resident-memory growth after warm-up ("flat")
SEED = 20240611
MODEL = node_settings(read_parameters(CONFIGS['DMSP-10-250'])).config.model
SPECIAL = np.array([math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308, -1e308, 5e-324, -1.0, 1e9])


def rss_kib(pid: int) -> int:
    """Resident memory of process ``pid`` [KiB] (VmRSS of /proc/<pid>/status)."""
    with open(f'/proc/{pid}/status') as status:
        return next(int(line.split()[1]) for line in status if line.startswith('VmRSS:'))


class Fuzzer:
    """Random inputs: a third garbage, the rest plausible (fresh stamps, values around the
    domain).
    """

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def number(self, low: float, high: float) -> float:
        pick = self.rng.random()
        if pick < 0.15:
            return float(self.rng.choice(SPECIAL))
        if pick < 0.3:
            return float(self.rng.choice([-1, 1]) * 10.0 ** self.rng.uniform(-12, 12))
        return float(self.rng.uniform(low, high))

    def stamp(self, now) -> tuple[int, int]:
        pick = self.rng.random()
        if pick < 0.1:
            return int(self.rng.integers(-(2**31), 2**31)), int(self.rng.integers(0, 2**32))
        if pick < 0.15:
            return 0, 0
        ns = now.nanoseconds + int(self.rng.normal(0, 0.05 if pick < 0.3 else 0.005) * 1e9)
        return divmod(ns, 10**9)

    def text(self) -> str:
        return str(self.rng.choice([JOINT, JOINT, JOINT, '', 'elbow', 'ü' * 50, 'x' * 5000]))

    def stamped(self, msg, now):
        msg.header.stamp.sec, msg.header.stamp.nanosec = self.stamp(now)
        msg.header.frame_id = self.text()
        return msg

    def pressure(self, now, msg):
        msg.fluid_pressure = self.number(AMBIENT - 1e5, AMBIENT + 1.2 * MODEL.spec.max_pressure)
        return self.stamped(msg, now)

    def state(self, now, msg):
        if self.rng.random() < 0.6:
            msg.name, msg.position = [JOINT], [self.number(0.0, 1.2 * MODEL.max_length)]
            msg.velocity = [self.number(-1.0, 1.0)]
        else:
            n = [int(k) for k in self.rng.integers(0, 4, size=4)]
            msg.name = [self.text() for _ in range(n[0])]
            msg.position, msg.velocity, msg.effort = (
                [self.number(0.0, 0.3) for _ in range(k)] for k in n[1:]
            )
        return self.stamped(msg, now)

    def command(self, now, msg):
        msg.wrench.force.x = self.number(
            -100.0, 1.5 * float(MODEL.force(MODEL.spec.max_pressure, 0.25).force)
        )
        msg.wrench.force.y = self.number(-1.0, 1.0)
        return self.stamped(msg, now)


@dataclass
class Run:
    """What one fuzz run sent, received and measured."""

    sent: int = 0
    estimates: list = field(default_factory=list)
    commands: list = field(default_factory=list)
    statuses: list = field(default_factory=list)
    rss: list[tuple[float, int]] = field(default_factory=list)  # (time since start [s], KiB)
    alive: bool = False
    after: list = field(default_factory=list)  # estimates of good input after the fuzz
    recovered: list = field(default_factory=list)  # statuses at OK of good input after the fuzz

    def growth(self) -> int:
        """Resident memory growth after warm-up [KiB]: newest samples' max minus the warm-up
        sample.
        """
        base = next(kib for t, kib in self.rss if t >= WARM_UP)
        return max(kib for t, kib in self.rss if t >= WARM_UP) - base


@pytest.fixture(scope='module')
def run(module_ros):
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import WrenchStamped
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import FluidPressure, JointState

    ros, processes = module_ros
    ns = '/fuzz'
    # every input read, however long the fuzz bursts wait in the queue (a node that falls behind
    # answers only its newest inputs: test_nodes_faults.py tests that)
    node = processes.node('model_node', ns, CONFIGS['DMSP-10-250'], max_queue_delay=3600.0)
    out = Run()
    estimates = ros.collect(WrenchStamped, f'{ns}/force_estimate', RELIABLE_QOS)
    commands = ros.collect(FluidPressure, f'{ns}/pressure_command', RELIABLE_QOS)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
    pubs = [
        ros.node.create_publisher(FluidPressure, f'{ns}/pressure', qos_profile_sensor_data),
        ros.node.create_publisher(JointState, f'{ns}/muscle_state', qos_profile_sensor_data),
        ros.node.create_publisher(WrenchStamped, f'{ns}/force_command', 10),
    ]
    why = lambda: processes.output(node)  # noqa: E731
    ros.spin_until(lambda: model_statuses(diagnostics, ns), 30, 'model_node up', diagnose=why)
    fuzz = Fuzzer(SEED)
    begin = ros.now().nanoseconds
    start = next_rss = time.monotonic()
    while (elapsed := time.monotonic() - start) < DURATION and node.poll() is None:
        if time.monotonic() >= next_rss:
            out.rss.append((elapsed, rss_kib(node.pid)))
            next_rss += 1.0
        now = ros.now()
        for pub, make, kind in zip(
            pubs,
            (fuzz.pressure, fuzz.state, fuzz.command),
            (FluidPressure, JointState, WrenchStamped),
        ):
            pub.publish(make(now, kind()))
        out.sent += 3
        while (
            wait := start + out.sent / 3 / RATE - time.monotonic()
        ) > 0:  # take outputs until the next send
            ros.executor.spin_once(timeout_sec=wait)
    out.alive = node.poll() is None
    end = ros.now().nanoseconds

    def stamp(array) -> int:
        return array.header.stamp.sec * 10**9 + array.header.stamp.nanosec

    def ours(arrays) -> list:
        return [a for a in arrays if model_statuses([a], ns)]

    # A loaded test process publishes on schedule and takes outputs when it can: wait until a
    # status stamped after the fuzz arrives (reliable, in order: every earlier one is in).
    if out.alive:
        ros.spin_until(
            lambda: any(stamp(a) > end for a in ours(diagnostics)),
            10,
            'a status after the fuzz',
            diagnose=why,
        )
    out.estimates, out.commands = list(estimates), list(commands)
    out.statuses = model_statuses([a for a in diagnostics if begin <= stamp(a) <= end], ns)
    if out.alive:  # still serving good input
        estimates.clear()

        def good() -> None:
            pubs[0].publish(pressure(ros.now().to_msg(), AMBIENT + 3e5))
            pubs[1].publish(state(ros.now().to_msg(), 0.23))

        expected = float(MODEL.force(3e5, 0.23).force)
        # The first answers may still pair good input with a fuzz input that is fresh: wait for the
        # good pair.
        ros.spin_until(
            lambda: (
                estimates and estimates[-1].wrench.force.x == pytest.approx(expected, rel=1e-9)
            ),
            10,
            'the estimate of good input after the fuzz',
            every=good,
            diagnose=why,
        )
        out.after = list(estimates)

        def recovered() -> list:
            after = model_statuses([a for a in diagnostics if stamp(a) > end], ns)
            return [s for s in after if s.level == b'\x00']

        # and, the last refusal's hold (1 s) past, its level back at OK
        ros.spin_until(
            recovered, 10, 'a status at OK of good input after the fuzz', every=good, diagnose=why
        )
        out.recovered = recovered()
    last = status_values(out.statuses[-1]) if out.statuses else {}
    received = sum(
        int(v) for k, v in last.items() if k.startswith('received ') and 'rate' not in k
    )
    print(
        f'\nfuzz: {elapsed:.1f} s, sent {out.sent} messages ({out.sent / elapsed:.0f}/s); '
        f'model_node received '
        f'{received}, rejected '
        f'{sum(int(v) for k, v in last.items() if k.startswith("rejected "))}, published '
        f'{len(out.estimates)} '
        f'estimates, {len(out.commands)} pressure commands, {len(out.statuses)} statuses '
        f'received; RSS '
        f'{out.rss[0][1]} -> {out.rss[-1][1]} KiB, growth after {WARM_UP:g} s warm-up '
        f'{out.growth()} KiB; '
        f'largest estimate {max((e.wrench.force.x for e in out.estimates), default=0):.4g} N '
        f'(in-domain bound {in_domain_max_force():.4g} N)'
    )
    return out


def test_node_survives_and_still_estimates(run):
    assert run.alive
    assert run.after[-1].wrench.force.x == pytest.approx(
        float(MODEL.force(3e5, 0.23).force), rel=1e-9
    )
    assert len(run.statuses) >= DURATION - 2  # /diagnostics at 1 Hz all along: never stuck


def test_fuzz_reached_every_path(run):
    """The fuzz is not all garbage: estimates and commands flowed (the node's own counters: a
    loaded test process may receive only some of them), the garbage was refused (ERROR), and
    good input after it brings the level back to OK.  (WARN is not asked of the fuzz: a refused
    input holds ERROR for 1 s, and a third of 900 messages a second is garbage, so a report at
    WARN is chance; the warning flags' WARN is test_core_engine.py's.)
    """
    counted = status_values(run.statuses[-1])
    assert int(counted['estimates']) > 100 and int(counted['pressure commands']) > 100
    assert int(counted['rejected pressure']) > 100
    assert run.estimates and run.commands  # and they arrived
    assert b'\x02' in {s.level for s in run.statuses}
    assert run.recovered and run.recovered[0].message == 'estimating'


def test_every_output_is_finite_and_physical(run):
    forces = np.array([e.wrench.force.x for e in run.estimates])
    gauges = np.array([c.fluid_pressure for c in run.commands]) - AMBIENT
    assert np.isfinite(forces).all() and (forces >= 0).all()
    assert (
        np.isfinite(gauges).all()
        and (gauges >= 0).all()
        and (gauges <= MODEL.spec.max_pressure).all()
    )
    assert all(s.level in (b'\x00', b'\x01', b'\x02') for s in run.statuses)


def test_memory_is_flat(run):
    assert run.rss[-1][0] >= DURATION - 2
    assert run.growth() <= RSS_BOUND, run.rss


def in_domain_max_force() -> float:
    """Largest force [N] the model gives inside its validity domain: length_range x [0,
    max_pressure].
    """
    p, length = np.meshgrid(
        np.linspace(0, MODEL.spec.max_pressure, 201),
        np.linspace(MODEL.domain.length_min, MODEL.domain.length_max, 201),
    )
    return float(np.nanmax(MODEL.force(p, length, 1.0).force))


def test_every_estimate_within_the_in_domain_bound(run):
    bound = in_domain_max_force()
    assert max(e.wrench.force.x for e in run.estimates) <= bound * (1 + 1e-9)
