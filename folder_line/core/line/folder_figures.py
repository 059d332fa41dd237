"""The folder's figures in a run's summary (:class:`FolderFigures`): counts, design figures, slack.

:meth:`folder_line.core.line.folder_stream.FolderStream.summary` makes them of the events handed
out, :func:`folder_line.core.line.folder_steps.static_summary` the part that does not depend on
the run. Each class's ``as_json()`` is its block of the ``simulate`` summary, keys in the order
written, a section of an effect the scene does not list left out.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = [
    'BounceFigures',
    'CycleTimes',
    'DeliveryFigures',
    'FaultCounts',
    'FolderFigures',
    'ReleaseFigures',
    'Slack',
    'SlipFigures',
]


@dataclass(frozen=True)
class CycleTimes:
    """The folder's machine cycle (``timing``), nominal s.

    Attributes
    ----------
    T : float
        The cycle.
    t_in, t_out : float
        The knife's contact and exit in the cycle.
    t_knife, t_dwell, t_fw, t_allowed : float
        The knife's table occupation, the dwell, the feed window and the feed time allowed.
    """

    T: float
    t_in: float
    t_out: float
    t_knife: float
    t_dwell: float
    t_fw: float
    t_allowed: float

    def as_json(self) -> dict[str, object]:
        """The ``timing`` block."""
        return asdict(self)


@dataclass(frozen=True)
class Slack:
    """What each part of the cycle leaves over at nominal speed, no faults (``slack``), s.

    Attributes
    ----------
    feed_margin_ideal : float
        The feed time allowed less the phase and the feed at belt speed.
    slip_cost : float or None
        The feed time the slip costs (``feed_slip``; None without it).
    feed_margin : float
        ``feed_margin_ideal`` less the slip cost.
    rest_at_stops : float
        Time at the stops before the knife.
    settle_time, settled_margin : float or None
        The bounce's settle time at ``V_tr`` and the rest left after it (``stop_bounce``; None without it).
    """

    feed_margin_ideal: float
    feed_margin: float
    rest_at_stops: float
    slip_cost: float | None = None
    settle_time: float | None = None
    settled_margin: float | None = None

    def as_json(self) -> dict[str, object]:
        """The ``slack`` block."""
        out: dict[str, object] = {'feed_margin_ideal': self.feed_margin_ideal}
        if self.slip_cost is not None:
            out['slip_cost'] = self.slip_cost
        out['feed_margin'] = self.feed_margin
        out['rest_at_stops'] = self.rest_at_stops
        if self.settle_time is not None:
            out['settle_time'] = self.settle_time
            out['settled_margin'] = self.settled_margin
        return out


@dataclass(frozen=True)
class SlipFigures:
    """``feed_slip``'s figures.

    Attributes
    ----------
    accel : float
        The signature's acceleration while it slips, m/s².
    slip_cost : float
        The feed time the slip costs, s.
    feed_margin_with_slip : float
        The feed time allowed less the feed and the slip cost, s.
    V_tr_min_with_slip : float or None
        The slowest belt that feeds in time with the slip, m/s (None: none does).
    """

    accel: float
    slip_cost: float
    feed_margin_with_slip: float
    V_tr_min_with_slip: float | None

    def as_json(self) -> dict[str, object]:
        """The ``feed_slip`` block."""
        return asdict(self)


@dataclass(frozen=True)
class BounceFigures:
    """``stop_bounce``'s figures: at the nominal belt speed, and the largest of the run.

    Attributes
    ----------
    bounces_at_V_tr : int
    settle_time_at_V_tr : float
        s.
    first_rebound_at_V_tr : float
        m.
    bounces_max : int
        The most bounces of a signature at the stops so far.
    settle_time_max : float
        The longest settle time so far, s.
    """

    bounces_at_V_tr: int
    settle_time_at_V_tr: float
    first_rebound_at_V_tr: float
    bounces_max: int
    settle_time_max: float

    def as_json(self) -> dict[str, object]:
        """The ``stop_bounce`` block."""
        return asdict(self)


@dataclass(frozen=True)
class ReleaseFigures:
    """The delivery's release of a signature on the pile (``release``).

    Attributes
    ----------
    u_rel : float
        Stroke position of the release.
    K_v : float
        Speed ratio there.
    chain_travel : float
        Chain travel to it, m.
    v_A : float
        Chain speed, m/s.
    carriage_speed : float
        ``K_v v_A``, m/s.
    """

    u_rel: float
    K_v: float
    chain_travel: float
    v_A: float
    carriage_speed: float

    def as_json(self) -> dict[str, object]:
        """The ``release`` block."""
        return asdict(self)


@dataclass(frozen=True)
class DeliveryFigures:
    """The delivery's efficiency minimum and sprocket torque with ``chain_friction`` (``delivery``).

    Attributes
    ----------
    eta_min : float
        The stroke's smallest efficiency.
    eta_min_u : float
        Stroke position u of it, in [0, 2].
    eta_min_travel_m : float
        Chain travel from the stroke start to it, m.
    sprocket_torque_peak_Nm, sprocket_torque_mean_Nm : float
        The sprocket torque over a cycle, N m.
    """

    eta_min: float
    eta_min_u: float
    eta_min_travel_m: float
    sprocket_torque_peak_Nm: float
    sprocket_torque_mean_Nm: float

    def as_json(self) -> dict[str, object]:
        """The ``delivery`` block."""
        return asdict(self)


@dataclass(frozen=True)
class FaultCounts:
    """``faults``' counts so far: missing, double and late signatures, belt slow-downs."""

    missing: int
    double: int
    late: int
    slowdowns: int

    def as_json(self) -> dict[str, object]:
        """The ``faults`` block."""
        return asdict(self)


