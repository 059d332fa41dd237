"""What a scene offers: its ``--set`` keys (``simulate --list-keys``), its metrics
(``simulate --list-metrics``) and the shipped scenes (``folder-line scenes``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import IO

from folder_line.config.keys import inert_keys, scene_keys
from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.config.scenes import SceneMapping, list_scenes
from folder_line.core.line.metric_units import metric_unit
from folder_line.core.line.metrics import flatten_metrics

__all__ = ['print_keys', 'print_metrics', 'print_scenes']


def _value_text(value: object) -> str:
    if isinstance(value, float):
        return f'{value:.10g}'
    return str(value)


def print_keys(data: Mapping[str, object], out: IO[str]) -> None:
    """Print every ``--set`` key of the merged scene ``data``: key, unit, the scene's value, the allowed
    range, what it is; then the keys of its sections it never reads, with why."""
    rows = [(k.key, k.unit or '-', _value_text(k.value), k.range_text(), k.note) for k in scene_keys(data)]
    widths = [max(len(r[i]) for r in [('key', 'unit', 'value', 'range', ''), *rows]) for i in range(4)]
    print(f"--set keys of scene {data.get('name')!r} (value: the scene's; range: what is accepted)", file=out)
    head = ('key', 'unit', 'value', 'range', 'what')
    for row in [head, *rows]:
        print('  '.join(cell.ljust(w) for cell, w in zip(row[:4], widths, strict=True)) + '  ' + row[4], file=out)
    inert = inert_keys(data)
    if inert:
        print('not read in this scene (refused by --set):', file=out)
        for key, why in inert.items():
            print(f'  {key}: {why}', file=out)


def print_metrics(summary: Mapping[str, object], out: IO[str]) -> None:
    """Print every metric of a simulation summary: dotted path, value, unit."""
    metrics = flatten_metrics(summary)
    width = max((len(p) for p in metrics), default=0)
    span = (
        f'line time {summary["from_s"]:g}..{summary["to_s"]:g} s (--from)'
        if 'from_s' in summary
        else f'{summary.get("duration_s"):g} s'
    )
    print(
        f'metrics of scene {summary.get("scene")!r} over {span} '
        '(a name may be any unique dotted suffix, e.g. V_tr_min)',
        file=out,
    )
    for path, value in metrics.items():
        unit = metric_unit(path, summary)
        print(f'  {path.ljust(width)}  {value:.10g}{" " + unit if unit else ""}', file=out)


def print_scenes(out: IO[str]) -> None:
    """Print the shipped scenes: name, machines, effects and description."""
    for name in list_scenes():
        data: SceneMapping = read_yaml_mapping(config_dir() / 'scenes' / f'{name}.yaml', f'scene {name}')
        machines = ', '.join(map(str, data.get('machines') or {}))
        effects_in = data.get('effects') or {}
        effects = ', '.join(
            str(e if isinstance(e, str) else next(iter(e)))
            for e in (effects_in if isinstance(effects_in, list) else list(effects_in))
        )
        print(f'{name}', file=out)
        print(f'  machines: {machines}', file=out)
        print(f'  effects:  {effects or "none"}', file=out)
        print(f'  {" ".join(str(data.get("description", "")).split())}', file=out)
