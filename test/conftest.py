"""Shared fixtures: identified muscles; for the node tests the colcon install, node processes
and a private rclpy context per test.
"""

import contextlib
import faulthandler
import math
import os
from pathlib import Path
import subprocess
import sys
import time
from typing import Callable
import uuid

import numpy as np
import pytest

from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.tools import node_process

REPO = Path(__file__).resolve().parents[1]
CONFIGS = {
    'DMSP-10-250': REPO / 'config' / 'dmsp_10_250.yaml',
    'DMSP-20-300': REPO / 'config' / 'dmsp_20_300.yaml',
    'DMSP-10-100': REPO / 'config' / 'dmsp_10_100.yaml',
}


@pytest.fixture
def martens_10_250():
    return muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'martens')


def with_martens_end(parameters: dict, end_factor: float = 1.09) -> dict:
    """``parameters`` of a shipped config with a ``martens_end`` block (which ``make-config`` does
    not write): its Martens block with the end factor ``end_factor`` appended.
    """
    models = parameters['models']
    if 'martens' in models:
        martens = models['martens']
        models['martens_end'] = {**martens, 'params': [*martens['params'], end_factor]}
    return parameters


#: A bound on the rounding error of a force computed by hand from a model's equation, in unit
#: roundoffs (eps/2) of the sum of its terms' magnitudes: about ten roundings of products and sums,
#: and a cube root or exponential of up to 4 ulp (numpy's SIMD routines on AVX-512 machines; libm's
#: within 1 ulp).  The same force on two machines, or on numpy's and the float path, differs by up
#: to twice this: an error 10⁵ times a double's rounding of the force where eq. 20's terms reach
#: 10⁷ N and cancel to hundreds (DMSP-20-300).
ROUNDINGS = 16
UNIT_ROUNDOFF = float(np.finfo(float).eps) / 2


def force_terms(muscle, p: float, length: float) -> float:
    """The sum of the magnitudes [N] of the terms of ``muscle``'s force at gauge ``p`` [Pa] and
    ``length`` [m]: Hildebrandt's eq. 20, Sárosi's eq. 19 (the larger of the two hysteresis
    branches); of any other model, whose coefficients cancel no large terms, those of
    F = (q2 p + q1) p + q0.
    """
    theta, name = np.abs(np.asarray(muscle.theta, float)), muscle.model.name
    if name == 'hildebrandt':
        c, d = theta[:3], theta[3:]
        return (
            p * (c @ length ** np.arange(3))
            + d[:4] @ length ** np.arange(4)
            + d[4] * (length ** (2 / 3))
        )
    if name in ('sarosi', 'sarosi_hysteresis'):
        kappa = abs(muscle.spec.nominal_length - length) / muscle.spec.nominal_length
        return max(
            (c0 * p + c1) * math.exp(c2 * kappa) + p * (d0 * kappa + d1) + d2
            for c0, c1, c2, d0, d1, d2 in theta.reshape(-1, 6)
        )
    op = muscle.operating(length)
    return float(abs(op.q2) * p * p + abs(op.q1) * p + abs(op.q0))


def force_rounding(muscle, p: float, length: float) -> float:
    """A bound [N] on the rounding error of ``muscle``'s force at ``p`` [Pa], ``length`` [m]."""
    return ROUNDINGS * UNIT_ROUNDOFF * force_terms(muscle, p, length)


def central_difference(
    f: Callable[[float], float], x: float, error: float, h: float = 1e-3
) -> tuple[float, float]:
    """f'(x) and a bound on its error, for an ``f`` whose values are off by at most ``error``.

    Richardson's R(h) = (4 D(h) - D(2h)) / 3 of the central differences D(h) = (f(x + h) -
    f(x - h)) / 2h: its rounding is at most 1.5 error / h, its truncation a h⁴ with
    R(2h) - R(h) = 15 a h⁴ + (their roundings, at most 2.25 error / h).
    """

    def difference(step):
        return (f(x + step) - f(x - step)) / (2 * step)

    d1, d2, d4 = difference(h), difference(2 * h), difference(4 * h)
    r1, r2 = (4 * d1 - d2) / 3, (4 * d2 - d4) / 3
    rounding = error / h
    return r1, 1.5 * rounding + (abs(r2 - r1) + 2.25 * rounding) / 15


