r"""Certified infeasibility beyond an edge of the feasible contact times (one vehicle, one axis).

At a contact time ``t`` the axis' equalities (``s(0), v(0), s(T), v(T)`` and the corner
``s(t) = c(t)``) are linear functionals of ``u``: :math:`\int_0^T g_k u = d_k(t)` with
:math:`g = ((t-\tau)_+, T-\tau, 1)` (:mod:`iamp.planners.pmp.saturated`).  For any
:math:`\lambda`, a plan in the box would give :math:`\lambda^\top d = \int w u \le
\sigma(\lambda) = \int \max(h w, \ell w)` (:math:`w = \lambda^\top g`), so

.. math::  m(\lambda; t) = \lambda^\top d(t) - \sigma(\lambda; t) > 0

proves that no input in the box meets the corner at ``t`` (Farkas).  With
:math:`\lambda_1 = \varepsilon = \pm 1` fixed, ``m`` is concave in :math:`(\lambda_2,
\lambda_3)`, and its maximum is how far the corner lies above (``ε = +1``) or below
(``ε = −1``) the positions the double integrator can reach at ``t`` under the box and the
boundary conditions (the reachable interval's end, an LP whose dual this is).  It is found
here directly (:func:`farkas_direction`: the best ``λ3`` for each ``λ2`` in closed form, ``λ2``
by bisection on the sign of the slope; ``u*`` is bang-bang on the sign of ``w``), not by the
dual Newton method of the saturated solve, which stalls within about ``1e-7 t_f`` of an edge
without a divergent direction (the maximum is often a kink, ``w`` vanishing on a whole piece).

**Interval bound.**  At fixed :math:`\lambda`, :math:`\partial_t m = \varepsilon(\dot c(t) -
v_0 - \int_0^t u^*(\tau; t)\,d\tau)`; moving ``t`` by ``s`` shifts ``w`` by :math:`\varepsilon s`
before ``t``, so ``u*`` changes only where :math:`|w| \le |s|`
(:func:`~iamp.planners.pmp.saturated_kernel.free_measure`) and on the ``|s|`` between the two
times:

.. math::  |\partial_t m(t+s) - \partial_t m(t)| \le D(\delta) = (\max|\ddot c| + U)\,\delta
           + (h - \ell)\,\mu(\delta),\qquad |s| \le \delta,

hence :math:`m(t+s) \ge m(t) + \partial_t m(t)\,s - |s|\,D(|s|)`.  :func:`edge_cover` steps
from a point where ``m > 0`` outward, each step the longest ``δ`` (halving) on which that lower
bound stays positive, re-maximising ``λ`` at every step: near the edge ``m`` grows linearly
while ``D(δ)δ`` is quadratic, so the steps are macroscopic right from the edge.

All quantities are in the axis' scaled units (time over ``T``, lengths over ``ℓ``; the
``λ`` of this module do not depend on ``ℓ``).
"""

from __future__ import annotations

import math
from typing import Any

from .saturated_kernel import axis_scale, free_measure, poly_at, support

#: Bracket doublings of :func:`farkas_direction` (and half its bisection steps).
MAX_STEPS = 50


def _terms(sig: float, d: list[float], lo: float, hi: float, eps: float, x2: float, x3: float
           ) -> tuple[float, list[float], float]:
    """``(m, ∇m, ∫_0^σ u*)`` at ``λ = (ε, x2, x3)``, ``∇`` over ``(λ2, λ3)`` (``u*`` = ``h``
    where ``w > 0``, ``ℓ`` where ``w < 0``; ``m`` with the exact support function of
    :func:`~iamp.planners.pmp.saturated_kernel.support`)."""
    lam = [eps, x2, x3]
    m = eps * d[0] + x2 * d[1] + x3 * d[2] - support([sig], [0.0, sig, 1.0] if 0.0 < sig < 1.0 else [0.0, 1.0],
                                                   lam, lo, hi)
    grad = [d[1], d[2]]
    before = 0.0  # ∫_0^σ u*
    # w = α + βτ on [0, σ] and on [σ, 1]
    for a, b, alpha, beta in ((0.0, sig, eps * sig + x2 + x3, -(eps + x2)), (sig, 1.0, x2 + x3, -x2)):
        if not b > a:
            continue
        cuts = [a, b]
        if beta != 0.0:
            theta = -alpha / beta
            if a < theta < b:
                cuts = [a, theta, b]
        for q in range(len(cuts) - 1):
            p, r = cuts[q], cuts[q + 1]
            w_mid = alpha + beta * 0.5 * (p + r)
            u = hi if w_mid > 0 else (lo if w_mid < 0 else 0.0)
            grad[0] -= u * ((r - p) - 0.5 * (r * r - p * p))
            grad[1] -= u * (r - p)
            if b <= sig:
                before += u * (r - p)
    return m, grad, before


