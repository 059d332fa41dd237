"""The delivery's derived figures, once per scene: :class:`DeliveryPlan`, :func:`delivery_plan`.

What the folder simulation (:mod:`folder_line.core.line.folder_sim`) and the constraints
(:mod:`folder_line.core.line.constraints`) need of the delivery D: the chain's path and
schedule (:mod:`folder_line.core.mechanisms.chain`), and where on the stroke the carriage
releases the sheet (where it is slowest, :func:`folder_line.core.mechanisms.delivery.stroke_minimum`).
Both modules import it from here, so neither imports the other for it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.line.scene import Scene
from folder_line.core.mechanisms import chain
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms.chain import ChainPath, ChainSchedule
from folder_line.core.mechanisms.cyclogram import CycleTiming
from folder_line.core.types.machines import ChainParams

__all__ = ['DeliveryPlan', 'delivery_plan']


@dataclass(frozen=True, eq=False)
class DeliveryPlan:
    """What the folder simulation needs of the delivery (derived once per scene).

    Attributes
    ----------
    params : DeliveryParams
        The transporter.
    chain : ChainParams
        Chain geometry.
    path : ChainPath
        Arc length along the guide (:mod:`folder_line.core.mechanisms.chain`).
    schedule : ChainSchedule
        Where the carriages are; carriage k takes sheet k at ``schedule.pickup_phase(k)``.
    rod : float
        Rod length ``l``, m.
    u_rel : float
        Stroke position of the slowest carriage, where the sheet is released.
    K_v_rel : float
        ``K_v`` there (the stroke's minimum).
    s_rel : float
        Chain travel from the stroke start to ``u_rel``, m.
    travel_rel : float
        ``L_transfer + s_rel``: chain travel from the take-over at the folding
        rollers to the release, m.
    """

    params: dlv.DeliveryParams
    chain: ChainParams
    path: ChainPath
    schedule: ChainSchedule
    rod: float
    u_rel: float
    K_v_rel: float
    s_rel: float
    travel_rel: float

    @property
    def v_A(self) -> float:
        """Chain speed per unit master phase, ``pitch / T``, m/s at nominal speed."""
        return self.schedule.v_A

    def release_phase(self, cycle: npt.ArrayLike) -> np.ndarray:
        """Master phase Θ at which carriage ``cycle`` releases sheet ``cycle`` on the pile, nominal s."""
        return self.schedule.phase_of_travel(self.travel_rel, cycle)


def delivery_plan(scene: Scene, timing: CycleTiming) -> DeliveryPlan | None:
    """The delivery's derived figures, or None if the scene has no delivery.

    ``timing`` must be the scene's cycle timing: its ``T`` is the schedule's (checked).
    """
    if 'delivery' not in scene.machines:
        return None
    params = scene.machine('delivery')
    chain_p = scene.machine('delivery_chain')
    sch = chain.schedule(scene)
    if sch.T != timing.T or sch.theta_pick0 != timing.T + timing.knife.t_out:
        raise ValueError('delivery_plan: timing is not the cycle timing of this scene')
    path = chain.chain_path(scene)
    u_rel, kv_rel = dlv.stroke_minimum(params, 'K_v', return_section='geometric')
    s_rel = float(path.arc(u_rel))
    return DeliveryPlan(
        params=params,
        chain=chain_p,
        path=path,
        schedule=sch,
        rod=params.rod_length(chain_p.x_max),
        u_rel=float(u_rel),
        K_v_rel=float(kv_rel),
        s_rel=s_rel,
        travel_rel=chain_p.L_transfer + s_rel,
    )
