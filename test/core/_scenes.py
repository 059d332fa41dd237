"""Test scenes and effect parameters shared by the core's tests (not a test module)."""

from __future__ import annotations

import dataclasses
from typing import Any

from folder_line.config.params import config_dir, load_params, read_yaml_mapping
from folder_line.core.line.scene import Scene, parse_scene

#: seeded faults of every kind, frequent enough to show in a few seconds of line time
FAULTS: dict[str, float] = {
    'p_missing': 0.05,
    'p_double': 0.05,
    'p_late': 0.05,
    'late_delay': 0.004,
    'p_slowdown': 0.05,
    'slowdown_factor': 0.6,
    'slowdown_duration': 0.15,
}


def folder_scene(
    name: str, effects: dict[str, Any], *, delivery: dict[str, Any] | None = None, chain: dict[str, Any] | None = None
) -> Scene:
    """The shipped knife, cyclogram, feed transporter, delivery and chain with ``effects``;
    ``delivery`` and ``chain`` override keys of those two sections."""
    machines: dict[str, Any] = {sec: dataclasses.asdict(load_params(sec)) for sec in ('knife', 'cyclogram', 'delivery')}
    for sec in ('feed_transporter', 'delivery_chain'):
        machines[sec] = read_yaml_mapping(config_dir() / f'{sec}.yaml', sec)
    machines['delivery'].update(delivery or {})
    machines['delivery_chain'].update(chain or {})
    return parse_scene(
        {
            'name': name,
            'machines': machines,
            'sheets': read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets'),
            'effects': effects,
        }
    )
