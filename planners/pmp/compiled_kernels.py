r"""numba kernels of the contact-time search: the value function, its gradient, the box
lower bound, the basin box, damped Newton and the branch-and-bound loop, one scalar box at
a time (``pip install iamp[fast]``).  All in one file on purpose: numba's on-disk cache is
invalidated per source file, so a caller compiled from another file could outlive a
changed kernel.

Each function is the loop form of its numpy twin, with the same equations and the same
order of operations where it matters (:func:`iamp.planners.pmp.fixed.ValueFunction.quad_sigma`,
:func:`~iamp.planners.pmp.fixed.ValueFunction.gradient_sigma`,
:func:`iamp.planners.pmp.bound.lower_bound`, :func:`iamp.planners.pmp.basin.basin_box`); see
those docstrings for the mathematics; the loop is
:func:`iamp.planners.pmp.search.global_search` with
:func:`iamp.planners.pmp.bound.branch_and_bound` (same order of boxes).  Scaled units
(``t_f = 1``).  Small dense solves use Gaussian elimination with partial pivoting instead
of LAPACK, so numbers agree with the numpy path to rounding, not bit for bit.

This module imports numba at import time: import it only through
:mod:`iamp.planners.pmp.compiled_search`.
"""

from __future__ import annotations

import numba
import numpy as np

from .basin import BOX_BOUND_MAX_M, K_BELOW, K_DIAG, ROUNDING_REL
from .bound import _DK_ABOVE, _DK_BELOW, _DKDIAG

jit = numba.njit(cache=True, error_model="numpy", nogil=True)


@jit
def horner(C, x):  # type: ignore[no-untyped-def]
    """``Σ_k C[k] x^k``."""
    y = C[C.size - 1]
    for k in range(C.size - 2, -1, -1):
        y = y * x + C[k]
    return y


@jit
def kern(s, t):  # type: ignore[no-untyped-def]
    """Bridge kernel ``K(s, t)`` with ``t_f = 1``."""
    lo = min(s, t)
    hi = max(s, t)
    return lo * lo * (1.0 - hi) ** 2 * (3.0 * hi - lo - 2.0 * lo * hi) / 6.0


@jit
def kern_ds(s, t):  # type: ignore[no-untyped-def]
    """``∂K(s, t)/∂s``."""
    if s <= t:
        return (1.0 - t) ** 2 * s * (2.0 * t - s - 2.0 * s * t) / 2.0
    return t * t * (1.0 - s) * (1.0 - 3.0 * s + 2.0 * t * s) / 2.0


@jit
def solve_ip(M, X):  # type: ignore[no-untyped-def]
    """``X ← M⁻¹X`` (``X`` of shape ``(n, k)``; ``M`` is overwritten) by Gaussian elimination
    with partial pivoting; ``False`` if a pivot vanishes."""
    n = M.shape[0]
    for p in range(n):
        piv = p
        for i in range(p + 1, n):
            if abs(M[i, p]) > abs(M[piv, p]):
                piv = i
        if M[piv, p] == 0.0 or not np.isfinite(M[piv, p]):
            return False
        if piv != p:
            for j in range(n):
                M[p, j], M[piv, j] = M[piv, j], M[p, j]
            for j in range(X.shape[1]):
                X[p, j], X[piv, j] = X[piv, j], X[p, j]
        for i in range(p + 1, n):
            f = M[i, p] / M[p, p]
            for j in range(p, n):
                M[i, j] -= f * M[p, j]
            for j in range(X.shape[1]):
                X[i, j] -= f * X[p, j]
    for p in range(n - 1, -1, -1):
        for j in range(X.shape[1]):
            acc = X[p, j]
            for i in range(p + 1, n):
                acc -= M[p, i] * X[i, j]
            X[p, j] = acc / M[p, p]
    return True


@jit
def solve(A, B):  # type: ignore[no-untyped-def]
    """``(A⁻¹B, ok)`` (copies; :func:`solve_ip`)."""
    X = B.copy()
    ok = solve_ip(A.copy(), X)
    return X, ok


@jit
def errors(EX, EY, sig):  # type: ignore[no-untyped-def]
    """``(m, 2)``: ``ẽ_x``, ``ẽ_y`` at ``σ``."""
    m = sig.size
    E = np.empty((m, 2))
    for i in range(m):
        E[i, 0] = horner(EX[i], sig[i])
        E[i, 1] = horner(EY[i], sig[i])
    return E


@jit
def kmatrix(sig):  # type: ignore[no-untyped-def]
    m = sig.size
    K = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            K[i, j] = kern(sig[i], sig[j])
    return K


@jit
def load_kx(EX, EY, sig, K, X, E):  # type: ignore[no-untyped-def]
    """``K ← K̃(σ)`` overwritten by its elimination, ``E ← ẽ``, ``X ← K̃⁻¹ẽ``; ``False`` if
    singular."""
    m = sig.size
    for i in range(m):
        for j in range(m):
            K[i, j] = kern(sig[i], sig[j])
        E[i, 0] = horner(EX[i], sig[i])
        E[i, 1] = horner(EY[i], sig[i])
        X[i, 0] = E[i, 0]
        X[i, 1] = E[i, 1]
    return solve_ip(K, X)


@jit
def quad_ws(EX, EY, sig, jbar, K, X, E):  # type: ignore[no-untyped-def]
    """``q(σ) = Σ_axis ẽᵀK̃⁻¹ẽ``; ``inf`` if degenerate (as ``quad_sigma``; scratch
    ``K``, ``X``, ``E``)."""
    if not load_kx(EX, EY, sig, K, X, E):
        return np.inf
    q = 0.0
    for i in range(sig.size):
        q += E[i, 0] * X[i, 0] + E[i, 1] * X[i, 1]
    if not np.isfinite(q) or q < -1e-9 * max(1.0, jbar):
        return np.inf
    return max(q, 0.0)


