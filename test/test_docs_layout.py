"""docs/architecture.md's ``## Package layout`` tree against the package's files, so it cannot
drift.
"""

from pathlib import Path
import re
import subprocess

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'pma_model_ros'
ENTRY = re.compile(r'^( {2}| {4}| {6})(\S+(?:\.py|/))(?:\s|$)')


def layout_tree() -> list[str]:
    """The paths under ``pma_model_ros/`` that docs/architecture.md's layout tree lists, in
    order.
    """
    text = (ROOT / 'docs' / 'architecture.md').read_text(encoding='utf-8')
    section = text.split('\n## Package layout\n', 1)[1].split('\n## ', 1)[0]
    block = section.split('```\n', 2)[1].splitlines()
    start = block.index(f'{PACKAGE}/')
    paths, parents = [], []
    for line in block[start + 1 :]:
        if not line.startswith(' '):
            break  # the next top-level entry
        match = ENTRY.match(line)
        if match is None:
            assert len(line) - len(line.lstrip()) > 6, (
                f'neither an entry nor a description: {line!r}'
            )
            continue
        depth = len(match.group(1)) // 2 - 1
        assert depth <= len(parents), f'{line!r} is indented deeper than its folder'
        parents = [*parents[:depth], match.group(2)]
        paths.append(''.join(parents))
    return paths


def package_files() -> list[str]:
    """The package's files: those git tracks, or outside a git work tree (a source archive in a
    colcon workspace) those on disk, without caches.
    """
    listed = subprocess.run(
        ['git', 'ls-files', PACKAGE], cwd=ROOT, capture_output=True, text=True, check=False
    )
    if listed.returncode == 0:
        return [path.removeprefix(f'{PACKAGE}/') for path in listed.stdout.split()]
    return [
        str(path.relative_to(ROOT / PACKAGE))
        for path in (ROOT / PACKAGE).rglob('*')
        if path.is_file() and '__pycache__' not in path.parts
    ]


def test_the_tree_lists_every_module_and_folder_once():
    paths = layout_tree()
    assert len(paths) == len(set(paths)), 'listed twice'
    files = package_files()
    modules = {f for f in files if f.endswith('.py')}
    assert {p for p in paths if p.endswith('.py')} == modules
    folders = {p for p in paths if p.endswith('/')}
    assert folders == {f.rsplit('/', 1)[0] + '/' for f in files if '/' in f}


def test_the_parser_reads_nesting():
    # The parser itself: core/data/ and core/physics/geometry.py under core/, and a wrapped
    # description is no entry.
    paths = layout_tree()
    assert 'core/physics/geometry.py' in paths and 'core/data/' in paths
    assert paths.index('core/') < paths.index('core/data/') < paths.index('nodes/')
