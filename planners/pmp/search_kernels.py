r"""The kernels of the ``m ≥ 2`` contact-time search, written once (issue 32).

The value function ``q(σ) = Σ_axis ẽᵀK̃⁻¹ẽ`` (:class:`~iamp.planners.pmp.fixed.ValueFunction`),
its gradient, the damped Newton method of :func:`~iamp.planners.pmp.search.newton_sigma` and
the box lower bound of :func:`~iamp.planners.pmp.bound.lower_bound` — the mathematics is in
those docstrings.  Each is one function here, marked :func:`~iamp.planners.pmp.jit.compilable`:

* the planner runs it as Python by default: it works on numpy arrays *across points or
  boxes* (each point a column: arrays of shape ``(n,)`` per quantity), with explicit loops
  over the few vehicles and polynomial coefficients, so the many boxes of a three-vehicle
  certificate stay vectorised;
* :func:`iamp.planners.pmp.compiled.load_search` compiles the *same code objects* with numba
  (no fastmath), where the per-call overhead of numpy on a handful of boxes disappears.

Only element-wise IEEE operations (``+ − × ÷``, ``sqrt``, ``abs``, comparisons, selection by
``np.where``) appear, in an order fixed by the code: no reductions whose order numpy chooses
(``np.sum``), no ``**`` (numpy's ``pow`` and numba's repeated products differ in the last
bit), no LAPACK (the small symmetric solves are the column Cholesky :func:`chol`).  So the
compiled and the Python path give the same numbers bit for bit (tested in
``tests/test_pmp_search_kernels.py`` in a subprocess with and without numba): no result
depends on whether numba is installed or loaded.

Layout: coefficient arrays ``EX``, ``EY`` (``m × d``, ascending) and their derivatives
``DEX``, ``DEY``; points and boxes as ``(n, m)`` arrays (rows), transposed to ``(m, n)``
inside so that each vehicle's values are one contiguous row.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .jit import compilable

#: the compiled twins by name once :func:`iamp.planners.pmp.compiled.load_search` has run in
#: this process; callers take :func:`kernel` (the same numbers either way)
TWINS: dict[str, Any] = {}
#: the twins :func:`iamp.planners.pmp.compiled.load_axis` compiles for the bounded PMP
#: (:data:`iamp.planners.pmp.compiled.BOUNDED_SEARCH_KERNELS`), while it is loaded
AXIS_TWINS: dict[str, Any] = {}


def kernel(name: str) -> Any:
    """The kernel ``name`` of this module as this process runs it: the twin of
    :func:`~iamp.planners.pmp.compiled.load_search`, else that of
    :func:`~iamp.planners.pmp.compiled.load_axis`, else the Python function (the same
    numbers, bit for bit, whichever runs).

    Parameters
    ----------
    name : str
        A kernel function of this module.

    Returns
    -------
    callable
        The function to call.
    """
    run = TWINS.get(name)
    if run is None:
        run = AXIS_TWINS.get(name)
    return run if run is not None else globals()[name]


#: ``∂K(s,t)/∂s`` below the diagonal (``s ≤ t``), coefficients ``A[a, b]`` of ``s^a t^b``
DK_BELOW = np.array([[0.0, 0.0, 0.0, 0.0],
                     [0.0, 1.0, -2.0, 1.0],
                     [-0.5, 0.0, 1.5, -1.0],
                     [0.0, 0.0, 0.0, 0.0]])
#: ``∂K(s,t)/∂s`` above the diagonal (``s ≥ t``)
DK_ABOVE = np.array([[0.0, 0.0, 0.5, 0.0],
                     [0.0, 0.0, -2.0, 1.0],
                     [0.0, 0.0, 1.5, -1.0],
                     [0.0, 0.0, 0.0, 0.0]])
#: ``d K(σ,σ)/dσ = σ²(1−σ)²(1−2σ)`` ascending
DK_DIAG = np.array([0.0, 0.0, 1.0, -4.0, 5.0, -2.0])


@compilable
def kern(s: Any, t: Any) -> Any:
    """``K̃(s, t)`` element-wise (unit horizon)."""
    below = s < t
    lo = np.where(below, s, t)
    hi = np.where(below, t, s)
    w = 1.0 - hi
    return lo * lo * (w * w) * (3.0 * hi - lo - 2.0 * lo * hi) / 6.0


@compilable
def kern_ds(s: Any, t: Any) -> Any:
    """``∂K̃(s, t)/∂s`` element-wise (``s ≠ t``)."""
    wt = 1.0 - t
    below = wt * wt * s * (2.0 * t - s - 2.0 * s * t) / 2.0
    above = t * t * (1.0 - s) * (1.0 - 3.0 * s + 2.0 * t * s) / 2.0
    return np.where(s <= t, below, above)


@compilable
def horner(coef: Any, x: Any) -> Any:
    """The polynomial ``coef`` (ascending, 1-D) at every entry of ``x``."""
    d = coef.shape[0]
    y = np.zeros(x.shape[0]) + coef[d - 1]
    for k in range(d - 2, -1, -1):
        y = y * x + coef[k]
    return y


@compilable
def chol(K: Any) -> Any:
    """Column Cholesky ``K = L Lᵀ`` of ``n`` symmetric ``m × m`` matrices (``K[i, j]`` a row
    of ``n``); returns ``(L, ok)``, ``ok`` false where a pivot is not positive (or NaN)."""
    m = K.shape[0]
    n = K.shape[2]
    L = np.zeros((m, m, n))
    ok = np.ones(n, dtype=np.bool_)
    for j in range(m):
        d = K[j, j].copy()
        for k in range(j):
            d = d - L[j, k] * L[j, k]
        ok = ok & (d > 0.0)
        dj = np.sqrt(np.where(ok, d, 1.0))
        L[j, j] = dj
        for i in range(j + 1, m):
            v = K[i, j].copy()
            for k in range(j):
                v = v - L[i, k] * L[j, k]
            L[i, j] = v / dj
    return L, ok


@compilable
def forward(L: Any, e: Any) -> Any:
    """``z = L⁻¹e`` (``e`` of shape ``(m, n)``)."""
    m = L.shape[0]
    z = np.empty(e.shape)
    for i in range(m):
        v = e[i].copy()
        for k in range(i):
            v = v - L[i, k] * z[k]
        z[i] = v / L[i, i]
    return z


@compilable
def backward(L: Any, z: Any) -> Any:
    """``w = L⁻ᵀz``."""
    m = L.shape[0]
    w = np.empty(z.shape)
    for i in range(m - 1, -1, -1):
        v = z[i].copy()
        for k in range(i + 1, m):
            v = v - L[k, i] * w[k]
        w[i] = v / L[i, i]
    return w


@compilable
def kmatrix(sT: Any) -> Any:
    """``K̃(σ_i, σ_j)`` for the columns of ``sT`` (``(m, n)``) as ``(m, m, n)``."""
    m = sT.shape[0]
    n = sT.shape[1]
    return kern(sT.reshape(m, 1, n), sT.reshape(1, m, n))


@compilable
def errors(C: Any, sT: Any) -> Any:
    """``ẽ_i(σ_i)`` of one axis as ``(m, n)``."""
    m = sT.shape[0]
    e = np.empty(sT.shape)
    for i in range(m):
        e[i] = horner(C[i], sT[i])
    return e


@compilable
def quad(EX: Any, EY: Any, sig: Any) -> Any:
    """``q(σ)`` for each row of ``sig`` (``(n, m)``); ``inf`` where ``K̃`` is not positive
    definite or ``q`` is not finite."""
    sT = np.ascontiguousarray(sig.T)
    L, ok = chol(kmatrix(sT))
    q = np.zeros(sT.shape[1])
    for a in range(2):
        C = EX if a == 0 else EY
        z = forward(L, errors(C, sT))
        for i in range(sT.shape[0]):
            q = q + z[i] * z[i]
    good = ok & np.isfinite(q)
    return np.where(good, q, np.inf)


@compilable
def gradient(EX: Any, EY: Any, DEX: Any, DEY: Any, sig: Any) -> Any:
    r"""``∇_σ J̃`` for each row of ``sig`` (``(n, m)``), NaN where ``K̃`` is not positive
    definite: with ``μ = K̃⁻¹ẽ`` per axis,
    ``∂J̃/∂σ_i = Σ_axis μ_i ẽ_i' − μ_i Σ_{j≠i} ∂₁K̃(σ_i,σ_j) μ_j − ½ μ_i² dK̃_ii/dσ``."""
    sT = np.ascontiguousarray(sig.T)
    m, n = sT.shape
    L, ok = chol(kmatrix(sT))
    dK = kern_ds(sT.reshape(m, 1, n), sT.reshape(1, m, n))  # dK[i, j] = ∂₁K̃(σ_i, σ_j)
    g = np.zeros((m, n))
    for a in range(2):
        C = EX if a == 0 else EY
        D = DEX if a == 0 else DEY
        mu = backward(L, forward(L, errors(C, sT)))
        for i in range(m):
            de = horner(D[i], sT[i])
            si = sT[i]
            w = 1.0 - si
            diag = si * si * (w * w) * (1.0 - 2.0 * si)
            cross = np.zeros(n)
            for j in range(m):
                if j != i:
                    cross = cross + dK[i, j] * mu[j]
            g[i] = g[i] + (mu[i] * de - mu[i] * cross - 0.5 * (mu[i] * mu[i]) * diag)
    g = np.where(ok, g, np.nan)
    return np.ascontiguousarray(g.T)


