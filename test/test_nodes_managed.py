"""model_node and joint_node as managed (lifecycle) nodes (nodes/managed.py).

In-process, on private Contexts: the transitions called directly, the callbacks fed bytes, what the
publishers publish recorded.  Then once over DDS: a model_node process started with
``autostart:=false``, driven from this process through the standard ``lifecycle_msgs`` services.
"""

import time

from diagnostic_msgs.msg import DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
import pytest
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.parameter import Parameter
from test_nodes_joint_node import command, joint_state
from test_nodes_joint_node import pressure as joint_pressure
from test_nodes_model_node import frozen_clock

from conftest import CONFIGS, edited_copy, REPO
from node_messages import (
    AMBIENT,
    force_command,
    pressure,
    raw,
    record,
    RELIABLE_QOS,
    SENSOR_QOS,
    stamp_key,
    state,
)
from pma_model_ros.nodes.joint_node import JointNode
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.nodes.startup import StartupError

CONFIG = CONFIGS['DMSP-10-250']
EXAMPLE_JOINT = REPO / 'config' / 'example_joint.yaml'
SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


@pytest.fixture
def make(private_node):
    """A factory of managed nodes (class, parameter file, overrides) on their own Contexts."""

    def make(cls, params_file, **overrides):
        return private_node(cls, '--params-file', params_file, overrides=overrides)

    return make


@pytest.fixture
def errors(monkeypatch):
    """The error lines the nodes log from now on."""
    logged = []
    monkeypatch.setattr(RcutilsLogger, 'error', lambda self, text, **_: logged.append(text))
    return logged


def label(node) -> str:
    return node._state_machine.current_state[1]


def entities(node) -> set[str]:
    """The topics of the node's publishers and subscriptions, and how many timers it has."""
    return {
        *(f'pub {p.topic_name}' for p in node.publishers),
        *(f'sub {s.topic_name}' for s in node.subscriptions),
        f'{len(list(node.timers))} timers',
    }


def inactive(diagnostics: list) -> bool:
    """Whether every status of ``diagnostics`` (one at least) says the node is inactive."""
    statuses = [s for d in diagnostics for s in d.status]
    return bool(statuses) and all(
        (s.level, s.message) == (DiagnosticStatus.OK, 'inactive') for s in statuses
    )


def feed_model_node(node, stamp, force: float = 100.0) -> None:
    """A pressure, a length and a force command, as bytes into the callbacks."""
    node._on_pressure(0, raw(pressure(stamp, AMBIENT + 300e3)))
    node._on_state(0, raw(state(stamp, 0.23, 0.0)))
    node._on_command(0, raw(force_command(force)))


def test_model_node_goes_through_every_transition(make):
    node = make(ModelNode, CONFIG, autostart=False)
    bare = entities(node)
    assert label(node) == 'unconfigured' and node.engine is None
    assert node.trigger_configure() == SUCCESS and label(node) == 'inactive'
    # timers: the 1 Hz report's and live re-identification's (nodes/live_reidentification.py)
    assert {'sub /pressure', 'sub /muscle_state', 'pub /pressure_command', '2 timers'} <= (
        entities(node) - bare
    )
    estimates, commands = record(node._estimate_pubs[0]), record(node._command_pubs[0])
    diagnostics = record(node._diag_pub)
    now = frozen_clock(node)
    feed_model_node(node, now)  # inactive: dropped unread
    node._on_timer()
    assert (estimates, commands) == ([], []) and inactive(diagnostics)
    assert node.engine.counts(0) == {}

    assert node.trigger_activate() == SUCCESS and label(node) == 'active'
    feed_model_node(node, now)
    node._on_timer()
    assert len(estimates) == 1 and len(commands) == 1 and diagnostics
    assert node.engine.counts(0)['estimates'] == 1

    assert node.trigger_deactivate() == SUCCESS and label(node) == 'inactive'
    assert node.engine.counts(0) == {}  # a fresh engine: nothing known
    sent = len(diagnostics)
    feed_model_node(node, now, force=200.0)
    node._on_timer()
    assert (len(estimates), len(commands), len(diagnostics)) == (1, 1, sent + 1)
    assert inactive(diagnostics[sent:])

    assert node.trigger_activate() == SUCCESS
    node._on_command(0, raw(force_command(100.0)))  # no length known since the activation
    assert len(commands) == 1
    feed_model_node(node, now)
    assert len(estimates) == 2 and len(commands) == 2

    assert node.trigger_deactivate() == SUCCESS and node.trigger_cleanup() == SUCCESS
    assert label(node) == 'unconfigured' and node.engine is None and entities(node) == bare
    assert node.trigger_configure() == SUCCESS and node.trigger_activate() == SUCCESS
    estimates = record(node._estimate_pubs[0])
    feed_model_node(node, now)
    assert len(estimates) == 1
    assert node.trigger_shutdown() == SUCCESS and label(node) == 'finalized'
    assert node.engine is None and entities(node) == bare


