"""What the figures of a recorded run show, as arrays: the numbers drawn, with no plotting.

Each function takes a :class:`~folder_line.analysis.recording.Recording` (and its
:class:`~folder_line.analysis.replay.Evaluation`) and returns the recorded samples of one
figure of :mod:`folder_line.analysis.figures` set against the model: the layup's exit
speeds (:func:`exit_speed_data`), the delivery's efficiency along the stroke
(:func:`efficiency_data`), the folder's first cycles operation by operation
(:func:`cycle_rows`) and the leaves' landing positions (:func:`landing_data`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from folder_line.analysis.recording import Recording
from folder_line.analysis.replay import Evaluation
from folder_line.core.effects import leaf_flight
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS
from folder_line.core.mechanisms import delivery
from folder_line.core.mechanisms.drive import target_rate
from folder_line.core.supervision.settings import CHECK_PERIOD, SPEED_REACHED
from folder_line.interfaces import NODE_OF_UNIT, NS_PER_S

__all__ = [
    'GANTT_CYCLES',
    'at_speed_time',
    'cycle_rows',
    'efficiency_data',
    'exit_speed_data',
    'landing_data',
    'off_speed',
]

#: cycles shown in the Gantt chart by default
GANTT_CYCLES = 8

#: the supervisor's state of a line running at speed
_AT_SPEED_STATE = 'EXECUTE'


def at_speed_time(rec: Recording, ev: Evaluation) -> float:
    """Line time at which the drive first reached speed, s: the samples before it are the start-up.

    The time of the first ``EXECUTE`` recorded on ``/line/supervisor/state`` (the supervisor
    leaves STARTING when the drive's speed factor reaches ``speed_reached``); ``inf`` if
    states were recorded but never ``EXECUTE``. Without recorded states, the first point of
    the check grid (:data:`~folder_line.core.supervision.settings.CHECK_PERIOD`) where the
    model drive ``ev.drive`` turns at :data:`~folder_line.core.supervision.settings.SPEED_REACHED`
    of the speed it heads for (nominal, or the press speed set) or more (0 for a drive at speed from the start).

    Parameters
    ----------
    rec : Recording
    ev : Evaluation
        ``rec`` judged (its ``drive``: the scene's drive under the recorded commands).

    Returns
    -------
    float
        s, in [0, inf].
    """
    if rec.states:
        return next((t_ns / NS_PER_S for t_ns, state in rec.states if state == _AT_SPEED_STATE), math.inf)
    grid = np.arange(0.0, rec.t_end + CHECK_PERIOD, CHECK_PERIOD)
    fast = np.flatnonzero(np.asarray(ev.drive.rate(grid), dtype=float) >= SPEED_REACHED * target_rate(ev.drive, grid))
    return float(grid[fast[0]]) if fast.size else math.inf


def off_speed(rec: Recording, ev: Evaluation, t: np.ndarray) -> np.ndarray:
    """Which line times ``t`` fall where the line was not running at speed: the start-up, and the
    ramps and standstills of holds, stops and suspends after it.

    With recorded states: the times before the first ``EXECUTE`` (:func:`at_speed_time`)
    and those in any later state but ``EXECUTE``. Without: where the model drive ``ev.drive``
    turns below :data:`~folder_line.core.supervision.settings.SPEED_REACHED` of its nominal speed.
    """
    t = np.asarray(t, dtype=float)
    if not rec.states:  # below the speed the drive heads for (the press speed set; nominal unless tuned)
        return np.asarray(ev.drive.rate(t), dtype=float) < SPEED_REACHED * target_rate(ev.drive, t)
    stamps = np.array([t_ns / NS_PER_S for t_ns, _ in rec.states])
    running = np.array([state == _AT_SPEED_STATE for _, state in rec.states])
    i = np.searchsorted(stamps, t, side='right') - 1  # the state shown at t
    return np.asarray((i < 0) | ~running[np.clip(i, 0, None)], dtype=bool)


def exit_speed_data(rec: Recording) -> dict[str, np.ndarray] | None:
    """The layup's exit speeds from the recorded crank_drive (and belt) joint states, or None.

    Returns
    -------
    dict or None
        ``t`` (s), ``phi`` (crank angle in [0, 2π), rad), ``vC = ω3 l3``, ``vE = ω5 l5``
        (m/s, signed), ``v_belt`` (recorded chute belt speed at the same stamps, m/s;
        0 without belts), ``vaC``, ``vaE`` (``sqrt(v² + v_belt²)``, m/s). None if the
        scene has no layup or nothing of it was recorded.
    """
    scene = rec.scene
    crank = rec.joints.get(NODE_OF_UNIT['drive'])
    if not scene.has_layup or crank is None or 'layup_crank' not in crank.names or crank.t.size == 0:
        return None
    lp = scene.machine('layup')
    t = crank.t
    phi = np.mod(crank.column('layup_crank'), 2.0 * math.pi)
    w3, w5 = crank.column('transporter3', 'velocity'), crank.column('transporter4', 'velocity')
    keep = np.ones(t.size, dtype=bool)
    v_belt = np.zeros(t.size)
    belts = rec.joints.get(NODE_OF_UNIT['belts'])
    if scene.has('chute_belts'):
        if belts is None or 'chute_belts' not in belts.names or belts.t.size == 0:
            keep[:] = False
        else:  # the belt's sample of the same tick
            i = np.minimum(np.searchsorted(belts.t, t), belts.t.size - 1)
            keep = belts.t[i] == t
            v_belt = np.where(keep, belts.column('chute_belts', 'velocity')[i], 0.0)
    vC, vE = w3 * lp.l3, w5 * lp.l5
    data = {
        't': t,
        'phi': phi,
        'vC': vC,
        'vE': vE,
        'v_belt': v_belt,
        'vaC': np.sqrt(vC * vC + v_belt * v_belt),
        'vaE': np.sqrt(vE * vE + v_belt * v_belt),
    }
    return {k: v[keep] for k, v in data.items()}


def efficiency_data(rec: Recording, ev: Evaluation) -> dict[str, np.ndarray] | None:
    """η, K_v and the sprocket torque at the recorded carriage positions, or None without a delivery.

    The stroke position ``u`` of each sample is the recorded carriage displacement
    ``x = u x_max + l (1 - cos α(u))`` inverted (x is increasing in u); samples with
    no carriage on the stroke (position and speed 0) are left out.

    Returns
    -------
    dict or None
        ``t`` (s), ``x`` (m), ``u``, ``eta`` (model at u), ``K_v_model``, ``K_v``
        (recorded carriage speed / chain speed; NaN-free: 0 where the chain stood),
        ``torque`` (recorded sprocket torque, N m; empty without efforts).
    """
    plan = ev.plan
    ft = rec.joints.get(NODE_OF_UNIT['feed'])
    if plan is None or ft is None or 'carriage' not in ft.names or ft.t.size == 0:
        return None
    x = ft.column('carriage')
    v = ft.column('carriage', 'velocity')
    v_chain = ft.column('chain', 'velocity')
    on = (x > 0.0) | (v > 0.0)
    u_grid = np.linspace(0.0, 2.0, 20001)
    st = delivery.evaluate_stroke(plan.params, u_grid, return_section='geometric')
    x_grid = u_grid * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
    u = np.interp(x[on], x_grid, u_grid)
    at = delivery.evaluate_stroke(plan.params, u, return_section='geometric')
    moving = v_chain[on] > 0.0
    kv = np.divide(v[on], v_chain[on], out=np.zeros(u.size), where=moving)
    torque = np.zeros(0)
    if ft.effort is not None and rec.scene.has('chain_friction'):
        torque = ft.column('chain', 'effort')[on]
    return {
        't': ft.t[on],
        'x': x[on],
        'u': u,
        'eta': at.eta,
        'K_v_model': at.K_v,
        'K_v': kv,
        'moving': moving,
        'torque': torque,
    }


def cycle_rows(rec: Recording, ev: Evaluation, n: int = GANTT_CYCLES) -> list[dict[str, Any]]:
    """The first ``n`` judged folder cycles (and the first violated one with its neighbours): the
    operations' times and the margins.

    Returns
    -------
    list of dict
        Per cycle: ``cycle``, ``start`` (knife exit that opens the cycle's feed window,
        s), ``contact``, ``exit`` (its knife, s; ``exit`` None if not recorded),
        ``deadline`` (end of the allowed feed time, s), ``sheets`` (list of dicts
        ``sheet``, ``handover``, ``at_stops``, ``settled``, ``release``, None where
        absent) and ``margins`` (constraint -> margin of the cycle).
    """
    timing = ev.timing
    if timing is None:
        return []
    contact = rec.events_of('knife_contact')
    judged = np.unique(contact['cycle'])
    cycles = judged[:n]
    bad = [int(c.cycle[i]) for c in ev.constraints if c.name in FOLDER_CONSTRAINTS for i in np.flatnonzero(c.violated)]
    if bad and min(bad) not in cycles:  # show the first violated cycle too, between its neighbours
        around = np.arange(min(bad) - 1, min(bad) + 2)
        cycles = np.union1d(cycles, around[np.isin(around, judged)])
    if cycles.size == 0:
        return []
    drive = ev.drive
    th_start = cycles * timing.T + timing.knife.t_out
    # to the ns, as the recorded event times (a cycle starts at the knife exit of the cycle before)
    t_start = np.round(np.asarray(drive.time_of(th_start), dtype=float) * NS_PER_S) / NS_PER_S

    def first_time(rows: np.ndarray, key: str, value: int) -> float | None:
        hit = rows[rows[key] == value]
        return float(hit['t'][0]) if hit.size else None

    exits = rec.events_of('knife_exit')
    hand = rec.events_of('sheet_handover')
    stops = rec.events_of('at_stops')
    settled = rec.events_of('settled')
    release = rec.events_of('released_on_pile')
    bouncing = rec.scene.has('stop_bounce')
    margins = {c.name: dict(zip(c.cycle.tolist(), c.margin.tolist(), strict=True)) for c in ev.constraints}
    out = []
    for k, t0 in zip(cycles.tolist(), t_start.tolist(), strict=True):
        tc = first_time(contact, 'cycle', k)
        assert tc is not None
        th_dead = float(np.asarray(drive.theta(np.asarray(tc)))) - (timing.T - timing.t_knife - timing.t_allowed)
        sheets = []
        for s in hand[hand['cycle'] == k]:
            sid = int(s['sheet'])
            t_a = first_time(stops, 'sheet', sid)
            sheets.append(
                {
                    'sheet': sid,
                    'handover': float(s['t']),
                    'at_stops': t_a,
                    'settled': first_time(settled, 'sheet', sid) if bouncing else t_a,
                    'release': first_time(release, 'sheet', sid),
                }
            )
        out.append(
            {
                'cycle': k,
                'start': t0,
                'contact': tc,
                'exit': first_time(exits, 'cycle', k),
                'deadline': float(np.asarray(drive.time_of(np.asarray(th_dead)))),
                'sheets': sheets,
                'margins': {name: m[k] for name, m in margins.items() if k in m and name in FOLDER_CONSTRAINTS},
            }
        )
    return out


def landing_data(rec: Recording) -> dict[str, Any] | None:
    """The leaves' landing positions, or None without ``leaf_flight``.

    Returns
    -------
    dict or None
        ``x`` (landed, m), ``spilled`` (m), ``edges``, ``counts`` and ``cv`` of the
        histogram across the container (:func:`folder_line.core.effects.leaf_flight.histogram`,
        the simulator's), ``x_left``, ``x_right`` (walls, m).
    """
    scene = rec.scene
    if not scene.has('leaf_flight') or 'container' not in scene.machines:
        return None
    cont = scene.machine('container')
    x = rec.events_of('leaf_landed')['value']
    hist = leaf_flight.histogram(x, cont.x_left, cont.x_right, cont.bins)
    return {
        'x': x,
        'spilled': rec.events_of('leaf_spilled')['value'],
        'edges': np.asarray(hist.edges),
        'counts': np.asarray(hist.counts),
        'cv': hist.cv,
        'x_left': float(cont.x_left),
        'x_right': float(cont.x_right),
    }
