"""One joint_node with its muscles, as a managed (lifecycle) node.

    ros2 launch pma_model_ros joint_node.launch.py params_file:=my_joint.yaml namespace:=arm

Arguments: ``params_file`` (a joint_node parameter file, default the shipped example elbow:
config/example_joint.yaml, whose muscle files are the shipped config/dmsp_10_250.yaml),
``namespace`` (default none), ``autostart`` (as in model_node.launch.py).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import LifecycleNode
from launch_ros.descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    """The launch arguments and the node."""
    shipped = PathJoinSubstitution(
        [FindPackageShare('pma_model_ros'), 'config', 'example_joint.yaml']
    )
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'params_file', default_value=shipped, description='joint_node parameter file'
            ),
            DeclareLaunchArgument('namespace', default_value='', description='node namespace'),
            DeclareLaunchArgument(
                'autostart',
                default_value='true',
                description='configure and activate at start-up (false: wait for a manager)',
            ),
            LifecycleNode(
                package='pma_model_ros',
                executable='joint_node',
                name='joint_node',
                namespace=LaunchConfiguration('namespace'),
                parameters=[
                    LaunchConfiguration('params_file'),
                    {
                        'autostart': ParameterValue(
                            LaunchConfiguration('autostart'), value_type=bool
                        )
                    },
                ],
                output='screen',
            ),
        ]
    )