def test_a_parameter_changed_while_unconfigured_is_read_by_the_next_configure(make):
    node = make(ModelNode, CONFIG, autostart=False)
    assert node.trigger_configure() == SUCCESS and node.trigger_cleanup() == SUCCESS
    assert node.set_parameters([Parameter('model', value='hildebrandt')])[0].successful
    assert node.trigger_configure() == SUCCESS
    assert node.engine.configs[0].model.model.name == 'hildebrandt'


@pytest.mark.parametrize(
    'old, new, reason',
    [
        (
            'max_input_age: 0.1',
            'max_input_age: -1.0',
            "parameter 'max_input_age' must be in [0.001, 3600] s",
        ),
        ('    model: martens', '    model: foo', "parameter 'model': unknown model 'foo'"),
    ],
)
def test_a_bad_file_fails_configure_and_leaves_the_node_unconfigured(
    make, errors, tmp_path, old, new, reason
):
    node = make(ModelNode, edited_copy(CONFIG, tmp_path, old, new), autostart=False)
    bare = entities(node)
    for _ in range(2):  # and again: nothing of the first attempt is left behind
        assert node.trigger_configure() == FAILURE
        assert label(node) == 'unconfigured' and node.engine is None and entities(node) == bare
    assert len(errors) == 2 and errors[0] == errors[1]
    assert errors[0].startswith('invalid parameters: ') and reason in errors[0]
    assert '\n' not in errors[0] and reason in node.refusal
    assert node.trigger_shutdown() == SUCCESS and label(node) == 'finalized'


def test_an_unexpected_error_in_configure_is_logged_and_released(make, errors, monkeypatch):
    """A bug in configure (not a bad parameter): its traceback logged, the transition's error
    processing releases what was built, and the node is unconfigured again.
    """
    node = make(ModelNode, CONFIG, autostart=False)
    bare = entities(node)
    built = ModelNode.configure

    def broken(self):
        built(self)
        raise RuntimeError('a bug')

    monkeypatch.setattr(ModelNode, 'configure', broken)
    assert node.trigger_configure() == TransitionCallbackReturn.ERROR
    assert label(node) == 'unconfigured' and node.engine is None and entities(node) == bare
    assert len(errors) == 1 and 'RuntimeError: a bug' in errors[0] and 'Traceback' in errors[0]
    assert node.refusal == 'configure raised RuntimeError: a bug (traceback logged)'
    monkeypatch.undo()
    assert node.trigger_configure() == SUCCESS


def test_with_autostart_a_bad_file_raises_at_construction_without_logging(make, errors, tmp_path):
    """run() logs the one FATAL line (test_nodes_startup, test_bad_input_matrix)."""
    with pytest.raises(StartupError, match="unknown model 'foo'") as refused:
        make(ModelNode, edited_copy(CONFIG, tmp_path, '    model: martens', '    model: foo'))
    assert errors == [] and refused.value.what == 'invalid parameters'


def test_with_autostart_a_bug_in_configure_is_not_called_invalid_parameters(
    make, errors, monkeypatch
):
    """run()'s FATAL line is ``configure failed: configure raised ...``, after the traceback."""
    built = ModelNode.configure

    def broken(self):
        built(self)
        raise RuntimeError('a bug')

    monkeypatch.setattr(ModelNode, 'configure', broken)
    with pytest.raises(StartupError) as failed:
        make(ModelNode, CONFIG)
    assert failed.value.what == 'configure failed'
    assert str(failed.value) == 'configure raised RuntimeError: a bug (traceback logged)'
    assert len(errors) == 1 and 'Traceback' in errors[0]


