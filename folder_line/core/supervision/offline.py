"""The supervisor offline: :func:`replay` of a recorded stream, :func:`run_closed_loop` of the live loop.

:func:`replay` runs a :class:`~folder_line.core.supervision.supervisor.Supervisor` over what a
live supervisor was fed and reproduces its transitions exactly; :func:`run_closed_loop`
runs the live loop without ROS (the streamed line's events fed step by step, the supervisor's
commands fed back) and returns what it fed, the input of :func:`replay`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream
from folder_line.core.supervision.settings import CHECK_PERIOD
from folder_line.core.supervision.supervisor import Supervisor
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.errors import ParameterError

__all__ = ['REPLAY_WINDOW', 'replay', 'run_closed_loop']

#: line time :func:`replay` feeds and ticks at once, s (a multiple of the live check period)
REPLAY_WINDOW = 60.0


def replay(
    scene: Scene,
    events: np.ndarray,
    *,
    heard: Mapping[str, Iterable[float]] | None = None,
    clock: Iterable[float] = (),
    bad_values: Iterable[tuple[float, str, int]] = (),
    operator: Iterable[tuple[float, str]] = (),
    lost: Iterable[tuple[float, str, float]] = (),
    tunings: Iterable[tuple[float, str, float, float]] = (),
    until: float | None = None,
    window: float = REPLAY_WINDOW,
    **params: Any,
) -> Supervisor:
    """Run a :class:`~folder_line.core.supervision.supervisor.Supervisor` over a recorded stream.

    Parameters
    ----------
    scene : Scene
    events : ndarray of EVENT_DTYPE
        The events the live supervisor was fed (any order).
    heard : mapping of str to iterable of float, optional
        Node -> the stamps at which it was heard, s.
    clock : iterable of float
        Stamps of the clock messages, s (with ``clock_ticks``).
    bad_values : iterable of (float, str, int)
        ``(stamp, topic, count)`` of messages with NaN/inf.
    operator : iterable of (float, str)
        Operator commands ``(t, command)`` (the live ``operator_log``; refused ones
        are refused again).
    lost : iterable of (float, str, float)
        Participants lost ``(t, node, waited wall s)`` (the live ``lost:<node>`` violations).
    tunings : iterable of (float, str, float, float)
        Tunings accepted ``(t, key, value, effective time)`` (the live ``tuning_log``).
    until : float, optional
        The live run's last watermark, s (default: the latest input time).
    window : float
        Line time fed and ticked at once, s (> 0; default :data:`REPLAY_WINDOW`): the
        supervisor is ticked at every multiple of it, as the live one is at its check
        period, so that what it holds between ticks does not grow with the recording.
    **params
        :class:`Supervisor` parameters; ``t_start`` as the live one's.

    Returns
    -------
    Supervisor
        After the replay: its ``transitions``, ``commands``, ``violations`` and
        ``balances`` are the live run's.
    """
    if not (math.isfinite(window) and window > 0):
        raise ParameterError('window', window, 'a positive number of seconds')
    sup = Supervisor(scene, **params)
    ev = np.asarray(events).reshape(-1)
    if ev.size > 1 and not bool(np.all(ev['t'][1:] >= ev['t'][:-1])):  # a recording comes sorted: no copy then
        ev = np.sort(ev, order='t', kind='stable')
    hd = {n: np.sort(np.asarray(list(ts), dtype=float)) for n, ts in (heard or {}).items()}
    clk = np.sort(np.asarray(list(clock), dtype=float))
    bad = sorted((float(t), str(tp), int(c)) for t, tp, c in bad_values)
    ops: list[tuple[float, str, tuple[str, float, float] | None]] = sorted(
        [(float(t), str(name), None) for t, name in operator]
        + [(float(t), 'tune', (str(k), float(v), float(e))) for t, k, v, e in tunings],
        key=lambda x: x[0],
    )
    gone = sorted((float(t), str(n), float(w)) for t, n, w in lost)
    times = [ev['t'][-1]] if ev.size else []
    times += [float(a[-1]) for a in hd.values() if a.size] + [b[0] for b in bad] + [o[0] for o in ops]
    times += [g[0] for g in gone]
    times += [float(clk[-1])] if clk.size else []
    end = float(until) if until is not None else (max(times) if times else 0.0)
    i_ev = i_c = 0
    i_h = dict.fromkeys(hd, 0)
    i_b = i_g = 0

    def feed_to(t: float) -> None:
        nonlocal i_ev, i_b, i_c, i_g
        j = int(np.searchsorted(ev['t'], t, side='right'))
        sup.feed(ev[i_ev:j])
        i_ev = max(i_ev, j)
        for n, a in hd.items():
            j = int(np.searchsorted(a, t, side='right'))
            sup.heard(n, a[i_h[n] : j])
            i_h[n] = max(i_h[n], j)
        j = int(np.searchsorted(clk, t, side='right'))
        sup.clock(clk[i_c:j])
        i_c = max(i_c, j)
        while i_b < len(bad) and bad[i_b][0] <= t:
            sup.bad_value(bad[i_b][1], bad[i_b][0], bad[i_b][2])
            i_b += 1
        while i_g < len(gone) and gone[i_g][0] <= t:
            sup.lost(gone[i_g][1], gone[i_g][0], gone[i_g][2])
            i_g += 1

    ticked = 0  # the windows ticked, from 0

    def tick_to(t: float) -> None:
        """Feed and tick every window's end before ``t``, then ``t``."""
        nonlocal ticked
        while (ticked + 1) * window < t:
            ticked += 1
            feed_to(ticked * window)
            sup.tick(ticked * window)
        feed_to(t)
        sup.tick(t)

    if sup.t_start is None:
        raise ParameterError('t_start', None, "replay needs the live run's t_start")
    ticked = math.floor(max(sup.t_start, 0.0) / window)  # no tick before the live one's first
    for t_op, name, tuning in ops:
        tick_to(t_op)
        if tuning is None:
            sup.command(name, t_op)
        else:
            sup.tune(tuning[0], tuning[1], t_op, effective=tuning[2])
    tick_to(end)
    return sup


