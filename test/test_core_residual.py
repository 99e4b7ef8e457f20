"""core/runtime/residual.py: measured - served forces, their window figures and the drift level,
against hand-calculated numbers.
"""

import math

import numpy as np
import pytest

from pma_model_ros.core.identification.validation import HeldOutBand
from pma_model_ros.core.physics.flags import Flag
from pma_model_ros.core.runtime.health import Level
from pma_model_ros.core.runtime.residual import (
    Figures,
    MIN_SAMPLES,
    next_level,
    Residuals,
    Thresholds,
)

S = 1_000_000_000  # [ns]
MAX_FORCE = 1000.0  # [N]
#: held-out err [%] at 0.25, 0.24, 0.23, 0.22 m: interior (0.24, 0.23) 5 %, edge (0.25, 0.22) 8 %
BAND = HeldOutBand((0.25, 0.24, 0.23, 0.22), (6.0, 4.0, 5.0, 8.0), MAX_FORCE)
AGE = 500_000_000  # [ns] max_input_age


def monitor(**thresholds) -> Residuals:
    return Residuals([BAND], [6e5], ['martens'], AGE, Thresholds(**thresholds))


def feed(r, samples, start=0, period=S // 100, length=0.235, flags=0):
    """(served [N], measured [N]) pairs at 100 Hz from ``start`` [ns]; the last stamp."""
    t = start
    for served, measured in samples:
        r.served(0, t, served, 3e5, length, flags)
        r.measured(0, t, measured, t)
        t += period
    return t - period


def test_a_constant_bias_of_5_percent_is_bias_rms_and_worst_5_within_a_5_percent_band():
    r = monitor()
    now = feed(r, [(100.0, 150.0)] * 50)  # +50 N of 1000 N
    f = r.figures(0, now)
    assert (f.samples, f.interior) == (50, 50)
    assert f.bias == pytest.approx(5) and f.rms == pytest.approx(5)
    assert f.worst == pytest.approx(5) and f.band == pytest.approx(5)  # 0.235 m: interior
    level, message, _ = r.report(0, now)
    assert (level, message) == (Level.OK, '')  # RMS = band: within it


def test_residuals_of_3_and_minus_4_percent():
    r = monitor()
    now = feed(r, [(200.0, 230.0), (200.0, 160.0)] * 10)
    f = r.figures(0, now)
    assert f.bias == pytest.approx(-0.5)
    assert f.rms == pytest.approx(math.sqrt((9 + 16) / 2))
    assert f.worst == pytest.approx(-4)


def test_above_the_band_warns_with_the_refit_command_and_above_twice_it_errs():
    r = monitor()
    now = feed(r, [(100.0, 160.0)] * 20)  # 6 % against 5 %
    level, message, _ = r.report(0, now)
    assert level == Level.WARN
    assert message.startswith('model drift: residual 6 % over the last 0.19 s against a band of')
    assert message.endswith(
        '5 %: refit: pma-model fit --bag <recording> --muscle <spec.yaml> '
        '--model martens --out <parameters.yaml>'
    )
    r = monitor()
    now = feed(r, [(100.0, 210.0)] * 20)  # 11 % > 2 x 5 %
    assert r.report(0, now)[0] == Level.ERROR
    assert r.values(0, r.figures(0, now))['residual level'] == 'ERROR'


def test_the_level_does_not_flap_within_the_hysteresis():
    # warn at ratio 1, leave below 0.8; error at 2, leave below 1.6
    ratios = [1.1, 0.9, 1.05, 0.81, 0.99, 0.79, 0.95, 2.1, 1.7, 1.61, 1.5, 0.85, 0.5]
    want = [
        'WARN',
        'WARN',
        'WARN',
        'WARN',
        'WARN',
        'OK',
        'OK',
        'ERROR',
        'ERROR',
        'ERROR',
        'WARN',
        'WARN',
        'OK',
    ]
    level, got = Level.OK, []
    for ratio in ratios:
        level = next_level(level, ratio, 1.0, 2.0, 0.2)
        got.append(level.name)
    assert got == want


def test_a_residual_oscillating_around_the_band_warns_once_and_stays():
    r = monitor()
    t, levels = 0, []
    for step in range(40):  # window RMS alternates 5.5 % and 4.5 % against 5 %: ratio 1.1, 0.9
        measured = 155.0 if step % 2 == 0 else 145.0
        t = feed(r, [(100.0, measured)] * 100, start=t + S // 100)
        levels.append(r.report(0, t)[0])
    assert levels[0] == Level.WARN and set(levels) == {Level.WARN}


def test_bad_measured_forces_are_refused_counted_and_never_enter_the_window():
    r = monitor()
    for k in range(MIN_SAMPLES - 1):
        r.served(0, k, 100.0, 3e5, 0.235, 0)
        assert r.measured(0, k, 150.0, k) == (3e5, 0.235, 150.0)
    t = MIN_SAMPLES
    r.served(0, t, 100.0, 3e5, 0.235, 0)
    for bad in (math.nan, math.inf, -101.0, 2001.0):  # outside [-10 %, 200 %] of 1000 N
        assert r.measured(0, t, bad, t) is None
    assert r.measured(0, t, 150.0, t + AGE + 1) is None  # stale
    assert r.measured(0, t + 1, 150.0, t + 1) is None  # no estimate of its stamp
    assert r.counts[0] == {'paired': MIN_SAMPLES - 1, 'rejected': 5, 'unpaired': 1, 'unjudged': 0}
    assert r.last_problem[0].startswith('stale measured force')
    assert r.figures(0, t) is None  # 9 samples: too few to judge
    assert r.measured(0, t, 150.0, t) is not None
    assert r.figures(0, t).samples == MIN_SAMPLES


def test_each_sample_is_judged_by_the_band_at_its_length_and_pressure():
    r = monitor()
    feed(r, [(100.0, 150.0)] * 10, length=0.26)  # beyond the measured lengths: edge 8 %
    feed(r, [(100.0, 150.0)] * 10, start=S, flags=Flag.LENGTH_OUT_OF_RANGE)  # held: edge
    now = feed(r, [(100.0, 150.0)] * 10, start=2 * S)  # interior 5 %
    f = r.figures(0, now)
    assert (f.samples, f.interior) == (30, 10) and f.band == pytest.approx((8 + 8 + 5) / 3)
    r.served(0, now + 1, 100.0, 6.5e5, 0.235, 0)  # above the identified 600 kPa
    assert r.measured(0, now + 1, 150.0, now + 1) is None
    assert r.counts[0]['unjudged'] == 1


def test_the_window_holds_the_last_window_seconds():
    r = monitor(window=1.0)
    feed(r, [(100.0, 300.0)] * 100)  # 20 % during the first second
    now = feed(r, [(100.0, 150.0)] * 100, start=2 * S)  # 5 % during the third
    assert r.figures(0, now).rms == pytest.approx(5)


def test_the_later_estimate_of_one_stamp_is_the_one_paired():
    r = monitor()
    r.served(0, 7, 90.0, 2e5, 0.23, 0)  # the pressure of stamp 7 with an older length
    r.served(0, 7, 100.0, 3e5, 0.235, 0)  # its length too
    assert r.measured(0, 7, 150.0, 7) == (3e5, 0.235, 150.0)


def test_a_muscle_without_held_out_errors_is_not_monitored():
    r = Residuals([None], [6e5], ['martens'], AGE)
    r.served(0, 0, 100.0, 3e5, 0.235, 0)
    assert r.measured(0, 0, 150.0, 0) is None
    assert r.values(0, None) == {'residual': 'unknown: the parameter file has no held_out errors'}


def test_a_described_window_parses_back_to_its_three_digits():
    """What /diagnostics carries is read back (``pma-model plot drift``): the line, to its 3
    significant digits.
    """
    text = (
        'bias -1.23 %, RMS 3.46 %, worst -8.77 % over 1234 samples in 9.99 s; band 4.66 % '
        '(1000 interior, 234 edge)'
    )
    assert Figures.parse(text) == Figures(1234, 9.99, -1.23, 3.46, -8.77, 4.66, 1000)
    assert Figures(1234, 9.99, -1.23456, 3.4567, -8.7654, 4.6575, 1000).describe() == text
    assert Figures.parse('too few samples in the window') is None


def test_many_muscles_at_once_are_judged_as_one_at_a_time():
    """One combined message of six muscles: a sample inside the band's lengths, one beyond them,
    one held (LENGTH_OUT_OF_RANGE: the edge figure), one above the identified pressures
    (unjudged), a NaN (refused) and one without an estimate of its stamp (unpaired); the
    muscle-by-muscle path counts and keeps the same.
    """
    t = 5 * S
    rows = [  # served [N], gauge [Pa], length [m], flags, measured [N], estimated at t
        (100.0, 3e5, 0.235, 0, 150.0, True),
        (100.0, 3e5, 0.255, 0, 90.0, True),
        (100.0, 3e5, 0.26, Flag.LENGTH_OUT_OF_RANGE, 110.0, True),
        (100.0, 7e5, 0.235, 0, 150.0, True),
        (100.0, 3e5, 0.235, 0, math.nan, True),
        (100.0, 3e5, 0.235, 0, 150.0, False),
    ]
    n = len(rows)
    one, many = (Residuals([BAND] * n, [6e5] * n, ['martens'] * n, AGE) for _ in range(2))
    for k, (served, gauge, length, flags, _, now) in enumerate(rows):
        one.served(k, t if now else t - S // 100, served, gauge, length, flags)
    # the combined path keeps the estimates as arrays (one served_all per stamp)
    columns = [np.array(c) for c in zip(*rows)]
    served, gauge, length, flags, _, now = columns
    flags = flags.astype(np.uint16)
    for stamp, which in ((t - S // 100, ~now.astype(bool)), (t, now.astype(bool))):
        many.served_all(stamp, which, served, gauge, length, flags)
    taken = [one.measured(k, t, row[4], t) for k, row in enumerate(rows)]
    taken_all = many.measured_all(np.arange(n), t, np.array([r[4] for r in rows]), t)
    assert list(zip(*(a.tolist() for a in taken_all))) == [
        (k, *sample) for k, sample in enumerate(taken) if sample is not None
    ]
    assert [k for k, s in enumerate(taken) if s is not None] == [0, 1, 2]
    assert one.counts == many.counts
    assert many.counts[3:] == [
        {'paired': 0, 'rejected': 0, 'unpaired': 0, 'unjudged': 1},
        {'paired': 0, 'rejected': 1, 'unpaired': 0, 'unjudged': 0},
        {'paired': 0, 'rejected': 0, 'unpaired': 1, 'unjudged': 0},
    ]
    # +5 % inside (5 % band), -1 % beyond the lengths and +1 % held (8 % edge band)
    for r in (one, many):
        kept = [(r._residuals[k, 0], r._bands[k, 0], r._inside[k, 0]) for k in range(3)]
        assert kept == [
            pytest.approx([5.0, 5.0, 1.0]),
            pytest.approx([-1.0, 8.0, 0.0]),
            pytest.approx([1.0, 8.0, 0.0]),
        ]
    # a stale stamp (1 s old against 0.5 s) and a force beyond twice the max force: refused alike
    assert one.measured(0, t, 150.0, t + S) is None
    assert not many.measured_all(np.array([0]), t, np.array([150.0]), t + S)[0].size
    assert one.measured(1, t, 2500.0, t) is None
    assert not many.measured_all(np.array([1]), t, np.array([2500.0]), t)[0].size
    assert one.counts == many.counts and one.last_problem == many.last_problem
    assert one.last_problem[0] == 'stale measured force: stamp 1 s from now'


def test_a_combined_message_of_every_muscle_is_judged_as_one_at_a_time(monkeypatch):
    """The combined input's usual message (every muscle monitored, each force taken and paired
    with the estimate of the newest stamp, or of the one before when it arrives after the next
    inputs' estimate) takes :meth:`Residuals._measured_every`; its samples are the
    muscle-by-muscle path's: +5 % inside the held-out lengths (5 % band), -1 % beyond them and
    +1 % held (8 % edge band), of 1000 N.
    """
    ms = S // 1000
    rows = [  # served [N], gauge [Pa], length [m], flags, measured [N]
        (100.0, 3e5, 0.235, 0, 150.0),
        (100.0, 3e5, 0.255, 0, 90.0),
        (100.0, 3e5, 0.26, int(Flag.LENGTH_OUT_OF_RANGE), 110.0),
    ]
    n = len(rows)
    one, many = (Residuals([BAND] * n, [6e5] * n, ['martens'] * n, AGE) for _ in range(2))
    served, gauge, length, flags, measured = (np.array(c) for c in zip(*rows))
    flags = flags.astype(np.uint16)
    every = []
    judged_every = many._measured_every
    monkeypatch.setattr(
        many, '_measured_every', lambda *a: every.append(judged_every(*a)) or every[-1]
    )
    t = 5 * S
    for estimated, stamp in (
        ((t,), t),
        ((t + ms,), t + ms),
        ((t + 2 * ms, t + 3 * ms), t + 2 * ms),
    ):
        for s in estimated:
            for k, row in enumerate(rows):
                one.served(k, s, *row[:4])
            many.served_all(s, None, served, gauge, length, flags)
        now = estimated[-1]
        taken = [one.measured(k, stamp, row[4], now) for k, row in enumerate(rows)]
        taken_all = many.measured_all(np.arange(n), stamp, measured, now)
        assert list(zip(*(a.tolist() for a in taken_all))) == [
            (k, *sample) for k, sample in enumerate(taken)
        ]
    assert len(every) == 3 and all(e is not None for e in every)  # the fast path, every time
    assert (
        one.counts
        == many.counts
        == [{'paired': 3, 'rejected': 0, 'unpaired': 0, 'unjudged': 0}] * n
    )
    for r in (one, many):
        for slot in range(3):
            kept = [
                (r._residuals[k, slot], r._bands[k, slot], r._inside[k, slot]) for k in range(n)
            ]
            assert kept == [
                pytest.approx([5.0, 5.0, 1.0]),
                pytest.approx([-1.0, 8.0, 0.0]),
                pytest.approx([1.0, 8.0, 0.0]),
            ]


def test_a_measured_force_pairs_with_the_newest_estimate_of_its_stamp():
    """Estimates stamped s, s + 1 ms, s again (the inputs' stamps went back) and s + 2 ms: a
    measured force stamped s, arriving after all four, is judged against the second estimate of
    s (served 200 N: +5 % of 1000 N at 250 N), on both paths; one of a stamp no longer estimated
    (s - 1 ms) is unpaired.
    """
    t, ms = 5 * S, S // 1000
    one, many = (Residuals([BAND] * 2, [6e5] * 2, ['martens'] * 2, AGE) for _ in range(2))
    for stamp, force in ((t, 100.0), (t + ms, 300.0), (t, 200.0), (t + 2 * ms, 400.0)):
        for k in range(2):
            one.served(k, stamp, force, 3e5, 0.235, 0)
        many.served_all(
            stamp, None, *(np.full(2, v) for v in (force, 3e5, 0.235)), np.zeros(2, np.uint16)
        )
    now = t + 3 * ms
    assert one.measured(0, t, 250.0, now) == (3e5, 0.235, 250.0)
    taken = many.measured_all(np.arange(2), t, np.full(2, 250.0), now)
    assert taken[0].tolist() == [0, 1] and taken[3].tolist() == [250.0, 250.0]
    assert one._residuals[0, 0] == pytest.approx(5.0)
    assert many._residuals[:, 0] == pytest.approx([5.0, 5.0])
    assert one.measured(0, t - ms, 250.0, now) is None
    assert not many.measured_all(np.arange(2), t - ms, np.full(2, 250.0), now)[0].size
    assert (
        one.counts[0]['unpaired'] == 1
        and many.counts == [{'paired': 1, 'rejected': 0, 'unpaired': 1, 'unjudged': 0}] * 2
    )


def test_a_sample_arriving_late_is_in_the_window_of_the_ones_it_came_with():
    """The window starts at the first sample, in arrival order, stamped inside it: one stamped
    0.2 s before the window that arrives 0.4 s old (under the 0.5 s max input age) among samples
    inside it is counted with them; one that arrived before them is not.
    """
    r = monitor(window=1.0)
    for stamp, arrival, offset in ((0, 0, 200.0), (16, 16, 50.0), (13, 17, 50.0)):  # [0.1 s]
        r.served(0, stamp * S // 10, 100.0, 3e5, 0.235, 0)
        r.measured(0, stamp * S // 10, 100.0 + offset, arrival * S // 10)
    feed(r, [(100.0, 150.0)] * (MIN_SAMPLES - 2), start=2 * S)
    f = r.figures(0, 2 * S + S // 2)  # the window: from 1.5 s on
    # every sample but the first (+20 %, stamped 0 s): +5 % each, the oldest stamped 1.3 s
    assert f.samples == MIN_SAMPLES and f.rms == pytest.approx(5)
    assert f.span == pytest.approx(2.5 - 1.3)
