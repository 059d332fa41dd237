"""Study ``fourbar``: a four-bar's rocker angle -- the closed form vs ``scipy.integrate.solve_ivp``.

What is measured
----------------
The layup's first loop, the crank-rocker O1-A-B-O2 of ``config/layup.yaml`` (crank
``R_kr``, rod ``l2``, rocker ``O2B``, ground O1 = (a, b) from O2): its rocker angle
``ψ(t) = θ3`` (angle of O2→B from +x, rad) for the crank ``φ = ω t`` at the nominal
``ω = params.omega``, over ``SPAN`` = 2 crank turns (4 s), output on a grid of
``OUTPUT_RATE`` = 250 Hz (``t_k = k / 250``, k = 0 … 1000, both ends included).

``closed form (folder_line)``  :func:`folder_line.core.numerics.loop.circle_intersection` of
                        circle(O2, O2B) and circle(A, l2) on branch +1 (the layup's
                        assembly, ``(A - O2) × (B - O2) > 0``), then ``ψ = atan2(B)``;
                        knob ``batch``: grid points per call (1 … the whole grid).
``solve_ivp RK45``      ``scipy.integrate.solve_ivp`` integrating the ODE a user would
``solve_ivp DOP853``    write, ``dψ/dt = ω ψ'(φ)`` with the velocity ratio from the
``solve_ivp LSODA``     differentiated loop equation at the current state:
                        ``dψ/dt = (B - A)·dA/dt / (A × B)``, ``B = O2B e(ψ)``
                        (:func:`user_rhs`, pure ``math``), from the reference ψ(0) over the
                        whole span in one call, ``dense_output=True`` evaluated at the grid;
                        knob ``rtol`` 1e-3 … 1e-12 with ``atol = ATOL_PER_RTOL · rtol``
                        (1e-3 rtol, rad).

Every method is charged the CPU time (``time.process_time``,
:func:`~folder_line.accuracy.measure.cpu_per_call`) of producing the whole grid of the
span, divided by ``SPAN``: CPU seconds per simulated second.

Reference and how it is checked
-------------------------------
:func:`folder_line.accuracy.reference.sixbar_reference` with ``loops=1``: Newton's method on the loop
closure ``O1 + R e(φ) + l2 e(θ2) - O2B e(θ3) = 0`` in mpmath at 50 digits, at the float
grid angles ``φ_k = fl(ω t_k)``. Its checks are in ``test/accuracy/test_linkage.py``
(loop residual < 1e-30 m, branch, agreement with the core, rates against an mpmath
finite difference); ``test/accuracy/test_fourbar.py`` checks that the ODE's right-hand
side at the reference ψ equals the reference rate. (The ODE's exact solution at ``t_k``
is ψ at ``ω t_k`` unrounded; it differs from ψ(φ_k) by at most ``|ψ'| ulp(4π)/2`` ≈ 2e-16 rad.)

Error and units
---------------
``error`` = ``max_k |ψ(t_k) - ψ_ref(t_k)|`` over the grid, rad. The cost ratio at equal
error is :func:`ratio_at_equal_error`.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from scipy.integrate import solve_ivp

from folder_line.accuracy.measure import Row, cpu_budget, cpu_per_call
from folder_line.accuracy.pareto import EqualErrorRatio, equal_error_ratio
from folder_line.accuracy.reference import ReferenceArrays, sixbar_reference
from folder_line.config.params import load_params
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.numerics.loop import circle_intersection

__all__ = [
    'ATOL_PER_RTOL',
    'CLOSED_FORM',
    'ODE_METHODS',
    'OUTPUT_RATE',
    'REFERENCE',
    'STUDY',
    'TURNS',
    'closed_form_psi',
    'default_params',
    'grid',
    'knob_settings',
    'ratio_at_equal_error',
    'reference',
    'run',
    'solve_ode',
    'span',
    'user_rhs',
]

STUDY = 'fourbar'
#: output grid, points per simulated second
OUTPUT_RATE = 250.0
#: crank turns simulated
TURNS = 2
#: atol of solve_ivp per unit rtol (rad)
ATOL_PER_RTOL = 1e-3
CLOSED_FORM = 'closed form (folder_line)'
ODE_METHODS = ('RK45', 'DOP853', 'LSODA')
QUANTITY = ('rocker angle ψ (θ3 of loop O1-A-B-O2)', 'rad')
REFERENCE = 'mpmath 50-digit loop closure of O1-A-B-O2 (residual < 1e-30 m; checked in test/accuracy)'

_SETTINGS: dict[tuple[str, bool], tuple[float, ...]] = {
    ('batch', False): (1, 10, 100, 1001),
    ('batch', True): (1, 100, 1001),
    ('rtol', False): tuple(10.0**-k for k in range(3, 13)),
    ('rtol', True): (1e-3, 1e-6, 1e-9, 1e-12),
}


def knob_settings(method: str, quick: bool = False) -> tuple[str, tuple[float, ...]]:
    """Knob name and settings of a method.

    Parameters
    ----------
    method : str
        :data:`CLOSED_FORM` or ``'solve_ivp ' + one of ODE_METHODS``.
    quick : bool
        The reduced settings of ``--quick``.

    Returns
    -------
    (str, tuple of float)
        ``batch`` (grid points per call; the largest is the whole grid) or ``rtol``.
    """
    knob = 'batch' if method == CLOSED_FORM else 'rtol'
    return knob, _SETTINGS[(knob, quick)]


def default_params() -> LayupParams:
    """The layup of ``config/layup.yaml`` (its loop O1-A-B-O2 is the four-bar)."""
    return load_params('layup')


def span(params: LayupParams) -> float:
    """Simulated span, s: :data:`TURNS` crank periods ``2π/ω`` (4 s for the defaults)."""
    return TURNS * 2.0 * math.pi / params.omega


def grid(params: LayupParams) -> np.ndarray:
    """Output times ``t_k = k / OUTPUT_RATE``, s, k = 0 … round(span · OUTPUT_RATE)."""
    n = round(span(params) * OUTPUT_RATE)
    return np.arange(n + 1) / OUTPUT_RATE


def reference(params: LayupParams) -> ReferenceArrays:
    """mpmath ψ and ψ' at the grid's crank angles ``fl(ω t_k)`` (cached).

    Parameters
    ----------
    params : LayupParams

    Returns
    -------
    ReferenceArrays
        ``theta3`` = ψ, rad; ``omega3`` = dψ/dt, rad/s.
    """
    return sixbar_reference(params, params.omega * grid(params), loops=1)


def closed_form_psi(params: LayupParams, t: np.ndarray) -> np.ndarray:
    """Rocker angle by the core's circle–circle intersection, vectorised.

    Parameters
    ----------
    params : LayupParams
    t : ndarray
        Times, s (crank ``φ = ω t``).

    Returns
    -------
    ndarray
        ψ = angle of O2→B from +x, rad in (-π, π].
    """
    phi = params.omega * t
    ax = params.a + params.R_kr * np.cos(phi)
    ay = params.b + params.R_kr * np.sin(phi)
    b = circle_intersection(0.0, 0.0, params.O2B, ax, ay, params.l2, 1.0, inputs=phi, mechanism='four-bar O1-A-B-O2')
    return np.arctan2(b.y, b.x)


def user_rhs(params: LayupParams) -> Callable[[float, np.ndarray], list[float]]:
    """The ODE a user would hand to ``solve_ivp``: ``dψ/dt`` from the velocity ratio.

    Differentiating ``|B - A|² = l2²`` with ``B = O2B e(ψ)`` turning about O2 and
    ``dA/dt = R ω (-sin φ, cos φ)`` gives ``dψ/dt = (B - A)·dA/dt / (A × B)``.

    Parameters
    ----------
    params : LayupParams

    Returns
    -------
    callable
        ``f(t, y) -> [dψ/dt]`` (rad/s), ``t`` in s, ``y = [ψ]`` in rad.
    """
    w, R, a, b, q = params.omega, params.R_kr, params.a, params.b, params.O2B
    cos, sin = math.cos, math.sin

    def f(t: float, y: np.ndarray) -> list[float]:
        ph = w * t
        c = cos(ph)
        s = sin(ph)
        ax = a + R * c
        ay = b + R * s
        bx = q * cos(y[0])
        by = q * sin(y[0])
        return [w * R * ((by - ay) * c - (bx - ax) * s) / (ax * by - ay * bx)]

    return f


def solve_ode(params: LayupParams, method: str, rtol: float, t: np.ndarray, psi0: float) -> np.ndarray:
    """ψ at the times ``t`` by ``solve_ivp`` over ``[t[0], t[-1]]`` with dense output.

    Parameters
    ----------
    params : LayupParams
    method : {'RK45', 'DOP853', 'LSODA'}
    rtol : float
        Relative tolerance; ``atol = ATOL_PER_RTOL · rtol`` rad.
    t : ndarray
        Increasing output times, s.
    psi0 : float
        ψ(t[0]), rad.

    Returns
    -------
    ndarray
        ψ(t), rad.
    """
    sol = solve_ivp(
        user_rhs(params),
        (float(t[0]), float(t[-1])),
        [psi0],
        method=method,
        rtol=rtol,
        atol=ATOL_PER_RTOL * rtol,
        dense_output=True,
    )
    if not sol.success:  # pragma: no cover - a smooth 1-D ODE
        raise RuntimeError(f'solve_ivp {method} rtol={rtol:g}: {sol.message}')
    psi: np.ndarray = sol.sol(t)[0]  # scipy has no type information
    return psi


def _error(psi: np.ndarray, ref: ReferenceArrays) -> float:
    d = np.remainder(psi - ref.theta3 + math.pi, 2.0 * math.pi) - math.pi
    return float(np.abs(d).max())


def _closed_form_batched(params: LayupParams, t: np.ndarray, batch: int) -> np.ndarray:
    return np.concatenate([closed_form_psi(params, t[i : i + batch]) for i in range(0, t.size, batch)])


def ratio_at_equal_error(
    rows: Iterable[Row], method_a: str = CLOSED_FORM, method_b: str = 'solve_ivp DOP853', error: float | None = None
) -> EqualErrorRatio:
    """CPU of ``method_b`` over ``method_a`` at the same error, log-log interpolated on the Pareto curves.

    Parameters
    ----------
    rows : iterable of Row
        Rows of this study (others are ignored).
    method_a : str
        The reference method, by default the closed form.
    method_b : str
        The method compared, by default ``solve_ivp DOP853``.
    error : float, optional
        Error level, rad. Default: the largest error of ``method_a``'s rows, i.e. the
        level every setting of ``a`` reaches (for the closed form, whose error does not
        depend on its knob, its error level; its cheapest setting is compared).

    Returns
    -------
    EqualErrorRatio
        ``ratio = cpu_b / cpu_a`` at ``error``; ``reached`` False when ``b`` never got
        down to that error: then the ratio is taken at ``b``'s best error (a lower bound).

    Raises
    ------
    KeyError
        A method has no rows.
    """
    rows = [r for r in rows if r.study == STUDY]
    if error is None:
        errs = [r.error for r in rows if r.method == method_a]
        if not errs:
            raise KeyError(f'no rows of {STUDY}/{method_a}')
        error = max(errs)
    return equal_error_ratio(rows, STUDY, method_a, method_b, error)


def run(quick: bool = False) -> list[Row]:
    """Measure the closed form and ``solve_ivp`` at every knob setting.

    Parameters
    ----------
    quick : bool
        Fewer settings and shorter timings (``--quick``).

    Returns
    -------
    list of Row
        Study ``fourbar``; errors in rad, CPU s per simulated s.
    """
    params = default_params()
    t = grid(params)
    ref = reference(params)
    sim = float(t[-1] - t[0])
    min_s, repeats = cpu_budget(quick)
    rows: list[Row] = []

    def row(method: str, knob: str, value: float, error: float, cpu: float) -> None:
        rows.append(Row(STUDY, method, knob, float(value), error, cpu / sim, QUANTITY[0], QUANTITY[1], REFERENCE))

    knob, batches = knob_settings(CLOSED_FORM, quick)
    for batch in batches:
        nb = int(min(batch, t.size))

        def batch_call(k: int = nb) -> object:
            return _closed_form_batched(params, t, k)

        cpu = cpu_per_call(batch_call, min_s=min_s, repeats=repeats)
        row(CLOSED_FORM, knob, nb, _error(_closed_form_batched(params, t, nb), ref), cpu)

    psi0 = float(ref.theta3[0])
    for method in ODE_METHODS:
        name = f'solve_ivp {method}'
        knob, rtols = knob_settings(name, quick)
        for rtol in rtols:

            def ode_call(m: str = method, r: float = rtol) -> object:
                return solve_ode(params, m, r, t, psi0)

            cpu = cpu_per_call(ode_call, min_s=min_s, repeats=repeats)
            row(name, knob, rtol, _error(solve_ode(params, method, rtol, t, psi0), ref), cpu)
    return rows


def _main(argv: Sequence[str]) -> None:  # pragma: no cover - a developer's look at the numbers
    t0 = time.process_time()
    rows = run(quick='--quick' in argv)
    for r in rows:
        print(f'{r.method:28s} {r.knob:6s} {r.value:10.3g} {r.error:10.3g} {r.cpu_s_per_sim_s:10.3g}')
    for m in ODE_METHODS:
        print(ratio_at_equal_error(rows, CLOSED_FORM, f'solve_ivp {m}'))
    print(f'CPU {time.process_time() - t0:.2f} s')


if __name__ == '__main__':  # pragma: no cover
    _main(sys.argv)
