"""What the supervisor says on ``/diagnostics``, as plain data: one source for the node and the batch bag.

The ``supervisor`` node (:mod:`folder_line.ros.nodes.supervisor`) turns these into rclpy
``diagnostic_msgs/DiagnosticStatus`` messages; ``simulate --bag`` (:mod:`folder_line.bag.batch`)
into the rosbags typestore's. So a live bag and a batch bag say the same, word for word.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from folder_line.core.line.margin_text import margin_at
from folder_line.core.line.stream import ConstraintTally
from folder_line.core.supervision.balance import Balance
from folder_line.core.supervision.records import Violation

__all__ = [
    'ERROR',
    'OK',
    'TUNING_STATUS',
    'WARN',
    'Status',
    'accepted_tunings',
    'balance_status',
    'constraint_statuses',
    'event_status',
    'status_stamp',
    'tuning_status',
    'violation_status',
]

#: ``diagnostic_msgs/DiagnosticStatus`` levels
OK, WARN, ERROR = 0, 1, 2


@dataclass(frozen=True)
class Status:
    """One ``diagnostic_msgs/DiagnosticStatus``: level, name, message, hardware id, key/values."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]


def status_stamp(t: float) -> int:
    """The ``header.stamp`` of a status array about line time ``t`` (s), ns: 0 for a non-finite one."""
    return max(0, round(t * 1_000_000_000)) if math.isfinite(t) else 0


def _text(v: object) -> str:
    return repr(v) if isinstance(v, float) else str(v)


def event_status(
    what: str,
    ok: bool,
    message: str,
    values: Mapping[str, object],
    hardware_id: str,
    *,
    t_start: float | None,
    watermark: float,
    late: int,
) -> Status:
    """``folder_line/supervisor/<what>``: OK or ERROR, the values and the logic's ``t_start``, ``watermark``,
    ``late`` (floats as their ``repr``), so that a bag replays through the offline supervisor."""
    extra = {'t_start': t_start, 'watermark': watermark, 'late': late}
    return Status(
        OK if ok else ERROR,
        f'folder_line/supervisor/{what}',
        message,
        hardware_id,
        tuple((k, _text(v)) for k, v in {**values, **extra}.items()),
    )


def violation_status(v: Violation) -> tuple[bool, str, dict[str, object]]:
    """``(ok, message, values)`` of the ``violation`` status of ``v`` (stamped with ``v.t``)."""
    values = {
        't': v.t,
        'cycle': v.cycle,
        'constraint': v.constraint,
        'margin': v.margin,
        'unit': v.unit,
        'action': v.action,
        'state': v.state,
    }
    return False, f'{v.constraint} violated in {margin_at(v.constraint, v.cycle)}: {v.action}', values


#: the name of the supervisor's status of an operator's tuning (:func:`tuning_status`)
TUNING_STATUS = 'folder_line/supervisor/tuning'


def accepted_tunings(statuses: Iterable[tuple[str, Mapping[str, str]]]) -> list[tuple[float, str, float, float]]:
    """``(t asked, key, value, effective time)`` of every accepted tuning among ``(status name, key/values)``
    as recorded (:func:`tuning_status`), in order."""
    return [
        (float(v['t']), v['key'], float(v['value']), float(v['effective']))
        for name, v in statuses
        if name == TUNING_STATUS and v.get('accepted') == 'True'
    ]


def tuning_status(
    t: float, key: str, value: object, effective: float, message: str
) -> tuple[bool, str, dict[str, object]]:
    """``(ok, message, values)`` of the ``tuning`` status of an operator's tuning asked for at ``t``
    (stamped with ``t``; ``effective`` NaN if refused, ``message`` then the reason)."""
    ok = math.isfinite(effective)
    values = {'t': t, 'key': key, 'value': value, 'effective': effective, 'accepted': ok}
    return ok, message, values


def balance_status(b: Balance) -> tuple[bool, str, dict[str, object]]:
    """``(ok, message, values)`` of the ``balance`` status of ``b`` (stamped with ``b.t``)."""
    if b.missing:  # a participant was lost: no number is judged on what never arrived
        return (
            False,
            f'{b.state}: not judged: {b.missing}',
            {'t': b.t, 'state': b.state, 'missing': b.missing, 'ok': False},
        )
    message = f'{b.state}: fed {b.fed} = delivered {b.delivered} + in the machine {b.in_machine}' + (
        '' if b.ok else ' BROKEN'
    )
    values = {
        't': b.t,
        'state': b.state,
        'fed': b.fed,
        'delivered': b.delivered,
        'in_machine': b.in_machine,
        **b.detail,
        'ok': b.ok,
    }
    return b.ok, message, values


def constraint_statuses(
    tallies: Iterable[ConstraintTally], hardware_id: str, rejected: Mapping[str, int], lost: Sequence[str]
) -> list[Status]:
    """The periodic array: one status per constraint from its tally (the rows the streamed line judged by
    the time it was advanced to, :attr:`folder_line.core.line.stream.LineStream.tallies`), then
    ``folder_line/supervisor/inputs`` (``rejected`` inputs per kind, ``lost`` participants)."""
    out = []
    for c in tallies:
        name = f'folder_line/{c.name}'
        n = c.evaluations
        if n == 0:
            out.append(
                Status(OK, name, 'no cycle evaluated yet', hardware_id, (('unit', c.unit), ('evaluations', '0')))
            )
            continue
        violations = c.violations
        last = c.last_margin
        level = ERROR if last < 0.0 else WARN if violations else OK
        message = (
            f'violated in {margin_at(c.name, c.last_cycle)}'
            if last < 0.0
            else f'{violations} violations so far'
            if violations
            else 'ok'
        )
        values: tuple[tuple[str, str], ...] = (
            ('margin', repr(last)),
            ('unit', c.unit),
            ('cycle', str(c.last_cycle)),
            ('min_margin', repr(c.min_margin)),
            ('violations', str(violations)),
            ('evaluations', str(n)),
        )
        out.append(Status(level, name, message, hardware_id, values))
    total = sum(rejected.values())
    level = WARN if total else OK
    message = f'{total} inputs rejected' if total else 'no input rejected'
    inputs: list[tuple[str, str]] = [(k, str(n)) for k, n in sorted(rejected.items())]
    if lost:
        level = ERROR
        message += f'; participants lost: {", ".join(lost)}'
        inputs.append(('lost', ','.join(lost)))
    # last: the constraints keep their places in the array
    out.append(Status(level, 'folder_line/supervisor/inputs', message, hardware_id, tuple(inputs)))
    return out