@compilable
def clip_unit(s: Any) -> Any:
    """``s`` clipped to ``[1e-12, 1 − 1e-12]`` (NaN stays NaN)."""
    lo = 1e-12
    hi = 1.0 - 1e-12
    return np.where(s < lo, lo, np.where(s > hi, hi, s))


@compilable
def newton(EX: Any, EY: Any, DEX: Any, DEY: Any, s0: Any, max_iter: int) -> Any:
    """Damped Newton on ``∇J̃(σ) = 0`` from ``s0`` (:func:`~iamp.planners.pmp.search.newton_sigma`):
    the Hessian is the central difference (``h = 10⁻⁶``) of :func:`gradient`, the Newton step
    is taken where it is positive definite (:func:`chol`), else a gradient step of ``0.02``
    in the sup norm; backtracking on ``q`` keeps it a descent method inside ``(0, 1)``.
    Returns ``(σ, q(σ))``."""
    m = s0.shape[0]
    s = clip_unit(s0.copy())
    q = quad(EX, EY, s.reshape(1, m))[0]
    h = 1e-6
    pts = np.empty((2 * m + 1, m))
    for _ in range(max_iter):
        for k in range(2 * m + 1):
            pts[k] = s
        for k in range(m):
            pts[1 + k, k] = s[k] + h
            pts[1 + m + k, k] = s[k] - h
        G = gradient(EX, EY, DEX, DEY, pts)
        if not (np.all(np.isfinite(G)) and np.isfinite(q)):
            break
        g = G[0]
        H = np.empty((m, m, 1))
        for i in range(m):
            for j in range(m):
                H[i, j, 0] = (G[1 + j, i] - G[1 + m + j, i]) / (2.0 * h)
        for i in range(m):
            for j in range(i + 1, m):
                v = 0.5 * (H[i, j, 0] + H[j, i, 0])
                H[i, j, 0] = v
                H[j, i, 0] = v
        L, ok = chol(H)
        if ok[0] and np.all(np.isfinite(H)):
            step = -backward(L, forward(L, g.reshape(m, 1)))[:, 0]
        else:
            gmax = np.max(np.abs(g))
            if gmax == 0.0:
                break
            step = -g / gmax * 0.02
        alpha = 1.0
        accepted = False
        smax = np.max(np.abs(step))
        sn = s
        qn = q
        while alpha > 1e-10 and alpha * smax >= 1e-15:  # below that nothing moves
            sn = clip_unit(s + alpha * step)
            qn = quad(EX, EY, sn.reshape(1, m))[0]
            if qn <= q + 1e-15 * max(1.0, abs(q)):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        moved = np.max(np.abs(sn - s))
        s = sn
        q = qn
        if moved < 1e-15:
            break
    return s, q


