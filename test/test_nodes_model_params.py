"""Runtime parameter changes of model_node: validated as a whole, applied without restart."""

import math

from geometry_msgs.msg import WrenchStamped
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from conftest import CONFIGS, edited_copy
from node_messages import AMBIENT, pressure, raw, record, state
from pma_model_ros.core.files.node_parameters import IDENTIFICATION
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.nodes.model_params import expected_undeclared

pytestmark = pytest.mark.ros


def test_set_parameters_validates_and_swaps_the_model(ros, processes, namespace):
    node = processes.node(
        'model_node', namespace, CONFIGS['DMSP-10-250'], joint_name='left_biceps'
    )
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    pressure_pub = ros.node.create_publisher(
        FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data
    )
    state_pub = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_state', qos_profile_sensor_data
    )
    params = read_parameters(CONFIGS['DMSP-10-250'])

    def publish():
        stamp = ros.now().to_msg()
        pressure_pub.publish(pressure(stamp, AMBIENT + 400e3))
        state_pub.publish(state(stamp, 0.24, name='left_biceps'))

    def set_parameters(**values):
        request = SetParameters.Request(
            parameters=[
                Parameter(k.replace('__', '.'), value=v).to_parameter_msg()
                for k, v in values.items()
            ]
        )
        return ros.call(SetParameters, f'{namespace}/model_node/set_parameters', request).results[
            0
        ]

    for name in ('martens', 'sarosi'):
        if name != 'martens':
            result = set_parameters(model=name)
            assert result.successful, result.reason
        expected = float(muscle_model(params, name).force(400e3, 0.24).force)
        estimates.clear()
        ros.spin_until(
            lambda: (
                estimates and estimates[-1].wrench.force.x == pytest.approx(expected, rel=1e-9)
            ),
            20,
            f'an estimate of model {name}',
            every=publish,
            diagnose=lambda: processes.output(node),
        )

    for values, words in (
        ({'model': 'foo'}, "unknown model 'foo'"),
        ({'models__sarosi__params': [1.0]}, "model 'sarosi' needs 6"),
        ({'muscle__inner_diameter': -1.0}, 'out of range'),
        ({'length_range': [0.25, 0.2]}, 'length range'),
    ):
        result = set_parameters(**values)
        assert not result.successful and words in result.reason, (values, result.reason)
    assert node.poll() is None, processes.output(node)


def flat(mapping: dict, prefix: str = '') -> dict:
    """A nested ``ros__parameters`` mapping as {dotted name: value}."""
    out = {}
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        out.update(flat(value, f'{name}.') if isinstance(value, dict) else {name: value})
    return out


def test_a_new_parameter_file_at_runtime_never_mixes_old_and_new(ros, processes, namespace):
    """File B (another default model, nominal length and braid angle) replaces file A at runtime,
    atomically (SetParametersAtomically) and one by one in a single request (SetParameters, as
    `ros2 param load` sends it): every estimate is all-A or all-B, never B's model with A's
    geometry or the reverse.
    """
    from rcl_interfaces.srv import SetParametersAtomically

    node = processes.node('model_node', namespace, CONFIGS['DMSP-10-250'])
    estimates = ros.collect(WrenchStamped, f'{namespace}/force_estimate')
    pressure_pub = ros.node.create_publisher(
        FluidPressure, f'{namespace}/pressure', qos_profile_sensor_data
    )
    state_pub = ros.node.create_publisher(
        JointState, f'{namespace}/muscle_state', qos_profile_sensor_data
    )
    a = read_parameters(CONFIGS['DMSP-10-250'])
    b = {
        **a,
        'model': 'sarosi',
        'muscle': {
            **a['muscle'],
            'nominal_length': a['muscle']['nominal_length'] + 0.002,
            'fiber_angle': a['muscle']['fiber_angle'] + 0.01,
        },
    }
    force = {
        name: float(muscle_model(p, m).force(400e3, 0.24).force)
        for name, p, m in (
            ('A', a, None),
            ('B', b, None),
            ('B model, A muscle', a, 'sarosi'),
            ('A model, B muscle', b, 'martens'),
        )
    }
    assert len({round(f, 6) for f in force.values()}) == 4, force  # the test could see a mix

    def publish():
        stamp = ros.now().to_msg()
        pressure_pub.publish(pressure(stamp, AMBIENT + 400e3))
        state_pub.publish(state(stamp, 0.24, name='DMSP-10-250'))

    def which(msg) -> str:
        return next(
            (k for k, f in force.items() if msg.wrench.force.x == pytest.approx(f, rel=1e-9)),
            'other',
        )

    def reach(name: str) -> None:
        ros.spin_until(
            lambda: estimates and which(estimates[-1]) == name,
            20,
            f'estimates of file {name}',
            every=publish,
            period=0.002,
            diagnose=lambda: processes.output(node),
        )

    def messages(params: dict, whole: bool) -> list:
        """The file's parameters; not ``whole``: without its undeclared entries (the other models'
        blocks, identification results), which a request of one parameter at a time cannot set.
        """
        selected = f'models.{params["model"]}.'
        return [
            Parameter(k, value=v).to_parameter_msg()
            for k, v in flat(params).items()
            if whole
            or not expected_undeclared(k)
            or k.startswith(selected)
            and k.removeprefix(selected).split('.')[0] not in IDENTIFICATION
        ]

    reach('A')
    response = ros.call(
        SetParametersAtomically,
        f'{namespace}/model_node/set_parameters_atomically',
        SetParametersAtomically.Request(parameters=messages(b, whole=True)),
    )
    assert response.result.successful, response.result.reason
    reach('B')
    response = ros.call(
        SetParameters,
        f'{namespace}/model_node/set_parameters',
        SetParameters.Request(parameters=messages(a, whole=False)),
    )
    assert all(r.successful for r in response.results), [r.reason for r in response.results]
    reach('A')
    seen = {which(msg) for msg in estimates}
    assert seen <= {'A', 'B'}, seen
    assert node.poll() is None, processes.output(node)


