r"""The scalar core of the saturated axis solve (:mod:`~iamp.planners.pmp.saturated`).

One function, :func:`axis_core`, runs the semi-smooth Newton method on the concave dual of
one axis in the scaled units of :class:`~iamp.planners.pmp.saturated._Axis` (the module
docstring of :mod:`~iamp.planners.pmp.saturated` states the mathematics).  It is written as
flat scalar loops over lists (row-major ``n × n`` matrices in one list), with the
arithmetic of the former method-based code operation for operation, so that

* the pure path runs it as Python (the default; no object per piece, no ``g(τ)`` list per
  piece end, about 3× fewer interpreter operations than before, the same numbers bit for
  bit), and
* :func:`iamp.planners.pmp.compiled.load_axis` compiles the *same code objects* with
  ``numba.njit`` (no fastmath, :mod:`~iamp.planners.pmp.jit`) for an opt-in compiled path with
  the same numbers.

Nothing here may use Python features numba lacks (no classes, no exceptions, no
comprehensions with ``zip``, no ``sum``/``max`` over generators).
"""

from __future__ import annotations

import math
from typing import Any

from .jit import compilable

#: Result codes of :func:`axis_core`.
CONVERGED = 0
NOT_CONVERGED = 1
SINGULAR_GRAM = 2


@compilable
def gauss(A: Any, r: Any, n: int) -> tuple[bool, list[float]]:
    """Solve ``A x = r`` (``A`` row-major ``n × n``) by Gaussian elimination with partial
    pivoting (first largest pivot); ``(False, ·)`` if a pivot is exactly zero."""
    w = n + 1
    M = [0.0] * (n * w)
    for i in range(n):
        for j in range(n):
            M[i * w + j] = A[i * n + j]
        M[i * w + n] = r[i]
    x = [0.0] * n
    for c in range(n):
        p = c
        best = abs(M[c * w + c])
        for i in range(c + 1, n):
            v = abs(M[i * w + c])
            if v > best:
                p = i
                best = v
        if M[p * w + c] == 0.0:
            return False, x
        if p != c:
            for j in range(w):
                tmp = M[c * w + j]
                M[c * w + j] = M[p * w + j]
                M[p * w + j] = tmp
        inv = 1.0 / M[c * w + c]
        for i in range(c + 1, n):
            f = M[i * w + c] * inv
            if f != 0.0:
                for j in range(c, n + 1):
                    M[i * w + j] -= f * M[c * w + j]
    for i in range(n - 1, -1, -1):
        acc = M[i * w + n]
        for j in range(i + 1, n):
            acc -= M[i * w + j] * x[j]
        x[i] = acc / M[i * w + i]
    return True, x


@compilable
def base_values(sig: Any, base: Any, lam: Any) -> list[float]:
    """``w(τ_j) = Σ_i λ_i (σ_i − τ_j)_+ + λ_m (1 − τ_j) + λ_{m+1}`` at every base point ``τ_j``
    (the multiplier's linear function of :func:`pieces` and :func:`support`)."""
    m = len(sig)
    nb = len(base)
    wv = [0.0] * nb
    for j in range(nb):
        tau = base[j]
        acc = 0.0
        for i in range(m):
            gi = sig[i] - tau
            if gi < 0.0:
                gi = 0.0
            acc += lam[i] * gi
        acc += lam[m] * (1.0 - tau)
        acc += lam[m + 1] * 1.0
        wv[j] = acc
    return wv


