"""JointEngine (joint_node's decisions, no ROS): estimates of several joints against
τ = r (F0 - F1) of the single muscles at lengths computed by hand, hysteresis branches with memory
(the play operator on each muscle's length or pressure), flags and how long they hold, freshness,
the command path's round trips, and inputs it must reject.

The forces come from each muscle's own parameter file (``MuscleModel.force``, the vector path), not
from the joint file or :class:`~pma_model_ros.core.physics.joint.MuscleAt`; stiffnesses are central
differences of those hand torques.
"""

import dataclasses
import math

import numpy as np
import pytest

from conftest import central_difference, CONFIGS, force_rounding, REPO
from pma_model_ros.core.files.joint_file import joints, load_joints
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.hysteresis import Follow
from pma_model_ros.core.physics.joint import Joint, Transmission
from pma_model_ros.core.runtime.engine import Config, Engine, Level
from pma_model_ros.core.runtime.joint_engine import JointEngine, Settings

AMBIENT = 101325.0  # [Pa]
AGE = 0.125  # [s] max_input_age (a binary fraction: the freshness edge is exact)
#: DMSP-10-250 identified over 0.198..0.25 m and 0..650 kPa (Table A2); martens extrapolates (up
#: to the rated 800 kPa), and so does hildebrandt as the file serves it; HELD is hildebrandt held
#: at the identified box (a file's ``extrapolates: false``).
HILDEBRANDT = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'hildebrandt')
HELD = dataclasses.replace(
    HILDEBRANDT, domain=dataclasses.replace(HILDEBRANDT.domain, extrapolates=False)
)
MARTENS = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'martens')
#: DMSP-20-300, identified over 0.222..0.296 m.
BIG = muscle_model(read_parameters(CONFIGS['DMSP-20-300']), 'hildebrandt')
#: DMSP-10-100 with Sárosi's two hysteresis branches, identified over 0.075..0.1 m.
SAROSI = muscle_model(read_parameters(CONFIGS['DMSP-10-100']), 'sarosi_hysteresis')

#: The example file: a 15 mm pulley, both DMSP-10-250 (hildebrandt) 0.234 m long at 0 rad.
ELBOW = load_joints(REPO / 'config' / 'example_joint.yaml')[0]
#: r(θ) = 12 mm + 3 mm·θ, so s(θ) = 0.012 θ + 0.0015 θ²; lengths 0.226 and 0.228 m at 0 rad.
WRIST = Joint(
    'wrist',
    (HILDEBRANDT, HILDEBRANDT),
    ('wrist_flexor', 'wrist_extensor'),
    (0.226, 0.228),
    Transmission((0.012, 0.003)),
    (-1.0, 1.0),
)
#: Two DMSP-10-100 (sarosi_hysteresis) on a 10 mm pulley, 0.0875 m long at 0 rad; both branches
#: follow the muscle's length with the default 0.5 mm deadband.
FINGER = Joint(
    'finger', (SAROSI, SAROSI), ('a', 'b'), (0.0875, 0.0875), Transmission((0.01,)), (-1, 1)
)
#: Two DMSP-20-300 on a 20 mm pulley, 0.26 m long at 0 rad.
KNEE = Joint(
    'knee', (BIG, BIG), ('quad', 'hamstring'), (0.26, 0.26), Transmission((0.02,)), (-1, 1)
)


def force(muscle, p, length, rate=None):
    """Tension [N] of ``muscle`` at gauge ``p`` [Pa] and ``length`` [m] (its own vector path)."""
    return float(muscle.force(p, length, rate).force)


def elbow_torque(theta, p0, p1):
    # r = 0.015 m, s = 0.015 θ: flexor 0.234 - 0.015 θ, extensor 0.234 + 0.015 θ
    return 0.015 * (
        force(HILDEBRANDT, p0, 0.234 - 0.015 * theta)
        - force(HILDEBRANDT, p1, 0.234 + 0.015 * theta)
    )