@compilable
def shift_range(coef: Any, x: Any, r: Any) -> Any:
    """Rigorous ``(lo, hi)`` of the polynomial ``coef`` (ascending, 1-D) on each
    ``[x − r, x + r]``: ``p(x) ∓ Σ_{k≥1} |p^{(k)}(x)/k!| r^k`` (exact Taylor shift by
    synthetic division)."""
    d = coef.shape[0]
    n = x.shape[0]
    A = np.empty((d, n))
    for k in range(d):
        A[k] = coef[k]
    for i in range(d - 1):
        for j in range(d - 2, i - 1, -1):
            A[j] = A[j] + x * A[j + 1]
    dev = np.zeros(n)
    rk = r.copy()
    for k in range(1, d):
        dev = dev + np.abs(A[k]) * rk
        rk = rk * r
    return A[0] - dev, A[0] + dev


@compilable
def shift_range2(A2: Any, cs: Any, ct: Any, rs: Any, rt: Any) -> Any:
    """:func:`shift_range` of the bivariate ``A2[a, b]`` (``s^a t^b``, ``4 × 4``) on the boxes
    ``[cs ± rs] × [ct ± rt]``."""
    n = cs.shape[0]
    B = np.empty((4, 4, n))
    for a in range(4):
        for b in range(4):
            B[a, b] = A2[a, b]
    for b in range(4):
        for i in range(3):
            for j in range(2, i - 1, -1):
                B[j, b] = B[j, b] + cs * B[j + 1, b]
    for a in range(4):
        for i in range(3):
            for j in range(2, i - 1, -1):
                B[a, j] = B[a, j] + ct * B[a, j + 1]
    dev = np.zeros(n)
    pa = np.ones(n)
    for a in range(4):
        pab = pa.copy()
        for b in range(4):
            if a + b > 0:
                dev = dev + np.abs(B[a, b]) * pab
            pab = pab * rt
        pa = pa * rs
    return B[0, 0] - dev, B[0, 0] + dev