@pytest.fixture
def warnings(monkeypatch):
    """The warning lines the nodes log from now on."""
    logged = []
    monkeypatch.setattr(RcutilsLogger, 'warning', lambda self, text, **_: logged.append(text))
    return logged


def change_state(node, transition: str | int) -> bool:
    """A ``change_state`` service call, as a lifecycle manager's arrives (the callback)."""
    service = next(s for s in node.services if s.srv_type is ChangeState)
    request = ChangeState.Request(
        transition=Transition(label=transition)
        if isinstance(transition, str)
        else Transition(id=transition)
    )
    return service.callback(request, ChangeState.Response()).success


def test_a_refused_transition_says_why(make, warnings):
    """A manager's ``configure`` of a node that autostart already activated (nav2's default
    sequence with the node's default) is refused with the state, its transitions and the cure;
    a transition the state has is not warned about.
    """
    node = make(ModelNode, CONFIG)  # autostart: true
    assert label(node) == 'active'
    assert change_state(node, 'configure') is False
    assert len(warnings) == 1
    assert "change_state 'configure' refused: the node is active" in warnings[0]
    assert 'deactivate (4)' in warnings[0] and 'autostart: false' in warnings[0]
    assert change_state(node, Transition.TRANSITION_ACTIVATE) is False  # by id
    assert 'change_state 3 refused: the node is active' in warnings[1]
    assert 'autostart' not in warnings[1]
    assert change_state(node, 'deactivate') is True and len(warnings) == 2


def test_autostart_is_read_only_and_defaults_to_true(make):
    node = make(ModelNode, CONFIG)
    assert label(node) == 'active' and node.get_parameter('autostart').value is True
    assert not node.set_parameters([Parameter('autostart', value=False)])[0].successful


def test_joint_node_commands_only_while_active(make):
    node = make(JointNode, EXAMPLE_JOINT, autostart=False)
    assert label(node) == 'unconfigured' and node.trigger_configure() == SUCCESS
    flexor, torques = record(node._command_pubs[0][0]), record(node._torque_pub)

    def feed():
        node._on_pressure(0, 0, raw(joint_pressure(node, AMBIENT + 400e3)))
        node._on_pressure(0, 1, raw(joint_pressure(node, AMBIENT + 300e3)))
        node._on_states(raw(joint_state(node, 0.5)))
        node._on_level('stiffness_command', raw(command(elbow=4.5)))
        node._on_torque(raw(command(elbow=1.0)))

    feed()
    assert (flexor, torques) == ([], [])
    assert node.trigger_activate() == SUCCESS
    feed()
    assert len(flexor) == 1 and len(torques) == 1
    assert node.engine.statuses(node.now())[0].values['commands'].startswith('stiffness 4.5')
    assert node.trigger_deactivate() == SUCCESS
    feed()
    assert len(flexor) == 1 and len(torques) == 1
    assert node.trigger_activate() == SUCCESS
    # fresh: the parameters' co-contraction again, no angle known
    assert node.engine.statuses(node.now())[0].values['commands'].startswith('co-contraction')
    node._on_torque(raw(command(elbow=1.0)))
    assert len(flexor) == 1
    assert node.trigger_shutdown() == SUCCESS and node.engine is None


def test_parameters_are_declared_before_configure_and_read_by_it(make):
    """As a lifecycle manager expects: every parameter exists while unconfigured (listed, set
    with the node's own validation), and configure reads the values set then.
    """
    node = make(ModelNode, CONFIG, autostart=False)
    assert label(node) == 'unconfigured'
    assert {'max_input_age', 'model', 'models.martens.params', 'muscle.max_pressure'} <= set(
        node.list_parameters([], 0).names
    )
    assert node.set_parameters([Parameter('max_input_age', value=0.25)])[0].successful
    refused = node.set_parameters([Parameter('model', value='foo')])[0]
    assert not refused.successful and "unknown model 'foo'" in refused.reason
    assert node.trigger_configure() == SUCCESS
    assert node.engine.configs[0].max_input_age == 0.25
    joint = make(JointNode, EXAMPLE_JOINT, autostart=False)
    assert joint.get_parameter('elbow.cocontraction').value is not None


