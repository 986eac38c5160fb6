r"""The matrices of the avoidance QP (SPEC §10), built once per grid.

Variables and equality rows are those of the discretised QP of SPEC §3 (the layout of
:class:`iamp.planners.qp.data.QPData`): per axis the nodal positions ``s_0..s_N``, speeds
``v_0..v_N`` and inputs (``u_0..u_{N-1}`` ZOH, ``u_0..u_N`` FOH),
``z = (s_x, v_x, u_x, s_y, v_y, u_y)``, cost :math:`\tfrac12 z^\top P z = J` exactly, and the
rows

.. math::

    s_{k+1} - s_k - h_k v_k - \alpha_k u_k - \beta_k u_{k+1} = 0, \qquad
    v_{k+1} - v_k - \gamma_k u_k - \delta_k u_{k+1} = 0,

(FOH :math:`\alpha = h^2/3, \beta = h^2/6, \gamma = \delta = h/2`; ZOH :math:`\alpha = h^2/2,
\gamma = h`) plus the four boundary rows per axis.  There are no corner (selector) rows.

Half-planes
-----------
Vehicle ``i``'s corner names two half-planes, each written as :math:`\sigma\, s \le c(t)`:

============ =============================================== ========== ===================================
half-plane   condition                                       :math:`\sigma` :math:`c(t)`
============ =============================================== ========== ===================================
``H_x`` front :math:`s_x \ge x_{s,i}(t) + L_i/2 + S_{x,i}`     −1         :math:`-(x_{s,i}(t) + L_i/2 + S_{x,i})`
``H_x`` rear  :math:`s_x \le x_{s,i}(t) - L_i/2 - S_{x,i}`     +1         :math:`x_{s,i}(t) - L_i/2 - S_{x,i}`
``H_y`` lower :math:`s_y \le y_{s,i} - W_i/2 - S_{y,i}`        +1         :math:`y_{s,i} - W_i/2 - S_{y,i}`
``H_y`` upper :math:`s_y \ge y_{s,i} + W_i/2 + S_{y,i}`        −1         :math:`-(y_{s,i} + W_i/2 + S_{y,i})`
============ =============================================== ========== ===================================

and the *margin* :math:`c(t) - \sigma s(t) \ge 0` inside the half-plane.  Every vehicle has
one ``H_x`` row and one ``H_y`` row at every interior node ``k = 1..N-1`` (the end nodes are
fixed by the boundary rows and checked before any solve), ``l = −∞``, ``u = c(t_k)`` when the
row is imposed and ``u = c(t_k) + R`` (:attr:`AvoidData.relax`, far beyond any reachable
position) when it is not: a choice of crossing times changes **only** ``u``, so the solver is
set up once per grid and every sweep candidate is a bound update (OSQP warm-starts from the
previous one).  A relaxed row's multiplier is checked to be zero.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from iamp.core.problem import Problem, SurroundingVehicle
from iamp.planners.qp.data import StateIndex

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

AXES = ("x", "y")


@dataclass(frozen=True)
class HalfPlane:
    """``σ · s_axis ≤ c(t)`` for one vehicle and one axis (module docstring's table)."""

    vehicle: SurroundingVehicle
    axis: str  # "x" or "y"

    @functools.cached_property
    def sigma(self) -> float:
        """The sign ``σ`` (module docstring's table; computed once: the half-plane and its vehicle
        are frozen)."""
        if self.axis == "x":
            return -1.0 if self.vehicle.corner.startswith("front") else 1.0
        return 1.0 if self.vehicle.corner.endswith("lower") else -1.0

    def bound(self, t: FloatArray) -> FloatArray:
        """``c(t)``."""
        v = self.vehicle
        t = np.asarray(t, dtype=float)
        if self.axis == "x":
            ax = v.length / 2 + v.safety_x
            xs = np.asarray(v.position(t), dtype=float)
            return np.asarray(-(xs + ax) if self.sigma < 0 else xs - ax, dtype=float)
        ay = v.width / 2 + v.safety_y
        return np.full(t.shape, -(v.y + ay) if self.sigma < 0 else v.y - ay)

    def margin(self, t: FloatArray, s: FloatArray) -> FloatArray:
        """``c(t) − σ s``: ``>= 0`` inside the half-plane."""
        return self.bound(t) - self.sigma * np.asarray(s, dtype=float)

    def describe(self) -> str:
        """``"H_x (s_x >= x_s(t) + 7.4 m)"`` and the like."""
        v = self.vehicle
        if self.axis == "x":
            ax = v.length / 2 + v.safety_x
            return f"H_x (s_x {'>=' if self.sigma < 0 else '<='} x_s(t) {'+' if self.sigma < 0 else '-'} {ax:g} m)"
        edge = v.y + (-1 if self.sigma > 0 else 1) * (v.width / 2 + v.safety_y)
        return f"H_y (s_y {'<=' if self.sigma > 0 else '>='} {edge:g} m)"


class AvoidData(StateIndex):
    """``P, q, A, l, u`` of the avoidance QP on one grid (module docstring).

    Parameters
    ----------
    problem : Problem
    t_nodes : ndarray, shape (N+1,)
        The grid (uniform for the sweep, aligned with the crossing times for ``refine``).
    hold : {"foh", "zoh"}
    with_limits : bool
        Append the physical limits' rows to ``A``.
    shared : GridShare, optional
        Where the plans of one planner keep ``A`` and ``P`` per grid (without ``with_limits``).
    """

    def __init__(self, problem: Problem, t_nodes: FloatArray, hold: str, with_limits: bool = False,
                 shared: Any = None) -> None:
        self.problem, self.hold = problem, hold
        self.t_nodes = np.asarray(t_nodes, dtype=float)
        N = self.N = self.t_nodes.size - 1
        foh = hold == "foh"
        self.nu = N + 1 if foh else N
        self.block = 2 * (N + 1) + self.nu
        self.n = 2 * self.block
        m = problem.m
        self.n_eq = 2 * (2 * N + 4)
        self.interior = np.arange(1, N)
        ni = N - 1
        self.n_rows = self.n_eq + 2 * m * ni
        b_eq = np.zeros(self.n_eq)
        ego = problem.ego
        ends = ((ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf))
        self.planes = [(HalfPlane(v, "x"), HalfPlane(v, "y")) for v in problem.vehicles]
        c_on = np.zeros(2 * m * ni)
        t_in = self.t_nodes[1:N]  # the interior nodes' times (``t_nodes[interior]``)
        for i, pair in enumerate(self.planes):
            for a, hp in enumerate(pair):
                first = (2 * i + a) * ni  # rows ``row(i, a, interior) - n_eq``: consecutive
                c_on[first:first + ni] = hp.bound(t_in)
        for axi, (s0, v0, sf, vf) in enumerate(ends):
            first = axi * (2 * N + 4) + 2 * N
            b_eq[first:first + 4] = (s0, v0, sf, vf)
        # A (equality rows, then the vehicles' rows) and P depend on the grid, the hold and the
        # half-planes' signs only: a planner's plans on one grid share them (``shared``, a
        # :class:`~iamp.planners.avoid.continuous.GridShare`; the same arrays as built here)
        key = ("matrices", N, hold, self.t_nodes.tobytes(),
               tuple(hp.sigma for pair in self.planes for hp in pair))
        kept = shared.get(key) if shared is not None and not with_limits else None
        if kept is None:
            self.A, self.P = self._matrices(foh)
            if shared is not None and not with_limits:
                shared.put(key, (self.A, self.P))
        else:
            self.A, self.P = kept
        #: physical limits (``with_limits``): rows ``[A_lim; -A_lim] z <= [hi; -lo]`` after the
        #: vehicles' rows, always imposed (:meth:`bounds`)
        self.limit_rows: Any = None
        self.n_limit_rows = 0
        if with_limits and problem.limits is not None:
            from iamp.planners.qp.limits import check_hold, limit_rows

            check_hold(problem.limits, hold)
            self.limit_rows = lr = limit_rows(self, self.t_nodes, hold, problem.limits)
            self.A = sp.csc_matrix(sp.vstack([self.A, lr.A, -lr.A]))
            self.A.sort_indices()
            c_on = np.r_[c_on, lr.hi, -lr.lo]
            self.n_limit_rows = 2 * lr.A.shape[0]
            self.n_rows += self.n_limit_rows
        self.q = np.zeros(self.n)
        self.b_eq = b_eq
        self.c_on = c_on
        span = max(abs(ego.x0), abs(ego.xf), abs(ego.y0), abs(ego.yf), 1.0)
        scale = max([span] + [float(np.max(np.abs(c_on), initial=0.0))])
        #: Added to a relaxed row's bound: ten times any position scale in the problem.
        self.relax = 10.0 * scale + 1e3

    def _matrices(self, foh: bool) -> tuple[sp.csc_matrix, sp.csc_matrix]:
        """``A`` (the equality rows, then the vehicles' rows at the interior nodes) and ``P``
        (upper triangle), both CSC with sorted indices; the steps ``h`` and the coefficients
        ``α, γ`` of the module docstring computed here, where they are used (a plan whose grid
        keeps its matrices, :class:`~iamp.planners.avoid.continuous.GridShare`, needs none)."""
        N = self.N
        h = np.diff(self.t_nodes)
        alpha, gamma = (h**2 / 3, h / 2) if foh else (h**2 / 2, h)
        k = np.arange(N)
        rows: list[IntArray] = []
        cols: list[IntArray] = []
        vals: list[FloatArray] = []

        def add(r: IntArray, c: IntArray, v: FloatArray | float) -> None:
            r, c = np.broadcast_arrays(np.asarray(r, dtype=np.int64), np.asarray(c, dtype=np.int64))
            rows.append(r.ravel())
            cols.append(c.ravel())
            vals.append(np.broadcast_to(np.asarray(v, dtype=float), r.shape).ravel())

        for axi in range(2):
            r0 = axi * (2 * N + 4)
            rp, rv = r0 + k, r0 + N + k
            add(rp, self.idx_s(axi, k + 1), 1.0)
            add(rp, self.idx_s(axi, k), -1.0)
            add(rp, self.idx_v(axi, k), -h)
            add(rp, self.idx_u(axi, k), -alpha)
            add(rv, self.idx_v(axi, k + 1), 1.0)
            add(rv, self.idx_v(axi, k), -1.0)
            add(rv, self.idx_u(axi, k), -gamma)
            if foh:
                add(rp, self.idx_u(axi, k + 1), -h**2 / 6)
                add(rv, self.idx_u(axi, k + 1), -h / 2)
            rb = r0 + 2 * N + np.arange(4)
            add(rb, np.array([self.idx_s(axi, 0), self.idx_v(axi, 0), self.idx_s(axi, N), self.idx_v(axi, N)]), 1.0)
        # inequality rows: vehicle i, axis a, interior node j -> row n_eq + (2 i + a) ni + (j - 1)
        for i, pair in enumerate(self.planes):
            for a, hp in enumerate(pair):
                add(self.row(i, a, self.interior), self.idx_s(a, self.interior), hp.sigma)
        A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(self.n_eq + 2 * len(self.planes) * (N - 1), self.n))
        A.sort_indices()
        # P (upper triangle), 1/2 z'Pz = J
        pr: list[IntArray] = []
        pc: list[IntArray] = []
        pv: list[FloatArray] = []
        for axi in range(2):
            u = self.idx_u(axi, np.arange(self.nu))
            if foh:
                d = np.zeros(self.nu)
                d[:-1] += h / 3
                d[1:] += h / 3
                pr += [u, u[:-1]]
                pc += [u, u[1:]]
                pv += [d, h / 6]
            else:
                pr.append(u)
                pc.append(u)
                pv.append(h.copy())
        P = sp.csc_matrix((np.concatenate(pv), (np.concatenate(pr), np.concatenate(pc))), shape=(self.n, self.n))
        P.sort_indices()
        return A, P

    # --- indices (idx_s, idx_v, idx_u from StateIndex) ------------------------------------
    def row(self, vehicle: int, axis: int, node: IntArray | int) -> IntArray:
        """Row of vehicle ``vehicle``'s half-plane ``axis`` (0 = H_x, 1 = H_y) at interior ``node``."""
        return np.asarray(self.n_eq + (2 * vehicle + axis) * (self.N - 1) + np.asarray(node) - 1, dtype=np.int64)

    # --- bounds ------------------------------------------------------------------------
    def imposed(self, phases: Sequence[tuple[int, int, int, int]]) -> NDArray[np.bool_]:
        """Which inequality rows are imposed.

        ``phases[i] = (first, second, last_first, first_second)``: half-plane ``first`` (0 =
        H_x, 1 = H_y) at nodes ``k <= last_first``, ``second`` at nodes ``k >= first_second``
        (``first_second = last_first + 1``: the crossing lies strictly between two nodes;
        ``first_second = last_first``: on that node, which lies in both).
        """
        on = np.zeros(self.n_rows - self.n_eq, dtype=bool)
        k = self.interior
        for i, (first, second, last_first, first_second) in enumerate(phases):
            on[self.row(i, first, k[k <= last_first]) - self.n_eq] = True
            on[self.row(i, second, k[k >= first_second]) - self.n_eq] = True
        return on

    def effective_on(self, on: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """``on`` with the physical-limit rows imposed (they are never relaxed)."""
        if not self.n_limit_rows:
            return on
        on = on.copy()
        on[on.size - self.n_limit_rows:] = True
        return on

    def bounds(self, on: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray]:
        """``l, u`` for the imposed rows ``on``."""
        on = self.effective_on(on)
        l = np.r_[self.b_eq, np.full(on.size, -np.inf)]
        u = np.r_[self.b_eq, np.where(on, self.c_on, self.c_on + self.relax)]
        return l, u

    # --- solution ------------------------------------------------------------------------
    def unpack(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Nodal states ``(N+1, 4)`` ``(s_x, v_x, s_y, v_y)`` and inputs ``(nu, 2)``."""
        N = self.N
        X = np.stack([z[self.idx_s(0, np.arange(N + 1))], z[self.idx_v(0, np.arange(N + 1))],
                      z[self.idx_s(1, np.arange(N + 1))], z[self.idx_v(1, np.arange(N + 1))]], axis=1)
        U = np.stack([z[self.idx_u(0, np.arange(self.nu))], z[self.idx_u(1, np.arange(self.nu))]], axis=1)
        return X, U