@compilable
def min_sq(lo: Any, hi: Any) -> Any:
    """``min x²`` over ``[lo, hi]``."""
    a = lo * lo
    b = hi * hi
    return np.where((lo <= 0.0) & (hi >= 0.0), 0.0, np.where(a < b, a, b))


@compilable
def nan_to_zero(x: Any) -> Any:
    """``x`` with NaN replaced by 0."""
    return np.where(x != x, 0.0, x)


@compilable
def vmax(a: Any, b: Any) -> Any:
    """Element-wise maximum (``b`` where ``a`` is NaN)."""
    return np.where(a > b, a, b)


@compilable
def speed_variance_max(a: Any, b: Any) -> Any:
    """``max Var v(σ) = x(1 − 3x)``, ``x = σ(1 − σ)``, over ``σ ∈ [a, b]`` (exact: ``x`` is
    unimodal in ``σ`` with its peak at ``1/2``, ``x(1 − 3x)`` peaks at ``x = 1/6``)."""
    xa = a * (1.0 - a)
    xb = b * (1.0 - b)
    pk = np.where(a > 0.5, a, np.where(b < 0.5, b, 0.5))
    xlo = np.where(xa < xb, xa, xb)
    xhi = pk * (1.0 - pk)
    x = np.where(xlo > 1.0 / 6.0, xlo, np.where(xhi < 1.0 / 6.0, xhi, 1.0 / 6.0))
    return x * (1.0 - 3.0 * x)


@compilable
def scale_interval(k: Any, lo: Any, hi: Any) -> Any:
    """Interval ``k·[lo, hi]``."""
    a = k * lo
    b = k * hi
    return np.where(a < b, a, b), np.where(a < b, b, a)


@compilable
def lower_bound(EX: Any, EY: Any, DEX: Any, DEY: Any, c: Any, r: Any) -> Any:
    """A rigorous lower bound of ``q`` on each box ``c ± r`` (rows of ``(n, m)``): the
    maximum of the three bounds of :mod:`iamp.planners.pmp.bound` (one vehicle, two vehicles
    at the same time, Fenchel with the mean value)."""
    cT = np.ascontiguousarray(c.T)
    rT = np.ascontiguousarray(r.T)
    m, n = cT.shape
    loT = cT - rT
    hiT = cT + rT
    # ranges of e_i on each box, per axis
    elo = np.empty((2, m, n))
    ehi = np.empty((2, m, n))
    for a in range(2):
        C = EX if a == 0 else EY
        for i in range(m):
            lo_i, hi_i = shift_range(C[i], cT[i], rT[i])
            elo[a, i] = lo_i
            ehi[a, i] = hi_i
    # 2. one vehicle
    best = np.zeros(n)
    for i in range(m):
        pk = np.where(loT[i] > 0.5, loT[i], np.where(hiT[i] < 0.5, hiT[i], 0.5))
        w = 1.0 - pk
        kmax = pk * pk * pk * (w * w * w) / 3.0
        single = nan_to_zero((min_sq(elo[0, i], ehi[0, i]) + min_sq(elo[1, i], ehi[1, i])) / kmax)
        best = vmax(best, single)
    # 3. pairs near the diagonal
    for i in range(m):
        for j in range(i + 1, m):
            num = np.zeros(n)
            for a in range(2):
                num = num + min_sq(elo[a, i] - ehi[a, j], ehi[a, i] - elo[a, j])
            d1 = np.abs(hiT[i] - loT[j])
            d2 = np.abs(hiT[j] - loT[i])
            dist = vmax(d1, d2)
            lo_ij = np.where(loT[i] < loT[j], loT[i], loT[j])
            hi_ij = vmax(hiT[i], hiT[j])
            pb = nan_to_zero(num / (dist * dist * speed_variance_max(lo_ij, hi_ij)))
            best = vmax(best, pb)
    # 1. Fenchel + mean value, w = K(c)⁻¹e(c) (ridged)
    K = kmatrix(cT)
    kd = np.zeros(n)
    for i in range(m):
        kd = vmax(kd, np.abs(K[i, i]))
    ridge = 1e-13 * kd + 1e-300
    Kr = K.copy()
    for i in range(m):
        Kr[i, i] = K[i, i] + ridge
    L, ok = chol(Kr)
    dklo = np.empty((m, n))
    dkhi = np.empty((m, n))
    for i in range(m):
        lo_i, hi_i = shift_range(DK_DIAG, cT[i], rT[i])
        dklo[i] = lo_i
        dkhi[i] = hi_i
    xlo = np.zeros((m, m, n))
    xhi = np.zeros((m, m, n))
    for i in range(m):
        for j in range(m):
            if i == j:
                continue
            below_only = hiT[i] <= loT[j]
            above_only = loT[i] >= hiT[j]
            if np.all(below_only):  # one piece of K for every box: range that one only
                xlo[i, j], xhi[i, j] = shift_range2(DK_BELOW, cT[i], cT[j], rT[i], rT[j])
            elif np.all(above_only):
                xlo[i, j], xhi[i, j] = shift_range2(DK_ABOVE, cT[i], cT[j], rT[i], rT[j])
            else:
                blo, bhi = shift_range2(DK_BELOW, cT[i], cT[j], rT[i], rT[j])
                alo, ahi = shift_range2(DK_ABOVE, cT[i], cT[j], rT[i], rT[j])
                xlo[i, j] = np.where(below_only, blo, np.where(above_only, alo, np.where(blo < alo, blo, alo)))
                xhi[i, j] = np.where(below_only, bhi, np.where(above_only, ahi, vmax(bhi, ahi)))
    g0 = np.zeros(n)
    Glo = np.zeros((m, n))
    Ghi = np.zeros((m, n))
    for a in range(2):
        C = EX if a == 0 else EY
        D = DEX if a == 0 else DEY
        e = errors(C, cT)
        w = backward(L, forward(L, e))
        for i in range(m):
            w[i] = np.where(ok & np.isfinite(w[i]), w[i], 0.0)
        for i in range(m):
            g0 = g0 + 2.0 * (w[i] * e[i])
        for i in range(m):
            Kw = np.zeros(n)
            for j in range(m):
                Kw = Kw + K[i, j] * w[j]
            g0 = g0 - w[i] * Kw
        for i in range(m):
            de_lo, de_hi = shift_range(D[i], cT[i], rT[i])
            glo, ghi = scale_interval(2.0 * w[i], de_lo, de_hi)
            dlo, dhi = scale_interval(-(w[i] * w[i]), dklo[i], dkhi[i])
            glo = glo + dlo
            ghi = ghi + dhi
            for j in range(m):
                if j != i:
                    ylo, yhi = scale_interval(-2.0 * w[i] * w[j], xlo[i, j], xhi[i, j])
                    glo = glo + ylo
                    ghi = ghi + yhi
            Glo[i] = Glo[i] + glo
            Ghi[i] = Ghi[i] + ghi
    slack = np.zeros(n)
    for i in range(m):
        slack = slack + rT[i] * vmax(np.abs(Glo[i]), np.abs(Ghi[i]))
    fench = g0 - slack
    fench = np.where(np.isfinite(fench) & (fench > 0.0), fench, 0.0)
    return vmax(best, fench)