@pytest.fixture
def node(private_node):
    """A ModelNode of config/dmsp_10_250.yaml on its own Context (no DDS)."""
    return private_node(ModelNode, '--params-file', CONFIGS['DMSP-10-250'])


def estimate(node) -> float:
    """The node's force estimate at 400 kPa gauge and 0.24 m (in-process)."""
    sent = record(node._estimate_pubs[0])
    now = node.get_clock().now()
    node._on_pressure(0, raw(pressure(now.to_msg(), AMBIENT + 400e3)))
    node._on_state(0, raw(state(now.to_msg(), 0.24, name='DMSP-10-250')))
    return sent[-1].wrench.force.x


def test_switching_model_declares_its_block_and_keeps_the_last_values(node):
    """The selected model's block only; a block set at runtime comes back as set."""
    params = read_parameters(CONFIGS['DMSP-10-250'])
    tuned = [
        params['models']['martens']['params'][0] * 1.01,
        *params['models']['martens']['params'][1:],
    ]
    assert node.set_parameters([Parameter('models.martens.params', value=tuned)])[0].successful
    assert node.set_parameters([Parameter('model', value='hildebrandt')])[0].successful
    blocks = {name.split('.')[0] for name in node.get_parameters_by_prefix('models')}
    assert blocks == {'hildebrandt'}
    assert estimate(node) == pytest.approx(
        float(muscle_model(params, 'hildebrandt').force(400e3, 0.24).force), rel=1e-12
    )
    assert node.set_parameters([Parameter('model', value='martens')])[0].successful
    assert list(node.get_parameter('models.martens.params').value) == tuned
    params['models']['martens']['params'] = tuned
    assert estimate(node) == pytest.approx(
        float(muscle_model(params).force(400e3, 0.24).force), rel=1e-12
    )


def test_identification_results_are_values_of_the_muscle_status(node):
    """Not parameters: the file's results of the selected model, in its /diagnostics status."""
    params = read_parameters(CONFIGS['DMSP-10-250'])
    assert not node.has_parameter('models.martens.err')
    for model in ('martens', 'hildebrandt'):
        assert node.set_parameters([Parameter('model', value=model)])[0].successful
        sent = record(node._diag_pub)
        node.publish_status(node.now())
        values = {kv.key: kv.value for kv in sent[0].status[0].values}
        entry = params['models'][model]
        assert values['identification err [% of max force]'] == f'{entry["err"]:.6g}'
        assert values['identification rmse [N]'] == f'{entry["rmse"]:.6g}'
        assert values['identification objective'] == entry['objective']


def test_pressure_range_defaults_to_an_empty_array_of_doubles(private_node, tmp_path):
    """``pressure_range`` (default ``[]``: up to the rated pressure) is declared with its default
    where a file has none, and takes doubles only.
    """
    path = edited_copy(CONFIGS['DMSP-10-100'], tmp_path, 'pressure_range: [0.0, 600000.0]', '')
    node = private_node(ModelNode, '--params-file', path)
    assert node.get_parameter('pressure_range').value == []
    assert node.engine.configs[0].model.domain.pressure_max == math.inf
    refused = node.set_parameters([Parameter('pressure_range', value=['a', 'b'])])[0]
    assert not refused.successful and node.get_parameter('pressure_range').value == []
    assert node.set_parameters([Parameter('pressure_range', value=[0.0, 5e5])])[0].successful
    assert node.engine.configs[0].model.domain.pressure_max == 5e5


def test_an_alias_selects_its_models_block(node):
    """``model: tondu_lopez`` is andrikopoulos's eq. 18: its block is declared, as the model's."""
    andrikopoulos = node.set_parameters([Parameter('model', value='andrikopoulos')])[0]
    assert andrikopoulos.successful
    expected = estimate(node)
    assert node.set_parameters([Parameter('model', value='tondu_lopez')])[0].successful
    assert node.has_parameter('models.andrikopoulos.params')
    assert node.engine.configs[0].model.model.name == 'andrikopoulos'
    assert estimate(node) == expected
    assert node.set_parameters([Parameter('model', value='martens')])[0].successful
    assert not node.has_parameter('models.andrikopoulos.params')


def test_a_file_selecting_an_alias_declares_its_models_block(private_node, tmp_path):
    path = edited_copy(
        CONFIGS['DMSP-10-250'], tmp_path, '    model: martens', '    model: tondu_lopez'
    )
    node = private_node(ModelNode, '--params-file', path)
    assert node.has_parameter('models.andrikopoulos.params')
    assert not node.has_parameter('models.martens.params')
