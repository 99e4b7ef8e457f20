"""The estimation engine: validation, pairing, freshness, commands, diagnostics (no rclpy), and its
two entry forms (one muscle's input, every muscle's input) making the same decisions.
"""

import itertools
import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from budget import examples
from conftest import CONFIGS
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.shipped_data import dmsp_10_100_hysteresis
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.physics.hysteresis import Follow
from pma_model_ros.core.physics.muscle_model import force_at
from pma_model_ros.core.runtime.engine import Config, Engine, Level
from pma_model_ros.core.runtime.estimation import (
    command_problem,
    commands_ok,
    lengths_ok,
    Muscles,
    pressures_ok,
)
from pma_model_ros.core.runtime.pairing import (
    fresh,
    NEVER,
    SECOND,
    stale_command_stamps,
    UNSTAMPED,
)

AMBIENT = 101325.0
P = 300e3  # gauge [Pa]
L = 0.23  # [m]


def ns(seconds: float) -> int:
    """A time [s] in the engine's integer nanoseconds."""
    return round(seconds * 1e9)


def feed_pressure(est, reading, stamp, now, k=0):
    """One pressure reading [Pa] of muscle ``k``: its force [N], or None."""
    return est.forces.item(0) if est.pressure(k, reading, ns(stamp), ns(now)) else None


def feed_length(est, value, rate, stamp, now, k=0):
    """One length [m] and rate [m/s] (None: unknown) of muscle ``k``: its force [N], or None."""
    got = est.length(k, value, math.nan if rate is None else rate, ns(stamp), ns(now))
    return est.forces.item(0) if got else None


def flags(est) -> int:
    return int(est.flags[0])


@pytest.fixture
def est(martens_10_250):
    return Engine([Config(martens_10_250, AMBIENT, max_input_age=0.1)], hold=1.0)


def test_estimate_needs_both_inputs_and_pairs_the_newest(est, martens_10_250):
    assert feed_pressure(est, AMBIENT + P, stamp=10.0, now=10.0) is None
    force = feed_length(est, L, 0.0, stamp=10.01, now=10.01)
    assert force == pytest.approx(float(martens_10_250.force(P, L).force), rel=1e-9)
    assert est.stamp == ns(10.01)
    force = feed_pressure(est, AMBIENT + 2 * P, stamp=10.02, now=10.02)
    assert force == pytest.approx(float(martens_10_250.force(2 * P, L).force), rel=1e-9)
    assert est.stamp == ns(10.02)
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
    feed_length(est, L, 0.0, stamp=1.0, now=1.0)
    assert feed_pressure(est, AMBIENT + P, stamp=1.0, now=1.0) == pytest.approx(expected, rel=1e-9)
    assert (
        0 < expected < 35.17
    )  # Table A2: 35.17 N at 310 kPa and the longer 0.234 m (a shorter muscle pulls less)


def test_stale_input_gives_no_estimate_and_error(est):
    feed_pressure(est, AMBIENT + P, stamp=10.0, now=10.0)
    assert feed_length(est, L, 0.0, stamp=10.2, now=10.2) is None  # pressure is 0.2 s old
    assert est.counts(0)['stale skipped'] == 1
    level, message = est.level(0, ns(10.2))
    assert level == Level.ERROR and 'stale pressure' in message
    assert feed_length(est, L, 0.0, stamp=10.0, now=10.3) is None  # length itself too old
    assert feed_pressure(est, AMBIENT + P, stamp=11.0, now=10.0) is None  # stamp from the future