@pytest.mark.parametrize(
    'cls, params_file, name',
    [
        (ModelNode, CONFIG, 'DMSP-10-250'),
        (JointNode, EXAMPLE_JOINT, 'elbow'),
    ],
)
def test_while_inactive_the_status_timer_says_inactive(make, cls, params_file, name):
    """Configured but not active: one status per muscle or joint at level OK, ``inactive``, from
    the status timer; none while unconfigured.
    """
    node = make(cls, params_file, autostart=False)
    assert node.trigger_configure() == SUCCESS
    diagnostics = record(node._diag_pub)
    node._on_timer()
    assert [s.name.split(': ')[1] for s in diagnostics[-1].status] == [name]
    assert inactive(diagnostics[-1:])
    assert node.trigger_activate() == SUCCESS
    node._on_timer()
    assert diagnostics[-1].status[0].message != 'inactive'
    assert node.trigger_deactivate() == SUCCESS
    node._on_timer()
    assert inactive(diagnostics[-1:])


# --- over DDS, from a second process
def lifecycle(ros, node_name: str):
    """(change(transition label or id) -> success, get() -> state label) of ``node_name``'s
    services.
    """

    def change(transition: str | int) -> bool:
        request = ChangeState.Request(
            transition=Transition(label=transition)
            if isinstance(transition, str)
            else Transition(id=transition)
        )
        return ros.call(ChangeState, f'{node_name}/change_state', request).success

    def get() -> str:
        return ros.call(GetState, f'{node_name}/get_state', GetState.Request()).current_state.label

    return change, get


@pytest.mark.ros
@pytest.mark.parametrize('executor', ['events', 'single'])
def test_lifecycle_services_from_another_process(ros, processes, namespace, executor):
    """model_node (a process, autostart false) answers only while active, driven through
    ``<node>/change_state`` (by label, as docs/nodes.md shows) and ``<node>/get_state``.
    """
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import FluidPressure, JointState

    proc = processes.node('model_node', namespace, CONFIG, autostart='false', executor=executor)
    why = lambda: processes.output(proc)  # noqa: E731
    node = f'{namespace}/model_node'
    change, get = lifecycle(ros, node)
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate', RELIABLE_QOS)
    commands = ros.collect(FluidPressure, f'{namespace}/pressure_command', RELIABLE_QOS)
    pressure_pub = ros.node.create_publisher(FluidPressure, f'{namespace}/pressure', SENSOR_QOS)
    state_pub = ros.node.create_publisher(JointState, f'{namespace}/muscle_state', SENSOR_QOS)
    command_pub = ros.node.create_publisher(
        WrenchStamped, f'{namespace}/force_command', RELIABLE_QOS
    )

    def publish():
        stamp = ros.now().to_msg()
        pressure_pub.publish(pressure(stamp, AMBIENT + 300e3))
        state_pub.publish(state(stamp, 0.23, 0.0))
        command_pub.publish(force_command(100.0))

    def quiet_for(seconds: float, what: str) -> None:
        """Publish inputs and commands for ``seconds`` (a deadline loop): nothing may answer."""
        end = time.monotonic() + seconds
        ros.spin_until(lambda: time.monotonic() > end, seconds + 5, what, every=publish)
        assert (estimates, commands) == ([], []), what

    def entities() -> tuple[int, int]:
        """The node's subscribers of its pressure and publishers of its estimate, as discovered."""
        return (
            ros.node.count_subscribers(f'{namespace}/pressure'),
            ros.node.count_publishers(f'{namespace}/force_estimate'),
        )

    assert get() == 'unconfigured'
    print(f'\n{node}: {get()}')
    # a transition the state does not have is refused (rclpy alone raised, ending the process)
    assert not change(Transition.TRANSITION_ACTIVATE) and get() == 'unconfigured', why()
    print(f'{node}: activate refused while unconfigured')
    quiet_for(1.0, 'inputs while unconfigured')
    # (the node answered get_state: it is discovered; the same count sees its entities once
    # configured, and sees them go at cleanup, below)
    assert entities() == (0, 0), 'entities of an unconfigured node'
    for transition, expected in (('configure', 'inactive'), ('activate', 'active')):
        assert change(transition), why()
        assert get() == expected
        print(f'{node}: {expected}')
        if expected == 'inactive':  # its entities exist and are matched: inputs reach it
            ros.spin_until(lambda: min(entities()) >= 1, 20, 'the configured node', diagnose=why)
            quiet_for(1.0, 'inputs while inactive')
    ros.spin_until(lambda: estimates and commands, 20, 'an estimate and a command', every=publish)
    print(f'  active: {len(estimates)} estimates, {len(commands)} pressure commands')

    assert change('deactivate') and get() == 'inactive'
    deactivated = ros.now().nanoseconds
    print(f'{node}: inactive')
    end = time.monotonic() + 1.0
    ros.spin_until(lambda: time.monotonic() > end, 10, 'inputs while inactive', every=publish)
    late = [e for e in estimates if stamp_key(e) >= deactivated]
    late += [c for c in commands if stamp_key(c) >= deactivated]
    assert late == [], 'answers to inputs sent after the deactivation'
    print('  inputs for 1 s after deactivate: 0 estimates, 0 pressure commands')

    assert change('activate') and get() == 'active'
    count = len(estimates)
    ros.spin_until(lambda: len(estimates) > count, 20, 'estimates again', every=publish)
    print(f'{node}: active again, estimates resume')
    for transition, expected in (
        ('deactivate', 'inactive'),
        ('cleanup', 'unconfigured'),
        ('shutdown', 'finalized'),
    ):
        assert change(transition), why()
        assert get() == expected
        print(f'{node}: {expected}')
        if expected == 'unconfigured':  # its entities are gone again, as discovered
            ros.spin_until(lambda: entities() == (0, 0), 20, 'the cleaned-up node', diagnose=why)
    assert proc.poll() is None, why()