@compilable
def split(c: Any, r: Any) -> Any:
    """Halve every box ``c ± r`` (rows) along each side at least half as long as its longest
    one: the children in the order of the sign patterns (``−`` before ``+``, the first
    vehicle slowest), each pattern's children in the order of their parents; a side that is
    not cut yields one child, not two."""
    n, m = c.shape
    rmax = r[:, 0].copy()
    for i in range(1, m):
        rmax = np.where(r[:, i] > rmax, r[:, i], rmax)
    cut = np.empty((n, m), dtype=np.bool_)
    rn = np.empty((n, m))
    count = np.ones(n, dtype=np.int64)
    for i in range(m):
        cut[:, i] = r[:, i] >= 0.5 * rmax
        rn[:, i] = np.where(cut[:, i], 0.5 * r[:, i], r[:, i])
        count = count * np.where(cut[:, i], 2, 1)
    total = int(np.sum(count))
    cs = np.empty((total, m))
    rs = np.empty((total, m))
    pos = 0
    for combo in range(2 ** m):
        keep = np.ones(n, dtype=np.bool_)
        child = np.empty((n, m))
        for i in range(m):
            up = (combo >> (m - 1 - i)) & 1
            sg = 1.0 if up else -1.0
            child[:, i] = c[:, i] + np.where(cut[:, i], sg * rn[:, i], 0.0)
            if not up:
                keep = keep & cut[:, i]
        k = int(np.sum(keep))
        cs[pos:pos + k] = child[keep]
        rs[pos:pos + k] = rn[keep]
        pos += k
    return cs, rs


# --- basin boxes (:mod:`iamp.planners.pmp.basin`) --------------------------------------------
# A polynomial in h = σ − s of degree ≤ D per variable is a flat array of (D+1)^m
# coefficients in C order: variable k has stride (D+1)^(m−1−k).

#: coefficients ``A[a, b]`` of ``s^a t^b`` of ``K(s, t) = s²(1−t)²(3t − s − 2st)/6`` (``s ≤ t``)
K_BELOW = np.zeros((4, 4))
for _b1, _v1 in ((0, 1.0), (1, -2.0), (2, 1.0)):  # (1 − t)²
    for (_a2, _b2), _v2 in (((0, 1), 3.0), ((1, 0), -1.0), ((1, 1), -2.0)):  # 3t − s − 2st
        K_BELOW[2 + _a2, _b1 + _b2] += _v1 * _v2 / 6.0
