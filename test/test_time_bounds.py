"""conftest.py's bounds: a test that hangs, or an rclpy teardown that deadlocks while it holds the
GIL (Fast DDS's destroy_participant), ends its pytest process with every thread's stack instead of
stalling the run; spin_until's deadline counts the time the test had a CPU.

Each case runs pytest in a process of its own on a file that uses this conftest.py.
"""

import os
import re
import subprocess
import sys
import time

import pytest

from conftest import REPO, RunClock

#: A regular expression that backtracks for minutes inside the re module's C code, holding the
#: GIL as a deadlocked destroy_participant does: no Python thread (pytest-timeout's) runs then.
HOLDS_THE_GIL = "re.match(r'(a+)+$', 'a' * 40 + 'b')"

CASES = {
    'a test over its bound': (
        'import time\n'
        'import pytest\n'
        '@pytest.mark.time_bound(2)\n'
        'def test_hangs():\n'
        '    time.sleep(600)\n'
    ),
    'a failed test whose teardown hangs': (
        'import time\n'
        'import pytest\n'
        '@pytest.fixture\n'
        'def hangs_after():\n'
        '    yield\n'
        '    time.sleep(600)\n'
        '@pytest.mark.time_bound(2)\n'
        'def test_fails(hangs_after):\n'
        '    assert False\n'
    ),
    'a teardown that holds the GIL': (
        'import re\n'
        'import conftest\n'
        'def test_teardown_deadlocks(monkeypatch):\n'
        "    monkeypatch.setattr(conftest, 'ROS_TEARDOWN_BOUND', 2.0)\n"
        '    with conftest.bounded_ros_teardown():\n'
        f'        {HOLDS_THE_GIL}\n'
    ),
}


@pytest.mark.parametrize('case', CASES)
def test_a_hang_ends_the_process_with_the_stacks(tmp_path, case):
    (tmp_path / 'conftest.py').symlink_to(REPO / 'test' / 'conftest.py')
    (tmp_path / 'test_case.py').write_text(CASES[case])
    began = time.monotonic()
    run = subprocess.run(
        [sys.executable, '-m', 'pytest', '-p', 'no:cacheprovider', '-n0', '-q', 'test_case.py'],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env={k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'},  # colcon test's
    )
    took = time.monotonic() - began
    assert run.returncode == 1, run.stdout + run.stderr
    assert re.search(r'^Timeout \(0:00:0[12][.0-9]*\)!$', run.stderr, re.M), run.stderr
    assert 'test_case.py' in run.stderr, run.stderr  # the hung test's frame
    assert took < 60, took  # the process start and the 2 s bound, not the hang


def test_the_run_clock_leaves_out_the_wait_for_a_cpu():
    """This thread and three busy processes on one CPU: it runs about a quarter of the time, and
    the clock counts about that much of the wall time.
    """
    mask = os.sched_getaffinity(0)
    cpu = min(mask)
    spin = f'import os; os.sched_setaffinity(0, {{{cpu}}}); [0 for _ in iter(int, 1)]'
    busy = [subprocess.Popen([sys.executable, '-c', spin]) for _ in range(3)]
    os.sched_setaffinity(0, {cpu})
    try:
        time.sleep(0.5)  # the three started
        clock = RunClock()
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            pass
        ran, wall = clock(), time.monotonic() - clock.start
    finally:
        os.sched_setaffinity(0, mask)
        for process in busy:
            process.kill()
            process.wait()
    assert 0 < ran < 0.5 * wall, (ran, wall)
