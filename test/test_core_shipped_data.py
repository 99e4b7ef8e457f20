"""The shipped muscle data (core/files/shipped_data.py) against the catalogue and the CSV files."""

import csv
from importlib import resources

import numpy as np
import pytest

from conftest import REPO
from pma_model_ros.core.files.shipped_data import (
    MAPPED_MUSCLES,
    sarosi_tables,
    share_directory,
    shipped_force_map,
    SHIPPED_MUSCLES,
    shipped_spec,
)


@pytest.mark.parametrize(
    # Festo's catalogue name DMSP-<inner diameter mm>-<nominal length mm>.
    ('muscle', 'diameter', 'length'),
    [('DMSP-10-250', 0.010, 0.25), ('DMSP-20-300', 0.020, 0.30), ('DMSP-10-100', 0.010, 0.10)],
)
def test_specs_follow_the_catalogue_names(muscle, diameter, length):
    spec = shipped_spec(muscle)
    assert spec.name == muscle
    assert spec.inner_diameter == pytest.approx(diameter)
    assert spec.nominal_length == pytest.approx(length)


@pytest.mark.parametrize('muscle', MAPPED_MUSCLES)
def test_maps_hold_every_row_of_their_csv(muscle):
    name = f'{SHIPPED_MUSCLES[muscle]}_force_map.csv'
    text = resources.files('pma_model_ros.core').joinpath('data', name).read_text('utf-8')
    rows = list(csv.reader(line for line in text.splitlines() if not line.startswith('#')))[1:]
    fmap = shipped_force_map(muscle)
    np.testing.assert_array_equal(
        np.column_stack([fmap.pressure, fmap.length, fmap.force]), np.array(rows, float)
    )


def test_unknown_or_unmapped_muscles_are_named():
    with pytest.raises(ValueError, match="unknown shipped muscle 'DMSP-40-400'"):
        shipped_spec('DMSP-40-400')
    with pytest.raises(ValueError, match="no shipped force map for 'DMSP-10-100'"):
        shipped_force_map('DMSP-10-100')


def test_sarosi_tables_are_a_mapping():
    assert isinstance(sarosi_tables(), dict) and sarosi_tables()


@pytest.mark.parametrize('muscle', SHIPPED_MUSCLES)
def test_the_spec_files_in_config_are_the_shipped_specs(muscle):
    """config/muscles/ holds, where a user looks, the very spec files of core/data."""
    name = f'{SHIPPED_MUSCLES[muscle]}.yaml'
    assert (REPO / 'config' / 'muscles' / name).read_bytes() == (
        resources.files('pma_model_ros.core').joinpath('data', name).read_bytes()
    )


def test_share_directory_of_the_development_install_is_the_source(monkeypatch, tmp_path):
    """No ament prefix path (scripts/setup's editable install): the source tree, from any working
    directory.
    """
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    monkeypatch.chdir(tmp_path)
    assert share_directory() == REPO


def test_share_directory_through_ament_index(monkeypatch, tmp_path):
    """A prefix on AMENT_PREFIX_PATH that has the package (a colcon install) comes first."""
    share = tmp_path / 'share' / 'pma_model_ros'
    (tmp_path / 'share/ament_index/resource_index/packages').mkdir(parents=True)
    (tmp_path / 'share/ament_index/resource_index/packages/pma_model_ros').touch()
    share.mkdir()
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    assert share_directory() == share
