"""Joint parameter files: muscles by file or inline, which muscle is positive, clear errors."""

import copy

import pytest
import yaml

from conftest import CONFIGS, docstring_yaml, REPO
from pma_model_ros.core.files import joint_file
from pma_model_ros.core.files.joint_file import joints, load_joints
from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.physics.hysteresis import DEFAULT_FOLLOW, Follow

EXAMPLE = REPO / 'config' / 'example_joint.yaml'


def example() -> dict:
    return copy.deepcopy(read_parameters(EXAMPLE))


def test_example_joint_reads_both_muscle_files_with_the_model_override():
    (elbow,) = load_joints(EXAMPLE)
    hildebrandt = muscle_model(read_parameters(CONFIGS['DMSP-10-250']), 'hildebrandt')
    assert elbow.muscle_names == ('flexor', 'extensor')
    assert elbow.length_at_zero == (0.234, 0.234) and elbow.limits == (-1.0, 1.0)
    assert elbow.transmission.arm == (0.015,)
    for muscle in elbow.muscles:
        assert muscle.model.name == 'hildebrandt' and (muscle.theta == hildebrandt.theta).all()


def test_inline_muscle_equals_its_file():
    parameters = example()
    single = read_parameters(CONFIGS['DMSP-10-250'])
    parameters['elbow']['extensor'] = {
        key: single[key] for key in ('muscle', 'model', 'length_range', 'models')
    }
    parameters['elbow']['extensor'] |= {'length_at_zero': 0.234, 'model': 'hildebrandt'}
    (inline,) = joints(parameters, REPO / 'config')
    (from_file,) = load_joints(EXAMPLE)
    assert inline.forward(0.4, 300e3, 500e3).torque == from_file.forward(0.4, 300e3, 500e3).torque


def test_each_muscle_says_what_its_hysteresis_branch_follows(tmp_path):
    """By file, inline beside the file (it overrides the file's mapping), or model_node's defaults:
    the length with a 0.5 mm deadband.
    """
    single = read_parameters(CONFIGS['DMSP-10-100'])
    single['hysteresis'] = {'input': 'pressure', 'pressure_deadband': 8000.0}
    (tmp_path / 'finger.yaml').write_text(yaml.safe_dump({'/**': {'ros__parameters': single}}))
    parameters = example()
    parameters['elbow']['flexor'] = {'file': 'finger.yaml', 'length_at_zero': 0.0875}
    parameters['elbow']['extensor'] = {
        'file': 'finger.yaml',
        'length_at_zero': 0.0875,
        'hysteresis': {'length_deadband': 0.001},
    }
    parameters['elbow']['radius'] = [0.01]
    (joint,) = joints(parameters, tmp_path)
    assert joint.follows == (Follow('pressure', 8000.0), Follow('length', 0.001))
    assert load_joints(EXAMPLE)[0].follows == (Follow('length', 0.0005),) * 2


def test_positive_picks_the_muscle_that_shortens():
    parameters = example()
    parameters['elbow']['positive'] = 'extensor'
    (elbow,) = joints(parameters, REPO / 'config')
    assert elbow.muscle_names == ('extensor', 'flexor')


@pytest.mark.parametrize(
    'change, message',
    [
        (lambda j: j.update(radius='big'), 'radius must be a list of numbers'),
        (lambda j: j.update(limits=[1.0]), r'limits must be \[min, max\]'),
        (lambda j: j.update(limits=[1.0, -1.0]), 'min < max'),
        (lambda j: j.update(muscles=['flexor', 'flexor']), 'two different names'),
        (lambda j: j.update(positive='biceps'), 'positive must name the muscle'),
        (lambda j: j.pop('extensor'), "no parameters under 'extensor:'"),
        (lambda j: j['flexor'].update(file='missing.yaml'), "muscle 'flexor'"),
        (lambda j: j['flexor'].update(model='nonsense'), "unknown model 'nonsense'"),
        (lambda j: j['flexor'].pop('length_at_zero'), 'length_at_zero must be a length in m'),
        (
            lambda j: j['flexor'].update(length_at_zero=0.3),
            "muscle 'flexor' would be 0.315 m long at θ = -1 rad",
        ),
        (
            lambda j: j['extensor'].update(hysteresis={'input': 'velocity'}),
            "muscle 'extensor': parameter 'hysteresis.input': unknown hysteresis.input 'velocity'",
        ),
        (
            lambda j: j['flexor'].update(hysteresis={'length_deadband': 0.5}),
            r"parameter 'hysteresis.length_deadband' must be in \[0, 0.1\] m",
        ),
    ],
)
def test_bad_joint_is_one_clear_error(change, message):
    parameters = example()
    change(parameters['elbow'])
    with pytest.raises(ValueError, match=message) as err:
        joints(parameters, REPO / 'config')
    assert str(err.value).startswith("joint 'elbow'")


def test_joint_list_errors(tmp_path):
    parameters = example()
    parameters['joints'] = 'elbow'
    with pytest.raises(ValueError, match='joints must be a non-empty list'):
        joints(parameters, REPO / 'config')
    parameters = example()
    parameters['joints'] = ['elbow', 'knee']
    parameters['knee'] = copy.deepcopy(parameters['elbow'])
    with pytest.raises(ValueError, match='two joints share a muscle name'):
        joints(parameters, REPO / 'config')
    path = tmp_path / 'joint.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': example()}}))
    with pytest.raises(ValueError, match="muscle 'flexor'.*dmsp_10_250.yaml"):
        load_joints(path)  # muscle files are found beside the joint file


def test_the_docstring_example_is_the_example_joint_with_a_hysteresis_mapping():
    (elbow,) = joints(docstring_yaml(joint_file), REPO / 'config')
    (shipped,) = load_joints(EXAMPLE)
    assert (elbow.muscle_names, elbow.transmission, elbow.limits, elbow.length_at_zero) == (
        shipped.muscle_names,
        shipped.transmission,
        shipped.limits,
        shipped.length_at_zero,
    )
    assert [m.model.name for m in elbow.muscles] == ['martens', 'hildebrandt']
    assert elbow.follows == (DEFAULT_FOLLOW, Follow('pressure', 10000.0))