def test_the_docs_name_the_lifecycle_services():
    """docs/nodes.md, "Managed nodes", gives the service calls of ``ros2 lifecycle set``."""
    text = (REPO / 'docs' / 'nodes.md').read_text(encoding='utf-8')
    section = text.split('## Managed nodes\n', 1)[1].split('\n## ', 1)[0]
    for transition in ('configure', 'activate', 'deactivate', 'cleanup', 'shutdown'):
        assert f'ros2 lifecycle set /left_biceps/model_node {transition}' in section
    assert 'lifecycle_msgs/srv/ChangeState' in section


@pytest.mark.ros
def test_a_lifecycle_managers_sequence_from_another_process(ros, processes, namespace):
    """What nav2's lifecycle_manager or launch_ros does, over the standard services: set a
    parameter before configure, configure, activate, deactivate (/diagnostics says inactive),
    cleanup, shutdown.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.msg import ParameterType, ParameterValue
    from rcl_interfaces.srv import GetParameters, SetParameters

    proc = processes.node('model_node', namespace, CONFIG, autostart='false')
    why = lambda: processes.output(proc)  # noqa: E731
    node = f'{namespace}/model_node'
    change, get = lifecycle(ros, node)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', RELIABLE_QOS)

    def messages() -> list[str]:
        """The messages of this node's statuses so far (its namespace is in their names)."""
        return [s.message for d in diagnostics for s in d.status if namespace[1:] in s.name]

    assert get() == 'unconfigured'
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.25)
    request = SetParameters.Request(parameters=[ParameterMsg(name='max_input_age', value=value)])
    result = ros.call(SetParameters, f'{node}/set_parameters', request).results[0]
    assert result.successful, result.reason
    assert change('configure') and get() == 'inactive', why()
    got = ros.call(
        GetParameters, f'{node}/get_parameters', GetParameters.Request(names=['max_input_age'])
    )
    assert got.values[0].double_value == 0.25
    ros.spin_until(lambda: 'inactive' in messages(), 10, 'an inactive status', diagnose=why)
    assert change('activate') and get() == 'active', why()
    ros.spin_until(
        lambda: messages() and messages()[-1] != 'inactive', 10, 'an active status', diagnose=why
    )
    assert change('deactivate') and get() == 'inactive', why()
    seen = len(messages())
    ros.spin_until(lambda: 'inactive' in messages()[seen:], 10, 'inactive again', diagnose=why)
    assert change('cleanup') and get() == 'unconfigured', why()
    assert change('shutdown') and get() == 'finalized', why()
    assert proc.poll() is None, why()
