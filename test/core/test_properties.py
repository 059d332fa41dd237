"""Property tests (hypothesis) of geometric and numerical invariants across the core.

Each property is checked against something independent of the code path under test:
an algebraic identity (the differentiated loop equations), a spectral derivative of a
periodic function, exact rational arithmetic, a brute-force sample scan, or the
geometric rotatability of a four-bar. Examples are derandomised so CI is reproducible.
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from folder_line.config.params import load_params
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import delivery_laws
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.chain import ChainPath
from folder_line.core.mechanisms.delivery_results import SECTION_DECELERATION, STATE_CARRIAGE_REVERSED, STATE_KV_ZERO
from folder_line.core.mechanisms.layup import LayupModel, LayupParams, check_assembly
from folder_line.core.mechanisms.layup_angles import GRASHOF_REL_TOL, TAU, classify_fourbar
from folder_line.core.numerics import integrators as ig
from folder_line.core.numerics import loop
from folder_line.core.numerics.roots import RTOL, brent, find_sign_changes
from folder_line.core.numerics.timebase import ShaftClock
from folder_line.errors import AssemblyError, ParameterError
from folder_line.interfaces import NS_PER_S

EPS = float(np.finfo(float).eps)
PROPS = settings(max_examples=60, deadline=None, derandomize=True)
LAYUP = dataclasses.asdict(load_params('layup'))


def spectral_derivative(f: np.ndarray, period: float) -> np.ndarray:
    """d f / dx of samples of a smooth periodic function on a uniform grid over one period."""
    n = f.size
    k = np.fft.fftfreq(n, d=1.0 / n)
    k[n // 2] = 0.0  # the Nyquist mode has no derivative
    return np.real(np.fft.ifft(np.fft.fft(f) * (2j * np.pi / period) * k))


# ----------------------------------------------------------------------------- loop.py dyads
@PROPS
@given(
    x0=st.floats(-5, 5),
    y0=st.floats(-5, 5),
    r0=st.floats(0.1, 5),
    r1=st.floats(0.1, 5),
    u=st.floats(0.05, 0.95),
    ang=st.floats(-math.pi, math.pi),
    branch=st.sampled_from([1, -1]),
    kin=st.lists(st.floats(-10, 10), min_size=8, max_size=8),
)
def test_dyad_joint_satisfies_the_differentiated_loop_equations(
    x0: float, y0: float, r0: float, r1: float, u: float, ang: float, branch: int, kin: list[float]
) -> None:
    """X on both circles on the asked side; V and A satisfy (X - ci).(V - vi) = 0 and
    (X - ci).(A - ai) = -|V - vi|^2 for both centres (the loop equations, differentiated)."""
    d = abs(r0 - r1) + (r0 + r1 - abs(r0 - r1)) * u  # strictly between the two tangencies
    x1, y1 = x0 + d * math.cos(ang), y0 + d * math.sin(ang)
    vx0, vy0, vx1, vy1, ax0, ay0, ax1, ay1 = kin
    it = loop.circle_intersection(x0, y0, r0, x1, y1, r1, branch, inputs=0.0)
    X, Y = float(it.x), float(it.y)
    scale = r0 + r1 + d
    assert abs(math.hypot(X - x0, Y - y0) - r0) <= 8 * EPS * scale / float(it.margin)
    assert abs(math.hypot(X - x1, Y - y1) - r1) <= 8 * EPS * scale / float(it.margin)
    assert np.sign((x1 - x0) * (Y - y0) - (y1 - y0) * (X - x0)) == branch
    vx, vy = (float(v) for v in loop.circle_point_velocity(X, Y, x0, y0, vx0, vy0, x1, y1, vx1, vy1))
    ax, ay = (
        float(a)
        for a in loop.circle_point_acceleration(X, Y, vx, vy, x0, y0, vx0, vy0, ax0, ay0, x1, y1, vx1, vy1, ax1, ay1)
    )
    cond = 1.0 / float(it.margin) ** 2  # 1 / sin^2(transmission angle)
    vs = 30.0 + math.hypot(vx, vy)
    for cx, cy, cvx, cvy, cax, cay in ((x0, y0, vx0, vy0, ax0, ay0), (x1, y1, vx1, vy1, ax1, ay1)):
        ex, ey = X - cx, Y - cy
        assert abs(ex * (vx - cvx) + ey * (vy - cvy)) <= 64 * EPS * cond * scale * vs
        rel2 = (vx - cvx) ** 2 + (vy - cvy) ** 2
        assert abs(ex * (ax - cax) + ey * (ay - cay) + rel2) <= 256 * EPS * cond**2 * (
            scale * (30 + abs(ax) + abs(ay)) + vs * vs
        )


# ----------------------------------------------------------------------------- L six-bar
@settings(max_examples=30, deadline=None, derandomize=True)
@given(factors=st.lists(st.floats(0.9, 1.1), min_size=9, max_size=9))
def test_sixbar_velocities_are_the_spectral_derivatives_of_the_positions(factors: list[float]) -> None:
    """For random accepted geometries (toggle margins >= 0.3): omega3/omega, omega5/omega are the
    derivatives of theta3, theta5 over the crank turn, eps3/omega^2 that of omega3/omega (spectral
    differentiation of the periodic samples: an independent route); each loop stays on its
    documented branch at every angle."""
    keys = ('R_kr', 'a', 'b', 'l2', 'O2B', 'l3', 'l4', 'l5', 'O2O3')
    try:
        p = LayupParams(**{**LAYUP, **{k: LAYUP[k] * f for k, f in zip(keys, factors, strict=True)}})
    except (ParameterError, AssemblyError):
        assume(False)
        return
    margins = check_assembly(p)
    assume(margins.margin1 >= 0.3 and margins.margin2 >= 0.3)
    n = 512
    phi = np.arange(n) * (TAU / n)
    s = LayupModel(p).arrays(phi)
    w = p.omega
    for theta, omega in ((s.theta3, s.omega3), (s.theta5, s.omega5)):
        th = np.unwrap(theta)
        assert abs(th[-1] - th[0]) < math.pi  # a rocker: no net turn
        ref = spectral_derivative(th - th.mean(), TAU)
        assert np.abs(omega / w - ref).max() <= 1e-9 * np.abs(ref).max()
    d_eps = spectral_derivative(s.omega3 / w, TAU)
    assert np.abs(s.eps3 / w**2 - d_eps).max() <= 1e-8 * np.abs(d_eps).max()
    assert np.all(s.xA * s.yB - s.yA * s.xB > 0.0)  # (A - O2) x (B - O2) > 0
    assert np.all((p.O2O3 - s.xC) * (s.yE - s.yC) - (0.0 - s.yC) * (s.xE - s.xC) < 0.0)  # (O3 - C) x (E - C) < 0


# ----------------------------------------------------------------------------- F knife
@PROPS
@given(r=st.floats(0.01, 0.1), ratio=st.floats(1.2, 10.0), e=st.floats(-0.05, 0.05), q=st.floats(0.01, 0.99))
def test_knife_stays_in_its_stroke_and_v_a_are_derivatives(r: float, ratio: float, e: float, q: float) -> None:
    """s in [s_min, s_max] at every angle, the dead centres attain them, and v / omega, a / omega^2
    are the spectral derivatives of s over a turn."""
    L = (r + abs(e)) * ratio
    lo, hi = math.sqrt((L - r) ** 2 - e * e), math.sqrt((L + r) ** 2 - e * e)
    p = knf.KnifeParams(r_k=r, L_k=L, e=e, n_k=50000.0, s_clear=lo + q * (hi - lo))
    n = 1024
    phi = np.arange(n) * (TAU / n)
    st_ = knf.state(p, phi)
    tol = 4 * EPS * (L + r)
    assert st_.s.min() >= p.s_min - tol and st_.s.max() <= p.s_max + tol
    dc = knf.dead_centres(p)
    assert abs(knf.position(p, dc.phi_outer) - p.s_max) <= tol and abs(knf.position(p, dc.phi_inner) - p.s_min) <= tol
    w = p.omega_k
    ds = spectral_derivative(st_.s, TAU)
    assert np.abs(st_.v / w - ds).max() <= 1e-9 * r
    dds = spectral_derivative(st_.v / w, TAU)
    assert np.abs(st_.a / w**2 - dds).max() <= 1e-8 * r * ratio
    assert np.array_equal(st_.occupies, st_.s >= p.s_clear)


# ----------------------------------------------------------------------------- timebase
@PROPS
@given(
    period_ns=st.integers(1, 10**12),
    phase0=st.fractions(0, 1, max_denominator=10**9),
    t=st.integers(-(10**15), 10**18),
    dt=st.integers(0, 10**12),
    k=st.integers(-(10**9), 10**9),
)
def test_shaft_clock_is_periodic_additive_and_monotone(
    period_ns: int, phase0: Fraction, t: int, dt: int, k: int
) -> None:
    """With an integral period P (ns): turns(t + k P) = turns(t) + (k, 0) exactly; the phase never
    runs backwards; the angle is in [0, 2 pi)."""
    clock = ShaftClock(Fraction(NS_PER_S, period_ns), phase0=phase0)
    whole, frac = clock.turns(t)
    w2, f2 = clock.turns(t + k * period_ns)
    assert (w2, f2) == (whole + k, frac)
    w3, f3 = clock.turns(t + dt)
    assert (w3, f3) >= (whole, frac)
    assert 0.0 <= frac < 1.0 and 0.0 <= clock.angle(t) < TAU
    assert clock.period_ns() == period_ns


# ----------------------------------------------------------------------------- roots
@PROPS
@given(
    r=st.floats(-1e3, 1e3),
    c=st.floats(-10, 10),
    left=st.floats(1e-9, 10),
    right=st.floats(1e-9, 10),
    sign=st.sampled_from([1.0, -1.0]),
    xtol=st.sampled_from([2e-12, 1e-15, 1e-6, 1e-3]),
)
def test_brent_root_is_bracketed_and_within_tolerance(
    r: float, c: float, left: float, right: float, sign: float, xtol: float
) -> None:
    """f = sign (x - r)(1 + (x - c)^2) has the one root r: Brent returns it within
    xtol + rtol |r| (plus the rounding of r itself), inside its final bracket, which holds a sign change."""

    def f(x: float) -> float:
        return sign * (x - r) * (1.0 + (x - c) ** 2)

    a, b = r - left, r + right
    assume(f(a) != 0.0 and f(b) != 0.0 and a < r < b)
    res = brent(f, a, b, xtol=xtol)
    assert abs(res.root - r) <= xtol + RTOL * abs(r) + 4 * math.ulp(r)
    lo, hi = res.bracket
    assert lo <= res.root <= hi and a <= lo and hi <= b
    assert res.f_root == 0.0 or ((lo < hi and (f(lo) <= 0.0) != (f(hi) <= 0.0)) or f(lo) == 0.0 or f(hi) == 0.0)
    assert res.iterations <= 100 and res.f_root == f(res.root)


@PROPS
@given(coef=st.lists(st.floats(-1, 1), min_size=7, max_size=7), n=st.integers(20, 300))
def test_sign_changes_match_the_sampled_sign_pattern(coef: list[float], n: int) -> None:
    """A random trigonometric polynomial on a grid: one crossing per sample interval with a sign
    change (and no other), inside that interval, directions alternating, f ~ 0 there."""
    a0, a1, b1, a2, b2, a3, b3 = coef

    def f(x: float) -> float:
        return (
            a0
            + a1 * math.cos(x)
            + b1 * math.sin(x)
            + a2 * math.cos(2 * x)
            + b2 * math.sin(2 * x)
            + a3 * math.cos(3 * x)
            + b3 * math.sin(3 * x)
        )

    grid = np.linspace(0.0, TAU, n)
    vals = np.array([f(x) for x in grid])
    assume(np.all(vals != 0.0))
    sgn = np.sign(vals)
    intervals = np.flatnonzero(sgn[:-1] != sgn[1:])
    sc = find_sign_changes(f, grid, values=vals)
    assert len(sc) == intervals.size
    assert np.all((grid[intervals] <= sc.x) & (sc.x <= grid[intervals + 1]))
    assert np.array_equal(sc.direction, sgn[intervals + 1].astype(np.int8))
    assert np.all(sc.direction[1:] != sc.direction[:-1])
    slope = sum(abs(v) * k for v, k in zip(coef, (0, 1, 1, 2, 2, 3, 3), strict=True))  # bound on |f'|
    assert all(abs(f(x)) <= slope * 2 * (2e-12 + RTOL * abs(x)) + 8 * EPS * sum(map(abs, coef)) for x in sc.x)


# ----------------------------------------------------------------------------- D delivery
@PROPS
@given(
    Lambda=st.floats(0.05, 5.0),
    alpha_m=st.floats(1.0, 89.9),
    law=st.sampled_from(delivery_laws.law_names()),
    fr=st.lists(st.floats(0.0, 0.5), min_size=8, max_size=8),
    mode=st.sampled_from(dlv.RETURN_SECTIONS),
    u=st.lists(st.floats(0.0, 2.0), min_size=1, max_size=40),
)
def test_delivery_ratios_stay_in_their_documented_ranges(
    Lambda: float, alpha_m: float, law: str, fr: list[float], mode: str, u: list[float]
) -> None:
    """0 <= eta <= eta_O <= 1, eta_A and eta_B in [0, 1], alpha in [0, alpha_m]; on the first section
    K_v >= cos(beta) > 0 (never kv_zero or reversed); where 'ok', eta = eta_O eta_A eta_B, friction
    only raises the forces (p_AB >= p_AB_ideal >= 1, p_ch >= p_ch_ideal = K_v > 0) and the power
    balance m_1_ideal / m_1 = eta holds."""
    names = ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')
    p = dlv.DeliveryParams(Lambda=Lambda, alpha_m_deg=alpha_m, law=law, **dict(zip(names, fr, strict=True)))
    s = dlv.evaluate_stroke(p, u, return_section=mode)
    assert np.all((s.eta >= 0.0) & (s.eta <= s.eta_O) & (s.eta_O <= 1.0))
    assert np.all((s.eta_A >= 0.0) & (s.eta_A <= 1.0) & (s.eta_B >= 0.0) & (s.eta_B <= 1.0))
    assert np.all((s.alpha >= 0.0) & (s.alpha <= math.radians(alpha_m) * (1 + 4 * EPS)))
    first = s.section == SECTION_DECELERATION
    assert np.all(s.K_v[first] >= np.cos(s.beta[first]) * (1 - 4 * EPS))
    assert not np.any(np.isin(s.state[first], (STATE_KV_ZERO, STATE_CARRIAGE_REVERSED)))
    ok = s.ok
    assert np.allclose(s.eta[ok], (s.eta_O * s.eta_A * s.eta_B)[ok], rtol=1e-14, atol=0.0)
    assert np.all(s.p_AB[ok] >= s.p_AB_ideal[ok] * (1 - 4 * EPS)) and np.all(s.p_AB_ideal[ok] >= 1.0)
    assert np.all(s.p_ch[ok] >= s.p_ch_ideal[ok] * (1 - 4 * EPS)) and np.all(s.K_v[ok] > 0.0)
    assert np.allclose(s.m_1_ideal[ok] / s.m_1[ok], s.eta[ok], rtol=1e-9, atol=0.0)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(Lambda=st.floats(0.01, 10.0), law=st.sampled_from(delivery_laws.law_names()), x_max=st.floats(0.01, 3.0))
def test_chain_path_is_monotone_bounded_and_inverted(Lambda: float, law: str, x_max: float) -> None:
    """The chain's arc length over the stroke rises monotonically, between the straight length
    x_max u and x_max u sqrt(1 + (Lambda max psi')^2), and position() inverts it."""
    p = dlv.DeliveryParams(
        Lambda=Lambda,
        alpha_m_deg=60.0,
        law=law,
        f_Ap=0.0,
        f_Bp=0.0,
        f_A=0.0,
        f_B=0.0,
        f_O=0.0,
        r_A=0.0,
        r_B=0.0,
        r_O=0.0,
    )
    path = ChainPath(p, x_max)
    u = np.linspace(0.0, 2.0, 20001)
    s = path.arc(u)
    assert s[0] == 0.0 and s[-1] == path.length
    assert np.all(np.diff(s) >= 0.0)
    grid = np.linspace(0.0, 1.0, 10001)
    steep = math.hypot(1.0, Lambda * float(np.max(delivery_laws.LAWS[law].dpsi(grid))))
    tol = 8 * EPS * path.length
    assert np.all(s >= x_max * u - tol) and np.all(s <= x_max * u * steep * (1 + 1e-9) + tol)
    back = path.position(s)
    slope = np.asarray(path.slope(u))
    assert np.all(np.abs(back - u) * slope <= 1e-12 * path.length + 4 * EPS * path.length)


# ----------------------------------------------------------------------------- four-bar classes
def crank_turns_fully(ground: float, crank: float, coupler: float, rocker: float) -> bool:
    """Whether the input link can make full turns: the dyad (coupler, rocker) closes for every
    distance |A - O2| in [|ground - crank|, ground + crank] (exact rational arithmetic)."""
    ground, crank, coupler, rocker = (Fraction(x) for x in (ground, crank, coupler, rocker))
    return ground + crank <= coupler + rocker and abs(ground - crank) >= abs(coupler - rocker)


@PROPS
@given(links=st.lists(st.floats(0.1, 10.0), min_size=4, max_size=4), perm=st.permutations(range(4)))
def test_grashof_class_is_geometric(links: list[float], perm: list[int]) -> None:
    """classify_fourbar agrees with geometry: away from the change-point tolerance, the input link
    turns fully exactly for 'crank-rocker' and 'double-crank'; Grashof-ness does not depend on
    which link is ground or input (only the label does)."""
    kind = classify_fourbar(*links)
    other = classify_fourbar(*(links[i] for i in perm))
    grashof = {'crank-rocker', 'rocker-crank', 'double-crank', 'double-rocker'}
    assert (kind in grashof) == (other in grashof) and (kind == 'change-point') == (other == 'change-point')
    srt = sorted(links)
    assume(abs((srt[0] + srt[3]) - (srt[1] + srt[2])) > 2 * GRASHOF_REL_TOL * sum(links))
    assert crank_turns_fully(*links) == (kind in ('crank-rocker', 'double-crank'))


# ----------------------------------------------------------------------------- RK4
@PROPS
@given(z=st.floats(0.01, 2.2), k=st.floats(0.1, 1e4), c=st.floats(-10, 10), y0=st.floats(-10, 10), n=st.integers(1, 60))
def test_rk4_on_a_linear_decay_is_the_exact_recurrence_with_monotone_dense_output(
    z: float, k: float, c: float, y0: float, n: int
) -> None:
    """y' = -k (y - c) with h = z / k: the steps are y_n = c + (y0 - c) R(z)^n (R the RK4 stability
    polynomial), and for z <= 2.2 the cubic Hermite dense output is monotone like the solution."""
    assume(abs(y0 - c) > 1e-3)
    h = z / k
    sol = ig.rk4(lambda t, y: -k * (y - c), (0.0, n * h), [y0], h)
    R = 1 - z + z * z / 2 - z**3 / 6 + z**4 / 24
    expect = c + (y0 - c) * R ** np.arange(sol.steps + 1)
    assert sol.steps == n
    assert np.allclose(sol.y[:, 0], expect, rtol=0.0, atol=16 * n * EPS * (abs(c) + abs(y0)))
    dense = sol.component(np.linspace(0.0, n * h, 50 * n + 1), 0)
    steps = np.diff(dense) * np.sign(c - y0)
    assert np.all(steps >= -16 * EPS * (abs(c) + abs(y0)))