@pytest.mark.parametrize(
    'absolute, words', [(math.nan, 'nan'), (-1.0, 'negative'), (6e6, 'absurd'), (math.inf, 'inf')]
)
def test_bad_pressure_rejected(est, absolute, words):
    feed_length(est, L, 0.0, stamp=1.0, now=1.0)
    feed_pressure(est, AMBIENT + P, stamp=1.0, now=1.0)
    assert feed_pressure(est, absolute, stamp=1.01, now=1.01) is None
    assert est.counts(0)['rejected pressure'] == 1
    level, message = est.level(0, ns(1.01))
    assert level == Level.ERROR and words in message.lower()
    assert est.level(0, ns(2.5))[0] == Level.ERROR  # inputs stale by then
    feed_pressure(est, AMBIENT + P, stamp=2.5, now=2.5)
    feed_length(est, L, 0.0, stamp=2.5, now=2.5)
    assert est.level(0, ns(2.5)) == (Level.OK, 'estimating')  # the rejection no longer holds


@pytest.mark.parametrize('length', [math.nan, 0.0, -0.1, 0.3])
def test_bad_length_rejected(est, length):
    feed_pressure(est, AMBIENT + P, stamp=1.0, now=1.0)
    assert feed_length(est, length, 0.0, stamp=1.0, now=1.0) is None
    assert est.counts(0)['rejected muscle_state'] == 1


def test_message_level_rejection_counts(est):
    est.reject(0, 'muscle_state', "joint 'x' not in ['y']", ns(1.0))
    assert est.counts(0) == {'received muscle_state': 1, 'rejected muscle_state': 1}
    assert est.level(0, ns(1.0)) == (Level.ERROR, "invalid input: joint 'x' not in ['y']")


def test_estimates_are_never_nan_and_nonnegative(est):
    feed_pressure(est, AMBIENT, stamp=1.0, now=1.0)  # 0 Pa gauge: slack muscle
    assert feed_length(est, 0.2, 0.0, stamp=1.0, now=1.0) == 0.0
    assert flags(est) & Flag.CLIPPED


def test_branch_unknown_only_before_the_first_motion():
    model = dmsp_10_100_hysteresis()
    est = Engine([Config(model, AMBIENT, 10.0)])
    feed_pressure(est, AMBIENT + 3e5, stamp=1.0, now=1.0)
    feed_length(est, 0.09, None, stamp=1.0, now=1.0)
    assert flags(est) & Flag.BRANCH_UNKNOWN
    level, message = est.level(0, ns(1.0))
    assert level == Level.WARN and 'hysteresis branch unknown' in message
    feed_length(est, 0.0904, None, stamp=2.0, now=2.0)  # 0.4 mm: inside the 0.5 mm deadband
    assert flags(est) & Flag.BRANCH_UNKNOWN
    force = feed_length(
        est, 0.0906, None, stamp=2.05, now=2.05
    )  # 0.6 mm longer: lengthening, the upper branch
    assert force == pytest.approx(float(model.force(3e5, 0.0906, 1.0).force), rel=1e-12)
    feed_length(est, 0.0906, 0.0, stamp=2.1, now=2.1)  # held still: the branch is kept, no warning
    assert feed_pressure(est, AMBIENT + 3e5, stamp=3.2, now=3.2) == pytest.approx(force, rel=1e-12)
    assert est.level(0, ns(3.2))[0] == Level.OK  # the warning was held for 1 s only
    feed_pressure(est, AMBIENT + 9e5, stamp=3.22, now=3.22)
    level, message = est.level(0, ns(3.22))
    assert level == Level.WARN and 'outside validity domain' in message


def test_velocity_noise_does_not_flip_the_branch():
    """At L0 = 0.1 m and 6 bar the DMSP-10-100's branches differ by 51 N (~10 %); a
    muscle held near L0 with ±0.2 mm of length noise and velocities of either sign stays on the
    branch it came by.
    """
    model = dmsp_10_100_hysteresis()
    up, down = (float(model.force(6e5, 0.1, rate).force) for rate in (1.0, -1.0))
    assert up - down == pytest.approx(51, abs=1)
    rng = np.random.default_rng(1)
    est = Engine([Config(model, AMBIENT, 10.0)])
    feed_pressure(est, AMBIENT + 6e5, stamp=0.0, now=0.0)
    feed_length(est, 0.098, -0.01, stamp=0.0, now=0.0)  # came from 2 mm shorter: lengthening
    lengths = 0.1 + rng.uniform(-2e-4, 2e-4, 500)  # peak to peak 0.4 mm < the 0.5 mm deadband
    forces = [
        feed_length(est, length, rng.normal(0, 0.01), stamp=0.0, now=0.0) for length in lengths
    ]
    np.testing.assert_allclose(
        forces, model.force(6e5, lengths, 1.0).force, rtol=1e-9
    )  # the upper branch


