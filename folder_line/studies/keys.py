"""Scene keys as the studies vary them: checked, read back from a scene, and their units.

A study varies any key ``--set`` accepts (:func:`folder_line.config.scenes.apply_overrides`).
Before any work the key is checked against the scene: its section must be in the scene and,
for a machine, an effect, ``sheets`` or ``drive``, the field must be one of that section's
parameters. Keys that :func:`apply_overrides` handles itself (``seed``, ``sample_rate`` and
any it adds) are taken as it takes them.

Units are read from the parameter dataclasses' numpydoc (``n_c : float`` / ``Folding
cylinder speed, rev/h; ...``): the unit is the word after the description's last comma,
when it is one of :data:`UNITS`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any

from folder_line.config.scenes import apply_overrides
from folder_line.core.effects import EFFECTS
from folder_line.core.line.machines import StreamParams
from folder_line.core.line.scene import MACHINES, parse_scene
from folder_line.core.mechanisms.drive import DriveSpec
from folder_line.errors import ParameterError

__all__ = ['UNITS', 'check_key', 'key_unit', 'scene_value']

#: units a parameter's description may name (SI, and the papers' rev/h, rev/min, deg)
UNITS = frozenset(
    {'m', 'm/s', 'm/s^2', 'm/s²', 's', 'rad', 'rad/s', 'deg', 'rev/h', 'rev/min', 'N', 'N m', 'kg', 'Hz', '1/s', 'W'}
)


def _section_class(head: str) -> type[Any] | None:
    """The parameter dataclass of a key's section, or None for keys apply_overrides places itself."""
    if head in MACHINES:
        return MACHINES[head]
    if head in EFFECTS:
        return EFFECTS[head].params
    if head == 'sheets':
        return StreamParams
    if head == 'drive':
        return DriveSpec
    return None


def check_key(source: Mapping[str, Any], key: str, option: str) -> None:
    """Refuse a key the scene does not have, before any work.

    Parameters
    ----------
    source : mapping
        The complete scene mapping (:func:`folder_line.config.scenes.scene_mapping`).
    key : str
        ``SECTION.FIELD`` as ``--set`` takes it.
    option : str
        The option that named it (``--vary``, ``--find``).

    Raises
    ------
    ParameterError
        Naming ``option`` and ``key``: a section the scene does not have, or a field the section does not have.
    """
    probe = scene_value(source, key)
    try:
        apply_overrides(source, {key: 0.0 if probe is None else probe})
    except ParameterError as exc:
        raise ParameterError(option, key, exc.reason) from None
    head, _, field = key.partition('.')
    cls = _section_class(head)
    if cls is None or not dataclasses.is_dataclass(cls):
        return
    names = [f.name for f in dataclasses.fields(cls)]
    if field not in names:
        raise ParameterError(option, key, f'{head} has no parameter {field!r}; it has {", ".join(names)}')


def scene_value(source: Mapping[str, Any], key: str) -> Any:
    """The value the scene itself gives ``key`` (its file, the defaults and ``--set`` merged), or None.

    A field the mapping leaves out (a ``drive`` default) is read from the parsed scene.
    """
    if key in ('seed', 'sample_rate'):
        return source.get(key)
    head, _, field = key.partition('.')
    if head in MACHINES:
        section = (source.get('machines') or {}).get(head)
    elif head in EFFECTS:
        section = (source.get('effects') or {}).get(head)
    else:
        section = source.get(head)
    if isinstance(section, Mapping) and field in section:
        return section[field]
    if head in ('drive', 'sheets'):
        try:
            return getattr(getattr(parse_scene(source), head), field, None)
        except ParameterError:
            return None
    return None


_PARAM = re.compile(r'^\s+(?P<names>[\w, ]+) : [^\n]+\n\s+(?P<text>[^\n]+)', re.MULTILINE)


def key_unit(key: str) -> str:
    """Unit of a scene key from its section's parameter docs (``'m/s'`` for ``feed_transporter.V_tr``), or ''."""
    head, _, field = key.partition('.')
    cls = _section_class(head)
    if cls is None:
        return ''
    for match in _PARAM.finditer(cls.__doc__ or ''):
        if field not in (n.strip() for n in match['names'].split(',')):
            continue
        text = re.split(r'[;(]', match['text'])[0].rstrip(' .')
        unit = text.rpartition(',')[2].strip()
        return unit if unit in UNITS else ''
    return ''