def wrist_torque(theta, p0, p1):
    r, s = 0.012 + 0.003 * theta, 0.012 * theta + 0.0015 * theta**2
    return r * (force(HILDEBRANDT, p0, 0.226 - s) - force(HILDEBRANDT, p1, 0.228 + s))


def knee_torque(theta, p0, p1):
    return 0.02 * (force(BIG, p0, 0.26 - 0.02 * theta) - force(BIG, p1, 0.26 + 0.02 * theta))


def torque_rounding(joint, theta, p0, p1):
    """A bound [N·m] on the rounding error of a hand torque r (F0 - F1) of ``joint`` at ``theta``
    [rad] and gauge ``p0``, ``p1`` [Pa] (conftest.force_rounding); both forces are off by about
    as much within the 2 mm of a central difference's steps.
    """
    (l0, l1), r = joint.lengths(theta), joint.transmission.radius(theta)
    m0, m1 = joint.muscles
    return abs(r) * (force_rounding(m0, p0, l0) + force_rounding(m1, p1, l1))


def hand_torque(torque, joint, theta, p0, p1):
    """A hand torque [N·m] as ``pytest.approx``, within the rounding of it and of the engine's
    float path (each off by at most :func:`torque_rounding`).
    """
    return pytest.approx(torque(theta, p0, p1), abs=2 * torque_rounding(joint, theta, p0, p1))


def stiffness_of(torque, joint, theta, p0, p1):
    """K = -dτ/dθ [N·m/rad] of a hand torque of ``joint`` by a central difference, and a bound on
    its error (conftest.central_difference).
    """
    slope, error = central_difference(
        lambda t: torque(t, p0, p1), theta, torque_rounding(joint, theta, p0, p1)
    )
    return -slope, error


def hand_stiffness(torque, joint, theta, p0, p1):
    """:func:`stiffness_of` as ``pytest.approx`` within its error bound (the engine's analytic K
    rounds far below it: its terms are the force's over a length, times r²).
    """
    stiffness, error = stiffness_of(torque, joint, theta, p0, p1)
    return pytest.approx(stiffness, abs=error)


def ns(seconds: float) -> int:
    """A time [s] in the engine's integer nanoseconds."""
    return round(seconds * 1e9)


class InSeconds:
    """A JointEngine whose times the tests write in seconds (it takes integer ns); ``status`` is
    one joint's (level, message, values) of a report at ``now``.
    """

    def __init__(self, engine: JointEngine) -> None:
        self.engine, self.index, self.state = engine, engine.index, engine.state

    def angle(self, k, theta, stamp, now):
        return self.engine.angle(k, theta, ns(stamp), ns(now))

    def pressure(self, k, muscle, absolute, stamp, now):
        return self.engine.pressure(k, muscle, absolute, ns(stamp), ns(now))

    def command(self, k, torque, now):
        return self.engine.command(k, torque, ns(now))

    def stiffness(self, k, value, now):
        return self.engine.stiffness(k, value, ns(now))

    def cocontraction(self, k, value, now):
        return self.engine.cocontraction(k, value, ns(now))

    def status(self, k, now):
        status = self.engine.statuses(ns(now))[k]
        return status.level, status.message, status.values


def engine(*joints, settings=None, hold=1.0):
    joints = joints or (ELBOW,)
    settings = settings or [Settings(300e3, 'min')] * len(joints)
    return InSeconds(JointEngine(joints, settings, AMBIENT, AGE, hold))


def feed(e, k, p0, p1, t=0.0):
    """Both muscles of joint ``k``: gauge ``p0``, ``p1`` [Pa], stamped and received at ``t``."""
    e.pressure(k, 0, AMBIENT + p0, t, t)
    e.pressure(k, 1, AMBIENT + p1, t, t)


