"""joint_simulator_node's callbacks and timer called in-process, on a private rclpy Context whose
ROS time the test sets (use_sim_time, the clock overridden): no DDS, no waiting.

Expected values: the rows of the measured map (Table A2, read here from the shipped CSV), the
first-order lag p(t) = p_cmd + (p0 - p_cmd) exp(-t/τ) by hand, the joint's limits, and for the link
the work-energy balance of the map torque and a damped oscillator's decay.  Bad parameters end the
start-up with a StartupError naming them (and the process with one line).
"""

import csv
import math
import sys

import numpy as np
import pytest
from rclpy.clock import ClockType
from rclpy.time import Time
from sensor_msgs.msg import FluidPressure, JointState

from conftest import lines_of_failed_start, REPO
from node_messages import AMBIENT, record
from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.simulation.muscle import GroundTruth
from pma_model_ros.nodes.joint_simulator_node import JointSimulatorNode
from pma_model_ros.nodes.startup import StartupError

with open(REPO / 'pma_model_ros' / 'core' / 'data' / 'dmsp_10_250_force_map.csv') as f:
    #: Table A2 (DMSP-10-250): {(gauge pressure [Pa], length [m]): force [N]}
    TABLE_A2 = {
        (float(row[0]), float(row[1])): float(row[2])
        for row in csv.reader(line for line in f if not line.startswith(('#', 'pressure')))
    }


@pytest.fixture
def make_node(private_node):
    """A factory of JointSimulatorNodes (keyword arguments: parameters), each at ROS time 0 on
    its own Context.
    """

    def make(**params):
        return private_node(JointSimulatorNode, overrides={'use_sim_time': True} | params)

    return make


def tick(node, t: float) -> None:
    """The timer's callback at ROS time ``t`` [s]."""
    clock = node.get_clock()
    clock.set_ros_time_override(Time(nanoseconds=round(t * 1e9), clock_type=ClockType.ROS_TIME))
    node._tick()


def command(node, k: int, absolute: float) -> None:
    node._on_command(k, FluidPressure(fluid_pressure=absolute))


def test_held_pressures_lag_then_give_the_map_torque(make_node):
    """Held at 1 rad (the limit): flexor 0.234 - 0.015 = 0.219 m, extensor 0.235 + 0.015 = 0.25 m,
    both measured lengths of Table A2.
    """
    node = make_node(length_at_zero=[0.234, 0.235], pressure_time_constant=0.05)
    states = record(node._state_pub)
    flexor, extensor = (record(p) for p in node._pressure_pubs)
    node._on_angle(JointState(name=['elbow'], position=[1.0]))
    command(node, 0, AMBIENT + 650000)  # measured pressures of Table A2
    command(node, 1, AMBIENT + 285000)
    tick(node, 0.05)  # one time constant from gauge 0: p = p_cmd (1 - e^-1), e^-1 = 0.3678794
    p0, p1 = 650000 * (1 - math.exp(-1)), 285000 * (1 - math.exp(-1))  # 410878.4, 180154.4 Pa
    assert flexor[-1].fluid_pressure == pytest.approx(AMBIENT + p0, rel=1e-12)
    assert extensor[-1].fluid_pressure == pytest.approx(AMBIENT + p1, rel=1e-12)
    # the map is monotone between its rows: the flexor between the 402187 and 444375 Pa rows
    # (22.8333 .. 46.1667 N), the extensor between the 132500 and 196250 Pa rows
    # (84.8333 .. 139.5 N)
    assert 0.015 * (22.8333 - 139.5) < states[-1].effort[0] < 0.015 * (46.1667 - 84.8333)
    tick(node, 0.1)  # from p(0.05): p_cmd + (p(0.05) - p_cmd) e^-1 = p_cmd (1 - e^-2)
    assert flexor[-1].fluid_pressure == pytest.approx(AMBIENT + 650000 * (1 - math.exp(-2)))
    tick(node, 2.0)  # 40 time constants: e^-38 of the step is left, < 1e-11 Pa
    assert flexor[-1].fluid_pressure == pytest.approx(AMBIENT + 650000, rel=1e-12)
    assert extensor[-1].fluid_pressure == pytest.approx(AMBIENT + 285000, rel=1e-12)
    assert (TABLE_A2[650000, 0.219], TABLE_A2[285000, 0.25]) == (158.6667, 217.6667)
    # τ = r (F0 - F1) = 0.015 (158.6667 - 217.6667) = -0.885 N·m
    state = states[-1]
    assert state.effort[0] == pytest.approx(-0.885, rel=1e-9)
    assert (list(state.name), list(state.position), list(state.velocity)) == (
        ['elbow'],
        [1.0],
        [0.0],
    )
    assert state.header.stamp.sec == 2 and state.header.stamp.nanosec == 0
    assert flexor[-1].header.stamp == extensor[-1].header.stamp == state.header.stamp
    assert len(states) == len(flexor) == len(extensor) == 3  # one of each per tick