def _above(alpha: float, beta: float, a: float, b: float, level: float) -> float:
    """The measure of ``{τ ∈ [a, b]: α + βτ > level}``."""
    if beta == 0.0:
        return b - a if alpha > level else 0.0
    theta = (level - alpha) / beta
    theta = a if theta < a else (b if theta > b else theta)
    return b - theta if beta > 0 else theta - a


def _best_x3(sig: float, d3: float, lo: float, hi: float, eps: float, x2: float) -> float:
    r"""The ``λ3`` that maximises ``m`` at fixed ``λ2`` (exact): ``∂m/∂λ3 = d̃_3 − ∫u*`` vanishes
    where the time with :math:`w > 0` is :math:`p = (\tilde d_3 - \ell)/(h - \ell)`; that time
    is piecewise linear in ``λ3`` between the values of ``−w`` at ``0, σ, 1`` (a clamped end
    where ``p`` is out of ``[0, 1]``)."""
    pieces = ((0.0, sig, eps * sig + x2, -(eps + x2)), (sig, 1.0, x2, -x2))
    p = (d3 - lo) / (hi - lo)

    def P(x3: float) -> float:
        return sum(_above(al, be, a, b, -x3) for a, b, al, be in pieces if b > a)

    levels = sorted({-(al + be * a) for a, b, al, be in pieces} | {-(al + be * b) for a, b, al, be in pieces})
    prev_x, prev_p = levels[0], P(levels[0])
    if p <= prev_p:
        return prev_x
    for x3 in levels[1:]:
        cur = P(x3)
        if cur >= p:
            return prev_x + (x3 - prev_x) * (p - prev_p) / (cur - prev_p) if cur > prev_p else x3
        prev_x, prev_p = x3, cur
    return levels[-1]


def farkas_direction(sig: float, d: list[float], lo: float, hi: float, eps: float, x: list[float]
                     ) -> tuple[float, list[float], float]:
    """The ``(λ2, λ3)`` that maximise the concave ``m(ε, λ2, λ3; σ)`` (module docstring): for
    each ``λ2`` the best ``λ3`` exactly (:func:`_best_x3`), and ``λ2`` by bisection on the sign
    of ``∂m/∂λ2`` there (the function of ``λ2`` is concave; its maximum may be a kink, where
    ``w`` vanishes on a whole piece), bracketed by doubling from ``x[0]``.

    Parameters
    ----------
    sig : float
        Contact time over ``T``, in ``(0, 1)``.
    d : list of float
        The scaled right-hand sides ``d̃`` at ``sig`` (corner, terminal position, terminal speed).
    lo, hi : float
        The scaled input bounds (finite, ``lo < hi``).
    eps : float
        ``λ_1``: ``+1`` (corner above the reachable positions) or ``−1`` (below).
    x : list of float
        The start ``(λ2, λ3)`` (only ``λ2`` is used).

    Returns
    -------
    tuple
        ``(m, [λ2, λ3], ∫_0^σ u*)`` at the best point found.
    """
    def slope(x2: float) -> float:
        return _terms(sig, d, lo, hi, eps, x2, _best_x3(sig, d[2], lo, hi, eps, x2))[1][0]

    a = b = float(x[0]) if math.isfinite(x[0]) else 0.0
    ga = gb = slope(a)
    width = 1.0
    for _ in range(MAX_STEPS):  # bracket: slope(a) > 0 > slope(b)
        if (ga > 0 and gb < 0) or ga == 0.0 or gb == 0.0:
            break
        if ga <= 0:
            a -= width
            ga = slope(a)
        if gb >= 0:
            b += width
            gb = slope(b)
        width *= 2.0
    if ga == 0.0:
        b = a
    elif gb == 0.0:
        a = b
    for _ in range(2 * MAX_STEPS):
        mid = 0.5 * (a + b)
        if not (a < mid < b):
            break
        gm = slope(mid)
        if gm > 0:
            a = mid
        elif gm < 0:
            b = mid
        else:
            a = b = mid
    best: tuple[float, list[float], float] = (-math.inf, [a, 0.0], 0.0)
    for x2 in (a, b):
        x3 = _best_x3(sig, d[2], lo, hi, eps, x2)
        m, _, before = _terms(sig, d, lo, hi, eps, x2, x3)
        if m > best[0]:
            best = (m, [x2, x3], before)
    return best


