r"""Basin exclusion boxes: a rigorous lower bound of ``q`` on a whole box around a local
minimiser, so that the branch and bound need not refine down to ``√ε`` there.

Scaled units (``t_f = 1``), ``q(σ) = Σ_axis eᵀK⁻¹e`` (:mod:`iamp.planners.pmp.bound`).

The bound
---------
For every vector ``w``, :math:`q(\sigma) \ge g_w(\sigma) = 2w^\top e(\sigma) - w^\top K(\sigma)w`
(Fenchel; equality at :math:`w = K^{-1}e`).  At an expansion point ``s`` take ``w`` *affine* in
``σ``,

.. math::  w(\sigma) = w^* + W(\sigma - s),\qquad w^* = K(s)^{-1}e(s),\quad
           W = \partial_\sigma (K^{-1}e)\,(s),

per axis.  Then :math:`G(\sigma) = g_{w(\sigma)}(\sigma) \le q(\sigma)` everywhere (away from the
diagonals, where ``K ≻ 0``), and because ``g_w`` is a concave quadratic in ``w`` with Hessian
``−2K``, :math:`q - G = (K^{-1}e - w)^\top K (K^{-1}e - w) = O(|h|^4)`: ``G`` matches ``q`` to
third order at ``s``.  On a box that does not cross a diagonal :math:`\sigma_i = \sigma_j`,
each ``K_{ij}`` is one polynomial, so ``G`` is a polynomial in :math:`h = \sigma - s` (degree
8) whose Taylor coefficients :math:`G(s+h) = \sum_\alpha c_\alpha h^\alpha` are computed
exactly (dense coefficient arrays, :func:`expansion`).  With :math:`g_i = c_{\epsilon_i}`,
:math:`hᵀHh = \sum_{|\alpha|=2} c_\alpha h^\alpha`, :math:`\lambda = \lambda_{\min}(H)` and
:math:`C_k = \sum_{|\alpha|=k}|c_\alpha|`, for :math:`|h|_\infty = \rho' \le \rho`

.. math::  q(s+h) \ge G(s+h) \ge c_0 - |g|_1\rho' + \rho'^2\Big(\lambda -
           \sum_{k\ge3} C_k\rho'^{k-2}\Big) \ge c_0 - |g|_1\rho

as long as :math:`\sum_{k\ge 3} C_k\rho^{k-2} \le \lambda` (:func:`basin_box`).  So every box
inside :math:`s \pm \rho` has the lower bound :math:`L = c_0 - |g|_1\rho`; at a polished
minimiser ``g ≈ 0`` and ``ρ`` is also capped at ``δ/|g|_1`` so that ``L ≥ q(s) − δ`` (``δ``
far below the certificate's tolerance).  ``ρ`` is the scale on which ``q`` stops being
quadratic (typically ``10⁻²``), instead of the ``√ε ≈ 3·10⁻⁵`` boxes the mean-value bound
needs next to a minimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .fixed import ValueFunction, bridge_kernel, bridge_kernel_ds, bridge_variance_dt
from .taylor import taylor_shift

FloatArray = npt.NDArray[np.float64]

#: coefficients ``A[a, b]`` of ``s^a t^b`` of ``K(s, t) = s²(1−t)²(3t − s − 2st)/6`` (``s ≤ t``)
K_BELOW = np.zeros((4, 4))
for _b1, _v1 in ((0, 1.0), (1, -2.0), (2, 1.0)):
    for (_a2, _b2), _v2 in (((0, 1), 3.0), ((1, 0), -1.0), ((1, 1), -2.0)):
        K_BELOW[2 + _a2, _b1 + _b2] += _v1 * _v2 / 6.0
#: ``K(σ, σ) = σ³(1−σ)³/3`` ascending
K_DIAG = np.array([0.0, 0.0, 0.0, 1.0, -3.0, 3.0, -1.0]) / 3.0
#: most vehicles with a basin box (the dense expansion has ``9^m`` coefficients)
MAX_M = 5
#: most vehicles for :meth:`Basin.box_bound` on every open box (its Taylor shift costs
#: ``m·9^(m+1)``: it pays for two vehicles, not for three)
BOX_BOUND_MAX_M = 2
#: relative allowance for rounding in the basin's lower bound (``≪ pmp_global_certificate_rel``)
ROUNDING_REL = 1e-11


@dataclass(frozen=True)
class Basin:
    """``q ≥ lower`` on every box inside ``centre ± radius`` (sup-norm ball)."""

    centre: FloatArray
    radius: float
    lower: float
    coeffs: FloatArray

    def contains(self, c: FloatArray, r: FloatArray) -> npt.NDArray[np.bool_]:
        """Which boxes ``c ± r`` (rows) lie inside the basin box."""
        out: npt.NDArray[np.bool_] = np.all(np.abs(c - self.centre) + r <= self.radius, axis=-1)
        return out

    def box_bound(self, c: FloatArray, r: FloatArray) -> FloatArray:
        r"""A lower bound of ``q`` on each box ``c ± r`` (rows) from the minorant ``G`` of this
        basin's centre, valid on the boxes whose times keep the centre's order (``−inf``
        elsewhere): with ``G``'s Taylor coefficients ``c'`` at the box centre,
        :math:`c'_0 + \sum_i \min_{|\delta_i|\le r_i}(c'_{\epsilon_i}\delta_i + \lambda'\delta_i^2)
        - \sum_{|\alpha|\ge3}|c'_\alpha| r^\alpha` (``λ'`` the least eigenvalue of the
        quadratic part): second order, so boxes next to the minimiser are decided at their
        own scale."""
        n, m = c.shape
        s = self.centre
        lo, hi = c - r, c + r
        ok = np.ones(n, dtype=bool)
        for i in range(m):
            for j in range(m):
                if s[i] < s[j]:
                    ok &= hi[:, i] < lo[:, j]
        out = np.full(n, -np.inf)
        if not np.any(ok):
            return out
        h, rr = c[ok] - s, r[ok]
        k = h.shape[0]
        A = np.broadcast_to(self.coeffs, (k,) + self.coeffs.shape).copy()
        for a in range(m):
            B = np.moveaxis(A, a + 1, -1)
            A = np.moveaxis(taylor_shift(B, h[:, a].reshape((k,) + (1,) * (m - 1))), -1, a + 1)
        eye = np.eye(m, dtype=int)
        flat = A.reshape(k, -1)
        c0 = flat[:, 0]
        g = np.stack([A[(slice(None),) + tuple(eye[i])] for i in range(m)], axis=1)
        H = np.empty((k, m, m))
        for i in range(m):
            for j in range(m):
                H[:, i, j] = A[(slice(None),) + tuple(eye[i] + eye[j])] * (1.0 if i == j else 0.5)
        lam = np.linalg.eigvalsh(H)[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.clip(-g / (2 * lam[:, None]), -rr, rr)
        quad = np.where(lam > 0, np.sum(g * d + lam[:, None] * d * d, axis=1),
                        -np.sum(np.abs(g) * rr, axis=1) + np.minimum(lam, 0.0) * np.sum(rr * rr, axis=1))
        idx = np.indices(self.coeffs.shape).reshape(m, -1)
        deg = np.sum(idx, axis=0)
        pw = np.prod(rr[:, :, None] ** idx[None, :, :], axis=1)
        rem = np.sum(np.abs(flat[:, deg >= 3]) * pw[:, deg >= 3], axis=1)
        rnd = 64 * np.finfo(float).eps * np.sum(np.abs(flat) * pw, axis=1) + ROUNDING_REL * np.abs(c0)
        out[ok] = c0 + quad - rem - rnd
        return out


def _affine_w(vf: ValueFunction, s: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
    """Per axis ``(w*, W)``: ``w* = K⁻¹e`` and ``W[:, k] = K⁻¹(∂e/∂σ_k − ∂K/∂σ_k w*)`` at ``s``
    (any ``w`` keeps the bound valid; this one makes it third-order tight)."""
    m = s.size
    K = bridge_kernel(s[:, None], s[None, :], 1.0)
    dK = bridge_kernel_ds(s[:, None], s[None, :], 1.0)  # dK[i, j] = ∂₁K(σ_i, σ_j)
    dd = bridge_variance_dt(s, 1.0)
    out = []
    for C, D in ((vf._EX, vf._DEX), (vf._EY, vf._DEY)):
        e = np.array([np.polynomial.polynomial.polyval(s[i], C[i]) for i in range(m)])
        de = np.array([np.polynomial.polynomial.polyval(s[i], D[i]) for i in range(m)])
        w = np.linalg.solve(K, e)
        R = np.diag(de)
        for k in range(m):
            v = np.zeros(m)
            for j in range(m):
                if j != k:
                    v[j] = dK[k, j] * w[k]
                    v[k] += dK[k, j] * w[j]
            v[k] += dd[k] * w[k]
            R[:, k] -= v
        out.append((np.asarray(w, dtype=np.float64), np.asarray(np.linalg.solve(K, R), dtype=np.float64)))
    return out


def _mul_lin(P: FloatArray, c0: float, c: FloatArray) -> FloatArray:
    """``P·(c0 + Σ_k c_k h_k)`` for a dense coefficient array (degree never overflows)."""
    out = c0 * P
    m = P.ndim
    for k in range(m):
        if c[k] != 0.0:
            dst = tuple(slice(1, None) if a == k else slice(None) for a in range(m))
            src = tuple(slice(None, -1) if a == k else slice(None) for a in range(m))
            out[dst] += c[k] * P[src]
    return out


def _embed(shape: tuple[int, ...], axes: tuple[int, ...], A: FloatArray) -> FloatArray:
    """Dense array with the coefficients ``A`` (indexed by the variables ``axes``, ascending)."""
    P = np.zeros(shape)
    idx: list[int | slice] = [0] * len(shape)
    for a, n in zip(axes, A.shape):
        idx[a] = slice(0, n)
    P[tuple(idx)] = A
    return P


def expansion(vf: ValueFunction, s: FloatArray) -> FloatArray:
    """Dense Taylor coefficients ``c[α]`` of ``G(s + h)`` (module docstring; shape
    ``(D+1,)*m``), valid where no two times cross."""
    m = s.size
    de = vf._EX.shape[1] - 1
    D = max(8, de + 1)
    shape = (D + 1,) * m
    Kemb: dict[tuple[int, int], FloatArray] = {}
    for i in range(m):
        Kemb[(i, i)] = _embed(shape, (i,), taylor_shift(K_DIAG, np.asarray(s[i])))
        for j in range(i + 1, m):
            lo, hi = (i, j) if s[i] < s[j] else (j, i)
            A = taylor_shift(taylor_shift(K_BELOW.T, np.full(4, s[lo])).T, np.full(4, s[hi]))  # [a(lo), b(hi)]
            Kemb[(i, j)] = Kemb[(j, i)] = _embed(shape, (i, j), A if lo == i else A.T)
    G = np.zeros(shape)
    for (w, W), C in zip(_affine_w(vf, s), (vf._EX, vf._EY)):
        for i in range(m):
            Ei = _embed(shape, (i,), taylor_shift(C[i], np.asarray(s[i])))
            G += _mul_lin(Ei, 2.0 * w[i], 2.0 * W[i])
            T = np.zeros(shape)
            for j in range(m):
                T += _mul_lin(Kemb[(i, j)], w[j], W[j])
            G -= _mul_lin(T, w[i], W[i])
    return G


def basin_box(vf: ValueFunction, s: FloatArray, delta: float) -> Basin | None:
    """The basin box at ``s`` (module docstring) with ``L ≥ c₀ − δ``; ``None`` if the
    quadratic part is not positive definite (``s`` is not a strict local minimiser) or the
    number of vehicles is above :data:`MAX_M` (the dense expansion grows like ``9^m``)."""
    s = np.asarray(s, dtype=float)
    m = s.size
    if m < 1 or m > MAX_M or not np.all((s > 0) & (s < 1)):
        return None
    gap = float(np.min(np.abs(s[:, None] - s[None, :]) + 2 * np.eye(m)))
    if gap <= 1e-6:
        return None
    try:
        with np.errstate(all="ignore"):
            c = expansion(vf, s)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(c)):
        return None
    deg = np.sum(np.indices(c.shape), axis=0)
    eye = np.eye(m, dtype=int)
    g = np.array([c[tuple(eye[i])] for i in range(m)])
    H = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            H[i, j] = c[tuple(eye[i] + eye[j])] * (1.0 if i == j else 0.5)
    lam = float(np.linalg.eigvalsh(H)[0]) - 1e-12 * float(np.max(np.abs(H)))
    if not lam > 0:
        return None
    Ck = np.array([np.sum(np.abs(c[deg == k])) for k in range(3, int(deg.max()) + 1)])

    def excess(rho: float) -> float:
        return float(np.sum(Ck * rho ** np.arange(1, Ck.size + 1)))  # Σ C_k ρ^{k−2}

    rho_max = min(0.499 * gap, 0.5)
    g1 = float(np.sum(np.abs(g)))
    if g1 > 0:
        rho_max = min(rho_max, delta / g1)
    if excess(rho_max) <= lam:
        rho = rho_max
    else:
        lo, hi = 0.0, rho_max
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if excess(mid) <= lam:
                lo = mid
            else:
                hi = mid
        rho = lo
    if rho <= 0:
        return None
    # rounding (of the coefficients, and of q itself when K is ill-conditioned): far below
    # the certificate's tolerance, but accounted for
    roundoff = 64 * np.finfo(float).eps * float(np.sum(np.abs(c) * rho ** deg)) + ROUNDING_REL * abs(float(c[(0,) * m]))
    return Basin(s.copy(), rho, float(c[(0,) * m]) - g1 * rho - roundoff, c)


def in_basins(basins: list[Basin], c: FloatArray, r: FloatArray) -> bool:
    """Whether the box ``c ± r`` (one row) lies inside one of ``basins``."""
    return any(bool(np.all(np.abs(c - b.centre) + r <= b.radius)) for b in basins)


def add_basin(vf: ValueFunction, basins: list[Basin], s: FloatArray) -> None:
    """Append the basin box at ``s`` (``δ`` a quarter of the certificate's tolerance on
    ``J̃(s)``) unless ``s`` already lies in one or has none."""
    from iamp.core.tolerances import TOLERANCES

    if not np.all(np.isfinite(s)) or in_basins(basins, s, np.zeros_like(s)):
        return
    q = float(vf.quad_sigma(s[None, :])[0])
    if not np.isfinite(q):
        return
    b = basin_box(vf, s, 0.25 * TOLERANCES["pmp_global_certificate_rel"] * (vf.scaled.jbar + 0.5 * q))
    if b is not None:
        basins.append(b)