def test_angle_commands_move_the_held_joint_within_its_limits(make_node):
    node = make_node(limits=[-0.5, 0.8])
    states = record(node._state_pub)

    def held_after(*names_and_positions):
        for names, positions in names_and_positions:
            node._on_angle(JointState(name=names, position=positions))
        tick(node, 0.01 * (len(states) + 1))
        return states[-1].position[0]

    assert held_after((['knee'], [0.5])) == 0.0  # not this joint
    assert held_after((['elbow'], [])) == 0.0  # names and positions do not pair
    assert held_after((['knee', 'elbow'], [0.7, 0.3])) == 0.3  # the elbow's entry
    assert held_after((['elbow'], [math.nan])) == 0.3  # ignored
    assert held_after((['elbow'], [3.0])) == 0.8  # stopped at the upper limit
    assert held_after((['elbow'], [-7.0])) == -0.5  # and at the lower one
    assert all(s.velocity[0] == 0.0 for s in states)  # held: it never moves by itself


def test_a_link_ignores_angle_commands_and_stops_at_its_limit(make_node):
    node = make_node(mode='link', pressure_time_constant=0.0, limits=[-1.0, 0.4])
    states = record(node._state_pub)
    node._on_angle(JointState(name=['elbow'], position=[0.3]))
    tick(node, 0.01)
    # unpressurised, both at the map's 5 kPa row: 0 N at every length, no torque, no motion
    assert (states[-1].position[0], states[-1].effort[0]) == (0.0, 0.0)
    command(node, 0, AMBIENT + 650000)  # the flexor alone turns it positive
    for i in range(2, 200):
        tick(node, 0.01 * i)
        if states[-1].position[0] == 0.4:
            break
    assert states[-2].velocity[0] > 0 and states[-1].velocity[0] == 0.0  # stopped, not bounced
    tick(node, 0.01 * (i + 1))
    assert states[-1].position[0] == 0.4 and states[-1].effort[0] > 0  # still pulled into the stop


def potential(theta: float) -> float:
    """V(θ) = -∫₀^θ τ dθ' [J] of the map torque at 500 kPa on both muscles (trapezoid rule, 401
    points: 1e-7 J off 0.185 J at 0.3 rad against 20001).
    """
    truth = GroundTruth(shipped_force_map('DMSP-10-250'))
    angles = np.linspace(0.0, theta, 401)
    torque = 0.015 * (
        truth.force(500e3, 0.234 - 0.015 * angles) - truth.force(500e3, 0.234 + 0.015 * angles)
    )
    return -float(np.sum((torque[1:] + torque[:-1]) / 2 * np.diff(angles)))