def test_branch_can_follow_the_pressure():
    """Filling then venting at a fixed length: the branch follows the pressure (hysteresis.input:
    pressure).
    """
    model = dmsp_10_100_hysteresis()
    est = Engine([Config(model, AMBIENT, 0.1, follow=Follow('pressure', 5e3))])
    feed_length(est, 0.09, 0.0, stamp=0.0, now=0.0)
    for k, gauge in enumerate([0.0, 2e5, 4e5, 6e5, 5.98e5, 5.9e5, 4e5]):
        force = feed_pressure(est, AMBIENT + gauge, stamp=k * 0.01, now=k * 0.01)
        expected = {0: 0.0, 1: 1.0, 2: 1.0, 3: 1.0, 4: 1.0, 5: -1.0, 6: -1.0}[
            k
        ]  # 2 kPa back: still filling
        if expected:
            assert force == pytest.approx(
                float(model.force(gauge, 0.09, expected).force), rel=1e-12
            ), k
        else:
            assert flags(est) & Flag.BRANCH_UNKNOWN


def test_command_inverts_the_model(est, martens_10_250):
    assert est.command(0, 100.0, ns(1.0)) is None  # no length yet
    feed_length(est, L, 0.0, stamp=1.0, now=1.0)
    gauge = est.command(0, 100.0, ns(1.05)) - AMBIENT
    assert float(martens_10_250.force(gauge, L).force) == pytest.approx(100.0, abs=1e-6)
    est.command(0, 1e5, ns(1.05))
    assert flags(est) & Flag.SATURATED
    assert est.level(0, ns(1.05))[0] == Level.ERROR  # pressure never received
    assert (
        est.command(0, math.nan, ns(1.05)) is None and est.counts(0)['rejected force_command'] == 1
    )
    assert est.command(0, 100.0, ns(1.2)) is None  # length now stale


def test_a_command_stamped_outside_max_input_age_is_refused_as_stale(est):
    """A stale (or future) force_command gives no pressure command, is counted and shown as a stale
    input is; a zero stamp (unstamped) is taken as received now.
    """
    feed_length(est, L, 0.0, stamp=10.0, now=10.0)
    assert est.command(0, 100.0, ns(10.0), stamp=ns(9.5)) is None
    assert est.counts(0) == {
        'received muscle_state': 1,
        'received force_command': 1,
        'stale force_command': 1,
    }
    assert est.level(0, ns(10.0)) == (
        Level.ERROR,
        'stale force_command: stamp is 0.5 s old (max_input_age 0.1 s)',
    )
    assert est.command(0, 100.0, ns(10.0), stamp=ns(10.2)) is None
    assert est.level(0, ns(10.0))[1] == (
        'stale force_command: stamp is 0.2 s in the future (max_input_age 0.1 s)'
    )
    for stamp in (ns(9.95), 0):  # fresh; unstamped
        assert est.command(0, 100.0, ns(10.0), stamp=stamp) is not None
    assert est.counts(0)['stale force_command'] == 2 and est.counts(0)['pressure commands'] == 2
    assert est.level(0, ns(11.1))[1] == 'no pressure received yet'  # the hold is over


