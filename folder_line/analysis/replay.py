"""The recorded run judged again: the line's constraints on the recorded events, the supervisor replayed.

The same constraint code as the line
------------------------------------
:func:`evaluate` judges the events of a :class:`~folder_line.analysis.recording.Recording`
with the functions the batch simulator and the live supervisor call,
:func:`folder_line.core.line.constraints.folder_evaluation` and
:func:`folder_line.core.line.constraints.evaluate_layup_constraints`, on the scene stored
in the bag and its drive under the recorded supervisor commands. Its numbers are
therefore those of ``simulate(scene, t_end, commands=...)`` for a run of ``t_end`` s (up
to the ns rounding of the event times), and the per-constraint figures are computed by
:meth:`folder_line.core.line.model.LineResult.summary`, as the ``simulate`` verb's are.

State transitions
-----------------
The recorded inputs of the live supervisor -- the events, the joint-state stamps
(liveness), the ``/clock`` messages, the operator's commands -- are replayed through
:func:`folder_line.core.supervision.offline.replay`, the logic the live node runs
(:func:`replay_transitions`): the transitions with their decision times and causes, and
the violations as the supervisor decided them (causal, with the action taken).
:func:`transitions_agree` says whether they agree with the states recorded on
``/line/supervisor/state`` (:func:`recorded_transitions`). The node's parameters are
read from the bag's custom data ``folder_line.supervisor`` (JSON) if it is there, else
they are the ones ``folder-line run`` starts the node with (:data:`SUPERVISOR_DEFAULTS`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from folder_line.analysis.recording import Recording
from folder_line.bag.statuses import accepted_tunings
from folder_line.core.line.constraints import evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.delivery_plan import delivery_plan
from folder_line.core.line.events import ConstraintSeries, event_kind
from folder_line.core.line.drives import make_drive
from folder_line.core.line.model import LineModel, LineResult
from folder_line.core.line.tuning import LineCommand
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.supervision.offline import replay
from folder_line.interfaces import NS_PER_S

__all__ = [
    'KEY_SUPERVISOR',
    'SUPERVISOR_DEFAULTS',
    'Evaluation',
    'evaluate',
    'recorded_transitions',
    'replay_transitions',
    'supervisor_parameters',
    'transitions_agree',
]


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The recorded events judged by the line's constraint code (:func:`evaluate`).

    Attributes
    ----------
    drive : Drive
        The scene's drive under the recorded commands, up to the run's horizon.
    timing : CycleTiming or None
        The folder's cycle timing (None without the folder).
    plan : DeliveryPlan or None
        The delivery's plan (None without the folder).
    constraints : list of ConstraintSeries
        Every constraint judged, per cycle or leaf.
    signatures : ndarray of int64
        Sheets per folder cycle (empty without the folder).
    cycles, sheets_counted : int
    summary : dict
        :meth:`folder_line.core.line.model.LineResult.summary` of the recorded events,
        with ``cycles`` and ``sheets_counted``.
    """

    drive: Drive
    timing: Any
    plan: Any
    constraints: list[ConstraintSeries]
    signatures: np.ndarray
    cycles: int
    sheets_counted: int
    summary: dict[str, Any]


def evaluate(rec: Recording, t_from: float = 0.0) -> Evaluation:
    """The recorded events judged by the line's constraint code; the simulate-style summary.

    Parameters
    ----------
    rec : Recording
        The recording (up to its ``t_end``).
    t_from : float, optional
        Start of the window reported, s of line time (``analyze --from``): every event
        recorded is judged (a cycle needs those before it), and the constraints decided,
        the events, cycles and sheets counted from ``t_from`` on are reported.
    """
    scene = rec.scene
    drive = make_drive(scene, rec.commands)
    timing = plan = None
    constraints: list[ConstraintSeries] = []
    signatures = np.zeros(0, dtype=np.int64)
    if scene.has_folder:
        timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
        plan = delivery_plan(scene, timing)
        fe = folder_evaluation(rec.events, timing, scene, drive, plan=plan)
        constraints += fe.constraints
        signatures = fe.signatures
    if scene.has_layup:
        constraints += evaluate_layup_constraints(rec.events, scene)
    events = rec.events
    if t_from > 0.0:
        events = events[events['t'] >= t_from]
        constraints = [
            dataclasses.replace(c, cycle=c.cycle[m], margin=c.margin[m], t=c.t[m])
            for c in constraints
            for m in [c.t >= t_from]
        ]

    def count(kind: str) -> int:
        return int(np.count_nonzero(events['kind'] == event_kind(kind)))

    if scene.has_folder:
        cycles = count('knife_contact')
        sheets = count('released_on_pile') if plan is not None else int(signatures.sum())
    else:
        lp = scene.machine('layup')

        def turns(t: float) -> int:
            return math.floor(float(np.asarray(drive.theta(np.asarray(t)), dtype=float)) * (lp.n_kr / 60.0))

        cycles = turns(rec.t_end) - (turns(t_from) if t_from > 0.0 else 0)
        sheets = count('leaf_landed')
    n_viol = sum(int(np.count_nonzero(c.violated)) for c in constraints)
    summary = LineResult(
        scene=scene,
        duration=max(rec.t_end - t_from, 1e-9),
        events=events,
        samples={},
        constraints=constraints,
        parts={},
    ).summary(max_violations=max(n_viol, 1))
    summary['cycles'] = cycles
    summary['sheets_counted'] = sheets
    return Evaluation(drive, timing, plan, constraints, signatures, cycles, sheets, summary)


