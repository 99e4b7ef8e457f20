"""The simulated joint against its measured maps: torque at measured points, pressure lag, the
link's rest.
"""

import math
import re

import pytest

from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.simulation.joint import PARAMETERS, SimulatedJoint

AMBIENT = 101325.0


def params(**overrides):
    return {p.name: p.default for p in PARAMETERS} | overrides


def measured(pressure, length):
    """The map's own row (Table A2) at a measured pressure [Pa] and length [m]."""
    fmap = shipped_force_map('DMSP-10-250')
    (i,) = [
        i
        for i in range(fmap.force.size)
        if fmap.pressure[i] == pressure and fmap.length[i] == length
    ]
    return float(fmap.force[i])


def test_held_torque_at_measured_points_is_the_map():
    joint = SimulatedJoint(params(length_at_zero=[0.234, 0.219], pressure_time_constant=0.0), 0.0)
    joint.command(0, AMBIENT + 360000)
    joint.command(1, AMBIENT + 402187)
    torque = joint.step(0.01)
    assert torque == pytest.approx(0.015 * (71.3333 - measured(402187, 0.219)), rel=1e-9)
    assert measured(360000, 0.234) == 71.3333


def test_held_angle_moves_only_when_told_and_stays_in_the_limits():
    joint = SimulatedJoint(params(angle=0.2), 0.0)
    joint.step(1.0)
    assert joint.angle == 0.2 and joint.velocity == 0.0
    joint.hold(0.4)
    assert joint.angle == 0.4
    joint.hold(3.0)
    assert joint.angle == 1.0
    joint.hold(math.nan)
    assert joint.angle == 1.0


def test_pressure_follows_the_command_with_a_first_order_lag():
    joint = SimulatedJoint(params(pressure_time_constant=0.05), 0.0)
    joint.command(0, AMBIENT + 400e3)
    joint.command(1, math.inf)  # ignored
    joint.step(0.05)
    assert joint.pressures[0] == pytest.approx(400e3 * (1 - math.exp(-1)), rel=1e-12)
    assert joint.pressures[1] == 0.0


def test_link_comes_to_rest_where_the_map_torques_balance():
    """Two equal muscles at equal lengths at θ = 0, equal pressures: the damped link settles at 0
    rad.
    """
    joint = SimulatedJoint(
        params(mode='link', angle=0.5, inertia=0.002, damping=0.05, pressure_time_constant=0.0),
        0.0,
    )
    joint.command(0, AMBIENT + 500e3)
    joint.command(1, AMBIENT + 500e3)
    assert joint.step(1e-3) < 0  # stretched extensor pulls back toward 0
    for i in range(1, 600):
        joint.step(i * 2e-3)
    assert joint.angle == pytest.approx(0.0, abs=1e-3) and abs(joint.velocity) < 1e-2


def test_bad_parameters():
    with pytest.raises(ValueError, match='mode'):
        SimulatedJoint(params(mode='free'), 0.0)
    with pytest.raises(ValueError, match='no shipped force map'):
        SimulatedJoint(params(maps=['DMSP-10-250', 'MAS-20']), 0.0)


def test_a_muscle_leaving_its_map_over_the_limits_is_refused():
    """0.245 m + 0.015 m/rad · 1 rad = 0.260 m at θ = -1 rad, beyond Table A2's longest 0.250 m."""
    with pytest.raises(ValueError, match=r"'flexor' is 0\.26 m at θ = -1 rad.*\[0\.198, 0\.25\]"):
        SimulatedJoint(params(length_at_zero=[0.245, 0.234]), 0.0)


def test_a_link_too_light_for_its_rate_is_refused_and_the_lightest_accepted_is_stable():
    """At the bound ω dt = 1 the undamped link, released from 0.5 rad, does not grow: semi-implicit
    Euler conserves a nearby energy, whose swing is at most 0.5 / sqrt(1 - (ω dt / 2)^2) rad.
    """
    released = {'mode': 'link', 'angle': 0.5, 'damping': 0.0, 'pressure_time_constant': 0.0}
    with pytest.raises(ValueError, match=r"'inertia' 1e-05 kg m\^2 is too small") as refused:
        SimulatedJoint(params(inertia=1e-5, **released), 0.0)
    least = float(re.search(r'at least ([0-9.e-]+)', str(refused.value))[1])
    joint = SimulatedJoint(params(inertia=least * 1.01, **released), 0.0)
    for k in (0, 1):
        joint.command(k, AMBIENT + 650e3)  # the stiffest: both at the map's top
    angles = [joint.step(i / 200) and joint.angle for i in range(1, 2001)]
    swing = [max(abs(a) for a in angles[i : i + 500]) for i in range(0, 2000, 500)]
    assert max(swing) <= 0.5 / math.sqrt(0.75) and swing[-1] <= 1.01 * swing[0], swing


def test_heavy_damping_is_stable_and_does_not_overshoot():
    """With c dt / I = 1000 · 0.005 / 0.01 = 500 (an explicit damping term is unstable beyond 2),
    the implicit one creeps toward 0 rad from 0.5 rad without crossing it.
    """
    joint = SimulatedJoint(
        params(mode='link', angle=0.5, inertia=0.01, damping=1e3, pressure_time_constant=0.0),
        0.0,
    )
    for k in (0, 1):
        joint.command(k, AMBIENT + 500e3)
    angles = [joint.step(i / 200) and joint.angle for i in range(1, 401)]
    assert all(0.0 < b <= a <= 0.5 for a, b in zip([0.5, *angles], angles))
