"""The bad-input matrix of docs/reliability.md: one row per bad input, over the core and over the
live node.

Message rows go through :class:`Engine` (what model_node and the offline tools run) and through one
live model_node process; parameter-file rows through ``param_file`` (the offline tools' reader) and
through model_node start-up.  The row ids are the ids of the docs table (checked below).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
import re
import subprocess
from typing import Callable
import uuid

from geometry_msgs.msg import WrenchStamped
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.optimize import brentq
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS, NO_DISCOVERY, Processes, REPO, Ros
from node_messages import AMBIENT, JOINT, model_statuses, RELIABLE_QOS, stamp_key, status_values
from pma_model_ros.core.files.param_file import node_settings, read_parameters
from pma_model_ros.core.physics.muscle_model import MuscleModel
from pma_model_ros.core.runtime.engine import Engine, Level
from pma_model_ros.nodes.model_node import DESERIALIZE
from pma_model_ros.tools import node_process
from pma_model_ros.wire.muscle_inputs import MuscleInputs

CONFIG = CONFIGS['DMSP-10-250']
P = 300e3  # gauge pressure of the good inputs [Pa]
L = 0.23  # length of the good inputs [m]
ERROR, WARN, OK = Level.ERROR, Level.WARN, Level.OK


@dataclass(frozen=True)
class Msg:
    """One input message, in terms both the core and the node take."""

    topic: str  #: 'pressure', 'muscle_state' or 'force_command'
    value: float = AMBIENT + P  #: absolute pressure [Pa] or wanted tension [N]
    names: tuple[str, ...] = (JOINT,)
    positions: tuple[float, ...] = (L,)  #: lengths [m]
    velocities: tuple[float, ...] = (0.0,)  #: length rates [m/s]
    age: float | None = 0.0  #: now - stamp [s] (< 0: from the future); None: unset stamp 0


GOOD = (Msg('pressure'), Msg('muscle_state'))


@dataclass(frozen=True)
class Expect:
    """What the node does with a row's message."""

    level: Level  #: diagnostic level it leads to
    pattern: str  #: regular expression found in the diagnostic message
    counter: str  #: diagnostic counter that counts it
    #: the output it gives: estimate [N] or command gauge pressure [Pa] of the model; None: no
    #: output
    output: Callable[[MuscleModel], float] | None = None
    context: tuple[Msg, ...] = GOOD  #: sent just before it, stamped now


def pressure(absolute: float, age: float | None = 0.0) -> Msg:
    return Msg('pressure', value=absolute, age=age)


def state(positions=(L,), names=(JOINT,), velocities=(0.0,)) -> Msg:
    return Msg(
        'muscle_state',
        names=tuple(names),
        positions=tuple(positions),
        velocities=tuple(velocities),
    )


def command(force: float) -> Msg:
    return Msg('force_command', value=force)


def rejected(source: str, words: str) -> Expect:
    return Expect(ERROR, re.escape(words), f'rejected {source}')


def stale(source: str, when: str) -> Expect:
    return Expect(ERROR, f'stale {source}: newest stamp is [-+.e0-9]+ s {when}', 'stale skipped')


def estimate(level: Level, words: str, gauge: float = P, length: float = L) -> Expect:
    return Expect(
        level, re.escape(words), 'estimates', lambda m: float(m.force(gauge, length).force)
    )


def pull_start(model: MuscleModel, length: float = L) -> float:
    """Gauge pressure [Pa] where the raw model force crosses 0 N (root-found, independent of the
    inverse).
    """
    return brentq(
        lambda p: float(model.force(p, length).raw), 0.0, model.spec.max_pressure, xtol=1e-6
    )


