"""Study ``linkage``: the layup six-bar's chute angles and rates -- closed form, Newton, finite differences.

What is measured
----------------
The L six-bar of ``config/layup.yaml`` (crank-rocker O1-A-B-O2 driving the double rocker
O2-C-E-O3, docs/machines.md, "Default parameters"), crank at its nominal speed ``ω = params.omega``
(π rad/s: one turn per ``PERIOD`` = 2 s). The outputs are the chute angles θ3 (O2C) and
θ5 (O3E) and their rates ω3, ω5 (the joint outputs of :class:`~folder_line.core.mechanisms.layup_state.LayupPoint`).

Convention of a simulated second: the line publishes the linkage at ``RATE`` = 1000 Hz,
so one simulated second is 1000 evaluations at crank angles ``φ_k = ω k / RATE``; one
crank turn is ``N_STEPS = RATE · PERIOD`` = 2000 of them. Every method is charged the
CPU time (``time.process_time``, :func:`~folder_line.accuracy.measure.cpu_per_call`) of
producing those 1000 outputs:

``closed form``         :meth:`LayupModel.arrays` (``accelerations=False``), knob ``batch``:
                        angles per call (1 … 65536); cost = CPU per call / batch · RATE.
                        Shows what vectorising buys (and what very large arrays cost).
``closed form, scalar`` :meth:`LayupModel.point` (pure ``math``, the per-tick path), called
                        ``batch`` times in a Python loop; a flat curve: the scalar path
                        gains nothing from batching, but beats ``arrays`` at batch 1.
``Newton loop closure`` our own Newton–Raphson on the four loop-closure equations (unknown
                        link angles θ2, θ3, θ4, θ5; block-triangular Jacobian, two 2×2
                        Cramer solves per iteration), pure ``math``, stepping through a
                        crank turn at ``RATE``: each step starts from the previous step's
                        solution and stops as soon as the largest residual is ≤ ``tol``
                        (knob ``tol``, m; 0 iterations if it already is). The stepping is
                        sequential by nature (each start is the previous result), so it is
                        a scalar loop, like a node's tick, not a vectorised one. Cost = CPU
                        of one turn / ``PERIOD``. The first step starts from the closed form
                        one step before ``φ = 0``.
``closed form velocity``  ω3, ω5 of the same ``arrays`` calls as ``closed form`` (the
                        differentiated loop equations, a closed 2×2 solve), knob ``batch``;
                        the same CPU times (positions and rates come from one call).
``finite difference velocity``  central differences ``ω (θ(φ+h) - θ(φ-h)) / (2h)`` of the
                        closed-form positions (``arrays`` on the 2 · 4096 shifted angles),
                        knob ``h`` (rad of crank), 1e-1 … 1e-9: truncation ``O(h²)`` on
                        the large side, round-off ``~ε/h`` on the small one, best near 1e-5.
                        Cost = CPU of a 4096-angle evaluation / 4096 · RATE.

Reference and how it is checked
-------------------------------
:func:`folder_line.accuracy.reference.sixbar_reference`: Newton's method on the loop
closures in mpmath at 50 digits from a law-of-cosines start, rates from the
differentiated loop equations in mpmath. ``test/accuracy/test_linkage.py`` checks the
loop residuals (< 1e-30 m), the assembly branches, the agreement with the core's closed
form (1e-13 rad) and the rates against an mpmath central difference of the reference's
own positions.

Error and units
---------------
``error`` is the largest absolute error over one crank turn, at the ``N_REF`` = 400
crank angles ``φ_k`` with ``k`` a multiple of ``STRIDE`` = 5 (every 5 ms; the swing
extremes are within 0.008 rad of crank of a sample), of both chutes together:
``max(|θ3 - θ3_ref|, |θ5 - θ5_ref|)`` in rad for positions, ``max(|ω3 - …|, |ω5 - …|)``
in rad/s for rates. ``cpu_s_per_sim_s`` is CPU seconds per simulated second as above.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from folder_line.accuracy.measure import Row, cpu_budget, cpu_per_call
from folder_line.accuracy.reference import ReferenceArrays, sixbar_reference
from folder_line.config.params import load_params
from folder_line.core.mechanisms.layup import LayupModel, LayupParams
from folder_line.errors import AssemblyError

__all__ = [
    'METHODS',
    'RATE',
    'REFERENCE',
    'STRIDE',
    'STUDY',
    'ClosedFormErrors',
    'closed_form_errors',
    'default_params',
    'fd_error',
    'fd_velocities',
    'knob_settings',
    'newton_error',
    'newton_turn',
    'reference',
    'run',
    'step_angles',
]

STUDY = 'linkage'
#: evaluations (crank angles) per simulated second
RATE = 1000.0
#: the error is taken at every STRIDE-th step of a turn
STRIDE = 5
#: angles per call of the finite-difference evaluation (and its timing)
FD_BATCH = 4096
#: cap on Newton iterations per step (never reached from a warm start)
NEWTON_MAX_ITER = 50

POSITION = ('chute angles θ3, θ5', 'rad')
VELOCITY = ('chute rates ω3, ω5', 'rad/s')
REFERENCE = 'mpmath 50-digit loop closure (residual < 1e-30 m; checked in test/accuracy/test_linkage.py)'

METHODS = (
    'closed form',
    'closed form, scalar',
    'Newton loop closure',
    'closed form velocity',
    'finite difference velocity',
)

_SETTINGS: dict[tuple[str, bool], tuple[float, ...]] = {
    ('closed form', False): (1, 16, 64, 256, 1024, 4096, 16384, 65536),
    ('closed form', True): (1, 64, 4096, 65536),
    ('closed form, scalar', False): (1, 16, 256, 4096),
    ('closed form, scalar', True): (1, 64, 4096),
    ('Newton loop closure', False): tuple(10.0**-k for k in range(3, 13)),
    ('Newton loop closure', True): (1e-3, 1e-6, 1e-9, 1e-12),
    ('finite difference velocity', False): tuple(10.0 ** (-k / 2) for k in range(2, 19)),
    ('finite difference velocity', True): (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-7, 1e-9),
}
_SETTINGS[('closed form velocity', False)] = _SETTINGS[('closed form', False)]
_SETTINGS[('closed form velocity', True)] = _SETTINGS[('closed form', True)]
_KNOB = {
    'closed form': 'batch',
    'closed form, scalar': 'batch',
    'Newton loop closure': 'tol',
    'closed form velocity': 'batch',
    'finite difference velocity': 'h',
}


def knob_settings(method: str, quick: bool = False) -> tuple[str, tuple[float, ...]]:
    """Knob name and settings of a method.

    Parameters
    ----------
    method : str
        One of :data:`METHODS`.
    quick : bool
        The reduced settings of ``--quick``.

    Returns
    -------
    (str, tuple of float)
        ``batch`` (angles per call), ``tol`` (m, largest loop residual) or ``h`` (rad of crank).
    """
    return _KNOB[method], _SETTINGS[(method, quick)]


def default_params() -> LayupParams:
    """The layup of ``config/layup.yaml``."""
    return load_params('layup')


def step_angles(params: LayupParams) -> np.ndarray:
    """Crank angles of one turn stepped at :data:`RATE`: ``φ_k = ω k / RATE``, rad.

    Parameters
    ----------
    params : LayupParams

    Returns
    -------
    ndarray
        ``N_STEPS = round(RATE · 2π/ω)`` angles (2000 for the defaults), in [0, 2π).
    """
    n = round(RATE * 2.0 * math.pi / params.omega)
    return params.omega * (np.arange(n) / RATE)


def reference(params: LayupParams) -> ReferenceArrays:
    """The mpmath reference at every :data:`STRIDE`-th step angle (cached).

    Parameters
    ----------
    params : LayupParams

    Returns
    -------
    ReferenceArrays
        θ3, θ5 (rad) and ω3, ω5 (rad/s) at ``step_angles(params)[::STRIDE]``.
    """
    return sixbar_reference(params, step_angles(params)[::STRIDE])


def _wrap(d: np.ndarray) -> np.ndarray:
    """Angle differences reduced to [-π, π), rad."""
    return np.remainder(d + math.pi, 2.0 * math.pi) - math.pi


def _pos_error(t3: np.ndarray, t5: np.ndarray, ref: ReferenceArrays, reps: int = 1) -> float:
    r3, r5 = np.tile(ref.theta3, reps)[: t3.size], np.tile(ref.theta5, reps)[: t5.size]
    return float(max(np.abs(_wrap(t3 - r3)).max(), np.abs(_wrap(t5 - r5)).max()))


def _vel_error(w3: np.ndarray, w5: np.ndarray, ref: ReferenceArrays, reps: int = 1) -> float:
    r3, r5 = np.tile(ref.omega3, reps)[: w3.size], np.tile(ref.omega5, reps)[: w5.size]
    return float(max(np.abs(w3 - r3).max(), np.abs(w5 - r5).max()))


@dataclass(frozen=True)
class ClosedFormErrors:
    """Errors of the closed form at one batch size.

    Attributes
    ----------
    position : float
        Largest chute-angle error, rad.
    velocity : float
        Largest chute-rate error, rad/s.
    """

    position: float
    velocity: float


def _batched_angles(phi: np.ndarray, batch: int) -> tuple[np.ndarray, int]:
    """``phi`` tiled to a whole number of calls of ``batch`` (at least one copy), and the copies begun."""
    n = -(-max(batch, phi.size) // batch) * batch
    reps = -(-n // phi.size)
    return np.tile(phi, reps)[:n], reps


def closed_form_errors(model: LayupModel, ref: ReferenceArrays, batch: int) -> ClosedFormErrors:
    """Errors of :meth:`LayupModel.arrays` called on ``batch`` angles at a time.

    The reference angles are tiled to a whole number of calls, so every output is
    checked (for ``batch`` larger than the reference grid, repeated copies).

    Parameters
    ----------
    model : LayupModel
    ref : ReferenceArrays
        From :func:`reference`.
    batch : int
        Angles per call.

    Returns
    -------
    ClosedFormErrors
        rad and rad/s.
    """
    phi, reps = _batched_angles(ref.phi, batch)
    out = [model.arrays(phi[i : i + batch], accelerations=False) for i in range(0, phi.size, batch)]
    t3, t5, w3, w5 = (np.concatenate([getattr(s, k) for s in out]) for k in ('theta3', 'theta5', 'omega3', 'omega5'))
    return ClosedFormErrors(_pos_error(t3, t5, ref, reps), _vel_error(w3, w5, ref, reps))


def _scalar_errors(model: LayupModel, ref: ReferenceArrays) -> ClosedFormErrors:
    pts = [model.point(x) for x in ref.phi.tolist()]
    t3 = np.array([p.theta3 for p in pts])
    t5 = np.array([p.theta5 for p in pts])
    w3 = np.array([p.omega3 for p in pts])
    w5 = np.array([p.omega5 for p in pts])
    return ClosedFormErrors(_pos_error(t3, t5, ref), _vel_error(w3, w5, ref))


def newton_turn(params: LayupParams, tol: float, phi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Step Newton–Raphson on the loop closures through the crank angles ``phi``.

    Unknowns θ2 (rod A→B), θ3 (O2→B, chute 3), θ4 (coupler C→E), θ5 (O3→E, chute 4);
    equations ``O1 + R e(φ) + l2 e(θ2) - O2B e(θ3) = 0`` and
    ``l3 e(θ3) + l4 e(θ4) - O3 - l5 e(θ5) = 0``. Each step starts from the previous
    step's solution (the first from the closed form one :data:`RATE` step before
    ``phi[0]``) and iterates full Newton steps until ``max |residual| <= tol``.

    Parameters
    ----------
    params : LayupParams
    tol : float
        Largest loop residual accepted, m (> 0).
    phi : ndarray, optional
        Crank angles in stepping order, rad; default :func:`step_angles`.

    Returns
    -------
    theta3, theta5 : ndarray
        Chute angles at ``phi``, rad (continuous, not wrapped).
    iterations : int
        Newton iterations over all steps.

    Raises
    ------
    AssemblyError
        No convergence within :data:`NEWTON_MAX_ITER` iterations at a step.
    """
    if phi is None:
        phi = step_angles(params)
    p = params
    R, a, b, l2, q, l3, l4, l5, d0 = p.R_kr, p.a, p.b, p.l2, p.O2B, p.l3, p.l4, p.l5, p.O2O3
    model = LayupModel(p)
    st = model.arrays(np.array([phi[0] - p.omega / RATE]), accelerations=False)
    t3 = float(st.theta3[0])
    t5 = float(st.theta5[0])
    t2 = math.atan2(float(st.yB[0] - st.yA[0]), float(st.xB[0] - st.xA[0]))
    t4 = math.atan2(float(st.yE[0] - st.yC[0]), float(st.xE[0] - st.xC[0]))
    cos, sin = math.cos, math.sin
    out3 = np.empty(len(phi))
    out5 = np.empty(len(phi))
    iters = 0
    for k, ph in enumerate(phi.tolist()):
        ax = a + R * cos(ph)
        ay = b + R * sin(ph)
        for it in range(NEWTON_MAX_ITER + 1):
            c2, s2, c3, s3, c4, s4, c5, s5 = cos(t2), sin(t2), cos(t3), sin(t3), cos(t4), sin(t4), cos(t5), sin(t5)
            f1 = ax + l2 * c2 - q * c3
            f2 = ay + l2 * s2 - q * s3
            g1 = l3 * c3 + l4 * c4 - d0 - l5 * c5
            g2 = l3 * s3 + l4 * s4 - l5 * s5
            if max(abs(f1), abs(f2), abs(g1), abs(g2)) <= tol:
                break
            if it == NEWTON_MAX_ITER:
                raise AssemblyError('Newton loop closure', ph, f'no convergence to {tol:g} m in {it} iterations')
            # loop 1: [[-l2 s2, q s3], [l2 c2, -q c3]] [d2, d3] = -[f1, f2]
            det = (l2 * s2) * (q * c3) - (q * s3) * (l2 * c2)
            d2 = (f1 * q * c3 + q * s3 * f2) / det
            d3 = (-l2 * s2 * -f2 + f1 * l2 * c2) / det
            # loop 2: [[-l4 s4, l5 s5], [l4 c4, -l5 c5]] [d4, d5] = -[g1, g2] - l3 d3 [-s3, c3]
            r1 = -g1 + l3 * d3 * s3
            r2 = -g2 - l3 * d3 * c3
            det2 = (l4 * s4) * (l5 * c5) - (l5 * s5) * (l4 * c4)
            d4 = (r1 * -l5 * c5 - l5 * s5 * r2) / det2
            d5 = (-l4 * s4 * r2 - r1 * l4 * c4) / det2
            t2 += d2
            t3 += d3
            t4 += d4
            t5 += d5
            iters += 1
        out3[k] = t3
        out5[k] = t5
    return out3, out5, iters