@jit
def quad(EX, EY, sig, jbar):  # type: ignore[no-untyped-def]
    """:func:`quad_ws` with its own scratch."""
    m = sig.size
    return quad_ws(EX, EY, sig, jbar, np.empty((m, m)), np.empty((m, 2)), np.empty((m, 2)))


@jit
def gradient_ws(EX, EY, DEX, DEY, sig, g, K, X, E):  # type: ignore[no-untyped-def]
    """``g ← ∇_σ J̃`` (as ``gradient_sigma``); ``False`` if ``K`` is singular."""
    m = sig.size
    ok = load_kx(EX, EY, sig, K, X, E)
    for i in range(m):
        g[i] = 0.0
        dd = sig[i] ** 2 * (1.0 - sig[i]) ** 2 * (1.0 - 2.0 * sig[i])
        for a in range(2):
            mu = X[i, a]
            de = horner(DEX[i], sig[i]) if a == 0 else horner(DEY[i], sig[i])
            cross = 0.0
            for j in range(m):
                if j != i:
                    cross += kern_ds(sig[i], sig[j]) * X[j, a]
            g[i] += mu * de - mu * cross - 0.5 * mu * mu * dd
    return ok


@jit
def gradient(EX, EY, DEX, DEY, sig):  # type: ignore[no-untyped-def]
    """``(∇_σ J̃, ok)`` with its own scratch (:func:`gradient_ws`)."""
    m = sig.size
    g = np.empty(m)
    ok = gradient_ws(EX, EY, DEX, DEY, sig, g, np.empty((m, m)), np.empty((m, 2)), np.empty((m, 2)))
    return g, ok


@jit
def shift1(C, c, out):  # type: ignore[no-untyped-def]
    """Taylor coefficients of ``p(c + h)`` into ``out`` (as ``taylor_shift``)."""
    n = C.size
    for k in range(n):
        out[k] = C[k]
    for i in range(n - 1):
        for j in range(n - 2, i - 1, -1):
            out[j] += c * out[j + 1]


@jit
def range1(C, c, r, buf):  # type: ignore[no-untyped-def]
    """Rigorous ``(lo, hi)`` of ``p`` on ``[c − r, c + r]`` (as ``poly_range``)."""
    shift1(C, c, buf)
    dev = 0.0
    rk = 1.0
    for k in range(1, C.size):
        rk *= r
        dev += abs(buf[k]) * rk
    return buf[0] - dev, buf[0] + dev


@jit
def range2(A2, cs, ct, rs, rt, B):  # type: ignore[no-untyped-def]
    """``(lo, hi)`` of ``Σ A2[a, b] s^a t^b`` on ``[cs ± rs] × [ct ± rt]`` (as ``poly2_range``;
    ``B`` is scratch of ``A2``'s shape)."""
    na, nb = A2.shape
    for a in range(na):
        for b in range(nb):
            B[a, b] = A2[a, b]
    for b in range(nb):
        for i in range(na - 1):
            for j in range(na - 2, i - 1, -1):
                B[j, b] += cs * B[j + 1, b]
    for a in range(na):
        for i in range(nb - 1):
            for j in range(nb - 2, i - 1, -1):
                B[a, j] += ct * B[a, j + 1]
    dev = 0.0
    pa = 1.0
    for a in range(na):
        pb = 1.0
        for b in range(nb):
            if a or b:
                dev += abs(B[a, b]) * pa * pb
            pb *= rt
        pa *= rs
    return B[0, 0] - dev, B[0, 0] + dev


@jit
def min_sq(lo, hi):  # type: ignore[no-untyped-def]
    if lo <= 0.0 <= hi:
        return 0.0
    return min(lo * lo, hi * hi)


@jit
def scaled(k, lo, hi):  # type: ignore[no-untyped-def]
    a = k * lo
    b = k * hi
    return min(a, b), max(a, b)


@jit
def workspace(m, d):  # type: ignore[no-untyped-def]
    """Scratch arrays of :func:`lower_bound_box` (allocated once per search)."""
    return (np.empty(max(d, 8)), np.empty((m, 2)), np.empty((m, 2)), np.empty((m, m)), np.empty((m, m)),
            np.empty((m, 2)), np.empty((m, m)), np.empty((m, m)), np.empty((m, 4)), np.empty((4, 4)))


@jit
def lower_bound_box(EX, EY, DEX, DEY, c, r, qstop, ws):  # type: ignore[no-untyped-def]
    """The three lower bounds of ``q`` on the box ``c ± r`` (``pmp_bound.lower_bound``);
    returns early, with a bound ``≥ qstop``, once the one-vehicle or pair bound reaches
    ``qstop`` (the caller discards the box either way)."""
    m = c.size
    buf, rlo, rhi = ws[0], ws[1], ws[2]
    best = 0.0
    for i in range(m):
        rlo[i, 0], rhi[i, 0] = range1(EX[i], c[i], r[i], buf)
        rlo[i, 1], rhi[i, 1] = range1(EY[i], c[i], r[i], buf)
        peak = min(max(0.5, c[i] - r[i]), c[i] + r[i])
        kmax = peak ** 3 * (1.0 - peak) ** 3 / 3.0
        single = (min_sq(rlo[i, 0], rhi[i, 0]) + min_sq(rlo[i, 1], rhi[i, 1])) / kmax
        if single == single:
            best = max(best, single)
    for i in range(m):
        for j in range(i + 1, m):
            num = 0.0
            for a in range(2):
                num += min_sq(rlo[i, a] - rhi[j, a], rhi[i, a] - rlo[j, a])
            dist = max(abs(c[i] + r[i] - (c[j] - r[j])), abs(c[j] + r[j] - (c[i] - r[i])))
            a_ = min(c[i] - r[i], c[j] - r[j])
            b_ = max(c[i] + r[i], c[j] + r[j])
            pk = min(max(0.5, a_), b_)
            x = min(max(1.0 / 6.0, min(a_ * (1.0 - a_), b_ * (1.0 - b_))), pk * (1.0 - pk))
            pb = num / (dist ** 2 * (x * (1.0 - 3.0 * x)))
            if pb == pb:
                best = max(best, pb)
    if best >= qstop:
        return best
    return max(best, fenchel_bound(EX, EY, DEX, DEY, c, r, ws))