NAN, INF = math.nan, math.inf
OUTSIDE = 'outside validity domain'
#: id: (message, expected behaviour); the order keeps each level's rows together (fewer hold waits
#: live).
MESSAGES = {
    'pressure-nan': (pressure(NAN), rejected('pressure', 'pressure is nan Pa')),
    'pressure-inf': (pressure(INF), rejected('pressure', 'pressure is inf Pa')),
    'pressure-minus-inf': (pressure(-INF), rejected('pressure', 'pressure is -inf Pa')),
    'pressure-negative-absolute': (
        pressure(-5.0),
        rejected('pressure', 'negative absolute pressure'),
    ),
    'pressure-absurd': (pressure(1e9), rejected('pressure', 'absurd pressure 1e+09 Pa')),
    'length-nan': (state([NAN]), rejected('muscle_state', 'length nan m outside the geometry')),
    'length-inf': (state([INF]), rejected('muscle_state', 'length inf m outside the geometry')),
    'length-zero': (state([0.0]), rejected('muscle_state', 'length 0 m outside the geometry')),
    'length-negative': (
        state([-0.23]),
        rejected('muscle_state', 'length -0.23 m outside the geometry'),
    ),
    'length-beyond-fibre': (
        state([0.29]),
        rejected('muscle_state', 'length 0.29 m outside the geometry'),
    ),
    'length-no-model-solution': (state([0.28]), estimate(WARN, OUTSIDE, length=0.28)),
    'joint-missing': (
        state(names=['elbow']),
        rejected('muscle_state', f"joint '{JOINT}' not in ['elbow']"),
    ),
    'arrays-empty': (state([], [], []), rejected('muscle_state', 'empty name or position array')),
    'arrays-mismatched-positions': (
        state([L], [JOINT, 'elbow'], []),
        rejected('muscle_state', 'mismatched arrays: 2 names, 1 positions'),
    ),
    'arrays-mismatched-velocities': (
        state(velocities=[0.0, 0.0]),
        rejected('muscle_state', 'mismatched arrays: 1 names, 1 positions, 2 velocities'),
    ),
    'command-nan': (command(NAN), rejected('force_command', 'force command is nan N')),
    'command-inf': (command(INF), rejected('force_command', 'force command is inf N')),
    'stamp-future': (pressure(AMBIENT + P, age=-10.0), stale('pressure', 'in the future')),
    'stamp-far-past': (pressure(AMBIENT + P, age=3600.0), stale('pressure', 'old')),
    'stamp-unset': (pressure(AMBIENT + P, age=None), stale('pressure', 'old')),
    'command-no-fresh-length': (
        command(100.0),
        Expect(
            ERROR,
            'stale muscle_state',
            'commands without fresh length',
            context=(Msg('pressure'), Msg('muscle_state', age=3600.0)),
        ),
    ),
    'pressure-below-ambient': (pressure(AMBIENT - 50e3), estimate(WARN, OUTSIDE, gauge=-50e3)),
    'pressure-above-rated': (pressure(AMBIENT + 1e6), estimate(WARN, OUTSIDE, gauge=1e6)),
    'length-above-range': (state([0.26]), estimate(WARN, OUTSIDE, length=0.26)),
    # the braid's shortest: 0.164 m
    'length-below-envelope': (state([0.15]), estimate(WARN, OUTSIDE, length=0.15)),
    'length-below-identified': (
        state([0.19]),
        estimate(WARN, 'extrapolated beyond the identified data', length=0.19),
    ),
    'pressure-vented': (pressure(AMBIENT - 5e3), estimate(OK, 'estimating', gauge=-5e3)),
    'pressure-gauge-sensor': (
        pressure(80e3),
        estimate(WARN, 'a gauge sensor read as absolute', gauge=80e3 - AMBIENT),
    ),
    'command-unreachable': (
        command(1e5),
        Expect(
            WARN, r'saturated \(SATURATED\)', 'pressure commands', lambda m: m.spec.max_pressure
        ),
    ),
    'command-negative': (
        command(-50.0),
        Expect(OK, 'estimating', 'pressure commands', pull_start),
    ),
    'velocity-nan': (state([0.24], velocities=[NAN]), estimate(OK, 'estimating', length=0.24)),
    'velocity-missing': (state([0.24], velocities=[]), estimate(OK, 'estimating', length=0.24)),
    'stamp-out-of-order': (
        pressure(AMBIENT + 500e3, age=0.05),
        estimate(OK, 'estimating', gauge=500e3),
    ),
}


def good_force(model: MuscleModel) -> float:
    return float(model.force(P, L).force)


# --- over the core
# -----------------------------------------------------------------------------------------