class AxisReach:
    """One axis of a one-vehicle problem in the scaled units of :mod:`iamp.planners.pmp.saturated`
    (time over ``T``; lengths over the axis' scale at a reference contact time ``t_ref``)."""

    def __init__(self, T: float, data: tuple[float, float, float, float, float, float], pos: list[float],
                 der: list[float], offset: float, moving: bool, cddot_max: float, t_ref: float):
        self.T = T
        self.s0, self.v0, self.sf, self.vf, lo, hi = data
        self.pos, self.der, self.offset, self.moving = pos, der, offset, moving
        self.ell = axis_scale(self._d(t_ref), lo, hi, T)
        self.lo, self.hi = lo * T * T / self.ell, hi * T * T / self.ell
        self.cddot = cddot_max * T * T / self.ell if moving else 0.0

    def _d(self, t: float) -> list[float]:
        c = (poly_at(self.pos, t) + self.offset) if self.moving else self.offset
        return [c - self.s0 - self.v0 * t, self.sf - self.s0 - self.v0 * self.T, (self.vf - self.v0) * self.T]

    def d(self, sig: float) -> list[float]:
        """``d̃`` at ``σ``."""
        return [x / self.ell for x in self._d(sig * self.T)]

    def d1_rate(self, sig: float) -> float:
        """``dd̃_1/dσ = T (ċ − v_0)/ℓ``."""
        cdot = poly_at(self.der, sig * self.T) if self.moving else 0.0
        return self.T * (cdot - self.v0) / self.ell

    def margin(self, sig: float, eps: float, x: list[float]) -> tuple[float, list[float], float, float]:
        """``(m, [λ2, λ3], ∂m/∂σ, floor)`` at ``σ`` with the best ``λ`` from ``x``
        (:func:`farkas_direction`); ``m > floor`` (a bound of its rounding) certifies ``σ``.

        Parameters
        ----------
        sig : float
            Contact time over ``T``.
        eps : float
            ``λ_1`` (``±1``).
        x : list of float
            Start of ``(λ2, λ3)``.

        Returns
        -------
        tuple
            ``m``, the multipliers, the slope of ``m`` in ``σ`` at fixed multipliers, the floor.
        """
        d = self.d(sig)
        m, x, before = farkas_direction(sig, d, self.lo, self.hi, eps, x)
        U = max(abs(self.lo), abs(self.hi))
        floor = 1e-12 * (1.0 + abs(x[0]) + abs(x[1])) * (1.0 + abs(d[0]) + abs(d[1]) + abs(d[2]) + U)
        return m, x, eps * (self.d1_rate(sig) - before), floor

    def drift(self, sig: float, eps: float, x: list[float], delta: float) -> float:
        """``D(δ)`` (module docstring), widened by a relative ``1e-9``: at fixed ``λ = (ε, x)``,
        ``|∂m/∂σ(σ + s) − ∂m/∂σ(σ)| <= D(δ)`` for every ``|s| <= δ``.

        Parameters
        ----------
        sig : float
            Contact time over ``T``.
        eps : float
            ``λ_1`` (``±1``).
        x : list of float
            ``(λ2, λ3)``.
        delta : float
            The half-width ``δ`` (over ``T``).

        Returns
        -------
        float
            The bound.
        """
        U = max(abs(self.lo), abs(self.hi))
        wa, wb = eps * sig + x[0] + x[1], -(eps + x[0])  # w on [0, σ]
        D = (self.cddot + U) * delta + (self.hi - self.lo) * free_measure(wa, wb, 0.0, 0.0, sig, delta, 1.0, 1.0)
        return D * (1.0 + 1e-9)


