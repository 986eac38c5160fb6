r"""Branch and bound on the closed-form value function: a certificate that the contact times
found are the global minimiser (to ``pmp_global_certificate_rel``).

In scaled units (``t_f = 1``), :math:`\tilde J(\sigma) = \tilde J_0 + \tfrac12\sum_{\text{axis}}
q_{\text{axis}}(\sigma)` with :math:`q = e^\top K^{-1} e`.  Three lower bounds of ``q`` over a box
:math:`B = \prod_i [c_i - r_i, c_i + r_i]` are combined (their maximum):

1. **Fenchel / mean value.**  For any vector ``w``, :math:`q \ge g_w = 2w^\top e - w^\top K w`
   (equality at :math:`w = K^{-1}e`).  ``g_w`` is a sum of one- and two-variable polynomials,
   so with ``w`` taken at the box centre,
   :math:`g_w(\sigma) \ge g_w(c) - \sum_i r_i \max_B |\partial_i g_w|`, where
   :math:`\partial_i g_w = 2w_i e_i' - 2w_i\sum_{j\ne i} w_j\,\partial_1K(\sigma_i,\sigma_j) -
   w_i^2\, dK_{ii}/d\sigma` is bounded by exact Taylor expansions of each polynomial at the
   centre (:func:`poly_range`; both pieces of ``K`` where the box straddles the diagonal).
   Because ``∇g_w(c) = ∇q(c)``, the bound is exact to second order near a minimum.
2. **One vehicle.**  :math:`q \ge (e_{x,i}^2 + e_{y,i}^2)/K_{ii}` (``w`` = unit vector), with
   :math:`\min_B e^2` from the Taylor range and :math:`\max_B K_{ii}` exact (unimodal).  This
   grows without bound at ``σ_i → 0, 1`` where the first bound cannot.
3. **Two vehicles at the same time.**  With :math:`w = \epsilon_i - \epsilon_j`,
   :math:`q \ge (e_i - e_j)^2 / \operatorname{Var}(s(\sigma_i)-s(\sigma_j))` (Cauchy–Schwarz) and,
   since :math:`s(\sigma_i)-s(\sigma_j) = \int_{\sigma_j}^{\sigma_i} v`, the variance is at most
   :math:`(\sigma_i-\sigma_j)^2 \max \operatorname{Var} v` over the times between.  The speed
   variance of the bridge is :math:`\partial_s\partial_t K|_{s=t} = x(1-3x)`,
   :math:`x = \sigma(1-\sigma)` (:func:`speed_variance_max`; at most ``1/12``, and small
   near the ends): infinite on the diagonal unless the corners meet.

A box is discarded when its bound is within ``pmp_global_certificate_rel`` of the best
value found; the others are halved along every side at least half as long as their
longest one.  Box centres better than the
incumbent are polished by Newton and replace it.  The search is *certified* when no box
remains within the budget.

Two more bounds come from the polished minimisers (:mod:`iamp.planners.pmp.basin`): every
box inside a basin box has that basin's lower bound, and (two vehicles) every open box is
also bounded by each basin's third-order minorant ``G`` (:meth:`~iamp.planners.pmp.basin.Basin.box_bound`), which
decides the boxes next to a minimiser at their own scale.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from iamp.core.tolerances import TOLERANCES

from .fixed import bridge_kernel
from .taylor import taylor_shift as taylor_shift

if TYPE_CHECKING:
    from .basin import Basin
    from .fixed import ValueFunction

FloatArray = npt.NDArray[np.float64]


def _poly2(terms: dict[tuple[int, int], float]) -> FloatArray:
    A = np.zeros((4, 4))
    for (a, b), v in terms.items():
        A[a, b] += v
    return A


def _mul2(p: dict[tuple[int, int], float], q: dict[tuple[int, int], float]) -> dict[tuple[int, int], float]:
    out: dict[tuple[int, int], float] = {}
    for (a1, b1), v1 in p.items():
        for (a2, b2), v2 in q.items():
            out[(a1 + a2, b1 + b2)] = out.get((a1 + a2, b1 + b2), 0.0) + v1 * v2
    return out


# ∂K(s,t)/∂s on each side of the diagonal (t_f = 1), as coefficients of s^a t^b
_DK_BELOW = _poly2(_mul2({(0, 0): 0.5, (0, 1): -1.0, (0, 2): 0.5}, {(1, 1): 2.0, (2, 0): -1.0, (2, 1): -2.0}))
_DK_ABOVE = _poly2(_mul2({(0, 2): 0.5}, {(0, 0): 1.0, (1, 0): -4.0, (2, 0): 3.0, (1, 1): 2.0, (2, 1): -2.0}))
# d K(σ,σ)/dσ = σ²(1−σ)²(1−2σ)
_DKDIAG = np.array([0.0, 0.0, 1.0, -4.0, 5.0, -2.0])


def poly_range(C: FloatArray, c: FloatArray, r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rigorous ``(lo, hi)`` of each row polynomial on ``[c − r, c + r]``:
    ``p(c) ∓ Σ_{k≥1} |p^{(k)}(c)/k!| r^k`` (exact Taylor expansion)."""
    A = taylor_shift(C, c)
    k = np.arange(A.shape[-1])
    dev = np.sum(np.abs(A[..., 1:]) * r[..., None] ** k[1:], axis=-1)
    return A[..., 0] - dev, A[..., 0] + dev