def feed(inputs: MuscleInputs, msg: Msg, now: int) -> tuple[float, int] | None:
    """``msg``, serialized by rclpy, into the node's wire layer and engine at ``now`` [ns]: its
    output (estimate [N] or command gauge [Pa], stamp [ns]), or None.
    """
    stamp = 0 if msg.age is None else now - round(msg.age * 1e9)
    if msg.topic == 'force_command':
        pressure = inputs.force_command(0, serialize_message(_wrench(msg.value)), now)
        return None if pressure is None else (pressure - AMBIENT, now)
    if msg.topic == 'pressure':
        out = FluidPressure(fluid_pressure=msg.value)
        out.header.stamp.sec, out.header.stamp.nanosec = divmod(stamp, 10**9)
        answer = inputs.pressure(0, serialize_message(out), now)
    else:
        out = JointState(
            name=list(msg.names), position=list(msg.positions), velocity=list(msg.velocities)
        )
        out.header.stamp.sec, out.header.stamp.nanosec = divmod(stamp, 10**9)
        answer = inputs.muscle_state(0, serialize_message(out), now)
    if answer is None:
        return None
    got = deserialize_message(answer, WrenchStamped)
    return got.wrench.force.x, got.header.stamp.sec * 10**9 + got.header.stamp.nanosec


def _wrench(force: float) -> WrenchStamped:
    out = WrenchStamped()
    out.wrench.force.x = force
    return out


@pytest.mark.parametrize('row', MESSAGES)
def test_core(row):
    msg, expect = MESSAGES[row]
    settings = node_settings(read_parameters(CONFIG))
    est, now = Engine([settings.config], hold=1.0), 100 * 10**9
    inputs = MuscleInputs(est, [JOINT], [settings.frame_id], DESERIALIZE)
    for good in expect.context:
        feed(inputs, good, now)
    before = est.counts(0).get(expect.counter, 0)
    out = feed(inputs, msg, now)
    level, message = est.level(0, now)
    assert level == expect.level and re.search(expect.pattern, message), message
    assert est.counts(0)[expect.counter] == before + 1, est.counts(0)
    if expect.output is None:
        assert out is None
    else:
        value, stamp = out
        assert value == pytest.approx(expect.output(settings.config.model), rel=1e-9, abs=1e-6)
        assert math.isfinite(value) and value >= 0
        assert stamp == now  # the newest input stamp: never an older one


# --- over the live node
# ------------------------------------------------------------------------------------


class Live:
    """One model_node process and the test's side of its topics."""

    def __init__(self, ros: Ros, processes: Processes) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import WrenchStamped
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import FluidPressure, JointState

        self.ros, self.processes, self.namespace = ros, processes, f'/t{uuid.uuid4().hex[:10]}'
        # every input read, however long it waits in a loaded node's queue (a node that falls
        # behind answers only its newest inputs: test_nodes_faults.py)
        self.node = processes.node('model_node', self.namespace, CONFIG, max_queue_delay=3600.0)
        ns = self.namespace
        self.estimates = ros.collect(WrenchStamped, f'{ns}/force_estimate', RELIABLE_QOS)
        self.commands = ros.collect(FluidPressure, f'{ns}/pressure_command', RELIABLE_QOS)
        self.diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
        self.pubs = {
            'pressure': ros.node.create_publisher(
                FluidPressure, f'{ns}/pressure', qos_profile_sensor_data
            ),
            'muscle_state': ros.node.create_publisher(
                JointState, f'{ns}/muscle_state', qos_profile_sensor_data
            ),
            'force_command': ros.node.create_publisher(WrenchStamped, f'{ns}/force_command', 10),
        }
        self.types = {
            'pressure': FluidPressure,
            'muscle_state': JointState,
            'force_command': WrenchStamped,
        }

    def why(self) -> str:
        return self.processes.output(self.node)

    def statuses(self) -> list:
        return model_statuses(self.diagnostics, self.namespace)

    def publish(self, msg: Msg, now) -> int:
        """Publish ``msg`` stamped ``now`` - age; its stamp [ns]."""
        out = self.types[msg.topic]()
        if msg.topic == 'pressure':
            out.fluid_pressure = msg.value
        elif msg.topic == 'muscle_state':
            out.name, out.position, out.velocity = (
                list(msg.names),
                list(msg.positions),
                list(msg.velocities),
            )
        else:
            out.wrench.force.x = msg.value
        stamp = 0 if msg.age is None else now.nanoseconds - round(msg.age * 1e9)
        out.header.stamp.sec, out.header.stamp.nanosec = divmod(stamp, 10**9)
        self.pubs[msg.topic].publish(out)
        return stamp