def test_three_joints_estimate_r_times_the_force_difference():
    e = engine(
        ELBOW,
        WRIST,
        KNEE,
        settings=[Settings(300e3, 'min'), Settings(600e3, 'sum'), Settings(0.0, 'min')],
    )
    assert e.index == {'elbow': 0, 'wrist': 1, 'knee': 2}
    cases = [  # joint, θ [rad], gauge pressures [Pa], the hand torque
        # docs/joints.md's worked example: r = 0.015 m, flexor 0.2265 m, extensor 0.2415 m
        (0, 0.5, (400e3, 300e3), elbow_torque),
        # r = 0.012 + 0.003·0.4 = 0.0132 m; s = 0.0048 + 0.0015·0.16 = 0.00504 m:
        # flexor 0.226 - 0.00504 = 0.22096 m, extensor 0.228 + 0.00504 = 0.23304 m
        (1, 0.4, (500e3, 250e3), wrist_torque),
        # r = 0.02 m, s = -0.006 m: quad 0.266 m, hamstring 0.254 m
        (2, -0.3, (150e3, 450e3), knee_torque),
    ]
    for k, _, pair, _ in cases:
        feed(e, k, *pair, t=10.0)
    for (k, theta, pair, torque), joint in zip(cases, (ELBOW, WRIST, KNEE)):
        tau, stiffness = e.angle(k, theta, 10.01, 10.02)
        assert tau == hand_torque(torque, joint, theta, *pair)
        assert stiffness == hand_stiffness(torque, joint, theta, *pair)
        assert e.status(k, 10.02)[:2] == (Level.OK, 'estimating')
    # docs/joints.md's rounded numbers of the worked example
    assert (round(e.state[0].torque, 3), round(e.state[0].stiffness_estimate, 2)) == (-0.692, 3.84)
    # counts of joint 1 alone: its two pressures, one angle, one estimate
    values = e.status(1, 10.02)[2]
    assert (
        values['received pressure'],
        values['received joint_states'],
        values['estimates'],
    ) == ('2', '1', '1')
    assert (
        values['wrist_flexor pressure: Events since startup'],
        values['joint_states: Events since startup'],
    ) == ('1', '1')
    assert values['commands'] == 'co-contraction sum 600000 Pa'


def finger_torque(theta, p0, p1, b0, b1):
    """τ [N·m] of FINGER with muscle 0 on branch ``b0`` and muscle 1 on ``b1`` (+1 or -1), each
    force the model's own on that branch: r = 10 mm, lengths 0.0875 ∓ 0.01 θ m.
    """
    return 0.01 * (
        force(SAROSI, p0, 0.0875 - 0.01 * theta, b0) - force(SAROSI, p1, 0.0875 + 0.01 * theta, b1)
    )


def mean_force(p, length):
    """The mean of the two branches' forces [N] (both pull at the pressures used here)."""
    return (force(SAROSI, p, length, 1.0) + force(SAROSI, p, length, -1.0)) / 2


def test_before_any_motion_the_branches_are_unknown_and_served_as_their_mean():
    e = engine(FINGER)
    feed(e, 0, 600e3, 500e3)
    tau, _ = e.angle(0, 0.2, 0.0, 0.0)  # the first angle: lengths 0.0855 and 0.0895 m
    assert tau == pytest.approx(
        0.01 * (mean_force(600e3, 0.0855) - mean_force(500e3, 0.0895)), rel=1e-9
    )
    # what model_node's engine serves a single muscle before its first motion
    single = Engine([Config(SAROSI, AMBIENT, 10.0)] * 2)
    served = []
    for m, (p, length) in enumerate(((600e3, 0.0855), (500e3, 0.0895))):
        single.pressure(m, AMBIENT + p, 0, 0)
        assert single.length(m, length, math.nan, 0, 0)
        served.append(single.forces.item(0))
        assert single.flags.item(0) & Flag.BRANCH_UNKNOWN
    assert tau == pytest.approx(0.01 * (served[0] - served[1]), rel=1e-12)
    level, message, values = e.status(0, 0.0)
    assert (level, message) == (Level.WARN, 'hysteresis branch unknown (BRANCH_UNKNOWN)')
    assert values['last warning flags'] == 'BRANCH_UNKNOWN'
    # 0.04 rad: 0.4 mm, inside the 0.5 mm deadband: still no motion
    tau, _ = e.angle(0, 0.24, 0.0, 0.0)
    assert tau == pytest.approx(
        0.01 * (mean_force(600e3, 0.0851) - mean_force(500e3, 0.0899)), rel=1e-9
    )