#: What the lint tests check (test_lint.py: ruff; test_flake8.py, test_pep257.py: ament's).
LINT_PATHS = ['pma_model_ros', 'test', 'bench', 'launch', 'setup.py']


def ruff_config() -> dict:
    """``ruff.toml``, the lint rules (tomllib imported here: Jazzy's flake8-import-order 0.18
    takes it for a third-party module).
    """
    import tomllib

    return tomllib.loads((REPO / 'ruff.toml').read_text())


#: In the reason of a test skipped for a missing pip-only library (rosbags, ruff: -pip rosdep keys;
#: requirements-dev.txt).  scripts/test installs them and sets PMA_TEST_ALL_LIBRARIES=1: there
#: such a skip fails the run.
PIP_ONLY = 'a pip-only library'
_skipped_for_libraries: list[str] = []


def pytest_configure(config):
    """Under pytest-xdist (``scripts/test`` runs two workers per core), each worker in a DDS domain
    of its own (1..100, from the run's), so that one worker's nodes and /diagnostics never reach
    another's tests.  The watchdog's stream: a copy of stderr, which outlives output capture.
    """
    # as scripts/netns-run, for a run outside it (`colcon test`): this host only, a domain of
    # the run's own, so that neither the robot's nodes nor another run's reach the tests
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    worker = os.environ.get('PYTEST_XDIST_WORKER')  # gw0, gw1, ...
    if worker:
        run = int(os.environ.get('ROS_DOMAIN_ID', '0'))
        os.environ['ROS_DOMAIN_ID'] = str(1 + (run + int(worker.removeprefix('gw'))) % 100)
    config.addinivalue_line(
        'markers',
        'time_bound(seconds): this test bound by seconds, not TEST_BOUND (conftest.py)',
    )
    try:
        _watchdog['stream'] = os.dup(sys.stderr.fileno())
    except (AttributeError, ValueError):  # pytest-xdist's worker stderr is no file
        _watchdog['stream'] = os.dup(sys.__stderr__.fileno())


#: Every test (set-up, call, teardown) ends within this many seconds [s], or its process prints
#: every thread's stack and exits with code 1 (a pytest-xdist worker is then replaced; a plain
#: pytest run, e.g. `colcon test`'s, ends failed): a hang cannot stall a run.  faulthandler's
#: watchdog thread needs no GIL, which a deadlock in C (Fast DDS's, below) may hold.
TEST_BOUND = 600.0
#: The longest an in-process rclpy teardown may take [s]: Fast DDS 2.14 can deadlock in
#: destroy_participant (nodes/startup.teardown, which the nodes bound the same way).
ROS_TEARDOWN_BOUND = 30.0
_watchdog: dict = {'deadline': math.inf, 'stream': None}


def _arm(deadline: float) -> None:
    """Dump the stacks and exit at ``deadline`` (time.monotonic() [s]); never if it is inf."""
    faulthandler.cancel_dump_traceback_later()
    if math.isfinite(deadline):
        later = max(deadline - time.monotonic(), 0.001)
        faulthandler.dump_traceback_later(later, exit=True, file=_watchdog['stream'])


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item):
    mark = item.get_closest_marker('time_bound')
    _watchdog['deadline'] = time.monotonic() + (mark.args[0] if mark else TEST_BOUND)
    _arm(_watchdog['deadline'])
    try:
        return (yield)
    finally:
        _watchdog['deadline'] = math.inf
        _arm(math.inf)


@pytest.hookimpl(trylast=True)
def pytest_exception_interact():
    """The test's bound again after a failure (pytest's faulthandler plugin cancels the watchdog
    there, for a debugger) and after ``--pdb``'s session.
    """
    _arm(_watchdog['deadline'])


