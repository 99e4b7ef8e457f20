"""A running node's parameters dumped as ``ros2 param dump`` does (ros2param/verb/dump.py: one
ListParameters call, then one GetParameters call with every listed name, written as
``<node>: ros__parameters: {...}`` with ``yaml.dump``) start a fresh node from that file alone,
which answers the same inputs as the first, to 1e-12.
"""

from geometry_msgs.msg import WrenchStamped
import pytest
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState
from test_nodes_multi_muscle import combined_inputs, expected_forces, INPUTS
import yaml

from conftest import CONFIGS, REPO
from node_messages import AMBIENT, pressure, state
from pma_model_ros.core.files.param_file import muscle_model, read_parameters

pytestmark = pytest.mark.ros

MULTI = REPO / 'config' / 'example_multi_muscle.yaml'
JOINT = REPO / 'config' / 'example_joint.yaml'
#: The fields of a ParameterValue by its type (ros2param.api.get_value).
FIELDS = {
    ParameterType.PARAMETER_BOOL: 'bool_value',
    ParameterType.PARAMETER_INTEGER: 'integer_value',
    ParameterType.PARAMETER_DOUBLE: 'double_value',
    ParameterType.PARAMETER_STRING: 'string_value',
    ParameterType.PARAMETER_BYTE_ARRAY: 'byte_array_value',
    ParameterType.PARAMETER_BOOL_ARRAY: 'bool_array_value',
    ParameterType.PARAMETER_INTEGER_ARRAY: 'integer_array_value',
    ParameterType.PARAMETER_DOUBLE_ARRAY: 'double_array_value',
    ParameterType.PARAMETER_STRING_ARRAY: 'string_array_value',
}


def dump(ros, node: str, path) -> dict:
    """Write ``ros2 param dump <node>``'s file for the running ``node`` (full name) to ``path``;
    its ``ros__parameters``.
    """
    names = sorted(
        ros.call(ListParameters, f'{node}/list_parameters', ListParameters.Request()).result.names
    )
    got = ros.call(GetParameters, f'{node}/get_parameters', GetParameters.Request(names=names))
    assert len(got.values) == len(names), f'{len(got.values)} values for {len(names)} names'
    flat = {}
    for name, value in zip(names, got.values):
        field = FIELDS.get(value.type)
        flat[name] = None if field is None else getattr(value, field)
        if isinstance(flat[name], (list, tuple)) or hasattr(flat[name], 'tolist'):
            flat[name] = list(flat[name])
    assert None not in flat.values(), flat
    dumped: dict = {}
    for name, value in flat.items():  # DumpVerb.insert_dict
        *parents, leaf = name.split('.')
        block = dumped
        for key in parents:
            block = block.setdefault(key, {})
        block[leaf] = value
    path.write_text(yaml.dump({node: {'ros__parameters': dumped}}, default_flow_style=False))
    print(f'{node}: {len(names)} parameters listed, {len(got.values)} values got, dumped')  # -rP
    return dumped


def dumped_and_reloaded(ros, processes, namespace, tmp_path, params_file, answers, node):
    """``answers(process)`` of ``node`` started from ``params_file``, then of a fresh one started
    from its dump alone (the same name, the first one stopped); both, and the dump.
    """
    before = answers(processes.node(node, namespace, params_file))
    dumped = dump(ros, f'{namespace}/{node}', tmp_path / 'dump.yaml')
    processes.stop_all()
    processes.running.clear()
    return before, answers(processes.node(node, namespace, tmp_path / 'dump.yaml')), dumped


def steady(ros, processes, proc, received, publish, value, expected, what):
    """The answer once ``value(received[-1])`` equals ``expected`` (a core computation) to 1e-9."""
    ros.spin_until(
        lambda: bool(received) and value(received[-1]) == pytest.approx(expected, rel=1e-9),
        30,
        what,
        every=publish,
        diagnose=lambda: f'last: {received[-1:]}\n{processes.output(proc)}',
    )
    return value(received[-1])