@dataclass(frozen=True)
class FolderFigures:
    """The folder's figures (the summary's ``folder`` block).

    Attributes
    ----------
    cycles : int
        Knife contacts (cycles judged at the knife).
    cycles_started : int
    sheets_fed, sheets_at_stops, sheets_folded, sheets_jammed, sheets_counted, sheets_in_machine : int
    sheets_balance_ok : bool
        Fed = counted + in the machine.
    V_d, V_tr, V_tr_min : float
        Delivery speed, belt speed, slowest belt that feeds in time, m/s.
    v_tr_over_v_d, V_tr_min_over_V_d : float
    knife_window_s : float
        The knife's table occupation, s.
    knife_window_deg, knife_in_deg, knife_out_deg : float
        Its crank angles, deg.
    timing : CycleTimes
    slack : Slack
    feed_slip : SlipFigures or None
    stop_bounce : BounceFigures or None
    release : ReleaseFigures or None
        With a delivery.
    delivery : DeliveryFigures or None
        With a delivery and ``chain_friction``.
    faults : FaultCounts or None
    """

    cycles: int
    cycles_started: int
    sheets_fed: int
    sheets_at_stops: int
    sheets_folded: int
    sheets_jammed: int
    sheets_counted: int
    sheets_in_machine: int
    sheets_balance_ok: bool
    V_d: float
    V_tr: float
    v_tr_over_v_d: float
    V_tr_min: float
    V_tr_min_over_V_d: float
    knife_window_s: float
    knife_window_deg: float
    knife_in_deg: float
    knife_out_deg: float
    timing: CycleTimes
    slack: Slack
    feed_slip: SlipFigures | None = None
    stop_bounce: BounceFigures | None = None
    release: ReleaseFigures | None = None
    delivery: DeliveryFigures | None = None
    faults: FaultCounts | None = None

    def as_json(self) -> dict[str, object]:
        """The ``folder`` block."""
        out: dict[str, object] = {
            'cycles': self.cycles,
            'cycles_started': self.cycles_started,
            'sheets_fed': self.sheets_fed,
            'sheets_at_stops': self.sheets_at_stops,
            'sheets_folded': self.sheets_folded,
            'sheets_jammed': self.sheets_jammed,
            'sheets_counted': self.sheets_counted,
            'sheets_in_machine': self.sheets_in_machine,
            'sheets_balance_ok': self.sheets_balance_ok,
            'V_d': self.V_d,
            'V_tr': self.V_tr,
            'v_tr_over_v_d': self.v_tr_over_v_d,
            'V_tr_min': self.V_tr_min,
            'V_tr_min_over_V_d': self.V_tr_min_over_V_d,
            'knife_window_s': self.knife_window_s,
            'knife_window_deg': self.knife_window_deg,
            'knife_in_deg': self.knife_in_deg,
            'knife_out_deg': self.knife_out_deg,
            'timing': self.timing.as_json(),
            'slack': self.slack.as_json(),
        }
        sections = (
            ('feed_slip', self.feed_slip),
            ('stop_bounce', self.stop_bounce),
            ('release', self.release),
            ('delivery', self.delivery),
            ('faults', self.faults),
        )
        for key, section in sections:
            if section is not None:
                out[key] = section.as_json()
        return out