@pytest.mark.parametrize('damping', [0.0, 0.02])
def test_a_released_link_keeps_or_loses_its_energy_to_the_damper(make_node, damping):
    """Released from rest at 0.3 rad, both muscles at 500 kPa, inertia 0.01 kg m², stepped every
    1 ms up to its first stop at the other side (about 0.15 s: K ≈ 4 N·m/rad).
    """
    inertia, theta0, dt = 0.01, 0.3, 1e-3
    node = make_node(
        mode='link', angle=theta0, inertia=inertia, damping=damping, pressure_time_constant=0.0
    )
    states = record(node._state_pub)
    command(node, 0, AMBIENT + 500e3)
    command(node, 1, AMBIENT + 500e3)
    i = 0
    while not (states and states[-1].velocity[0] >= 0 and len(states) > 1):
        i += 1
        tick(node, i * dt)
        assert i < 400, 'no turn within 0.4 s'
    turn = min(range(len(states)), key=lambda n: states[n].position[0])
    theta1, t1 = states[turn].position[0], (turn + 1) * dt
    assert states[0].effort[0] < 0  # the stretched extensor pulls back toward 0
    if damping == 0.0:
        # the torque is odd in θ (equal muscles, lengths swap): no loss, it turns at -θ0
        assert theta1 == pytest.approx(-theta0, abs=1e-3)
    else:
        # work-energy: V(θ0) - V(θ1) is what the damper took, ∫ c θ'² dt
        dissipated = sum(damping * s.velocity[0] ** 2 * dt for s in states[: turn + 1])
        assert potential(theta0) - potential(theta1) == pytest.approx(dissipated, rel=0.01)
        # a lightly damped oscillator's half swing: |θ1| = θ0 exp(-c t1 / (2 I)),
        # 0.3 exp(-0.02·0.154/0.02) = 0.3·0.857 = 0.257 rad
        assert -theta1 == pytest.approx(theta0 * math.exp(-damping * t1 / (2 * inertia)), rel=0.01)
        assert -theta1 < theta0 - 0.03  # lost a visible share: not the undamped swing


def test_topics_rate_and_commands_per_muscle(make_node):
    node = make_node(muscles=['biceps', 'triceps'], joint_name='arm', rate=250.0)
    published = {p.topic_name for p in node.publishers}
    assert {'/joint_states', '/biceps/pressure', '/triceps/pressure'} <= published
    subscribed = {s.topic_name for s in node.subscriptions}
    assert {
        '/biceps/pressure_command',
        '/triceps/pressure_command',
        '/angle_command',
    } <= subscribed
    assert [t.timer_period_ns for t in node.timers] == [4_000_000]  # 1 / 250 Hz = 4 ms
    biceps, triceps = (record(p) for p in node._pressure_pubs)
    states = record(node._state_pub)
    command(node, 1, AMBIENT + 300e3)  # the triceps' command
    command(node, 1, math.nan)  # ignored
    tick(node, 5.0)  # 100 time constants of 0.05 s
    assert biceps[-1].fluid_pressure == pytest.approx(AMBIENT, rel=1e-12)
    assert triceps[-1].fluid_pressure == pytest.approx(AMBIENT + 300e3, rel=1e-12)
    assert list(states[-1].name) == ['arm']


@pytest.mark.parametrize(
    'params, message',
    [
        ({'rate': 5000.0}, "parameter 'rate' must be in [1, 1000] Hz, got 5000.0"),
        ({'rate': 200}, "parameter 'rate' to '200' of type 'INTEGER', expecting type 'DOUBLE'"),
        ({'pressure_time_constant': -1.0}, "'pressure_time_constant' must be in [0, 60] s"),
        ({'mode': 'free'}, "parameter 'mode' must be one of ('held', 'link'), got 'free'"),
        ({'maps': ['DMSP-10-250', 'MAS-20']}, "no shipped force map for 'MAS-20'"),
        ({'muscles': ['flexor']}, "parameter 'muscles' needs two entries, got ['flexor']"),
        ({'limits': [1.0, -1.0]}, "'limits' must be finite [min, max] rad with min < max"),
        ({'angle': 1.5}, "parameter 'angle' 1.5 rad is outside 'limits' [-1, 1]"),
        # r(θ) = 0.01 + 0.02 θ is -0.01 m at -1 rad
        ({'radius': [0.01, 0.02]}, "'radius': lever arm r = -0.01 m at θ = -1 rad"),
    ],
)
def test_bad_parameters_are_a_startup_error_naming_them(make_node, params, message):
    with pytest.raises(StartupError) as err:
        make_node(**params)
    assert message in str(err.value)


def test_process_with_a_bad_mode_exits_1_with_one_line():
    lines = lines_of_failed_start(
        [sys.executable, '-m', 'pma_model_ros.nodes.joint_simulator_node']
        + ['--ros-args', '-p', 'mode:=free']
    )
    assert len(lines) == 1 and "parameter 'mode' must be one of" in lines[0], lines
