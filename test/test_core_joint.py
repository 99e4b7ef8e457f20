"""Antagonistic joint: torque and stiffness by hand from single-muscle forces, the inverse's round
trips (hypothesis, every model of every shipped file), saturation, and the float path against the
vector path.
"""

import dataclasses
import math

from hypothesis import assume, given, HealthCheck
from hypothesis import strategies as st
import numpy as np
import pytest

from budget import examples
from conftest import CONFIGS, force_rounding, REPO
from pma_model_ros.core.files.joint_file import load_joints
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.joint import envelope, Joint, Transmission

EXAMPLE = load_joints(REPO / 'config' / 'example_joint.yaml')[0]
#: The highest pressure the example's muscles are commanded: the rated 800 kPa (hildebrandt is
#: served extrapolated beyond its map's 650 kPa).
TOP = EXAMPLE.muscles[0].limits.command_top
#: docs/joints.md's worked example: the example joint at 0.5 rad, flexor 400 kPa, extensor 300 kPa
#: (gauge).
THETA, P_FLEXOR, P_EXTENSOR = 0.5, 400e3, 300e3


def paired(muscle) -> Joint:
    """Two copies of ``muscle`` on a pulley whose ±1 rad spans 80 % of its identified length
    range.
    """
    low, high = muscle.domain.length_min, min(muscle.domain.length_max, muscle.spec.nominal_length)
    return Joint(
        'test',
        (muscle, muscle),
        ('a', 'b'),
        ((low + high) / 2,) * 2,
        Transmission((0.4 * (high - low),)),
        (-1.0, 1.0),
    )


MUSCLES = [
    muscle_model(read_parameters(path), name)
    for path in CONFIGS.values()
    for name in read_parameters(path)['models']
]
JOINTS = [paired(m) for m in MUSCLES]
IDS = [f'{m.spec.name}-{m.model.name}' for m in MUSCLES]


def test_worked_example_by_hand():
    flexor = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'hildebrandt')

    def torque(theta):  # r = 15 mm; the flexor is 0.234 m at 0, shortening by r theta
        f = float(flexor.force(P_FLEXOR, 0.234 - 0.015 * theta).force)
        e = float(flexor.force(P_EXTENSOR, 0.234 + 0.015 * theta).force)
        return 0.015 * (f - e)

    h = 1e-4
    stiffness = -(torque(THETA + h) - torque(THETA - h)) / (2 * h)
    result = EXAMPLE.forward(THETA, P_FLEXOR, P_EXTENSOR)
    assert float(result.torque) == pytest.approx(torque(THETA), rel=1e-12)
    assert float(result.stiffness) == pytest.approx(stiffness, rel=1e-6)
    assert (round(torque(THETA), 3), round(stiffness, 2)) == (-0.692, 3.84)  # docs/joints.md
    assert not result.flags.any()


def test_lengths_follow_the_pulley_and_rep103():
    flexor, extensor = EXAMPLE.lengths(np.array([-1.0, 0.0, 1.0]))
    assert flexor == pytest.approx([0.249, 0.234, 0.219], abs=1e-15)  # shortens for positive θ
    assert extensor == pytest.approx([0.219, 0.234, 0.249], abs=1e-15)
    assert float(EXAMPLE.forward(0.0, 500e3, 0.0).torque) > 0  # the flexor alone turns positive


def test_lever_arm_polynomial_travel_is_its_integral():
    arm = Transmission((0.02, 0.004, -0.003))
    theta = 0.7
    assert arm.travel(theta) == pytest.approx(
        0.02 * 0.7 + 0.002 * 0.7**2 - 0.001 * 0.7**3, rel=1e-14
    )
    assert arm.radius_slope(theta) == pytest.approx(0.004 - 0.006 * 0.7, rel=1e-14)


