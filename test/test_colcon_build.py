"""Packaging test: `colcon build` of this repo installs a proper ament_python package.

Uses the session's colcon build (test/conftest.py) in a temporary directory -- build, install and
log bases all live outside the source tree -- then checks the install layout, the console scripts,
the ament index and that the source tree got no build artifacts.
"""

import os
from pathlib import Path
import subprocess
import sys

import pytest

from conftest import explain

PKG = 'pma_model_ros'
REPO = Path(__file__).resolve().parents[1]
EXECUTABLES = ['pma-model', 'model_node', 'simulator_node', 'joint_node', 'joint_simulator_node']
CONFIGS = ['dmsp_10_250.yaml', 'dmsp_20_300.yaml', 'dmsp_10_100.yaml']
# Directories a build must never write into the source tree (the editable install's
# *.egg-info from scripts/setup is expected and not a colcon artifact).
ARTIFACT_NAMES = ('build', 'install', 'log', 'dist')


def _run(cmd, env=None, timeout=120, cwd=None):
    return subprocess.run(
        [str(c) for c in cmd], env=env, cwd=cwd, timeout=timeout, capture_output=True, text=True
    )


def _run_installed(cmd, build):
    """Run with the colcon install on PYTHONPATH/AMENT_PREFIX_PATH (cwd outside the repo)."""
    return _run(cmd, env=build['env'], cwd=build['tmp'])


@pytest.fixture
def build(colcon_install):
    """The session's colcon install (test/conftest.py): prefix, site-packages, run env, tmp dir."""
    return colcon_install


def test_source_tree_stays_clean(build):
    found = [d for d in ARTIFACT_NAMES if (REPO / d).exists() or (REPO / PKG / d).exists()]
    assert not found, f'colcon build wrote into the source tree: {found}'


def test_ament_index_marker(build):
    marker = build['prefix'] / 'share/ament_index/resource_index/packages' / PKG
    assert marker.is_file()


def test_package_xml_installed(build):
    assert (build['prefix'] / 'share' / PKG / 'package.xml').is_file()


@pytest.mark.parametrize('name', CONFIGS)
def test_config_installed(build, name):
    dst = build['prefix'] / 'share' / PKG / 'config' / name
    assert dst.is_file(), f'{dst} not installed'
    assert dst.read_text() == (REPO / 'config' / name).read_text()


def test_package_data_installed(build):
    """core/data/*.csv|*.yaml must ship inside the installed python package."""
    data = [p for ext in ('*.csv', '*.yaml') for p in (REPO / PKG / 'core/data').glob(ext)]
    missing = [p.name for p in data if not (build['site'] / PKG / 'core/data' / p.name).is_file()]
    assert not missing, f'package data not installed: {missing}'


@pytest.mark.parametrize('exe', EXECUTABLES)
def test_executable_installed(build, exe):
    path = build['prefix'] / 'lib' / PKG / exe
    assert path.is_file(), f'{path} missing (ros2 run {PKG} {exe} would fail)'
    assert os.access(path, os.X_OK), f'{path} is not executable'


def test_installed_package_is_importable(build):
    proc = _run_installed([sys.executable, '-c', f'import {PKG}; print({PKG}.__file__)'], build)
    assert proc.returncode == 0, explain(proc)
    assert Path(proc.stdout.strip()).is_relative_to(build['site']), (
        f'imported {proc.stdout.strip()}, not the colcon-installed copy'
    )


def test_pma_model_help(build):
    proc = _run_installed([build['prefix'] / 'lib' / PKG / 'pma-model', '--help'], build)
    assert proc.returncode == 0, f'pma-model --help failed: {explain(proc)}'
    assert 'usage' in proc.stdout.lower()


def test_ament_index_finds_share_directory(build):
    code = (
        'from ament_index_python.packages import get_package_share_directory as g; '
        f'print(g("{PKG}"))'
    )
    proc = _run_installed([sys.executable, '-c', code], build)
    assert proc.returncode == 0, explain(proc)
    assert Path(proc.stdout.strip()) == build['prefix'] / 'share' / PKG
