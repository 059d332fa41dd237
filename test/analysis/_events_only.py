"""A :class:`~folder_line.analysis.recording.Recording` of events only, as tests build one from ``simulate``."""

from __future__ import annotations

import numpy as np

from folder_line.analysis.recording import Recording
from folder_line.core.line.scene import Scene


def events_recording(scene: Scene, events: np.ndarray, duration: float, *, to_the_ns: bool = False) -> Recording:
    """A recording of ``duration`` s holding only ``events`` (their ``time_ref`` in ns); with ``to_the_ns``
    the events' times are rounded to the ns, as a bag carries them."""
    ns = np.round(events['t'] * 1e9).astype(np.int64)
    if to_the_ns:
        events = events.copy()
        events['t'] = ns / 1e9
    return Recording(
        bag=None,
        run=None,
        scene=scene,
        t_end=duration,
        duration=duration,
        events=events,
        event_ns=ns,
        joints={},
        states=[],
        commands=(),
        sheet_count=None,
        landing_x=np.zeros(0),
        bad_events=0,
    )