@compilable
def pieces(sig: Any, base: Any, lam: Any, lo: float, hi: float) -> list[float]:
    """Sub-pieces of ``[0, 1]`` between base points and switching points: flat
    ``[τa, τb, wa, wb, kind, …]`` (kind ``0`` free, ``−1`` lower, ``+1`` upper)."""
    wv = base_values(sig, base, lam)
    nb = len(base)
    out: list[float] = []
    cuts = [0.0, 0.0, 0.0, 0.0]
    for j in range(nb - 1):
        ta = base[j]
        tb = base[j + 1]
        wa = wv[j]
        wb = wv[j + 1]
        cuts[0] = ta
        nc = 1
        for q in range(2):
            bnd = lo if q == 0 else hi
            if (wa - bnd) * (wb - bnd) < 0.0:
                c = ta + (tb - ta) * (bnd - wa) / (wb - wa)
                # insertion into the sorted cuts
                k = nc
                while k > 0 and cuts[k - 1] > c:
                    cuts[k] = cuts[k - 1]
                    k -= 1
                cuts[k] = c
                nc += 1
        cuts[nc] = tb
        for k in range(nc):
            a = cuts[k]
            b = cuts[k + 1]
            if b <= a:
                continue
            fa = wa + (wb - wa) * (a - ta) / (tb - ta)
            fb = wa + (wb - wa) * (b - ta) / (tb - ta)
            mid = 0.5 * (fa + fb)
            kind = -1.0 if mid <= lo else (1.0 if mid >= hi else 0.0)
            out.append(a)
            out.append(b)
            out.append(fa)
            out.append(fb)
            out.append(kind)
    return out


