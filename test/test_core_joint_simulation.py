"""The simulated joint against its measured maps: torque at measured points, pressure lag, the
link's rest.
"""

import math

import pytest

from pma_model_ros.core.joint_simulation import PARAMETERS, SimulatedJoint
from pma_model_ros.core.shipped_data import shipped_force_map

AMBIENT = 101325.0


def params(**overrides):
    return {name: default for name, (default, _, _) in PARAMETERS.items()} | overrides


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
