"""What the supervisor records: :class:`Violation`, :class:`ConstraintStats`, :class:`Outcome`.

Its violations (each with the action taken), the running figures per constraint that the
supervisor node reports on ``/diagnostics``, and its answer to an operator command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from folder_line.core.line.tuning import LineCommand

__all__ = ['ConstraintStats', 'Outcome', 'Violation']


@dataclass(frozen=True)
class Violation:
    """One violated evaluation, as decided.

    Attributes
    ----------
    t : float
        Decision time, s (a knife contact, a release, a leaf exit, a check-grid
        point for liveness, a message stamp for a non-finite value).
    cycle : int
        Machine cycle of the evaluation (``chute_speed``: the leaf id; liveness and
        non-finite values: the cycle running at ``t``, -1 before the first).
    constraint : str
        Constraint name; ``liveness:<node>`` for a stale node, ``finite:<topic>``
        for a NaN/inf.
    margin : float
        Negative. Liveness: ``k P - silence`` in s at the decision; non-finite:
        minus the number of non-finite values in the message.
    unit : str
        Unit of the margin.
    action : str
        ``'hold'``, ``'suspend'`` or ``'abort'`` if that command was applied, else
        ``'none'`` (not enforcing, or PackML did not allow it in ``state``).
    state : str
        PackML state when it was decided.
    """

    t: float
    cycle: int
    constraint: str
    margin: float
    unit: str
    action: str
    state: str


@dataclass(frozen=True)
class Outcome:
    """Answer to an operator command: ``ok``, a message (the reason of a refusal), the drive command issued."""

    ok: bool
    message: str
    command: LineCommand | None = None


@dataclass
class ConstraintStats:
    """Running figures of one constraint (what ``/diagnostics`` reports).

    Attributes
    ----------
    name, unit : str
    evaluations, violations : int
    last_margin : float
        Margin of the latest evaluation (0 before any).
    last_cycle : int
    last_t : float
        Its decision time, s.
    min_margin : float
        Smallest margin so far (``inf`` before any evaluation).
    """

    name: str
    unit: str
    evaluations: int = 0
    violations: int = 0
    last_margin: float = 0.0
    last_cycle: int = -1
    last_t: float = -math.inf
    min_margin: float = math.inf

    def add(self, t: float, cycle: int, margin: float) -> None:
        self.evaluations += 1
        self.violations += int(margin < 0.0)
        self.last_margin, self.last_cycle, self.last_t = margin, cycle, t
        self.min_margin = min(self.min_margin, margin)