def test_angle_noise_keeps_the_branches_of_the_last_motion():
    """θ from 0 to 0.2 rad shortens muscle 0 by 2 mm (branch -1) and lengthens muscle 1 (+1);
    then 500 angles within ±0.024 rad of 0.2 (±0.24 mm: 0.48 mm peak to peak, inside the 0.5 mm
    deadband) keep both.  joint_states velocities never reach the engine.
    """
    e = engine(FINGER)
    feed(e, 0, 600e3, 500e3)
    e.angle(0, 0.0, 0.0, 0.0)  # the first angle: branches unknown, warned at 0 s
    feed(e, 0, 600e3, 500e3, t=1.5)
    e.angle(0, 0.2, 1.5, 1.5)
    angles = 0.2 + np.random.default_rng(3).uniform(-0.024, 0.024, 500)
    torques = [e.angle(0, float(theta), 1.5, 1.5)[0] for theta in angles]
    assert torques == pytest.approx(
        [finger_torque(theta, 600e3, 500e3, -1.0, 1.0) for theta in angles], rel=1e-9
    )
    # what a flip would have cost: each force moves by 25..31 N, the torque by over 0.4 N·m
    theta = float(angles[-1])
    assert abs(finger_torque(theta, 600e3, 500e3, 1.0, -1.0) - torques[-1]) > 0.4

    def held(t, p0, p1):  # the branches of the last motion
        return finger_torque(t, p0, p1, -1.0, 1.0)

    assert e.state[0].stiffness_estimate == hand_stiffness(held, FINGER, theta, 600e3, 500e3)
    assert e.status(0, 1.5)[:2] == (
        Level.OK,
        'estimating',
    )  # no BRANCH_UNKNOWN since the 0 s warning


def test_a_reversal_beyond_the_deadband_sends_the_muscles_to_opposite_branches():
    e = engine(FINGER)
    feed(e, 0, 600e3, 500e3)
    e.angle(0, 0.0, 0.0, 0.0)
    e.angle(0, 0.2, 0.0, 0.0)  # muscle 0 shortening (-1), muscle 1 lengthening (+1)
    tau, _ = e.angle(0, 0.16, 0.0, 0.0)  # back 0.4 mm: inside the deadband
    assert tau == pytest.approx(finger_torque(0.16, 600e3, 500e3, -1.0, 1.0), rel=1e-9)
    tau, _ = e.angle(0, 0.14, 0.0, 0.0)  # back 0.6 mm from the run's extreme at 0.2 rad
    assert tau == pytest.approx(finger_torque(0.14, 600e3, 500e3, 1.0, -1.0), rel=1e-9)
    assert abs(tau - finger_torque(0.14, 600e3, 500e3, -1.0, 1.0)) > 0.4  # both flipped
    # a torque command is inverted on the same branches
    p0, p1 = (p - AMBIENT for p in e.command(0, 0.2, 0.0))
    assert p1 == pytest.approx(300e3, abs=1e-6)  # the co-contraction level
    assert finger_torque(0.14, p0, p1, 1.0, -1.0) == pytest.approx(0.2, abs=1e-8)


def finger_following_pressure() -> Joint:
    """Two DMSP-10-100 on a 10 mm pulley; muscle b's branch follows its gauge pressure (5 kPa
    deadband, inline beside its file), muscle a's its length.
    """
    block = {
        'radius': [0.01],
        'limits': [-1.0, 1.0],
        'muscles': ['a', 'b'],
        'positive': 'a',
        'a': {'file': 'dmsp_10_100.yaml', 'length_at_zero': 0.0875},
        'b': {
            'file': 'dmsp_10_100.yaml',
            'length_at_zero': 0.0875,
            'hysteresis': {'input': 'pressure', 'pressure_deadband': 5000.0},
        },
    }
    (joint,) = joints({'joints': ['finger'], 'finger': block}, REPO / 'config')
    return joint