@contextlib.contextmanager
def bounded_ros_teardown():
    """The block (an rclpy teardown) ends within :data:`ROS_TEARDOWN_BOUND`, else the process
    prints every thread's stack and exits with code 1; then the test's own bound again.
    """
    _arm(min(time.monotonic() + ROS_TEARDOWN_BOUND, _watchdog['deadline']))
    try:
        yield
    finally:
        _arm(_watchdog['deadline'])


#: The longest test files (``--durations``), started first: pytest-xdist hands each worker whole
#: files in collection order, so a long file collected last would run alone at the end.
LONGEST_FIRST = (
    'test_readme_recording.py',
    'test_core_identification.py',
    'test_colcon_build.py',
    'test_nodes_fuzz.py',
    'test_bags_estimate.py',
    'test_core_calibration.py',
)


def pytest_collection_modifyitems(items):
    def rank(item) -> int:
        name = item.path.name
        return LONGEST_FIRST.index(name) if name in LONGEST_FIRST else len(LONGEST_FIRST)

    items.sort(key=rank)  # stable: the rest in collection order


def pytest_collectreport(report):
    _note_library_skip(report)


def pytest_runtest_logreport(report):
    _note_library_skip(report)


def _note_library_skip(report) -> None:
    if report.skipped and PIP_ONLY in str(report.longrepr):
        _skipped_for_libraries.append(f'{report.nodeid}: {report.longrepr[-1]}')


def pytest_sessionfinish(session):
    if _skipped_for_libraries and os.environ.get('PMA_TEST_ALL_LIBRARIES') == '1':
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter):
    if _skipped_for_libraries and os.environ.get('PMA_TEST_ALL_LIBRARIES') == '1':
        terminalreporter.write_line(
            'FAILED: scripts/test installs every test library, yet these skipped for one:',
            red=True,
        )
        for line in _skipped_for_libraries:
            terminalreporter.write_line(f'  {line}', red=True)


