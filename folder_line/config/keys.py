"""Every key ``--set`` accepts for a scene, with its unit, the scene's value and the allowed range.

One source for units and ranges: the numpydoc ``Attributes`` (or ``Parameters``) section of each
parameter dataclass (``V_tr : float`` / ``Belt speed at nominal line speed, m/s (> 0).``) gives the
unit (the first known unit after a comma) and the range (``in [0, 1)``, ``(> 0)``, ``>= 0``); a
physical range of :mod:`folder_line.core.limits` that names the key (``(`knife.n_k`)``) takes
precedence, since the dataclass checks that one. Text keys list their choices from the registries
the dataclasses check them against. ``test/config/test_keys.py`` checks every printed range against
the real validation (a value just outside is refused, one just inside accepted).

Keys the scene would never read (:func:`folder_line.core.line.inert.inert_reason`) are not
listed: ``--set`` refuses them.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from folder_line.config.scenes import DRIVE_DEFAULT, PRESS_KEYS
from folder_line.core.effects import EFFECTS
from folder_line.core.effects.arrival_jitter import DISTRIBUTIONS
from folder_line.core.effects.motor_dynamics import METHODS
from folder_line.core.limits import CYLINDER_SPEED, LIMITS, SAMPLE_RATE, Limit
from folder_line.core.line.inert import inert_reason
from folder_line.core.line.scene import MACHINES
from folder_line.core.mechanisms.delivery import RETURN_SECTIONS
from folder_line.core.mechanisms.delivery_laws import law_names
from folder_line.core.mechanisms.drive import DRIVE_PROFILES, DriveSpec
from folder_line.core.types.machines import StreamParams

__all__ = ['KeyInfo', 'field_docs', 'inert_keys', 'scene_keys']

#: units a field's description may name after a comma, longest first so that ``N m s`` is not read as ``N``
_UNITS = (
    'kg m²',
    'N m s',
    'N m',
    'm/s²',
    'm/s',
    'rev/min',
    'rev/h',
    'rad/s',
    '1/s',
    'Hz',
    'degrees',
    'dimensionless',
    'kg',
    'N',
    'mm',
    'm',
    's',
)
_UNIT_RE = re.compile(r',\s+(' + '|'.join(re.escape(u) for u in _UNITS) + r')(?=[\s;,.(]|$)')
_NUM = r'-?\d+(?:\.\d+)?(?:e[-+]?\d+)?'
_INTERVAL_RE = re.compile(r'in\s+([\[(])\s*(' + _NUM + r'),\s*(' + _NUM + r')\s*([\])])')
_BOUND_RE = re.compile(r'(>=|>)\s*(' + _NUM + r')(?!\w|\.\d)')
#: text keys: their choices, from the registries the dataclasses check them against
_CHOICES: dict[str, tuple[str, ...]] = {
    'drive.profile': DRIVE_PROFILES,
    'delivery.law': law_names(),
    'chain_friction.return_section': RETURN_SECTIONS,
    'motor_dynamics.method': METHODS,
    'arrival_jitter.distribution': DISTRIBUTIONS,
}
#: the seed: what :func:`folder_line.core.line.scene.parse_scene` accepts
_SEED_HI = 2**63


@dataclass(frozen=True)
class KeyInfo:
    """One key of ``--set``.

    Attributes
    ----------
    key : str
        As ``--set`` takes it (``knife.n_k``, ``feed_slip.mu``, ``sheets.phase``, ``seed``, ``press.n_c``).
    unit : str
        Unit of the value ('' for a ratio, a count or text).
    value : object
        The scene's value (its default).
    lo, hi : float
        The allowed range (``-inf``/``inf`` where open-ended); NaN both when the documentation gives no
        numeric range (text keys, or a bound set by another key).
    lo_open, hi_open : bool
        Whether an end is excluded.
    whole : bool
        The value is a whole number.
    choices : tuple of str
        The accepted values of a text key.
    note : str
        What the key is (its documentation up to the unit), and how it is tied to others.
    rule : str
        The documentation's words on the allowed values after the unit (``> r_k + |e|``): what
        :meth:`range_text` shows where no numeric range is known.
    """

    key: str
    unit: str
    value: object
    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False
    whole: bool = False
    choices: tuple[str, ...] = ()
    note: str = ''
    rule: str = ''

    @property
    def has_range(self) -> bool:
        """Whether a numeric range is known (at least one finite end)."""
        return not (math.isnan(self.lo) or math.isnan(self.hi)) and (math.isfinite(self.lo) or math.isfinite(self.hi))

    def range_text(self) -> str:
        """``[1, 100000]``, ``(0, inf)``, ``one of constant, ramp``, the documented rule, or ``-``."""
        if self.choices:
            return 'one of ' + ', '.join(self.choices)
        if not self.has_range:
            return self.rule or '-'
        left = '(' if self.lo_open or not math.isfinite(self.lo) else '['
        right = ')' if self.hi_open or not math.isfinite(self.hi) else ']'
        return f'{left}{self.lo:.10g}, {self.hi:.10g}{right}'


def field_docs(cls: type) -> dict[str, str]:
    """Field name -> its description in the numpydoc ``Attributes``/``Parameters`` section of ``cls``.

    A line ``a, b : float`` documents both fields. Fields without an entry are absent.
    """
    lines = inspect.cleandoc(cls.__doc__ or '').splitlines()
    out: dict[str, str] = {}
    names: list[str] = []
    inside = False
    for i, line in enumerate(lines):
        underline = i + 1 < len(lines) and lines[i + 1].strip() and set(lines[i + 1].strip()) == {'-'}
        if underline:  # a section heading
            inside = line.strip() in ('Attributes', 'Parameters')
            names = []
            continue
        if not inside or (line.strip() and set(line.strip()) == {'-'}):
            continue
        head = re.match(r'^(\w+(?:\s*,\s*\w+)*)\s*:', line)
        if head and not line.startswith(' '):
            names = [n.strip() for n in head.group(1).split(',')]
            for n in names:
                out[n] = ''
        elif line.startswith(' ') and names:
            for n in names:
                out[n] = f'{out[n]} {line.strip()}'.strip()
    return out


def _limit_of(key: str) -> Limit | None:
    """The limit of :mod:`folder_line.core.limits` whose description names ``key`` in backquotes."""
    for limit in LIMITS.values():
        named = re.findall(r'`([\w.]+)`', limit.what)
        if key in named or f'effects.{key}' in named:
            return limit
    return None


def _unit(doc: str) -> str:
    m = _UNIT_RE.search(doc)
    if m is None or m.group(1) == 'dimensionless':
        return ''
    return m.group(1)


def _documented_range(doc: str) -> tuple[float, float, bool, bool]:
    """(lo, hi, lo_open, hi_open) from the description; NaN bounds if it gives none."""
    found = _INTERVAL_RE.search(doc)
    bound = _BOUND_RE.search(doc)
    if found and (bound is None or found.start() < bound.start()):
        return float(found.group(2)), float(found.group(3)), found.group(1) == '(', found.group(4) == ')'
    if bound:
        return float(bound.group(2)), math.inf, bound.group(1) == '>', False
    return math.nan, math.nan, False, False


def _what(doc: str) -> str:
    """What a field is: its description up to the unit (``Crank radius O1A``), or its first sentence."""
    text = re.sub(r'\s+', ' ', doc).strip()
    unit = _UNIT_RE.search(text)
    if unit is not None:
        return text[: unit.start()]
    m = re.match(r'(.+?[.;])(\s|$)', text)
    return (m.group(1) if m else text).rstrip('.;')


def _rule(doc: str) -> str:
    """The documentation's words on the allowed values: what follows the unit (or the first comma)."""
    text = re.sub(r'\s+', ' ', doc).strip()
    unit = _UNIT_RE.search(text)
    rest = text[unit.end() :] if unit is not None else text.partition(', ')[2]
    rest = rest.strip(' ,;:.')
    if rest.startswith('(') and rest.endswith(')'):
        rest = rest[1:-1]
    return rest