def test_a_branch_can_follow_its_muscles_pressure():
    """Muscle a, the joint held still, stays unknown."""
    joint = finger_following_pressure()
    assert joint.follows == (Follow('length', 0.0005), Follow('pressure', 5000.0))
    e = engine(joint)
    steps = [  # b's gauge pressure [Pa] and its branch after it
        (400e3, None),  # the first reading
        (500e3, 1.0),  # filled by 100 kPa
        (497e3, 1.0),  # 3 kPa back: inside the deadband
        (490e3, -1.0),  # 10 kPa back from the 500 kPa peak: venting
        (494e3, -1.0),
    ]
    for p1, branch in steps:
        feed(e, 0, 600e3, p1)
        tau, _ = e.angle(0, 0.0, 0.0, 0.0)
        expected = 0.01 * (
            mean_force(600e3, 0.0875)
            - (mean_force(p1, 0.0875) if branch is None else force(SAROSI, p1, 0.0875, branch))
        )
        assert tau == pytest.approx(expected, rel=1e-9), p1
        # muscle a has not moved: the joint keeps warning
        assert e.status(0, 0.0)[:2] == (Level.WARN, 'hysteresis branch unknown (BRANCH_UNKNOWN)')


def test_a_torque_command_after_a_pressure_turned_a_branch_uses_the_new_branch():
    """The branch changes on a pressure message, with no joint_states after it: the command's
    pressures give the wanted torque with muscle b on the venting branch (-1), a on the mean.
    """
    e = engine(finger_following_pressure())
    for p1 in (400e3, 500e3):  # b filled: branch +1
        feed(e, 0, 600e3, p1)
    e.angle(0, 0.0, 0.0, 0.0)
    feed(e, 0, 600e3, 490e3)  # 10 kPa back: venting, -1
    # -0.3 N·m: a held at the 300 kPa level, b's pressure solved on its branch
    p0, p1 = (p - AMBIENT for p in e.command(0, -0.3, 0.0))
    assert p0 == pytest.approx(300e3) and force(SAROSI, p1, 0.0875, -1.0) > 0
    assert 0.01 * (mean_force(p0, 0.0875) - force(SAROSI, p1, 0.0875, -1.0)) == pytest.approx(
        -0.3, rel=1e-9
    )


def test_a_muscle_outside_its_identified_lengths_flags_the_joint_until_the_hold_ends():
    """A 30 mm pulley at 0.7 rad: s = 0.021 m, flexor 0.213 m, extensor 0.255 m > 0.25 m."""
    reach = Joint(
        'reach', (HILDEBRANDT,) * 2, ('a', 'b'), (0.234, 0.234), Transmission((0.03,)), (-1, 1)
    )
    e = engine(reach, hold=1.0)
    feed(e, 0, 500e3, 200e3)
    tau, stiffness = e.angle(0, 0.7, 0.0, 0.0)
    # hildebrandt does not extrapolate: the extensor's force is the one at 0.25 m ...
    assert tau == pytest.approx(
        0.03 * (force(HILDEBRANDT, 500e3, 0.213) - force(HILDEBRANDT, 200e3, 0.25)), rel=1e-9
    )
    # ... and does not change with θ there: K = r² dF0/dL alone
    h = 1e-6
    slope = (force(HILDEBRANDT, 500e3, 0.213 + h) - force(HILDEBRANDT, 500e3, 0.213 - h)) / (2 * h)
    assert stiffness == pytest.approx(0.03**2 * slope, rel=1e-6)
    assert e.status(0, 0.0)[:2] == (Level.WARN, 'outside validity domain (LENGTH_OUT_OF_RANGE)')

    def inside(t):  # fresh inputs at t, the joint at 0 rad: 0.234 m both, no flag
        feed(e, 0, 500e3, 200e3, t)
        assert e.angle(0, 0.0, t, t) is not None
        return e.status(0, t)

    assert inside(0.5)[0] == Level.WARN  # 0.5 s after the flag, within the 1 s hold
    assert inside(0.999)[0] == Level.WARN  # just within the 1 s hold
    assert inside(1.0)[:2] == (Level.OK, 'estimating')  # held for 1 s: model_node's rule
    assert inside(1.5)[2]['last warning flags'] == 'LENGTH_OUT_OF_RANGE'


