"""model_node's callbacks called in-process, on a private rclpy Context: no DDS, no timing.

Each test builds the node from a shipped parameter file, hands messages to its subscription
callbacks and reads what it published (each publisher's ``publish`` replaced by a list's append).
The expected forces come from each muscle's own single-muscle file through the core.
"""

import math
import subprocess
import sys
import time

from builtin_interfaces.msg import Time
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from conftest import CONFIGS, REPO
from node_messages import AMBIENT, force_command, JOINT, pressure, raw, record, state
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.nodes.model_node import ModelNode

EXAMPLE = REPO / 'config' / 'example_multi_muscle.yaml'
MARTENS = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'martens')


@pytest.fixture
def make_node(private_node):
    """A factory of ModelNodes (a params file and parameter overrides), each on its own Context,
    destroyed after the test.
    """

    def make(params_file, **overrides):
        return private_node(ModelNode, '--params-file', params_file, overrides=overrides)

    return make


def frozen_clock(node, back: float = 0.0):
    """Stop the node's clock (its callbacks read ``node.now()``) at its current time, so that the
    test's stamps stay fresh however slowly a loaded machine runs it; that time less ``back`` [s],
    as a stamp.
    """
    t = node.now()
    node.now = lambda: t
    t -= round(back * 1e9)
    return Time(sec=t // 10**9, nanosec=t % 10**9)


def shifted(stamp: Time, seconds: float) -> Time:
    """``stamp`` moved by ``seconds``."""
    t = stamp.sec * 10**9 + stamp.nanosec + round(seconds * 1e9)
    return Time(sec=t // 10**9, nanosec=t % 10**9)


def test_one_muscle_answers_each_input_with_the_newest_pair(make_node):
    node = make_node(CONFIGS['DMSP-10-250'])
    estimates = record(node._estimate_pubs[0])
    first, second = frozen_clock(node, 0.001), frozen_clock(node)
    node._on_pressure(0, raw(pressure(first, AMBIENT + 300e3)))
    assert estimates == []  # no length yet
    node._on_state(0, raw(state(second, 0.23, 0.0)))
    node._on_pressure(0, raw(pressure(second, AMBIENT + 500e3)))
    assert [m.wrench.force.x for m in estimates] == pytest.approx(
        [float(MARTENS.force(300e3, 0.23).force), float(MARTENS.force(500e3, 0.23).force)],
        rel=1e-9,
    )
    assert all(m.header.stamp == second and m.header.frame_id == 'dmsp_10_250' for m in estimates)
    assert estimates[0].wrench.force.x > 0 and math.isfinite(estimates[1].wrench.force.x)


def test_one_muscle_command_and_diagnostics_on_change(make_node):
    node = make_node(CONFIGS['DMSP-10-250'])
    # every change at once (the callbacks run within the 1.5 ms limit)
    node.engine.health.report_interval = 0
    commands, diagnostics = record(node._command_pubs[0]), record(node._diag_pub)
    now = frozen_clock(node)
    node._on_state(0, raw(state(now, 0.23, 0.0)))
    assert [d.status[0].message for d in diagnostics] == [
        'no pressure received yet'
    ]  # first report: a change
    node._on_command(0, raw(force_command(100.0)))
    gauge = commands[0].fluid_pressure - AMBIENT
    assert float(MARTENS.force(gauge, 0.23).force) == pytest.approx(100.0, abs=1e-6)
    node._on_pressure(0, raw(pressure(now, AMBIENT + 300e3)))
    assert diagnostics[-1].status[0].message == 'estimating' and len(diagnostics) == 2
    node._on_state(
        0, raw(state(now, 0.23, 0.0, name='elbow'))
    )  # not this muscle's joint: rejected, ERROR at once
    assert (
        diagnostics[-1].status[0].message == "invalid input: joint 'DMSP-10-250' not in ['elbow']"
    )


def test_diagnostics_carry_the_expected_error_at_the_served_length(make_node):
    """The nested held-out error that judges the newest length, in N and %: between the measured
    lengths the worst of those inside (the file's ``models.martens.held_out``: 4.66 % at 0.234 m,
    of 542.5 N); beyond them the worse of the shortest's and longest's (8.81 % at 0.25 m), said to
    be beyond them (extrapolated or held as served, which the band does not know).
    """
    node = make_node(CONFIGS['DMSP-10-250'])
    diagnostics = record(node._diag_pub)
    now = frozen_clock(node)

    def expected() -> tuple[str, str]:
        node.publish_status(node.now())
        values = {v.key: v.value for v in diagnostics[-1].status[0].values}
        return values['expected error [N]'], values['expected error [% of max force]']

    assert expected() == ('unknown', 'unknown: no length yet')
    held = read_parameters(CONFIGS['DMSP-10-250'])['models']['martens']['held_out']
    worst = max(held['err'][1:-1])  # 0.234, 0.219 and 0.204 m: between the measured lengths
    node._on_state(0, raw(state(now, 0.23, 0.0)))
    node._on_pressure(0, raw(pressure(now, AMBIENT + 300e3)))
    assert expected() == (f'{worst * 542.5 / 100:.3g}', f'{worst:.3g}') == ('25.3', '4.66')
    node._on_state(0, raw(state(now, 0.26, 0.0)))  # beyond L0 = 0.25 m, the longest held out
    edge = max(held['err'][0], held['err'][-1])  # 0.25 m and 0.198 m
    beyond = (
        ' (0.26 m is beyond the measured lengths 0.198..0.25 m: the worst of the shortest and '
        'longest, extrapolated or held there as served)'
    )
    assert (
        expected()
        == (f'{edge * 542.5 / 100:.3g}', f'{edge:.3g}{beyond}')
        == ('47.8', f'8.81{beyond}')
    )


def test_gauge_sensor_readings_and_commands(make_node):
    """pressure_reference: gauge: a reading of 300 kPa is 300 kPa gauge, and commands are published
    in gauge.
    """
    node = make_node(CONFIGS['DMSP-10-250'], pressure_reference='gauge')
    estimates, commands = record(node._estimate_pubs[0]), record(node._command_pubs[0])
    now = frozen_clock(node)
    node._on_state(0, raw(state(now, 0.25, 0.0)))
    node._on_pressure(0, raw(pressure(now, 300e3)))
    assert estimates[-1].wrench.force.x == pytest.approx(
        float(MARTENS.force(300e3, 0.25).force), rel=1e-9
    )
    node._on_command(0, raw(force_command(100.0)))
    assert float(MARTENS.force(commands[0].fluid_pressure, 0.25).force) == pytest.approx(
        100.0, abs=1e-6
    )


def expected_forces(inputs: dict) -> dict[str, float]:
    example = read_parameters(EXAMPLE)
    # after one length sample a hysteresis branch is unknown (it follows the motion, not the rate):
    # branch 0
    return {
        name: float(
            muscle_model(read_parameters(REPO / 'config' / f'{cfg}.yaml'), example[name]['model'])
            .force(p, L, 0.0)
            .force
        )
        for name, (cfg, p, L, rate) in inputs.items()
    }


INPUTS = {
    'biceps': ('dmsp_20_300', 400e3, 0.26, 0.0),
    'triceps': ('dmsp_20_300', 250e3, 0.28, -0.02),
    'wrist_flexor': ('dmsp_10_250', 500e3, 0.23, 0.01),
    'finger': ('dmsp_10_100', 600e3, 0.095, 0.01),
}


def joint_states(stamp, names, values, rates=()):
    msg = JointState(name=list(names), position=list(values), velocity=list(rates))
    msg.header.stamp = stamp
    return msg


def test_combined_mode_one_vector_call_per_message(make_node):
    node = make_node(EXAMPLE)
    estimates = record(node._estimate_pubs[0])
    stamp = frozen_clock(node)
    order = list(reversed(INPUTS))  # states in another order than the pressures
    node._on_states(
        raw(
            joint_states(
                stamp, order, [INPUTS[n][2] for n in order], [INPUTS[n][3] for n in order]
            )
        )
    )
    assert estimates == []
    node._on_pressures(raw(joint_states(stamp, INPUTS, [AMBIENT + v[1] for v in INPUTS.values()])))
    expected = expected_forces(INPUTS)
    assert list(estimates[-1].name) == list(INPUTS) and estimates[-1].header.stamp == stamp
    assert list(estimates[-1].effort) == pytest.approx([expected[n] for n in INPUTS], rel=1e-9)
    # a states message without the finger: the others answered, the finger rejected
    node._on_states(
        raw(
            joint_states(
                stamp,
                order[1:],
                [INPUTS[n][2] for n in order[1:]],
                [INPUTS[n][3] for n in order[1:]],
            )
        )
    )
    assert list(estimates[-1].name) == ['biceps', 'triceps', 'wrist_flexor']
    assert node.engine.level(3, node.now())[1] == "invalid input: joint 'finger' not in " + str(
        order[1:]
    )


def test_stale_force_commands_give_no_pressure_command(make_node):
    """A force_command (one muscle) or force_commands (combined) stamped farther than
    max_input_age from the node clock is refused as stale, counted and shown; unstamped (zero) and
    fresh ones are answered.
    """
    node = make_node(CONFIGS['DMSP-10-250'])
    commands = record(node._command_pubs[0])
    now = frozen_clock(node)
    node._on_state(0, raw(state(now, 0.23, 0.0)))
    for stamp in (shifted(now, -0.5), now, None):
        command = force_command(100.0)
        if stamp is not None:
            command.header.stamp = stamp
        node._on_command(0, raw(command))
    assert len(commands) == 2 and node.engine.counts(0)['stale force_command'] == 1
    assert node.engine.level(0, node.now())[1] == (
        'stale force_command: stamp is 0.5 s old (max_input_age 0.1 s)'
    )
    combined = make_node(EXAMPLE, input_mode='combined')
    pressures = record(combined._command_pubs[0])
    now = frozen_clock(combined)
    combined._on_states(raw(joint_states(now, INPUTS, [v[2] for v in INPUTS.values()])))
    efforts = JointState(name=['biceps', 'finger'], effort=[100.0, 20.0])
    efforts.header.stamp = shifted(now, 0.3)  # from the future
    combined._on_commands(raw(efforts))
    assert pressures == [] and combined.engine.counts(0)['stale force_command'] == 1
    assert combined.engine.level(3, combined.now())[1].startswith(
        'stale force_command: stamp is 0.3 s in the future'
    )
    efforts.header.stamp = now
    combined._on_commands(raw(efforts))
    assert list(pressures[-1].name) == ['biceps', 'finger']


def test_approximate_time_pairing_answers_once_per_tick(make_node):
    node = make_node(CONFIGS['DMSP-10-250'], pairing='approximate_time')
    estimates = record(node._estimate_pubs[0])
    for _ in range(3):
        tick = frozen_clock(node)
        node._on_state(0, raw(state(tick, 0.23, 0.0)))
        node._on_pressure(0, raw(pressure(tick, AMBIENT + 300e3)))
    assert len(estimates) == 3
    assert (
        node.engine.counts(0)['received pressure']
        == node.engine.counts(0)['received muscle_state']
        == 3
    )


def test_runtime_model_swap_is_used_by_the_next_estimate(make_node):
    node = make_node(CONFIGS['DMSP-10-250'])
    estimates = record(node._estimate_pubs[0])
    assert node.set_parameters([Parameter('model', value='hildebrandt')])[0].successful
    assert not node.set_parameters([Parameter('model', value='nope')])[0].successful
    now = frozen_clock(node)
    node._on_state(0, raw(state(now, 0.23, 0.0)))
    node._on_pressure(0, raw(pressure(now, AMBIENT + 300e3)))
    hildebrandt = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'hildebrandt')
    assert estimates[-1].wrench.force.x == pytest.approx(
        float(hildebrandt.force(300e3, 0.23).force), rel=1e-9
    )
    assert JOINT == node.settings[0].joint_name


def test_the_node_does_not_load_the_identification_tools():
    # scipy.optimize serves only the offline fits (core/identification/protocols.py); loading it
    # cost the node ~0.3 s of start-up (bench/startup.py).
    code = "import sys, pma_model_ros.nodes.model_node; print('scipy.optimize' in sys.modules)"
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == 'False'


def received(ago: float) -> dict:
    """A message info as the single-threaded executor hands it over: written and received
    ``ago`` [s] ago (rmw's ``source_timestamp`` and ``received_timestamp``, system clock [ns]).
    """
    t = time.time_ns() - round(ago * 1e9)
    return {'source_timestamp': t, 'received_timestamp': t}


def test_an_input_that_waited_in_its_queue_is_skipped_and_counted(make_node):
    """A node that fell behind takes inputs that DDS received long ago: one that waited longer
    than max_queue_delay (5 ms by default) is counted as received and skipped, unread, and the
    next one in time is answered; each answer's delay since reception is reported, and past
    max_answer_delay (20 ms) it holds the level at WARN.
    """
    node = make_node(CONFIGS['DMSP-10-250'])
    node.engine.health.report_interval = 0
    estimates, diagnostics = record(node._estimate_pubs[0]), record(node._diag_pub)
    stamp = frozen_clock(node)
    node._on_state(0, raw(state(stamp, 0.23, 0.0)), received(0.0))
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + 300e3)), received(1.0))  # waited 1 s
    assert estimates == []
    counts = node.engine.counts(0)
    assert counts['received pressure'] == 1 and counts['skipped behind'] == 1
    assert 'rejected pressure' not in counts  # skipped, not judged
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + 300e3)), received(0.0))
    assert [m.wrench.force.x for m in estimates] == pytest.approx(
        [float(MARTENS.force(300e3, 0.23).force)], rel=1e-9
    )
    status = diagnostics[-1].status[0]  # the report of the change to OK, with this answer
    values = {kv.key: kv.value for kv in status.values}
    assert status.message == 'estimating' and float(values['answer delay max [ms]']) < 20
    assert values['skipped behind'] == '1'
    # an answer 30 ms after the reception of its input (the callback itself was slow)
    node._on_state(0, raw(state(stamp, 0.23, 0.0)), received(0.03))
    assert node.engine.counts(0)['skipped behind'] == 2  # 30 ms > 5 ms in the queue: skipped
    node._max_queue_delay = 10**9  # let it through: its answer is then 30 ms late
    node._on_state(0, raw(state(stamp, 0.23, 0.0)), received(0.03))
    level, message = node.engine.level(0, node.now())
    assert level == 1 and message.startswith('answers late: ')
    assert '(max_answer_delay 20 ms)' in message
    assert float(message.split()[2]) >= 30.0
    assert diagnostics[-1].status[0].message == message


