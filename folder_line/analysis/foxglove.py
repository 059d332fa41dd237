"""A Foxglove layout of a scene's line: the machine in 3D, the joint states, the constraints' margins, the
supervisor's state and the events, laid out as the Foxglove app exports a layout (JSON).

:func:`foxglove_layout` builds it from the scene: the joints each node publishes, in the order of their
``JointState`` arrays, and the constraints the supervisor judges, each plotted from ``/diagnostics``
(a status's ``margin`` value is text; Foxglove's plot reads a number from it). The shipped layouts in
``config/foxglove/`` are its output for the shipped scenes (``docs/bags.md`` tells how to open one).
"""

from __future__ import annotations

import json

from folder_line.core.line.scene import Scene
from folder_line.core.line.scenery import LINE_FRAME
from folder_line.core.line.stream import LineStream
from folder_line.files.json_types import JsonObject, JsonValue
from folder_line.interfaces import (
    DIAGNOSTICS_TOPIC,
    EVENTS_TOPIC,
    MARKERS_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    UNIT_OF_NODE,
    joint_states_topic,
)

__all__ = ['CONSTRAINT_PREFIX', 'foxglove_layout', 'layout_text']

#: a constraint's status name on ``/diagnostics`` is this prefix and the constraint's name
CONSTRAINT_PREFIX = 'folder_line/'
#: message times as the bag logs them: line time
_TIME = 'receiveTime'


def _plot(title: str, paths: list[tuple[str, str]]) -> JsonObject:
    """A Plot panel's configuration: ``paths`` of (message path, legend label), against line time."""
    return {
        'title': title,
        'paths': [{'value': p, 'label': label, 'enabled': True, 'timestampMethod': _TIME} for p, label in paths],
        'showLegend': True,
        'legendDisplay': 'top',
        'showXAxisLabels': True,
        'showYAxisLabels': True,
        'isSynced': True,
        'xAxisVal': 'timestamp',
    }


def _column(ids: list[str]) -> str | JsonObject:
    """Panels one above the other, in equal parts (a mosaic of nested splits)."""
    if len(ids) == 1:
        return ids[0]
    return {
        'direction': 'column',
        'first': ids[0],
        'second': _column(ids[1:]),
        'splitPercentage': 100.0 / len(ids),
    }


def foxglove_layout(scene: Scene) -> JsonObject:
    """The layout of ``scene``'s line.

    Left, the 3D panel on ``/line/markers`` in frame ``line``; right, a tab per node of its joint
    states (a plot per joint: position and velocity, in the joint's unit, rad or m) and a tab of the
    margins (a plot per constraint, in its unit: below zero is a violation); below them, the
    supervisor's state over time, the sheet rate and the latest event.

    Parameters
    ----------
    scene : Scene
        The scene (its machines and effects decide the joints and the constraints).

    Returns
    -------
    dict
        The layout, as the Foxglove app's *Import from file* takes it.
    """
    stream = LineStream(scene)
    config: JsonObject = {
        '3D!line': {
            'followTf': LINE_FRAME,
            'topics': {MARKERS_TOPIC: {'visible': True}},
            'layers': {'grid': {'layerId': 'foxglove.Grid', 'visible': True, 'frameId': LINE_FRAME, 'size': 10}},
        },
    }
    tabs: list[JsonValue] = []
    for node, unit in UNIT_OF_NODE.items():
        names = stream.units.get(unit, ())
        topic = joint_states_topic(node)
        panels = []
        for i, joint in enumerate(names):
            panels.append(f'Plot!{node}_{joint}')
            config[panels[-1]] = _plot(
                f'{node}: {joint}', [(f'{topic}.position[{i}]', 'position'), (f'{topic}.velocity[{i}]', 'velocity')]
            )
        if panels:
            tabs.append({'title': node, 'layout': _column(panels)})
    margins: list[str] = []
    for name, tally in stream.tallies.constraints.items():
        status = f'{DIAGNOSTICS_TOPIC}.status[:]{{name=="{CONSTRAINT_PREFIX}{name}"}}'
        margins.append(f'Plot!margin_{name}')
        config[margins[-1]] = _plot(
            f'{name}: margin, {tally.unit} (below 0: violated)',
            [
                (f'{status}.values[:]{{key=="margin"}}.value', 'margin'),
                (f'{status}.values[:]{{key=="min_margin"}}.value', 'least so far'),
            ],
        )
    if margins:
        tabs.append({'title': 'margins', 'layout': _column(margins)})
    config['Tab!views'] = {'activeTabIdx': 0, 'tabs': tabs}
    config['StateTransitions!supervisor'] = {
        'paths': [{'value': f'{SUPERVISOR_STATE_TOPIC}.data', 'label': 'supervisor', 'timestampMethod': _TIME}],
        'isSynced': True,
    }
    config['Plot!rate'] = _plot('sheets per second', [(f'{SHEET_RATE_TOPIC}.data', 'rate')])
    config['RawMessages!events'] = {'topicPath': EVENTS_TOPIC, 'diffEnabled': False, 'expansion': 'all'}
    below: JsonObject = {
        'direction': 'row',
        'first': 'StateTransitions!supervisor',
        'second': {'direction': 'row', 'first': 'Plot!rate', 'second': 'RawMessages!events', 'splitPercentage': 50},
        'splitPercentage': 40,
    }
    return {
        'configById': config,
        'globalVariables': {},
        'userNodes': {},
        'playbackConfig': {'speed': 1},
        'layout': {
            'direction': 'row',
            'first': '3D!line',
            'second': {'direction': 'column', 'first': 'Tab!views', 'second': below, 'splitPercentage': 70},
            'splitPercentage': 45,
        },
    }


def layout_text(scene: Scene) -> str:
    """:func:`foxglove_layout` as the JSON text of a file (indented, a final newline)."""
    return json.dumps(foxglove_layout(scene), indent=2) + '\n'
