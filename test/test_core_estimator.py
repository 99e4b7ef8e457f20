"""The message-independent estimator: validation, pairing, freshness, commands, diagnostics (no rclpy)."""
import math

import pytest

from pma_model_ros.core.estimator import Config, Estimator, Level
from pma_model_ros.core.flags import Flag

AMBIENT = 101325.0
P = 300e3          # gauge [Pa]
L = 0.23           # [m]


@pytest.fixture
def est(martens_10_250):
    return Estimator(Config(martens_10_250, AMBIENT, max_input_age=0.1), hold=1.0)


def test_estimate_needs_both_inputs_and_pairs_the_newest(est, martens_10_250):
    assert est.pressure(AMBIENT + P, stamp=10.0, now=10.0) is None
    e = est.estimate(est.length(L, 0.0, stamp=10.01, now=10.01, tag="stamp-b"), 10.01)
    assert e.force == pytest.approx(float(martens_10_250.force(P, L).force))
    assert (e.stamp, e.tag) == (10.01, "stamp-b")
    e = est.estimate(est.pressure(AMBIENT + 2 * P, stamp=10.02, now=10.02, tag="stamp-c"), 10.02)
    assert e.force == pytest.approx(float(martens_10_250.force(2 * P, L).force))
    assert (e.stamp, e.tag) == (10.02, "stamp-c")
    assert est.counts["estimates"] == 2


def test_stale_input_gives_no_estimate_and_error(est):
    est.pressure(AMBIENT + P, stamp=10.0, now=10.0)
    assert est.length(L, 0.0, stamp=10.2, now=10.2) is None   # pressure is 0.2 s old
    assert est.counts["stale skipped"] == 1
    level, message = est.level(10.2)
    assert level == Level.ERROR and "stale pressure" in message
    assert est.length(L, 0.0, stamp=10.0, now=10.3) is None   # length itself too old
    assert est.pressure(AMBIENT + P, stamp=11.0, now=10.0) is None  # stamp from the future


@pytest.mark.parametrize("absolute, words", [(math.nan, "nan"), (-1.0, "negative"), (6e6, "absurd"),
                                              (math.inf, "inf")])
def test_bad_pressure_rejected(est, absolute, words):
    est.estimate(est.length(L, 0.0, stamp=1.0, now=1.0), 1.0)
    est.estimate(est.pressure(AMBIENT + P, stamp=1.0, now=1.0), 1.0)
    assert est.pressure(absolute, stamp=1.01, now=1.01) is None
    assert est.counts["rejected pressure"] == 1
    level, message = est.level(1.01)
    assert level == Level.ERROR and words in message.lower()
    assert est.level(2.5)[0] == Level.ERROR            # inputs stale by then
    est.estimate(est.pressure(AMBIENT + P, stamp=2.5, now=2.5), 2.5)
    est.estimate(est.length(L, 0.0, stamp=2.5, now=2.5), 2.5)
    assert est.level(2.5) == (Level.OK, "estimating")  # the rejection no longer holds


@pytest.mark.parametrize("length", [math.nan, 0.0, -0.1, 0.3])
def test_bad_length_rejected(est, length):
    est.pressure(AMBIENT + P, stamp=1.0, now=1.0)
    assert est.length(length, 0.0, stamp=1.0, now=1.0) is None
    assert est.counts["rejected muscle_state"] == 1


def test_message_level_rejection_counts(est):
    est.reject("muscle_state", "joint 'x' not in ['y']", now=1.0)
    assert est.counts["received muscle_state"] == est.counts["rejected muscle_state"] == 1
    assert est.level(1.0) == (Level.ERROR, "invalid input: joint 'x' not in ['y']")


def test_estimates_are_never_nan_and_nonnegative(est):
    est.pressure(AMBIENT, stamp=1.0, now=1.0)                 # 0 Pa gauge: slack muscle
    e = est.estimate(est.length(0.2, 0.0, stamp=1.0, now=1.0), 1.0)
    assert e.force == 0.0 and e.flags & Flag.CLIPPED


def test_warning_for_outside_domain_and_unknown_branch():
    from pma_model_ros.core.sarosi import dmsp_10_100_hysteresis
    est = Estimator(Config(dmsp_10_100_hysteresis(), AMBIENT, 0.1))
    est.pressure(AMBIENT + 3e5, stamp=1.0, now=1.0)
    e = est.estimate(est.length(0.09, None, stamp=1.0, now=1.0), 1.0)
    assert e.flags & Flag.BRANCH_UNKNOWN
    level, message = est.level(1.0)
    assert level == Level.WARN and "hysteresis branch unknown" in message
    est.estimate(est.length(0.09, 0.01, stamp=2.05, now=2.05), 2.05)
    est.estimate(est.pressure(AMBIENT + 3e5, stamp=2.1, now=2.1), 2.1)
    assert est.level(2.1)[0] == Level.OK                      # warning held for 1 s only
    est.estimate(est.pressure(AMBIENT + 9e5, stamp=2.12, now=2.12), 2.12)
    level, message = est.level(2.12)
    assert level == Level.WARN and "outside validity domain" in message


def test_command_inverts_the_model(est, martens_10_250):
    assert est.command(100.0, now=1.0) is None                # no length yet
    est.length(L, 0.0, stamp=1.0, now=1.0)
    cmd = est.command(100.0, now=1.05)
    gauge = cmd.pressure - AMBIENT
    assert float(martens_10_250.force(gauge, L).force) == pytest.approx(100.0, abs=1e-6)
    assert est.command(1e5, now=1.05).flags & Flag.SATURATED
    assert est.level(1.05)[0] == Level.ERROR                  # pressure never received
    assert est.command(math.nan, now=1.05) is None and est.counts["rejected force_command"] == 1
    assert est.command(100.0, now=1.2) is None                # length now stale


def test_config_swap_and_status(est, martens_10_250):
    from pma_model_ros.core.param_file import muscle_model, read_parameters
    from conftest import CONFIGS
    est.pressure(AMBIENT + P, stamp=1.0, now=1.0)
    first = est.estimate(est.length(L, 0.0, stamp=1.0, now=1.0), 1.0).force
    est.config = Config(muscle_model(read_parameters(CONFIGS["DMSP-10-250"]), "sarosi"), AMBIENT, 0.1)
    second = est.estimate(est.length(L, 0.0, stamp=1.01, now=1.01), 1.01).force
    assert first != second
    est.status(1.0)
    status = est.status(2.0)
    assert status.values["model"] == "sarosi" and status.values["estimates"] == "2"
    assert float(status.values["estimates rate [Hz]"]) == pytest.approx(0.0)