def _step(axis: AxisReach, eps: float, x: list[float], s: float, side: float, end: float
          ) -> tuple[float, list[float]]:
    """The longest ``δ`` (halving from ``|end − s|``) with ``[s, s + side·δ]`` certified by one
    axis and sign at ``s`` (module docstring's bound), ``0`` if none; and the multipliers."""
    m, x, rate, floor = axis.margin(s, eps, x)
    if not m > floor:
        return 0.0, x
    rate *= side  # side · ∂m/∂σ
    delta = abs(end - s)
    while delta > 1e-12 and not m + delta * (rate - axis.drift(s, eps, x, delta)) > floor:
        delta *= 0.5
    return (delta if delta > 1e-12 else 0.0), x


def edge_cover(axes: list[AxisReach], start: float, side: float, warm: list[Any] | None = None,
               max_steps: int = 200, limit: float | None = None) -> tuple[float, int, int]:
    """Contact times (over ``T``) from ``start`` towards ``side`` (``+1`` up to ``1``, ``−1``
    down to ``0``) at which no input in the box meets some axis' corner (module docstring):
    each step the longest ``δ`` certified by the axis and sign of the step before, or, where
    that falls below half its last step (its margin nears zero, perhaps where the other axis'
    corner goes out of reach), by the best of all four.

    Parameters
    ----------
    axes : list of AxisReach
        The axes (those with an infinite or empty box are skipped).
    start : float
        The first contact time over ``T``; the cover starts only where some ``m > 0`` there.
    side : float
        ``+1`` or ``−1``.
    warm : list, optional
        Per axis scaled multipliers ``(λ1, λ2, λ3)`` or ``None`` (their ``λ2`` over ``|λ1|``
        starts the bracket of :func:`farkas_direction`).
    max_steps : int
        Margins evaluated (each one :func:`farkas_direction`) before giving up.
    limit : float, optional
        Where to stop (over ``T``; default the end of ``(0, 1)`` on ``side``).

    Returns
    -------
    tuple
        ``(reached, axis, steps)``: every ``σ`` between ``start`` and ``reached`` is certified
        infeasible (``reached == start`` and ``axis == −1`` when nothing was; ``axis`` is the
        first step's).
    """
    end = (1.0 if side > 0 else 0.0) if limit is None else limit
    combos = [(k, eps) for k, ax in enumerate(axes) if ax.lo < ax.hi and math.isfinite(ax.lo)
              and math.isfinite(ax.hi) for eps in (1.0, -1.0)]
    xs: dict[tuple[int, float], list[float]] = {}
    for k, eps in combos:
        lam = warm[k] if warm is not None and k < len(warm) else None
        ok = lam is not None and len(lam) == 3 and lam[0] != 0.0 and math.isfinite(lam[0])
        xs[(k, eps)] = [lam[1] / abs(lam[0]), lam[2] / abs(lam[0])] if ok and lam is not None else [0.0, 0.0]
    s, steps, first = start, 0, -1
    cur: tuple[int, float] | None = None
    prev = math.inf
    while steps < max_steps and s != end:
        best, best_c = 0.0, cur
        for c in ([cur] if cur is not None else []) + [c for c in combos if c != cur]:
            if steps >= max_steps:
                break
            steps += 1
            delta, xs[c] = _step(axes[c[0]], c[1], xs[c], s, side, end)
            if delta > best:
                best, best_c = delta, c
            if c == cur and delta >= 0.5 * prev:
                break
        if not best > 0.0 or best_c is None:
            break
        if first < 0:
            first = best_c[0]
        cur, prev = best_c, best
        s = end if best >= abs(end - s) else s + side * best
    return s, first, steps


def cover_interval(axes: list[AxisReach], a: float, b: float, max_steps: int = 60) -> tuple[float, float, int]:
    """The part of ``[a, b]`` (over ``T``) around its centre certified infeasible: if the centre
    is, :func:`edge_cover` from it towards both ends.  Returns ``(lo, hi, steps)``: ``[lo, hi]``
    is certified (``lo > hi`` when nothing is).

    Parameters
    ----------
    axes : list of AxisReach
        The two axes.
    a, b : float
        The interval (over ``T``).
    max_steps : int
        Margins evaluated per direction.

    Returns
    -------
    tuple
        ``(lo, hi, steps)``.
    """
    c = 0.5 * (a + b)
    hi, k, up = edge_cover(axes, c, 1.0, None, max_steps, b)
    if k < 0:
        return 1.0, 0.0, up
    lo, _, down = edge_cover(axes, c, -1.0, None, max_steps, a)
    return lo, hi, up + down
