"""The lint gate: ruff with ament_flake8's and ament_pep257's rules (``ruff.toml``)."""

import subprocess

import pytest

try:
    from ruff.__main__ import find_ruff_bin
except ImportError:  # pip-only (a -pip rosdep key): colcon test on a ROS install without it
    pytest.skip(
        'needs ruff, a pip-only library: pip install -r requirements-dev.txt',
        allow_module_level=True,
    )

from conftest import LINT_PATHS, REPO


@pytest.mark.parametrize('command', [['check'], ['format', '--check']])
def test_ruff(command: list[str]) -> None:
    run = subprocess.run(
        [find_ruff_bin(), *command, *LINT_PATHS],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