def _info(key: str, cls: type, field: dataclasses.Field[object], value: object, docs: Mapping[str, str]) -> KeyInfo:
    doc = docs.get(field.name, '')
    whole = field.type in ('int', int)
    limit = _limit_of(key)
    if limit is not None:
        lo, hi, lo_open, hi_open = limit.lo, limit.hi, False, False
        unit = limit.unit
    else:
        lo, hi, lo_open, hi_open = _documented_range(doc)
        unit = _unit(doc)
    return KeyInfo(
        key=key,
        unit=unit,
        value=value,
        lo=lo,
        hi=hi,
        lo_open=lo_open,
        hi_open=hi_open,
        whole=whole,
        choices=_CHOICES.get(key, ()),
        note=_what(doc),
        rule=_rule(doc),
    )


def _section_keys(prefix: str, cls: type, values: Mapping[str, object]) -> Iterator[KeyInfo]:
    docs = field_docs(cls)
    for field in dataclasses.fields(cls):
        if field.init:
            yield _info(f'{prefix}.{field.name}', cls, field, values.get(field.name), docs)


def _all_keys(data: Mapping[str, Any]) -> Iterator[KeyInfo]:
    machines = data.get('machines') or {}
    for section, values in machines.items():
        if section in MACHINES and isinstance(values, Mapping):
            yield from _section_keys(section, MACHINES[section], values)
    if 'knife' in machines and 'cyclogram' in machines:
        n_c = machines['cyclogram'].get('n_c')
        for field in PRESS_KEYS:
            yield KeyInfo(
                key=f'press.{field}',
                unit=CYLINDER_SPEED.unit,
                value=n_c,
                lo=CYLINDER_SPEED.lo,
                hi=CYLINDER_SPEED.hi,
                note='Press speed: sets cyclogram.n_c to it and knife.n_k to twice it',
            )
    yield from _section_keys('sheets', StreamParams, data.get('sheets') or {})
    yield from _section_keys('drive', DriveSpec, {**DRIVE_DEFAULT, **(data.get('drive') or {})})
    for name, values in (data.get('effects') or {}).items():
        if name in EFFECTS and isinstance(values, Mapping):
            yield from _section_keys(name, EFFECTS[name].params, values)
    yield KeyInfo(
        key='seed',
        unit='',
        value=data.get('seed', 0),
        lo=0.0,
        hi=float(_SEED_HI),
        hi_open=True,
        whole=True,
        note='Seed of every random draw',
    )
    yield KeyInfo(
        key='sample_rate',
        unit=SAMPLE_RATE.unit,
        value=data.get('sample_rate', 0.0),
        lo=SAMPLE_RATE.lo,
        hi=SAMPLE_RATE.hi,
        note='Joint-state sample rate (0: events only)',
    )


