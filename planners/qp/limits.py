r"""The inequality rows that impose a scenario's physical limits (SPEC §14) on a discretised QP.

Shared by the equality QP (SPEC §3) and the avoidance QP (SPEC §10): both use the variable
layout of :class:`iamp.planners.qp.data.StateIndex`, ``z = (s_x, v_x, u_x, s_y, v_y, u_y)``
with ``N + 1`` nodal positions and speeds and ``nu`` nodal inputs per axis (ZOH ``nu = N``,
FOH ``nu = N + 1``).  :func:`limit_rows` returns the rows ``lo <= A z <= hi``:

=========  ==================================================================  ==============
bound      rows (every node)                                                   nodes
=========  ==================================================================  ==============
ax         :math:`a_{x,lo} \le u_{x,k} \le a_{x,hi}`                           inputs ``k < nu``
ay         :math:`a_{y,lo} \le u_{y,k} \le a_{y,hi}`                           inputs
a_total    :math:`|\cos\theta_j u_{x,k} + \sin\theta_j u_{y,k}| \le A\cos(\pi/M)`,  inputs
           :math:`\theta_j = 2\pi j / M,\ j = 0..M/2-1` (the inscribed regular
           ``M``-gon, ``M`` even >= 16; opposite edges share one two-sided row)
vx         :math:`v_{lo} \le v_{x,k} \le v_{hi}`                               ``0..N``
y          :math:`y_{lo} \le s_{y,k} \le y_{hi}`                               ``0..N``
jerk       :math:`|u_{a,k+1} - u_{a,k}| \le J\,h_k` per axis ``a`` (FOH only)  ``0..N-1``
=========  ==================================================================  ==============

What the rows guarantee between nodes:

* the input bounds (``ax``, ``ay``, ``a_total``, ``jerk``) hold **everywhere**: with ZOH the
  input is constant on each interval; with FOH it is linear, so on each interval it is a
  convex combination of its two nodal values, and the box, the polygon and the slope bound
  are convex sets;
* the polygon lies inside the circle :math:`|u| \le A` (its vertices are on it), so the
  friction circle holds everywhere, conservatively by at most the factor
  :math:`\cos(\pi/M)` (0.981 for ``M = 16``);
* ``vx`` and ``y`` hold at the nodes only (``between="nodes"``, SPEC §14); between them the
  speed (quadratic per FOH piece) and ``s_y`` (cubic; quadratic with ZOH) can overshoot.  The
  plan reports the largest such violation exactly (:mod:`iamp.core.peaks`); it falls as ``N``
  grows.
* ``between="certified"`` adds, per interval, the inner **Bernstein coefficients** of those
  polynomials, which are linear in ``z``; a polynomial lies in the hull of its Bernstein
  coefficients, so the bound then holds for all ``t`` (conservatively, by :math:`O(h^2)`):

  ===========  ====================================================================  =====
  quantity     inner Bernstein coefficients on :math:`[t_k, t_{k+1}]`                 hold
  ===========  ====================================================================  =====
  :math:`v_x`  :math:`v_k + \tfrac{h_k}{2} u_{x,k}`                                    FOH
  :math:`s_y`  :math:`s_k + \tfrac{h_k}{3} v_k,\ s_k + \tfrac{2h_k}{3} v_k + \tfrac{h_k^2}{6} u_{y,k}`  FOH
  :math:`s_y`  :math:`s_k + \tfrac{h_k}{2} v_k`                                        ZOH
  ===========  ====================================================================  =====

  (ZOH's speed is linear per interval: its node rows already hold everywhere.)

Without ``certified`` rows the matrix ``A`` depends on the layout and ``M`` only, not on the
grid: the jerk rows read :math:`-J h_k \le u_{k+1} - u_k \le J h_k`, so a new grid (an
aligned one for ``refine``) changes only ``lo, hi`` (:meth:`LimitRows.bounds_for`); the
certified rows' coefficients depend on :math:`h_k`, and :meth:`LimitRows.set_grid` rebuilds
``A``'s values on the same pattern.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from iamp.core.errors import ScenarioError
from iamp.core.physical import PhysicalLimits
from iamp.planners.qp.data import StateIndex

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Sides of the polygon inscribed in the friction circle (even, at least 16).
POLYGON_SIDES = 16

#: Row kinds, in the order the rows are stacked.
KINDS = ("ax", "ay", "a_total", "vx", "y", "vx_between", "y_between", "jerk_x", "jerk_y")
#: Where the speed and ``y`` bounds are imposed (module docstring).
BETWEEN = ("nodes", "certified")


@dataclass
class LimitRows:
    r"""The rows ``lo <= A z <= hi`` of one :class:`~iamp.core.physical.PhysicalLimits`.

    Attributes
    ----------
    A : scipy.sparse.csc_matrix, shape (n_rows, n)
        Constant on a given layout (no grid values in it).
    lo, hi : ndarray, shape (n_rows,)
        Bounds on the current grid (``±inf`` where a row is one-sided; every row here is
        two-sided and finite).
    kind : ndarray of str, shape (n_rows,)
        The bound each row imposes (:data:`KINDS`).
    node : ndarray of int, shape (n_rows,)
        The node ``k`` of the row (the interval's left node for jerk rows).
    polygon_sides : int or None
        ``M`` when ``a_total`` is imposed, else None.
    """

    A: sp.csc_matrix
    lo: FloatArray
    hi: FloatArray
    kind: NDArray[np.str_]
    node: IntArray
    polygon_sides: int | None
    limits: PhysicalLimits
    hold: str
    _jerk_rows: IntArray = field(repr=False, default_factory=lambda: np.zeros(0, dtype=np.int64))
    between: str = "nodes"
    index: StateIndex | None = field(default=None, repr=False)

    @property
    def n_rows(self) -> int:
        return int(self.lo.size)

    def bounds_for(self, t_nodes: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``lo, hi`` on another grid of the same ``N`` (only the jerk rows change)."""
        lo, hi = self.lo.copy(), self.hi.copy()
        if self._jerk_rows.size:
            h = np.diff(np.asarray(t_nodes, dtype=float))
            jerk = float(self.limits.jerk)  # type: ignore[arg-type]
            hk = h[self.node[self._jerk_rows]]
            lo[self._jerk_rows] = -jerk * hk
            hi[self._jerk_rows] = jerk * hk
        return lo, hi

    def set_grid(self, t_nodes: FloatArray) -> None:
        """Replace ``lo, hi`` (and, with certified rows, the values of ``A``) by their values on
        ``t_nodes`` (same pattern)."""
        if self.between == "certified" and self.index is not None:
            fresh = limit_rows(self.index, t_nodes, self.hold, self.limits, self.polygon_sides or POLYGON_SIDES,
                               between=self.between)
            self.A.data[:] = fresh.A.data
        self.lo, self.hi = self.bounds_for(t_nodes)

    def violation(self, z: FloatArray) -> FloatArray:
        """Per row, how far ``A z`` lies outside ``[lo, hi]`` (0 inside)."""
        Az = self.A @ np.asarray(z, dtype=float)
        return np.asarray(np.maximum(np.maximum(self.lo - Az, Az - self.hi), 0.0), dtype=float)

    def describe(self) -> dict[str, int]:
        """Rows per kind (for reports; counted once per ``kind`` array, a new dict each call)."""
        kept = self.__dict__.get("_described")
        if kept is None or kept[0] is not self.kind:
            kinds, counts = np.unique(self.kind, return_counts=True)
            kept = self.__dict__["_described"] = (self.kind, {str(k): int(c) for k, c in zip(kinds, counts)})
        return dict(kept[1])


def polygon_normals(sides: int = POLYGON_SIDES) -> tuple[FloatArray, float]:
    r"""Unit normals :math:`(\cos\theta_j, \sin\theta_j)`, :math:`\theta_j = 2\pi j/M`,
    ``j = 0..M/2-1``, and the apothem factor :math:`\cos(\pi/M)` of the regular ``M``-gon
    inscribed in the unit circle with a vertex at angle :math:`\pi/M`.

    Each normal stands for the two opposite edges :math:`\pm`, so the polygon is
    :math:`\{u : |n_j^\top u| \le \cos(\pi/M)\ \forall j\}`.
    """
    if sides < 16 or sides % 2:
        raise ValueError(f"the friction-circle polygon needs an even number >= 16 of sides (got {sides})")
    theta = 2.0 * np.pi * np.arange(sides // 2) / sides
    normals = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    normals[np.abs(normals) < 1e-15] = 0.0  # cos(π/2) is 6e-17 in floating point: an exact zero
    return normals, math.cos(math.pi / sides)


def check_hold(limits: PhysicalLimits, hold: str) -> None:
    """Refuse a jerk bound with ZOH (its input jumps at every node): :class:`ScenarioError`
    naming ``limits.jerk`` (the CLI's exit 2)."""
    if limits.jerk is not None and hold == "zoh":
        raise ScenarioError("a jerk bound needs a continuous input: use --hold foh (ZOH's input jumps at every "
                            "node, so its jerk is unbounded)", "limits.jerk", limits.source)


def limit_rows(index: StateIndex, t_nodes: FloatArray, hold: str, limits: PhysicalLimits,
               polygon_sides: int = POLYGON_SIDES, between: str = "nodes") -> LimitRows:
    r"""The inequality rows of ``limits`` on the layout ``index`` (module docstring's table).

    Parameters
    ----------
    index : StateIndex
        The QP's variable layout (``N``, ``block``; :class:`~iamp.planners.qp.data.QPData`
        or :class:`~iamp.planners.avoid.data.AvoidData`).
    t_nodes : ndarray, shape (N+1,)
        The grid (used for the jerk rows' bounds :math:`\pm J h_k` only).
    hold : {"foh", "zoh"}
    limits : PhysicalLimits
    polygon_sides : int
        ``M`` of the friction-circle polygon (even, >= 16).
    between : {"nodes", "certified"}
        ``certified`` adds the Bernstein rows that make the ``vx`` and ``y`` bounds hold
        between the nodes too (module docstring).

    Returns
    -------
    LimitRows
        With ``A`` of shape ``(n_rows, 2 * index.block)``; ``n_rows = 0`` when no bound is set.

    Raises
    ------
    ScenarioError
        ``jerk`` with ``hold = "zoh"`` (field ``limits.jerk``).
    """
    if hold not in ("foh", "zoh"):
        raise ValueError(f"unknown hold {hold!r}")
    if between not in BETWEEN:
        raise ValueError(f"unknown between {between!r}; choose from {', '.join(BETWEEN)}")
    check_hold(limits, hold)
    N, block = int(index.N), int(index.block)
    nu = block - 2 * (N + 1)
    if nu != (N + 1 if hold == "foh" else N):
        raise ValueError(f"layout has {nu} inputs per axis, which is not {hold.upper()} on N = {N}")
    n = 2 * block
    t = np.asarray(t_nodes, dtype=float)
    if t.shape != (N + 1,):
        raise ValueError(f"t_nodes must have N + 1 = {N + 1} entries (got {t.shape})")
    h = np.diff(t)
    rows: list[IntArray] = []
    cols: list[IntArray] = []
    vals: list[FloatArray] = []
    lo: list[FloatArray] = []
    hi: list[FloatArray] = []
    kind: list[str] = []
    node: list[IntArray] = []
    r0 = 0

    def block_rows(k: IntArray, terms: list[tuple[IntArray, FloatArray | float]], l: FloatArray | float,
                   u: FloatArray | float,
                   name: str) -> None:
        nonlocal r0
        r = r0 + np.arange(k.size, dtype=np.int64)
        for c, v in terms:
            rows.append(r)
            cols.append(np.asarray(c, dtype=np.int64))
            vals.append(np.broadcast_to(np.asarray(v, dtype=float), r.shape).astype(float))
        lo.append(np.broadcast_to(l, r.shape).astype(float))
        hi.append(np.broadcast_to(u, r.shape).astype(float))
        kind.extend([name] * k.size)
        node.append(k.astype(np.int64))
        r0 += k.size

    ku = np.arange(nu, dtype=np.int64)
    kn = np.arange(N + 1, dtype=np.int64)
    for a, name in enumerate(("ax", "ay")):
        rng = getattr(limits, name)
        if rng is not None:
            block_rows(ku, [(index.idx_u(a, ku), 1.0)], float(rng[0]), float(rng[1]), name)
    sides: int | None = None
    if limits.a_total is not None:
        sides = int(polygon_sides)
        normals, apothem = polygon_normals(sides)
        r_max = float(limits.a_total) * apothem
        for c, s in normals:
            terms: list[tuple[IntArray, FloatArray | float]] = []
            if c != 0:
                terms.append((index.idx_u(0, ku), float(c)))
            if s != 0:
                terms.append((index.idx_u(1, ku), float(s)))
            block_rows(ku, terms, -r_max, r_max, "a_total")
    if limits.vx is not None:
        block_rows(kn, [(index.idx_v(0, kn), 1.0)], float(limits.vx[0]), float(limits.vx[1]), "vx")
    if limits.y is not None:
        block_rows(kn, [(index.idx_s(1, kn), 1.0)], float(limits.y[0]), float(limits.y[1]), "y")
    if between == "certified":
        kk = np.arange(N, dtype=np.int64)
        if limits.vx is not None and hold == "foh":
            block_rows(kk, [(index.idx_v(0, kk), 1.0), (index.idx_u(0, kk), h / 2)], float(limits.vx[0]),
                       float(limits.vx[1]), "vx_between")
        if limits.y is not None:
            y_lo, y_hi = float(limits.y[0]), float(limits.y[1])
            if hold == "foh":
                block_rows(kk, [(index.idx_s(1, kk), 1.0), (index.idx_v(1, kk), h / 3)], y_lo, y_hi, "y_between")
                block_rows(kk, [(index.idx_s(1, kk), 1.0), (index.idx_v(1, kk), 2 * h / 3),
                                (index.idx_u(1, kk), h**2 / 6)], y_lo, y_hi, "y_between")
            else:
                block_rows(kk, [(index.idx_s(1, kk), 1.0), (index.idx_v(1, kk), h / 2)], y_lo, y_hi, "y_between")
    jerk_start = r0
    if limits.jerk is not None:
        kk = np.arange(N, dtype=np.int64)
        jerk = float(limits.jerk)
        for a, name in enumerate(("jerk_x", "jerk_y")):
            block_rows(kk, [(index.idx_u(a, kk + 1), 1.0), (index.idx_u(a, kk), -1.0)], -jerk * h, jerk * h, name)
    n_rows = r0
    if rows:
        A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_rows, n))
    else:
        A = sp.csc_matrix((0, n))
    A.sort_indices()
    return LimitRows(
        A=A,
        lo=np.concatenate(lo) if lo else np.zeros(0),
        hi=np.concatenate(hi) if hi else np.zeros(0),
        kind=np.array(kind, dtype=str),
        node=np.concatenate(node) if node else np.zeros(0, dtype=np.int64),
        polygon_sides=sides,
        limits=limits,
        hold=hold,
        _jerk_rows=np.arange(jerk_start, n_rows, dtype=np.int64),
        between=between,
        index=index,
    )