@pytest.mark.parametrize('joint', JOINTS, ids=IDS)
def test_stiffness_is_minus_the_torque_slope(joint):
    """Analytic K against a central difference of the torque, where both muscles pull inside the
    box.
    """
    theta = np.linspace(-0.8, 0.8, 9)
    p0, p1, h, branches = 500e3, 450e3, 1e-5, (-1.0, 1.0)  # θ rising: 0 shortens, 1 lengthens
    k = joint.forward(theta, p0, p1, branches).stiffness
    fd = -(
        joint.forward(theta + h, p0, p1, branches).torque
        - joint.forward(theta - h, p0, p1, branches).torque
    ) / (2 * h)
    # each torque off by at most its rounding (conftest.force_rounding: eq. 20's terms reach
    # 10⁷ N on DMSP-20-300 and cancel), the difference by that over h
    r, lengths = joint.transmission.radius(theta), joint.lengths(theta)
    rounding = np.abs(r) * [
        sum(force_rounding(m, p, at[i]) for m, p, at in zip(joint.muscles, (p0, p1), lengths))
        for i in range(theta.size)
    ]
    bound = 1e-5 * np.abs(fd) + 1e-6 * np.abs(fd).max() + rounding / h
    assert np.all(np.abs(k - fd) <= bound), (k, fd, bound)


def test_stiffness_of_a_variable_lever_arm_has_the_r_prime_term():
    joint = dataclasses.replace(EXAMPLE, transmission=Transmission((0.015, 0.002)))
    h = 1e-5
    fd = -(
        joint.forward(0.3 + h, 600e3, 200e3).torque - joint.forward(0.3 - h, 600e3, 200e3).torque
    ) / (2 * h)
    assert float(joint.forward(0.3, 600e3, 200e3).stiffness) == pytest.approx(float(fd), rel=1e-6)


def test_float_path_equals_vector_path():
    m0, m1, r, r_slope = EXAMPLE.at(0.3)
    for p0, p1 in ((0.0, 0.0), (200e3, 650e3), (800e3, 100e3), (-5e3, 9e5)):
        vector = EXAMPLE.forward(0.3, p0, p1)
        assert EXAMPLE.torque_stiffness(m0, m1, r, r_slope, p0, p1) == pytest.approx(
            (float(vector.torque), float(vector.stiffness)), rel=1e-9, abs=1e-12
        )


@pytest.mark.parametrize('branches', [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (0.0, -1.0)])
def test_each_muscle_is_on_the_branch_given(branches):
    """Two DMSP-10-100 (sarosi_hysteresis) on a 10 mm pulley at 0.2 rad (0.0855 and 0.0895 m): the
    forces are the single muscle's on each branch (0: unknown, flagged BRANCH_UNKNOWN), the torque
    r (F0 - F1), both paths alike.
    """
    sarosi = muscle_model(read_parameters(CONFIGS['DMSP-10-100']), 'sarosi_hysteresis')
    finger = Joint(
        'finger', (sarosi,) * 2, ('a', 'b'), (0.0875,) * 2, Transmission((0.01,)), (-1, 1)
    )
    rates = [b or None for b in branches]  # the single muscle's length rate: None is unknown
    forces = [
        float(sarosi.force(p, length, rate).force)
        for p, length, rate in zip((600e3, 500e3), (0.0855, 0.0895), rates)
    ]
    vector = finger.forward(0.2, 600e3, 500e3, branches)
    assert vector.forces.tolist() == pytest.approx(forces, rel=1e-12)
    assert float(vector.torque) == pytest.approx(0.01 * (forces[0] - forces[1]), rel=1e-12)
    unknown = [bool(f & Flag.BRANCH_UNKNOWN) for f in vector.flags.tolist()]
    assert unknown == [b == 0 for b in branches]
    m0, m1, r, r_slope = finger.at(0.2, branches)
    assert [bool(m.flags & Flag.BRANCH_UNKNOWN) for m in (m0, m1)] == unknown
    assert finger.torque_stiffness(m0, m1, r, r_slope, 600e3, 500e3) == pytest.approx(
        (float(vector.torque), float(vector.stiffness)), rel=1e-12
    )


