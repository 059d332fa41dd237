"""The supervisor replayed on a recording's inputs, and its state transitions against the recorded ones.

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

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeAlias

from folder_line.analysis.recording import Recording
from folder_line.bag.statuses import accepted_tunings
from folder_line.core.supervision.offline import replay
from folder_line.core.supervision.supervisor import Supervisor
from folder_line.files.json_types import JsonObject
from folder_line.interfaces import NS_PER_S

__all__ = [
    'KEY_SUPERVISOR',
    'SUPERVISOR_DEFAULTS',
    'StateTransition',
    'SupervisorValue',
    'recorded_transitions',
    'replay_transitions',
    'supervisor_parameters',
    'transitions_agree',
]


@dataclass(frozen=True)
class StateTransition:
    """A change of the supervisor's state, recorded or replayed.

    Attributes
    ----------
    t : float
        s: a recorded one's log time of the first message in the new state, a replayed one's
        decision time.
    source : str
        The state left (``''``: the first state recorded).
    target : str
        The state entered.
    cause : str or None
        Why (a replayed one's); None for a recorded one (the state topic gives no cause).
    """

    t: float
    source: str
    target: str
    cause: str | None = None

    def as_json(self) -> JsonObject:
        """``{'t', 'from', 'to'}``, and ``'cause'`` if it has one."""
        out: JsonObject = {'t': self.t, 'from': self.source, 'to': self.target}
        if self.cause is not None:
            out['cause'] = self.cause
        return out


def recorded_transitions(states: Sequence[tuple[int, str]]) -> list[StateTransition]:
    """The state changes of a ``/line/supervisor/state`` sequence.

    Returns
    -------
    list of StateTransition
        Without causes; the first state is reported as a change from ``''``.
    """
    out: list[StateTransition] = []
    prev = ''
    for t_ns, state in states:
        if state != prev:
            out.append(StateTransition(t_ns / NS_PER_S, prev, state))
            prev = state
    return out


#: a value of the supervisor node's parameters (a rate, a lead, a switch, a policy)
SupervisorValue: TypeAlias = float | bool | str
#: the live supervisor node's parameters as ``folder-line run`` starts it (its defaults, and the
#: rate of :class:`folder_line.ros.run.RunConfig`); a bag's custom data ``folder_line.supervisor``
#: (JSON) overrides them. test/test_analysis.py keeps them equal to the node's.
SUPERVISOR_DEFAULTS: dict[str, SupervisorValue] = {
    'rate': 200.0,
    'command_lead': 0.1,
    'enforce': True,
    'double_sheet': 'hold',
}
#: custom data key of the supervisor's parameters in a bag
KEY_SUPERVISOR = 'folder_line.supervisor'


def supervisor_parameters(rec: Recording) -> dict[str, SupervisorValue]:
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


def replay_transitions(
    rec: Recording, params: Mapping[str, SupervisorValue] | None = None
) -> tuple[list[StateTransition], Supervisor]:
    """Replay the recorded inputs through :func:`folder_line.core.supervision.offline.replay`.

    The live supervisor node runs in lockstep: at every tick it is fed the events up to
    that tick (all of them: it waits until every machine node's tick is complete), the
    NaN/inf values found and the operator's commands, and decides exactly at the tick.
    All of these are in the bag (the operator's commands, lost participants and the
    first watermark in the supervisor's ``/diagnostics`` statuses). Its parameters:
    :func:`supervisor_parameters`, updated from ``params``. The logic needs no line model:
    it keeps the drive under the commands it issues.

    A bag with gaps (:mod:`folder_line.bag.gaps`) is replayed up to its first gap: what the
    supervisor decided after it depends on what it saw in it.

    Returns
    -------
    (list of StateTransition, Supervisor)
        The transitions (decision time, s; with their causes) and the replayed supervisor
        (its ``violations``, ``commands``, ``balances``).
    """
    p = supervisor_parameters(rec)
    p.update(params or {})
    period = 1.0 / float(p['rate'])
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
    events, until = rec.events, max(rec.t_end, t_start)
    if rec.gaps:  # what the supervisor did after a gap depends on what it saw in it: replayed up to the first
        until = min(until, max(rec.gaps[0].first_ns / NS_PER_S, t_start))
        events = events[rec.event_ns < rec.gaps[0].first_ns]
    sup = replay(
        rec.scene,
        events,
        bad_values=[b for b in rec.bad_values if b[0] <= until],
        operator=[o for o in operator if o[0] <= until],
        lost=[x for x in lost if x[0] <= until],
        tunings=[x for x in tunings if x[0] <= until],
        until=until,
        periods={},
        lead=float(p['command_lead']),
        check_period=period,
        enforce=bool(p['enforce']),
        double=str(p['double_sheet']),
        state='STARTING',
        t_start=t_start,
    )
    out = [StateTransition(float(tr.t), tr.source, tr.target, tr.cause) for tr in sup.transitions]
    return out, sup


def transitions_agree(
    replayed: Sequence[StateTransition], recorded: Sequence[StateTransition], initial: str = 'STARTING'
) -> bool:
    """Whether the recorded state sequence is the replayed one, as the state topic can show it.

    The supervisor publishes its state once per tick: states it passes through within
    one tick do not appear on the topic. So the recorded sequence of states must be
    the replayed one (``initial`` then each transition's target) with at most such
    states left out, ending in the same state; and each state shown must have been
    decided no later than it is shown, each showing paired with its own transition (a
    state the line enters twice, EXECUTE after an unhold, is two transitions).
    """
    full = [initial] + [t.target for t in replayed]
    decided = [-math.inf] + [t.t for t in replayed]
    seen = [t.target for t in recorded]
    if not seen:
        return not replayed
    if seen[-1] != full[-1]:
        return False
    i = 0
    for shown in recorded:  # a subsequence of full, each shown no earlier than it was decided
        state = shown.target
        while i < len(full) and full[i] != state:
            i += 1
        if i == len(full) or decided[i] > shown.t:
            return False
        i += 1
    return True
