"""The estimation engine: validation, pairing, freshness, commands, diagnostics (no rclpy), and its
two entry forms (one muscle's input, every muscle's input) making the same decisions.
"""

import math

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from conftest import CONFIGS
from pma_model_ros.core.engine import Config, Engine, Level
from pma_model_ros.core.flags import Flag
from pma_model_ros.core.hysteresis import Follow
from pma_model_ros.core.param_file import muscle_model, read_parameters
from pma_model_ros.core.sarosi import dmsp_10_100_hysteresis

AMBIENT = 101325.0
P = 300e3  # gauge [Pa]
L = 0.23  # [m]


@pytest.fixture
def est(martens_10_250):
    return Engine([Config(martens_10_250, AMBIENT, max_input_age=0.1)], hold=1.0)


def test_estimate_needs_both_inputs_and_pairs_the_newest(est, martens_10_250):
    assert est.pressure(0, AMBIENT + P, stamp=10.0, now=10.0) is None
    force = est.length(0, L, 0.0, stamp=10.01, now=10.01, tag='stamp-b')
    assert force == pytest.approx(float(martens_10_250.force(P, L).force), rel=1e-9)
    assert (est.stamp, est.tag) == (10.01, 'stamp-b')
    force = est.pressure(0, AMBIENT + 2 * P, stamp=10.02, now=10.02, tag='stamp-c')
    assert force == pytest.approx(float(martens_10_250.force(2 * P, L).force), rel=1e-9)
    assert (est.stamp, est.tag) == (10.02, 'stamp-c')
    assert est.counts(0)['estimates'] == 2


def test_force_against_a_hand_calculation(est):
    """Martens eq. 14 at one point, from Table 2's geometry and the shipped parameters by hand (no
    package code).
    """
    params = read_parameters(CONFIGS['DMSP-10-250'])
    c0, c1, c2, c3, d0 = params['models']['martens']['params']
    spec = params['muscle']
    L0, D0, H0 = spec['nominal_length'], spec['inner_diameter'], spec['membrane_thickness']
    angle = spec['fiber_angle'] + d0
    fibre = L0 / math.cos(angle)
    n = L0 * math.tan(angle) / (math.pi * D0)
    dV = (fibre**2 - 3 * L**2) / (4 * math.pi * n**2)
    D = math.sqrt(fibre**2 - L**2) / (n * math.pi)
    dD = -L / (n * math.pi * math.sqrt(fibre**2 - L**2))
    E = c0 + c1 * L + c2 * L**2 + c3 * L**3
    f_pe = E * (D - D0) / D0 * H0 * L * math.pi
    f_l = E * (L - L0) / L0 * H0 * math.pi * D
    expected = -P * dV + f_pe * dD - f_l
    est.length(0, L, 0.0, stamp=1.0, now=1.0)
    assert est.pressure(0, AMBIENT + P, stamp=1.0, now=1.0) == pytest.approx(expected, rel=1e-9)
    assert (
        0 < expected < 35.17
    )  # Table A2: 35.17 N at 310 kPa and the longer 0.234 m (a shorter muscle pulls less)


def test_stale_input_gives_no_estimate_and_error(est):
    est.pressure(0, AMBIENT + P, stamp=10.0, now=10.0)
    assert est.length(0, L, 0.0, stamp=10.2, now=10.2) is None  # pressure is 0.2 s old
    assert est.counts(0)['stale skipped'] == 1
    level, message = est.level(0, 10.2)
    assert level == Level.ERROR and 'stale pressure' in message
    assert est.length(0, L, 0.0, stamp=10.0, now=10.3) is None  # length itself too old
    assert est.pressure(0, AMBIENT + P, stamp=11.0, now=10.0) is None  # stamp from the future


