"""The README stands on its own: short, no path outside the repository, and the files it names exist.

The manual is in docs/ (test/test_docs.py checks its links and its reach); the README is a pitch,
the quick start, a tour of the verbs and links into the manual.
"""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
README = REPO / 'README.md'
#: the README holds the pitch, one picture, the quick start, the verbs and the links; the manual is docs/
MAX_LINES = 200


def test_no_path_outside_the_repository() -> None:
    text = README.read_text(encoding='utf-8')
    # the project's working notes live outside the repository; the README may name none of them
    outside = ('../', 'shared' + '/spec', 'MACHINES' + '.md')
    assert not [name for name in outside if name in text]


def test_the_physics_is_referred_to_modules_that_exist() -> None:
    """The introduction sends the reader to the papers' modules: each one it names is in the repository."""
    intro = README.read_text(encoding='utf-8').split('## Quick start', 1)[0]
    named = re.findall(r'`([\w/]+\.py)`', intro)
    assert 'folder_line/core/mechanisms/layup.py' in named and 'delivery.py' in named
    mechanisms = REPO / 'folder_line' / 'core' / 'mechanisms'
    for name in named:
        assert (REPO / name).is_file() or (mechanisms / name).is_file(), name
    for paper in ('000', '001', '002'):
        assert paper in intro


def test_the_readme_is_short() -> None:
    lines = README.read_text(encoding='utf-8').splitlines()
    assert len(lines) <= MAX_LINES, f'README.md has {len(lines)} lines; at most {MAX_LINES}: move the rest to docs/'


def test_the_quick_start_is_the_two_commands() -> None:
    """``make run`` then ``make test``, as the Makefile's first line and .ci/run say."""
    text = README.read_text(encoding='utf-8')
    quick = text.split('## Quick start', 1)[1].split('\n## ', 1)[0]
    block = re.search(r'```sh\n(.*?)```', quick, re.S)
    assert block is not None
    assert [line.split('#')[0].strip() for line in block.group(1).splitlines()] == ['make run', 'make test']
    makefile = (REPO / 'Makefile').read_text(encoding='utf-8')
    assert makefile.startswith('# Quick start: `make run` then `make test`.')
    assert re.search(r'^run: ', makefile, re.M) and re.search(r'^test: ', makefile, re.M)


def test_one_picture_small_and_in_the_repository() -> None:
    text = README.read_text(encoding='utf-8')
    images = re.findall(r'!\[[^\]]*\]\(([^)\s]+)\)', text)
    assert len(images) == 1, images
    picture = REPO / images[0]
    assert picture.is_file() and picture.suffix == '.png'
    assert picture.stat().st_size < 300_000


def test_every_verb_is_toured() -> None:
    """The tour names every verb ``folder-line --help`` lists (each operator command at least by its range)."""
    from folder_line.cli.main import verbs

    text = README.read_text(encoding='utf-8')
    tour = text.split('## A tour of the verbs', 1)[1].split('\n## ', 1)[0]
    operator = {'start', 'stop', 'hold', 'unhold', 'suspend', 'unsuspend', 'reset', 'clear', 'abort'}
    missing = [v for v in verbs() if v not in operator and f'`{v}' not in tour]
    assert not missing, missing
    assert '`hold` … `abort`' in tour
