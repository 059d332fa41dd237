"""The supervisor offline: :func:`replay` of a recorded stream, :func:`run_closed_loop` of the live loop.

:func:`replay` runs a :class:`~folder_line.core.supervision.supervisor.Supervisor` over what a
live supervisor was fed and reproduces its transitions exactly; :func:`run_closed_loop`
runs the live loop without ROS (the streamed line's events fed step by step, the supervisor's
commands fed back) and returns what it fed, the input of :func:`replay`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import LineCommand
from folder_line.core.supervision.settings import CHECK_PERIOD
from folder_line.core.supervision.supervisor import Supervisor
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.errors import ParameterError

__all__ = ['REPLAY_WINDOW', 'ReplayInputs', 'replay', 'run_closed_loop']

#: line time :func:`replay` feeds and ticks at once, s (a multiple of the live check period)
REPLAY_WINDOW = 60.0


@dataclass(frozen=True, eq=False)
class ReplayInputs:
    """What :func:`run_closed_loop` fed its supervisor: the input of :func:`replay`.

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        The events, in the order fed.
    heard : dict of str to ndarray
        Node -> the stamps at which it was heard, s.
    clock : ndarray
        Stamps of the clock messages, s (empty without ``clock_ticks``).
    bad_values : list of (float, str, int)
        ``(stamp, topic, count)`` of the non-finite values fed.
    operator : list of (float, str)
        Operator commands ``(t, command)`` as given.
    until : float
        Line time fed to, s.
    """

    events: np.ndarray
    heard: dict[str, np.ndarray]
    clock: np.ndarray
    bad_values: list[tuple[float, str, int]]
    operator: list[tuple[float, str]]
    until: float


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
    **params: Any,  # Supervisor's keyword parameters, checked there
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
    feeder = _Feeder(sup, window, ev, hd, clk, bad, gone)
    if sup.t_start is None:
        raise ParameterError('t_start', None, "replay needs the live run's t_start")
    feeder.ticked = math.floor(max(sup.t_start, 0.0) / window)  # no tick before the live one's first
    for t_op, name, tuning in ops:
        feeder.tick_to(t_op)
        if tuning is None:
            sup.command(name, t_op)
        else:
            sup.tune(tuning[0], tuning[1], t_op, effective=tuning[2])
    feeder.tick_to(end)
    return sup


class _Feeder:
    """What :func:`replay` feeds a supervisor, in time order, with a cursor into each input.

    ``ev`` the events (sorted by time), ``hd`` node -> the stamps it was heard at, ``clk`` the
    clock stamps, ``bad`` the ``(stamp, topic, count)`` of bad values and ``gone`` the
    ``(t, node, waited wall s)`` of lost participants, all sorted; ``window`` the line time fed
    and ticked at once, s; ``ticked`` the windows ticked, from 0.
    """

    def __init__(
        self,
        sup: Supervisor,
        window: float,
        ev: np.ndarray,
        hd: dict[str, np.ndarray],
        clk: np.ndarray,
        bad: list[tuple[float, str, int]],
        gone: list[tuple[float, str, float]],
    ) -> None:
        self.sup, self.window = sup, window
        self.ev, self.hd, self.clk, self.bad, self.gone = ev, hd, clk, bad, gone
        self.i_ev = self.i_c = self.i_b = self.i_g = 0
        self.i_h = dict.fromkeys(hd, 0)
        self.ticked = 0

    def feed_to(self, t: float) -> None:
        """Feed every input up to line time ``t`` (s) not fed yet."""
        sup = self.sup
        j = int(np.searchsorted(self.ev['t'], t, side='right'))
        sup.feed(self.ev[self.i_ev : j])
        self.i_ev = max(self.i_ev, j)
        for n, a in self.hd.items():
            j = int(np.searchsorted(a, t, side='right'))
            sup.heard(n, a[self.i_h[n] : j])
            self.i_h[n] = max(self.i_h[n], j)
        j = int(np.searchsorted(self.clk, t, side='right'))
        sup.clock(self.clk[self.i_c : j])
        self.i_c = max(self.i_c, j)
        bad, gone = self.bad, self.gone
        while self.i_b < len(bad) and bad[self.i_b][0] <= t:
            sup.bad_value(bad[self.i_b][1], bad[self.i_b][0], bad[self.i_b][2])
            self.i_b += 1
        while self.i_g < len(gone) and gone[self.i_g][0] <= t:
            sup.lost(gone[self.i_g][1], gone[self.i_g][0], gone[self.i_g][2])
            self.i_g += 1

    def tick_to(self, t: float) -> None:
        """Feed and tick every window's end before ``t`` (s), then ``t``."""
        while (self.ticked + 1) * self.window < t:
            self.ticked += 1
            self.feed_to(self.ticked * self.window)
            self.sup.tick(self.ticked * self.window)
        self.feed_to(t)
        self.sup.tick(t)


def run_closed_loop(
    scene: Scene,
    duration: float,
    *,
    step: float = CHECK_PERIOD,
    operator: Iterable[tuple[float, str]] = (),
    silent: Mapping[str, float] | None = None,
    bad_values: Iterable[tuple[float, str, int]] = (),
    **params: Any,  # Supervisor's keyword parameters, checked there
) -> tuple[Supervisor, LineStream, ReplayInputs]:
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
    (Supervisor, LineStream, ReplayInputs)
        The supervisor, the stream (under every command issued), and what was fed: the input of
        :func:`replay`.
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
            ticks = _node_ticks(prev, W, period, silent.get(node, math.inf))
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
        _check_lead(sup, new, W)
        if new:
            stream.set_commands(sup.commands)
        prev = W
    inputs = ReplayInputs(
        np.concatenate(fed) if fed else np.zeros(0, dtype=EVENT_DTYPE),
        {n: np.asarray(v) for n, v in heard.items()},
        np.asarray(clock),
        bad_given,
        given,
        prev,
    )
    return sup, stream, inputs


def _node_ticks(prev: float, W: float, period: float, silent_from: float) -> np.ndarray:
    """A node's ticks (multiples of its ``period``, s) after ``prev`` up to ``W`` and before ``silent_from``, s."""
    lo = 0 if not math.isfinite(prev) else math.floor(prev / period) + 1
    ticks = np.arange(lo, math.floor(W / period + 1e-9) + 1, dtype=float) * period
    ticks_heard: np.ndarray = ticks[(ticks > prev) & (ticks <= W) & (ticks < silent_from)]
    return ticks_heard


def _check_lead(sup: Supervisor, new: Iterable[LineCommand], W: float) -> None:
    """Refuse a command issued at the step ``W`` (s) that would rewrite the events already fed."""
    for c in new:
        if c.t <= W:
            raise ParameterError(
                'lead',
                sup.settings.lead,
                f'command {c.kind} effective at {c.t!r} s, not after the '
                f'events already fed up to {W!r} s: use lead >= step',
            )