def test_one_muscle_dump_reloads_to_the_same_answers(ros, processes, namespace, tmp_path):
    """Separate ``pressure`` and ``muscle_state`` topics, at three operating points."""
    params = read_parameters(CONFIGS['DMSP-10-250'])
    model = muscle_model(params, params['model'])
    points = [(400e3, 0.24), (200e3, 0.22), (600e3, 0.245)]
    received = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    pressures = ros.node.create_publisher(
        FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data
    )
    states = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_state', qos_profile_sensor_data
    )

    def answers(proc):
        out = []
        for gauge, length in points:

            def publish(gauge=gauge, length=length):
                stamp = ros.now().to_msg()
                pressures.publish(pressure(stamp, AMBIENT + gauge))
                states.publish(state(stamp, length))

            expected = float(model.force(gauge, length).force)
            out.append(
                steady(
                    ros,
                    processes,
                    proc,
                    received,
                    publish,
                    lambda m: m.wrench.force.x,
                    expected,
                    f'force at {gauge:g} Pa, {length} m',
                )
            )
        return out

    before, after, dumped = dumped_and_reloaded(
        ros, processes, namespace, tmp_path, CONFIGS['DMSP-10-250'], answers, 'model_node'
    )
    print(f'answers of the first node: {before}\nanswers of the reloaded one: {after}')  # -rP
    assert after == pytest.approx(before, rel=0, abs=1e-12)
    assert dumped['muscles'] == [] and dumped['pressure_range'] == params['pressure_range']


def test_multi_muscle_combined_dump_reloads_to_the_same_answers(
    ros, processes, namespace, tmp_path
):
    """config/example_multi_muscle.yaml: four muscles, combined JointState inputs."""
    received = ros.collect(JointState, f'{namespace}/force_estimates')
    expected = expected_forces()
    publish = combined_inputs(ros, namespace)

    def answers(proc):
        ros.spin_until(
            lambda: (
                bool(received)
                and list(received[-1].name) == list(INPUTS)
                and list(received[-1].effort)
                == pytest.approx([expected[n] for n in INPUTS], rel=1e-9)
            ),
            30,
            f'force_estimates equal to {expected}',
            every=publish,
            diagnose=lambda: f'last: {received[-1:]}\n{processes.output(proc)}',
        )
        return list(received[-1].effort)

    before, after, dumped = dumped_and_reloaded(
        ros, processes, namespace, tmp_path, MULTI, answers, 'model_node'
    )
    print(f'answers of the first node: {before}\nanswers of the reloaded one: {after}')  # -rP
    assert after == pytest.approx(before, rel=0, abs=1e-12)
    assert dumped['input_mode'] == 'combined' and dumped['muscles'] == list(INPUTS)


def test_joint_node_dump_reloads_to_the_same_answers(ros, processes, namespace, tmp_path):
    """config/example_joint.yaml: joint_states and each muscle's pressure; torque_estimate."""
    received = ros.collect(JointState, f'{namespace}/torque_estimate')
    angles = ros.node.create_publisher(
        JointState, f'{namespace}/joint_states', qos_profile_sensor_data
    )
    pubs = {
        m: ros.node.create_publisher(
            FluidPressure, f'{namespace}/{m}/pressure', qos_profile_sensor_data
        )
        for m in ('flexor', 'extensor')
    }
    points = [(0.3, 400e3, 200e3), (-0.5, 150e3, 500e3)]

    def answers(proc):
        out = []
        for theta, p_flexor, p_extensor in points:

            def publish(theta=theta, p_flexor=p_flexor, p_extensor=p_extensor):
                stamp = ros.now().to_msg()
                pubs['flexor'].publish(pressure(stamp, AMBIENT + p_flexor))
                pubs['extensor'].publish(pressure(stamp, AMBIENT + p_extensor))
                msg = JointState(name=['elbow'], position=[theta])
                msg.header.stamp = stamp
                angles.publish(msg)

            received.clear()
            ros.spin_until(
                lambda: len(received) >= 3 and received[-1].effort == received[-2].effort,
                30,
                f'torque_estimate at {theta} rad',
                every=publish,
                diagnose=lambda: processes.output(proc),
            )
            out.append(received[-1].effort[0])
        return out

    before, after, dumped = dumped_and_reloaded(
        ros, processes, namespace, tmp_path, JOINT, answers, 'joint_node'
    )
    print(f'answers of the first node: {before}\nanswers of the reloaded one: {after}')  # -rP
    assert after == pytest.approx(before, rel=0, abs=1e-12)
    # the flexor's higher pressure turns the joint the positive way, the extensor's the other
    assert before[0] > 0 > before[1]
    # the muscle files' folder, the joint file's, listed absolute: the dump, elsewhere, finds them
    assert dumped['elbow']['flexor']['file'] == 'dmsp_10_250.yaml'
    assert dumped['config_dir'] == str(JOINT.parent.resolve())
