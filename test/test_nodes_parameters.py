"""Runtime parameter changes of model_node: validated as a whole, applied without restart."""
import pytest
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS
from node_messages import AMBIENT, pressure, state
from pma_model_ros.core.param_file import muscle_model, read_parameters

pytestmark = pytest.mark.ros


def test_set_parameters_validates_and_swaps_the_model(ros, processes, namespace):
    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'], joint_name='left_biceps')
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    pressure_pub = ros.node.create_publisher(FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data)
    state_pub = ros.node.create_publisher(JointState, f'{namespace}/muscle_state', qos_profile_sensor_data)
    params = read_parameters(CONFIGS['DMSP-10-250'])

    def publish():
        stamp = ros.now().to_msg()
        pressure_pub.publish(pressure(stamp, AMBIENT + 400e3))
        state_pub.publish(state(stamp, 0.24, name='left_biceps'))

    def set_parameters(**values):
        request = SetParameters.Request(parameters=[Parameter(k.replace('__', '.'), value=v).to_parameter_msg()
                                                    for k, v in values.items()])
        return ros.call(SetParameters, f'{namespace}/model_node/set_parameters', request).results[0]

    for name in ('martens', 'sarosi'):
        if name != 'martens':
            result = set_parameters(model=name)
            assert result.successful, result.reason
        expected = float(muscle_model(params, name).force(400e3, 0.24).force)
        estimates.clear()
        ros.spin_until(lambda: estimates and estimates[-1].wrench.force.x == pytest.approx(expected, rel=1e-9),
                       20, f'an estimate of model {name}', every=publish, diagnose=lambda: processes.output(node))

    for values, words in (({'model': 'foo'}, "unknown model 'foo'"),
                          ({'models__sarosi__params': [1.0]}, "model 'sarosi' needs 6"),
                          ({'muscle__inner_diameter': -1.0}, 'out of range'),
                          ({'length_range': [0.25, 0.2]}, 'length range')):
        result = set_parameters(**values)
        assert not result.successful and words in result.reason, (values, result.reason)
    assert node.poll() is None, processes.output(node)