@pytest.mark.parametrize(
    'absolute, words', [(math.nan, 'nan'), (-1.0, 'negative'), (6e6, 'absurd'), (math.inf, 'inf')]
)
def test_bad_pressure_rejected(est, absolute, words):
    est.length(0, L, 0.0, stamp=1.0, now=1.0)
    est.pressure(0, AMBIENT + P, stamp=1.0, now=1.0)
    assert est.pressure(0, absolute, stamp=1.01, now=1.01) is None
    assert est.counts(0)['rejected pressure'] == 1
    level, message = est.level(0, 1.01)
    assert level == Level.ERROR and words in message.lower()
    assert est.level(0, 2.5)[0] == Level.ERROR  # inputs stale by then
    est.pressure(0, AMBIENT + P, stamp=2.5, now=2.5)
    est.length(0, L, 0.0, stamp=2.5, now=2.5)
    assert est.level(0, 2.5) == (Level.OK, 'estimating')  # the rejection no longer holds


@pytest.mark.parametrize('length', [math.nan, 0.0, -0.1, 0.3])
def test_bad_length_rejected(est, length):
    est.pressure(0, AMBIENT + P, stamp=1.0, now=1.0)
    assert est.length(0, length, 0.0, stamp=1.0, now=1.0) is None
    assert est.counts(0)['rejected muscle_state'] == 1


def test_message_level_rejection_counts(est):
    est.reject(0, 'muscle_state', "joint 'x' not in ['y']", now=1.0)
    assert est.counts(0) == {'received muscle_state': 1, 'rejected muscle_state': 1}
    assert est.level(0, 1.0) == (Level.ERROR, "invalid input: joint 'x' not in ['y']")


def test_estimates_are_never_nan_and_nonnegative(est):
    est.pressure(0, AMBIENT, stamp=1.0, now=1.0)  # 0 Pa gauge: slack muscle
    assert est.length(0, 0.2, 0.0, stamp=1.0, now=1.0) == 0.0
    assert est.flags & Flag.CLIPPED


def test_branch_unknown_only_before_the_first_motion():
    model = dmsp_10_100_hysteresis()
    est = Engine([Config(model, AMBIENT, 10.0)])
    est.pressure(0, AMBIENT + 3e5, stamp=1.0, now=1.0)
    est.length(0, 0.09, None, stamp=1.0, now=1.0)
    assert est.flags & Flag.BRANCH_UNKNOWN
    level, message = est.level(0, 1.0)
    assert level == Level.WARN and 'hysteresis branch unknown' in message
    est.length(0, 0.0904, None, stamp=2.0, now=2.0)  # 0.4 mm: inside the 0.5 mm deadband
    assert est.flags & Flag.BRANCH_UNKNOWN
    force = est.length(
        0, 0.0906, None, stamp=2.05, now=2.05
    )  # 0.6 mm longer: lengthening, the upper branch
    assert force == pytest.approx(float(model.force(3e5, 0.0906, 1.0).force), rel=1e-12)
    est.length(0, 0.0906, 0.0, stamp=2.1, now=2.1)  # held still: the branch is kept, no warning
    assert est.pressure(0, AMBIENT + 3e5, stamp=3.2, now=3.2) == pytest.approx(force, rel=1e-12)
    assert est.level(0, 3.2)[0] == Level.OK  # the warning was held for 1 s only
    est.pressure(0, AMBIENT + 9e5, stamp=3.22, now=3.22)
    level, message = est.level(0, 3.22)
    assert level == Level.WARN and 'outside validity domain' in message