@pytest.fixture(scope='module')
def live(module_ros):
    live = Live(*module_ros)
    publish_good = lambda: [live.publish(m, live.ros.now()) for m in GOOD]  # noqa: E731
    live.ros.spin_until(
        lambda: live.estimates,
        30,
        'a first estimate from good input',
        every=publish_good,
        diagnose=live.why,
    )
    return live


@pytest.mark.ros
@pytest.mark.parametrize('row', MESSAGES)
def test_live(row, live):
    """Send good context then the row's message every 50 ms until /diagnostics reports the row.

    The first period sends the context alone, so that the node holds this row's inputs, not the
    previous row's; the row's outputs are those stamped from the second period on (estimates carry
    their input's stamp, commands the node clock).
    """
    msg, expect = MESSAGES[row]
    model = node_settings(read_parameters(CONFIG)).config.model
    wanted = None if expect.output is None else expect.output(model)
    old = [len(x) for x in (live.estimates, live.commands, live.statuses())]
    baseline = int(status_values(live.statuses()[-1]).get(expect.counter, 0)) if old[2] else 0
    periods: list[int] = []  # send times [ns]
    sent: set[int] = set()  # stamps sent [ns]

    def send():
        now = live.ros.now()
        sent.update(live.publish(m, now) for m in expect.context + ((msg,) if periods else ()))
        periods.append(now.nanoseconds)

    def mine(msgs: list) -> list:
        return [m for m in msgs if len(periods) > 1 and stamp_key(m) >= periods[1]]

    def estimates() -> list:
        return mine(live.estimates[old[0] :])

    def commands() -> list[float]:
        return [c.fluid_pressure - AMBIENT for c in mine(live.commands[old[1] :])]

    def reported() -> bool:
        shown = any(
            s.level == bytes([expect.level])
            and re.search(expect.pattern, s.message)
            and int(status_values(s).get(expect.counter, 0)) > baseline
            for s in live.statuses()[old[2] :]
        )
        outputs = (
            commands() if msg.topic == 'force_command' else [e.wrench.force.x for e in estimates()]
        )
        return shown and (
            wanted is None or any(v == pytest.approx(wanted, rel=1e-9) for v in outputs)
        )

    live.ros.spin_until(
        reported,
        15,
        f'/diagnostics {expect.level.name} "{expect.pattern}"'
        + ('' if wanted is None else f' and output {wanted:g}'),
        every=send,
        period=0.05,
        diagnose=lambda: live.why() + '\n' + '\n'.join(s.message for s in live.statuses()[-5:]),
    )
    assert live.node.poll() is None, live.why()
    allowed = [good_force(model)] + (
        [] if wanted is None or msg.topic == 'force_command' else [wanted]
    )
    for e in estimates():
        assert any(e.wrench.force.x == pytest.approx(v, rel=1e-9) for v in allowed), (
            e.wrench.force.x,
            allowed,
        )
        assert stamp_key(e) in sent  # the stamp of one of its inputs
    if msg.topic == 'force_command' and wanted is not None:  # the previous row's may come first
        answers = commands()
        start = next(i for i, c in enumerate(answers) if c == pytest.approx(wanted, rel=1e-9))
        assert all(c == pytest.approx(wanted, rel=1e-9) for c in answers[start:]), answers
    else:
        assert not commands(), commands()


# --- parameter files and values
# ----------------------------------------------------------------------------

GOOD_FILE = CONFIG.read_text()
#: Martens' first parameter as the shipped file writes it (its params line starts with it)
MARTENS_C0 = read_parameters(CONFIG)['models']['martens']['params'][0]


def edited(old: str, new: str) -> Callable[[Path], Path]:
    """A parameter file: the shipped DMSP-10-250 file with ``old`` replaced by ``new``."""
    assert old in GOOD_FILE, old

    def make(tmp: Path) -> Path:
        path = tmp / 'params.yaml'
        path.write_text(GOOD_FILE.replace(old, new.replace('MARKER', str(tmp / 'marker'))))
        return path

    return make


def text(content: str) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        (tmp / 'params.yaml').write_text(content)
        return tmp / 'params.yaml'

    return make


