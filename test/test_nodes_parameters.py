"""The four nodes' parameters, declared from the core's tables (nodes/parameters.py), in-process on
private Contexts: what ``ros2 param list`` shows, read-only flags, unknown names, ``**kwargs``.
"""

import copy

import pytest
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.parameter import Parameter
import yaml

from conftest import CONFIGS, lines_of_failed_start, REPO
from pma_model_ros.nodes.joint_node import JointNode
from pma_model_ros.nodes.joint_simulator_node import JointSimulatorNode
from pma_model_ros.nodes.model_node import ModelNode
from pma_model_ros.nodes.simulator_node import SimulatorNode
from pma_model_ros.tools import node_process

EXAMPLE_JOINT = REPO / 'config' / 'example_joint.yaml'
MULTI = REPO / 'config' / 'example_multi_muscle.yaml'
#: The parameter file each node class is built from in these tests.
NODES = {
    ModelNode: CONFIGS['DMSP-10-250'],
    JointNode: EXAMPLE_JOINT,
    SimulatorNode: None,
    JointSimulatorNode: None,
}
#: Declared by rclpy for every node (not ours).
RCLPY = {'use_sim_time', 'start_type_description_service'}


@pytest.fixture
def make(private_node):
    """A factory: node class, its parameter file, ``-p`` overrides and constructor keywords."""

    def make(cls, params_file=None, overrides=(), **kwargs):
        args = ['--params-file', params_file] if params_file else []
        for name, value in overrides:
            args += ['-p', f'{name}:={value}']
        return private_node(cls, *args, **kwargs)

    return make


@pytest.fixture
def warnings(monkeypatch):
    """The warnings the nodes log from now on."""
    logged = []
    monkeypatch.setattr(RcutilsLogger, 'warning', lambda self, text, **_: logged.append(text))
    return logged


def listed(node) -> list[str]:
    """What ``ros2 param list`` lists of ``node``."""
    return node.list_parameters([], 0).names


@pytest.mark.parametrize('cls', NODES)
def test_every_node_passes_its_keywords_to_rclpy(make, cls):
    """``**kwargs`` reach rclpy's Node, as in ros2/examples: here a namespace and an override."""
    node = make(
        cls,
        NODES[cls],
        namespace='/kw',
        parameter_overrides=[Parameter('use_sim_time', value=True)],
    )
    assert node.get_namespace() == '/kw' and node.get_parameter('use_sim_time').value is True


def test_model_node_declares_its_muscle_and_the_selected_model_only(make):
    """One muscle: 15 parameters of the muscle (hardware_id among them), 2 of its model's block
    (params, extrapolates: the file sets no nominal_length or pressure_offset, which are then not
    declared, as no parameter without a value is), 25 node-wide (``autostart``, ``executor``, 7
    ``reidentify.*`` and 5 ``residual.*`` among them), 2 of rclpy's: 44; and the QoS overrides of
    its 6 topics, 2 each (nodes/qos.py: ``residual.enabled`` false adds no topic).  Four muscles:
    15 each under ``<name>.`` and the block entries its file gives.  Every one has a value.
    """
    node = make(ModelNode, CONFIGS['DMSP-10-250'])
    names = listed(node)
    qos = [n for n in names if n.startswith('qos_overrides.')]
    assert len(names) - len(qos) == 44 and len(qos) == 6 * 2
    assert all(node.get_parameter(n).value is not None for n in names)
    assert {n.split('.')[1] for n in names if n.startswith('models.')} == {'martens'}
    multi = make(ModelNode, MULTI)
    given = yaml.safe_load(MULTI.read_text())['/**']['ros__parameters']
    for muscle in given['muscles']:
        own = [n for n in listed(multi) if n.startswith(f'{muscle}.')]
        block = given[muscle]['models'][given[muscle]['model']]
        entries = {'params', 'extrapolates', 'nominal_length', 'pressure_offset'} & set(block)
        assert len(own) == 15 + len(entries), own