#: ``K(σ, σ) = σ³(1−σ)³/3`` ascending
K_DIAG = np.array([0.0, 0.0, 0.0, 1.0, -3.0, 3.0, -1.0]) / 3.0
#: relative allowance for rounding in the basin's lower bound (``≪ pmp_global_certificate_rel``)
ROUNDING_REL = 1e-11
#: 64 ulps of 1
EPS64 = 64.0 * 2.220446049250313e-16


@compilable
def shift_coeffs(coef: Any, x: float) -> Any:
    """Coefficients in ``h`` of ``p(x + h)`` (``coef`` ascending, 1-D)."""
    A = coef.copy()
    d = A.shape[0]
    for i in range(d - 1):
        for j in range(d - 2, i - 1, -1):
            A[j] = A[j] + x * A[j + 1]
    return A


@compilable
def stride(m: int, D: int, k: int) -> int:
    """The flat stride of variable ``k``."""
    out = 1
    for _ in range(m - 1 - k):
        out = out * (D + 1)
    return out


@compilable
def mul_lin(P: Any, c0: float, c: Any, m: int, D: int) -> Any:
    """``P·(c0 + Σ_k c_k h_k)`` (the degree never overflows ``D`` here)."""
    out = c0 * P
    for k in range(m):
        if c[k] != 0.0:
            post = stride(m, D, k)
            pre = P.shape[0] // (post * (D + 1))
            o3 = out.reshape(pre, D + 1, post)
            p3 = P.reshape(pre, D + 1, post)
            o3[:, 1:, :] = o3[:, 1:, :] + c[k] * p3[:, :-1, :]
    return out


@compilable
def affine_w(EX: Any, EY: Any, DEX: Any, DEY: Any, s: Any) -> Any:
    """Per axis ``(w*, W)`` at ``s`` (:func:`iamp.planners.pmp.basin.expansion`): ``w* = K⁻¹e``
    and ``W[:, k] = K⁻¹(∂e/∂σ_k − ∂K/∂σ_k w*)``, as ``w`` of shape ``(2, m)`` and ``W`` of
    shape ``(2, m, m)``; ``ok`` false where ``K(s)`` is not positive definite."""
    m = s.shape[0]
    sT = np.ascontiguousarray(s.reshape(m, 1))
    L, okv = chol(kmatrix(sT))
    w = np.zeros((2, m))
    W = np.zeros((2, m, m))
    for a in range(2):
        C = EX if a == 0 else EY
        D = DEX if a == 0 else DEY
        e = errors(C, sT)
        wa = backward(L, forward(L, e))
        R = np.zeros((m, m))
        for i in range(m):
            R[i, i] = horner(D[i], sT[i])[0]
        for k in range(m):
            v = np.zeros(m)
            for j in range(m):
                if j != k:
                    dkj = kern_ds(sT[k], sT[j])[0]
                    v[j] = dkj * wa[k, 0]
                    v[k] = v[k] + dkj * wa[j, 0]
            sk_ = s[k]
            wk = 1.0 - sk_
            v[k] = v[k] + sk_ * sk_ * (wk * wk) * (1.0 - 2.0 * sk_) * wa[k, 0]
            for i in range(m):
                R[i, k] = R[i, k] - v[i]
        Wa = backward(L, forward(L, R))
        for i in range(m):
            w[a, i] = wa[i, 0]
            for k in range(m):
                W[a, i, k] = Wa[i, k]
    return w, W, okv[0]


@compilable
def expansion(EX: Any, EY: Any, DEX: Any, DEY: Any, s: Any, D: int) -> Any:
    """Flat Taylor coefficients of the minorant ``G(s + h)`` of
    :mod:`iamp.planners.pmp.basin` (valid where no two times cross); ``ok`` false where
    ``K(s)`` is not positive definite."""
    m = s.shape[0]
    N = 1
    for _ in range(m):
        N = N * (D + 1)
    w, W, ok = affine_w(EX, EY, DEX, DEY, s)
    Kemb = np.zeros((m, m, N))
    for i in range(m):
        A = shift_coeffs(K_DIAG, s[i])
        si = stride(m, D, i)
        for a in range(A.shape[0]):
            Kemb[i, i, a * si] = A[a]
        for j in range(i + 1, m):
            lo = i if s[i] < s[j] else j
            hi = j if lo == i else i
            B = K_BELOW.copy()
            for b in range(4):
                B[:, b] = shift_coeffs(np.ascontiguousarray(K_BELOW[:, b]), s[lo])
            for a in range(4):
                B[a, :] = shift_coeffs(np.ascontiguousarray(B[a, :]), s[hi])
            sl = stride(m, D, lo)
            sh = stride(m, D, hi)
            for a in range(4):
                for b in range(4):
                    Kemb[i, j, a * sl + b * sh] = B[a, b]
            Kemb[j, i] = Kemb[i, j]
    G = np.zeros(N)
    for ax in range(2):
        C = EX if ax == 0 else EY
        for i in range(m):
            A = shift_coeffs(np.ascontiguousarray(C[i]), s[i])
            Ei = np.zeros(N)
            si = stride(m, D, i)
            for a in range(A.shape[0]):
                Ei[a * si] = A[a]
            G = G + mul_lin(Ei, 2.0 * w[ax, i], 2.0 * W[ax, i], m, D)
            T = np.zeros(N)
            for j in range(m):
                T = T + mul_lin(Kemb[i, j], w[ax, j], W[ax, j], m, D)
            G = G - mul_lin(T, w[ax, i], W[ax, i], m, D)
    return G, ok