def poly2_range(A2: FloatArray, cs: FloatArray, ct: FloatArray, rs: FloatArray,
                rt: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`poly_range` for one bivariate polynomial (``A2[a, b]`` of ``s^a t^b``) over
    boxes ``[cs ± rs] × [ct ± rt]`` (arrays of one shape)."""
    n = cs.shape
    B = np.broadcast_to(A2, n + A2.shape).copy()
    # shift in s: for each t-power b
    Bs = np.moveaxis(B, -2, -1)  # (..., b, a)
    Bs = taylor_shift(Bs, np.broadcast_to(cs[..., None], n + (A2.shape[1],)))
    B = np.moveaxis(Bs, -1, -2)  # (..., a, b)
    B = taylor_shift(B, np.broadcast_to(ct[..., None], n + (A2.shape[0],)))
    pa = rs[..., None, None] ** np.arange(A2.shape[0])[:, None]
    pb = rt[..., None, None] ** np.arange(A2.shape[1])[None, :]
    W = np.abs(B) * pa * pb
    dev = np.sum(W, axis=(-1, -2)) - W[..., 0, 0]
    return B[..., 0, 0] - dev, B[..., 0, 0] + dev


def _min_sq(lo: FloatArray, hi: FloatArray) -> FloatArray:
    out: FloatArray = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(lo * lo, hi * hi))
    return out


def speed_variance_max(a: FloatArray, b: FloatArray) -> FloatArray:
    """``max Var v(σ) = x(1 − 3x)``, ``x = σ(1 − σ)``, over ``σ ∈ [a, b]`` (exact: ``x`` is
    unimodal in ``σ`` with its peak at ``1/2``, ``x(1 − 3x)`` peaks at ``x = 1/6``)."""
    xa, xb = a * (1 - a), b * (1 - b)
    pk = np.clip(0.5, a, b)
    x = np.clip(1.0 / 6.0, np.minimum(xa, xb), pk * (1 - pk))
    out: FloatArray = x * (1 - 3 * x)
    return out


def lower_bound(vf: ValueFunction, c: FloatArray, r: FloatArray) -> FloatArray:
    """A rigorous lower bound of ``q(σ) = Σ_axis eᵀK⁻¹e`` on each box ``c ± r`` (``(n, m)``)."""
    n, m = c.shape
    lo, hi = c - r, c + r
    E = (vf._EX, vf._EY)
    D = (vf._DEX, vf._DEY)
    # ranges of e_i on each box, per axis: (n, m)
    rng = [poly_range(np.broadcast_to(C, (n,) + C.shape), c, r) for C in E]
    # 2. one vehicle
    peak = np.clip(0.5, lo, hi)
    kmax = peak**3 * (1 - peak) ** 3 / 3
    with np.errstate(divide="ignore", invalid="ignore"):
        single = (_min_sq(*rng[0]) + _min_sq(*rng[1])) / kmax
    single = np.where(np.isnan(single), 0.0, single)
    best = np.max(single, axis=1)
    # 3. pairs near the diagonal
    for i in range(m):
        for j in range(i + 1, m):
            num = sum(_min_sq(rg[0][:, i] - rg[1][:, j], rg[1][:, i] - rg[0][:, j]) for rg in rng)
            dist = np.maximum(np.abs(hi[:, i] - lo[:, j]), np.abs(hi[:, j] - lo[:, i]))
            vmax = speed_variance_max(np.minimum(lo[:, i], lo[:, j]), np.maximum(hi[:, i], hi[:, j]))
            with np.errstate(divide="ignore", invalid="ignore"):
                pb = num / (dist**2 * vmax)
            best = np.maximum(best, np.where(np.isnan(pb), 0.0, pb))
    # 1. Fenchel + mean value
    K = bridge_kernel(c[:, :, None], c[:, None, :], 1.0)
    ridge = 1e-13 * np.max(np.abs(np.diagonal(K, axis1=1, axis2=2)), axis=1) + 1e-300
    Kr = K + ridge[:, None, None] * np.eye(m)
    dkd = poly_range(np.broadcast_to(_DKDIAG, (n, m, _DKDIAG.size)), c, r)
    cross: dict[tuple[int, int], tuple[FloatArray, FloatArray]] = {}
    for i in range(m):
        for j in range(m):
            if i == j:
                continue
            parts = []
            if np.any(lo[:, i] < hi[:, j]):
                parts.append(poly2_range(_DK_BELOW, c[:, i], c[:, j], r[:, i], r[:, j]))
            if np.any(hi[:, i] > lo[:, j]):
                parts.append(poly2_range(_DK_ABOVE, c[:, i], c[:, j], r[:, i], r[:, j]))
            below_only = hi[:, i] <= lo[:, j]
            above_only = lo[:, i] >= hi[:, j]
            if len(parts) == 2:
                bl, ab = parts
                plo = np.where(below_only, bl[0], np.where(above_only, ab[0], np.minimum(bl[0], ab[0])))
                phi = np.where(below_only, bl[1], np.where(above_only, ab[1], np.maximum(bl[1], ab[1])))
            else:
                plo, phi = parts[0]
            cross[(i, j)] = (plo, phi)
    # the gradients of the two axes cancel at a minimum: sum their intervals before the slack
    g0 = np.zeros(n)
    Glo = np.zeros((n, m))
    Ghi = np.zeros((n, m))
    for C, DC in zip(E, D):
        e = np.stack([np.polynomial.polynomial.polyval(c[:, i], C[i]) for i in range(m)], axis=1)
        try:
            w = np.linalg.solve(Kr, e[..., None])[..., 0]
        except np.linalg.LinAlgError:
            w = np.zeros((n, m))
        w = np.where(np.isfinite(w), w, 0.0)
        g0 += 2 * np.sum(w * e, axis=1) - np.einsum("ni,nij,nj->n", w, K, w)
        de_lo, de_hi = poly_range(np.broadcast_to(DC, (n,) + DC.shape), c, r)
        for i in range(m):
            glo, ghi = _scale(2 * w[:, i], de_lo[:, i], de_hi[:, i])
            dlo, dhi = _scale(-w[:, i] ** 2, dkd[0][:, i], dkd[1][:, i])
            glo, ghi = glo + dlo, ghi + dhi
            for j in range(m):
                if j != i:
                    xlo, xhi = _scale(-2 * w[:, i] * w[:, j], *cross[(i, j)])
                    glo, ghi = glo + xlo, ghi + xhi
            Glo[:, i] += glo
            Ghi[:, i] += ghi
    slack = np.sum(r * np.maximum(np.abs(Glo), np.abs(Ghi)), axis=1)
    fench = np.maximum(g0 - slack, 0.0)
    fench = np.where(np.isfinite(fench), fench, 0.0)
    out: FloatArray = np.maximum(best, fench)
    return out


def _scale(k: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Interval ``k·[lo, hi]``."""
    a, b = k * lo, k * hi
    return np.minimum(a, b), np.maximum(a, b)


def _cut(r: FloatArray) -> npt.NDArray[np.bool_]:
    """The sides :func:`_split` halves: those at least half as long as the box's longest."""
    out: npt.NDArray[np.bool_] = r >= 0.5 * np.max(r, axis=1, keepdims=True)
    return out


def _split(c: FloatArray, r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Halve every box along each side at least half as long as its longest one."""
    m = c.shape[1]
    cut = _cut(r)
    rn = np.where(cut, 0.5 * r, r)
    cs, rs = [], []
    for signs in np.ndindex(*([2] * m)):
        sg = np.array(signs, dtype=float) * 2 - 1
        child = c + np.where(cut, sg * rn, 0.0)
        keep = np.all(cut | (sg > 0), axis=1)  # a side that is not cut yields one child, not two
        cs.append(child[keep])
        rs.append(rn[keep])
    return np.vstack(cs), np.vstack(rs)


@dataclass
class BoundResult:
    sigma: FloatArray
    q: float
    certified: bool
    boxes: int


def branch_and_bound(vf: ValueFunction, s_best: FloatArray, q_best: float,
                     polish: Callable[[FloatArray], tuple[FloatArray, float]], max_boxes: int = 200_000,
                     progress: Callable[[int, int], None] | None = None,
                     basins: list[Basin] | None = None) -> BoundResult:
    """Certify (or improve) ``s_best`` as the global minimiser of ``q`` over ``(0, 1)^m``.

    ``basins`` (:mod:`iamp.planners.pmp.basin`, extended in place) give the lower bound of
    every box inside one of them; each polished improvement adds its own basin box."""
    m = s_best.size
    eps = TOLERANCES["pmp_global_certificate_rel"]
    jbar = vf.scaled.jbar
    from .basin import BOX_BOUND_MAX_M, add_basin, in_basins

    basins = [] if basins is None else basins
    c = np.full((1, m), 0.5)
    r = np.full((1, m), 0.5)
    for _ in range(max(1, 6 // m)):  # start from a coarse grid of boxes
        c, r = _split(c, r)
    evaluated = 0
    truncated = False

    def uncertified(c: FloatArray, s_best: FloatArray, q_best: float) -> BoundResult:
        """Budget spent: not certified; at least polish from the most promising boxes left."""
        qc = vf.quad_sigma(c)
        for k in np.argsort(qc)[:32]:
            if np.isfinite(qc[k]):
                s_new, q_new = polish(c[k])
                if q_new < q_best:
                    s_best, q_best = s_new, q_new
        return BoundResult(s_best, q_best, False, evaluated)

    while c.shape[0]:
        evaluated += c.shape[0]
        if evaluated > max_boxes:
            return uncertified(c, s_best, q_best)
        qc = vf.quad_sigma(c)
        k = int(np.argmin(qc))
        if qc[k] < q_best and not in_basins(basins, c[k], r[k]):
            s_new, q_new = polish(c[k])  # the polished, verified value (inf if untrusted)
            add_basin(vf, basins, s_new)
            if q_new < q_best:
                s_best, q_best = s_new, q_new
        lb = lower_bound(vf, c, r)
        for b in basins:
            lb = np.where(b.contains(c, r), np.maximum(lb, b.lower), lb)
        J_best = jbar + 0.5 * q_best
        keep = jbar + 0.5 * lb < J_best - eps * abs(J_best)
        for b in basins if m <= BOX_BOUND_MAX_M else ():  # the basins' minorants, on the boxes still open
            if np.any(keep):
                near = np.nonzero(keep)[0]
                lb[near] = np.maximum(lb[near], b.box_bound(c[near], r[near]))
                keep = jbar + 0.5 * lb < J_best - eps * abs(J_best)
        c, r, lb = c[keep], r[keep], lb[keep]
        if progress is not None:
            progress(min(evaluated, max_boxes), max_boxes)
        if not c.shape[0]:
            break
        children = 2 ** np.sum(_cut(r), axis=1)
        if evaluated + int(np.sum(children)) > max_boxes:
            # the next level would overrun the budget (and memory: up to 2^m children a box):
            # no certificate any more; go on with the boxes of least lower bound that fit
            truncated = True
            order = np.argsort(lb, kind="mergesort")  # stable: the same boxes on every machine
            take = order[np.cumsum(children[order]) <= max_boxes - evaluated]
            if take.size == 0:
                return uncertified(c, s_best, q_best)
            c, r = c[take], r[take]
        c, r = _split(c, r)
    return BoundResult(s_best, q_best, not truncated, evaluated)