#: id: (parameter file, words of the core's ValueError, words of model_node's one line)
FILES = {
    'file-missing-key': (
        edited('inner_diameter: 0.01, ', ''),
        "'muscle.inner_diameter' is missing",
        "'muscle.inner_diameter' is not set",
    ),
    'file-wrong-type': (
        edited('nominal_length: 0.25', 'nominal_length: long'),
        "muscle.nominal_length must be a number, got 'long'",
        "parameter 'muscle.nominal_length' must be a number [m], got 'long'",
    ),
    'file-scalar-for-list': (
        edited('length_range: [0.198, 0.25]', 'length_range: 0.2'),
        'length_range must be [min, max] in m, got 0.2',
        "expecting type 'DOUBLE_ARRAY'",
    ),
    'file-unknown-model': (
        edited('    model: martens', '    model: foo'),
        "unknown model 'foo'",
        "parameter 'model': unknown model 'foo'",
    ),
    'file-negative-geometry': (
        edited('inner_diameter: 0.01', 'inner_diameter: -0.01'),
        'muscle.inner_diameter must be a positive finite number',
        "parameter 'muscle.inner_diameter' must be in [0, 1] m, got -0.01",
    ),
    'file-nan-geometry': (
        edited('inner_diameter: 0.01', 'inner_diameter: .nan'),
        'muscle.inner_diameter must be a positive finite number',
        "parameter 'muscle.inner_diameter' must be in [0, 1] m, got nan",
    ),
    'file-wrong-parameter-count': (
        edited(f'params: [{MARTENS_C0!r}, ', 'params: ['),
        "model 'martens' needs 5",
        "model 'martens' needs 5",
    ),
    'file-reversed-length-range': (
        edited('length_range: [0.198, 0.25]', 'length_range: [0.25, 0.198]'),
        'length range must satisfy 0 < min < max',
        'length range must satisfy 0 < min < max',
    ),
    'file-negative-max-input-age': (
        edited('max_input_age: 0.1', 'max_input_age: -1.0'),
        'max_input_age',
        "parameter 'max_input_age' must be in [0.001, 3600] s, got -1.0",
    ),
    'file-string-for-number': (
        edited('max_input_age: 0.1', 'max_input_age: soon'),
        'ambient_pressure/max_input_age must be numbers',
        "parameter 'max_input_age' must be a number [s], got 'soon'",
    ),
    'file-yaml-list': (
        text('- a\n- b\n'),
        'expected a YAML mapping at the top, got list',
        "Couldn't parse params file",
    ),
    'file-yaml-scalar': (
        text('42\n'),
        'expected a YAML mapping at the top, got int',
        "'muscle.name' is not set",
    ),
    'file-empty': (
        text(''),
        'expected a YAML mapping at the top, got NoneType',
        "'muscle.name' is not set",
    ),
    'file-not-yaml': (text('a: [b\n'), 'not valid YAML', "Couldn't parse params file"),
    'file-python-tag': (
        edited(
            '    model: martens', '    model: !!python/object/apply:os.system ["touch MARKER"]'
        ),
        'could not determine a constructor for the tag',
        "expecting type 'STRING': model",
    ),
    'file-not-found': (
        lambda tmp: tmp / 'absent.yaml',
        'parameter file not found',
        'Error opening YAML file',
    ),
    'file-directory': (lambda tmp: tmp, 'is not a regular file', "Couldn't parse params file"),
}


@pytest.mark.parametrize('row', FILES)
def test_core_parameter_file(row, tmp_path):
    make, words, _ = FILES[row]
    with pytest.raises(ValueError, match=re.escape(words)):
        node_settings(read_parameters(make(tmp_path)))
    assert not (tmp_path / 'marker').exists()


@pytest.fixture(scope='module')
def startups(tmp_path_factory) -> dict[str, tuple[int, str, Path]]:
    """model_node started for every file row and failing argument row, all at once (start-up
    dominates).

    Row: (exit code, output, the row's tmp dir).
    """
    started = {}
    for row, (params, words) in ARGUMENTS.items():
        if words:
            started[row] = (
                node_process.command('model_node', f'/t{uuid.uuid4().hex[:10]}', CONFIG, params),
                None,
            )
    for row, (make, _, _) in FILES.items():
        tmp = tmp_path_factory.mktemp(row)
        started[row] = (
            node_process.command('model_node', f'/t{uuid.uuid4().hex[:10]}', make(tmp)),
            tmp,
        )
    procs = {
        row: (
            subprocess.Popen(
                cmd,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                cwd=REPO,
                env=NO_DISCOVERY,
            ),
            tmp,
        )
        for row, (cmd, tmp) in started.items()
    }
    results = {}
    for row, (proc, tmp) in procs.items():
        try:
            output = proc.communicate(timeout=120)[0]
        except subprocess.TimeoutExpired:  # it started: the test shows that
            proc.kill()
            output = proc.communicate()[0]
        results[row] = proc.returncode, output, tmp
    return results


