"""The README's walkthrough ("Your own muscle") prints what the README shows: its ``pma-model``
commands are run here as written, in a fresh folder with the files its ``cp`` lines copy, and
each output block after them is compared line by line.
"""

from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys

import pytest

from conftest import REPO

README = (REPO / 'README.md').read_text(encoding='utf-8')
#: Fenced blocks of the README in order: (info string, text).
BLOCKS = re.findall(r'^ *```(\w*)\n(.*?)^ *```', README, re.M | re.S)


def walkthrough() -> list[tuple[list[str], str]]:
    """Each sh block of ``pma-model`` commands followed by a plain block: (its commands, the
    output the README shows).
    """
    steps = []
    for (kind, text), (after, shown) in zip(BLOCKS, BLOCKS[1:]):
        commands = [line for line in text.splitlines() if line.startswith('.venv/bin/pma-model ')]
        if kind == 'sh' and commands and after == '':
            steps.append((commands, shown))
    return steps


STEPS = walkthrough()


def test_the_walkthrough_has_its_steps():
    """Fit (step 4) and the queries (step 6)."""
    assert [len(commands) for commands, _ in STEPS] == [1, 2]


@pytest.fixture(scope='module')
def folder(tmp_path_factory) -> Path:
    """The README's top folder as the walkthrough's cp lines leave it: my_map.csv, my_spec.yaml."""
    folder = tmp_path_factory.mktemp('walkthrough')
    copies = [line.split() for line in README.splitlines() if line.startswith('cp ')]
    assert len(copies) == 2
    for _, source, target in copies:
        shutil.copy(REPO / source, folder / target)
    return folder


@pytest.mark.parametrize('step', range(len(STEPS)), ids=['fit', 'force and pressure'])
def test_each_step_prints_what_the_readme_shows(folder, step):
    commands, shown = STEPS[step]
    printed = ''
    for command in commands:
        argv = shlex.split(command)[1:]
        proc = subprocess.run(
            [sys.executable, '-m', 'pma_model_ros.cli', *argv],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        printed += proc.stdout
    assert printed.strip('\n').splitlines() == shown.strip('\n').splitlines()
