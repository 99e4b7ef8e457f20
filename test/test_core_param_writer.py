"""Writing parameter files (core/files/param_writer.py): what is written reads back as the
muscle.
"""

import math

import pytest
import yaml

from pma_model_ros.core.files.param_file import muscle_model, read_parameters
from pma_model_ros.core.files.param_writer import build_parameters, write_parameters
from pma_model_ros.core.files.shipped_data import shipped_spec
from pma_model_ros.core.physics.models import Domain


def test_written_file_reads_back_with_comment_header(tmp_path):
    spec = shipped_spec('DMSP-10-250')
    models = {
        'martens': {'params': [1 / 3, 2.0, -0.5, 0.1, 0.2], 'objective': 'minimax', 'err': 4.2}
    }
    domain = Domain(0.198, 0.25, 6.5e5)
    path = tmp_path / 'muscle.yaml'
    write_parameters(path, build_parameters(spec, 'martens', domain, models), 'first\nsecond')
    text = path.read_text(encoding='utf-8')
    assert text.startswith('# first\n# second\n/**:\n')
    params = read_parameters(path)
    assert params['length_range'] == [0.198, 0.25]
    assert params['pressure_range'] == [0.0, 650000.0]
    assert params['frame_id'] == 'dmsp_10_250' and params['joint_name'] == 'DMSP-10-250'
    # Theta0 = 28.6 deg = 0.4991641660703783 rad, written with 12 significant digits
    assert params['muscle']['fiber_angle'] == 0.49916416607
    read = muscle_model(params)
    assert read.spec.fiber_angle == pytest.approx(math.radians(28.6), rel=1e-11)
    assert read.spec.nominal_length == spec.nominal_length and read.model.name == 'martens'


def test_no_pressure_range_without_a_known_maximum():
    spec = shipped_spec('DMSP-20-300')
    built = build_parameters(spec, 'mckibben', Domain(0.22, 0.3, math.inf), {'mckibben': {}})
    assert 'pressure_range' not in built['/**']['ros__parameters']
    assert yaml.safe_load(yaml.safe_dump(built)) == built


def test_a_given_rest_length_is_kept_beside_the_calibrated_one(tmp_path):
    """A fit's file: muscle.nominal_length the calibrated L0, muscle.given_nominal_length the
    spec's as given; the muscle reads back with the calibrated one.
    """
    spec = shipped_spec('DMSP-20-300')
    calibrated = type(spec)(**(spec.to_mapping() | {'nominal_length': 0.305}))
    path = tmp_path / 'fit.yaml'
    built = build_parameters(
        calibrated, 'mckibben', Domain(0.222, 0.296, 6.75e5), {'mckibben': {}}, given_length=0.3
    )
    write_parameters(path, built, 'fit')
    params = read_parameters(path)
    assert params['muscle']['given_nominal_length'] == 0.3
    assert muscle_model(params).spec.nominal_length == 0.305