def test_config_swap_and_status(est, martens_10_250):
    feed_pressure(est, AMBIENT + P, stamp=1.0, now=1.0)
    first = feed_length(est, L, 0.0, stamp=1.0, now=1.0)
    sarosi = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'sarosi')
    est.configure([Config(sarosi, AMBIENT, 0.1)])
    assert feed_pressure(est, AMBIENT + P, stamp=1.01, now=1.01) == pytest.approx(
        float(sarosi.force(P, L).force), rel=1e-9
    )
    assert first == pytest.approx(float(martens_10_250.force(P, L).force), rel=1e-9)
    est.statuses(ns(1.0))
    status = est.statuses(ns(2.0))[0]
    assert status.values['model'] == 'sarosi' and status.values['estimates'] == '2'
    assert status.values['pressure: Events in window'] == '0'  # none since the 1 s report
    assert status.values['pressure: Events since startup'] == '2'
    assert status.values['pressure: Actual frequency (Hz)'] == '0.000000'


def test_config_swap_to_a_shorter_muscle_rejects_the_kept_length(est):
    """A length the new geometry cannot take gives no estimate (and ERROR), never a force at the
    wrong length.
    """
    feed_length(est, L, 0.0, stamp=1.0, now=1.0)
    est.configure(
        [Config(dmsp_10_100_hysteresis(), AMBIENT, 0.1)]
    )  # fibre length 0.107 m < 0.23 m
    assert feed_pressure(est, AMBIENT + P, stamp=1.0, now=1.0) is None
    assert est.level(0, ns(1.0))[0] == Level.ERROR and est.counts(0)['rejected muscle_state'] == 1


def test_approximate_time_pairs_each_input_once(martens_10_250):
    est = Engine([Config(martens_10_250, AMBIENT, 0.1)], pairing='approximate_time', slop=0.002)
    assert feed_length(est, L, 0.0, stamp=1.0, now=1.0) is None
    assert (
        feed_pressure(est, AMBIENT + P, stamp=1.0005, now=1.001) is not None
    )  # the pair of tick 1
    assert feed_length(est, L, 0.0, stamp=1.001, now=1.0015) is None  # waits for its pressure
    assert (
        feed_pressure(est, AMBIENT + P, stamp=1.010, now=1.010) is None
    )  # 9 ms apart: the length dropped
    assert est.counts(0)['unpaired'] == 1
    assert (
        feed_length(est, L, 0.0, stamp=1.011, now=1.011) is not None
    )  # pairs with the 1.010 pressure
    assert est.counts(0)['estimates'] == 2
    with pytest.raises(ValueError, match='pairing'):
        Engine([Config(martens_10_250)], pairing='exact')


def test_approximate_time_skips_a_stale_pair(martens_10_250):
    """A pressure and a length within ``slop`` of each other but 0.12 s old (max_input_age 0.1 s)
    pair, and give no estimate: one 'stale skipped', no 'unpaired'; the muscle is ERROR (stale)
    until a fresh pair estimates.
    """
    est = Engine([Config(martens_10_250, AMBIENT, 0.1)], pairing='approximate_time', slop=0.002)
    assert feed_pressure(est, AMBIENT + P, stamp=0.880, now=1.000) is None
    assert feed_length(est, L, 0.0, stamp=0.881, now=1.001) is None
    counts = est.counts(0)
    assert counts['stale skipped'] == 1 and 'unpaired' not in counts and 'estimates' not in counts
    level, text = est.level(0, ns(1.001))
    assert level == Level.ERROR and text.startswith('stale '), text
    assert feed_pressure(est, AMBIENT + P, stamp=1.010, now=1.010) is None  # waits for its length
    assert feed_length(est, L, 0.0, stamp=1.011, now=1.011) is not None
    assert est.counts(0)['estimates'] == 1 and est.level(0, ns(1.011))[0] == Level.OK


# --- the two entry forms make the same decisions
# ----------------------------------------------------------

MODELS = [
    muscle_model(read_parameters(CONFIGS[muscle]), name)
    for muscle in ('DMSP-10-250', 'DMSP-20-300')
    for name in ('martens', 'sarosi', 'hildebrandt', 'wickramatunge')
] + [dmsp_10_100_hysteresis()]