@compilable
def min_eig(H: Any) -> Any:
    """The least eigenvalue of the symmetric ``H`` (cyclic Jacobi until the off-diagonal part is
    negligible, at most 50 sweeps)."""
    m = H.shape[0]
    A = H.copy()
    for _ in range(50):
        off = 0.0
        dia = 0.0
        for i in range(m):
            dia += A[i, i] * A[i, i]
            for j in range(i + 1, m):
                off += A[i, j] * A[i, j]
        if off <= 1e-36 * dia:  # the off-diagonal part moves the eigenvalues by ~1e-18 relative
            break
        for p in range(m):
            for q in range(p + 1, m):
                if A[p, q] != 0.0:
                    diff = A[q, q] - A[p, p]
                    if abs(A[p, q]) < 1e-30 * abs(diff):  # θ would overflow: t ≈ 1/(2θ)
                        t = A[p, q] / diff
                    else:
                        theta = diff / (2.0 * A[p, q])
                        t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                        if theta < 0.0:
                            t = -t
                    cs = 1.0 / np.sqrt(t * t + 1.0)
                    sn = t * cs
                    for k in range(m):
                        akp = A[k, p]
                        akq = A[k, q]
                        A[k, p] = cs * akp - sn * akq
                        A[k, q] = sn * akp + cs * akq
                    for k in range(m):
                        apk = A[p, k]
                        aqk = A[q, k]
                        A[p, k] = cs * apk - sn * aqk
                        A[q, k] = sn * apk + cs * aqk
    out = A[0, 0]
    for i in range(1, m):
        if A[i, i] < out:
            out = A[i, i]
    return out


@compilable
def degrees(m: int, D: int) -> Any:
    """The total degree of every flat coefficient."""
    N = 1
    for _ in range(m):
        N = N * (D + 1)
    deg = np.zeros(N, dtype=np.int64)
    for f in range(N):
        x = f
        t = 0
        for _ in range(m):
            t += x % (D + 1)
            x = x // (D + 1)
        deg[f] = t
    return deg


@compilable
def basin_radius(c: Any, m: int, D: int, gap: float, delta: float) -> Any:
    """``(ρ, L)``: the radius of the basin box whose flat minorant coefficients are ``c``
    and its lower bound ``L = c₀ − |g|₁ρ − rounding`` (:func:`iamp.planners.pmp.basin.basin_box`);
    ``ρ = 0`` when the quadratic part is not positive definite."""
    deg = degrees(m, D)
    g1 = 0.0
    H = np.empty((m, m))
    hmax = 0.0
    for i in range(m):
        si = stride(m, D, i)
        g1 += abs(c[si])
        for j in range(m):
            H[i, j] = c[si + stride(m, D, j)] * (1.0 if i == j else 0.5)
            if abs(H[i, j]) > hmax:
                hmax = abs(H[i, j])
    lam = min_eig(H) - 1e-12 * hmax
    if not lam > 0.0:
        return 0.0, -np.inf
    dmax = m * D
    Ck = np.zeros(dmax + 1)
    for f in range(c.shape[0]):
        if deg[f] >= 3:
            Ck[deg[f]] += abs(c[f])
    rho_max = min(0.499 * gap, 0.5)
    if g1 > 0.0:
        rho_max = min(rho_max, delta / g1)
    rho = rho_max
    if excess(Ck, rho_max) > lam:
        lo = 0.0
        hi = rho_max
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if excess(Ck, mid) <= lam:
                lo = mid
            else:
                hi = mid
        rho = lo
    if rho <= 0.0:
        return 0.0, -np.inf
    pw = np.empty(dmax + 1)
    pw[0] = 1.0
    for k in range(1, dmax + 1):
        pw[k] = pw[k - 1] * rho
    tot = 0.0
    for f in range(c.shape[0]):
        tot += abs(c[f]) * pw[deg[f]]
    roundoff = EPS64 * tot + ROUNDING_REL * abs(c[0])
    return rho, c[0] - g1 * rho - roundoff


