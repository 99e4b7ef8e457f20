"""One model_node from a parameter file, as a managed (lifecycle) node.

    ros2 launch pma_model_ros model_node.launch.py params_file:=my_muscle.yaml namespace:=biceps
    ros2 launch pma_model_ros model_node.launch.py autostart:=false   # for a lifecycle manager

Arguments: ``params_file`` (a model_node parameter file, default the shipped DMSP-10-250),
``namespace`` (default none), ``autostart`` (true: the node configures and activates itself;
false: it waits unconfigured for a lifecycle manager, docs/nodes.md).
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
        [FindPackageShare('pma_model_ros'), 'config', 'dmsp_10_250.yaml']
    )
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'params_file', default_value=shipped, description='model_node parameter file'
            ),
            DeclareLaunchArgument('namespace', default_value='', description='node namespace'),
            DeclareLaunchArgument(
                'autostart',
                default_value='true',
                description='configure and activate at start-up (false: wait for a manager)',
            ),
            LifecycleNode(
                package='pma_model_ros',
                executable='model_node',
                name='model_node',
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
