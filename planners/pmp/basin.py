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

from . import search_kernels as sk
from .fixed import ValueFunction

FloatArray = npt.NDArray[np.float64]

#: most vehicles with a basin box (the dense expansion has ``9^m`` coefficients)
MAX_M = 5
#: most vehicles for :meth:`Basin.box_bound` on every open box (its Taylor shift costs
#: ``m·9^(m+1)``: it pays for two vehicles, not for three)
BOX_BOUND_MAX_M = 2


@dataclass(frozen=True)
class Basin:
    """``q ≥ lower`` on every box inside ``centre ± radius`` (sup-norm ball)."""

    centre: FloatArray
    radius: float
    lower: float
    #: the flat Taylor coefficients of the minorant at ``centre``
    #: (:func:`~iamp.planners.pmp.search_kernels.expansion`)
    coeffs: FloatArray
    #: their degree per variable
    degree: int

    def contains(self, c: FloatArray, r: FloatArray) -> npt.NDArray[np.bool_]:
        """Which boxes ``c ± r`` (rows) lie inside the basin box."""
        out: npt.NDArray[np.bool_] = np.all(np.abs(c - self.centre) + r <= self.radius, axis=-1)
        return out

    def box_bound(self, c: FloatArray, r: FloatArray) -> FloatArray:
        r"""A lower bound of ``q`` on each box ``c ± r`` (rows) from the minorant ``G`` of this
        basin's centre, valid on the boxes whose times keep the centre's order (``−inf``
        elsewhere; at most :data:`BOX_BOUND_MAX_M` vehicles): with ``G``'s Taylor
        coefficients ``c'`` at the box centre,
        :math:`c'_0 + \sum_i \min_{|\delta_i|\le r_i}(c'_{\epsilon_i}\delta_i + \lambda'\delta_i^2)
        - \sum_{|\alpha|\ge3}|c'_\alpha| r^\alpha` (``λ'`` the least eigenvalue of the
        quadratic part): second order, so boxes next to the minimiser are decided at their
        own scale (:func:`iamp.planners.pmp.search_kernels.box_bound`)."""
        if c.shape[1] > BOX_BOUND_MAX_M:
            return np.full(c.shape[0], -np.inf)
        with np.errstate(all="ignore"):
            run = sk.kernel("box_bound")
            out: FloatArray = run(self.coeffs, self.centre, np.ascontiguousarray(c, dtype=np.float64),
                                  np.ascontiguousarray(r, dtype=np.float64), self.degree)
        return out


def degree(vf: ValueFunction) -> int:
    """``D``: the degree per variable of the dense expansion (8, or more for long error
    polynomials)."""
    return max(8, int(vf._EX.shape[1]))


def expansion(vf: ValueFunction, s: FloatArray) -> FloatArray:
    """Dense Taylor coefficients ``c[α]`` of ``G(s + h)`` (module docstring; shape
    ``(D+1,)*m``), valid where no two times cross
    (:func:`iamp.planners.pmp.search_kernels.expansion`); NaN if ``K(s)`` is singular."""
    s = np.ascontiguousarray(s, dtype=np.float64)
    D = degree(vf)
    with np.errstate(all="ignore"):
        c, ok = sk.kernel("expansion")(vf._EX, vf._EY, vf._DEX, vf._DEY, s, D)
    out: FloatArray = np.asarray(c, dtype=np.float64).reshape((D + 1,) * s.size)
    return out if ok else np.full_like(out, np.nan)


def basin_box(vf: ValueFunction, s: FloatArray, delta: float) -> Basin | None:
    """The basin box at ``s`` (module docstring) with ``L ≥ c₀ − δ``; ``None`` if the
    quadratic part is not positive definite (``s`` is not a strict local minimiser) or the
    number of vehicles is above :data:`MAX_M` (the dense expansion grows like ``9^m``)
    (:func:`iamp.planners.pmp.search_kernels.basin_radius`)."""
    s = np.ascontiguousarray(s, dtype=np.float64)
    m = s.size
    if m < 1 or m > MAX_M or not np.all((s > 0) & (s < 1)):
        return None
    gap = float(np.min(np.abs(s[:, None] - s[None, :]) + 2 * np.eye(m)))
    if gap <= 1e-6:
        return None
    c = expansion(vf, s).reshape(-1)
    if not np.all(np.isfinite(c)):
        return None
    D = degree(vf)
    with np.errstate(all="ignore"):
        rho, lower = sk.kernel("basin_radius")(c, m, D, gap, float(delta))
    if not rho > 0:
        return None
    return Basin(s.copy(), float(rho), float(lower), c, D)


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
