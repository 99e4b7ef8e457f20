"""The README and docs/*.md describe the product as it is: no work history or machine words, and
every file, module or link they name exists.  The code's comments and docstrings are held to the
history and machine words too.
"""

from pathlib import Path
import re

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / 'pma_model_ros'

#: The pages: the README and every page under docs/.
PAGES = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]

#: The parameter files a user copies: their comments are documentation too.
COMMENTED = [
    *sorted((REPO / 'config').rglob('*.yaml')),
    *sorted((REPO / 'docs' / 'examples').glob('*.yaml')),
]

#: The code whose text (comments and docstrings included) is held to the same words.
CODE = [
    *sorted(PACKAGE.rglob('*.py')),
    *sorted((REPO / 'bench').glob('*.py')),
    REPO / 'bench' / 'run',
    *sorted(p for p in (REPO / 'scripts').iterdir() if p.is_file()),
]

#: Words of the work's history or of one machine, each with why it is one and what legitimate
#: text it must leave alone.
HISTORY = {
    # A work item's number: "issue 31", "Issue 13's", "issue #7".  A GitHub link is
    # ".../issues/123" or "owner/repo#123": neither has a space or '#' right after "issue".
    'issue number': r'\bissues?\s*#?\s*\d+',
    # "the targets", "this issue": the work item itself.  The word in an identifier
    # (`..._the_issue_target`) is not matched (\b does not split at '_').
    'the issue': r"\b(?:the|this|that)\s+issue\b|\bissue's\b",
    # A work stop's number: "stop 12", "stop #3".  Not a duration ("stop 5 s") or a plural verb
    # ("the node stops 2 muscles").
    'stop number': r'\bstop\s*#?\s*\d+\b(?!\s*(?:s|ms|us|µs|min|h|Hz)\b)',
    # A work session; the package has no other sessions (pytest's live only in test/, not read).
    'session': r'\bsessions?\b',
    # "this machine", "this 2-core machine", "this AMD machine": the one the text was written
    # on.  "a 2-core machine" with its figures stays: it says what was measured.
    'this machine': r'\bthis\s+(?:[\w-]+\s+){0,2}machines?\b',
    # The change being made when the text was written, not the product.
    'this change': r'\bthis\s+change\b',
    # Absolute paths of one machine.  Repository paths are relative; a URL's path has a host in
    # front (the lookbehind skips a path that continues a word, a dot or another path).
    'machine path': r'(?<![\w.~/-])/(?:tmp|work|home|root)(?:/|\b)',
    # flock lock files (a prefix of the commands that shared a machine).
    'flock': r'\bflock\b',
}
HISTORY_RE = {name: re.compile(pattern, re.I) for name, pattern in HISTORY.items()}


