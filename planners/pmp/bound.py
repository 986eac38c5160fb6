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
   centre (:func:`~iamp.planners.pmp.search_kernels.shift_range`; both pieces of ``K`` where the
   box straddles the diagonal).
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

from . import search_kernels as sk
from .search_kernels import speed_variance_max as speed_variance_max
from .taylor import taylor_shift as taylor_shift

if TYPE_CHECKING:
    from .basin import Basin
    from .fixed import ValueFunction

FloatArray = npt.NDArray[np.float64]


def lower_bound(vf: ValueFunction, c: FloatArray, r: FloatArray) -> FloatArray:
    """A rigorous lower bound of ``q(σ) = Σ_axis eᵀK⁻¹e`` on each box ``c ± r`` (``(n, m)``):
    the three bounds of the module docstring (:func:`iamp.planners.pmp.search_kernels.lower_bound`)."""
    c = np.ascontiguousarray(c, dtype=np.float64)
    r = np.ascontiguousarray(r, dtype=np.float64)
    with np.errstate(all="ignore"):
        out: FloatArray = sk.kernel("lower_bound")(vf._EX, vf._EY, vf._DEX, vf._DEY, c, r)
    return out


def _cut(r: FloatArray) -> npt.NDArray[np.bool_]:
    """The sides :func:`_split` halves: those at least half as long as the box's longest."""
    out: npt.NDArray[np.bool_] = r >= 0.5 * np.max(r, axis=1, keepdims=True)
    return out


def _split(c: FloatArray, r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Halve every box along each side at least half as long as its longest one
    (:func:`iamp.planners.pmp.search_kernels.split`)."""
    run = sk.kernel("split")
    cs, rs = run(np.ascontiguousarray(c, dtype=np.float64), np.ascontiguousarray(r, dtype=np.float64))
    return cs, rs


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