def test_velocity_noise_does_not_flip_the_branch():
    """Issue 11, 4: at L0 = 0.1 m and 6 bar the DMSP-10-100's branches differ by 51 N (~10 %); a
    muscle held near L0 with ±0.2 mm of length noise and velocities of either sign stays on the
    branch it came by.
    """
    model = dmsp_10_100_hysteresis()
    up, down = (float(model.force(6e5, 0.1, rate).force) for rate in (1.0, -1.0))
    assert up - down == pytest.approx(51, abs=1)
    rng = np.random.default_rng(1)
    est = Engine([Config(model, AMBIENT, 10.0)])
    est.pressure(0, AMBIENT + 6e5, stamp=0.0, now=0.0)
    est.length(0, 0.098, -0.01, stamp=0.0, now=0.0)  # came from 2 mm shorter: lengthening
    lengths = 0.1 + rng.uniform(-2e-4, 2e-4, 500)  # peak to peak 0.4 mm < the 0.5 mm deadband
    forces = [est.length(0, length, rng.normal(0, 0.01), stamp=0.0, now=0.0) for length in lengths]
    np.testing.assert_allclose(
        forces, model.force(6e5, lengths, 1.0).force, rtol=1e-9
    )  # the upper branch


def test_branch_can_follow_the_pressure():
    """Filling then venting at a fixed length: the branch follows the pressure (hysteresis.input:
    pressure).
    """
    model = dmsp_10_100_hysteresis()
    est = Engine([Config(model, AMBIENT, 0.1, follow=Follow('pressure', 5e3))])
    est.length(0, 0.09, 0.0, stamp=0.0, now=0.0)
    for k, gauge in enumerate([0.0, 2e5, 4e5, 6e5, 5.98e5, 5.9e5, 4e5]):
        force = est.pressure(0, AMBIENT + gauge, stamp=k * 0.01, now=k * 0.01)
        expected = {0: 0.0, 1: 1.0, 2: 1.0, 3: 1.0, 4: 1.0, 5: -1.0, 6: -1.0}[
            k
        ]  # 2 kPa back: still filling
        if expected:
            assert force == pytest.approx(
                float(model.force(gauge, 0.09, expected).force), rel=1e-12
            ), k
        else:
            assert est.flags & Flag.BRANCH_UNKNOWN


def test_command_inverts_the_model(est, martens_10_250):
    assert est.command(0, 100.0, now=1.0) is None  # no length yet
    est.length(0, L, 0.0, stamp=1.0, now=1.0)
    gauge = est.command(0, 100.0, now=1.05) - AMBIENT
    assert float(martens_10_250.force(gauge, L).force) == pytest.approx(100.0, abs=1e-6)
    est.command(0, 1e5, now=1.05)
    assert est.flags & Flag.SATURATED
    assert est.level(0, 1.05)[0] == Level.ERROR  # pressure never received
    assert (
        est.command(0, math.nan, now=1.05) is None and est.counts(0)['rejected force_command'] == 1
    )
    assert est.command(0, 100.0, now=1.2) is None  # length now stale


def test_config_swap_and_status(est, martens_10_250):
    est.pressure(0, AMBIENT + P, stamp=1.0, now=1.0)
    first = est.length(0, L, 0.0, stamp=1.0, now=1.0)
    sarosi = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'sarosi')
    est.configure([Config(sarosi, AMBIENT, 0.1)])
    assert est.pressure(0, AMBIENT + P, stamp=1.01, now=1.01) == pytest.approx(
        float(sarosi.force(P, L).force), rel=1e-9
    )
    assert first == pytest.approx(float(martens_10_250.force(P, L).force), rel=1e-9)
    est.status(0, 1.0)
    status = est.status(0, 2.0)
    assert status.values['model'] == 'sarosi' and status.values['estimates'] == '2'
    assert float(status.values['estimates rate [Hz]']) == pytest.approx(0.0)


def test_config_swap_to_a_shorter_muscle_rejects_the_kept_length(est):
    """A length the new geometry cannot take gives no estimate (and ERROR), never a force at the
    wrong length.
    """
    est.length(0, L, 0.0, stamp=1.0, now=1.0)
    est.configure(
        [Config(dmsp_10_100_hysteresis(), AMBIENT, 0.1)]
    )  # fibre length 0.107 m < 0.23 m
    assert est.pressure(0, AMBIENT + P, stamp=1.0, now=1.0) is None
    assert est.level(0, 1.0)[0] == Level.ERROR and est.counts(0)['rejected muscle_state'] == 1