def history_words(text: str) -> list[tuple[int, str, str]]:
    """(line number, pattern name, matched text) of every history or machine word in ``text``."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for name, pattern in HISTORY_RE.items():
            found += [(number, name, m.group()) for m in pattern.finditer(line)]
    return found


def report(path: Path, found: list[tuple]) -> str:
    return '\n'.join(f'{path.relative_to(REPO)}:{n}: {what}: {text!r}' for n, what, text in found)


# --- (a) history and machine words


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_a_page_has_no_history_or_machine_words(page):
    found = history_words(page.read_text(encoding='utf-8'))
    assert not found, '\n' + report(page, found)


@pytest.mark.parametrize('path', CODE + COMMENTED, ids=lambda p: str(p.relative_to(REPO)))
def test_the_code_has_no_history_or_machine_words(path):
    found = history_words(path.read_text(encoding='utf-8'))
    assert not found, '\n' + report(path, found)


@pytest.mark.parametrize(
    'text',
    [
        'the targets of issue 31',
        "Issue 13's case",
        'as in issue #7',
        "the issue's targets",
        "the\nissue's targets",
        'measured at stop 12',
        'in the last session',
        '7.4 s on this 2-core machine',
        'on this machine',
        'this change makes it faster',
        'written to /tmp/x.mcap',
        '`/work/main/config`',
        'under /home/user',
        '/root/.ros',
        'flock /tmp/lock bench/run',
    ],
)
def test_each_history_pattern_finds_its_words(text):
    assert history_words(text), text


@pytest.mark.parametrize(
    'text',
    [
        'eProsima/Fast-DDS#6502, see https://github.com/ros2/rclpy/issues/1234',
        '`test_martens_end_predicts_dmsp_20_300_within_the_issue_target` pins it',
        'the simulator stops 2 s later; a stop 5 ms after the last message',
        'on a 2-core machine shared with other jobs; a ROS 2 Jazzy machine',
        'the node changes nothing; this changes no figure',
        'pma_model_ros/core/data/tmp/x, https://example.org/home/index, ~/home/x, ./tmp/x',
    ],
)
def test_legitimate_text_passes(text):
    assert not history_words(text), history_words(text)


# --- (b) files, modules and links named in the pages

#: Path-like mentions, each resolved from the repository root (``root``) or from the package
#: (``package``): a mention must not continue a word, a dot or another path (URLs, ``.venv/...``,
#: ``site-packages/rclpy/...``).
START = r'(?<![\w.~/$-])'
PATHS = [
    # pma_model_ros/..., any file or folder
    ('root', re.compile(START + r'(pma_model_ros/[\w./-]*)')),
    # the package's subfolders named without pma_model_ros/: core/..., nodes/..., a module or a
    # folder (core/data/, core/physics/)
    (
        'package',
        re.compile(START + r'((?:core|nodes|bags|wire|cli|tools)/(?:[\w-]+/)*(?:\w+\.py)?)'),
    ),
    ('root', re.compile(START + r'(bench/[\w.-]+)')),
    ('root', re.compile(START + r'(scripts/[\w.-]+)')),
    ('root', re.compile(START + r'(test/[\w.-]+\.py)')),
    ('root', re.compile(START + r'(config/[\w./-]*)')),
    ('root', re.compile(START + r'(docs/[\w./-]*)')),
]
#: Dotted module paths: pma_model_ros.core.engine, or from a subpackage of the package
#: (core.param_file.all_node_settings); a module may be followed by attributes.
DOTTED = re.compile(
    r'(?<![\w./-])((?:pma_model_ros|core|nodes|bags|wire|tools)(?:\.[A-Za-z_]\w*)+)(?![\w/-])'
)
#: Suffixes that make a dotted name a file's name, not a module path.
FILE_SUFFIXES = {
    'md',
    'py',
    'yaml',
    'csv',
    'png',
    'svg',
    'mcap',
    'db3',
    'txt',
    'toml',
    'cfg',
    'xml',
}
#: Markdown links [text](target); targets without a scheme are files of the repository.
LINK = re.compile(r'\]\(([^)\s]+)\)')


def path_mentions(text: str) -> list[tuple[int, str, Path]]:
    """(line number, mention, the path it names) of each path-like mention in ``text``."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for base, pattern in PATHS:
            for match in pattern.finditer(line):
                mention = match.group(1).rstrip('.')
                if any(c in line[match.end(1) : match.end(1) + 1] for c in '*{<'):
                    continue  # a pattern (bench/*.py, test/test_<package>_<module>.py)
                root = REPO if base == 'root' else PACKAGE
                found.append((number, mention, root / mention))
    return found


def defines(module: Path, name: str) -> bool:
    """Whether ``module`` (a .py file or a package's __init__.py) has ``name`` in its text: a
    definition, an assignment or an import.
    """
    return re.search(rf'\b{re.escape(name)}\b', module.read_text(encoding='utf-8')) is not None


def dotted_problem(dotted: str) -> str | None:
    """Why the dotted path ``dotted`` names no module of the package (with at most two
    attributes after it), or None.
    """
    parts = dotted.split('.')
    if parts[0] == 'pma_model_ros':
        parts = parts[1:]
    where, module = PACKAGE, PACKAGE / '__init__.py'
    for i, part in enumerate(parts):
        if (where / part / '__init__.py').is_file():
            where, module = where / part, where / part / '__init__.py'
        elif (where / f'{part}.py').is_file():
            module, rest = where / f'{part}.py', parts[i + 1 :]
            break
        else:
            rest = parts[i:]
            break
    else:
        return None
    if not rest:
        return None
    if len(rest) > 2 or not defines(module, rest[0]):
        folder = module.parent.relative_to(REPO)
        return f'{rest[0]!r} is no module of {folder}/ nor a name in {module.name}'
    return None