def _scale(joint, theta):
    m0, m1, r, _ = joint.at(theta)
    return r * (m0.force(m0.p_max) + m1.force(m1.p_max))


def _top(joint) -> float:
    """The highest pressure commanded to either muscle [Pa]
    (:class:`~pma_model_ros.core.physics.muscle_model.Limits`).
    """
    return min(m.limits.command_top for m in joint.muscles)


def _check_round_trip(joint, theta, wanted, solution):
    got = joint.forward(theta, *solution.pressures)
    assert not solution.flags & Flag.SATURATED, solution
    assert abs(float(got.torque) - wanted) <= 1e-9 * _scale(joint, theta)
    for p, muscle in zip(solution.pressures, joint.muscles):
        assert 0.0 <= p <= muscle.limits.command_top


@pytest.mark.parametrize('joint', JOINTS, ids=IDS)
@examples(60)
@given(theta=st.floats(-1.0, 1.0), share=st.floats(0.0, 1.0), level=st.floats(0.0, 1.0))
def test_round_trip_lower_pressure(joint, theta, share, level):
    p_max = _top(joint)
    level *= p_max
    low = float(joint.forward(theta, level, p_max).torque)  # reachable, lower pressure at level
    high = float(joint.forward(theta, p_max, level).torque)
    wanted = low + share * (high - low)
    solution = joint.pressures_one(theta, wanted, level, 'min')
    _check_round_trip(joint, theta, wanted, solution)
    assert min(solution.pressures) == pytest.approx(level, abs=1e-9 * p_max) or wanted in (
        low,
        high,
    )


@pytest.mark.parametrize('joint', JOINTS, ids=IDS)
@examples(60)
@given(theta=st.floats(-1.0, 1.0), share=st.floats(0.0, 1.0), total=st.floats(0.0, 2.0))
def test_round_trip_pressure_sum(joint, theta, share, total):
    p_max = _top(joint)
    total *= p_max
    low = float(joint.forward(theta, max(0.0, total - p_max), min(total, p_max)).torque)
    high = float(joint.forward(theta, min(total, p_max), max(0.0, total - p_max)).torque)
    wanted = low + share * (high - low)
    solution = joint.pressures_one(theta, wanted, total, 'sum')
    _check_round_trip(joint, theta, wanted, solution)
    assert sum(solution.pressures) == pytest.approx(total, rel=1e-12, abs=1e-6)


@pytest.mark.parametrize('joint', JOINTS, ids=IDS)
@examples(40, suppress_health_check=[HealthCheck.filter_too_much])
@given(theta=st.floats(-1.0, 1.0), u0=st.floats(0.3, 1.0), u1=st.floats(0.3, 1.0))
def test_round_trip_stiffness(joint, theta, u0, u1):
    """A pair where both muscles pull gives (τ, K); asking for them gets a pair with that τ and
    K.
    """
    p_max = _top(joint)
    given_pair = joint.forward(theta, u0 * p_max, u1 * p_max)
    assume((given_pair.forces > 0).all())
    wanted, stiffness = float(given_pair.torque), float(given_pair.stiffness)
    solution = joint.pressures_one(theta, wanted, stiffness=stiffness)
    _check_round_trip(joint, theta, wanted, solution)
    assert float(joint.forward(theta, *solution.pressures).stiffness) == pytest.approx(
        stiffness, rel=1e-9
    )


def test_out_of_reach_torque_is_saturated_at_the_bound():
    theta, level = 0.5, 200e3
    top = float(EXAMPLE.forward(theta, TOP, level).torque)
    bottom = float(EXAMPLE.forward(theta, level, TOP).torque)
    for wanted, bound, pair in (
        (top + 1.0, top, (TOP, level)),
        (bottom - 1.0, bottom, (level, TOP)),
    ):
        solution = EXAMPLE.pressures_one(theta, wanted, level)
        assert solution.flags & Flag.SATURATED
        assert solution.pressures == pytest.approx(pair, abs=1e-6)
        assert solution.torque == pytest.approx(bound, rel=1e-12)
        assert solution.torque_range == pytest.approx((bottom, top), rel=1e-12)


