r"""The demo's pair: simulator_node (a muscle whose force is its measured map, sweeping pressure
and length) and model_node estimating it, in one namespace.

    ros2 launch pma_model_ros simulator_demo.launch.py
    ros2 launch pma_model_ros simulator_demo.launch.py muscle:=DMSP-20-300 \\
        params_file:=install/pma_model_ros/share/pma_model_ros/config/dmsp_20_300.yaml

Arguments: ``muscle`` (the simulated muscle: DMSP-10-250 or DMSP-20-300, the shipped maps),
``params_file`` (model_node's parameter file, of the same muscle), ``namespace`` (default
``demo``), ``autostart`` (model_node's, as in model_node.launch.py).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import LifecycleNode, Node
from launch_ros.descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    """The launch arguments and the two nodes."""
    shipped = PathJoinSubstitution(
        [FindPackageShare('pma_model_ros'), 'config', 'dmsp_10_250.yaml']
    )
    namespace = LaunchConfiguration('namespace')
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'muscle', default_value='DMSP-10-250', description='simulated muscle'
            ),
            DeclareLaunchArgument(
                'params_file', default_value=shipped, description='model_node parameter file'
            ),
            DeclareLaunchArgument('namespace', default_value='demo', description='namespace'),
            DeclareLaunchArgument(
                'autostart',
                default_value='true',
                description="model_node's autostart (false: wait for a manager)",
            ),
            Node(
                package='pma_model_ros',
                executable='simulator_node',
                name='simulator_node',
                namespace=namespace,
                parameters=[{'muscle': LaunchConfiguration('muscle'), 'trajectory': 'sweep'}],
                output='screen',
            ),
            LifecycleNode(
                package='pma_model_ros',
                executable='model_node',
                name='model_node',
                namespace=namespace,
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