def run_closed_loop(
    scene: Scene,
    duration: float,
    *,
    step: float = CHECK_PERIOD,
    operator: Iterable[tuple[float, str]] = (),
    silent: Mapping[str, float] | None = None,
    bad_values: Iterable[tuple[float, str, int]] = (),
    **params: Any,
) -> tuple[Supervisor, LineStream, dict[str, Any]]:
    """The live loop offline: the streamed line's events fed step by step, the supervisor's commands fed back.

    Every ``step`` s of line time: the events of the stream (under the commands issued
    so far) up to the step, every watched node heard at its own
    ticks (``n P``) unless ``silent`` from some time, a clock message (with
    ``clock_ticks``), the bad values due; then a tick;
    an operator command due is given at its step. A command whose effective time is
    not after the step at which it was issued would rewrite events already fed: it
    raises (choose ``lead`` >= ``step``).

    Parameters
    ----------
    scene : Scene
        As for :class:`Supervisor`.
    duration : float
        Line time to run, s.
    step : float
        Feed and tick spacing, s.
    operator : iterable of (float, str)
        Operator commands, given at the first step at or after their time.
    silent : mapping of str to float, optional
        Node -> time from which it is no longer heard (it died).
    bad_values : iterable of (float, str, int)
        NaN/inf observations ``(stamp, topic, count)``, fed at their step.
    **params
        :class:`Supervisor` parameters.

    Returns
    -------
    (Supervisor, LineStream, dict)
        The supervisor, the stream (under every command issued), and what was fed (``events``, ``heard``,
        ``clock``, ``bad_values``, ``operator`` as given to the supervisor, ``until``): the input
        of :func:`replay`.
    """
    sup = Supervisor(scene, **params)
    stream = LineStream(scene)
    silent = dict(silent or {})
    ops = sorted(((float(t), str(n)) for t, n in operator), key=lambda x: x[0])
    bads = sorted((float(t), str(tp), int(c)) for t, tp, c in bad_values)
    fed: list[np.ndarray] = []
    heard: dict[str, list[float]] = {n: [] for n in sup.watched}
    given: list[tuple[float, str]] = []
    bad_given: list[tuple[float, str, int]] = []
    clock: list[float] = []
    n_steps = math.floor(duration / step + 1e-9)
    prev = -math.inf
    for i in range(1, n_steps + 1):
        W = i * step
        rows = stream.advance(W).events
        sup.feed(rows)
        fed.append(rows)
        for node, period in sup.watched.items():
            lo = 0 if not math.isfinite(prev) else math.floor(prev / period) + 1
            ticks = np.arange(lo, math.floor(W / period + 1e-9) + 1, dtype=float) * period
            ticks = ticks[(ticks > prev) & (ticks <= W) & (ticks < silent.get(node, math.inf))]
            sup.heard(node, ticks)
            heard[node] += ticks.tolist()
        if sup.clock_ticks:  # the clock publishes every step
            sup.clock(W)
            clock.append(W)
        while bads and bads[0][0] <= W:
            b = bads.pop(0)
            sup.bad_value(b[1], b[0], b[2])
            bad_given.append(b)
        new = sup.tick(W)
        while ops and ops[0][0] <= W:
            _, name = ops.pop(0)
            out = sup.command(name, W)
            given.append((W, name))
            if out.command is not None:
                new.append(out.command)
        for c in new:
            if c.t <= W:
                raise ParameterError(
                    'lead',
                    sup.settings.lead,
                    f'command {c.kind} effective at {c.t!r} s, not after the '
                    f'events already fed up to {W!r} s: use lead >= step',
                )
        if new:
            stream.set_commands(sup.commands)
        prev = W
    inputs = {
        'events': np.concatenate(fed) if fed else np.zeros(0, dtype=EVENT_DTYPE),
        'heard': {n: np.asarray(v) for n, v in heard.items()},
        'clock': np.asarray(clock),
        'bad_values': bad_given,
        'operator': given,
        'until': prev,
    }
    return sup, stream, inputs