def test_approximate_time_pairs_each_input_once(martens_10_250):
    est = Engine([Config(martens_10_250, AMBIENT, 0.1)], pairing='approximate_time', slop=0.002)
    assert est.length(0, L, 0.0, stamp=1.0, now=1.0) is None
    assert est.pressure(0, AMBIENT + P, stamp=1.0005, now=1.001) is not None  # the pair of tick 1
    assert est.length(0, L, 0.0, stamp=1.001, now=1.0015) is None  # waits for its pressure
    assert (
        est.pressure(0, AMBIENT + P, stamp=1.010, now=1.010) is None
    )  # 9 ms apart: the length dropped
    assert est.counts(0)['unpaired'] == 1
    assert (
        est.length(0, L, 0.0, stamp=1.011, now=1.011) is not None
    )  # pairs with the 1.010 pressure
    assert est.counts(0)['estimates'] == 2
    with pytest.raises(ValueError, match='pairing'):
        Engine([Config(martens_10_250)], pairing='exact')


# --- the two entry forms make the same decisions
# ----------------------------------------------------------

MODELS = [
    muscle_model(read_parameters(CONFIGS[muscle]), name)
    for muscle in ('DMSP-10-250', 'DMSP-20-300')
    for name in ('martens', 'sarosi', 'hildebrandt', 'wickramatunge')
] + [dmsp_10_100_hysteresis()]

#: One message of every muscle: kind, per-muscle value (NaN, negative, absurd, out of geometry
#: included), rate.
good = st.floats(0.0, 1.0)
values = st.one_of(good, good, good, good, st.sampled_from([math.nan, -1.0, 0.0, 2.0, math.inf]))
steps = st.tuples(
    st.sampled_from(['pressure', 'length', 'pressure', 'length', 'wait']),
    st.lists(values, min_size=len(MODELS), max_size=len(MODELS)),
    st.sampled_from([-0.01, 0.0, 0.01, math.nan, None]),
    st.one_of(st.floats(0.0, 0.005), st.floats(0.0, 0.005), st.floats(0.0, 0.3)),  # time step [s]
    st.one_of(st.floats(-0.003, 0.0), st.floats(-0.15, 0.05)),
)  # stamp - now [s]: some stale


def _physical(kind: str, unit: float, model) -> float:
    """A unit draw as a pressure [Pa absolute] or a length [m] of ``model``, beyond the bounds at
    the edges.
    """
    if not 0 <= unit <= 1:
        return unit
    if kind == 'pressure':
        return AMBIENT + (unit - 0.1) * 1.2 * model.spec.max_pressure
    return unit * 1.1 * model.max_length


@pytest.mark.parametrize('pairing', ['every_input', 'approximate_time'])
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(stream=st.lists(steps, min_size=1, max_size=25))
def test_one_by_one_equals_all_at_once(pairing, stream):
    """A stream of messages of every muscle, fed muscle by muscle (float path) and as one vector
    per message: the same estimates, flags, counters and diagnostic levels and texts.
    """
    configs = [Config(m, AMBIENT, 0.1, ('absolute', 'gauge')[k % 2]) for k, m in enumerate(MODELS)]
    one, many = (Engine(configs, hold=0.5, pairing=pairing, slop=0.003) for _ in range(2))
    now = 100.0
    for kind, units, rate, dt, offset in stream:
        now += dt
        if kind == 'wait':
            continue
        column = np.array([_physical(kind, u, m) for u, m in zip(units, MODELS)])
        if kind == 'pressure':
            singles = [
                one.pressure(k, column[k], now + offset, now, tag=k) for k in range(len(MODELS))
            ]
            got = many.pressures(column, now + offset, now, tag='msg')
        else:
            rates = None if rate is None else np.full(len(MODELS), rate)
            singles = [
                one.length(k, column[k], rate, now + offset, now, tag=k)
                for k in range(len(MODELS))
            ]
            got = many.lengths(column, rates, now + offset, now, tag='msg')
        assert got.tolist() == [s is not None for s in singles]
        expected = [s for s in singles if s is not None]
        # math vs numpy: ulps of terms up to ~1e3 N, which cancel near 0 N
        assert many.forces[got].tolist() == pytest.approx(expected, rel=1e-9, abs=1e-6)
        for k in range(len(MODELS)):
            assert one.counts(k) == many.counts(k)
            assert one.level(k, now) == many.level(k, now)
        assert many.levels(now).tolist() == [one.level(k, now)[0] for k in range(len(MODELS))]
        due = any(one.status_due(now, k) for k in range(len(MODELS)))
        assert many.status_due(now) == due  # the vector form's shortcut included
        if (
            due or kind == 'pressure' and dt > 0.1
        ):  # report on change, and now and then (the timer)
            assert [one.status(k, now) for k in range(len(MODELS))] == [
                many.status(k, now) for k in range(len(MODELS))
            ]