@compilable
def evaluate(sig: Any, base: Any, d: Any, lam: Any, lo: float, hi: float, hessian: bool
             ) -> tuple[list[float], float, list[float], list[float]]:
    """``(F, D, G_free, pieces)``: residuals ``∫g u − d̃``, dual value, free Gram matrix
    (row-major), the flat pieces of :func:`pieces`."""
    m = len(sig)
    n = m + 2
    F = [0.0] * n
    D = 0.0
    for k in range(n):
        F[k] = -d[k]
        D += lam[k] * d[k]
    G = [0.0] * (n * n)
    ps = pieces(sig, base, lam, lo, hi)
    ga = [0.0] * n
    gb = [0.0] * n
    for q in range(len(ps) // 5):
        a = ps[5 * q]
        b = ps[5 * q + 1]
        wa = ps[5 * q + 2]
        wb = ps[5 * q + 3]
        kind = ps[5 * q + 4]
        h = b - a
        if kind == 0.0:
            ua = wa
            ub = wb
        elif kind < 0.0:
            ua = lo
            ub = lo
        else:
            ua = hi
            ub = hi
        for i in range(m):
            x = sig[i] - a
            ga[i] = 0.0 if x < 0.0 else x
            y = sig[i] - b
            gb[i] = 0.0 if y < 0.0 else y
        ga[m] = 1.0 - a
        gb[m] = 1.0 - b
        ga[m + 1] = 1.0
        gb[m + 1] = 1.0
        um = 0.5 * (ua + ub)
        wm = 0.5 * (wa + wb)
        D += h / 6 * ((0.5 * ua * ua - wa * ua) + 4 * (0.5 * um * um - wm * um) + (0.5 * ub * ub - wb * ub))
        for k in range(n):
            F[k] += h / 6 * (2 * ga[k] * ua + ga[k] * ub + gb[k] * ua + 2 * gb[k] * ub)
        if hessian and kind == 0.0:
            for k in range(n):
                for l in range(k, n):
                    v = h / 6 * (2 * ga[k] * ga[l] + ga[k] * gb[l] + gb[k] * ga[l] + 2 * gb[k] * gb[l])
                    G[k * n + l] += v
                    if l != k:
                        G[l * n + k] += v
    return F, D, G, ps


@compilable
def max_abs(x: Any) -> float:
    """``max(abs(v) for v in x)`` (first maximum; ``x`` non-empty)."""
    r: float = abs(x[0])
    for k in range(1, len(x)):
        v = abs(x[k])
        if v > r:
            r = v
    return r


@compilable
def axis_core(sig: Any, base: Any, d: Any, lo: float, hi: float, lam0: Any, warm: bool, tol_residual: float,
              max_newton: int) -> tuple[int, int, float, float, float, list[float], list[float], list[float],
                                        list[float]]:
    """The semi-smooth Newton method of :func:`~iamp.planners.pmp.saturated.solve_axis`.

    Returns ``(code, iterations, residual, D, cost, lam, F, vcum_at_contact, pieces)``:
    ``code`` :data:`CONVERGED`, :data:`NOT_CONVERGED` (the caller looks for a Farkas
    certificate) or :data:`SINGULAR_GRAM`; ``cost`` = ``½∫ũ²`` and ``vcum_at_contact`` =
    ``∫_0^{σ_i} ũ`` (at the piece end nearest ``σ_i``), both scaled, at the returned ``lam``."""
    m = len(sig)
    n = m + 2
    lam = [0.0] * n
    if not warm:
        # unbounded optimum: the full Gram system ∫ g gᵀ λ = d̃ (closed form per piece)
        G0 = [0.0] * (n * n)
        ga = [0.0] * n
        gb = [0.0] * n
        for j in range(len(base) - 1):
            a = base[j]
            b = base[j + 1]
            for i in range(m):
                x = sig[i] - a
                ga[i] = 0.0 if x < 0.0 else x
                y = sig[i] - b
                gb[i] = 0.0 if y < 0.0 else y
            ga[m] = 1.0 - a
            gb[m] = 1.0 - b
            ga[m + 1] = 1.0
            gb[m + 1] = 1.0
            h = b - a
            for k in range(n):
                for l in range(n):
                    G0[k * n + l] += h / 6 * (2 * ga[k] * ga[l] + ga[k] * gb[l] + gb[k] * ga[l] + 2 * gb[k] * gb[l])
        ok, sol = gauss(G0, d, n)
        if not ok:
            return SINGULAR_GRAM, 0, math.nan, math.nan, math.nan, lam, lam, [0.0] * m, [0.0] * 0
        for k in range(n):
            lam[k] = sol[k]
    else:
        for k in range(n):
            lam[k] = lam0[k]
    F, D, G, ps = evaluate(sig, base, d, lam, lo, hi, True)
    it = 0
    res = max_abs(F)
    while res > tol_residual:
        if it >= max_newton:
            break
        it += 1
        trace = 0.0
        for k in range(n):
            trace += G[k * n + k]
        reg = 1e-14 * (trace if not (1e-300 > trace) else 1e-300)
        A = [0.0] * (n * n)
        for k in range(n):
            for l in range(n):
                A[k * n + l] = G[k * n + l] + (reg if k == l else 0.0)
        negF = [0.0] * n
        for k in range(n):
            negF[k] = -F[k]
        ok, step = gauss(A, negF, n)
        finite = ok
        if ok:
            for k in range(n):
                if not math.isfinite(step[k]):
                    finite = False
        if not finite:
            step = negF  # gradient ascent direction of D
        slope = 0.0
        for k in range(n):
            slope += step[k] * F[k]
        slope = -slope  # ∇Dᵀ step = −Fᵀ step  (> 0)
        alpha = 1.0
        accepted = False
        trial = [0.0] * n
        F2 = F
        D2 = D
        G2 = G
        ps2 = ps
        res2 = res
        for _ in range(40):
            for k in range(n):
                trial[k] = lam[k] + alpha * step[k]
            F2, D2, G2, ps2 = evaluate(sig, base, d, trial, lo, hi, True)
            res2 = max_abs(F2)
            if D2 >= D + 1e-4 * alpha * slope or res2 <= tol_residual:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        lam = trial
        F = F2
        D = D2
        G = G2
        ps = ps2
        res = res2
        if max_abs(lam) > 1e12:
            break
    code = CONVERGED if not (res > tol_residual) else NOT_CONVERGED
    # cost ½∫ũ² and ∫ũ up to every piece end (at lam)
    cost = 0.0
    npc = len(ps) // 5
    vcum = [0.0] * (npc + 1)
    ends = [0.0] * (npc + 1)
    for q in range(npc):
        a = ps[5 * q]
        b = ps[5 * q + 1]
        kind = ps[5 * q + 4]
        if kind == 0.0:
            ua = ps[5 * q + 2]
            ub = ps[5 * q + 3]
        elif kind < 0.0:
            ua = lo
            ub = lo
        else:
            ua = hi
            ub = hi
        cost += (b - a) / 6 * (ua * ua + ua * ub + ub * ub)
        vcum[q + 1] = vcum[q] + (b - a) * (ua + ub) / 2
        ends[q + 1] = b
    vc = [0.0] * m
    for i in range(m):
        j = 0
        dist = abs(ends[0] - sig[i])
        for q in range(1, npc + 1):
            e = abs(ends[q] - sig[i])
            if e < dist:
                j = q
                dist = e
        vc[i] = vcum[j]
    return code, it, res, D, cost, lam, F, vc, ps


@compilable
def farkas_margin(sig: Any, base: Any, d: Any, lo: float, hi: float, cand: Any) -> tuple[float, float]:
    """``(‖c‖, λ̂ᵀd̃ − σ(λ̂))`` for ``λ̂ = c/‖c‖`` (``margin`` NaN when ``‖c‖`` is zero or not
    finite): the Farkas test of :func:`~iamp.planners.pmp.saturated._raise_infeasible_or_stall`,
    with ``σ`` the exact support function of ``_Axis.support``, operation for operation."""
    n = len(cand)
    sq = 0.0
    for k in range(n):
        sq += cand[k] * cand[k]
    norm = math.sqrt(sq)
    if not norm > 0 or not math.isfinite(norm):
        return norm, math.nan
    direc = [0.0] * n
    for k in range(n):
        direc[k] = cand[k] / norm
    lin = 0.0
    for k in range(n):
        lin += direc[k] * d[k]
    return norm, lin - support(sig, base, direc, lo, hi)


@compilable
def support(sig: Any, base: Any, lam: Any, lo: float, hi: float) -> float:
    """``σ(λ) = ∫ max(h̃ w, ℓ̃ w) dτ`` (exact; ``inf`` when an infinite bound meets a nonzero
    ``w``): ``w`` is linear between the base points, cut where it changes sign."""
    wv = base_values(sig, base, lam)
    nb = len(base)
    total = 0.0
    cuts = [0.0, 0.0, 0.0]
    for j in range(nb - 1):
        ta = base[j]
        tb = base[j + 1]
        wa = wv[j]
        wb = wv[j + 1]
        cuts[0] = ta
        nc = 2
        if wa * wb < 0:
            cuts[1] = ta + (tb - ta) * (-wa) / (wb - wa)
            cuts[2] = tb
            nc = 3
        else:
            cuts[1] = tb
        for k in range(nc - 1):
            a = cuts[k]
            b = cuts[k + 1]
            fa = wa + (wb - wa) * (a - ta) / (tb - ta)
            fb = wa + (wb - wa) * (b - ta) / (tb - ta)
            mean = 0.5 * (fa + fb) * (b - a)
            if mean > 0:
                if not math.isfinite(hi):
                    return math.inf
                total += hi * mean
            elif mean < 0:
                if not math.isfinite(lo):
                    return math.inf
                total += lo * mean
    return total


@compilable
def poly_at(c: Any, x: float) -> float:
    """``numpy.polynomial.polynomial.polyval(x, c)`` for a float ``x``, operation for operation."""
    acc: float = c[len(c) - 1] + x * 0
    for i in range(2, len(c) + 1):
        acc = c[len(c) - i] + acc * x
    return acc


#: Values per axis and contact time in the output of :func:`contact_points`.
POINT_WIDTH = 11


@compilable
def axis_scale(d: Any, lo: float, hi: float, T: float) -> float:
    """The scale of one axis' system (:class:`~iamp.planners.pmp.saturated._Axis`'s, operation for
    operation): the largest of ``|d_q|`` (at least ``1e-300``) and the finite ``|ℓ| T²``, ``|h| T²``.

    Parameters
    ----------
    d : list of float
        The right-hand sides (corner offsets, terminal position and speed terms) [m].
    lo, hi : float
        The axis' input bounds (``±inf`` where unbounded) [m/s²].
    T : float
        The horizon [s].

    Returns
    -------
    float
        The scale [m].
    """
    scale = 1e-300
    for q in range(len(d)):
        if abs(d[q]) > scale:
            scale = abs(d[q])
    if math.isfinite(lo) and abs(lo) * T * T > scale:
        scale = abs(lo) * T * T
    if math.isfinite(hi) and abs(hi) * T * T > scale:
        scale = abs(hi) * T * T
    return scale


@compilable
def contact_points(ts: Any, T: float, T2: float, T3: float, pos: Any, off_x: float, off_y: float, data: Any,
                   warm: Any, has_warm: Any, retry_cold: bool, tol_residual: float, max_newton: int) -> list[float]:
    """Both axes of the one-vehicle bounded problem at every contact time of ``ts``.

    ``T2``, ``T3`` are ``T**2``, ``T**3`` as Python computes them; ``data`` holds
    ``(s0, v0, sf, vf, ℓ, h)`` of x then y; ``pos`` the coefficients of ``x_s`` (ascending),
    ``off_x``/``off_y`` the corner's offsets; ``warm`` three scaled multipliers per point and axis,
    used where ``has_warm`` (per point and axis) is non-zero; ``retry_cold``: a warm start that
    fails is retried from the unbounded optimum.  The scaling is
    :class:`~iamp.planners.pmp.saturated._Axis`'s and the physical values those of
    :func:`~iamp.planners.pmp.saturated.solve_axis_value` and ``_axis_solution``, operation for
    operation.  Returns per point and axis :data:`POINT_WIDTH` values: result code, dual value,
    cost, jump ``Φ``, ``a``, ``b`` (of ``w = −p_v``), ``v(t)``, the three scaled multipliers,
    and ``|∫u − (v_f − v_0)|`` (the terminal speed residual of the multipliers' law, physical).
    Where the code is :data:`NOT_CONVERGED`, the second to fourth values are instead the
    Farkas test of :func:`~iamp.planners.pmp.saturated.solve_axis` (``1`` when a certificate
    was found, its margin and its ramp multiplier in physical units, as ``AxisInfeasible``'s
    ``margin_phys`` and ``lam_phys[0]``), zeros where none was.
    """
    out = [0.0] * (len(ts) * 2 * POINT_WIDTH)
    for p in range(len(ts)):
        t = ts[p]
        for k in range(2):
            s0 = data[6 * k]
            v0 = data[6 * k + 1]
            sf = data[6 * k + 2]
            vf = data[6 * k + 3]
            lo = data[6 * k + 4]
            hi = data[6 * k + 5]
            c = poly_at(pos, t) + off_x if k == 0 else off_y
            d = [c - s0 - v0 * t, sf - s0 - v0 * T, (vf - v0) * T]
            scale = axis_scale(d, lo, hi, T)
            for q in range(3):
                d[q] = d[q] / scale
            los = lo * T * T / scale
            his = hi * T * T / scale
            sg = t / T
            sig = [sg]
            base = [0.0, sg, 1.0] if 0.0 < sg < 1.0 else [0.0, 1.0]
            use = has_warm[2 * p + k] != 0.0
            lam0 = [0.0, 0.0, 0.0]
            for q in range(3):
                lam0[q] = warm[6 * p + 3 * k + q]
            code, _, _, D, cost, lam, F, vc, _ = axis_core(sig, base, d, los, his, lam0, use, tol_residual,
                                                          max_newton)
            if code != CONVERGED and use and retry_cold:
                code, _, _, D, cost, lam, F, vc, _ = axis_core(sig, base, d, los, his, lam0, False, tol_residual,
                                                              max_newton)
            o = (2 * p + k) * POINT_WIDTH
            out[o] = float(code)
            if code == NOT_CONVERGED:
                # the Farkas test of saturated._raise_infeasible_or_stall: along lam, then along -F
                for c_k in range(2):
                    cand = [0.0] * 3
                    for q in range(3):
                        cand[q] = lam[q] if c_k == 0 else -F[q]
                    norm, margin = farkas_margin(sig, base, d, los, his, cand)
                    if not norm > 0 or not math.isfinite(norm):
                        continue
                    if margin > 1e-9:
                        out[o + 1] = 1.0
                        out[o + 2] = margin * scale * scale / T3
                        out[o + 3] = cand[0] / norm * scale / T3
                        break
            if code == CONVERGED:
                lam_ramp = lam[0] * scale / T3
                lam_lin = lam[1] * scale / T3
                lam_c = lam[2] * scale / T2
                out[o + 1] = D * scale * scale / T3
                out[o + 2] = cost * scale * scale / T3
                out[o + 3] = -(lam[0] * scale / T3)
                out[o + 4] = lam_ramp * (sg * T) + lam_lin * T + lam_c
                out[o + 5] = -lam_ramp - lam_lin
                out[o + 6] = v0 + vc[0] * scale / T
                out[o + 10] = abs(F[2]) * scale / T
            out[o + 7] = lam[0]
            out[o + 8] = lam[1]
            out[o + 9] = lam[2]
    return out


@compilable
def free_measure(wa: float, wb: float, lo: float, hi: float, t: float, delta: float, phi: float, b: float) -> float:
    r"""A bound of the time, within ``[0, t']``, where ``u_λ(·; t')`` is not saturated, for every
    ``t'`` with :math:`|t' - t| \le \delta` (``t' \le b``): a term of the certificate's ``M``
    (:func:`iamp.planners.pmp.bounded.certify_global_one`).

    Before ``min(t, t')`` the law is :math:`w(\tau; t') = w_a + w_b\tau \pm \Phi(t' - t)`, so it
    is free only where :math:`w_a + w_b\tau \in (\ell - |\Phi|\delta, h + |\Phi|\delta)`, a
    sub-interval of ``[0, t]`` whose length is exact for a line; at most ``δ`` more lies between
    ``t`` and ``t'``.  Widened by a relative ``1e-9`` (rounding) and never above ``b``."""
    lo_w = lo - phi * delta
    hi_w = hi + phi * delta
    if not (math.isfinite(lo_w) and math.isfinite(hi_w) and math.isfinite(wa) and math.isfinite(wb)):
        return b
    if wb == 0.0:
        inside = t if lo_w < wa < hi_w else 0.0
    else:
        e1 = (lo_w - wa) / wb
        e2 = (hi_w - wa) / wb
        t1 = e1 if e1 < e2 else e2
        t2 = e2 if e1 < e2 else e1
        # max(0.0, min(t, t2) - max(0.0, t1)), each as Python's min/max picks
        upper = t2 if t2 < t else t
        lower = t1 if t1 > 0.0 else 0.0
        inside = upper - lower
        if not inside > 0.0:
            inside = 0.0
    bound = inside * (1.0 + 1e-9) + 1e-9 * b + delta
    return bound if bound < b else b


#: Values per interval in the output of :func:`interval_terms`.
INTERVAL_WIDTH = 13


@compilable
def interval_terms(ab: Any, T: float, T2: float, T3: float, pos: Any, der: Any, off_x: float, off_y: float,
                   data: Any, warm: Any, has_warm: Any, cddot_x: float, tol_residual: float,
                   max_newton: int) -> list[float]:
    r"""The certificate's bound terms on every interval ``[a, b]`` of ``ab`` (flat ``a, b, …``):
    both axes at the centre ``t`` in one :func:`contact_points` call (warm as there, no cold
    retry), then per interval :data:`INTERVAL_WIDTH` values: the first axis that did not
    converge (``-1`` if none; the others are then left zero), the bound
    :math:`D - |r|\delta - \tfrac12 M\delta^2`, ``D``, ``|r|``, ``M``, the three scaled
    multipliers of x and of y (those of the axes before a failing one), and per axis the rate
    ``μ₃`` (physical) of the multiplier path the bound follows.

    The bound is that of :math:`f(t') = D(\bar\lambda + (t'-t)\,\mu_3 e_3;\ t')` (weak duality
    holds for every multiplier, so :math:`J_b(t') \ge f(t')`): moving the multiplier of the
    terminal speed by :math:`\mu_3 = \theta\Phi` as the ramp moves shifts the law on both sides
    of the contact time, and the curvature's free-set term
    :math:`\Phi^2|F\cap[0,t']|` becomes
    :math:`\Phi^2\big((1-\theta)^2|F\cap[0,t']| + \theta^2|F\cap[t',T]|\big)`, least at
    :math:`\theta = \bar\mu_L/(\bar\mu_L + \bar\mu_R)` (:func:`free_measure` on each side;
    ``θ = 0`` is the fixed-multiplier bound).  The slope adds :math:`|\mu_3|` times the terminal
    speed residual of :func:`contact_points`."""
    n = len(ab) // 2
    ts = [0.0] * n
    for q in range(n):
        ts[q] = 0.5 * (ab[2 * q] + ab[2 * q + 1])
    raw = contact_points(ts, T, T2, T3, pos, off_x, off_y, data, warm, has_warm, False, tol_residual, max_newton)
    W = POINT_WIDTH
    out = [0.0] * (n * INTERVAL_WIDTH)
    for q in range(n):
        a = ab[2 * q]
        b = ab[2 * q + 1]
        t = ts[q]
        delta = 0.5 * (b - a)
        c0 = poly_at(der, t)
        dual = 0.0
        slope = 0.0
        slack = 0.0
        curv = 0.0
        bad = -1
        r = q * INTERVAL_WIDTH
        for k in range(2):
            o = (2 * q + k) * W
            if raw[o] != 0.0:
                bad = k
                break
            lo = data[6 * k + 4]
            hi = data[6 * k + 5]
            jump = raw[o + 3]
            wa = raw[o + 4]
            wb = raw[o + 5]
            speed = raw[o + 6]
            phi = abs(jump)
            # the free time before and after t' (the law moves by at most |Φ| |t' − t| on each
            # side for any θ in [0, 1]); the side after t' mirrored (τ → T − τ) onto the form of
            # free_measure, with the post-contact line w_a + Φ t + (w_b − Φ) τ
            mu_l = free_measure(wa, wb, lo, hi, t, delta, phi, b)
            mu_r = free_measure(wa + jump * t + (wb - jump) * T, jump - wb, lo, hi, T - t, delta, phi, T - a)
            theta = mu_l / (mu_l + mu_r) if mu_l + mu_r > 0.0 else 0.0
            mu3 = theta * jump
            # u_λ(t'; t') = clip(w_a + w_b t' − Φ (t' − t) + μ₃ (t' − t)): monotone in t', so Φ u_λ
            # is least at an end
            u0 = wa + wb * a - jump * (a - t) + mu3 * (a - t)
            u1 = wa + wb * b - jump * (b - t) + mu3 * (b - t)
            u0 = lo if u0 < lo else (hi if u0 > hi else u0)
            u1 = lo if u1 < lo else (hi if u1 > hi else u1)
            pu = jump * u0 if jump * u0 < jump * u1 else jump * u1
            dual += raw[o + 1]
            slope += jump * (speed - (c0 if k == 0 else 0.0))
            slack += abs(mu3) * raw[o + 10]
            # f'' = −Φ c̈ + Φ u_λ(t'; t') − Φ² ((1 − θ)² |F ∩ [0, t']| + θ² |F ∩ [t', T]|) ≥ this
            # axis' term (certify_global_one)
            curv += pu - phi * ((cddot_x if k == 0 else 0.0)
                                + phi * ((1.0 - theta) * (1.0 - theta) * mu_l + theta * theta * mu_r))
            out[r + 11 + k] = mu3
            out[r + 5 + 3 * k] = raw[o + 7]
            out[r + 6 + 3 * k] = raw[o + 8]
            out[r + 7 + 3 * k] = raw[o + 9]
        out[r] = float(bad)
        M = -curv if curv < 0.0 else 0.0
        if bad < 0:
            rate = abs(slope) + slack
            out[r + 1] = dual - rate * delta - 0.5 * M * delta * delta
            out[r + 2] = dual
            out[r + 3] = rate
            out[r + 4] = M
    return out


@compilable
def cover_points(times: Any, corners: Any, m: int, T: float, T2: float, T3: float, data: Any,
                 tol_residual: float, max_newton: int) -> list[float]:
    """Both axes at many choices of ``m`` contact times, cold, with the Farkas test: what the
    several-vehicle cover of :func:`iamp.planners.pmp.bounded._cover_infeasible` asks of
    :func:`~iamp.planners.pmp.saturated.solve_axis` per box centre, operation for operation
    (``_Axis``'s scaling, ``axis_core`` from the unbounded optimum, then
    ``_raise_infeasible_or_stall``'s test along ``λ`` and along ``−F``).

    ``times`` holds ``m`` contact times per point (distinct within a point), ``corners`` the
    ``m`` corner positions of x then the ``m`` of y per point, ``data`` ``(s0, v0, sf, vf, ℓ, h)``
    of x then y, ``T2``, ``T3`` ``T**2``, ``T**3`` as Python computes them.  Returns per point and
    axis ``m + 3`` values: ``0`` converged, ``1`` a Farkas certificate (then its physical margin
    and the physical multipliers of the ``m`` ramps follow, as ``AxisInfeasible``'s
    ``margin_phys`` and ``lam_phys[:m]``), ``2`` neither (a stall or a singular system)."""
    n = len(times) // m
    width = m + 2
    out = [0.0] * (n * 2 * (m + 3))
    for p in range(n):
        for k in range(2):
            s0 = data[6 * k]
            v0 = data[6 * k + 1]
            sf = data[6 * k + 2]
            vf = data[6 * k + 3]
            lo = data[6 * k + 4]
            hi = data[6 * k + 5]
            d = [0.0] * width
            for i in range(m):
                d[i] = corners[(2 * p + k) * m + i] - s0 - v0 * times[p * m + i]
            d[m] = sf - s0 - v0 * T
            d[m + 1] = (vf - v0) * T
            scale = axis_scale(d, lo, hi, T)
            for q in range(width):
                d[q] = d[q] / scale
            los = lo * T * T / scale
            his = hi * T * T / scale
            sig = [0.0] * m
            for i in range(m):
                sig[i] = times[p * m + i] / T
            # sorted(set([0.0, 1.0] + [s for s in sig if 0 < s < 1]))
            inner = [0.0] * 0
            for i in range(m):
                s = sig[i]
                if 0.0 < s < 1.0:
                    seen = False
                    for x in inner:
                        if x == s:
                            seen = True
                    if not seen:
                        inner.append(s)
            inner.sort()
            base = [0.0] * (len(inner) + 2)
            for i in range(len(inner)):
                base[i + 1] = inner[i]
            base[len(inner) + 1] = 1.0
            lam0 = [0.0] * width
            code, _, _, _, _, lam, F, _, _ = axis_core(sig, base, d, los, his, lam0, False, tol_residual, max_newton)
            o = (2 * p + k) * (m + 3)
            if code == CONVERGED:
                continue
            out[o] = 2.0
            if code == SINGULAR_GRAM:
                continue
            for c_k in range(2):
                cand = [0.0] * width
                for q in range(width):
                    cand[q] = lam[q] if c_k == 0 else -F[q]
                norm, margin = farkas_margin(sig, base, d, los, his, cand)
                if not norm > 0 or not math.isfinite(norm):
                    continue
                if margin > 1e-9:
                    out[o] = 1.0
                    out[o + 1] = margin * scale * scale / T3
                    for i in range(m):
                        out[o + 2 + i] = cand[i] / norm * scale / T3
                    break
    return out
