"""Packaging test: `colcon build` of this repo installs a proper ament_python package.

Builds once (module-scoped) into a temporary directory -- build, install and log
bases all live outside the source tree -- then checks the install layout, the
console scripts, the ament index and that the source tree got no build artifacts.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

PKG = 'pma_model_ros'
REPO = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).parent / 'colcon'
EXECUTABLES = ['pma-model', 'model_node', 'simulator_node']
CONFIGS = ['dmsp_10_250.yaml', 'dmsp_20_300.yaml', 'dmsp_10_100.yaml']
# Names that must never appear (newly) in the source tree because of a build.
ARTIFACT_NAMES = {'build', 'install', 'log', 'dist'}


def _artifacts():
    """Build-artifact-looking paths at the top of the repo and of the package."""
    found = set()
    for d in (REPO, REPO / PKG):
        for p in d.iterdir():
            if p.name in ARTIFACT_NAMES or p.name.endswith('.egg-info'):
                found.add(p.relative_to(REPO).as_posix())
    return found


def _run(cmd, env=None, timeout=120, cwd=None):
    return subprocess.run([str(c) for c in cmd], env=env, cwd=cwd, timeout=timeout,
                          capture_output=True, text=True)


def _run_installed(cmd, build):
    """Run with the colcon install on PYTHONPATH/AMENT_PREFIX_PATH (cwd outside the repo)."""
    return _run(cmd, env=build['env'], cwd=build['tmp'])


def _explain(proc):
    return f'exit {proc.returncode}\n--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}'


@pytest.fixture(scope='module')
def build(tmp_path_factory):
    """Run colcon once; return (install prefix of the package, env for running it)."""
    assert COLCON.exists(), f'{COLCON} missing: run scripts/setup (installs colcon into .venv)'
    tmp = tmp_path_factory.mktemp('colcon')
    before = _artifacts()
    env = dict(os.environ, COLCON_HOME=str(tmp / 'colcon_home'))
    proc = _run([COLCON, '--log-base', tmp / 'log', 'build',
                 '--base-paths', REPO, '--packages-select', PKG,
                 '--build-base', tmp / 'build', '--install-base', tmp / 'install'],
                env=env, cwd=tmp, timeout=600)
    assert proc.returncode == 0, 'colcon build failed: ' + _explain(proc)
    prefix = tmp / 'install' / PKG
    site = sorted(prefix.glob('lib/python3.*/site-packages'))
    assert site, f'no lib/python3.*/site-packages under {prefix}'
    run_env = dict(os.environ, PYTHONPATH=str(site[0]), AMENT_PREFIX_PATH=str(prefix))
    return {'prefix': prefix, 'site': site[0], 'env': run_env, 'tmp': tmp,
            'new_artifacts': _artifacts() - before}


def test_source_tree_stays_clean(build):
    assert not build['new_artifacts'], \
        f'colcon build wrote artifacts into the source tree: {sorted(build["new_artifacts"])}'


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
    assert proc.returncode == 0, _explain(proc)
    assert Path(proc.stdout.strip()).is_relative_to(build['site']), \
        f'imported {proc.stdout.strip()}, not the colcon-installed copy'


def test_pma_model_help(build):
    proc = _run_installed([build['prefix'] / 'lib' / PKG / 'pma-model', '--help'], build)
    assert proc.returncode == 0, f'pma-model --help failed: {_explain(proc)}'
    assert 'usage' in proc.stdout.lower()


def test_ament_index_finds_share_directory(build):
    code = ('from ament_index_python.packages import get_package_share_directory as g; '
            f'print(g("{PKG}"))')
    proc = _run_installed([sys.executable, '-c', code], build)
    assert proc.returncode == 0, _explain(proc)
    assert Path(proc.stdout.strip()) == build['prefix'] / 'share' / PKG