def test_without_reception_times_nothing_is_skipped(make_node):
    """The callbacks as the events executor calls them (no message info): every input is read,
    and no answer delay is reported.
    """
    node = make_node(CONFIGS['DMSP-10-250'], executor='events')
    assert not node.reception_times
    estimates = record(node._estimate_pubs[0])
    stamp = frozen_clock(node)
    node._on_state(0, raw(state(stamp, 0.23, 0.0)))
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + 300e3)))
    assert len(estimates) == 1
    assert 'answer delay max [ms]' not in node.engine.statuses(node.now())[0].values
    assert all(s._callback_type.name == 'MessageOnly' for s in node.subscriptions)


def test_the_single_executor_hands_sensor_inputs_their_reception_times(make_node):
    node = make_node(EXAMPLE, input_mode='combined')
    kinds = {s.topic_name: s._callback_type.name for s in node.subscriptions}
    assert kinds == {
        '/muscle_pressures': 'WithMessageInfo',
        '/muscle_states': 'WithMessageInfo',
        '/force_commands': 'MessageOnly',  # reliable commands: never skipped
    }


def test_combined_inputs_skipped_and_answered_for_every_muscle(make_node):
    node = make_node(EXAMPLE)
    estimates = record(node._estimate_pubs[0])
    stamp = frozen_clock(node)
    lengths = [INPUTS[n][2] for n in INPUTS]
    node._on_states(raw(joint_states(stamp, INPUTS, lengths)), received(1.0))
    assert [node.engine.counts(k)['skipped behind'] for k in range(4)] == [1, 1, 1, 1]
    node._on_states(raw(joint_states(stamp, INPUTS, lengths)), received(0.0))
    pressures = [AMBIENT + v[1] for v in INPUTS.values()]
    node._on_pressures(raw(joint_states(stamp, INPUTS, pressures)), received(0.0))
    assert len(estimates) == 1
    values = [s.values for s in node.engine.statuses(node.now())]
    assert all(float(v['answer delay max [ms]']) < 20 for v in values)