@pytest.mark.parametrize(
    'muscle, gauge, served, flags',
    [
        # docs/nodes.md flags: within the 10 kPa vented band below 0 a muscle is vented, unflagged
        (HELD, -5e3, 0.0, set()),
        (HELD, 0.0, 0.0, set()),
        (HELD, 650e3, 650e3, set()),  # the map's top (Table A2)
        # beyond the band: a vacuum a muscle cannot hold
        (HELD, -20e3, 0.0, {'BELOW_AMBIENT', 'PRESSURE_OUT_OF_RANGE'}),
        (HELD, 700e3, 650e3, {'PRESSURE_OUT_OF_RANGE'}),  # served at the top
        # martens extrapolates up to the rated 800 kPa: its own value there, then held
        (MARTENS, 700e3, 700e3, {'EXTRAPOLATED'}),
        (MARTENS, 900e3, 800e3, {'EXTRAPOLATED', 'PRESSURE_OUT_OF_RANGE'}),
    ],
    ids=['vented', 'zero', 'map-top', 'vacuum', 'above-map', 'extrapolated', 'above-rated'],
)
def test_pressure_flags_follow_the_readme_rule(muscle, gauge, served, flags):
    """Muscle 1 at ``gauge`` [Pa]: the torque is that of the ``served`` pressure; the joint warns
    with docs/nodes.md's flag table's ``flags``, or is OK without any.
    """
    joint = Joint(
        'j', (muscle, muscle), ('a', 'b'), (0.234, 0.234), Transmission((0.015,)), (-1, 1)
    )
    e = engine(joint)
    feed(e, 0, 300e3, gauge)
    tau, _ = e.angle(0, 0.0, 0.0, 0.0)
    assert tau == pytest.approx(
        0.015 * (force(muscle, 300e3, 0.234) - force(muscle, served, 0.234)), rel=1e-9, abs=1e-12
    )
    level, message, values = e.status(0, 0.0)
    assert level == (Level.WARN if flags else Level.OK)
    assert set(values['last warning flags'].split('|')) == (flags or {'OK'})
    assert all(f'({flag})' in message for flag in flags)


def test_only_fresh_pressures_give_an_estimate():
    e = engine()
    assert e.angle(0, 0.0, 0.0, 0.0) is None  # no pressure yet
    assert e.status(0, 0.0)[:2] == (Level.ERROR, 'no flexor pressure received yet')
    e.pressure(0, 0, AMBIENT + 300e3, 0.0, 0.0)
    assert e.angle(0, 0.0, 0.0, 0.0) is None  # the extensor's still missing
    e.pressure(0, 1, AMBIENT + 300e3, 0.125, 0.125)  # stamped 0.125 s after the flexor's
    assert e.angle(0, 0.0, 0.125, 0.125) is not None  # 0.125 s old: max_input_age, fresh
    assert e.angle(0, 0.0, 0.125, 0.25) is None  # the angle and flexor now 0.125/0.25 s old
    assert e.angle(0, 0.0, 0.25, 0.25) is None  # the flexor 0.25 s old
    assert e.angle(0, 0.0, 0.0625, 0.0625) is not None  # a stamp ahead by 0.0625 s: fresh
    level, message, counts = e.status(0, 0.25)
    assert (counts['received joint_states'], counts['stale skipped'], counts['estimates']) == (
        '6',
        '4',
        '2',
    )
    assert (level, message) == (
        Level.ERROR,
        'stale flexor pressure: newest stamp is 0.25 s old (max_input_age 0.125 s)',
    )