def test_out_of_reach_stiffness_keeps_the_torque():
    top = float(EXAMPLE.forward(0.0, TOP, TOP).stiffness)  # both at max: the stiffest at 0 N·m
    solution = EXAMPLE.pressures_one(0.0, 0.0, stiffness=top + 10.0)
    assert solution.flags & Flag.SATURATED
    assert abs(solution.torque) <= 1e-9 * _scale(EXAMPLE, 0.0)
    assert solution.stiffness == pytest.approx(top, rel=1e-6)


def test_out_of_reach_torque_in_stiffness_mode_gives_the_torque_bound():
    low, high = EXAMPLE.torque_range(0.2)
    solution = EXAMPLE.pressures_one(0.2, high + 3.0, stiffness=4.0)
    assert solution.flags & Flag.SATURATED and solution.torque == pytest.approx(high, rel=1e-12)
    assert solution.pressures == (TOP, 0.0)


def test_envelope_bounds_every_pressure_pair():
    angles = np.linspace(-1, 1, 5)
    env = envelope(EXAMPLE, angles, [0.0, 400e3])
    grid = np.linspace(0, TOP, 41)
    for i, theta in enumerate(angles):
        torques = EXAMPLE.forward(theta, grid[:, None], grid[None, :]).torque
        assert torques.max() == pytest.approx(env['torque_max'][i], rel=1e-12)
        assert torques.min() == pytest.approx(env['torque_min'][i], rel=1e-12)
        assert env['level_max'][0, i] == pytest.approx(env['torque_max'][i], rel=1e-12)
        assert (
            env['level_min'][1, i] >= env['torque_min'][i]
            and env['level_max'][1, i] <= env['torque_max'][i]
        )


def test_geometry_check_names_the_angle():
    spec = EXAMPLE.muscles[1].spec
    limit = spec.nominal_length / math.cos(spec.fiber_angle)  # eq. 3: the longest length, 0.2847 m
    with pytest.raises(ValueError, match="muscle 'extensor' would be .* at θ = ") as err:
        dataclasses.replace(EXAMPLE, transmission=Transmission((0.1,)), limits=(0.0, 1.0))
    angle = float(str(err.value).split('θ = ')[1].split(' rad')[0])
    assert angle == pytest.approx((limit - 0.234) / 0.1, abs=0.003)


def test_lever_arm_must_stay_positive():
    with pytest.raises(ValueError, match='lever arm r = .* at θ = -1 rad'):
        dataclasses.replace(EXAMPLE, transmission=Transmission((0.01, 0.02)))


def test_out_of_reach_cocontraction_is_saturated_at_the_nearest_level():
    solution = EXAMPLE.pressures_one(0.0, 0.0, 900e3)  # above the rated 800 kPa
    assert solution.flags & Flag.SATURATED and solution.pressures == (TOP, TOP)
    solution = EXAMPLE.pressures_one(0.0, 0.0, 2e6, 'sum')  # above 800 + 800 kPa
    assert solution.flags & Flag.SATURATED and solution.pressures == (TOP, TOP)


def test_pressures_broadcast_over_samples():
    # 0.5 N·m: inside the reachable range at each angle and level (at 0.5 rad and 400 kPa: up to
    # 0.519 N·m)
    solutions = EXAMPLE.pressures(np.array([-0.5, 0.0, 0.5]), 0.5, np.array([[300e3], [400e3]]))
    assert len(solutions) == 6
    for solution, (theta, level) in zip(
        solutions, [(t, c) for c in (300e3, 400e3) for t in (-0.5, 0.0, 0.5)]
    ):
        assert min(solution.pressures) == level
        assert float(EXAMPLE.forward(theta, *solution.pressures).torque) == pytest.approx(
            0.5, rel=1e-9
        )
    (stiff,) = EXAMPLE.pressures(0.0, 0.0, stiffness=4.5)
    assert stiff.stiffness == pytest.approx(4.5, rel=1e-9)
