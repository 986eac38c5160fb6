"""The one-vehicle certificate's Taylor bound is a bound on the function it expands (issue 32).

:func:`iamp.planners.pmp.bounded.certify_global_one` bounds, on an interval ``|t' − t| ≤ δ``
of contact times, the dual function along a multiplier path from the centre's optimum,
:math:`f(t') = D(\\bar\\lambda + (t'-t)\\mu_3e_3; t') \\ge D(t) - |r|\\,|t'-t| - \\tfrac12 M (t'-t)^2`,
with ``M`` a bound of :math:`-f''` (one-sided: the term :math:`\\Phi u_\\lambda` counts with its
sign; the free-set term split at ``t'`` by the path).  Weak duality then gives
:math:`J_b \\ge f`.  The test in ``test_pmp_bounded.py`` checks the end result against
:math:`J_b`, which lies far above ``f`` away from the centre, so it cannot see a wrong
curvature term; this one computes ``f(t')`` itself (independent of the kernel:
``ψ(w) = ½u² − wu``, ``u = clip(w)``, exact Simpson per linear piece) and checks the expansion
at 41 contact times of the interval and the curvature bound ``M`` against second differences
of ``f`` (it fails for ``|Φu|`` in place of ``Φu``, for the largest instead of the least
``Φu``, for a free-set term without its ``(1 − θ)²`` side, or half the other side's).
"""

from __future__ import annotations

import numpy as np
from hypothesis import assume, given
from hypothesis import strategies as st
from test_pmp_bounded import SETTINGS, bounded_problems

from iamp.core.problem import Problem
from iamp.planners.pmp.bounded import _IntervalBound, input_box
from iamp.planners.pmp.saturated import contact_points, interval_terms
from iamp.planners.pmp.saturated_kernel import INTERVAL_WIDTH, POINT_WIDTH


def _dual(lam: tuple[float, float, float], tp: float, T: float, d: tuple[float, float, float], lo: float,
          hi: float) -> float:
    """:math:`D(\\lambda; t') = \\lambda^\\top d + \\int_0^T \\psi(w)`, ``w = λ₁(t'−τ)₊ + λ₂(T−τ) + λ₃``
    (physical units), exactly: ``w`` is linear between ``0``, ``t'``, ``T`` and the points where it
    meets ``ℓ`` or ``h``, so ``ψ(w(τ))`` is a quadratic there and Simpson's rule is exact."""
    def w(tau: float) -> float:
        return lam[0] * max(tp - tau, 0.0) + lam[1] * (T - tau) + lam[2]

    def psi(tau: float) -> float:
        x = w(tau)
        u = min(max(x, lo), hi)
        return 0.5 * u * u - x * u

    cuts = [0.0, tp, T]
    for p0, p1 in ((0.0, tp), (tp, T)):
        w0, w1 = w(p0), w(p1)
        for level in (lo, hi):
            if np.isfinite(level) and (w0 - level) * (w1 - level) < 0:
                cuts.append(p0 + (p1 - p0) * (level - w0) / (w1 - w0))
    cuts = sorted(cuts)
    total = lam[0] * d[0] + lam[1] * d[1] + lam[2] * d[2]
    for p0, p1 in zip(cuts[:-1], cuts[1:]):
        if p1 > p0:
            total += (p1 - p0) / 6 * (psi(p0) + 4 * psi(0.5 * (p0 + p1)) + psi(p1))
    return float(total)


@SETTINGS
@given(bounded_problems(), st.floats(0.05, 0.95), st.floats(0.005, 0.2))
def test_the_taylor_bound_is_below_the_fixed_multiplier_dual(problem: Problem, centre: float, width: float
                                                             ) -> None:
    T = float(problem.tf)
    a, b = max(1e-3 * T, (centre - width / 2) * T), min((1 - 1e-3) * T, (centre + width / 2) * T)
    ib = _IntervalBound(problem)
    raw = interval_terms([a, b], T, ib.pos, ib.der, ib.off[0], ib.off[1], ib.flat_data, [0.0] * 6, [0.0, 0.0],
                         ib.cddot_max[0])
    assume(raw[0] < 0)  # both axes converged
    _, dual, slope, M = raw[1:5]
    assert INTERVAL_WIDTH == 13
    mu3 = raw[11:13]  # the rate of the terminal-speed multiplier along the path, per axis
    t = 0.5 * (a + b)
    pts = contact_points([t], T, ib.pos, ib.off[0], ib.off[1], ib.flat_data, [0.0] * 6, [0.0, 0.0], False)
    ego = problem.ego
    boxes = input_box(problem)
    veh = problem.vehicles[0]
    h = 1e-3 * (b - a)
    taus = np.r_[np.linspace(a + h, b - h, 41), [t - h, t, t + h]]
    total = np.zeros_like(taus)
    for k, (s0, v0, sf, vf) in enumerate(((ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf))):
        o = k * POINT_WIDTH
        jump, wa, wb = pts[o + 3], pts[o + 4], pts[o + 5]
        lam1 = -jump
        lam2 = -wb - lam1  # b = −λ₁ − λ₂
        lam3 = wa - lam1 * t - lam2 * T  # a = λ₁t + λ₂T + λ₃
        lo, hi = boxes[k]
        for q, tp in enumerate(taus):
            c = float(veh.position(tp)) + veh.offset_x if k == 0 else veh.corner_y
            d = (c - s0 - v0 * tp, sf - s0 - v0 * T, vf - v0)
            total[q] += _dual((lam1, lam2, lam3 + (tp - t) * mu3[k]), float(tp), T, d, lo, hi)
    scale = max(1.0, abs(dual))
    # the reference reproduces D and |r| at the centre (the multipliers and the data are read right)
    assert abs(total[-2] - dual) <= 1e-9 * scale, (total[-2], dual)
    assert abs(abs(total[-1] - total[-3]) / (2 * h) - slope) <= 1e-5 * max(1.0, slope) + 1e-6 * scale / (b - a)
    # the expansion holds, and so does the curvature bound it rests on: −∂²D/∂t'² ≤ M (second
    # differences of the exact D over the interval)
    bound = dual - slope * np.abs(taus - t) - 0.5 * M * (taus - t) ** 2
    assert np.all(total >= bound - 1e-9 * scale), float(np.min(total - bound))
    D = total[:41]
    curv = -(D[2:] - 2 * D[1:-1] + D[:-2]) / (taus[1] - taus[0]) ** 2
    assert np.all(curv <= M * (1 + 1e-6) + 1e-6 * scale / (b - a) ** 2), (float(np.max(curv)), M)