#: One message of every muscle: kind, per-muscle value (NaN, negative, absurd, out of geometry
#: included; or every value usual: the array path's shortcut), rate, time step, stamp - now,
#: which muscles it holds.
good = st.floats(0.0, 1.0)
values = st.one_of(good, good, good, good, st.sampled_from([math.nan, -1.0, 0.0, 2.0, math.inf]))


def often(usual, rare):
    """``usual`` three times in four, else ``rare``."""
    return st.tuples(st.integers(0, 3), usual, rare).map(lambda t: t[2] if t[0] == 0 else t[1])


steps = st.tuples(
    st.sampled_from(['pressure', 'length', 'pressure', 'length', 'wait']),
    often(
        st.lists(st.floats(0.12, 0.6), min_size=len(MODELS), max_size=len(MODELS)),
        st.lists(values, min_size=len(MODELS), max_size=len(MODELS)),
    ),
    st.sampled_from([-0.01, 0.0, 0.01, math.nan, None]),
    often(st.floats(0.0, 0.005), st.floats(0.0, 0.3)),  # time step [s]
    often(st.floats(-0.003, 0.0), st.floats(-0.15, 0.05)),  # stamp - now [s]: some stale
    often(st.none(), st.lists(st.booleans(), min_size=len(MODELS), max_size=len(MODELS))),
)  # present: None (every muscle) or a mask


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
@examples(150)
@given(start=st.booleans(), stream=st.lists(steps, min_size=1, max_size=25))
def test_muscle_by_muscle_equals_all_at_once(pairing, start, stream):
    """A stream of messages of every muscle (or of some: the others rejected as absent), fed
    muscle by muscle (the one-muscle float path: each muscle's own model) and as one message of all
    (the array path: the bank): the same estimates, flags, counters, levels and statuses.
    """
    configs = [Config(m, AMBIENT, 0.1, ('absolute', 'gauge')[k % 2]) for k, m in enumerate(MODELS)]
    single, many = (Engine(configs, hold=0.5, pairing=pairing, slop=0.003) for _ in range(2))
    now, shortcuts = 100.0, 0
    usual = ('pressure', [0.3] * len(MODELS), 0.0, 0.001, 0.0, None)
    if start:  # every muscle's usual pressure and length first: all estimated by the array path
        stream = [usual, ('length',) + usual[1:], *stream]
    for kind, units, rate, dt, offset, mask in stream:
        now += dt
        if kind == 'wait':
            continue
        t, stamp = ns(now), ns(now + offset)
        column = np.array([_physical(kind, u, m) for u, m in zip(units, MODELS)])
        rates = np.full(len(MODELS), math.nan if rate is None else rate)
        present = None if mask is None or all(mask) else np.array(mask)
        source = 'pressure' if kind == 'pressure' else 'muscle_state'
        singles, flags, stamps = [], [], []
        for k in range(len(MODELS)):
            if present is not None and not present[k]:
                for engine in (single, many):
                    engine.reject(k, source, f'muscle {k} absent', t)
                singles.append(None)
                continue
            if kind == 'pressure':
                got = single.pressure(k, column.item(k), stamp, t)
            else:
                got = single.length(k, column.item(k), rates.item(k), stamp, t)
            singles.append(single.forces.item(0) if got else None)
            flags.append(int(single.flags[0]) if got else None)
            stamps += [single.stamp] if got else []
        if kind == 'pressure':
            got = many.pressures(column, stamp, t, present)
        else:
            got = many.lengths(column, rates, stamp, t, present)
        assert got.tolist() == [s is not None for s in singles]
        shortcuts += got.all()
        expected = [s for s in singles if s is not None]
        # ulps of terms up to ~1e3 N, which cancel near 0 N
        assert many.forces[got].tolist() == pytest.approx(expected, rel=1e-9, abs=1e-6)
        assert many.flags[got].tolist() == [f for f in flags if f is not None]
        if got.any():  # the newest input stamp among the muscles estimated
            assert many.stamp == max(stamps)
        for k in range(len(MODELS)):
            assert single.counts(k) == many.counts(k)
            assert single.level(k, t) == many.level(k, t)
        assert many.levels(t).tolist() == [single.level(k, t)[0] for k in range(len(MODELS))]
        due = single.status_due(t)
        assert many.status_due(t) == due
        if due or kind == 'pressure' and dt > 0.1:  # report on change, and now and then
            assert single.statuses(t) == many.statuses(t)
    assert shortcuts or not start  # the array path's usual case was compared