@compilable
def excess(Ck: Any, rho: float) -> Any:
    """``Σ_{k≥3} C_k ρ^{k−2}``."""
    out = 0.0
    p = rho
    for k in range(3, Ck.shape[0]):
        out += Ck[k] * p
        p = p * rho
    return out


@compilable
def col_sums(W: Any, m: int, D: int) -> Any:
    """``Σ_f W[f]`` over the ``(D+1)^m`` flat coefficients (rows of ``W``), one variable at a
    time (the first first), each in ascending order: a fixed order of the additions."""
    X = np.ascontiguousarray(W)
    rest = W.shape[0]
    k = W.shape[1]
    for _ in range(m):
        rest = rest // (D + 1)
        X3 = X.reshape(D + 1, rest, k)
        acc = X3[0].copy()
        for j in range(1, D + 1):
            acc = acc + X3[j]
        X = acc
    return X.reshape(k)


@compilable
def box_bound(coeffs: Any, s: Any, c: Any, r: Any, D: int) -> Any:
    r"""A lower bound of ``q`` on each box ``c ± r`` (rows) from a basin's minorant (flat
    ``coeffs`` at the centre ``s``; ``m ≤ 2``) on the boxes whose times keep the centre's
    order, ``−inf`` elsewhere (:meth:`iamp.planners.pmp.basin.Basin.box_bound`)."""
    n = c.shape[0]
    m = c.shape[1]
    out = np.full(n, -np.inf)
    ok = np.ones(n, dtype=np.bool_)
    for i in range(m):
        for j in range(m):
            if s[i] < s[j]:
                ok = ok & (c[:, i] + r[:, i] < c[:, j] - r[:, j])
    idx = np.nonzero(ok)[0]
    k = idx.shape[0]
    if k == 0:
        return out
    N = coeffs.shape[0]
    # the coefficients of every box, boxes last: A[f, b]
    A = np.empty((N, k))
    for f in range(N):
        A[f] = coeffs[f]
    rr = np.empty((m, k))
    for a in range(m):
        h = np.empty(k)
        for b in range(k):
            h[b] = c[idx[b], a] - s[a]
            rr[a, b] = r[idx[b], a]
        post = stride(m, D, a)
        pre = N // (post * (D + 1))
        hrep = np.empty(post * k)
        for p in range(post):
            hrep[p * k:(p + 1) * k] = h
        A3 = A.reshape(pre, D + 1, post * k)
        for i in range(D):
            for j in range(D - 1, i - 1, -1):
                A3[:, j, :] = A3[:, j, :] + hrep * A3[:, j + 1, :]
    c0 = A[0].copy()
    g = np.empty((m, k))
    for i in range(m):
        g[i] = A[stride(m, D, i)]
    if m == 1:
        lam = A[2].copy()
    else:
        a11 = A[2 * stride(m, D, 0)]
        a22 = A[2 * stride(m, D, 1)]
        a12 = 0.5 * A[stride(m, D, 0) + stride(m, D, 1)]
        half = 0.5 * (a11 - a22)
        lam = 0.5 * (a11 + a22) - np.sqrt(half * half + a12 * a12)
    pos = lam > 0.0
    quad = np.zeros(k)
    lin = np.zeros(k)
    sq = np.zeros(k)
    for i in range(m):
        d = -g[i] / (2.0 * lam)
        d = np.where(d < -rr[i], -rr[i], np.where(d > rr[i], rr[i], d))
        quad = quad + (g[i] * d + lam * d * d)
        lin = lin + np.abs(g[i]) * rr[i]
        sq = sq + rr[i] * rr[i]
    quad = np.where(pos, quad, -lin + np.where(lam < 0.0, lam, 0.0) * sq)
    # |c'_α| r^α per coefficient and box, summed in a fixed order (col_sums)
    pw = np.empty((m, D + 1, k))
    for i in range(m):
        pw[i, 0] = 1.0
        for a in range(1, D + 1):
            pw[i, a] = pw[i, a - 1] * rr[i]
    deg = degrees(m, D)
    W = np.abs(A)
    Wr = np.empty((N, k))
    for f in range(N):
        p = pw[m - 1, f % (D + 1)]
        if m == 2:
            p = p * pw[0, f // (D + 1)]
        W[f] = W[f] * p
        if deg[f] >= 3:
            Wr[f] = W[f]
        else:
            Wr[f] = 0.0
    tot = col_sums(W, m, D)
    rem = col_sums(Wr, m, D)
    rnd = EPS64 * tot + ROUNDING_REL * np.abs(c0)
    val = c0 + quad - rem - rnd
    for b in range(k):
        out[idx[b]] = val[b]
    return out
