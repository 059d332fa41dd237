"""The manual in docs/ holds together: every link resolves, nothing points outside the repository.

``make docs`` (in CI after ``make test``) builds it with Sphinx, warnings as errors, which also
checks the toctree, the cross-references and the API reference's docstrings; that build takes
about half a minute and imports every module, so it is not run here. These tests are the cheap
part that any change to a page, a docstring or a file name can break:

* every relative link and image in README.md and docs/**/*.md names a file that exists, and a
  ``#anchor`` into a Markdown page names one of its headings;
* no file of the repository names the working notes outside it (the physics is told in
  docs/machines.md, in our words);
* every page of docs/ that a docstring or comment names exists, and the package's docstrings send
  the reader to the manual, not to the README;
* every module of the package (but the command line and the accuracy benchmark) has its
  ``automodule`` in docs/api/;
* rosdoc2 finds the Sphinx project.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / 'docs'
PAGES = sorted(DOCS.rglob('*.md'))
MARKDOWN = [REPO / 'README.md', *PAGES]

#: folders that are not the repository's own text (environments, builds, caches)
_SKIP = {
    '.git',
    '.venv',
    'build',
    'out',
    'install',
    'log',
    '__pycache__',
    '.pytest_cache',
    '.hypothesis',
    '.mypy_cache',
}

_FENCE = re.compile(r'^(```|~~~).*?^\1\s*$', re.S | re.M)
_CODE = re.compile(r'`[^`\n]*`')
_LINK = re.compile(r'!?\[(?:[^\]\\]|\\.)*\]\(([^)\s]+)(?:\s+"[^"]*")?\)')
_HEADING = re.compile(r'^(#{1,6})\s+(.*?)\s*#*\s*$', re.M)


def _prose(text: str) -> str:
    """``text`` without fenced code blocks and inline code, where a bracket is no link."""
    return _CODE.sub('', _FENCE.sub('', text))


def _anchors(page: Path) -> set[str]:
    """The ids a heading of ``page`` gets: MyST's GitHub-style slug and docutils' id."""
    out: set[str] = set()
    for _, title in _HEADING.findall(_FENCE.sub('', page.read_text(encoding='utf-8'))):
        plain = title.replace('`', '').replace('*', '')
        out.add(re.sub(r'[^\w\- ]', '', plain.lower().replace(' ', '-')))  # myst_parser.slugs.github_slugify
        out.add(re.sub(r'[^a-z0-9]+', '-', plain.lower()).strip('-'))  # docutils.nodes.make_id, ASCII titles
    return out


def _links(page: Path) -> list[str]:
    return _LINK.findall(_prose(page.read_text(encoding='utf-8')))


def _text_files() -> list[Path]:
    out = []
    for path in REPO.rglob('*'):
        rel = path.relative_to(REPO)
        if any(part in _SKIP or part.endswith('.egg-info') for part in rel.parts) or not path.is_file():
            continue
        out.append(path)
    return out


@pytest.mark.parametrize('page', MARKDOWN, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_resolves(page: Path) -> None:
    broken = []
    for target in _links(page):
        if re.match(r'[a-z][a-z0-9+.-]*:', target):  # https:, mailto: -- not ours to check
            continue
        path, _, anchor = target.partition('#')
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(f'{target}: no such file')
        elif not dest.resolve().is_relative_to(REPO):
            broken.append(f'{target}: outside the repository')
        elif anchor and dest.suffix == '.md' and anchor not in _anchors(dest):
            broken.append(f'{target}: no heading #{anchor} in {dest.relative_to(REPO)}')
    assert not broken, broken


def test_the_links_are_found() -> None:
    """The link scan sees links (a regex that matched nothing would pass every page)."""
    readme = _links(REPO / 'README.md')
    assert 'docs/machines.md' in readme and 'docs/images/line.png' in readme
    assert 'limits.md' in _links(DOCS / 'cli.md')
    assert '#default-parameters' in _anchors(DOCS / 'machines.md') or 'default-parameters' in _anchors(
        DOCS / 'machines.md'
    )


def test_every_page_is_reached_from_the_index() -> None:
    """Each page is in a toctree (Sphinx refuses an orphan with -W; this says which, without a build)."""
    listed = set()
    for page in PAGES:
        for block in re.findall(r'```\{toctree\}\n(.*?)```', page.read_text(encoding='utf-8'), re.S):
            for line in block.splitlines():
                if line.strip() and not line.startswith(':'):
                    listed.add((page.parent / line.strip()).with_suffix('.md'))
    assert [p.relative_to(REPO) for p in PAGES if p != DOCS / 'index.md' and p not in listed] == []


def test_no_file_names_the_working_notes_outside_the_repository() -> None:
    """The scans of the papers and our notes on them stay outside; the manual says the physics itself."""
    names = ('../' + 'shared', 'shared' + '/spec', 'shared' + '/seeds', 'MACHINES' + '.md', 'seeds' + '/0')
    named = []
    for path in _text_files():
        try:
            text = path.read_text(encoding='utf-8')
        except UnicodeDecodeError:  # a picture, a bag
            continue
        named += [f'{path.relative_to(REPO)}: {n}' for n in names if n in text]
    assert not named, named


def _sources() -> list[Path]:
    return [p for top in ('folder_line', 'bench', 'test', 'launch') for p in (REPO / top).rglob('*.py')]


def test_every_document_the_code_names_exists() -> None:
    missing = []
    for path in _sources():
        for name in re.findall(r'\bdocs/[\w./-]+\.md\b', path.read_text(encoding='utf-8')):
            if not (REPO / name).is_file():
                missing.append(f'{path.relative_to(REPO)}: {name}')
    assert not missing, missing


def test_the_package_sends_the_reader_to_the_manual() -> None:
    """A docstring that points at a document names a page of docs/, not the README (which is short)."""
    readme = [
        f'{p.relative_to(REPO)}:{i}'
        for p in (REPO / 'folder_line').rglob('*.py')
        for i, line in enumerate(p.read_text(encoding='utf-8').splitlines(), 1)
        if 'README' in line
    ]
    assert not readme, readme


def test_every_module_is_in_the_api_reference() -> None:
    documented = set()
    for page in (DOCS / 'api').glob('*.md'):
        documented |= set(re.findall(r'^\.\. automodule:: (\S+)$', page.read_text(encoding='utf-8'), re.M))
    modules = set()
    for path in (REPO / 'folder_line').rglob('*.py'):
        parts = path.relative_to(REPO).with_suffix('').parts
        if parts[1] in ('cli', 'accuracy'):  # documented by --help and docs/cli.md, docs/accuracy.md
            continue
        modules.add('.'.join(parts[:-1] if parts[-1] == '__init__' else parts))
    assert sorted(modules - documented) == [] and sorted(documented - modules) == []


def test_rosdoc2_finds_the_sphinx_project() -> None:
    head, config = yaml.safe_load_all((REPO / 'rosdoc2.yaml').read_text(encoding='utf-8'))
    assert head == {'type': 'rosdoc2 config', 'version': 1}
    (sphinx,) = [b['sphinx'] for b in config['builders'] if 'sphinx' in b]
    source = REPO / sphinx['sphinx_sourcedir']
    assert (source / 'conf.py').is_file() and (source / 'index.md').is_file()
    assert (REPO / config['settings']['python_source'] / '__init__.py').is_file()
    assert '<rosdoc2>rosdoc2.yaml</rosdoc2>' in (REPO / 'package.xml').read_text(encoding='utf-8')


def test_make_docs_builds_with_warnings_as_errors_in_ci() -> None:
    makefile = (REPO / 'Makefile').read_text(encoding='utf-8')
    recipe = re.search(r'^docs: .*\n\t(.*)$', makefile, re.M)
    assert recipe is not None and 'sphinx-build -W' in recipe.group(1) and 'docs build/docs' in recipe.group(1)
    ci = (REPO / '.ci' / 'run').read_text(encoding='utf-8').splitlines()
    assert ci.index('make docs') > ci.index('make test')
    assert re.search(r'^clean:.*\n\trm -rf .*\bbuild\b', makefile, re.M)