def test_read_only_where_the_node_never_changes_a_parameter(make):
    """joint_node and the simulators read their parameters at start-up: all are read-only;
    model_node's read-only ones are its table's.
    """
    for cls in (JointNode, SimulatorNode, JointSimulatorNode):
        node = make(cls, NODES[cls])
        ours = [n for n in listed(node) if n not in RCLPY]
        assert ours and all(d.read_only for d in node.describe_parameters(ours)), cls
    node = make(ModelNode, CONFIGS['DMSP-10-250'])
    fixed = {
        n
        for n, d in zip(listed(node), node.describe_parameters(listed(node)))
        if d.read_only and not n.startswith('qos_overrides.')  # rclpy's, always read-only
    }
    assert fixed - RCLPY == {
        'muscles',
        'input_mode',
        'pairing',
        'pairing_slop',
        'max_queue_delay',
        'max_answer_delay',
        'forward_command_topic',
        'forward_command_order',
        'autostart',
        'executor',
        'reidentify.per_cell',
        'reidentify.cell_share',
        'reidentify.lengths',
        'reidentify.check_every',
        'residual.enabled',  # read by configure, as the subscriptions it creates
        'residual.window',
        'residual.warn_ratio',
        'residual.error_ratio',
        'residual.hysteresis',
    }


@pytest.mark.parametrize(
    'cls, typo, near',
    [
        (ModelNode, 'max_input_agee', 'max_input_age'),
        (ModelNode, 'models.martens.parms', 'models.martens.params'),
        (JointNode, 'elbow.cocontracton', 'elbow.cocontraction'),
        (SimulatorNode, 'noise.force_sdt', 'noise.force_std'),
        (JointSimulatorNode, 'inertia_', 'inertia'),
    ],
)
def test_an_unknown_parameter_is_named_with_the_nearest(make, warnings, cls, typo, near):
    make(cls, NODES[cls], overrides=[(typo, '1.0')])
    assert warnings == [f"unknown parameter '{typo}' (did you mean '{near}'?): ignored"]


@pytest.mark.parametrize(
    'cls, topic',
    [
        (ModelNode, '/diagnostics.publisher'),
        (JointNode, '/flexor/pressure.subscription'),
        (SimulatorNode, '/pressure.publisher'),
        (JointSimulatorNode, '/joint_states.publisher'),
    ],
)
def test_a_qos_override_is_known_of_a_topic_the_node_has_only(make, warnings, cls, topic):
    """``qos_overrides.<topic>.<entity>.<policy>`` of one of the node's topics is no unknown
    parameter (it is applied); of a topic it has not, or a policy not overridable, it is.
    """
    known = f'qos_overrides.{topic}.reliability'
    typo = f'qos_overrides.{topic}.depht'
    node = make(
        cls,
        NODES[cls],
        overrides=[
            (known, 'best_effort'),
            ('qos_overrides./nope.publisher.depth', '5'),
            (typo, '5'),
        ],
    )
    assert node.get_parameter(known).value == 'best_effort'
    nope, near = sorted(warnings, key=lambda w: '/nope' not in w)
    assert (
        near
        == f"unknown parameter '{typo}' (did you mean 'qos_overrides.{topic}.depth'?): ignored"
    )
    assert nope.startswith("unknown parameter 'qos_overrides./nope.publisher.depth'"), nope


def test_entries_read_undeclared_are_no_unknown_parameters(make, warnings):
    """The other models' blocks and the identification results of a file: read, not declared."""
    make(ModelNode, MULTI)
    parameters = yaml.safe_load(MULTI.read_text())['/**']['ros__parameters']
    assert len(parameters['biceps']['models']) > 1  # blocks of the models not selected
    assert warnings == []


def test_a_fit_files_given_rest_length_is_no_unknown_parameter(make, warnings, tmp_path):
    """muscle.given_nominal_length (pma-model fit's record of the spec's L0 beside a calibrated
    one): read by pma-model scale, no warning, and the node serves the calibrated L0.
    """
    text = CONFIGS['DMSP-10-250'].read_text()
    assert 'nominal_length: 0.25,' in text
    path = tmp_path / 'fit.yaml'
    path.write_text(
        text.replace(
            'nominal_length: 0.25,', 'nominal_length: 0.2517, given_nominal_length: 0.25,'
        )
    )
    node = make(ModelNode, path)
    assert warnings == []
    assert node.get_parameter('muscle.nominal_length').value == 0.2517


