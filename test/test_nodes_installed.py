"""The colcon install tree: the installed model_node, started as `ros2 run` would, estimates
force; the installed joint_node finds its shipped muscle files.
"""

import time

from geometry_msgs.msg import WrenchStamped
import pytest
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from node_messages import AMBIENT, pressure, state
from pma_model_ros.core.files.param_file import muscle_model, read_parameters

pytestmark = pytest.mark.ros


def test_installed_model_node_estimates(colcon_install, ros, processes, namespace):
    prefix = colcon_install['prefix']
    config = prefix / 'share/pma_model_ros/config/dmsp_10_250.yaml'
    node = processes.start(
        [
            prefix / 'lib/pma_model_ros/model_node',
            '--ros-args',
            '-r',
            f'__ns:={namespace}',
            '--params-file',
            config,
        ],
        env=colcon_install['env'],
        cwd=colcon_install['tmp'],
    )
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    pressure_pub = ros.node.create_publisher(
        FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data
    )
    state_pub = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_state', qos_profile_sensor_data
    )

    def publish():
        stamp = ros.now().to_msg()
        pressure_pub.publish(pressure(stamp, AMBIENT + 400e3))
        state_pub.publish(state(stamp, 0.24))

    ros.spin_until(
        lambda: estimates,
        30,
        'an estimate from the installed model_node',
        every=publish,
        diagnose=lambda: processes.output(node),
    )
    expected = float(muscle_model(read_parameters(config)).force(400e3, 0.24).force)
    assert estimates[-1].wrench.force.x == pytest.approx(expected, rel=1e-9)
    assert estimates[-1].header.frame_id == 'dmsp_10_250'


def test_installed_joint_node_finds_the_shipped_muscle_files(colcon_install, processes, namespace):
    """Without ``config_dir``, from a directory outside the source tree: the example joint's
    relative muscle files come from the install's share directory (ament_index).
    """
    prefix = colcon_install['prefix']
    config = prefix / 'share/pma_model_ros/config/example_joint.yaml'
    node = processes.start(
        [prefix / 'lib/pma_model_ros/joint_node', '--ros-args', '-r', f'__ns:={namespace}']
        + ['--params-file', config],
        env=colcon_install['env'],
        cwd=colcon_install['tmp'],
    )
    deadline = time.monotonic() + 30
    while "joint 'elbow': flexor (hildebrandt)" not in processes.output(node):
        assert node.poll() is None and time.monotonic() < deadline, processes.output(node)
        time.sleep(0.1)
