"""Sphinx configuration of the folder_line manual: ``make docs`` builds it into build/docs, warnings as errors.

The prose is MyST Markdown (one page per topic); the API reference is autodoc over the
package's numpydoc docstrings (napoleon). ``rosdoc2.yaml`` at the repository root points a
ROS 2 documentation build (rosdoc2) here.
"""

from __future__ import annotations

import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))  # the package from this tree, wherever Sphinx runs

project = 'folder_line'
author = 'folder_line team'
copyright = 'folder_line team, Apache-2.0'
release = version = ET.parse(REPO / 'package.xml').getroot().findtext('version', default='')

extensions = ['myst_parser', 'sphinx.ext.autodoc', 'sphinx.ext.napoleon']
source_suffix = {'.md': 'markdown'}
root_doc = 'index'
exclude_patterns = ['_build']

# MyST: headings get anchors, so a link may name a section (`limits.md#work-a-scene-asks-for-is-bounded-up-front`)
myst_heading_anchors = 4

# autodoc + napoleon: the docstrings are numpydoc
napoleon_google_docstring = False
napoleon_numpy_docstring = True
# an Attributes section as fields of its class, so a property it names is not described twice
napoleon_use_ivar = True
autodoc_member_order = 'bysource'
# the numpydoc says each argument's type, shape and unit; the annotations (numpy's ArrayLike unions
# spelt out) would only make the signatures unreadable
autodoc_typehints = 'none'
# Short names in signatures (``Recording``, ``state``, ``t``) are defined in more than one module;
# Sphinx links each to the first it finds and warns that there were several. That is all these
# warnings say, so they are the one kind not turned into errors.
suppress_warnings = ['ref.python']

html_theme = 'alabaster'
html_title = 'folder_line'
html_theme_options = {'description': 'a folding/layup line as ROS 2 nodes', 'page_width': '1180px'}


# Two rewrites of a docstring on its way into the API pages (the docstrings stay as they are):
# * A module docstring may have sections of its own ("Model", "Geometry", underlined). In the API
#   pages many modules share a page, so their sections would clash (two "Model" targets on one
#   page); shown as rubrics they keep their titles and clash with nothing.
# * In a field napoleon made of a parameter (``:param L_k: ... > r_k + |e|.``) an absolute value
#   ``|e|`` is text, not an RST substitution: its bars are escaped. (The parameters' words are
#   read by ``simulate --list-keys`` too, so they are not put in backticks.)
# Runs after napoleon, which has turned the numpydoc sections (Parameters, Returns, Notes, ...) into fields.
_UNDERLINE = re.compile(r'^([-=~^"\'`#*+])\1{2,}\s*$')
_ABSOLUTE = re.compile(r'(?<![\\`|])\|(\w+)\|(?![\w`|])')


def _for_the_api_pages(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    out: list[str] = []
    for line in lines:
        m = _UNDERLINE.match(line)
        if m and out and out[-1].strip() and not _UNDERLINE.match(out[-1]) and not out[-1].startswith(' '):
            title = out.pop().strip()
            out += [f'.. rubric:: {title}', '']
            continue
        if line.startswith(':'):
            line = _ABSOLUTE.sub(r'\\|\1\\|', line)
        out.append(line)
    lines[:] = out


def setup(app: Any) -> None:
    app.connect('autodoc-process-docstring', _for_the_api_pages, priority=900)
