"""What the streamed folder carries from one window to the next (:class:`FolderState`).

The signatures in the machine (:data:`SHEET_DTYPE`), the slots whose nominal time has not
come, the random streams, the cursors and the running counts of
:class:`folder_line.core.line.folder_stream.FolderStream` (its module docstring says what each is for).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from folder_line.core.effects import faults
from folder_line.core.mechanisms.belt import BeltStream
from folder_line.core.types.events import empty_events

__all__ = ['SHEET_DTYPE', 'FolderState']

#: one signature in the machine: its draws, and each time once found (NaN before)
SHEET_DTYPE = np.dtype(
    [
        ('id', 'i8'),
        ('cycle', 'i8'),  # its slot: the cycle it is handed over, folded and taken in
        ('theta_h', 'f8'),  # hand-over phase, nominal s
        ('L', 'f8'),  # travel to the stops, m
        ('mu', 'f8'),  # feed_slip friction (NaN: the effect's)
        ('e', 'f8'),  # stop_bounce restitution (NaN: the effect's)
        ('t_h', 'f8'),  # hand-over time, s
        ('b_h', 'f8'),  # belt phase at the hand-over, nominal s
        ('t_m', 'f8'),  # feed_slip: the time it reaches the belt speed, s
        ('rest', 'f8'),  # feed_slip: belt travel left after the slip, m
        ('b_a', 'f8'),  # belt phase at the arrival, nominal s
        ('t_a', 'f8'),  # at the stops, s
        ('v', 'f8'),  # impact speed, m/s
        ('t_s', 'f8'),  # settled (t_a without stop_bounce), s
        ('bounces', 'i8'),  # rebounds off the stops
        ('settle', 'f8'),  # settle time after the impact, s
        ('fate', 'i1'),  # -1 open, 0 jammed, 1 folded
        ('t_c', 'f8'),  # its cycle's knife contact, s
        ('t_x', 'f8'),  # its cycle's knife exit, s
        ('t_r', 'f8'),  # released on the pile, s
    ]
)

#: a slot whose nominal hand-over time has not come: the faults drawn for it
_SLOT_DTYPE = np.dtype(
    [('k', 'i8'), ('theta', 'f8'), ('missing', '?'), ('double', '?'), ('delay', 'f8'), ('first_id', 'i8')]
)


@dataclass
class _Counts:
    """The running counts of the summary (of the events handed out)."""

    contacts: int = 0
    started: int = 0
    fed: int = 0
    at_stops: int = 0
    folded: int = 0
    jammed: int = 0
    released: int = 0
    missing: int = 0
    double: int = 0
    late: int = 0
    slowdowns: int = 0
    bounces_max: int = 0
    settle_max: float = 0.0


@dataclass
class FolderState:
    """What the folder carries from one window to the next (module docstrings); copied whole by a checkpoint."""

    belt: BeltStream
    slowdowns: faults.SlowdownStream | None
    rng_faults: np.random.Generator | None
    rng_jitter: np.random.Generator | None
    rng_length: np.random.Generator | None
    rng_e: np.random.Generator | None
    rng_mu: np.random.Generator | None
    computed: float = -math.inf
    emitted: float = -math.inf
    slot_next: int = 0
    sheet_next: int = 0
    kc_next: int = 0
    kx_next: int = 0
    start0_found: bool = False
    start0_t: float = math.nan
    slots: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_SLOT_DTYPE))
    sheets: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=SHEET_DTYPE))
    history: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=SHEET_DTYPE))
    found: list[np.ndarray] = field(default_factory=list)  # events found, not handed out
    judged_next: int = 0  # the first cycle not judged
    # per cycle from judged_next on: signatures of its slot (-1: not drawn), settled so far, knife contact out
    expected: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    settled: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    contacted: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    exit_base: int = 0  # the cycle of exit_t[0]
    exit_t: np.ndarray = field(default_factory=lambda: np.zeros(0))  # knife exits from cycle judged_next - 1 on, s
    rows: np.ndarray = field(default_factory=empty_events)  # the rows of the cycles not judged
    t_last: float = -math.inf  # the latest event handed out, s
    counts: _Counts = field(default_factory=_Counts)
