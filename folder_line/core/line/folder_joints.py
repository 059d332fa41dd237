"""The folder's joint states: the knife drive, the first transporter, the feed belt, chain and carriage.

:meth:`folder_line.core.line.folder_stream.FolderStream.sample_unit` hands each unit to one of
these functions, at line times ``t`` (s) with the master phase Θ (nominal s) and its rate λ there.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from folder_line.core.effects import chain_friction
from folder_line.core.line.delivery_plan import DeliveryPlan
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.belt import BeltPhase
from folder_line.core.mechanisms.cyclogram import CycleTiming
from folder_line.core.mechanisms.delivery_results import DeliverySamples
from folder_line.core.types.events import JointSamples, stack_samples

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['belts_samples', 'drive_samples', 'feed_samples']

TWO_PI = 2.0 * math.pi


def drive_samples(
    timing: CycleTiming, kp: knf.KnifeParams, t: np.ndarray, theta: np.ndarray, lam: np.ndarray, with_torque: bool
) -> JointSamples:
    """Unit ``drive``: the knife crank angle (rad) and the knife's position (m), with their rates.

    ``with_torque``: efforts too (zeros), as the feed unit has them.
    """
    phi = np.mod(timing.omega_k * theta, TWO_PI)
    pos = knf.position(kp, phi)
    v = knf.velocity(kp, phi) * lam
    zeros = np.zeros(t.size)
    return stack_samples(
        'drive',
        ('knife_crank', 'knife'),
        t,
        [phi, pos],
        [timing.omega_k * lam, v],
        [zeros, zeros] if with_torque else None,
    )


def belts_samples(
    timing: CycleTiming, t: np.ndarray, theta: np.ndarray, lam: np.ndarray, with_torque: bool
) -> JointSamples:
    """Unit ``belts``: the first transporter's travel (m) and speed (m/s) at the printing speed ``V_d``."""
    return stack_samples(
        'belts',
        ('first_transporter',),
        t,
        [timing.V_d * theta],
        [timing.V_d * lam],
        [np.zeros(t.size)] if with_torque else None,
    )


def feed_samples(
    scene: Scene,
    plan: DeliveryPlan | None,
    V_tr: float,
    belt: BeltPhase,
    torque_params: chain_friction.Params | None,
    t: np.ndarray,
    theta: np.ndarray,
    lam: np.ndarray,
) -> JointSamples:
    """Unit ``feed``: the feed belt (m, m/s), and with a delivery its chain and the carriage on the stroke.

    With ``torque_params`` (``chain_friction`` and a delivery) the chain's effort is the sprocket
    torque, N m.
    """
    zeros = np.zeros(t.size)
    b = belt.at(t, theta)
    names = ['feed_belt']
    pos = [V_tr * b]
    vel = [V_tr * lam * belt.factor(t)]
    eff: list[np.ndarray] | None = [zeros] if torque_params is not None else None
    if plan is not None:
        chain_pos = plan.v_A * theta
        sch = plan.schedule
        a0, slack = sch.stroke_travel(theta)  # the carriage that entered the stroke last
        on = a0 <= sch.S + slack
        car_x = np.zeros(t.size)
        car_v = np.zeros(t.size)
        st = None
        u = None
        if on.any():
            u = plan.path.position(np.clip(a0[on], 0.0, sch.S))
            st = dlv.evaluate_stroke(plan.params, u, return_section='geometric')
            car_x[on] = u * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
            car_v[on] = st.K_v * plan.v_A * lam[on]
        names += ['chain', 'carriage']
        pos += [chain_pos, car_x]
        vel += [plan.v_A * lam, car_v]
        if eff is not None:
            assert torque_params is not None
            if t.size == 1:  # a node's tick: reuse the carriage's stroke evaluation
                torque = _sprocket_torque(torque_params, plan, a0, slack, on, st)
            else:
                torque = np.asarray(chain_friction.sprocket_torque(scene, theta), dtype=float)
            if torque.shape != t.shape or not np.all(np.isfinite(torque)):
                raise ValueError('chain_friction.sprocket_torque must return finite values shaped like Θ')
            eff += [torque, zeros]
    return stack_samples('feed', tuple(names), t, pos, vel, eff)


def _sprocket_torque(
    p: chain_friction.Params,
    plan: DeliveryPlan,
    a0: np.ndarray,
    slack: np.ndarray,
    on0: np.ndarray,
    st0: DeliverySamples | None,
) -> np.ndarray:
    """:func:`folder_line.core.effects.chain_friction.sprocket_torque` at the same Θ, bit for bit (the fast
    path of a node's tick: the carriage joint's stroke evaluation reused where it is the same), N m."""
    sch = plan.schedule
    total = np.zeros(a0.shape)
    for m in range(sch.max_on_stroke):  # carriages on the stroke at once
        a = a0 + m * sch.pitch
        on = (a >= -slack) & (a <= sch.S + slack)
        if np.any(on):
            if m == 0 and st0 is not None and p.return_section == 'geometric' and np.array_equal(on, on0):
                total[on] += st0.forces(p.P_k, p.r).M_1
            else:
                u = plan.path.position(np.clip(a[on], 0.0, sch.S))
                total[on] += chain_friction.stroke_state(p, plan.params, u).M_1
    return total