def github_anchor(title: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation but '-' and '_' dropped,
    spaces to hyphens.
    """
    title = re.sub(r'[`*]', '', title.strip().lower())
    return re.sub(r'[^\w\- ]', '', title).replace(' ', '-')


def anchors(page: Path) -> set[str]:
    text = re.sub(r'```.*?```', '', page.read_text(encoding='utf-8'), flags=re.S)
    return {github_anchor(t) for t in re.findall(r'^#+\s+(.*)$', text, re.M)}


def missing_names(page: Path) -> list[tuple[int, str, str]]:
    """(line number, kind, mention) of each file, module or link of ``page`` that does not
    exist.
    """
    text = page.read_text(encoding='utf-8')
    problems = [(n, 'no such file', m) for n, m, path in path_mentions(text) if not path.exists()]
    for number, line in enumerate(text.splitlines(), 1):
        for match in DOTTED.finditer(line):
            if match.group(1).rsplit('.', 1)[1] in FILE_SUFFIXES:
                continue  # a file's name: bags.md, core.py
            why = dotted_problem(match.group(1))
            if why is not None:
                problems.append((number, why, match.group(1)))
        for target in LINK.findall(line):
            if re.match(r'[a-z]+:', target):
                continue  # https:, mailto:
            file, _, anchor = target.partition('#')
            path = (page.parent / file) if file else page
            if not path.exists():
                problems.append((number, 'link to no file', target))
            elif anchor and path.suffix == '.md' and anchor not in anchors(path):
                problems.append((number, 'link to no heading', target))
    return list(dict.fromkeys(problems))  # a mention and its link: once


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_file_module_and_link_a_page_names_exists(page):
    problems = missing_names(page)
    assert not problems, '\n' + report(page, problems)


def test_every_page_the_code_names_exists():
    """The code's docstrings and help texts, and the comments of the parameter files, point at
    pages (``docs/calibration.md``).
    """
    problems = []
    for path in CODE + COMMENTED:
        for number, mention, target in path_mentions(path.read_text(encoding='utf-8')):
            if mention.startswith('docs/') and not target.exists():
                problems.append(f'{path.relative_to(REPO)}:{number}: {mention}')
    assert not problems, '\n' + '\n'.join(problems)


def test_the_name_checks_find_what_does_not_exist(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text(
        '# A page\n'
        'core/no_such_module.py, `pma_model_ros/nodes/nothing.py`, bench/nothing.py,\n'
        'scripts/nothing, test/test_nothing.py, config/nothing.yaml, docs/nothing.md,\n'
        'pma_model_ros.core.no_such_module, core.no_such_module.f,\n'
        '[a](nothing.md), [b](#no-heading)\n',
        encoding='utf-8',
    )
    found = [mention for _, _, mention in missing_names(page)]
    assert sorted(found) == sorted(
        [
            'core/no_such_module.py',
            'pma_model_ros/nodes/nothing.py',
            'bench/nothing.py',
            'scripts/nothing',
            'test/test_nothing.py',
            'config/nothing.yaml',
            'docs/nothing.md',
            'pma_model_ros.core.no_such_module',
            'core.no_such_module.f',
            'nothing.md',
            '#no-heading',
        ]
    )


def test_the_name_checks_pass_what_exists(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text(
        '# A page: `its` title\n'
        '## `model_node` over DDS\n'
        'pma_model_ros/wire/cdr.py and wire/cdr.py, pma_model_ros/core/data/, bench/run,\n'
        'bench/*.py, scripts/test, test/test_docs.py::test_x, config/dmsp_10_250.yaml, bags.md\n'
        'pma_model_ros.wire.cdr, pma_model_ros.wire,\n'
        'pma_model_ros.bags.synthetic.record_simulation,\n'
        'site-packages/rclpy/executors.py, https://example.org/core/x.py, .venv/bin/x\n'
        '[a](#a-page-its-title), [b](https://example.org/nothing.md), [c](#model_node-over-dds)\n',
        encoding='utf-8',
    )
    assert missing_names(page) == []


def test_the_readme_is_a_guide_of_at_most_300_lines():
    """The README walks a newcomer through; the reference lives in docs/."""
    lines = (REPO / 'README.md').read_text(encoding='utf-8').count('\n')
    assert lines <= 300, f'README.md has {lines} lines: move reference material to docs/'
