"""Reading parameter files (core/param_file.py): the identified muscle and the node's settings."""

import copy

import pytest

from conftest import docstring_yaml, REPO
from pma_model_ros.core import param_file
from pma_model_ros.core.param_file import (
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
    assert settings.joint_name == 'DMSP-10-250' and settings.frame_id == 'DMSP-10-250'


@pytest.mark.parametrize(
    ('change', 'message'),
    [
        (lambda p: p['models'].pop('martens'), 'models.martens is missing'),
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


def test_the_docstring_example_is_the_shipped_file_s_martens(params):
    example = docstring_yaml(param_file)
    assert example['muscle'] == params['muscle']
    for key in ('model', 'length_range', 'pressure_range'):
        assert example[key] == params[key]
    assert example['models']['martens'] == params['models']['martens']


def test_identification_results_as_diagnostic_values(params):
    """The file's numbers to 6 digits (err: 4.20 % in the README's Table 3 comparison)."""
    assert identification(params) == {
        'identification objective': 'minimax',
        'identification err [% of max force]': '4.20303',
        'identification rmse [N]': '7.94343',
        'identification r2': '0.996793',
        'identification cv_err [% of max force]': '8.2323',
        'identification edge_cv_err [% of max force]': '8.2323',
    }
    assert identification(params, 'hildebrandt')['identification err [% of max force]'] == (
        f'{params["models"]["hildebrandt"]["err"]:.6g}'
    )
    assert identification({'model': 'martens', 'models': {'martens': {'params': []}}}) == {}