@jit
def fenchel_bound(EX, EY, DEX, DEY, c, r, ws):  # type: ignore[no-untyped-def]
    """Bound 1 of :func:`iamp.planners.pmp.bound.lower_bound` (Fenchel with ``w`` at the box
    centre, mean value with exact Taylor ranges) on the box ``c ± r``."""
    m = c.size
    buf, rlo, K, Kr, W, xlo, xhi, V, B4 = ws[0], ws[1], ws[3], ws[4], ws[5], ws[6], ws[7], ws[8], ws[9]
    dmax = 0.0
    for i in range(m):
        for j in range(m):
            K[i, j] = kern(c[i], c[j])
        dmax = max(dmax, abs(K[i, i]))
    for i in range(m):
        for j in range(m):
            Kr[i, j] = K[i, j]
        Kr[i, i] += 1e-13 * dmax + 1e-300
        W[i, 0] = horner(EX[i], c[i])
        W[i, 1] = horner(EY[i], c[i])
    g0 = 0.0
    E0 = rlo  # reuse: the ranges are no longer needed
    for i in range(m):
        E0[i, 0] = W[i, 0]
        E0[i, 1] = W[i, 1]
    ok = solve_ip(Kr, W)
    for i in range(m):
        V[i, 0], V[i, 1] = range1(_DKDIAG_NB, c[i], r[i], buf)  # d K_ii / dσ
        V[i, 2], V[i, 3] = 0.0, 0.0
    for i in range(m):
        for j in range(m):
            if i == j:
                continue
            below_only = c[i] + r[i] <= c[j] - r[j]
            above_only = c[i] - r[i] >= c[j] + r[j]
            if below_only:
                xlo[i, j], xhi[i, j] = range2(_DKB_NB, c[i], c[j], r[i], r[j], B4)
            elif above_only:
                xlo[i, j], xhi[i, j] = range2(_DKA_NB, c[i], c[j], r[i], r[j], B4)
            else:
                l1, h1 = range2(_DKB_NB, c[i], c[j], r[i], r[j], B4)
                l2, h2 = range2(_DKA_NB, c[i], c[j], r[i], r[j], B4)
                xlo[i, j], xhi[i, j] = min(l1, l2), max(h1, h2)
    for a in range(2):
        if ok:
            for i in range(m):
                if not np.isfinite(W[i, a]):
                    W[i, a] = 0.0
        else:
            for i in range(m):
                W[i, a] = 0.0
        for i in range(m):
            g0 += 2.0 * W[i, a] * E0[i, a]
            for j in range(m):
                g0 -= W[i, a] * K[i, j] * W[j, a]
        D = DEX if a == 0 else DEY
        for i in range(m):
            w_i = W[i, a]
            dlo, dhi = range1(D[i], c[i], r[i], buf)
            glo, ghi = scaled(2.0 * w_i, dlo, dhi)
            l2, h2 = scaled(-w_i * w_i, V[i, 0], V[i, 1])
            glo += l2
            ghi += h2
            for j in range(m):
                if j != i:
                    l3, h3 = scaled(-2.0 * w_i * W[j, a], xlo[i, j], xhi[i, j])
                    glo += l3
                    ghi += h3
            V[i, 2] += glo
            V[i, 3] += ghi
    slack = 0.0
    for i in range(m):
        slack += r[i] * max(abs(V[i, 2]), abs(V[i, 3]))
    fench = max(g0 - slack, 0.0)
    if not np.isfinite(fench):
        fench = 0.0
    return fench


_DKDIAG_NB = np.asarray(_DKDIAG, dtype=np.float64)
_DKB_NB = np.asarray(_DK_BELOW, dtype=np.float64)
_DKA_NB = np.asarray(_DK_ABOVE, dtype=np.float64)
_KB_NB = np.asarray(K_BELOW, dtype=np.float64)
_KD_NB = np.asarray(K_DIAG, dtype=np.float64)
_ROUNDING_REL = float(ROUNDING_REL)
_BOX_BOUND_MAX_M = int(BOX_BOUND_MAX_M)


