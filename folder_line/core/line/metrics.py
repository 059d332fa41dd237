"""Metrics: every numeric field of a simulation summary, named by its dotted path.

Metrics are read off the JSON document of a summary, as ``simulate --json`` writes it
(``as_json()`` of a :class:`~folder_line.core.line.line_summary.LineSummary`, or of a
:class:`~folder_line.core.line.line_summary.WindowSummary` with ``--from``): each of its
numbers (not a bool, not inside a list) is a metric named by the keys that lead to it,
joined by dots: ``violations.count``, ``min_margin_s.feed_window``,
``folder.V_tr_min``, ``layup.landing_cv``. A name may also be a unique dotted suffix of a
path (``V_tr_min`` for ``folder.V_tr_min``), as an engineer says it.
"""

from __future__ import annotations

from collections.abc import Mapping

from folder_line.errors import ParameterError

__all__ = ['flatten_metrics', 'resolve_metric']

#: numbers of the summary that are inputs, not results
_NOT_METRICS = frozenset({'seed'})


def flatten_metrics(summary: Mapping[str, object], prefix: str = '') -> dict[str, float]:
    """Every numeric leaf of ``summary`` by its dotted path, in the summary's order.

    Parameters
    ----------
    summary : mapping
        The JSON document of a summary (``LineSummary.as_json()``: nested mappings, lists, numbers,
        strings, bools).
    prefix : str
        Path of ``summary`` itself inside a larger one ('' at the top).

    Returns
    -------
    dict of str to float
        Path -> value. Bools, strings, lists and None are not metrics, nor is the top-level ``seed`` (an
        input, not a result); an int is given as a float.
    """
    out: dict[str, float] = {}
    for key, value in summary.items():
        path = f'{prefix}{key}'
        if path in _NOT_METRICS:
            continue
        if isinstance(value, Mapping):
            out.update(flatten_metrics(value, f'{path}.'))
        elif isinstance(value, int | float) and not isinstance(value, bool):
            out[path] = float(value)
    return out


def resolve_metric(name: str, paths: Mapping[str, float] | list[str] | tuple[str, ...], option: str) -> str:
    """The metric path ``name`` stands for among ``paths``: itself, or the one path ending in ``.name``.

    Raises
    ------
    ParameterError
        Naming ``option`` and ``name`` when no path, or more than one, matches (listing them).
    """
    known = list(paths)
    if name in known:
        return name
    matches = [p for p in known if p.endswith(f'.{name}')]
    if len(matches) == 1:
        return matches[0]
    if matches:
        raise ParameterError(option, name, f'is ambiguous; say one of: {", ".join(matches)}')
    close = [p for p in known if name.split('.')[-1].lower() in p.lower()][:8]
    hint = f'; similar: {", ".join(close)}' if close else ''
    raise ParameterError(option, name, f'is not a metric of this scene (see simulate --list-metrics){hint}')
