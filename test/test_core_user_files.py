"""Reading the files a user names (core/files/user_files.py): one regular UTF-8 file of bounded
size.
"""

import os

import pytest

from conftest import REPO
from pma_model_ros.core.files.user_files import (
    load_yaml_mapping,
    MAX_FILE_BYTES,
    read_spec_yaml,
    read_user_file,
)


def test_reads_utf8_text(tmp_path):
    path = tmp_path / 'note.yaml'
    path.write_text('name: Sárosi\n', encoding='utf-8')
    assert read_user_file(path, 'note') == 'name: Sárosi\n'


@pytest.mark.parametrize(
    ('make', 'message'),
    [
        (lambda d: d / 'missing.yaml', 'note not found'),
        (lambda d: d, 'is not a regular file'),
        (
            lambda d: (
                (d / 'latin1.yaml').write_bytes('Sárosi'.encode('latin-1')) and d / 'latin1.yaml'
            ),
            'is not UTF-8 text',
        ),
    ],
)
def test_refuses_what_is_not_one_utf8_file(tmp_path, make, message):
    with pytest.raises(ValueError, match=message):
        read_user_file(make(tmp_path), 'note')


def test_refuses_a_file_over_the_limit(tmp_path):
    path = tmp_path / 'huge.csv'
    with open(path, 'wb') as f:
        f.truncate(16 * 1024 * 1024 + 1)  # sparse: no disk used
    assert os.path.getsize(path) > MAX_FILE_BYTES
    with pytest.raises(ValueError, match='over the 16777216-byte limit'):
        read_user_file(path, 'force map file')


def test_yaml_must_be_a_mapping():
    assert load_yaml_mapping('a: 1\n', 'x.yaml') == {'a': 1}
    with pytest.raises(ValueError, match='x.yaml: expected a YAML mapping at the top, got list'):
        load_yaml_mapping('- 1\n', 'x.yaml')
    with pytest.raises(ValueError, match='x.yaml: not valid YAML'):
        load_yaml_mapping('a: [1\n', 'x.yaml')


def test_a_spec_file_top_level_or_under_muscle(tmp_path):
    # Festo's DMSP-20-300: 20 mm inner diameter, 300 mm nominal length, 6 bar rated.
    spec = {
        'name': 'DMSP-20-300',
        'nominal_length': 0.3,
        'inner_diameter': 0.02,
        'membrane_thickness': 0.0018,
        'fiber_angle': 0.5,
        'max_pressure': 6e5,
    }
    flat = tmp_path / 'flat.yaml'
    flat.write_text(''.join(f'{k}: {v}\n' for k, v in spec.items()), encoding='utf-8')
    nested = tmp_path / 'nested.yaml'
    nested.write_text('muscle:\n' + ''.join(f'  {k}: {v}\n' for k, v in spec.items()))
    for path in (flat, nested):
        read = read_spec_yaml(path)
        assert (read.name, read.nominal_length, read.inner_diameter) == ('DMSP-20-300', 0.3, 0.02)


def test_a_ros_parameter_file_as_spec_names_the_spec_file():
    config = REPO / 'config' / 'dmsp_20_300.yaml'
    with pytest.raises(ValueError) as err:
        read_spec_yaml(config)
    assert str(err.value) == (
        f'{config} is a ROS parameter file, not a muscle spec; the spec of its muscle '
        f'DMSP-20-300 is {REPO / "config" / "muscles" / "dmsp_20_300.yaml"}'
    )
