"""Reading parameter files (core/files/param_file.py): the identified muscle and the node's
settings.
"""

import copy

import pytest

from conftest import docstring_yaml, REPO
from pma_model_ros.core.files import param_file
from pma_model_ros.core.files.param_file import (
    all_node_settings,
    identification,
    muscle_model,
    node_settings,
    read_parameters,
)

CONFIG = REPO / 'config' / 'dmsp_10_250.yaml'


@pytest.fixture
def params():
    return read_parameters(CONFIG)


def test_reads_the_muscle_and_its_default_model(params):
    muscle = muscle_model(params)
    # Festo's DMSP-10-250: 10 mm inner diameter, 250 mm nominal length, rated 8 bar.
    assert muscle.spec.name == 'DMSP-10-250'
    assert (muscle.spec.inner_diameter, muscle.spec.nominal_length) == (0.01, 0.25)
    assert muscle.spec.max_pressure == 8e5
    assert muscle.model.name == params['model']
    assert muscle_model(params, 'mckibben').model.name == 'mckibben'


def test_node_settings_default_to_the_standard_atmosphere_and_the_muscles_name(params):
    bare = {
        k: v for k, v in params.items() if k not in ('ambient_pressure', 'joint_name', 'frame_id')
    }
    settings = node_settings(bare)
    assert settings.config.ambient_pressure == 101325.0  # ISO 2533 sea-level pressure
    # the frame: the joint name as a URDF link and tf2 take it (lower case, '_' for '-')
    assert settings.joint_name == 'DMSP-10-250' and settings.frame_id == 'dmsp_10_250'
    named = node_settings(bare | {'joint_name': 'Left arm/Biceps.2'})
    assert named.frame_id == 'left_arm_biceps_2'


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda p: p['models'].pop('martens'), "'models.martens' is missing"),
        (lambda p: p.update(length_range=[0.2]), 'length_range must be'),
        (lambda p: p.update(pressure_range=[1e5, 6e5]), 'pressure_range must be'),
        (lambda p: p['models']['martens'].update(pressure_offset=1e6), 'pressure_offset must be'),
    ],
)
def test_bad_files_name_the_key(params, change, message):
    bad = copy.deepcopy(params)
    change(bad)
    with pytest.raises(ValueError, match=message):
        muscle_model(bad, 'martens')


def test_many_muscles_each_under_its_name(params):
    one = {k: params[k] for k in ('muscle', 'model', 'length_range', 'pressure_range', 'models')}
    both = {'muscles': ['left', 'right'], 'left': one, 'right': one, 'ambient_pressure': 9e4}
    left, right = all_node_settings(both)
    assert (left.joint_name, right.joint_name) == ('left', 'right')
    assert left.config.ambient_pressure == right.config.ambient_pressure == 9e4
    with pytest.raises(ValueError, match='two muscles share a joint_name'):
        all_node_settings(both | {'right': one | {'joint_name': 'left'}})
    with pytest.raises(ValueError, match="muscle 'right': no parameters"):
        all_node_settings({'muscles': ['left', 'right'], 'left': one})


@pytest.mark.parametrize(
    ('file', 'edit', 'named'),
    [
        (
            'dmsp_10_250.yaml',
            ('    model: martens', '    modle: martens'),
            "unknown key 'modle' (did you mean 'model'?)",
        ),
        (
            'dmsp_10_250.yaml',
            ('    length_range:', '    lenght_range:'),
            "unknown key 'lenght_range' (did you mean 'length_range'?)",
        ),
        (
            'dmsp_10_250.yaml',
            ('    max_input_age: 0.1', '    max_input_agee: 0.1'),
            "unknown key 'max_input_agee' (did you mean 'max_input_age'?)",
        ),
        (
            'dmsp_10_250.yaml',
            ('      martens:', '      martins:'),
            "unknown key 'models.martins' (did you mean 'models.martens'?)",
        ),
        (
            'example_multi_muscle.yaml',
            ('    biceps:\n      muscle:', '    biceps:\n      muscel:'),
            "unknown key 'biceps.muscel' (did you mean 'biceps.muscle'?)",
        ),
        (
            'example_joint.yaml',
            ('      radius:', '      raduis:'),
            "unknown key 'elbow.raduis' (did you mean 'elbow.radius'?)",
        ),
        (
            'example_joint.yaml',
            ('length_at_zero: 0.234}\n      extensor', 'length_at_zeroo: 0.234}\n      extensor'),
            "unknown key 'elbow.flexor.length_at_zeroo' "
            "(did you mean 'elbow.flexor.length_at_zero'?)",
        ),
    ],
)
def test_a_misspelled_key_is_named_with_the_file_and_the_right_key(tmp_path, file, edit, named):
    text = (REPO / 'config' / file).read_text()
    assert edit[0] in text
    path = tmp_path / file
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ValueError) as err:
        read_parameters(path)
    assert str(err.value) == f'{path}: {named}'


def test_the_shipped_files_have_no_unknown_key():
    for path in (REPO / 'config').glob('*.yaml'):
        read_parameters(path)


def test_a_muscle_spec_given_as_parameter_file_is_named_so():
    spec = REPO / 'config' / 'muscles' / 'dmsp_10_250.yaml'
    with pytest.raises(ValueError, match='is a muscle spec, not a ROS parameter file'):
        read_parameters(spec)


def test_the_docstring_example_is_the_shipped_file_s_martens(params):
    example = docstring_yaml(param_file)
    assert example['muscle'] == params['muscle']
    for key in ('model', 'length_range', 'pressure_range'):
        assert example[key] == params[key]
    assert example['models']['martens'] == params['models']['martens']


def test_identification_results_as_diagnostic_values(params):
    """The file's numbers to 6 digits, with units, and the held-out err of each length."""
    martens = params['models']['martens']
    held = martens['held_out']
    assert identification(params) == {
        'identification objective': martens['objective'],
        'identification err [% of max force]': f'{martens["err"]:.6g}',
        'identification rmse [N]': f'{martens["rmse"]:.6g}',
        'identification r2': f'{martens["r2"]:.6g}',
        'identification cv_err [% of max force]': f'{martens["cv_err"]:.6g}',
        'identification interior_cv_err [% of max force]': f'{martens["interior_cv_err"]:.6g}',
        'identification edge_cv_err [% of max force]': f'{martens["edge_cv_err"]:.6g}',
        'identification held_out [m: % of max force]': ', '.join(
            f'{length:.4g}: {err:.3g}' for length, err in zip(held['lengths'], held['err'])
        ),
    }
    assert max(held['err']) == martens['cv_err']  # the worst held-out length is cv_err
    assert max(held['err'][1:-1]) == martens['interior_cv_err']  # of those inside
    assert max(held['err'][0], held['err'][-1]) == martens['edge_cv_err']  # the two edges
    assert identification(params, 'hildebrandt')['identification err [% of max force]'] == (
        f'{params["models"]["hildebrandt"]["err"]:.6g}'
    )
    assert identification({'model': 'martens', 'models': {'martens': {'params': []}}}) == {}
