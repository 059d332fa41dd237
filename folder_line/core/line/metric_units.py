"""Units of the metrics (:mod:`folder_line.core.line.metrics`): what a path into the summary measures.

The summary names most of its units in its keys (``knife_window_s``, ``eta_min_travel_m``,
``sprocket_torque_peak_Nm``, ``min_margin_s.*``) or next to the value (``min_margin.<c>.unit``);
:func:`metric_unit` reads those and a short table of the rest (speeds, times of the cycle).
"""

from __future__ import annotations

import re
from collections.abc import Mapping

__all__ = ['metric_unit']

#: (pattern on the dotted path, unit), the first that matches wins; '' is a count or a ratio
_RULES: tuple[tuple[re.Pattern[str], str], ...] = tuple(
    (re.compile(p), u)
    for p, u in (
        (r'(^|\.)min_margin\.[^.]+\.(cycle|evaluations|violations)$', ''),
        (r'(^|\.)min_margin_s\.', 's'),
        (r'_s$', 's'),
        (r'_m$', 'm'),
        (r'_deg$', 'deg'),
        (r'_Nm$', 'N m'),
        (r'(^|\.)(timing|slack)\.', 's'),
        (r'(^|\.)(settle_time\w*|slip_cost)$', 's'),
        (r'(^|\.)(leaves\w*|exit_speed\.leaves)$', ''),
        (r'(^|\.)(V_d|V_tr|V_tr_min|V_tr_min_with_slip|v_A|carriage_speed)$', 'm/s'),
        (r'speed(\.(min|max|mean))?$', 'm/s'),
        (r'(^|\.)accel$', 'm/s²'),
        (r'(^|\.)(first_rebound\w*|chain_travel)$', 'm'),
        (r'(^|\.)landing_x\.(mean|min|max)$', 'm'),
        (r'(^|\.)phi$', 'rad'),
    )
)


def metric_unit(path: str, summary: Mapping[str, object] | None = None) -> str:
    """The unit of the metric ``path`` ('' for a count, a ratio or where unknown).

    Parameters
    ----------
    path : str
        A dotted path of :func:`folder_line.core.line.metrics.flatten_metrics`.
    summary : mapping, optional
        The JSON document of the summary it comes from (``as_json()``): ``min_margin.<constraint>.margin``
        takes the constraint's own unit (``s``, ``m``, ``m/s``, ``sheets``; ``1`` is read as '').
    """
    m = re.match(r'^(?:.*\.)?min_margin\.([^.]+)\.margin$', path)
    if m is not None and summary is not None:
        margins = summary.get('min_margin', {})
        entry = margins.get(m.group(1), {}) if isinstance(margins, Mapping) else {}
        unit = str(entry.get('unit', '')) if isinstance(entry, Mapping) else ''
        return '' if unit == '1' else unit
    for pattern, unit in _RULES:
        if pattern.search(path):
            return unit
    return ''