def newton_error(params: LayupParams, tol: float) -> float:
    """Largest chute-angle error of :func:`newton_turn` over one turn, rad.

    Parameters
    ----------
    params : LayupParams
    tol : float
        Residual tolerance, m.

    Returns
    -------
    float
        ``max |θ - θ_ref|`` over θ3, θ5 at every :data:`STRIDE`-th step, rad.
    """
    t3, t5, _ = newton_turn(params, tol)
    return _pos_error(t3[::STRIDE], t5[::STRIDE], reference(params))


def fd_velocities(model: LayupModel, phi: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference chute rates from closed-form positions, rad/s.

    Parameters
    ----------
    model : LayupModel
    phi : ndarray
        Crank angles, rad.
    h : float
        Crank-angle step, rad (> 0).

    Returns
    -------
    omega3, omega5 : ndarray
        ``ω (θ(φ + h) - θ(φ - h)) / (2h)`` (differences wrapped to [-π, π)), ``ω = params.omega``.
    """
    n = phi.size
    st = model.arrays(np.concatenate([phi + h, phi - h]), accelerations=False)
    k = model.params.omega / (2.0 * h)
    return (_wrap(st.theta3[:n] - st.theta3[n:]) * k, _wrap(st.theta5[:n] - st.theta5[n:]) * k)


def fd_error(model: LayupModel, ref: ReferenceArrays, h: float) -> float:
    """Largest chute-rate error of :func:`fd_velocities` at the reference angles, rad/s.

    Parameters
    ----------
    model : LayupModel
    ref : ReferenceArrays
    h : float
        Crank-angle step, rad.

    Returns
    -------
    float
    """
    w3, w5 = fd_velocities(model, ref.phi, h)
    return _vel_error(w3, w5, ref)


@dataclass(frozen=True, eq=False)
class _Setup:
    """What every method of :func:`run` is measured on: the six-bar, its reference, one turn of crank
    angles (``period`` s of line at :data:`RATE`) and the timing batches."""

    params: LayupParams
    model: LayupModel
    ref: ReferenceArrays
    phi_turn: np.ndarray
    period: float
    quick: bool
    min_s: float
    repeats: int

    def cpu(self, call: Callable[[], object]) -> float:
        """CPU s per call of ``call`` (:func:`~folder_line.accuracy.measure.cpu_per_call`)."""
        return cpu_per_call(call, min_s=self.min_s, repeats=self.repeats)


def _row(method: str, value: float, error: float, cpu: float, kind: tuple[str, str]) -> Row:
    """A row of the study: ``kind`` is the quantity and its unit (:data:`POSITION`, :data:`VELOCITY`)."""
    return Row(STUDY, method, _KNOB[method], float(value), error, cpu, kind[0], kind[1], REFERENCE)


def _closed_form_rows(su: _Setup) -> list[Row]:
    """The vectorised closed form, positions and rates, per batch size."""
    rows: list[Row] = []
    for batch in knob_settings('closed form', su.quick)[1]:
        nb = int(batch)
        chunk = np.resize(su.phi_turn, nb)

        def batch_call(c: np.ndarray = chunk) -> object:
            return su.model.arrays(c, accelerations=False)

        cpu = su.cpu(batch_call)
        err = closed_form_errors(su.model, su.ref, nb)
        rows.append(_row('closed form', nb, err.position, cpu / nb * RATE, POSITION))
        rows.append(_row('closed form velocity', nb, err.velocity, cpu / nb * RATE, VELOCITY))
    return rows


def _scalar_rows(su: _Setup) -> list[Row]:
    """The closed form called angle by angle, per batch size."""
    rows: list[Row] = []
    scalar_err = _scalar_errors(su.model, su.ref)
    point = su.model.point
    for batch in knob_settings('closed form, scalar', su.quick)[1]:
        nb = int(batch)
        chunk_list = np.resize(su.phi_turn, nb).tolist()

        def scalar_call(xs: list[float] = chunk_list) -> None:
            for x in xs:
                point(x)

        cpu = su.cpu(scalar_call)
        rows.append(_row('closed form, scalar', nb, scalar_err.position, cpu / nb * RATE, POSITION))
    return rows


def _newton_rows(su: _Setup) -> list[Row]:
    """Newton's loop closure over a turn, per residual tolerance."""
    rows: list[Row] = []
    for tol in knob_settings('Newton loop closure', su.quick)[1]:

        def newton_call(x: float = tol) -> object:
            return newton_turn(su.params, x, su.phi_turn)

        cpu = su.cpu(newton_call)
        rows.append(_row('Newton loop closure', tol, newton_error(su.params, tol), cpu / su.period, POSITION))
    return rows


def _fd_rows(su: _Setup) -> list[Row]:
    """Central differences of the closed-form positions, per crank-angle step."""
    rows: list[Row] = []
    fd_phi = np.resize(su.phi_turn, FD_BATCH)
    for h in knob_settings('finite difference velocity', su.quick)[1]:

        def fd_call(x: float = h) -> object:
            return fd_velocities(su.model, fd_phi, x)

        cpu = su.cpu(fd_call)
        rows.append(
            _row('finite difference velocity', h, fd_error(su.model, su.ref, h), cpu / FD_BATCH * RATE, VELOCITY)
        )
    return rows


def run(quick: bool = False) -> list[Row]:
    """Measure every method at every knob setting.

    Parameters
    ----------
    quick : bool
        Fewer settings and shorter timings (``--quick``).

    Returns
    -------
    list of Row
        Study ``linkage``; positions in rad, rates in rad/s, CPU s per simulated s
        at :data:`RATE` evaluations per simulated second.
    """
    params = default_params()
    model = LayupModel(params)
    ref = reference(params)
    phi_turn = step_angles(params)
    period = phi_turn.size / RATE
    min_s, repeats = cpu_budget(quick)
    su = _Setup(params, model, ref, phi_turn, period, quick, min_s, repeats)
    return [*_closed_form_rows(su), *_scalar_rows(su), *_newton_rows(su), *_fd_rows(su)]


if __name__ == '__main__':  # pragma: no cover - a developer's look at the numbers
    import time

    t0 = time.process_time()
    for r in run(quick='--quick' in sys.argv):
        print(f'{r.method:28s} {r.knob:6s} {r.value:10.3g} {r.error:10.3g} {r.unit:6s} {r.cpu_s_per_sim_s:10.3g}')
    print(f'CPU {time.process_time() - t0:.2f} s')
