"""ament_flake8, the lint test of the ament_python template, with the rules of ``ruff.toml``.

ament_flake8's own configuration plus what ``ruff.toml`` ignores, so that ``colcon test`` on a ROS
install (ament_flake8 from rosdep) and the lint gate (:mod:`test_lint`) judge the code alike.
"""

import configparser
from pathlib import Path

import pytest

from conftest import LINT_PATHS, REPO, ruff_config

try:
    from ament_flake8.main import main_with_errors
except ImportError:  # no ament_flake8: e.g. a pip install without requirements-dev.txt
    pytest.skip(
        'needs ament_flake8 (rosdep: ament_flake8; pip: ros-jazzy-ament-flake8)',
        allow_module_level=True,
    )

#: Checks of flake8's plugins that ruff does differently, and why they are off here.
FLAKE8_ONLY = {
    'E203': "whitespace before ':' in slices, as ruff format writes them (ruff: preview only)",
    'A003': "a class attribute named like a builtin (a field 'input'); ruff's A003 flags only one "
    'that shadows a use in the class body',
}


def flake8_config(tmp_path: Path) -> Path:
    """ament_flake8's configuration file with ``ruff.toml``'s ignores and first-party names."""
    import ament_flake8

    ruff = ruff_config()
    config = configparser.ConfigParser()
    config.read(Path(ament_flake8.__file__).parent / 'configuration' / 'ament_flake8.ini')
    section = config['flake8']
    ignored = [*section['extend-ignore'].split(','), *ruff['lint']['ignore'], *FLAKE8_ONLY]
    section['extend-ignore'] = ','.join(dict.fromkeys(ignored))
    section['application-import-names'] = ','.join(ruff['lint']['isort']['known-first-party'])
    section['max-line-length'] = str(ruff['line-length'])
    # one process: flake8's pool forks this pytest process, whose earlier tests left DDS and
    # executor threads; a forked worker then waited forever for its tasks (seen: test_flake8 hung
    # after test_nodes_qos.py and test_nodes_managed.py in one session)
    section['jobs'] = '1'
    path = tmp_path / 'flake8.ini'
    with open(path, 'w') as out:
        config.write(out)
    return path


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(tmp_path):
    rc, errors = main_with_errors(
        argv=['--config', str(flake8_config(tmp_path)), *(str(REPO / p) for p in LINT_PATHS)]
    )
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)
