"""What a node logs of its faults (core/runtime/health.py, FaultLog): one line per cause at most
every second, naming the muscles or joints that have it.
"""

from pma_model_ros.core.runtime.health import FaultLog, Level
from pma_model_ros.core.runtime.pairing import SECOND

NAN = 'invalid input: pressure is NaN'


def test_one_line_per_cause_and_second():
    log = FaultLog()
    entries = [('biceps', Level.ERROR, NAN), ('triceps', Level.OK, 'estimating')]
    assert log.lines(entries, 0) == [(Level.ERROR, f'biceps: {NAN}')]
    assert log.lines(entries, SECOND - 1) == []  # the same cause within the second
    assert log.lines(entries, SECOND) == [(Level.ERROR, f'biceps: {NAN}')]


def test_causes_are_logged_apart_and_muscles_together():
    log = FaultLog()
    stale = 'stale pressure: newest stamp is 0.5 s old (max_input_age 0.1 s)'
    entries = [
        ('a', Level.ERROR, NAN),
        ('b', Level.ERROR, 'invalid input: pressure is -3e+05 Pa absolute'),
        ('c', Level.ERROR, stale),
        ('d', Level.WARN, 'saturated (SATURATED)'),
    ]
    assert log.lines(entries, 0) == [
        (Level.ERROR, f'a, b: {NAN}'),
        (Level.ERROR, f'c: {stale}'),
        (Level.WARN, 'd: saturated (SATURATED)'),
    ]
    assert log.lines([('e', Level.WARN, 'answers late: 31 ms')], 1) == [
        (Level.WARN, 'e: answers late: 31 ms')
    ]


def test_many_muscles_are_counted_not_listed():
    entries = [(f'm{k}', Level.ERROR, NAN) for k in range(64)]
    [(level, line)] = FaultLog().lines(entries, 0)
    assert line == f'm0, m1, m2, m3, m4 and 59 more: {NAN}'


def test_a_clock_that_goes_back_logs_again():
    """Sim time restarted (a bag replayed again): the throttle does not wait for the old time."""
    log = FaultLog()
    entries = [('a', Level.ERROR, NAN)]
    assert log.lines(entries, 100 * SECOND)
    assert log.lines(entries, 5 * SECOND)