def test_gauge_sensor_reading(martens_10_250):
    """A gauge sensor's 300 kPa read as absolute loses 101 kPa, about 81 N on a
    DMSP-10-250 at L0 (0.8 N/kPa); with pressure_reference gauge it is served at 300 kPa gauge, and
    a command comes back in gauge.
    """
    served = {}
    for reference in ('absolute', 'gauge'):
        engine = Engine([Config(martens_10_250, AMBIENT, 0.1, reference)])
        feed_length(engine, 0.25, 0.0, stamp=1.0, now=1.0)
        served[reference] = feed_pressure(engine, 300e3, stamp=1.0, now=1.0)
        command = engine.command(
            0, served['gauge' if reference == 'gauge' else 'absolute'], ns(1.0)
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
        engine.pressures(pressures, ns(now), ns(now))
        engine.lengths(lengths, np.full(3, math.nan), ns(now), ns(now))
        if engine.status_due(ns(now)):
            engine.statuses(ns(now))
    assert not engine.status_due(ns(now)) and engine.levels(ns(now)).tolist() == [0, 0, 0]
    now += 0.2  # the lengths are now 0.2 s old
    assert not engine.pressures(pressures, ns(now), ns(now)).any()
    assert engine.status_due(ns(now))
    assert engine.level(0, ns(now))[1].startswith('stale muscle_state')


def test_status_due_when_a_fresh_but_older_stamp_goes_stale(martens_10_250):
    """Levels reported OK; a pressure arrives fresh but with a stamp older than those seen at the
    check: when it goes stale the change is due at once, not only at the next 1 Hz report.
    """
    engine = Engine([Config(martens_10_250, AMBIENT, 0.1)], hold=1.0)
    feed_pressure(engine, AMBIENT + P, stamp=10.0, now=10.0)
    feed_length(engine, L, None, stamp=10.0, now=10.0)
    assert engine.status_due(ns(10.0))
    engine.statuses(ns(10.0))
    assert not engine.status_due(ns(10.001))  # every level reported OK, nothing happened since
    feed_pressure(engine, AMBIENT + P, stamp=9.952, now=10.002)  # 50 ms old: fresh
    assert not engine.status_due(ns(10.002))
    feed_length(engine, L, None, stamp=10.06, now=10.06)  # the pressure is now 108 ms old
    assert engine.levels(ns(10.06)).tolist() == [Level.ERROR]
    assert engine.status_due(ns(10.06))


def test_on_change_reports_wait_for_the_report_interval(martens_10_250):
    engine = Engine([Config(martens_10_250, AMBIENT, 0.1)], report_interval=0.1)
    feed_length(engine, L, 0.0, stamp=1.0, now=1.0)
    assert engine.status_due(ns(1.0))
    engine.statuses(ns(1.0))  # ERROR: no pressure yet
    feed_pressure(engine, AMBIENT + P, stamp=1.05, now=1.05)  # OK now, 0.05 s after the report
    assert not engine.status_due(ns(1.05))
    feed_length(engine, L, 0.0, stamp=1.12, now=1.12)
    assert engine.status_due(ns(1.12))  # reported with the next input after 0.1 s


def test_each_input_rule_answers_alike_for_a_float_and_an_array():
    """The bounds the node, its float path and bag estimate share (one function each): absolute
    pressure in [0, 50 bar], a length in (0, max_length), a finite command, a stamp within
    max_input_age (exactly max_age is fresh), and a command stamp of 0 never stale.
    """
    bar = 1e5
    pressures = [-1.0, -0.0, 0.0, 3 * bar, 50 * bar, 50 * bar + 1, math.nan, math.inf]
    expected = [False, True, True, True, True, False, False, False]
    assert [bool(pressures_ok(p)) for p in pressures] == expected
    assert pressures_ok(np.array(pressures)).tolist() == expected
    lengths, limit = [0.0, 1e-9, 0.2, 0.3 - 1e-12, 0.3, math.nan, -math.inf], 0.3
    expected = [False, True, True, True, False, False, False]
    assert [bool(lengths_ok(x, limit)) for x in lengths] == expected
    assert lengths_ok(np.array(lengths), limit).tolist() == expected
    forces = [0.0, -5.0, 1e9, math.nan, math.inf, -math.inf]
    expected = [True, True, True, False, False, False]
    assert [bool(commands_ok(f)) for f in forces] == expected
    assert [command_problem(f) == '' for f in forces] == expected
    assert command_problem(math.nan) == 'force command is nan N'
    now, age = 10 * SECOND, SECOND // 10
    stamps = [now, now - age, now + age, now - age - 1, now + age + 1, NEVER, UNSTAMPED]
    assert [bool(fresh(s, now, age)) for s in stamps] == [True, True, True] + [False] * 4
    assert fresh(np.array(stamps), now, age).tolist() == [True, True, True] + [False] * 4
    stale = [False, False, False, True, True, True, False]
    assert [bool(stale_command_stamps(s, now, age)) for s in stamps] == stale
    assert stale_command_stamps(np.array(stamps), now, age).tolist() == stale


#: Raw values at and beyond the input rules' bounds: absolute pressures [Pa] around 0 and 50 bar,
#: and, named as each muscle has its own, around the gauge pressures served as they are (0 to the
#: highest identified; below 0, the vented band); lengths [m] around 0 and the geometry's limit,
#: and the rest length (where a force at 0 Pa may be above 0 N)
PRESSURE_EDGES = [math.nan, math.inf, -math.inf, -1.0, -0.0, 0.0, 5e6, 5e6 + 1]
PRESSURE_EDGES += ['vented', 'ambient', 'known', 'above known']
LENGTH_EDGES = [
    math.nan,
    math.inf,
    -math.inf,
    -1.0,
    -0.0,
    0.0,
    1e-9,
    'limit',
    'below limit',
    'rest',
]


def column(edges: list) -> st.SearchStrategy:
    """One message of every muscle: units (see :func:`_raw`; drawn as 1-tuples), one to three of
    them replaced by raw ``edges`` one time in four.
    """
    usual = st.lists(good.map(lambda u: (u,)), min_size=len(MODELS), max_size=len(MODELS))
    edits = st.lists(
        st.tuples(st.integers(0, len(MODELS) - 1), st.sampled_from(edges)), min_size=1, max_size=3
    )

    def edited(values: list, changes: list) -> list:
        for k, edge in changes:
            values[k] = edge
        return values

    return often(usual, st.builds(edited, usual, edits))


def _raw(kind: str, draw, config: Config) -> float:
    """A drawn value of ``config``'s muscle (a pressure as its sensor reads it: absolute or
    gauge): a unit across the identified gauge pressures or lengths (the usual message), or a raw
    edge.
    """
    model = config.model
    known, domain = model.limits.pressure_known, model.domain
    if kind == 'length':
        if isinstance(draw, tuple):
            return domain.length_min + draw[0] * (domain.length_max - domain.length_min)
        if type(draw) is float:
            return draw
        if draw == 'rest':
            return model.spec.nominal_length
        return model.max_length * {'limit': 1, 'below limit': 1 - 1e-15}[draw]
    if type(draw) is float:
        return draw
    gauge = {'vented': -5e3, 'ambient': 0.0, 'known': known, 'above known': known + 1e3}
    gauge = draw[0] * known if isinstance(draw, tuple) else gauge[draw]
    return config.ambient_pressure + gauge - config.reading_offset


def check_message(pressures: list, lengths: list, ambients: tuple, alike: int | None) -> None:
    """One message of each input of every muscle (draws as :func:`_raw` takes them), checked on
    its lowest and highest values first: which pressures and lengths it takes equals pressures_ok
    and lengths_ok value by value, and the forces it serves from them equal force_at's at the same
    inputs (bit for bit).  The muscles differ in pressure reference and ambient (``ambients``, in
    turn), and in model and geometry, or not (``alike``: an arm of MODELS[alike], where the tests
    on the lowest and highest pass).
    """
    models = MODELS if alike is None else [MODELS[alike]] * len(MODELS)
    configs = [
        Config(m, ambients[k % len(ambients)], 0.1, ('absolute', 'gauge')[k % 2])
        for k, m in enumerate(models)
    ]
    muscles = Muscles(configs)
    readings = np.array([_raw('pressure', d, c) for d, c in zip(pressures, configs)])
    absolute, ok, pressure_span = muscles.take_pressures(readings)
    offsets = np.array([c.reading_offset for c in configs])
    assert np.array_equal(absolute, readings + offsets, equal_nan=True)
    want = pressures_ok(readings + offsets)
    assert (ok is None) == want.all() and (ok is None or ok.tolist() == want.tolist())
    column = np.array([_raw('length', d, c) for d, c in zip(lengths, configs)])
    taken, span = muscles.take_lengths(column)
    want = lengths_ok(column, np.array([m.max_length for m in models]))
    assert (taken is None) == want.all() and (taken is None or taken.tolist() == want.tolist())
    assert span is None or span == (column.min(), column.max())
    if alike is not None and all(isinstance(d, tuple) for d in lengths):
        assert span is not None  # the usual message of an arm of one type takes the shortcut
    if ok is not None or taken is not None:
        return
    muscles.store_pressures(None, absolute, pressure_span)
    muscles.store_lengths(None, column, np.zeros(len(MODELS)), span)
    force, flags, has = muscles.forces(None)
    ambient = np.array([c.ambient_pressure for c in configs])
    with np.errstate(invalid='ignore', over='ignore'):
        want = force_at(muscles.bank.operating(column, np.zeros(len(MODELS))), absolute - ambient)
    usable = want.raw < math.inf
    assert usable.all() if has is None else has.tolist() == usable.tolist()
    assert force[usable].tolist() == want.force[usable].tolist()
    assert flags.tolist() == want.flags.tolist()


def test_each_edge_of_a_message_is_decided_as_the_elementwise_rules():
    """:func:`check_message` of every raw edge alone in a usual message (at the identified
    lengths' middle and longest: wickramatunge's force at 0 Pa is above 0 N there), at a muscle
    reading absolute pressures and at one reading gauge, in a mixed arm and in arms of one type.
    """
    for alike, k, ambients, unit in itertools.product(
        (None, 0, 3, 4, len(MODELS) - 1), (0, 1), ((AMBIENT,), (AMBIENT, 95e3)), (0.5, 1.0)
    ):
        pressures, lengths = [(0.5,)] * len(MODELS), [(unit,)] * len(MODELS)
        for edge in PRESSURE_EDGES:
            check_message(pressures[:k] + [edge] + pressures[k + 1 :], lengths, ambients, alike)
        for edge in LENGTH_EDGES:
            check_message(pressures, lengths[:k] + [edge] + lengths[k + 1 :], ambients, alike)


@examples(300)
@given(
    pressures=column(PRESSURE_EDGES),
    lengths=column(LENGTH_EDGES),
    ambients=st.sampled_from([(AMBIENT,), (AMBIENT, 95e3)]),
    alike=st.one_of(st.none(), st.integers(0, len(MODELS) - 1)),
)
def test_a_messages_lowest_and_highest_decide_as_the_elementwise_rules(
    pressures, lengths, ambients, alike
):
    """:func:`check_message` of random messages: usual values, some raw edges among them."""
    check_message(pressures, lengths, ambients, alike)
