"""The lint gate: ruff with ament_flake8's and ament_pep257's rules (``ruff.toml``)."""

from pathlib import Path
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
PATHS = ['pma_model_ros', 'test', 'bench']


def _ruff() -> str:
    found = shutil.which('ruff', path=str(Path(sys.executable).parent)) or shutil.which('ruff')
    if found is None:
        pytest.fail('ruff is not installed: scripts/setup installs it (requirements-dev.txt)')
    return found


@pytest.mark.parametrize('command', [['check'], ['format', '--check']])
def test_ruff(command: list[str]) -> None:
    run = subprocess.run(
        [_ruff(), *command, *PATHS], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert run.returncode == 0, run.stdout + run.stderr
