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


def _joint_file_beside(folder, muscle_file: str) -> object:
    """The example elbow written into ``folder`` with both muscles from ``muscle_file``."""
    parameters = example()
    for muscle in ('flexor', 'extensor'):
        parameters['elbow'][muscle]['file'] = muscle_file
    path = folder / 'elbow.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': parameters}}))
    return path


def test_relative_muscle_files_follow_one_rule(tmp_path):
    """Beside the joint file (pma-model joint and joint_node alike), unless config_dir is set;
    the package's config/ only for joints given without a file. The muscle beside it is the
    DMSP-20-300 (its file, under the name the joint names), not the shipped DMSP-10-250.
    """
    (tmp_path / 'mine.yaml').write_text((REPO / 'config' / 'dmsp_20_300.yaml').read_text())
    path = _joint_file_beside(tmp_path, 'mine.yaml')
    (elbow,) = load_joints(path)
    assert elbow.muscles[0].spec.name == 'DMSP-20-300'
    argv = ['joint_node', '--ros-args', '--params-file', str(CONFIGS['DMSP-10-250'])]
    assert joint_file.joint_file_of(argv) is None  # a muscle's file: no joints
    argv += ['--params-file', str(path)]
    assert joint_file.joint_file_of(argv) == path
    default = REPO / 'config'
    rule = joint_file.muscle_folder
    assert rule('', path, default) == tmp_path.resolve()
    assert rule(str(default), path, default) == default
    assert rule('', None, default) == default


@pytest.mark.parametrize(
    'config, what',
    [('dmsp_10_250.yaml', 'one muscle'), ('example_multi_muscle.yaml', 'several muscles')],
)
def test_a_muscle_file_is_not_a_joint_file(config, what):
    path = REPO / 'config' / config
    with pytest.raises(ValueError) as err:
        load_joints(path)
    assert str(err.value) == (
        f"{path}: not a joint file (no 'joints:'): a parameter file of {what}, read by "
        'model_node and pma-model force; a joint file lists its joints (config/example_joint.yaml)'
    )