def recorded_transitions(states: Sequence[tuple[int, str]]) -> list[dict[str, Any]]:
    """The state changes of a ``/line/supervisor/state`` sequence.

    Returns
    -------
    list of dict
        ``{'t': log time of the first message in the new state (s), 'from': ..., 'to': ...}``;
        the first state is reported as a change from ``''``.
    """
    out: list[dict[str, Any]] = []
    prev = ''
    for t_ns, state in states:
        if state != prev:
            out.append({'t': t_ns / NS_PER_S, 'from': prev, 'to': state})
            prev = state
    return out


#: the live supervisor node's parameters as ``folder-line run`` starts it (its defaults, and the
#: rate of :class:`folder_line.ros.run.RunConfig`); a bag's custom data ``folder_line.supervisor``
#: (JSON) overrides them. test/test_analysis.py keeps them equal to the node's.
SUPERVISOR_DEFAULTS: dict[str, Any] = {'rate': 200.0, 'command_lead': 0.1, 'enforce': True, 'double_sheet': 'hold'}
#: custom data key of the supervisor's parameters in a bag
KEY_SUPERVISOR = 'folder_line.supervisor'


def supervisor_parameters(rec: Recording) -> dict[str, Any]:
    """The live supervisor's parameters: :data:`SUPERVISOR_DEFAULTS`, updated from the bag if it has them."""
    params = dict(SUPERVISOR_DEFAULTS)
    text = rec.bag.custom.get(KEY_SUPERVISOR)
    if text:
        try:
            stored = json.loads(text)
        except ValueError:
            stored = None
        if isinstance(stored, dict):
            params.update({k: v for k, v in stored.items() if k in params})
    return params


def replay_transitions(rec: Recording, params: Mapping[str, Any] | None = None) -> tuple[list[dict[str, Any]], Any]:
    """Replay the recorded inputs through :func:`folder_line.core.supervision.offline.replay`.

    The live supervisor node runs in lockstep: at every tick it is fed the events up to
    that tick (all of them: it waits until every machine node's tick is complete), the
    NaN/inf values found and the operator's commands, and decides exactly at the tick.
    All of these are in the bag (the operator's commands, lost participants and the
    first watermark in the supervisor's ``/diagnostics`` statuses). Its parameters:
    :func:`supervisor_parameters`, updated from ``params``.

    Returns
    -------
    (list of dict, Supervisor)
        The transitions ``{'t', 'from', 'to', 'cause'}`` (decision time, s) and the
        replayed supervisor (its ``violations``, ``commands``, ``balances``).
    """
    p = supervisor_parameters(rec)
    p.update(params or {})
    scene = rec.scene
    horizon = rec.horizon
    period = 1.0 / float(p['rate'])
    base = LineModel(scene, horizon)
    cache: dict[tuple[LineCommand, ...], Any] = {(): base}

    def model_factory(commands: tuple[LineCommand, ...]) -> Any:
        if commands not in cache:
            cache[commands] = LineModel(scene, horizon, commands)
        return cache[commands]

    starts = [float(v['t_start']) for _, _, v in rec.supervisor_status if 't_start' in v]
    if starts:
        t_start = starts[0]
    elif rec.diagnostics_ns.size:  # the first tick published the first /diagnostics, stamped with its time
        t_start = int(rec.diagnostics_ns.min()) / NS_PER_S  # the first watermark
    else:
        t_start = 0.0
    operator = [
        (float(v['t']), v['command'])
        for _, name, v in rec.supervisor_status
        if name.endswith('/operator') and 't' in v and 'command' in v
    ]
    tunings = accepted_tunings((name, v) for _, name, v in rec.supervisor_status)
    lost = [
        (float(v['t']), str(v['constraint']).split(':', 1)[1], -float(v['margin']))
        for _, name, v in rec.supervisor_status
        if name.endswith('/violation') and str(v.get('constraint', '')).startswith('lost:')
    ]
    kwargs: dict[str, Any] = {
        'periods': {},
        'lead': float(p['command_lead']),
        'check_period': period,
        'enforce': bool(p['enforce']),
        'double': str(p['double_sheet']),
        'state': 'STARTING',
        't_start': t_start,
        'model_factory': model_factory,
    }
    sup = replay(
        scene,
        horizon,
        rec.events,
        bad_values=rec.bad_values,
        operator=operator,
        lost=lost,
        tunings=tunings,
        until=max(rec.t_end, t_start),
        **kwargs,
    )
    out = [
        {'t': float(tr.t), 'from': tr.source, 'to': tr.target, 'cause': getattr(tr, 'cause', '')}
        for tr in sup.transitions
    ]
    return out, sup


def transitions_agree(
    replayed: Sequence[Mapping[str, Any]], recorded: Sequence[Mapping[str, Any]], initial: str = 'STARTING'
) -> bool:
    """Whether the recorded state sequence is the replayed one, as the state topic can show it.

    The supervisor publishes its state once per tick: states it passes through within
    one tick do not appear on the topic. So the recorded sequence of states must be
    the replayed one (``initial`` then each transition's target) with at most such
    states left out, ending in the same state; and each state shown must have been
    decided no later than it is shown, each showing paired with its own transition (a
    state the line enters twice, EXECUTE after an unhold, is two transitions).
    """
    full = [initial] + [str(t['to']) for t in replayed]
    decided = [-math.inf] + [float(t['t']) for t in replayed]
    seen = [str(t['to']) for t in recorded]
    if not seen:
        return not replayed
    if seen[-1] != full[-1]:
        return False
    i = 0
    for shown in recorded:  # a subsequence of full, each shown no earlier than it was decided
        state = str(shown['to'])
        while i < len(full) and full[i] != state:
            i += 1
        if i == len(full) or decided[i] > float(shown['t']):
            return False
        i += 1
    return True