def test_a_key_copied_into_every_block_is_one_warning(make, warnings, tmp_path):
    """64 muscles, each block holding three node-wide keys (192 unknown names): one warning per
    key, naming the blocks and the node-wide name (its cost at start-up: bench/startup.py, the
    row with 192 unknown parameters).
    """
    from pma_model_ros.core.files.param_file import read_parameters

    shipped = read_parameters(CONFIGS['DMSP-10-250'])
    block = {key: shipped[key] for key in ('muscle', 'model', 'length_range', 'models')}
    names = [f'm{i:02d}' for i in range(64)]
    copied = {'ambient_pressure': 101325.0, 'max_input_age': 0.1, 'pressure_reference': 'absolute'}
    params = {'muscles': names, 'input_mode': 'combined'}
    params |= {name: copy.deepcopy(block | copied) for name in names}  # (rcl takes no aliases)
    path = tmp_path / 'arm_64.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': params}}, default_flow_style=None))
    make(ModelNode, path)
    assert warnings == [
        f"unknown parameter '{key}' in 64 blocks ({', '.join(names)}) "
        f"(did you mean '{key}'?): ignored"
        for key in copied
    ]


@pytest.mark.parametrize('cls', [ModelNode, JointNode])
def test_no_subscription_exists_before_the_checks_and_warnings(make, monkeypatch, cls):
    """The subscriptions come last in configure: nothing is matched before the node can answer."""
    from pma_model_ros.nodes import parameters

    seen = []
    warn = parameters.warn_unknown

    def counting(node, *args):
        seen.append(len(list(node.subscriptions)))
        return warn(node, *args)

    monkeypatch.setattr(parameters, 'warn_unknown', counting)
    monkeypatch.setattr('pma_model_ros.nodes.model_node.warn_unknown', counting)
    node = make(cls, NODES[cls])
    assert seen == [0] and list(node.subscriptions)


@pytest.mark.parametrize(
    'cls, source, name',
    [
        (ModelNode, CONFIGS['DMSP-10-250'], 'pressure_range'),
        (ModelNode, CONFIGS['DMSP-10-250'], 'muscles'),
        (JointNode, EXAMPLE_JOINT, 'forward_command_order'),
    ],
)
def test_an_empty_array_in_a_file_is_the_documented_default(make, tmp_path, cls, source, name):
    """An empty array in a file, which rcl reads as no value, is the default ``[]``, as
    documented, and listed with that value.
    """
    lines = [
        line for line in source.read_text().splitlines() if not line.startswith(f'    {name}:')
    ]
    path = tmp_path / 'params.yaml'
    path.write_text(
        '\n'.join(lines).replace('ros__parameters:', f'ros__parameters:\n    {name}: []')
    )
    node = make(cls, path)
    assert list(node.get_parameter(name).value) == []


@pytest.mark.parametrize(
    'override, words',
    [
        # a string beside the file's double: rcl kept the file's 0.1 without a word
        ('max_input_age:=0.5ms', ["'max_input_age'", "a string ('0.5ms')", 'a double (0.1)']),
        ('ambient_pressure:=1.01325', ["'ambient_pressure'", 'bar? 1.01325 bar = 101325 Pa']),
        ('ambient_pressure:=101.325', ["'ambient_pressure'", 'kPa? 101.325 kPa = 101325 Pa']),
    ],
)
@pytest.mark.parametrize('node, params_file', [('model_node', 'DMSP-10-250'), ('joint_node', '')])
def test_a_wrong_value_ends_the_process_with_one_line(node, params_file, override, words):
    path = CONFIGS[params_file] if params_file else EXAMPLE_JOINT
    cmd = node_process.command(node, '/', path, {})
    lines = lines_of_failed_start([*cmd, '-p', override])
    assert len(lines) == 1 and 'FATAL' in lines[0], lines
    assert all(w in lines[0] for w in words), lines


@pytest.mark.parametrize(
    'node, params_file, words',
    [
        ('model_node', EXAMPLE_JOINT, ['a joint file', 'joint_node', 'dmsp_10_250.yaml']),
        ('joint_node', CONFIGS['DMSP-10-250'], ['not a joint file', 'one muscle', 'model_node']),
        ('joint_node', MULTI, ['not a joint file', 'several muscles', 'model_node']),
    ],
)
def test_the_other_nodes_file_is_named_as_such(node, params_file, words):
    lines = lines_of_failed_start(node_process.command(node, '/', params_file, {}))
    assert len(lines) == 1 and 'FATAL' in lines[0], lines
    assert all(w in lines[0] for w in words), lines