def one_line(code: int, output: str, words: str) -> None:
    """The start-up ended with exit code 1 and one line with ``words``."""
    lines = [line for line in output.splitlines() if line.strip()]
    assert code == 1 and len(lines) == 1, f'exit {code}, output:\n' + '\n'.join(lines)
    assert words in lines[0] and 'Traceback' not in lines[0], lines[0]


@pytest.mark.ros
@pytest.mark.parametrize('row', FILES)
def test_node_parameter_file(row, startups):
    code, output, tmp = startups[row]
    one_line(code, output, FILES[row][2])
    assert not (tmp / 'marker').exists()


#: id: (-p overrides on the shipped file, words of model_node's one line); no core counterpart.
ARGUMENTS = {
    'arg-out-of-range': (
        {'max_input_age': -1.0},
        "parameter 'max_input_age' must be in [0.001, 3600] s, got -1.0",
    ),
    'arg-wrong-type': ({'use_sim_time': 3}, "expecting type 'BOOL': use_sim_time"),
    'arg-unknown-model': ({'model': 'foo'}, "parameter 'model': unknown model 'foo'"),
    # rcl would keep the file's 0.1 without a word
    'arg-type-differs-from-file': (
        {'max_input_age': 'soon'},
        "parameter 'max_input_age' is a double (0.1) in",
    ),
}


@pytest.mark.ros
@pytest.mark.parametrize('row', [row for row, (_, words) in ARGUMENTS.items() if words])
def test_node_argument(row, startups):
    one_line(*startups[row][:2], ARGUMENTS[row][1])


def test_docs_table_lists_every_row():
    """docs/reliability.md's matrix has exactly these rows, so every documented row is backed by a
    test.
    """
    documented = re.findall(
        r'^\| `([a-z0-9-]+)` \|', (REPO / 'docs' / 'reliability.md').read_text(), re.M
    )
    assert sorted(documented) == sorted([*MESSAGES, *FILES, *ARGUMENTS])


# --- input safety
# ------------------------------------------------------------------------------------------

#: Calls and imports that would run or unpickle something a user supplies.
UNSAFE_CALLS = {'eval', 'exec', 'compile', '__import__'}
UNSAFE_ATTRIBUTES = {'load', 'unsafe_load', 'full_load', 'system', 'popen'}  # yaml.load, ...
UNSAFE_MODULES = {'pickle', 'marshal', 'shelve', 'dill', 'cloudpickle'}
UNSAFE_KEYWORDS = {('shell', True), ('allow_pickle', True)}


def test_package_loads_no_code_from_data():
    """No eval/exec, no yaml.load (only safe_load), no pickle, no shell in the package's
    modules.
    """
    import ast

    found = []
    for path in sorted((REPO / 'pma_model_ros').rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            where = f'{path.relative_to(REPO)}:{getattr(node, "lineno", 0)}'
            if isinstance(node, ast.Call):
                func = node.func
                if (
                    isinstance(func, ast.Name)
                    and func.id in UNSAFE_CALLS
                    or isinstance(func, ast.Attribute)
                    and func.attr in UNSAFE_ATTRIBUTES
                ):
                    found.append(f'{where} {ast.unparse(func)}()')
                found += [
                    f'{where} {k.arg}={ast.unparse(k.value)}'
                    for k in node.keywords
                    if isinstance(k.value, ast.Constant)
                    and (k.arg, k.value.value) in UNSAFE_KEYWORDS
                ]
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                names = (
                    [a.name for a in node.names]
                    if isinstance(node, ast.Import)
                    else [node.module or '']
                )
                found += [
                    f'{where} import {n}' for n in names if n.split('.')[0] in UNSAFE_MODULES
                ]
    assert not found, found


@pytest.mark.parametrize(
    'name', ['../data/dmsp_10_250', '/etc/passwd', 'dmsp_10_250.yaml', 'DMSP-10-250/..']
)
def test_simulator_muscle_is_a_name_not_a_path(name):
    from pma_model_ros.core.files.shipped_data import shipped_force_map

    with pytest.raises(ValueError, match='no shipped force map for'):
        shipped_force_map(name)
