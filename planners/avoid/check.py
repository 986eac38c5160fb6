r"""Checks of the avoidance QP (SPEC §10): which half-plane comes first, the recomputed KKT
conditions, and the exact crossing time of a solution.

KKT conditions of :math:`\min \tfrac12 z^\top P z + q^\top z` s.t. :math:`l \le Az \le u`
with multipliers :math:`y` (OSQP's convention, :math:`L = \tfrac12 z^\top Pz + q^\top z +
y^\top Az` plus the bounds' support terms), recomputed from the data, each relative to the
largest magnitude among its terms (at least 1):

.. math::

    r_{\text{stat}} = \|Pz + q + A^\top y\|_\infty, \quad
    r_{\text{primal}} = \|Az - \Pi_{[l,u]}(Az)\|_\infty, \quad
    r_{\text{sign}} = \max_{i \in \mathcal I} \max(-y_i, 0), \quad
    r_{\text{compl}} = \max_{i \in \mathcal I} |y_i|\,(u_i - a_i^\top z),

with :math:`\mathcal I` the inequality rows (``l = −∞``, so the multiplier must be
:math:`\ge 0` and vanish unless the row binds); the relative complementarity divides by
:math:`\max(1, z^\top P z)` (a multiplier times a slack has the unit of the cost).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy import optimize

from iamp.core.errors import ScenarioError
from iamp.core.polyroots import roots_in_unit_interval
from iamp.core.problem import Problem
from iamp.core.trajectory_pieces import shifted_poly

from ..qp.backends.base import compressed, matvec
from .data import HalfPlane

FloatArray = NDArray[np.float64]

AXIS_NAMES = ("H_x", "H_y")
#: Start/end states inside a region by less than this [m] count as on its boundary.
BOUNDARY_TOL_M = 1e-9


@dataclass
class Candidate:
    """One solved crossing-time candidate."""

    phases: tuple[tuple[int, int, int, int], ...]
    status: str
    cost: float
    z: FloatArray
    y: FloatArray
    on: NDArray[np.bool_]
    sol: Any


def crossing_orders(problem: Problem) -> tuple[list[list[tuple[int, int]]], str | None]:
    """Per vehicle, the possible ``(first, second)`` half-plane orders (0 = H_x, 1 = H_y).

    Returns ``(orders, reason)``; ``reason`` says why no safe plan exists (a start or end
    state inside a safety region) and is ``None`` otherwise.  Raises
    :class:`~iamp.core.errors.ScenarioError` naming the vehicle when a start or end state
    lies outside the region but in neither half-plane, or when no order leads from the
    start's half-plane to another at the end.
    """
    ego = problem.ego
    ends = (("initial", 0.0, ego.x0, ego.y0), ("final", problem.tf, ego.xf, ego.yf))
    orders: list[list[tuple[int, int]]] = []
    for i, v in enumerate(problem.vehicles):
        ax, ay = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        inside: list[str] = []
        member: dict[str, set[int]] = {}
        for label, t, x, y in ends:
            xs = float(v.position(t))
            dx, dy = x - xs, y - v.y
            if abs(dx) < ax - BOUNDARY_TOL_M and abs(dy) < ay - BOUNDARY_TOL_M:
                inside.append(f"the ego's {label} state (s_x = {x:g} m, s_y = {y:g} m at t = {t:g} s) lies inside "
                              f"vehicle {v.name}'s safety region (x in [{xs - ax:.2f}, {xs + ax:.2f}] m, "
                              f"y in [{v.y - ay:.2f}, {v.y + ay:.2f}] m)")
                continue
            planes = (HalfPlane(v, "x"), HalfPlane(v, "y"))
            s = (x, y)
            member[label] = {a for a in (0, 1)
                             if float(planes[a].margin(np.array(t), np.array(s[a]))) >= -BOUNDARY_TOL_M}
            if not member[label]:
                side, lat = v.corner.split("-")
                other = f"{'rear' if side == 'front' else 'front'}-{lat}"
                raise ScenarioError(
                    f"vehicle {v.name}: corner {v.corner!r} does not describe the manoeuvre: the ego's {label} state "
                    f"(s_x = {x:g} m, s_y = {y:g} m at t = {t:g} s) is outside its safety region but in neither "
                    f"{planes[0].describe()} nor {planes[1].describe()} (try {other!r})",
                    f"vehicles[{i}].corner", getattr(ego, "source", None))
        if inside:
            return [], "; ".join(inside) + ": no safe plan exists"
        pairs = [(f, s) for f in sorted(member["initial"]) for s in sorted(member["final"]) if f != s]
        if not pairs:
            only = AXIS_NAMES[next(iter(member["initial"]))]
            raise ScenarioError(
                f"vehicle {v.name}: the ego starts and ends in {only} only, so corner {v.corner!r} names no "
                f"crossing (SPEC §10 needs the start in one half-plane and the end in the other)",
                f"vehicles[{i}].corner", getattr(ego, "source", None))
        orders.append(pairs)
    return orders, None


def kkt_conditions(P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray, u: FloatArray,
                   z: FloatArray, y: FloatArray, n_eq: int, lower: sp.spmatrix | None = None) -> dict[str, float]:
    """The four relative KKT residuals of the module docstring (rows ``>= n_eq`` are the
    one-sided inequalities ``a_i z <= u_i``); ``P`` is the upper triangle of the cost Hessian and
    ``lower``, when the caller keeps it, its strict lower part ``triu(P, 1).T``
    (:class:`KKTCheck` of the one point)."""
    return KKTCheck(P, q, A, l, u, n_eq, lower)(z, y)


class KKTCheck:
    """:func:`kkt_conditions` of any point ``(z, y)`` of one QP: what depends on the QP alone
    (``P``'s two triangles, ``Aᵀ``, the largest finite bound) is set up once, so checking a second
    point (the backend's answer to the same QP) repeats none of it; the same numbers."""

    def __init__(self, P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray, u: FloatArray, n_eq: int,
                 lower: sp.spmatrix | None = None) -> None:
        self.Pu = P if type(P) is sp.csc_matrix else sp.csc_matrix(P)  # the same arrays, the same products
        self.lower = sp.triu(self.Pu, 1).T if lower is None else lower
        self.A = A
        # Aᵀ of a CSC matrix is the CSR matrix of its own three arrays (what ``A.T`` builds, without
        # the constructor's checks: :func:`~iamp.planners.qp.backends.base.compressed`)
        self.AT = (compressed(sp.csr_matrix, A.data, A.indices, A.indptr, (A.shape[1], A.shape[0]))
                   if type(A) is sp.csc_matrix else A.T)
        self.q, self.l, self.u, self.n_eq = q, l, u, n_eq
        self.bound_max = float(max(np.abs(l[np.isfinite(l)]).max(initial=0.0),
                                   np.abs(u[np.isfinite(u)]).max(initial=0.0)))

    def __call__(self, z: FloatArray, y: FloatArray) -> dict[str, float]:
        """The four relative KKT residuals at ``(z, y)`` (each largest magnitude one reduction,
        exact in any order)."""
        l, u, n_eq = self.l, self.u, self.n_eq
        Pz = matvec(self.Pu, z) + matvec(self.lower, z)
        Az = matvec(self.A, z)
        Aty = matvec(self.AT, y)
        stat = float(np.abs(Pz + self.q + Aty).max())
        stat_scale = max(1.0, float(np.abs(Pz).max()), float(np.abs(Aty).max()))
        primal = float(np.abs(Az - Az.clip(l, u)).max())
        primal_scale = max(1.0, float(np.abs(Az).max()), self.bound_max)
        yi = y[n_eq:]
        slack = u[n_eq:] - Az[n_eq:]
        sign = float(np.maximum(-yi, 0.0).max(initial=0.0))
        compl = float((np.abs(yi) * np.maximum(slack, 0.0)).max(initial=0.0))
        zPz = float(z @ Pz)
        return {"kkt_stationarity_rel": stat / stat_scale, "kkt_primal_rel": primal / primal_scale,
                "kkt_dual_sign_rel": sign / max(1.0, float(np.abs(y).max())),
                "kkt_complementarity_rel": compl / max(1.0, abs(zPz))}


class ScanGrid:
    r"""The 1 ms scan points of :func:`leave_time`, ``numpy.linspace(0, t_f, n)`` with
    :math:`n = \max(2, \lceil t_f / 10^{-3} \rceil + 1)`, each computed when asked as
    ``linspace`` computes it (:math:`t_k = k \cdot (t_f / (n - 1))`, plus 0, which changes no bit
    here; the last one :math:`t_f`): the exact-root path reads three of its ~10,000 points."""

    def __init__(self, tf: float) -> None:
        self.tf = float(tf)
        self.size = max(2, math.ceil(self.tf / 1e-3) + 1)  # numpy.ceil's integer, without numpy
        self.step = self.tf / (self.size - 1)

    def at(self, k: int) -> float:
        """Point ``k`` (``0 <= k < size``)."""
        return self.tf if k == self.size - 1 else k * self.step

    def full(self) -> FloatArray:
        """Every point (``numpy.linspace``)."""
        return np.linspace(0.0, self.tf, self.size)

    def last_at_or_below(self, x: float) -> int:
        """``numpy.searchsorted(points, x, side="right") - 1``: the last index whose point is
        ``<= x`` (-1: none; NaN sorts after every point)."""
        n = self.size
        if x != x or x >= self.tf:
            return n - 1
        if x < 0.0:
            return -1
        k = min(n - 1, int(x / self.step)) if self.step > 0.0 else n - 1
        while k + 1 < n and self.at(k + 1) <= x:
            k += 1
        while k >= 0 and self.at(k) > x:
            k -= 1
        return k


def leave_time(traj: Any, plane: HalfPlane, tf: float) -> float:
    r"""The last instant the trajectory is in ``plane``: :math:`\sup\{t : c(t) - \sigma s(t) \ge -10^{-12}\}`
    (1e-12 m tolerance); ``tf`` when it ends inside, 0 when it never is.

    A held trajectory (:class:`~iamp.planners.qp.hold.HoldTrajectory`) gives it as the last exact
    root of its margin, a polynomial per piece (:func:`_scan_bracket`: the margin is negative
    after it, up to ``t_f``), once the trajectory evaluated at the 1 ms scan points on either side
    of that root confirms the sign change there.  Any other case scans those points
    (:class:`ScanGrid`) and solves the root on the last bracket (Brent's method to 1e-13 s).
    """
    grid = ScanGrid(tf)
    axis = 0 if plane.axis == "x" else 2

    def margin(x: FloatArray) -> FloatArray:
        return np.asarray(plane.margin(x, traj.states(x)[:, axis]), dtype=float)

    exact = _scan_bracket(traj, plane, grid, margin)
    if exact is None:
        inside = np.flatnonzero(margin(grid.full()) >= -1e-12)
        if inside.size == 0:
            return 0.0
        k = int(inside[-1])
    else:
        k, root = exact
        if k < 0:
            return 0.0
        if root is not None:
            return float(min(max(root, grid.at(k)), grid.at(k + 1)))
    if k == grid.size - 1:
        return float(tf)

    def g(x: float) -> float:  # the same 1e-12 m tolerance as the scan: a sign change is bracketed
        return float(margin(np.array([x]))[0]) + 1e-12

    return float(optimize.brentq(g, grid.at(k), grid.at(k + 1), xtol=1e-13))


def _scan_bracket(traj: Any, plane: HalfPlane, t: ScanGrid, margin: Any) -> tuple[int, float | None] | None:
    r"""The last index ``k`` of the scan ``t`` whose margin is ``>= -1e-12`` (``-1``: none) and the
    margin's last root (``t_k <= root <= t_{k+1}``; None when ``k`` is the last index or ``-1``),
    from the exact roots of the margin of a held trajectory, or None (the caller scans).

    On each piece of the hold the margin :math:`c(t) - \sigma s(t)` is a polynomial (the
    position a cubic of FOH, a quadratic of ZOH; ``c`` the vehicle's polynomial or a constant);
    its last root ``t*`` with the 1e-12 m tolerance (:func:`iamp.core.polyroots.roots_in_unit_interval`)
    names the scan's interval ``[t_k, t_{k+1}]`` holding it, which is accepted only when the
    margin evaluated as the scan does is inside at ``t_k`` and outside at ``t_{k+1}`` and at
    ``t_f``; past ``t*`` the margin keeps the sign it has at ``t_f``."""
    nodes, X, U = (getattr(traj, name, None) for name in ("t_nodes", "X", "U"))
    hold = getattr(traj, "hold", None)
    if nodes is None or X is None or U is None or hold not in ("foh", "zoh"):
        return None
    nodes = np.asarray(nodes, dtype=float)
    t0 = nodes[:-1]
    h = nodes[1:] - t0  # numpy.diff's subtraction
    a = 0 if plane.axis == "x" else 1
    S = np.empty((h.size, 4))  # s(t_k + σ h) in σ, column by column (numpy.stack's numbers)
    S[:, 0] = X[:-1, 2 * a]
    np.multiply(X[:-1, 2 * a + 1], h, out=S[:, 1])
    S[:, 2] = U[:h.size, a] * h**2 / 2
    if hold == "foh":
        S[:, 3] = (U[1:, a] - U[:-1, a]) / h * h**3 / 6
    else:
        S[:, 3] = np.zeros(h.size) * h**3 / 6
    v = plane.vehicle
    if plane.axis == "x":
        xs = shifted_poly(v.x_poly, t0, h, max(3, len(v.x_poly) - 1))
        half = v.length / 2 + v.safety_x
        c = -xs if plane.sigma < 0 else xs
        c[:, 0] += -half
    else:
        c = np.zeros((h.size, 4))
        c[:, 0] = -(v.y + v.width / 2 + v.safety_y) if plane.sigma < 0 else v.y - (v.width / 2 + v.safety_y)
    M = np.zeros((h.size, max(c.shape[1], 4)))
    M[:, :c.shape[1]] += c
    M[:, :4] -= plane.sigma * S
    M[:, 0] += 1e-12
    rows, sig = roots_in_unit_interval(M)
    # the margin at the scan points the answer needs (t_k and t_{k+1} around the last root, or
    # t_0 without a root) and at t_f, in one call (the trajectory is evaluated point by point:
    # the numbers of one call per point)
    if rows.size == 0:
        first, end = margin(np.array([t.at(0), t.at(t.size - 1)]))
        if end >= -1e-12:
            return int(t.size - 1), None
        return (-1, None) if first < -1e-12 else None
    last = float((t0[rows] + sig.clip(0.0, 1.0) * h[rows]).max())
    k = min(max(t.last_at_or_below(last), 0), t.size - 2)
    at_k, at_k1, end = margin(np.array([t.at(k), t.at(k + 1), t.at(t.size - 1)]))
    if end >= -1e-12:
        return int(t.size - 1), None
    if at_k >= -1e-12 and at_k1 < -1e-12:
        return k, last
    return None
