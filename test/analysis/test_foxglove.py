"""The shipped Foxglove layouts: valid JSON, each the layout of its scene, and every message path in them
names a topic a recorded bag has, with the type the panel expects, and a field that is there.

The bag is read with the independent ``mcap`` reader and ``mcap_ros2``'s decoder; the paths are
evaluated on the decoded messages (the subset of Foxglove's message path syntax the layouts use:
``.field``, ``[i]``, ``[:]`` and ``{key=="value"}`` filters).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from folder_line.analysis.foxglove import layout_text
from folder_line.bag.batch import write_batch_bag
from folder_line.bag.metadata import segment_files
from folder_line.cli.main import main as cli_main
from folder_line.config.scenes import list_scenes, load_scene

REPO = Path(__file__).resolve().parents[2]
LAYOUTS = REPO / 'config' / 'foxglove'
SHIPPED = list_scenes()
_TOKEN = re.compile(r'\.(\w+)|\[(\d+)\]|\[(:)\]|\{(\w+)=="([^"]*)"\}')


def _panels(node: Any) -> Iterator[str]:
    """Panel ids in a mosaic tree."""
    if isinstance(node, str):
        yield node
    else:
        yield from _panels(node['first'])
        yield from _panels(node['second'])


def _values(msg: Any, path: str) -> list[Any]:
    """What ``path`` (after its topic) picks out of ``msg``."""
    items = [msg]
    at = 0
    while at < len(path):
        m = _TOKEN.match(path, at)
        assert m is not None, (path, at)
        field, index, every, key, value = m.groups()
        if field is not None:
            items = [getattr(x, field) for x in items if hasattr(x, field)]
        elif index is not None:
            items = [x[int(index)] for x in items if int(index) < len(x)]
        elif every is not None:
            items = [y for x in items for y in x]
        else:
            items = [x for x in items if str(getattr(x, key)) == value]
        at = m.end()
    return items


@pytest.fixture(scope='module')
def line_bag(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[str, list[Any]]]:
    """A 3 s bag of the ``line`` scene (every machine), markers on: topic -> (schema name, messages)."""
    bag = tmp_path_factory.mktemp('foxglove') / 'bag'
    write_batch_bag(bag, load_scene('line'), 3.0, marker_rate=5.0)
    (path,) = segment_files(bag)
    out: dict[str, tuple[str, list[Any]]] = {}
    with path.open('rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, _, ros in reader.iter_decoded_messages():
            assert schema is not None
            out.setdefault(channel.topic, (schema.name, []))[1].append(ros)
    return out


def test_every_shipped_scene_has_its_layout_and_it_is_current() -> None:
    assert sorted(p.stem for p in LAYOUTS.glob('*.json')) == SHIPPED
    for name in SHIPPED:
        text = (LAYOUTS / f'{name}.json').read_text(encoding='utf-8')
        assert text == layout_text(load_scene(name)), f'{name}: run folder-line layout --scene {name} --out ...'


@pytest.mark.parametrize('name', SHIPPED)
def test_a_layout_is_whole(name: str) -> None:
    """Every panel the layout places has a configuration and every configured panel is placed (a tab's too)."""
    layout = json.loads((LAYOUTS / f'{name}.json').read_text(encoding='utf-8'))
    placed = list(_panels(layout['layout']))
    for tab in layout['configById']['Tab!views']['tabs']:
        placed += list(_panels(tab['layout']))
    assert sorted(placed) == sorted(layout['configById'])
    assert layout['configById']['3D!line']['followTf'] == 'line'


#: the message type each kind of path is plotted from
EXPECTED = {
    '/line/markers': 'visualization_msgs/msg/MarkerArray',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
    '/line/supervisor/state': 'std_msgs/msg/String',
    '/line/sheet_counter/rate': 'std_msgs/msg/Float64',
    '/line/events': 'sensor_msgs/msg/TimeReference',
}


def test_every_path_of_the_line_layout_is_in_a_recorded_bag(line_bag: dict[str, tuple[str, list[Any]]]) -> None:
    layout = json.loads((LAYOUTS / 'line.json').read_text(encoding='utf-8'))
    config = layout['configById']
    topics = [*list(config['3D!line']['topics']), config['RawMessages!events']['topicPath']]
    for topic in topics:
        assert line_bag[topic][0] == EXPECTED[topic], topic
        assert line_bag[topic][1], topic  # messages to show
    assert all(m.header.frame_id == 'line' for arr in line_bag['/line/markers'][1] for m in arr.markers)
    plotted = 0
    for panel, cfg in config.items():
        for entry in cfg.get('paths', []):
            topic, _, rest = entry['value'].partition('.')
            schema, messages = line_bag[topic]
            if topic.endswith('/joint_states'):
                assert schema == 'sensor_msgs/msg/JointState', topic
                joint = cfg['title'].split(': ')[1]
                index = int(re.search(r'\[(\d+)\]', rest).group(1))  # type: ignore[union-attr]
                assert all(msg.name[index] == joint for msg in messages), (panel, joint)
            else:
                assert schema == EXPECTED[topic], topic
            values = [v for msg in messages for v in _values(msg, '.' + rest)]
            assert values, (panel, entry['value'])  # the path picks something out of the bag
            if panel.startswith('Plot!'):
                numbers = [float(v) for v in values]  # a plot needs numbers (Foxglove reads them from text)
                assert all(x == x for x in numbers), (panel, entry['value'])
            plotted += 1
    assert plotted >= 2 * 11 + 2 * 6 + 2  # 11 joints, 6 constraints, the state and the rate


def test_the_layout_verb_writes_and_refuses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'new' / 'folder.json'
    assert cli_main(['layout', '--scene', 'folder', '--out', str(out)]) == 0
    assert out.read_text(encoding='utf-8') == (LAYOUTS / 'folder.json').read_text(encoding='utf-8')
    capsys.readouterr()
    assert cli_main(['layout', '--scene', 'layup', '--set', 'layup.nope=1']) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'layup.nope' in err
    assert cli_main(['layout', '--out', str(tmp_path)]) == 2  # a folder is not a layout file
    assert capsys.readouterr().err.startswith('folder-line: error: --out')