def test_gauge_sensor_reading(martens_10_250):
    """Issue 11, 5: a gauge sensor's 300 kPa read as absolute loses 101 kPa, about 81 N on a
    DMSP-10-250 at L0 (0.8 N/kPa); with pressure_reference gauge it is served at 300 kPa gauge, and
    a command comes back in gauge.
    """
    served = {}
    for reference in ('absolute', 'gauge'):
        engine = Engine([Config(martens_10_250, AMBIENT, 0.1, reference)])
        engine.length(0, 0.25, 0.0, stamp=1.0, now=1.0)
        served[reference] = engine.pressure(0, 300e3, stamp=1.0, now=1.0)
        command = engine.command(
            0, served['gauge' if reference == 'gauge' else 'absolute'], now=1.0
        )
        assert command == pytest.approx(300e3, rel=1e-9)
    assert served['gauge'] - served['absolute'] == pytest.approx(81, abs=2)
    assert served['gauge'] == pytest.approx(
        float(martens_10_250.force(300e3, 0.25).force), rel=1e-12
    )
    with pytest.raises(ValueError, match='pressure_reference'):
        Config(martens_10_250, AMBIENT, 0.1, 'psi')


def test_status_due_after_a_steady_stretch(martens_10_250):
    """Levels reported OK for a while; then an input with the other one stale must be reported at
    once.
    """
    engine = Engine([Config(martens_10_250, AMBIENT, 0.1)] * 3, hold=1.0)
    pressures, lengths = np.full(3, AMBIENT + P), np.full(3, L)
    now = 10.0
    for _ in range(5):
        now += 0.001
        engine.pressures(pressures, now, now)
        engine.lengths(lengths, None, now, now)
        if engine.status_due(now):
            [engine.status(k, now) for k in range(3)]
    assert not engine.status_due(now) and engine.levels(now).tolist() == [0, 0, 0]
    now += 0.2  # the lengths are now 0.2 s old
    assert not engine.pressures(pressures, now, now).any()
    assert engine.status_due(now) and engine.level(0, now)[1].startswith('stale muscle_state')


def test_on_change_reports_wait_for_the_report_interval(martens_10_250):
    engine = Engine([Config(martens_10_250, AMBIENT, 0.1)], report_interval=0.1)
    engine.length(0, L, 0.0, stamp=1.0, now=1.0)
    assert engine.status_due(1.0, 0)
    engine.status(0, 1.0)  # ERROR: no pressure yet
    engine.pressure(
        0, AMBIENT + P, stamp=1.05, now=1.05
    )  # now OK, but 0.05 s after the last report
    assert not engine.status_due(1.05, 0) and not engine.status_due(1.05)
    engine.length(0, L, 0.0, stamp=1.12, now=1.12)
    assert engine.status_due(1.12, 0) and engine.status_due(
        1.12
    )  # reported with the next input after 0.1 s