def test_a_torque_command_round_trips_through_the_hand_torque():
    e = engine(ELBOW, WRIST, settings=[Settings(300e3, 'min'), Settings(600e3, 'sum')])
    feed(e, 0, 300e3, 300e3)  # fresh pressures: an estimate, so the status can be OK
    e.angle(0, -0.3, 0.0, 0.0)
    e.angle(1, 0.4, 0.0, 0.0)
    # elbow: the lower pressure at the file's 300 kPa
    p0, p1 = (p - AMBIENT for p in e.command(0, 2.5, 0.0))
    assert min(p0, p1) == pytest.approx(300e3, abs=1e-6) and p0 > p1  # the flexor pulls more
    assert elbow_torque(-0.3, p0, p1) == pytest.approx(2.5, abs=1e-8)
    # wrist: the pressures sum to 600 kPa
    p0, p1 = (p - AMBIENT for p in e.command(1, -0.8, 0.0))
    assert p0 + p1 == pytest.approx(600e3, abs=1e-6)
    assert wrist_torque(0.4, p0, p1) == pytest.approx(-0.8, abs=1e-8)
    # a wanted stiffness: both τ and K = -dτ/dθ are met
    e.angle(0, 0.2, 0.0, 0.0)
    e.stiffness(0, 4.5, 0.0)
    p0, p1 = (p - AMBIENT for p in e.command(0, 1.0, 0.0))
    assert elbow_torque(0.2, p0, p1) == pytest.approx(1.0, abs=1e-8)
    stiffness, error = stiffness_of(elbow_torque, ELBOW, 0.2, p0, p1)
    assert stiffness == pytest.approx(4.5, rel=1e-5, abs=error)
    assert e.status(0, 0.0)[2]['commands'] == 'stiffness 4.5 N·m/rad'
    # a co-contraction command ends the stiffness mode
    e.cocontraction(0, 400e3, 0.0)
    p0, p1 = (p - AMBIENT for p in e.command(0, -1.0, 0.0))
    assert p0 == pytest.approx(400e3, abs=1e-6) and elbow_torque(0.2, p0, p1) == pytest.approx(
        -1.0, abs=1e-8
    )
    assert e.status(0, 0.0)[:2] == (Level.OK, 'estimating')
    assert e.status(0, 0.0)[2]['pressure commands'] == '3'  # the elbow's three


def test_an_out_of_reach_torque_is_served_at_the_map_top_and_warns():
    e = engine()
    feed(e, 0, 300e3, 300e3)
    e.angle(0, 0.0, 0.0, 0.0)
    assert e.status(0, 0.0)[0] == Level.OK
    p0, p1 = (p - AMBIENT for p in e.command(0, 100.0, 0.0))
    # hildebrandt (extrapolated) commands up to the rated 800 kPa; the extensor stays at the
    # 300 kPa level
    assert (p0, p1) == pytest.approx((800e3, 300e3), abs=1e-6)
    assert elbow_torque(0.0, p0, p1) < 100.0
    assert e.status(0, 0.0)[:2] == (Level.WARN, 'saturated (SATURATED)')


def test_settings_are_checked():
    with pytest.raises(
        ValueError, match=r"cocontraction_mode must be one of \('min', 'sum'\), got 'max'"
    ):
        Settings(300e3, 'max')
    for level in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match='cocontraction must be a gauge pressure >= 0 Pa'):
            Settings(level, 'min')


def _nan_angle(e):
    return e.angle(0, math.nan, 0.0, 0.0)