def _tied(info: KeyInfo) -> KeyInfo:
    """The knife and cylinder speeds: set together with ``press.n_c``."""
    if info.key in ('knife.n_k', 'cyclogram.n_c'):
        return dataclasses.replace(info, note=f'{info.note}; set with press.n_c (knife.n_k = 2 cyclogram.n_c)')
    return info


def _read(data: Mapping[str, Any], key: str) -> bool:
    machines = [m for m in (data.get('machines') or {}) if isinstance(m, str)]
    effects = [e for e in (data.get('effects') or {}) if isinstance(e, str)]
    return inert_reason(key, machines, effects) is None


def scene_keys(data: Mapping[str, Any]) -> list[KeyInfo]:
    """Every key ``--set`` accepts for the merged scene mapping ``data``
    (:func:`folder_line.config.scenes.scene_mapping`), in the scene's order.

    Parameters
    ----------
    data : mapping
        A merged scene (defaults and overrides in).

    Returns
    -------
    list of KeyInfo
        Machine keys, ``press.n_c`` (with a folder), ``sheets.*``, ``drive.*``, the listed effects' keys,
        ``seed``, ``sample_rate``; keys the scene never reads left out (:func:`inert_keys`).
    """
    return [_tied(info) for info in _all_keys(data) if _read(data, info.key)]


def inert_keys(data: Mapping[str, Any]) -> dict[str, str]:
    """The keys of the scene's sections that it never reads, each with why
    (:func:`folder_line.core.line.inert.inert_reason`)."""
    machines = [m for m in (data.get('machines') or {}) if isinstance(m, str)]
    effects = [e for e in (data.get('effects') or {}) if isinstance(e, str)]
    out: dict[str, str] = {}
    for info in _all_keys(data):
        why = inert_reason(info.key, machines, effects)
        if why is not None:
            out[info.key] = why
    return out
