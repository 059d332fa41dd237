"""Study ``motor``: the ``motor_dynamics`` ODE -- RK4 at h, DOPRI5 and ``solve_ivp`` at rtol.

What is measured
----------------
The master drive of the shipped ``line`` scene (``config/scenes/line.yaml``:
``J = 0.5`` kg m², ``T_0 = 197.9`` N m, ``omega_0 = 157.08`` rad/s, ``omega_nom = 152.4``
rad/s, ``b = 0.03`` N m s; time constant ``τ = J/(T_0/ω_0 + b) = 0.388`` s) spinning up
from standstill::

    dΘ/dt = ω / ω_nom,      J dω/dt = T_0 (1 - ω/ω_0) - b ω - T_load(Θ)

over ``DURATION = 2`` s (5.2 τ: the whole start-up, from the steepest acceleration to
within 0.6 % of the steady speed), in two cases, each a group of curves:

``start-up, no load``  the scene without ``chain_friction`` (``T_load = 0``)
``with chain load``    the scene as shipped, with ``chain_friction`` (the delivery's
                       sprocket torque, which jumps where a carriage enters or leaves the
                       stroke and has kinks inside it: 4 breaks per 0.072 nominal s)

Methods (one curve each, per case; the case is part of the method name):

``RK4 (folder_line)``   fixed step ``h`` (knob ``h``, s), :func:`motor_dynamics.build_drive`
                        with ``method: rk4``, ``periodic=False`` (accepted for
                        ``h <= 2.21 τ = 0.857`` s; the largest ``h`` is near that limit)
``DOPRI5 (folder_line)``  adaptive, knob ``rtol``; ``build_drive`` with ``method: dopri5``,
                        ``periodic=False``, largest step ``h = DURATION`` (no cap, as scipy's
                        default ``max_step``); with the load it lands on every break
``solve_ivp RK45``      ``scipy.integrate.solve_ivp(method='RK45', dense_output=True)``,
``solve_ivp DOP853``    knob ``rtol``, on the same right-hand side written as a plain Python
                        function (:func:`user_rhs`), over the whole span in one call: the
                        load's jumps are left to the step-size control, as a user who
                        reaches for ``solve_ivp`` would do

The load in :func:`user_rhs` is the core's own scalar torque (``MasterLoad.torque_piece``
on the piece holding Θ; a test checks it against the public vectorised
``chain_friction.master_load_torque``, which costs ~10x more per scalar call), so the
comparison is of the integrators, not of two evaluations of the load.

All adaptive methods use ``atol = ATOL_PER_RTOL rtol`` (1e-3 rtol) on both components
(Θ in nominal s, ω in rad/s): the tolerance is one knob, and atol only matters at the
start from ``y = 0``. The core is measured through its public API (``build_drive`` on a
scene), so its cost is what a user pays: integration, dense output and the drive object.

Reference and how it is checked
-------------------------------
* No load: the closed form of the linear ODE (:func:`closed_form`, from the
  ``motor_dynamics`` docstring): ``ω(t) = ω_ss (1 - e^{-t/τ})``,
  ``Θ(t) = (ω_ss/ω_nom)(t - τ (1 - e^{-t/τ}))``, evaluated with ``expm1``. The test
  checks it against ``mpmath.odefun`` (Taylor series at 40 digits) and checks the float
  evaluation against the same formula in mpmath at 40 digits (agreement ~1e-16).
* Chain load: :func:`chain_reference`, ``solve_ivp`` DOP853 at ``rtol = 1e-13``,
  ``atol = 1e-15``, largest step 2 ms, integrated piecewise between the load's breaks (a
  terminal event on ``Θ = break``, then a restart with the next piece's smooth torque),
  so that no step straddles a jump or a kink. The test checks it against the core's
  DOPRI5 at ``rtol = 1e-13`` (an independent integrator with its own break landing) and
  against itself at ``rtol = 1e-12``: both agree to < 5e-11 nominal s (measured ~6e-12),
  so errors in this case are resolved down to ~1e-11; smaller ones are the reference's.

What the curves show
--------------------
Without load the core's DOPRI5 takes scipy RK45's steps, so its error is RK45's to
rounding and the two curves differ in CPU time only. With the load the breaks (~90 over
the span) cap every step at a piece of the load, and each step may spend ``rtol |Θ|``
(Θ grows to ~1.6 nominal s), so the phase error of the adaptive methods is tens of
times ``rtol`` there, and a loose ``rtol`` buys nothing (the steps are the pieces).
``solve_ivp`` without break handling pays for every jump with rejected steps.

Error and units
---------------
``error`` is the largest ``|Θ - Θ_ref|`` over a uniform grid of ``GRID_POINTS`` times on
``[0, DURATION]`` (every method's dense output), in **nominal seconds of master phase**
(multiply by ``ω_nom = 152.4`` for radians of the master shaft). ``cpu_s_per_sim_s`` is
the CPU time of one complete integration (``time.process_time``,
:func:`~folder_line.accuracy.measure.cpu_per_call`) divided by ``DURATION``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from folder_line.accuracy.measure import Row, cpu_budget, cpu_per_call
from folder_line.config.scenes import scene_mapping
from folder_line.core.effects import chain_friction as cf
from folder_line.core.effects import motor_dynamics as md
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.numerics.arrays import FloatArray
from folder_line.errors import IntegrationError

__all__ = [
    'ATOL_PER_RTOL',
    'CASES',
    'DOP853',
    'DOPRI5',
    'DURATION',
    'GRID_POINTS',
    'METHODS',
    'RK4',
    'RK45',
    'STUDY',
    'ChainReference',
    'chain_reference',
    'closed_form',
    'error_of',
    'knob_settings',
    'make_scene',
    'motor_params',
    'run',
    'run_core',
    'run_scipy',
    'user_rhs',
]


STUDY = 'motor'
#: simulated span from standstill, s (5.2 time constants of the line scene's motor)
DURATION = 2.0
#: error grid: uniform times on [0, DURATION]
GRID_POINTS = 20001
#: atol of every adaptive method, per unit rtol (same atol on Θ and ω)
ATOL_PER_RTOL = 1e-3
#: the two cases: label -> whether the scene lists chain_friction
CASES = {'start-up, no load': False, 'with chain load': True}
#: the methods, by their name in the rows
RK4 = 'RK4 (folder_line)'
DOPRI5 = 'DOPRI5 (folder_line)'
RK45 = 'solve_ivp RK45'
DOP853 = 'solve_ivp DOP853'
METHODS = (RK4, DOPRI5, RK45, DOP853)

_RTOL_FULL = tuple(10.0**-k for k in range(3, 13))
_SETTINGS: dict[tuple[bool, bool, str], tuple[float, ...]] = {
    # (chain load, quick, method) -> knob settings
    (False, False, RK4): (0.8, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 3e-3, 1e-3, 1e-4, 1e-5),
    (False, True, RK4): (0.2, 0.02, 2e-3),
    (True, False, RK4): (0.1, 0.03, 0.01, 3e-3, 1e-3, 3e-4, 1e-4),
    (True, True, RK4): (0.01, 1e-3),
}
for _load in (False, True):
    for _m in (DOPRI5, RK45, DOP853):
        _SETTINGS[(_load, False, _m)] = _RTOL_FULL
        _SETTINGS[(_load, True, _m)] = (1e-3, 1e-6, 1e-9) if not _load else (1e-4, 1e-8)

#: chain-load reference tolerances
REF_RTOL = 1e-13
REF_ATOL = 1e-15
#: chain-load reference largest step, s: the restarts read the state at a break off DOP853's
#: 7th-order dense output, whose error on a long step (the load-free piece allows ~0.05 s)
#: reaches ~1e-5 rad/s; at 2 ms it is below the step error
REF_MAX_STEP = 2e-3


def knob_settings(chain: bool, method: str, quick: bool = False) -> tuple[float, ...]:
    """Knob settings of one curve: ``h`` (s) for RK4, ``rtol`` (dimensionless) otherwise."""
    return _SETTINGS[(chain, quick, method)]


# ------------------------------------------------------------------------------ scenes


def make_scene(chain: bool, **motor: Any) -> Scene:
    """The shipped ``line`` scene's master drive, with or without its chain load.

    Parameters
    ----------
    chain : bool
        Keep ``chain_friction`` (the delivery's load on the master shaft).
    **motor
        Overrides of ``motor_dynamics`` keys (``method``, ``h`` in s, ``rtol``, ``atol`` ...).

    Returns
    -------
    Scene
        The line scene listing only ``motor_dynamics`` (and ``chain_friction`` if ``chain``).
    """
    data = scene_mapping('line', {f'motor_dynamics.{k}': v for k, v in motor.items()})
    keep = ('motor_dynamics', 'chain_friction') if chain else ('motor_dynamics',)
    data['effects'] = {k: v for k, v in data['effects'].items() if k in keep}
    return parse_scene(data)


def motor_params(scene: Scene) -> md.Params:
    """The ``motor_dynamics`` parameters of ``scene`` (a scene of :func:`make_scene`)."""
    p: md.Params = scene.effect('motor_dynamics')
    return p


# ------------------------------------------------------------------------------ references


def closed_form(p: md.Params, t: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Θ(t) (nominal s) and ω(t) (rad/s) from standstill without load, t in s.

    ``ω = ω_ss (1 - e^{-t/τ})``, ``Θ = (ω_ss/ω_nom)(t - τ (1 - e^{-t/τ}))`` with
    ``c = T_0/ω_0 + b``, ``τ = J/c``, ``ω_ss = T_0/c`` (``expm1`` keeps full relative
    accuracy of ω near t = 0).
    """
    tt = np.asarray(t, dtype=float)
    c = p.T_0 / p.omega_0 + p.b
    tau = p.J / c
    w_ss = p.T_0 / c
    em = np.expm1(-tt / tau)
    return w_ss / p.omega_nom * (tt + tau * em), -w_ss * em


def _scalar_load(scene: Scene) -> Callable[[float], float]:
    """The master-shaft load torque at one Θ (N m): the piece's smooth formula on the piece holding Θ."""
    load = cf.master_load(scene, motor_params(scene).omega_nom)
    torque_piece, next_break = load.torque_piece, load.next_break

    def torque(theta: float) -> float:
        return torque_piece(theta, (theta, next_break(theta)))

    return torque


def user_rhs(scene: Scene) -> Callable[[float, FloatArray], FloatArray]:
    """The motor ODE's right-hand side as a plain function ``f(t, y)`` for ``solve_ivp``.

    ``y = (Θ, ω)`` (nominal s, rad/s); returns ``(ω/ω_nom, (T_0 (1 - ω/ω_0) - b ω - T_load(Θ))/J)``.
    ``T_load`` (N m) is the core's scalar chain load (``MasterLoad.torque_piece`` on the piece
    ``(Θ, next break)``: the piece that holds Θ, a break itself counting as the start of the
    next piece -- the same torque the core integrates), or 0 without ``chain_friction``.
    """
    p = motor_params(scene)
    J, T0, w0, b, wn = p.J, p.T_0, p.omega_0, p.b, p.omega_nom
    if not scene.has('chain_friction'):

        def rhs_free(t: float, y: FloatArray) -> FloatArray:
            w = y[1]
            return np.array([w / wn, (T0 * (1.0 - w / w0) - b * w) / J])

        return rhs_free
    load = _scalar_load(scene)

    def rhs(t: float, y: FloatArray) -> FloatArray:
        w = y[1]
        return np.array([w / wn, (T0 * (1.0 - w / w0) - b * w - load(y[0])) / J])

    return rhs


@dataclass(frozen=True)
class ChainReference:
    """A piecewise dense solution: ``sols[i]`` on ``[starts[i], starts[i + 1]]``.

    Attributes
    ----------
    starts : ndarray
        Start time of each piece, s (the first is 0).
    sols : tuple
        ``scipy`` ``OdeSolution`` of each piece (``sol(t)`` -> ``(Θ, ω)``).
    t_end : float
        End of the last piece, s.
    """

    starts: FloatArray
    sols: tuple[Any, ...]
    t_end: float

    def __call__(self, t: npt.ArrayLike) -> FloatArray:
        """``(Θ, ω)`` at ``t`` (s), shape ``(2,) + t.shape`` (nominal s, rad/s)."""
        tt = np.asarray(t, dtype=float)
        flat = tt.ravel()
        idx = np.clip(np.searchsorted(self.starts, flat, side='right') - 1, 0, len(self.sols) - 1)
        out = np.empty((2, flat.size))
        for k in np.unique(idx):
            m = idx == k
            out[:, m] = self.sols[k](flat[m])
        return out.reshape((2, *tt.shape))

    def theta(self, t: npt.ArrayLike) -> FloatArray:
        """Θ(t), nominal s."""
        theta: FloatArray = self(t)[0]  # row 0 of the (2, ...) array
        return theta


def chain_reference(
    scene: Scene,
    duration: float = DURATION,
    *,
    rtol: float = REF_RTOL,
    atol: float = REF_ATOL,
    max_step: float = REF_MAX_STEP,
    method: str = 'DOP853',
) -> ChainReference:
    """Start-up with the chain load by ``solve_ivp`` DOP853, piecewise between the load's breaks.

    Each piece integrates the smooth torque of that piece (``MasterLoad.torque_piece``) up to
    a terminal event ``Θ = next break``; the next piece restarts from the event state. No
    step straddles a jump or a kink, so DOP853 keeps its 8th order.

    Parameters
    ----------
    scene : Scene
        Lists ``motor_dynamics`` and ``chain_friction``.
    duration : float
        Span from standstill, s.
    rtol, atol : float
        DOP853 tolerances (atol in nominal s and rad/s).
    max_step : float
        Largest step, s (keeps the dense output, read at every break, as accurate as the steps).
    method : str
        ``solve_ivp`` method (``'DOP853'`` for the reference; ``'RK45'`` for a comparison
        with the core's DOPRI5, which also lands on the breaks).

    Returns
    -------
    ChainReference

    Raises
    ------
    IntegrationError
        ``solve_ivp`` failed on a piece.
    """
    p = motor_params(scene)
    J, T0, w0, b, wn = p.J, p.T_0, p.omega_0, p.b, p.omega_nom
    load = cf.master_load(scene, wn)
    t, y = 0.0, np.zeros(2)
    lo = 0.0
    starts: list[float] = []
    sols: list[Any] = []
    while t < duration:
        hi = load.next_break(lo)
        piece = (lo, hi)

        def rhs(_t: float, yy: FloatArray, piece: tuple[float, float] = piece) -> FloatArray:
            w = yy[1]
            return np.array([w / wn, (T0 * (1.0 - w / w0) - b * w - load.torque_piece(yy[0], piece)) / J])

        def hit(_t: float, yy: FloatArray, hi: float = hi) -> float:
            return float(yy[0] - hi)

        # solve_ivp reads these attributes of an event function; mypy allows none on a function
        hit.terminal = True  # type: ignore[attr-defined]
        hit.direction = 1.0  # type: ignore[attr-defined]
        res = solve_ivp(
            rhs, (t, duration), y, method=method, rtol=rtol, atol=atol, max_step=max_step, dense_output=True, events=hit
        )
        if res.status < 0:
            raise IntegrationError(f'solve_ivp {method}', len(sols), t, max_step, f'chain reference: {res.message}')
        starts.append(t)
        sols.append(res.sol)
        if res.status != 1:
            break
        t = float(res.t_events[0][0])
        y = np.array(res.y_events[0][0], dtype=float)
        lo = hi
    return ChainReference(np.array(starts), tuple(sols), float(duration))


# ------------------------------------------------------------------------------ methods


def run_core(scene: Scene, duration: float = DURATION) -> md.MotorDrive:
    """The core's drive over ``[0, duration]`` (s), whole span integrated (``periodic=False``)."""
    return md.build_drive(scene, duration, periodic=False)


def run_scipy(
    rhs: Callable[[float, FloatArray], FloatArray], method: str, rtol: float, duration: float = DURATION
) -> Any:
    """``solve_ivp`` from standstill over ``[0, duration]`` (s) with dense output.

    ``atol = ATOL_PER_RTOL rtol``; ``method`` is ``'RK45'`` or ``'DOP853'``. Returns the
    ``OdeSolution`` (``sol(t)`` -> ``(Θ, ω)``); raises :class:`IntegrationError` if it fails.
    """
    res = solve_ivp(
        rhs, (0.0, duration), [0.0, 0.0], method=method, rtol=rtol, atol=ATOL_PER_RTOL * rtol, dense_output=True
    )
    if res.status != 0:
        raise IntegrationError(f'solve_ivp {method}', 0, 0.0, math.nan, f'at rtol={rtol!r}: {res.message}')
    return res.sol


def _core_scene(chain: bool, method: str, value: float) -> Scene:
    if method == RK4:
        return make_scene(chain, method='rk4', h=value)
    return make_scene(chain, method='dopri5', h=DURATION, rtol=value, atol=ATOL_PER_RTOL * value)


def _runner(chain: bool, method: str, value: float) -> Callable[[], Callable[[FloatArray], FloatArray]]:
    """A zero-argument call doing one full integration; it returns Θ(t) of the result."""
    if method in (RK4, DOPRI5):
        scene = _core_scene(chain, method, value)

        def core() -> Callable[[FloatArray], FloatArray]:
            return run_core(scene).theta

        return core
    rhs = user_rhs(make_scene(chain))
    name = 'RK45' if method == RK45 else 'DOP853'

    def scipy_run() -> Callable[[FloatArray], FloatArray]:
        sol = run_scipy(rhs, name, value)
        return lambda t: sol(t)[0]

    return scipy_run


def error_of(
    chain: bool, method: str, value: float, reference: Callable[[FloatArray], FloatArray] | None = None
) -> float:
    """Largest ``|Θ - Θ_ref|`` (nominal s) over the error grid of one method at one knob setting.

    ``reference`` maps times (s) to Θ (nominal s); default the closed form without load, the
    :func:`chain_reference` with it.
    """
    t = np.linspace(0.0, DURATION, GRID_POINTS)
    ref = reference(t) if reference is not None else _reference_theta(chain, t)
    theta = _runner(chain, method, value)()
    return float(np.max(np.abs(theta(t) - ref)))


def _reference_theta(chain: bool, t: FloatArray) -> FloatArray:
    if chain:
        return chain_reference(make_scene(True)).theta(t)
    return closed_form(motor_params(make_scene(False)), t)[0]


# ------------------------------------------------------------------------------ run


def _measure(
    fn: Callable[[], Callable[[FloatArray], FloatArray]], t: FloatArray, ref: FloatArray, min_s: float
) -> tuple[float, float]:
    """Error (max over the grid) and CPU seconds of one call; a slow call is timed once."""
    c0 = time.process_time()
    theta = fn()
    first = time.process_time() - c0
    err = float(np.max(np.abs(theta(t) - ref)))
    cpu = first if first > 10 * min_s else cpu_per_call(fn, min_s=min_s, repeats=3)
    return err, cpu


def run(quick: bool = False) -> list[Row]:
    """Rows of the ``motor`` study (module docstring): both cases, four methods each.

    Parameters
    ----------
    quick : bool
        Fewer knob settings (3 per method without load, 2 with it) and shorter timing batches.

    Returns
    -------
    list of Row
        ``error`` in nominal s of master phase, ``cpu_s_per_sim_s`` in CPU s per simulated s.
    """
    min_s = cpu_budget(quick)[0]  # repeated 3 times even with --quick (see _measure)
    t = np.linspace(0.0, DURATION, GRID_POINTS)
    rows: list[Row] = []
    for case, chain in CASES.items():
        if chain:
            ref = chain_reference(make_scene(True)).theta(t)
            reference = (
                f'solve_ivp DOP853 rtol {REF_RTOL:g}, piecewise between the load breaks; '
                'checked against the core DOPRI5 at rtol 1e-13'
            )
        else:
            ref = closed_form(motor_params(make_scene(False)), t)[0]
            reference = 'closed form (expm1); checked against mpmath.odefun at 40 digits'
        for method in METHODS:
            knob = 'h' if method == RK4 else 'rtol'
            for value in knob_settings(chain, method, quick):
                err, cpu = _measure(_runner(chain, method, value), t, ref, min_s)
                rows.append(
                    Row(
                        study=STUDY,
                        method=f'{method} [{case}]',
                        knob=knob,
                        value=float(value),
                        error=err,
                        cpu_s_per_sim_s=cpu / DURATION,
                        quantity=f'master phase Θ, {case}',
                        unit='nominal s',
                        reference=reference,
                    )
                )
    return rows