@pytest.mark.parametrize(
    'act, problem, source',
    [
        (_nan_angle, 'angle is nan rad', 'rejected joint_states'),
        # 9 rad: the extensor would be 0.234 + 0.015·9 = 0.369 m, longer than L0/cos Θ0 = 0.2847 m
        (
            lambda e: e.angle(0, 9.0, 0.0, 0.0),
            "angle 9 rad puts muscle 'extensor' at 0.369 m, outside its geometry (0, 0.2847) m",
            'rejected joint_states',
        ),
        (
            lambda e: e.pressure(0, 0, math.nan, 0.0, 0.0),
            "muscle 'flexor': pressure is nan Pa",
            'rejected pressure',
        ),
        (
            lambda e: e.pressure(0, 1, -3.0, 0.0, 0.0),
            "muscle 'extensor': negative absolute pressure -3 Pa",
            'rejected pressure',
        ),
        (
            lambda e: e.command(0, math.inf, 0.0),
            'torque command is inf N·m',
            'rejected command',
        ),
        (
            lambda e: e.stiffness(0, -1.0, 0.0),
            'stiffness -1 N·m/rad is not >= 0',
            'rejected command',
        ),
        (
            lambda e: e.cocontraction(0, math.nan, 0.0),
            'co-contraction nan Pa is no gauge pressure >= 0',
            'rejected command',
        ),
    ],
)
def test_a_bad_input_is_rejected_and_changes_nothing(act, problem, source):
    e = engine()
    feed(e, 0, 400e3, 300e3)
    before = e.angle(0, 0.5, 0.0, 0.0)
    before_command = e.command(0, 1.0, 0.0)
    assert act(e) is None
    level, message, values = e.status(0, 0.0)
    rejected = [key for key in values if key.startswith('rejected')]
    assert (level, message, rejected) == (Level.ERROR, f'invalid input: {problem}', [source])
    assert values[source] == '1'
    # the newest inputs are untouched: the same estimate and command as before
    assert e.angle(0, 0.5, 0.0, 0.0) == before and e.command(0, 1.0, 0.0) == before_command
    assert before == (
        hand_torque(elbow_torque, ELBOW, 0.5, 400e3, 300e3),
        hand_stiffness(elbow_torque, ELBOW, 0.5, 400e3, 300e3),
    )
    for t, level in ((0.999, Level.ERROR), (1.0, Level.OK)):  # held for 1 s, inputs fresh
        feed(e, 0, 400e3, 300e3, t)
        e.angle(0, 0.5, t, t)
        assert e.status(0, t)[0] == level


def test_a_command_before_any_angle_is_rejected():
    e = engine()
    assert e.command(0, 1.0, 0.0) is None
    assert e.status(0, 0.0)[1] == 'invalid input: torque command before any angle (joint_states)'


def test_stale_commands_are_refused_counted_and_shown():
    """torque_command, stiffness_command and cocontraction_command stamps farther than max_age
    from the clock: refused (no pressures, the settings unchanged), counted, ERROR with the
    stale input's wording; a zero stamp (unstamped) is taken as received now.
    """
    e = engine()
    feed(e, 0, 300e3, 300e3, t=10.0)
    e.angle(0, 0.2, 10.0, 10.0)
    raw = e.engine
    assert raw.command(0, 1.0, ns(10.0), stamp=ns(9.8)) is None
    assert raw.status_due(ns(10.0))
    assert e.status(0, 10.0)[:2] == (
        Level.ERROR,
        'stale torque_command: stamp is 0.2 s old (max_input_age 0.125 s)',
    )
    raw.stiffness(0, 4.0, ns(10.0), stamp=ns(10.5))
    raw.cocontraction(0, 0.0, ns(10.0), stamp=ns(1.0))
    assert e.state[0].stiffness is None and e.state[0].level == 300e3  # unchanged
    assert raw.counts(0)['stale command'] == 3 and raw.counts(0)['received command'] == 3
    assert e.status(0, 10.0)[1].startswith('stale cocontraction_command: stamp is 9 s old')
    assert raw.command(0, 1.0, ns(10.0), stamp=ns(10.1)) is not None  # fresh
    assert raw.command(0, 1.0, ns(10.0), stamp=0) is not None  # unstamped
    raw.stiffness(0, 4.0, ns(10.0), stamp=0)
    assert e.state[0].stiffness == 4.0
