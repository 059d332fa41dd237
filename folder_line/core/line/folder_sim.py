"""F with D over a span in one window: :class:`FolderLine` and :func:`simulate_folder`.

:class:`FolderLine` runs the streamed folder
(:class:`folder_line.core.line.folder_stream.FolderStream`) over ``[0, duration]`` in one
window and keeps what it handed out: the events, the per-cycle constraint margins
(:mod:`folder_line.core.line.constraints`), the summary, and the joint states at any time
of the span. Every event time is a closed form in the master phase Θ mapped through
``drive.time_of`` (or, with ``feed_slip``, a closed form in line time); nothing is read off
the sample grid.

Timeline (one cycle, master phase Θ in nominal seconds)
-------------------------------------------------------
The knife crank turns at ``φ_k = ω_k Θ`` (``φ_k = 0`` at Θ = 0, the window is
centred on it for ``e = 0``), period ``T = 2π/ω_k``; the knife occupies the table
for ``Θ mod T`` in ``[t_in, t_out]`` (``t_in < 0 < t_out``,
:func:`folder_line.core.mechanisms.knife.window`). **Cycle k starts at the knife exit**
``kT + t_out`` (the feed window opens) and ends at the next exit::

    Θ ─► kT + t_out                                     (k+1)T + t_in    (k+1)T + t_out
             │                                                 │                │
    knife ███│                                                 │████████████████│
             │◄─────────── feed window t_fw ───────►│◄ t_dwell ►│◄── t_knife ───►│
             │◄────── t_allowed ───────►│◄ reserve ►│           │                │
             ▲          ▲     ▲     ▲   ▲                       ▲                ▲
        handover  at_stops bounce settled deadline         knife_contact     knife_exit
        (+phase)                                          (sheet k folded)  (carriage k takes it;
                                                                              cycle k+1 starts)

* ``sheet_handover`` of sheet k at ``Θ_h = kT + t_out + phase`` (``sheets.phase``;
  a late fault adds its delay, in nominal s); a slot with ``Θ_h < 0`` (before the
  line starts) feeds nothing;
* ``at_stops`` after ``L_feed`` of feed-belt travel: without ``feed_slip`` the
  signature rides the belt from the hand-over, ``ΔΘ = L_feed / V_tr`` (the belt
  moves ``V_tr dΘ``; a belt slow-down of factor f over ``[t_s, t_e)`` makes it
  ``f V_tr dΘ`` there, integrated exactly by :class:`folder_line.core.mechanisms.belt.BeltPhase`);
  with ``feed_slip`` see :mod:`folder_line.core.effects.feed_slip`. Value: the impact
  speed;
* ``bounce`` (value: rebound distance) and ``settled`` with ``stop_bounce``
  (:mod:`folder_line.core.effects.stop_bounce`);
* ``knife_contact`` of cycle k at ``(k+1)T + t_in``, ``knife_exit`` at
  ``(k+1)T + t_out`` (one each per cycle, ``sheet = -1``). The signature(s) of
  cycle k that are at the stops by the knife contact are folded; one that arrives
  later is *jammed* (it stays in the machine; the constraints flag the cycle);
* with a delivery, carriage k takes the folded signature k at the knife exit,
  ``Θ_pick(k) = (k+1)T + t_out`` (the line's one numbering, :mod:`folder_line.core.mechanisms.chain`),
  and the chain (speed ``v_A = pitch / T`` per unit Θ) carries it
  ``L_transfer + s(u_rel)`` to the release point, ``released_on_pile`` at
  ``Θ = Θ_pick(k) + (L_transfer + s(u_rel)) / v_A``. ``u_rel`` is where the
  carriage is slowest (``delivery.stroke_minimum(..., 'K_v', return_section=
  'geometric')``), ``s(u)`` the chain's arc length along the curved guide
  (:class:`folder_line.core.mechanisms.chain.ChainPath`).

A drive that the supervisor holds (:mod:`folder_line.core.mechanisms.drive`, "Supervisor
commands") stops Θ: the hand-over slots, knife and chain events are at fixed Θ, so
the sheet stream stops with the line and every signature stays where it is until
Θ moves again. What runs in line time goes on regardless: the bounce off the stops
and the settling (``stop_bounce``), belt slow-downs of ``faults``. With ``feed_slip``
the slip phase freezes the speeds at the hand-over (``feed_slip`` docstring), an
approximation while λ ramps.

Only events at ``t <= duration`` are returned; sheets handed over but not yet
counted are *in the machine* (``sheets_fed = sheets_counted + sheets_in_machine``,
checked in the summary). Sheets are numbered 0, 1, ... in slot order as their slots
are drawn (a double fault feeds two with consecutive ids; a missing one takes no id).

Joint samples per unit (on ``t_samples``; λ = ``drive.rate``, f the belt slow-down factor)
------------------------------------------------------------------------------------------
* ``drive``: ``knife_crank`` (φ_k wrapped to [0, 2π), ω_k λ),
  ``knife`` (s(φ_k) m, v(φ_k) λ m/s);
* ``belts``: ``first_transporter`` (V_d Θ m, V_d λ m/s);
* ``feed`` (the feed transporter): ``feed_belt`` (its travel, V_tr λ f), and with a delivery
  ``chain`` (v_A Θ, v_A λ) and ``carriage``: the carriage on the stroke (the one
  that entered it last), its displacement from the stroke start
  ``u x_max + l (1 - cos α(u))`` (``= u x_max`` at both ends of the stroke; the
  rod's tilt makes the carriage lag or lead the pin: this keeps position and speed
  consistent) and speed ``K_v(u) v_A λ``; 0 and 0 while no carriage is on the
  stroke.
* efforts only with ``chain_friction``: the sprocket torque on ``chain`` (N m,
  :func:`folder_line.core.effects.chain_friction.sprocket_torque`), 0 on every
  other joint; without it ``effort`` is None.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from folder_line.core.line.folder_figures import FolderFigures
from folder_line.core.line.folder_stream import FolderStream
from folder_line.core.line.tuning import Tuning
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.types.events import ConstraintSeries, JointSamples, LinePart, SubResult

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['FolderLine', 'join_rows', 'simulate_folder']


def join_rows(
    rows: Iterable[ConstraintSeries], names: Iterable[str], empty: dict[str, ConstraintSeries]
) -> list[ConstraintSeries]:
    """The rows of several windows as one series per constraint, in the order of ``names``."""
    by: dict[str, list[ConstraintSeries]] = {}
    for r in rows:
        by.setdefault(r.name, []).append(r)
    out = []
    for name in names:
        parts = by.get(name) or [empty[name]]
        first = parts[0]
        out.append(
            ConstraintSeries(
                name,
                first.unit,
                np.concatenate([p.cycle for p in parts]).astype(np.int64),
                np.concatenate([p.margin for p in parts]),
                first.description,
                t=np.concatenate([p.t for p in parts]),
            )
        )
    return out


class FolderLine(LinePart[FolderFigures]):
    """The folder (and its delivery) on a drive over ``[0, duration]``, in one window, kept.

    Parameters
    ----------
    scene : Scene
        Must have ``knife``, ``cyclogram`` and ``feed_transporter``; ``delivery`` and
        ``delivery_chain`` optional; the listed effects run.
    drive : Drive
        Master drive.
    duration : float
        Line time, s (> 0).
    tunings : iterable of Tuning
        The operator's changes: here the feed transporter's speed ``feed_transporter.V_tr``.

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        Sorted by time, kind, sheet.
    constraints : list of ConstraintSeries
    summary : FolderFigures
    timing : CycleTiming
    plan : DeliveryPlan or None
    stream : FolderStream
        The stream that computed it (its belt, its signatures).
    units : dict of str to tuple of str
    """

    def __init__(self, scene: Scene, drive: Drive, duration: float, tunings: Iterable[Tuning] = ()) -> None:
        fs = FolderStream(scene, drive, tunings)
        duration = float(duration)
        fs.compute(duration)
        events, rows = fs.emit(duration)
        rows += fs.finish()
        self.scene = scene
        self.drive = drive
        self.duration = duration
        self.stream = fs
        self.timing = fs.timing
        self.V_tr = fs.V_tr
        self.plan = fs.plan
        self.knife = fs.knife
        self.belt = fs.belt
        self.events = events
        self.constraints = join_rows(rows, fs.constraint_names, fs.empty_rows)
        self.summary = fs.summary()
        self.units = fs.units

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one unit (``drive``, ``belts``, ``feed``) at ``t`` (s, in ``[0, duration]``)."""
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(tt, theta, lam)
        return self.stream.sample_unit(unit, tt, theta, lam)


def simulate_folder(scene: Scene, drive: Drive, duration: float, t_samples: np.ndarray) -> SubResult[FolderFigures]:
    """Simulate the folder (and its delivery) for ``duration`` seconds of line time.

    ``FolderLine(scene, drive, duration).result(t_samples)``: events, samples per unit on
    ``t_samples`` (s in ``[0, duration]``; may be empty), constraints, summary.
    """
    return FolderLine(scene, drive, duration).result(t_samples)
