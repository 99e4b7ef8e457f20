"""The forward_command_controller array of joint_node (wire/forward_commands.py), without ROS
nodes: which commands make a message, its order and its bytes.
"""

from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64MultiArray

from pma_model_ros.wire.forward_commands import ForwardCommands

#: Two joints' muscles (each joint's in the order of its pressure commands).
MUSCLES = [['a_flexor', 'a_extensor'], ['b_flexor', 'b_extensor']]


def data(message: bytes) -> list[float]:
    msg = deserialize_message(message, Float64MultiArray)
    assert list(msg.layout.dim) == [] and msg.layout.data_offset == 0
    return list(msg.data)


def test_nothing_until_every_muscle_of_the_order_had_a_command_then_the_others_held():
    forward = ForwardCommands(['b_extensor', 'a_flexor', 'b_flexor', 'a_extensor'], MUSCLES)
    forward.command(0, (300e3, 200e3))
    assert forward.message() is None  # joint b never commanded
    forward.command(1, (150e3, 250e3))
    assert data(forward.message()) == [250e3, 300e3, 150e3, 200e3]
    assert forward.message() is None  # no new command since
    forward.command(0, (310e3, 210e3))  # joint a alone: b's last values repeated
    assert data(forward.message()) == [250e3, 310e3, 150e3, 210e3]
    forward.command(0, (310e3, 210e3))  # the same values again: still one message per command
    assert data(forward.message()) == [250e3, 310e3, 150e3, 210e3]


def test_an_order_of_some_muscles_ignores_the_others():
    forward = ForwardCommands(['b_flexor'], MUSCLES)
    forward.command(0, (300e3, 200e3))
    assert forward.message() is None  # nothing of the order commanded
    forward.command(1, (150e3, 250e3))
    assert data(forward.message()) == [150e3]