@pytest.fixture
def logged(monkeypatch):
    """The lines the nodes log from now on, as (severity, text)."""
    from rclpy.impl.rcutils_logger import RcutilsLogger

    lines = []
    for severity in ('info', 'warning'):
        monkeypatch.setattr(
            RcutilsLogger,
            severity,
            lambda self, text, severity=severity, **_: lines.append((severity, text)),
        )
    return lines


def test_faults_are_logged_once_a_second_per_cause(make_node, logged):
    """660 NaN pressures in one second: one WARN line; a second later, another."""
    node = make_node(CONFIGS['DMSP-10-250'])
    node.engine.health.report_interval = 0
    stamp = frozen_clock(node)
    node._on_state(0, raw(state(stamp, 0.23, 0.0)))
    for _ in range(660):
        node._on_pressure(0, raw(pressure(stamp, math.nan)))
        node._on_timer()  # the 1 Hz report, here as often as the inputs
    faults = [text for severity, text in logged if severity == 'warning']
    nan = 'DMSP-10-250: invalid input: pressure is nan Pa'
    assert faults == ['DMSP-10-250: no pressure received yet', nan]
    t = node.now() + 10**9
    node.now = lambda: t
    node._on_pressure(0, raw(pressure(stamp, math.nan)))
    node._on_timer()
    assert [text for severity, text in logged if severity == 'warning'][2:] == [nan]