COLCON = Path(sys.executable).parent / 'colcon'
#: The environment of node processes that only start and fail: no DDS discovery.  Twenty of them
#: discovering each other at once made Fast DDS's discovery deadlock (nodes/startup.teardown)
#: likely enough to fail a CI run.
NO_DISCOVERY = {**os.environ, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF'}


def lines_of_failed_start(cmd: list[str]) -> list[str]:
    """The output lines of a node process ``cmd`` that must fail at start-up with exit code 1."""
    run = subprocess.run(
        cmd, capture_output=True, text=True, timeout=30, check=False, env=NO_DISCOVERY, cwd=REPO
    )
    assert run.returncode == 1, run.stdout + run.stderr
    return (run.stdout + run.stderr).strip().splitlines()


def edited_copy(source: Path, tmp_path: Path, old: str, new: str) -> Path:
    """A copy of ``source`` in ``tmp_path`` with its one ``old`` text replaced by ``new``."""
    text = source.read_text()
    assert old in text, (source, old)
    path = tmp_path / source.name
    path.write_text(text.replace(old, new))
    return path


def docstring_yaml(module) -> dict:
    """The ``ros__parameters`` of the YAML example in ``module``'s docstring (the block after
    ``::``).
    """
    import textwrap

    import yaml

    block = []
    for line in module.__doc__.split('::\n\n', 1)[1].splitlines():
        if line and not line.startswith('    '):
            break
        block.append(line)
    return yaml.safe_load(textwrap.dedent('\n'.join(block)))['/**']['ros__parameters']


def explain(proc):
    return f'exit {proc.returncode}\n--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}'


@pytest.fixture(scope='session')
def colcon_install(tmp_path_factory):
    """Run colcon once per session into a tmp dir; the install prefix, site-packages and a run
    env.
    """
    assert COLCON.exists(), f'{COLCON} missing: run scripts/setup (installs colcon into .venv)'
    tmp = tmp_path_factory.mktemp('colcon_nodes')
    env = dict(os.environ, COLCON_HOME=str(tmp / 'colcon_home'))
    proc = subprocess.run(
        [
            str(c)
            for c in (
                COLCON,
                '--log-base',
                tmp / 'log',
                'build',
                '--base-paths',
                REPO,
                '--packages-select',
                'pma_model_ros',
                '--build-base',
                tmp / 'build',
                '--install-base',
                tmp / 'install',
            )
        ],
        env=env,
        cwd=tmp,
        timeout=600,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, 'colcon build failed: ' + explain(proc)
    prefix = tmp / 'install' / 'pma_model_ros'
    site = sorted(prefix.glob('lib/python3.*/site-packages'))
    assert site, f'no lib/python3.*/site-packages under {prefix}'
    run_env = dict(os.environ, PYTHONPATH=str(site[0]), AMENT_PREFIX_PATH=str(prefix))
    return {'prefix': prefix, 'site': site[0], 'env': run_env, 'tmp': tmp}


@pytest.fixture
def namespace():
    """A fresh ROS namespace, so tests never hear each other's nodes."""
    return f'/t{uuid.uuid4().hex[:10]}'


#: The node processes that tests started and have not stopped (:class:`Processes`).
RUNNING: set[int] = set()


def run_delay(pid: int | str = 'thread-self') -> float:
    """How long [s] the (main) thread of process ``pid`` has waited, runnable, for a CPU: the
    kernel's schedstat run delay; 0 where it is unreadable (a process that ended).
    """
    try:
        return int(Path(f'/proc/{pid}/schedstat').read_text().split()[1]) * 1e-9
    except (OSError, IndexError, ValueError):
        return 0.0


class RunClock:
    """Seconds [s] since it was made, less the longest time that the test's thread or one of its
    node processes (:data:`RUNNING`) waited for a CPU meanwhile: the time they had to run.

    What a test's deadline counts: on a loaded machine (load 6 on 2 cores: a process runs about a
    third of the time) the deadline stretches by the waits, while a node that hangs, blocks or
    answers wrongly (it waits for no CPU then) still fails on it.
    """

    def __init__(self) -> None:
        self.start = time.monotonic()
        self.delays = {pid: run_delay(pid) for pid in ('thread-self', *RUNNING)}

    def __call__(self) -> float:
        waited = max(
            (run_delay(pid) - self.delays.get(pid, 0.0) for pid in ('thread-self', *RUNNING)),
            default=0.0,
        )
        return time.monotonic() - self.start - max(waited, 0.0)


class Processes:
    """Node processes of one test, their output in log files; all stopped at teardown."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.running: list[tuple[subprocess.Popen, Path]] = []

    def start(
        self, cmd: list[str], env: dict | None = None, cwd: Path | None = None
    ) -> subprocess.Popen:
        log = self.tmp / f'node{len(self.running)}.log'
        with open(log, 'w') as out:
            proc = node_process.start([str(c) for c in cmd], out, env=env, cwd=cwd)
        self.running.append((proc, log))
        RUNNING.add(proc.pid)
        return proc

    def node(
        self, name: str, namespace: str, params_file: Path | None = None, **params
    ) -> subprocess.Popen:
        """Start a node of this package (``params`` as -p overrides; use '__' for '.' in names)."""
        params = {k.replace('__', '.'): v for k, v in params.items()}
        return self.start(node_process.command(name, namespace, params_file, params))

    def output(self, proc: subprocess.Popen) -> str:
        """Everything ``proc`` printed so far (for assertion messages)."""
        log = next(log for p, log in self.running if p is proc)
        return f'--- output of {proc.args[:4]}... (exit {proc.poll()}) ---\n{log.read_text()}'

    def stop_all(self) -> None:
        for proc, _ in self.running:
            node_process.stop(proc, timeout=5.0)
            RUNNING.discard(proc.pid)


@pytest.fixture
def processes(tmp_path):
    procs = Processes(tmp_path)
    yield procs
    procs.stop_all()


class Ros:
    """A test node in its own rclpy context, with deadline-based spinning."""

    def __init__(self, node, executor) -> None:
        self.node, self.executor = node, executor

    def spin_until(
        self,
        done: Callable[[], bool],
        timeout: float,
        what: str,
        every: Callable[[], None] | None = None,
        period: float = 0.1,
        diagnose: Callable[[], str] = str,
    ) -> None:
        """Spin until ``done()``, calling ``every()`` each ``period`` [s]; after ``timeout`` [s]
        of :class:`RunClock` (time the test and its nodes had a CPU) fail with ``what`` and
        ``diagnose()`` (e.g. the nodes' output).
        """
        clock = RunClock()
        next_call = time.monotonic()
        while not done():
            now = time.monotonic()
            if clock() > timeout:
                pytest.fail(
                    f'timed out after {timeout:g} s of run time ({now - clock.start:.1f} s on '
                    f'the wall clock) waiting for {what}\n{diagnose()}'
                )
            if every is not None and now >= next_call:
                every()
                next_call = now + period
            self.executor.spin_once(timeout_sec=0.02)

    def now(self):
        return self.node.get_clock().now()

    def collect(self, msg_type, topic: str, qos=10) -> list:
        """Subscribe ``topic``; the returned list fills with received messages."""
        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    def call(self, srv_type, name: str, request, timeout: float = 10.0):
        """Call service ``name`` once it is available; its response.

        The request goes again every second without an answer: right after discovery the server may
        not have matched the client's response reader yet, and DDS then drops the response.
        """
        client = self.node.create_client(srv_type, name)
        self.spin_until(client.service_is_ready, timeout, f'service {name}')
        futures: list = []
        self.spin_until(
            lambda: any(f.done() for f in futures),
            timeout,
            f'response of {name}',
            every=lambda: futures.append(client.call_async(request)),
            period=1.0,
        )
        return next(f for f in futures if f.done()).result()


@pytest.fixture
def private_node():
    """A factory of in-process nodes, each on its own Context (as rclpy's own tests), destroyed
    after the test: ``make(cls, *ros_args, overrides=None, **kwargs)`` initialises a Context with
    ``--ros-args *ros_args`` and returns ``cls(context=..., **kwargs)``, ``overrides`` (a dict)
    as its ``parameter_overrides``.  A constructor that raises leaves its Context to be shut down,
    and the half-built node it carries (``StartupError.node``) to be destroyed first, not left to
    the garbage collector after its Context has gone (a fresh clone's ``.ci/run`` once hung in a
    garbage collection inside the constructor of the test after one that left such a node:
    faulthandler ``Garbage-collecting``, 97 % CPU for minutes).
    """
    import rclpy
    from rclpy.parameter import Parameter

    made = []

    def make(cls, *ros_args, overrides: dict | None = None, **kwargs):
        context = rclpy.Context()
        rclpy.init(context=context, args=['--ros-args', *map(str, ros_args)])
        made.append((context, []))
        if overrides:
            kwargs['parameter_overrides'] = [Parameter(k, value=v) for k, v in overrides.items()]
        try:
            node = cls(context=context, **kwargs)
        except Exception as err:
            if getattr(err, 'node', None) is not None:
                made[-1][1].append(err.node)
            raise
        made[-1][1].append(node)
        return node

    yield make
    with bounded_ros_teardown():
        for context, nodes in reversed(made):
            for node in nodes:
                node.destroy_node()
            rclpy.shutdown(context=context)


@pytest.fixture
def ros():
    import rclpy  # here, not at the top: the core tests must not need rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node(f'test_{uuid.uuid4().hex[:8]}', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    yield Ros(node, executor)
    with bounded_ros_teardown():
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


@pytest.fixture(scope='module')
def module_ros(tmp_path_factory):
    """``ros`` and ``processes`` shared by one module's tests: one node process serves many
    cases.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node(f'test_{uuid.uuid4().hex[:8]}', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    procs = Processes(tmp_path_factory.mktemp('module_nodes'))
    yield Ros(node, executor), procs
    procs.stop_all()
    with bounded_ros_teardown():
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
