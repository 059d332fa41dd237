"""The event-kind lookups of the supervisor's per-tick path equal numpy's general functions."""

from __future__ import annotations

import numpy as np

from folder_line.core.types.events import EVENT_DTYPE, EVENT_KINDS, append_events, kind_table, kinds_in


def test_kinds_in_is_isin_for_any_value() -> None:
    names = ('sheet_handover', 'knife_contact', 'leaf_exit', 'belt_slowdown_end')
    table = kind_table(names)
    wanted = np.array([EVENT_KINDS.index(n) for n in names])
    rng = np.random.default_rng(7)
    for dtype in (np.int16, np.int64, np.int32):
        info = np.iinfo(dtype)
        kinds = np.concatenate(
            [
                np.arange(-3, len(EVENT_KINDS) + 3),
                rng.integers(info.min, info.max, 500, endpoint=True),
                [info.min, info.max, 1 << 16 if dtype != np.int16 else 0],
            ]
        ).astype(dtype)
        assert np.array_equal(kinds_in(kinds, table), np.isin(kinds, wanted)), dtype
    assert kinds_in(np.zeros(0, dtype=np.int16), table).shape == (0,)


def test_append_events_is_concatenate() -> None:
    rng = np.random.default_rng(3)
    for n, m in ((0, 0), (0, 4), (5, 0), (7, 3)):
        a, b = np.zeros(n, dtype=EVENT_DTYPE), np.zeros(m, dtype=EVENT_DTYPE)
        for x in (a, b):
            x['t'] = rng.uniform(0, 10, x.size)
            x['kind'] = rng.integers(0, len(EVENT_KINDS), x.size)
            x['sheet'] = rng.integers(-1, 100, x.size)
        out = append_events(a, b)
        assert out.dtype == EVENT_DTYPE and out.tobytes() == np.concatenate([a, b]).tobytes()
