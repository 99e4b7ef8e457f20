"""The package's shape: no import circles between its modules, no module over
:data:`MAX_LINES` lines, and at most :data:`MAX_CORE_ENTRIES` entries at the top of ``core/``.

The import graph is read from the source with :mod:`ast`, nothing is imported: every ``import``
and ``from ... import`` of a module counts, at its top, inside a function or under
``TYPE_CHECKING``; relative imports are resolved, and ``from package import name`` where ``name``
is a submodule is an import of that submodule.
"""

import ast
from pathlib import Path

PACKAGE = 'pma_model_ros'
ROOT = Path(__file__).resolve().parents[1] / PACKAGE
#: Longest module [lines]: a longer one holds more than one concern.
MAX_LINES = 600
#: Most entries (modules, subpackages and data/) at the top of core/.
MAX_CORE_ENTRIES = 10


def modules(root: Path = ROOT) -> dict[str, tuple[Path, bool]]:
    """Every module of the package by dotted name: (its file, whether it is a package)."""
    found = {}
    for path in sorted(root.rglob('*.py')):
        parts = list(path.relative_to(root.parent).with_suffix('').parts)
        is_package = parts[-1] == '__init__'
        found['.'.join(parts[:-1] if is_package else parts)] = (path, is_package)
    return found


def imported(name: str, path: Path, is_package: bool, known: set[str]) -> set[str]:
    """The modules of ``known`` that the module ``name`` (its file ``path``) imports."""
    package = name if is_package else name.rpartition('.')[0]
    targets = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), str(path))):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')[: len(package.split('.')) - node.level + 1]
                source = '.'.join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ''
            submodules = {f'{source}.{alias.name}' for alias in node.names} & known
            targets.update(submodules)
            if len(submodules) < len(node.names):
                targets.add(source)
    return (targets & known) - {name}


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Each module of the package and the modules of the package it imports."""
    found = modules(root)
    return {
        name: imported(name, path, is_package, set(found))
        for name, (path, is_package) in found.items()
    }


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One import circle (``[a, b, ..., a]``) per group of modules that import each other."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups = []

    def visit(module: str) -> None:  # Tarjan's strongly connected components
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in sorted(graph[module]):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while not group or group[-1] != module:
                group.append(stack.pop())
            if len(group) > 1:
                groups.append(set(group))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return [_circle_in(graph, group) for group in groups]


def _circle_in(graph: dict[str, set[str]], group: set[str]) -> list[str]:
    """A shortest circle through the first module of ``group`` (modules that import each other)."""
    start = min(group)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        following = []
        for module in frontier:
            for other in sorted(graph[module] & group):
                if other == start:
                    return [*paths[module], start]
                if other not in paths:
                    paths[other] = [*paths[module], other]
                    following.append(other)
        frontier = following
    raise AssertionError(f'no circle through {start}')


def test_the_graph_reads_every_kind_of_import():
    graph = import_graph()
    assert len(graph) > 50
    # relative, from a sibling package, a submodule by name from its package, inside a function
    core = 'pma_model_ros.core.'
    assert f'{core}runtime.estimation' in graph[f'{core}runtime.engine']
    assert f'{core}files.node_parameters' in graph[f'{core}runtime.engine']
    assert f'{core}physics.elementwise' in graph[f'{core}physics.geometry']
    assert f'{core}files.param_file' in graph[f'{core}identification.transfer']


def test_circles_are_found():
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a', 'd'}, 'd': set(), 'e': {'e2'}, 'e2': {'e'}}
    assert sorted(circles(graph)) == [['a', 'b', 'c', 'a'], ['e', 'e2', 'e']]
    assert circles({'a': {'b'}, 'b': set()}) == []


def test_no_import_circles():
    found = circles(import_graph())
    assert not found, 'modules that import each other:\n' + '\n'.join(
        ' -> '.join(circle) for circle in found
    )


def test_no_module_is_too_long():
    lengths = {
        path.relative_to(ROOT.parent): len(path.read_text(encoding='utf-8').splitlines())
        for path, _ in modules().values()
    }
    long = {str(path): n for path, n in lengths.items() if n > MAX_LINES}
    assert not long, f'modules over {MAX_LINES} lines: {long}'


def test_the_core_has_few_entries_at_its_top():
    entries = sorted(p.name for p in (ROOT / 'core').iterdir() if p.name != '__pycache__')
    assert len(entries) <= MAX_CORE_ENTRIES, f'core/ holds {len(entries)}: {entries}'