def test_a_parameter_change_is_logged(make_node, logged):
    node = make_node(CONFIGS['DMSP-10-250'])
    assert node.set_parameters([Parameter('model', value='hildebrandt')])[0].successful
    assert ('info', "parameters set: model = 'hildebrandt'") in logged


def callback_of(node, topic: str):
    """The callback of ``node``'s subscription of ``topic``: what the executor calls."""
    return next(s.callback for s in node.subscriptions if s.topic_name == topic)


def test_forward_commands_are_the_pressure_commands_in_the_configured_order(make_node):
    """``forward_command_topic``, combined: one Float64MultiArray per force_commands message that
    commanded a muscle, every value the muscle's pressure command (absolute Pa) in
    ``forward_command_order`` (by joint_name); nothing until every muscle had a command, then the
    others' last values.  Each value gives the wanted tension at the muscle's length.
    """
    order = ['finger', 'biceps', 'wrist_flexor', 'triceps']
    node = make_node(
        EXAMPLE,
        forward_command_topic='muscle_controller/commands',
        forward_command_order=order,
    )
    assert node._forward_pub.topic_name == '/muscle_controller/commands'
    forward, pressures = record(node._forward_pub), record(node._command_pubs[0])
    stamp = frozen_clock(node)
    node._on_states(raw(joint_states(stamp, INPUTS, [v[2] for v in INPUTS.values()])))
    on_commands = callback_of(node, '/force_commands')
    on_commands(raw(JointState(name=['biceps', 'finger'], effort=[100.0, 20.0])))
    assert len(pressures) == 1 and forward == []  # triceps and wrist_flexor never commanded
    wanted = {'biceps': 150.0, 'triceps': 300.0, 'wrist_flexor': 80.0, 'finger': 40.0}
    on_commands(raw(JointState(name=list(wanted), effort=list(wanted.values()))))
    on_commands(raw(JointState(name=['triceps'], effort=[200.0])))
    assert len(forward) == 2
    both = [dict(zip(p.name, p.position)) for p in pressures[1:]]
    assert list(forward[0].data) == [both[0][m] for m in order]
    assert list(forward[1].data) == [both[0][m] for m in order[:3]] + [both[1]['triceps']]
    forces = expected_forces(
        {
            m: (INPUTS[m][0], forward[0].data[i] - AMBIENT, INPUTS[m][2], 0.0)
            for i, m in enumerate(order)
        }
    )
    assert forces == pytest.approx(wanted, abs=1e-6)  # [N]


def test_one_muscle_forwards_its_pressure_command(make_node):
    """One muscle, ``forward_command_order`` empty: the array holds its one pressure command."""
    node = make_node(CONFIGS['DMSP-10-250'], forward_command_topic='pressure_controller/commands')
    forward, commands = record(node._forward_pub), record(node._command_pubs[0])
    now = frozen_clock(node)
    node._on_state(0, raw(state(now, 0.23, 0.0)))
    callback_of(node, '/force_command')(raw(force_command(100.0)))
    assert [list(m.data) for m in forward] == [[commands[-1].fluid_pressure]]
    gauge = forward[0].data[0] - AMBIENT
    assert float(MARTENS.force(gauge, 0.23).force) == pytest.approx(100.0, abs=1e-6)


def test_a_bad_model_node_forward_command_order_fails_configure(make_node):
    from pma_model_ros.nodes.startup import StartupError

    with pytest.raises(StartupError, match=r"'bicep' is no muscle's joint_name \(did you mean"):
        make_node(EXAMPLE, forward_command_topic='c/commands', forward_command_order=['bicep'])
