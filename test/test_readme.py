"""The README stands on its own: no path outside the repository, and the files it names exist."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
README = REPO / 'README.md'


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
