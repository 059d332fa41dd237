"""``folder-line report``'s figures and text as an engineer reads them (issue #15, item 6): the
container in ``layup_geometry.png``, no heading without content."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from folder_line.analysis.figures import pyplot
from folder_line.cli import report
from folder_line.cli.main import main
from folder_line.config.params import load_container, load_params
from folder_line.core.types.machines import ContainerParams


def _empty_headings(lines: list[str]) -> list[str]:
    """Markdown headings with nothing but blank lines before the next heading or the end."""
    empty = []
    for i, line in enumerate(lines):
        if not line.startswith('#'):
            continue
        rest = next((x for x in lines[i + 1 :] if x.strip()), None)
        if rest is None or rest.startswith('#'):
            empty.append(line)
    return empty


def test_empty_headings_helper() -> None:
    assert _empty_headings(['# a', 'text', '## b', '', '## c', 'x', '## d', '']) == ['## b', '## d']


def test_report_has_no_empty_heading(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['report', '--out', str(tmp_path)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert '## Derived figures' in printed
    assert not _empty_headings(printed)
    assert '## Plots' not in printed  # the images are in report.md; the console lists the files
    for name in ('layup_speeds.png', 'layup_geometry.png', 'delivery_efficiency.png'):
        assert f'  {name}' in printed
    md = (tmp_path / 'report.md').read_text().splitlines()
    assert not _empty_headings(md)
    plots = md[md.index('## Plots') + 1 :]
    assert [x for x in plots if x] == [
        f'![{n}]({n}.png)' for n in ('layup_speeds', 'layup_geometry', 'knife_cyclogram', 'delivery_efficiency')
    ]


def test_default_container_is_the_config() -> None:
    cont = load_container()
    assert (cont.x_left, cont.x_right, cont.y_floor, cont.bins) == (-0.45, 1.10, -1.25, 31)


WIDE = ContainerParams(x_left=-0.6, x_right=1.3, y_floor=-1.5, bins=10)


@pytest.mark.parametrize('cont', [load_container(), WIDE], ids=['default', 'wide'])
def test_layup_geometry_draws_the_container(cont: ContainerParams) -> None:
    lay = load_params('layup')
    fig = report.layup_geometry_figure(lay, cont)
    try:
        (ax,) = fig.axes
        (box,) = [ln for ln in ax.get_lines() if ln.get_label().startswith('container')]
        x, y = np.asarray(box.get_xdata()), np.asarray(box.get_ydata())
        np.testing.assert_array_equal(x, [cont.x_left, cont.x_left, cont.x_right, cont.x_right])
        # walls from the floor up to the exits' paths, in the six-bar's frame; the floor between them
        (path_c,) = [ln for ln in ax.get_lines() if ln.get_label() == 'path of exit C']
        (path_e,) = [ln for ln in ax.get_lines() if ln.get_label() == 'path of exit E']
        top = max(np.max(path_c.get_ydata()), np.max(path_e.get_ydata()))
        np.testing.assert_array_equal(y, [top, cont.y_floor, cont.y_floor, top])
        assert f'{cont.x_left:g}' in box.get_label() and f'{cont.x_right:g}' in box.get_label()
        assert f'floor y = {cont.y_floor:g} m' in box.get_label()
        texts = {t.get_text() for t in ax.texts}
        wanted = {f'x_left = {cont.x_left:g}', f'x_right = {cont.x_right:g}', f'floor y_floor = {cont.y_floor:g}'}
        assert wanted <= texts
        lo, hi = ax.get_ylim()
        assert lo < cont.y_floor and hi > 0.0  # floor and pivots in view
        x_lo, x_hi = ax.get_xlim()
        assert x_lo < cont.x_left and x_hi > cont.x_right
        # the exits sweep inside the container
        assert cont.x_left < np.min(path_c.get_xdata()) and np.max(path_e.get_xdata()) < cont.x_right
    finally:
        pyplot().close(fig)


def test_report_set_container_is_drawn_and_listed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['report', '--set', 'container.x_right=0.6', '--out', str(tmp_path / 'r')]) == 0
    out = capsys.readouterr().out
    assert '- `container.x_right=0.6`' in out  # the values given, at the top
    params = report.report_params(None, {'container.x_right': 0.6})
    assert params.container.x_right == 0.6 and params.container.x_left == load_container().x_left
    assert main(['report', '--set', 'container.depth=1', '--out', str(tmp_path / 'bad')]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith('folder-line: error: container.depth=1: unknown container parameter; known: ')
    assert not (tmp_path / 'bad').exists()  # nothing half-written
