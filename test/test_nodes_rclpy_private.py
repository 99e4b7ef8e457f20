"""The private rclpy names of nodes/rclpy_private.py still mean what the package takes them for:
each test fails if an rclpy update renames or changes one.  And no other module uses a private
rclpy name.
"""

import re
import time

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import FluidPressure

from conftest import CONFIGS, REPO
from pma_model_ros.nodes import rclpy_private
from pma_model_ros.nodes.model_node import ModelNode

pytestmark = pytest.mark.ros


def test_rcl_error_is_what_rclpy_raises_for_a_file_rcl_cannot_parse(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**: {ros__parameters: [1, 2')
    context = rclpy.Context()
    with pytest.raises(rclpy_private.RCLError):
        rclpy.init(context=context, args=['--ros-args', '--params-file', str(bad)])
    assert issubclass(rclpy_private.RCLError, Exception)


def test_parameter_overrides_hold_what_was_set_declared_or_not(private_node):
    node = private_node(
        rclpy.node.Node, '-p', 'a.b:=2.5', overrides={'c': 'x'}, node_name='overridden'
    )
    overrides = rclpy_private.parameter_overrides(node)
    assert {name: p.value for name, p in overrides.items()} == {'a.b': 2.5, 'c': 'x'}
    assert all(isinstance(p, Parameter) for p in overrides.values())


def test_the_clock_handle_reads_the_clock_in_nanoseconds(private_node):
    clock = private_node(rclpy.node.Node, node_name='clocked').get_clock()
    before = clock.now().nanoseconds
    read = rclpy_private.clock_handle(clock).get_now().nanoseconds
    assert isinstance(read, int) and before <= read <= clock.now().nanoseconds


def test_a_transition_the_state_has_not_is_answered_false(private_node):
    """The change_state service (found by its type, public API) answers ``success: false``: the
    RCLError that rclpy raises there is caught.
    """
    node = private_node(
        ModelNode, '--params-file', CONFIGS['DMSP-10-250'], overrides={'autostart': False}
    )
    service = next(s for s in node.services if s.srv_type is ChangeState)
    request = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_ACTIVATE))
    assert service.callback(request, ChangeState.Response()).success is False
    request = ChangeState.Request(transition=Transition(label='configure'))
    assert service.callback(request, ChangeState.Response()).success is True


def test_the_state_and_its_transitions_are_read(private_node):
    """An unconfigured lifecycle node has configure (1) and shutdown (5), lifecycle_msgs'
    Transition ids.
    """
    node = private_node(
        ModelNode, '--params-file', CONFIGS['DMSP-10-250'], overrides={'autostart': False}
    )
    state, transitions = rclpy_private.lifecycle_state(node)
    assert state == 'unconfigured'
    assert (Transition.TRANSITION_CONFIGURE, 'configure') in transitions
    assert (Transition.TRANSITION_UNCONFIGURED_SHUTDOWN, 'shutdown') in transitions
    assert all(label != 'activate' for _, label in transitions)


def test_no_other_module_uses_a_private_rclpy_name():
    private = re.compile(
        r'rclpy\._|_rclpy_pybind11|_parameter_overrides|_service_change_state|_state_machine'
        r'|\.handle\b'
    )
    users = [
        path.relative_to(REPO).as_posix()
        for path in (REPO / 'pma_model_ros').rglob('*.py')
        if private.search(path.read_text()) and path.name != 'rclpy_private.py'
    ]
    assert users == []


def test_take_returns_waiting_messages_with_their_info_then_none(private_node):
    """What the executor's take does: the raw bytes and DDS's info of each waiting message, in
    order, then None.
    """
    node = private_node(rclpy.node.Node, node_name='taker')
    sub = node.create_subscription(FluidPressure, 'taken', lambda _: None, 10, raw=True)
    pub = node.create_publisher(FluidPressure, 'taken', 10)
    deadline = time.monotonic() + 10
    while not pub.get_subscription_count() and time.monotonic() < deadline:
        time.sleep(0.01)
    for value in (1.0, 2.0, 3.0):
        pub.publish(FluidPressure(fluid_pressure=value))
    taken = []
    while len(taken) < 3 and time.monotonic() < deadline:
        if (message := rclpy_private.take(sub)) is not None:
            taken.append(message)
    values = [deserialize_message(data, FluidPressure).fluid_pressure for data, _ in taken]
    assert values == [1.0, 2.0, 3.0]
    assert all(info['received_timestamp'] >= info['source_timestamp'] > 0 for _, info in taken)
    assert rclpy_private.take(sub) is None