@jit
def _mul_lin_add(P, c0, c, strides, D, sign, out):  # type: ignore[no-untyped-def]
    """``out += sign · P · (c0 + Σ_k c_k h_k)`` on flat dense coefficient arrays."""
    m = strides.size
    for idx in range(P.size):
        v = P[idx]
        if v == 0.0:
            continue
        out[idx] += sign * c0 * v
        for k in range(m):
            if (idx // strides[k]) % (D + 1) < D:
                out[idx + strides[k]] += sign * c[k] * v


@jit
def basin_box(EX, EY, DEX, DEY, s, delta, max_m):  # type: ignore[no-untyped-def]
    """``(radius, lower, G)`` of the basin box at ``s`` (``pmp_basin.basin_box``; ``G`` the
    flat dense Taylor coefficients of the minorant); radius 0 if there is none."""
    m = s.size
    if m < 1 or m > max_m:
        return 0.0, 0.0, np.zeros(1)
    gap = 2.0
    for i in range(m):
        if not (0.0 < s[i] < 1.0):
            return 0.0, 0.0, np.zeros(1)
        for j in range(i + 1, m):
            gap = min(gap, abs(s[i] - s[j]))
    if gap <= 1e-6:
        return 0.0, 0.0, np.zeros(1)
    D = max(8, EX.shape[1])
    N = (D + 1) ** m
    strides = np.empty(m, dtype=np.int64)
    st = 1
    for k in range(m):
        strides[m - 1 - k] = st  # C order, as numpy's dense array
        st *= D + 1
    # affine w = w* + W h per axis
    K = kmatrix(s)
    E = errors(EX, EY, s)
    R = np.zeros((m, 2 * m))
    Wst, ok = solve(K, E)
    if not ok:
        return 0.0, 0.0, np.zeros(1)
    for a in range(2):
        for i in range(m):
            R[i, a * m + i] = horner(DEX[i], s[i]) if a == 0 else horner(DEY[i], s[i])
        for k in range(m):
            dd = s[k] ** 2 * (1.0 - s[k]) ** 2 * (1.0 - 2.0 * s[k])
            vk = dd * Wst[k, a]
            for j in range(m):
                if j != k:
                    R[j, a * m + k] -= kern_ds(s[k], s[j]) * Wst[k, a]
                    vk += kern_ds(s[k], s[j]) * Wst[j, a]
            R[k, a * m + k] -= vk
    Wd, ok = solve(K, R)
    if not ok:
        return 0.0, 0.0, np.zeros(1)
    # the shifted kernel pieces, embedded sparsely
    Kb = np.zeros((m, m, 7, 7))
    buf = np.empty(7)
    for i in range(m):
        shift1(_KD_NB, s[i], buf)
        for a in range(7):
            Kb[i, i, a, 0] = buf[a]
        for j in range(i + 1, m):
            lo, hi = (i, j) if s[i] < s[j] else (j, i)
            A = _KB_NB.copy()
            for b in range(4):
                for p in range(3):
                    for q in range(2, p - 1, -1):
                        A[q, b] += s[lo] * A[q + 1, b]
            for a in range(4):
                for p in range(3):
                    for q in range(2, p - 1, -1):
                        A[a, q] += s[hi] * A[a, q + 1]
            for a in range(4):
                for b in range(4):
                    Kb[lo, hi, a, b] = A[a, b]  # [exponent of lo, exponent of hi]
                    Kb[hi, lo, b, a] = A[a, b]  # [exponent of hi, exponent of lo]
    G = np.zeros(N)
    T = np.zeros(N)
    ebuf = np.empty(EX.shape[1])
    for a in range(2):
        Ea = EX if a == 0 else EY
        for i in range(m):
            w_i = Wst[i, a]
            Wi = Wd[i, a * m: a * m + m]
            shift1(Ea[i], s[i], ebuf)
            for p in range(ebuf.size):  # 2 w_i e_i
                idx = p * strides[i]
                G[idx] += 2.0 * w_i * ebuf[p]
                for k in range(m):
                    G[idx + strides[k]] += 2.0 * Wi[k] * ebuf[p]
            T[:] = 0.0
            for j in range(m):  # T = Σ_j w_j K_ij
                w_j = Wst[j, a]
                Wj = Wd[j, a * m: a * m + m]
                na = 7 if i == j else 4
                nb = 1 if i == j else 4
                for p in range(na):
                    for q in range(nb):
                        v = Kb[i, j, p, q]
                        if v == 0.0:
                            continue
                        idx = p * strides[i] + (q * strides[j] if i != j else 0)
                        T[idx] += w_j * v
                        for k in range(m):
                            T[idx + strides[k]] += Wj[k] * v
            _mul_lin_add(T, w_i, Wi, strides, D, -1.0, G)
    # gradient, Hessian, C_k
    g1 = 0.0
    H = np.empty((m, m))
    for i in range(m):
        g1 += abs(G[strides[i]])
        for j in range(m):
            H[i, j] = G[strides[i] + strides[j]] * (1.0 if i == j else 0.5)
    Ck = np.zeros(2 * D + m * D + 1)
    degmax = 0
    for idx in range(N):
        dg = 0
        for k in range(m):
            dg += (idx // strides[k]) % (D + 1)
        if dg >= 3:
            Ck[dg] += abs(G[idx])
            degmax = max(degmax, dg)
    hmax = 0.0
    for i in range(m):
        for j in range(m):
            hmax = max(hmax, abs(H[i, j]))
    lam = np.linalg.eigvalsh(H)[0] - 1e-12 * hmax
    if not lam > 0:
        return 0.0, 0.0, np.zeros(1)
    rho_max = min(0.499 * gap, 0.5)
    if g1 > 0:
        rho_max = min(rho_max, delta / g1)
    ex = 0.0
    for k in range(3, degmax + 1):
        ex += Ck[k] * rho_max ** (k - 2)
    if ex <= lam:
        rho = rho_max
    else:
        lo_, hi_ = 0.0, rho_max
        for _ in range(40):
            mid = 0.5 * (lo_ + hi_)
            ex = 0.0
            for k in range(3, degmax + 1):
                ex += Ck[k] * mid ** (k - 2)
            if ex <= lam:
                lo_ = mid
            else:
                hi_ = mid
        rho = lo_
    if rho <= 0:
        return 0.0, 0.0, np.zeros(1)
    roundoff = 0.0
    for idx in range(N):
        dg = 0
        for k in range(m):
            dg += (idx // strides[k]) % (D + 1)
        roundoff += abs(G[idx]) * rho ** dg
    roundoff = roundoff * 64 * 2.220446049250313e-16 + _ROUNDING_REL * abs(G[0])
    return rho, G[0] - g1 * rho - roundoff, G


@jit
def g_bound(G, s, c, r, D, A, H, expo, rp):  # type: ignore[no-untyped-def]
    """:meth:`iamp.planners.pmp.basin.Basin.box_bound` for one box (``-inf`` where the box
    does not keep the order of the times at ``s``; ``A``, ``H``, ``rp`` are scratch, ``expo``
    the exponents of every flat index and, in its last column, their sum)."""
    m = s.size
    for i in range(m):
        for j in range(m):
            if s[i] < s[j] and not c[i] + r[i] < c[j] - r[j]:
                return -np.inf
    N = A.size
    for idx in range(N):
        A[idx] = G[idx]
    st = 1
    for a in range(m - 1, -1, -1):  # C order: the last variable has stride 1
        h = c[a] - s[a]
        for base in range(N):
            if expo[base, a] != 0:
                continue
            n = D - expo[base, m]  # total degree ≤ D: the line's own degree
            for i in range(n):
                for j in range(n - 1, i - 1, -1):
                    A[base + j * st] += h * A[base + (j + 1) * st]
        st *= D + 1
    c0 = A[0]
    st_i = 1
    for i in range(m - 1, -1, -1):
        st_j = 1
        for j in range(m - 1, -1, -1):
            H[i, j] = A[st_i + st_j] * (1.0 if i == j else 0.5)
            st_j *= D + 1
        st_i *= D + 1
    if m == 1:
        lam = H[0, 0]
    elif m == 2:
        lam = 0.5 * (H[0, 0] + H[1, 1]) - np.sqrt(0.25 * (H[0, 0] - H[1, 1]) ** 2 + H[0, 1] ** 2)
    else:
        lam = np.linalg.eigvalsh(H)[0]
    quadv = 0.0
    st = 1
    for i in range(m - 1, -1, -1):
        g = A[st]
        if lam > 0:
            d = min(max(-g / (2 * lam), -r[i]), r[i])
            quadv += g * d + lam * d * d
        else:
            quadv += -abs(g) * r[i] + lam * r[i] * r[i]
        st *= D + 1
    for k in range(m):
        rp[k, 0] = 1.0
        for e in range(1, D + 1):
            rp[k, e] = rp[k, e - 1] * r[k]
    rem = 0.0
    tot = 0.0
    for idx in range(N):
        v = abs(A[idx])
        if v == 0.0:
            continue
        dg = 0
        for k in range(m):
            v *= rp[k, expo[idx, k]]
            dg += expo[idx, k]
        tot += v
        if dg >= 3:
            rem += v
    return c0 + quadv - rem - (64 * 2.220446049250313e-16 * tot + _ROUNDING_REL * abs(c0))


@jit
def g_bound2(G, s, c, r, D, A):  # type: ignore[no-untyped-def]
    """:func:`g_bound` for two vehicles on a ``(D+1, D+1)`` scratch ``A``, looping only over
    total degrees ``≤ D`` (the minorant's degree)."""
    if s[0] < s[1] and not c[0] + r[0] < c[1] - r[1]:
        return -np.inf
    if s[1] < s[0] and not c[1] + r[1] < c[0] - r[0]:
        return -np.inf
    n = D + 1
    h0 = c[0] - s[0]
    h1 = c[1] - s[1]
    for a in range(n):
        for b in range(n - a):
            A[a, b] = G[a * n + b]
    for a in range(n):  # shift in the second time
        d = D - a
        for i in range(d):
            for j in range(d - 1, i - 1, -1):
                A[a, j] += h1 * A[a, j + 1]
    for b in range(n):  # then in the first
        d = D - b
        for i in range(d):
            for j in range(d - 1, i - 1, -1):
                A[j, b] += h0 * A[j + 1, b]
    c0 = A[0, 0]
    g0, g1 = A[1, 0], A[0, 1]
    lam = 0.5 * (A[2, 0] + A[0, 2]) - np.sqrt(0.25 * (A[2, 0] - A[0, 2]) ** 2 + 0.25 * A[1, 1] ** 2)
    if lam > 0:
        d0 = min(max(-g0 / (2 * lam), -r[0]), r[0])
        d1 = min(max(-g1 / (2 * lam), -r[1]), r[1])
        quadv = g0 * d0 + lam * d0 * d0 + g1 * d1 + lam * d1 * d1
    else:
        quadv = -abs(g0) * r[0] - abs(g1) * r[1] + lam * (r[0] * r[0] + r[1] * r[1])
    rem = 0.0
    tot = 0.0
    pa = 1.0
    for a in range(n):
        pb = pa
        for b in range(n - a):
            v = abs(A[a, b]) * pb
            tot += v
            if a + b >= 3:
                rem += v
            pb *= r[1]
        pa *= r[0]
    return c0 + quadv - rem - (64 * 2.220446049250313e-16 * tot + _ROUNDING_REL * abs(c0))


@jit
def stationary_points(ex, ey):  # type: ignore[no-untyped-def]
    """Zeros in ``(0, 1)`` of ``P = N'σ(1−σ) − 3N(1−2σ)``, ``N = e_x² + e_y²`` (one vehicle
    alone, :func:`iamp.planners.pmp.search.stationarity_poly`), by sign changes on 256 cells
    and bisection: starting points only (a missed double root costs boxes, not rigour)."""
    d = ex.size
    N = np.zeros(2 * d - 1)
    for i in range(d):
        for j in range(d):
            N[i + j] += ex[i] * ex[j] + ey[i] * ey[j]
    P = np.zeros(2 * d)
    for k in range(1, N.size):
        P[k] += k * N[k]
        P[k + 1] -= k * N[k]
    for k in range(N.size):
        P[k] -= 3 * N[k]
        P[k + 1] += 6 * N[k]
    out = np.empty(2 * d)
    n = 0
    prev = horner(P, 0.0)
    for g in range(1, 257):
        x = g / 256.0
        v = horner(P, x)
        if (prev < 0.0) != (v < 0.0) and n < out.size:
            lo, hi, flo = x - 1.0 / 256.0, x, prev
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                fm = horner(P, mid)
                if (fm < 0.0) == (flo < 0.0):
                    lo, flo = mid, fm
                else:
                    hi = mid
            r = 0.5 * (lo + hi)
            if 0.0 < r < 1.0:
                out[n] = r
                n += 1
        prev = v
    return out[:n]


@jit
def make_starts(EX, EY, jbar, max_starts):  # type: ignore[no-untyped-def]
    """:func:`iamp.planners.pmp.search.start_points` for ``m ≤ 5`` (every combination of the
    one-vehicle stationary points, every ordering evenly spaced), the best ``max_starts``
    by ``q``; an empty array if there would be more than ``8·max_starts`` combinations
    (the caller then samples them as the pure path does)."""
    m = EX.shape[0]
    R = np.full((m, 2 * EX.shape[1]), 0.5)
    nr = np.ones(m, dtype=np.int64)
    total = 1
    for i in range(m):
        rt = stationary_points(EX[i], EY[i])
        if rt.size:
            R[i, :rt.size] = rt
            nr[i] = rt.size
        total *= nr[i]
    nperm = 1
    for k in range(2, m + 1):
        nperm *= k
    if total + nperm > 8 * max_starts or m > 5:
        return np.empty((0, m))
    out = np.empty((total + nperm, m))
    for t in range(total):
        rem = t
        for i in range(m - 1, -1, -1):
            out[t, i] = R[i, rem % nr[i]]
            rem //= nr[i]
    perm = np.arange(m)
    for t in range(nperm):  # lexicographic order, as itertools.permutations
        for k in range(m):
            out[total + t, perm[k]] = (k + 1.0) / (m + 1.0)
        i = m - 2
        while i >= 0 and perm[i] > perm[i + 1]:
            i -= 1
        if i < 0:
            break
        j = m - 1
        while perm[j] < perm[i]:
            j -= 1
        perm[i], perm[j] = perm[j], perm[i]
        perm[i + 1:] = perm[i + 1:][::-1].copy()
    vals = np.empty(out.shape[0])
    for t in range(out.shape[0]):
        vals[t] = quad(EX, EY, out[t], jbar)
    order = np.argsort(vals)[:max_starts]
    return out[order]


@jit
def newton(EX, EY, DEX, DEY, s0, jbar, max_iter):  # type: ignore[no-untyped-def]
    """:func:`iamp.planners.pmp.search.newton_sigma` (Cholesky for the definiteness test)."""
    lo, hi = 1e-12, 1.0 - 1e-12
    m = s0.size
    K = np.empty((m, m))
    X = np.empty((m, 2))
    E = np.empty((m, 2))
    g = np.empty(m)
    gp = np.empty(m)
    gm = np.empty(m)
    sp = np.empty(m)
    sn = np.empty(m)
    step = np.empty(m)
    Hs = np.empty((m, m))
    L = np.empty((m, m))
    s = np.minimum(np.maximum(s0.copy(), lo), hi)
    q = quad_ws(EX, EY, s, jbar, K, X, E)
    h = 1e-6
    for _ in range(max_iter):
        if not np.isfinite(q):
            break
        good = gradient_ws(EX, EY, DEX, DEY, s, g, K, X, E)
        for k in range(m):
            sp[:] = s
            sp[k] += h
            good = gradient_ws(EX, EY, DEX, DEY, sp, gp, K, X, E) and good
            sp[k] -= 2 * h
            good = gradient_ws(EX, EY, DEX, DEY, sp, gm, K, X, E) and good
            for i in range(m):
                Hs[k, i] = (gp[i] - gm[i]) / (2 * h)
        if not good or not np.all(np.isfinite(g)) or not np.all(np.isfinite(Hs)):
            break
        for i in range(m):
            for j in range(i):
                Hs[i, j] = Hs[j, i] = 0.5 * (Hs[i, j] + Hs[j, i])
        pd = True  # Cholesky: positive definite?
        for i in range(m):
            for j in range(i + 1):
                acc = Hs[i, j]
                for k in range(j):
                    acc -= L[i, k] * L[j, k]
                if i == j:
                    if not acc > 0:
                        pd = False
                        break
                    L[i, i] = np.sqrt(acc)
                else:
                    L[i, j] = acc / L[j, j]
            if not pd:
                break
        if pd:  # step = −H⁻¹g by the two triangular solves
            for i in range(m):
                acc = -g[i]
                for k in range(i):
                    acc -= L[i, k] * step[k]
                step[i] = acc / L[i, i]
            for i in range(m - 1, -1, -1):
                acc = step[i]
                for k in range(i + 1, m):
                    acc -= L[k, i] * step[k]
                step[i] = acc / L[i, i]
        else:
            gmax = np.max(np.abs(g))
            if gmax == 0.0:
                break
            for i in range(m):
                step[i] = -g[i] / gmax * 0.02
        alpha = 1.0
        accepted = False
        qn = q
        smax = np.max(np.abs(step))
        while alpha > 1e-10 and alpha * smax >= 1e-15:  # below that nothing moves
            for i in range(m):
                sn[i] = min(max(s[i] + alpha * step[i], lo), hi)
            qn = quad_ws(EX, EY, sn, jbar, K, X, E)
            if qn <= q + 1e-15 * max(1.0, abs(q)):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        moved = 0.0
        for i in range(m):
            moved = max(moved, abs(sn[i] - s[i]))
            s[i] = sn[i]
        q = qn
        if moved < 1e-15:
            break
    return s, q


@jit
def trusted(P, s, q):  # type: ignore[no-untyped-def]
    """:func:`iamp.planners.pmp.search.trusted_q`: ``q`` if the times are distinct
    (``> 1e-6``) and ``J̃ = J̃₀ + q/2`` agrees with ``½∫|ũ|²`` of the solved jump system
    (``pmp_cost_consistency_rel``), else ``inf``.  ``P = (ego, CX, CY, jbar, tol)``."""
    ego, CX, CY, jbar, tolc = P
    m = s.size
    for i in range(m):
        for j in range(i + 1, m):
            if abs(s[i] - s[j]) <= 1e-6:
                return np.inf
    if not np.isfinite(q):
        return np.inf
    n = m + 2
    M = np.zeros((n, n))
    z = np.empty((n, 2))
    for i in range(m):  # jump_system_sigma
        M[i, 0] = s[i] ** 2 / 2
        M[i, 1] = s[i] ** 3 / 6
        for j in range(m):
            M[i, 2 + j] = -max(s[i] - s[j], 0.0) ** 3 / 6
        z[i, 0] = horner(CX[i], s[i]) - ego[0] - ego[1] * s[i]
        z[i, 1] = CY[i] - ego[4] - ego[5] * s[i]
        M[m, 2 + i] = -((1.0 - s[i]) ** 3) / 6
        M[m + 1, 2 + i] = -((1.0 - s[i]) ** 2) / 2
    M[m, 0], M[m, 1], M[m + 1, 0], M[m + 1, 1] = 0.5, 1.0 / 6.0, 1.0, 0.5
    z[m, 0], z[m, 1] = ego[2] - ego[0] - ego[1], ego[6] - ego[4] - ego[5]
    z[m + 1, 0], z[m + 1, 1] = ego[3] - ego[1], ego[7] - ego[5]
    if not solve_ip(M, z):
        return np.inf
    bp = np.empty(m + 2)  # exact ½∫u²: u is linear between the sorted breakpoints
    bp[0], bp[m + 1] = 0.0, 1.0
    bp[1:m + 1] = np.sort(s)
    J = 0.0
    for a in range(2):
        u_prev = 0.0
        for k in range(m + 2):
            u = z[0, a] + z[1, a] * bp[k]
            for i in range(m):
                u -= z[2 + i, a] * max(bp[k] - s[i], 0.0)
            if k:
                J += 0.5 * (bp[k] - bp[k - 1]) / 3 * (u_prev * u_prev + u_prev * u + u * u)
            u_prev = u
    Jc = jbar + 0.5 * q
    if not (np.isfinite(J) and np.isfinite(Jc) and abs(Jc - J) <= tolc * max(abs(J), 1e-300)):
        return np.inf
    return q


@jit
def in_basins(B, nb, c, r):  # type: ignore[no-untyped-def]
    """Whether ``c ± r`` lies inside one of the first ``nb`` basins (rows
    ``[centre..., radius, lower]``)."""
    m = c.size
    for b in range(nb):
        inside = True
        for i in range(m):
            if abs(c[i] - B[b, i]) + r[i] > B[b, m]:
                inside = False
                break
        if inside:
            return b
    return -1

@jit
def add_basin(EX, EY, DEX, DEY, B, BG, nb, s, jbar, eps, max_m):  # type: ignore[no-untyped-def]
    m = s.size
    if nb >= B.shape[0] or in_basins(B, nb, s, np.zeros(m)) >= 0:
        return nb
    for i in range(m):
        if not np.isfinite(s[i]):
            return nb
    q = quad(EX, EY, s, jbar)
    if not np.isfinite(q):
        return nb
    rho, low, G = basin_box(EX, EY, DEX, DEY, s, 0.25 * eps * (jbar + 0.5 * q), max_m)
    if rho <= 0:
        return nb
    B[nb, :m] = s
    B[nb, m] = rho
    B[nb, m + 1] = low
    if BG.shape[1] == G.size:
        BG[nb] = G
    return nb + 1

@jit
def polish_best(EX, EY, DEX, DEY, P, c, n, best_s, best_q):  # type: ignore[no-untyped-def]
    """Budget spent: Newton from the 32 box centres of least ``q`` (``pmp_bound``'s
    ``uncertified``); ``(σ, q)`` of the best trusted point."""
    jbar = P[3]
    qc = np.empty(n)
    for k in range(n):
        qc[k] = quad(EX, EY, c[k], jbar)
    order = np.argsort(qc)
    for t in range(min(32, n)):
        k = order[t]
        if np.isfinite(qc[k]):
            s, q = newton(EX, EY, DEX, DEY, c[k], jbar, 60)
            q = trusted(P, s, q)
            if q < best_q:
                best_s, best_q = s, q
    return best_s, best_q


@jit
def search(EX, EY, DEX, DEY, P, starts, eps, max_boxes, max_m):  # type: ignore[no-untyped-def]
    """``(σ, q, certified, boxes)``: :func:`~iamp.planners.pmp.search.global_search`
    (``P`` as in :func:`trusted`)."""
    jbar = P[3]
    m = starts.shape[1]
    ws = workspace(m, EX.shape[1])
    B = np.empty((64, m + 2))
    D = max(8, EX.shape[1])
    BG = np.zeros((64, (D + 1) ** m if m <= _BOX_BOUND_MAX_M else 1))  # minorants kept for g_bound only
    Hbuf = np.empty((m, m))
    Kq = np.empty((m, m))
    Xq = np.empty((m, 2))
    Eq = np.empty((m, 2))
    Abuf = np.empty(BG.shape[1])
    expo = np.zeros((BG.shape[1], m + 1), dtype=np.int64)
    for idx in range(BG.shape[1] if m <= _BOX_BOUND_MAX_M else 0):
        rem = idx
        for k in range(m - 1, -1, -1):
            expo[idx, k] = rem % (D + 1)
            expo[idx, m] += expo[idx, k]
            rem //= D + 1
    rp = np.empty((m, D + 1))
    A2buf = np.empty((D + 1, D + 1))
    nb = 0
    best_s = starts[0].copy()
    best_q = np.inf
    for k in range(starts.shape[0]):
        if in_basins(B, nb, starts[k], np.zeros(m)) >= 0:
            continue
        s, q = newton(EX, EY, DEX, DEY, starts[k], jbar, 60)
        nb = add_basin(EX, EY, DEX, DEY, B, BG, nb, s, jbar, eps, max_m)
        q = trusted(P, s, q)
        if q < best_q:
            best_s, best_q = s, q
    # the branch and bound (pmp_bound.branch_and_bound)
    levels = max(1, 6 // m)
    n = 2 ** (levels * m)
    c = np.empty((n, m))
    r = np.full((n, m), 0.5 / 2 ** levels)
    for idx in range(n):
        rem = idx
        for i in range(m - 1, -1, -1):  # C order, as repeated halving
            c[idx, i] = (rem % 2 ** levels + 0.5) / 2 ** levels
            rem //= 2 ** levels
    evaluated = 0
    truncated = False
    while n:
        evaluated += n
        if evaluated > max_boxes:
            best_s, best_q = polish_best(EX, EY, DEX, DEY, P, c, n, best_s, best_q)
            return best_s, best_q, False, evaluated
        kbest = -1
        qmin = np.inf
        for k in range(n):
            qk = quad_ws(EX, EY, c[k], jbar, Kq, Xq, Eq)
            if qk < qmin:
                qmin, kbest = qk, k
        if kbest >= 0 and qmin < best_q and in_basins(B, nb, c[kbest], r[kbest]) < 0:
            s, q = newton(EX, EY, DEX, DEY, c[kbest], jbar, 60)
            nb = add_basin(EX, EY, DEX, DEY, B, BG, nb, s, jbar, eps, max_m)
            q = trusted(P, s, q)
            if q < best_q:
                best_s, best_q = s, q
        J_best = jbar + 0.5 * best_q
        qstop = 2.0 * (J_best - eps * abs(J_best) - jbar)  # discard a box with q ≥ qstop on it
        keep = 0
        lbk = np.empty(n)
        for k in range(n):
            b = in_basins(B, nb, c[k], r[k])
            if b >= 0 and B[b, m + 1] >= qstop:
                continue
            lb = lower_bound_box(EX, EY, DEX, DEY, c[k], r[k], qstop, ws)
            for bb in range(nb if m <= _BOX_BOUND_MAX_M else 0):  # the basins' minorants
                if lb >= qstop:
                    break
                if m == 2:
                    lb = max(lb, g_bound2(BG[bb], B[bb, :m], c[k], r[k], D, A2buf))
                else:
                    lb = max(lb, g_bound(BG[bb], B[bb, :m], c[k], r[k], D, Abuf, Hbuf, expo, rp))
            if lb < qstop:
                c[keep] = c[k]
                r[keep] = r[k]
                lbk[keep] = lb
                keep += 1
        n = keep
        if n == 0:
            break
        # split: halve every side at least half as long as the longest one
        cntk = np.empty(n, dtype=np.int64)
        cnt = 0
        for k in range(n):
            rmax = np.max(r[k])
            ncut = 0
            for i in range(m):
                if r[k, i] >= 0.5 * rmax:
                    ncut += 1
            cntk[k] = 2 ** ncut
            cnt += cntk[k]
        if evaluated + cnt > max_boxes:  # the budget would overrun: boxes of least bound that fit
            truncated = True
            order = np.argsort(lbk[:n], kind="mergesort")
            ct = np.empty((n, m))
            rt = np.empty((n, m))
            sel = 0
            cnt = 0
            for j in range(n):
                k = order[j]
                if evaluated + cnt + cntk[k] > max_boxes:
                    break
                ct[sel] = c[k]
                rt[sel] = r[k]
                cnt += cntk[k]
                sel += 1
            if sel == 0:
                best_s, best_q = polish_best(EX, EY, DEX, DEY, P, c, n, best_s, best_q)
                return best_s, best_q, False, evaluated
            c, r, n = ct, rt, sel
        c2 = np.empty((cnt, m))
        r2 = np.empty((cnt, m))
        t = 0
        for k in range(n):
            rmax = np.max(r[k])
            cut = r[k] >= 0.5 * rmax
            ncut = 0
            for i in range(m):
                if cut[i]:
                    ncut += 1
            for code in range(2 ** ncut):
                bit = 0
                for i in range(m):
                    if cut[i]:
                        sg = 1.0 if (code >> (ncut - 1 - bit)) & 1 else -1.0
                        bit += 1
                        r2[t, i] = 0.5 * r[k, i]
                        c2[t, i] = c[k, i] + sg * r2[t, i]
                    else:
                        r2[t, i] = r[k, i]
                        c2[t, i] = c[k, i]
                t += 1
        c, r, n = c2, r2, cnt
    return best_s, best_q, not truncated, evaluated

