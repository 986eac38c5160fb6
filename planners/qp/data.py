r"""The matrices of the discretised QP of SPEC §3, built once per problem.

Per axis the variables are the nodal positions ``s_0..s_N``, speeds ``v_0..v_N`` and inputs
(``u_0..u_{N-1}`` for ZOH, ``u_0..u_N`` for FOH); ``z = (s_x, v_x, u_x, s_y, v_y, u_y)``.
The QP is

.. math::

    \min_z\ \tfrac12 z^\top P z + q^\top z \quad\text{s.t.}\quad A z = b
    \qquad (l = u = b \text{ in the backends' form } l \le Az \le u),

with ``q = 0`` and ``½ zᵀPz = J`` exactly (no scaling):

* FOH: :math:`J = \sum_k \tfrac{h_k}{6}(u_k^2 + u_k u_{k+1} + u_{k+1}^2)`, so
  :math:`P_{kk} \mathrel{+}= h_k/3,\ P_{k+1,k+1} \mathrel{+}= h_k/3,\ P_{k,k+1} = h_k/6`;
* ZOH: :math:`J = \tfrac12\sum_k h_k u_k^2`, so :math:`P_{kk} = h_k`.

The rows of ``A z = b`` are, per axis, the exact discretisation of the double integrator

.. math::

    s_{k+1} - s_k - h_k v_k - \alpha_k u_k - \beta_k u_{k+1} = 0, \qquad
    v_{k+1} - v_k - \gamma_k u_k - \delta_k u_{k+1} = 0,

(FOH: :math:`\alpha = h^2/3,\ \beta = h^2/6,\ \gamma = \delta = h/2`; ZOH:
:math:`\alpha = h^2/2,\ \gamma = h`, no :math:`u_{k+1}` term), the four boundary rows
:math:`s_0 = s(0),\ v_0 = v(0),\ s_N = s(t_f),\ v_N = v(t_f)`, and, per vehicle ``i``, two
*selector rows* :math:`\sum_{j=1}^{N-1} w_{ij} s_{x,j} = \text{corner}_{x,i}`,
:math:`\sum_j w_{ij} s_{y,j} = \text{corner}_{y,i}` whose pattern holds every interior node
(explicit zeros): moving the contact to node ``k`` (:math:`w_{ij} = [j = k]`) is a *value*
update of ``A`` on an unchanged pattern, plus the corner values in ``b``.  A non-uniform
(aligned) grid is likewise a value update of ``P`` and ``A``.

Multipliers: with :math:`L = \tfrac12 z^\top Pz + y^\top(Az - b)` the selector rows read
:math:`s(t_i) - \text{corner}_i`, so their multipliers are :math:`\nu_i` in the SPEC §3.3
convention, equal to the PMP jumps :math:`\Phi_i` (FOH).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from iamp.core.problem import Problem

from .backends.base import FloatArray, IntArray, KKTResiduals
from .hold import HOLDS

#: (N, hold, m) -> the pattern-only arrays of :class:`QPData` (the last 16 used).
_PATTERNS: OrderedDict[tuple[int, str, int], dict[str, Any]] = OrderedDict()
_PATTERN_ARRAYS = ("_coo_tags", "_coo_k", "_perm", "_sel_pos", "_p_perm", "_m_src", "_m_of_a", "_res_segments")


class StateIndex:
    """Where ``s_k``, ``v_k``, ``u_k`` of axis ``ax`` sit in ``z = (s_x, v_x, u_x, s_y, v_y, u_y)``.

    Shared by the equality QP and the avoidance QP (same variable layout: ``N + 1`` positions,
    ``N + 1`` speeds and ``nu`` inputs per axis, ``block`` variables per axis).
    """

    N: int
    block: int

    def idx_s(self, ax: int, k: IntArray | int) -> IntArray:
        return np.asarray(ax * self.block + np.asarray(k), dtype=np.int64)

    def idx_v(self, ax: int, k: IntArray | int) -> IntArray:
        return np.asarray(ax * self.block + self.N + 1 + np.asarray(k), dtype=np.int64)

    def idx_u(self, ax: int, k: IntArray | int) -> IntArray:
        return np.asarray(ax * self.block + 2 * (self.N + 1) + np.asarray(k), dtype=np.int64)


class QPData(StateIndex):
    r"""The data ``P, q, A, b`` of the discretised QP with a fixed sparsity pattern.

    Parameters
    ----------
    problem : Problem
    steps : int
        Number of intervals ``N`` (at least ``m + 1``).
    hold : {"foh", "zoh"}

    Attributes
    ----------
    P : scipy.sparse.csc_matrix
        Upper triangle of the cost Hessian, ``½ zᵀPz = J``.
    q : ndarray
        Zero.
    A : scipy.sparse.csc_matrix
        Equality-constraint matrix (dynamics, boundary, selector rows).
    b : ndarray
        Right-hand side.
    n, n_rows : int
        Number of variables and of rows.
    row_collision : int
        First selector row (vehicle ``i``'s rows are ``row_collision + 2i + {0, 1}``).
    """

    A: sp.csc_matrix
    P: sp.csc_matrix
    _M: sp.csr_matrix

    def __init__(self, problem: Problem, steps: int, hold: str = "foh") -> None:
        if hold not in HOLDS:
            raise ValueError(f"unknown hold {hold!r}; choose from {', '.join(HOLDS)}")
        if int(steps) != steps or steps < problem.m + 1:
            raise ValueError(f"steps must be an integer >= {problem.m + 1} (got {steps})")
        self.problem, self.N, self.hold = problem, int(steps), hold
        N, m = self.N, problem.m
        self.nu = N if hold == "zoh" else N + 1
        self.block = 2 * (N + 1) + self.nu  # variables per axis
        self.n = 2 * self.block
        self.n_dyn = 2 * N + 4  # rows per axis
        self.row_collision = 2 * self.n_dyn
        self.n_rows = self.row_collision + 2 * m
        self._build_pattern()
        k, ku = np.arange(N + 1), np.arange(self.nu)
        self._X_idx = np.stack([self.idx_s(0, k), self.idx_v(0, k), self.idx_s(1, k), self.idx_v(1, k)], axis=1)
        self._U_idx = np.stack([self.idx_u(0, ku), self.idx_u(1, ku)], axis=1)
        self.q = np.zeros(self.n)
        self.nodes: tuple[int, ...] | None = None
        self.t_nodes = np.linspace(0.0, problem.tf, N + 1)
        self.h = np.diff(self.t_nodes)
        self.b = np.zeros(self.n_rows)
        ego = problem.ego
        for ax, (s0, v0, sf, vf) in enumerate([(ego.x0, ego.vx0, ego.xf, ego.vxf),
                                               (ego.y0, ego.vy0, ego.yf, ego.vyf)]):
            r = ax * self.n_dyn + 2 * N
            self.b[r:r + 4] = (s0, v0, sf, vf)
        self.set_grid(self.t_nodes)

    def _build_pattern(self) -> None:
        """The sparsity patterns and value maps, computed once per ``(N, hold, m)`` and then
        taken from a small cache (read-only index arrays, fresh value arrays)."""
        key = (self.N, self.hold, self.problem.m)
        pat = _PATTERNS.get(key)
        if pat is None:
            self._compute_pattern()
            pat = {name: getattr(self, name) for name in _PATTERN_ARRAYS}
            pat.update(A=(self.A.indices.copy(), self.A.indptr.copy()), P=(self.P.indices.copy(), self.P.indptr.copy()),
                       M=(self._M.indices.copy(), self._M.indptr.copy(), self._M.shape))
            for v in pat.values():
                for a in v if isinstance(v, tuple) else (v,):
                    if isinstance(a, np.ndarray):
                        a.setflags(write=False)
            _PATTERNS[key] = pat
            while len(_PATTERNS) > 16:
                _PATTERNS.popitem(last=False)
            return
        _PATTERNS.move_to_end(key)
        self._coo_tags, self._coo_k, self._perm = pat["_coo_tags"], pat["_coo_k"], pat["_perm"]
        self._sel_pos, self._p_perm, self._m_src = pat["_sel_pos"], pat["_p_perm"], pat["_m_src"]
        self._m_of_a, self._res_segments = pat["_m_of_a"], pat["_res_segments"]
        ind, ptr = pat["A"]
        self.A = sp.csc_matrix((np.zeros(ind.size), ind.copy(), ptr.copy()), shape=(self.n_rows, self.n))
        ind, ptr = pat["P"]
        self.P = sp.csc_matrix((np.zeros(ind.size), ind.copy(), ptr.copy()), shape=(self.n, self.n))
        ind, ptr, shape = pat["M"]
        self._M = sp.csr_matrix((np.zeros(ind.size), ind.copy(), ptr.copy()), shape=shape)

    def _compute_pattern(self) -> None:
        """COO triplets with symbolic value tags, then the CSC data permutation."""
        N, m, foh = self.N, self.problem.m, self.hold == "foh"
        k = np.arange(N)
        rows: list[IntArray] = []
        cols: list[IntArray] = []
        tags: list[IntArray] = []  # which value formula (see set_grid)

        def add(r: IntArray | int | list[int], c: IntArray | list[IntArray], tag: int) -> None:
            rr, cc = np.broadcast_arrays(np.asarray(r), np.asarray(c))
            rows.append(rr.ravel().astype(np.int64))
            cols.append(cc.ravel().astype(np.int64))
            tags.append(np.full(rr.size, tag, dtype=np.int64))

        for ax in range(2):
            r0 = ax * self.n_dyn
            rp, rv = r0 + k, r0 + N + k  # position rows, speed rows
            add(rp, self.idx_s(ax, k + 1), 0)  # +1
            add(rp, self.idx_s(ax, k), 1)  # -1
            add(rp, self.idx_v(ax, k), 2)  # -h
            add(rp, self.idx_u(ax, k), 3)  # -alpha
            if foh:
                add(rp, self.idx_u(ax, k + 1), 4)  # -beta
            add(rv, self.idx_v(ax, k + 1), 0)
            add(rv, self.idx_v(ax, k), 1)
            add(rv, self.idx_u(ax, k), 5)  # -gamma
            if foh:
                add(rv, self.idx_u(ax, k + 1), 6)  # -delta
            rb = r0 + 2 * N
            add(np.array([rb, rb + 1, rb + 2, rb + 3]),
                np.array([self.idx_s(ax, 0), self.idx_v(ax, 0), self.idx_s(ax, N), self.idx_v(ax, N)]), 0)
        interior = np.arange(1, N)
        for i in range(m):
            for ax in range(2):
                add(self.row_collision + 2 * i + ax, self.idx_s(ax, interior), 7)  # selector
        R, C, T = np.concatenate(rows), np.concatenate(cols), np.concatenate(tags)
        self._coo_tags = T
        local = R % self.n_dyn
        coo_k = np.where(R < self.row_collision, np.where(local < N, local, local - N), 0)
        self._coo_k = np.minimum(coo_k, N - 1)
        ids = sp.coo_matrix((np.arange(1, R.size + 1, dtype=float), (R, C)), shape=(self.n_rows, self.n)).tocsc()
        if ids.nnz != R.size:  # pragma: no cover - a modelling bug
            raise RuntimeError("duplicate entries in the QP pattern")
        self._perm = ids.data.astype(np.int64) - 1  # CSC position -> COO entry
        self.A = sp.csc_matrix((np.zeros(R.size), ids.indices.copy(), ids.indptr.copy()),
                               shape=(self.n_rows, self.n))
        inv = np.empty_like(self._perm)
        inv[self._perm] = np.arange(self._perm.size)
        sel = np.flatnonzero(T == 7)
        self._sel_pos = inv[sel].reshape(m, 2, N - 1)  # [vehicle, axis, interior node - 1]
        pr: list[IntArray] = []
        pc: list[IntArray] = []
        for ax in range(2):
            uu = self.idx_u(ax, np.arange(self.nu))
            pr.append(uu)
            pc.append(uu)
            if foh:
                pr.append(uu[:-1])
                pc.append(uu[1:])
        PR, PC = np.concatenate(pr), np.concatenate(pc)
        pids = sp.coo_matrix((np.arange(1, PR.size + 1, dtype=float), (PR, PC)), shape=(self.n, self.n)).tocsc()
        self._p_perm = pids.data.astype(np.int64) - 1
        self.P = sp.csc_matrix((np.zeros(PR.size), pids.indices.copy(), pids.indptr.copy()), shape=(self.n, self.n))
        self._build_residual_matrix()

    def _build_residual_matrix(self) -> None:
        r"""The stacked matrix :math:`M = \begin{bmatrix} P & 0 \\ 0 & A^\top \\ A & 0
        \end{bmatrix}` (``P`` whole, symmetric), so that one product
        :math:`M\,(z, y) = (Pz,\ A^\top y,\ Az)` gives every term of the KKT residuals.
        Its values are gathered from ``P.data`` and ``A.data`` (``_m_src``); the two copies
        of each entry of ``A`` are at ``_m_of_a`` (updated with ``A``)."""
        n, npd = self.n, self.P.nnz
        P, A = self.P, self.A
        p_cols = np.repeat(np.arange(n), np.diff(P.indptr))
        p_rows = P.indices.astype(np.int64)
        off = np.flatnonzero(p_rows != p_cols)
        a_cols = np.repeat(np.arange(n), np.diff(A.indptr))
        a_rows = A.indices.astype(np.int64)
        ia = np.arange(A.nnz)
        rows = np.concatenate([p_rows, p_cols[off], n + a_cols, 2 * n + a_rows])
        cols = np.concatenate([p_cols, p_rows[off], n + a_rows, a_cols])
        src = np.concatenate([np.arange(npd), off, npd + ia, npd + ia])
        ids = sp.coo_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)),
                            shape=(2 * n + self.n_rows, n + self.n_rows)).tocsr()
        order = ids.data.astype(np.int64) - 1  # CSR position -> stacked entry
        self._m_src = src[order]
        where = np.empty_like(order)
        where[order] = np.arange(order.size)
        na = A.nnz
        k0 = p_rows.size + off.size
        self._m_of_a = np.stack([where[k0:k0 + na], where[k0 + na:k0 + 2 * na]], axis=1)
        m_ = self.n_rows
        self._res_segments = np.cumsum([0, m_, n, n, n, m_])  # starts of Az−b, Pz+Aᵀy, Pz, Aᵀy, Az, b
        self._M = sp.csr_matrix((np.zeros(order.size), ids.indices.copy(), ids.indptr.copy()), shape=ids.shape)

    def _refresh_residual_matrix(self) -> None:
        self._M.data[:] = np.concatenate([self.P.data, self.A.data])[self._m_src]

    # --- values ----------------------------------------------------------------------
    def set_grid(self, t_nodes: Sequence[float] | FloatArray) -> None:
        """Fill the ``h``-dependent values of ``P`` and ``A`` for the grid ``t_nodes``
        (pattern unchanged); any contact selection is cleared."""
        t = np.asarray(t_nodes, dtype=float)
        if t.shape != (self.N + 1,) or np.any(np.diff(t) <= 0):
            raise ValueError("t_nodes must be N + 1 strictly increasing times")
        h = np.diff(t)
        self.t_nodes, self.h = t.copy(), h
        foh = self.hold == "foh"
        hk = h[self._coo_k]
        table = {
            0: np.ones_like(hk), 1: -np.ones_like(hk), 2: -hk,
            3: -(hk**2 / 3 if foh else hk**2 / 2), 4: -hk**2 / 6,
            5: -(hk / 2 if foh else hk), 6: -hk / 2, 7: np.zeros_like(hk),
        }
        vals = np.zeros(self._coo_tags.size)
        for tag, v in table.items():
            mask = self._coo_tags == tag
            vals[mask] = v[mask]
        self.A.data[:] = vals[self._perm]
        pv = np.zeros(self._p_perm.size)
        nu = self.nu
        for ax in range(2):
            base = ax * (nu + (self.N if foh else 0))
            if foh:
                d = np.zeros(nu)
                d[:-1] += h / 3
                d[1:] += h / 3
                pv[base:base + nu] = d
                pv[base + nu:base + nu + self.N] = h / 6
            else:
                pv[base:base + nu] = h
        self.P.data[:] = pv[self._p_perm]
        self.nodes = None
        self.b[self.row_collision:] = 0.0
        self._refresh_residual_matrix()
        vs = self.problem.vehicles
        self._corner_x = np.array([np.asarray(v.corner_x(t), dtype=float) for v in vs]).reshape(len(vs), -1)
        self._corner_y = np.array([float(v.corner_y) for v in vs])

    def check_nodes(self, nodes: Sequence[int]) -> tuple[int, ...]:
        out = tuple(int(k) for k in nodes)
        if len(out) != self.problem.m or any(not 0 < k < self.N for k in out):
            raise ValueError(f"need {self.problem.m} interior node(s) in 1..{self.N - 1}, got {out}")
        return out

    def selector_update(self, nodes: Sequence[int]) -> tuple[IntArray, FloatArray]:
        """Put vehicle ``i``'s contact at interior node ``nodes[i]``.

        Returns ``(positions, values)`` of the entries of ``A.data`` that changed (the old
        ones set to 0, the new ones to 1), and writes the corner values into ``b``.
        """
        nd = self.check_nodes(nodes)
        pos: list[IntArray] = []
        vals: list[FloatArray] = []
        old = self.nodes
        for i, k in enumerate(nd):
            if old is not None and old[i] == k:
                continue
            if old is not None:
                pos.append(self._sel_pos[i, :, old[i] - 1])
                vals.append(np.zeros(2))
            pos.append(self._sel_pos[i, :, k - 1])
            vals.append(np.ones(2))
        m, r0 = len(nd), self.row_collision
        self.b[r0:r0 + 2 * m:2] = self._corner_x[np.arange(m), nd]  # corner_x(t_k), tabulated per grid
        self.b[r0 + 1:r0 + 2 * m:2] = self._corner_y
        self.nodes = nd
        if not pos:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        p, v = np.concatenate(pos), np.concatenate(vals)
        self.A.data[p] = v
        self._M.data[self._m_of_a[p]] = v[:, None]
        return p, v

    # --- solution <-> arrays -----------------------------------------------------------
    def unpack(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Primal vector → nodal states ``(N+1, 4)`` ``(s_x, v_x, s_y, v_y)`` and inputs."""
        z = np.asarray(z, dtype=float)
        return z[self._X_idx], z[self._U_idx]

    def pack(self, X: FloatArray, U: FloatArray) -> FloatArray:
        """Inverse of :meth:`unpack`."""
        z = np.empty(self.n)
        k, ku = np.arange(self.N + 1), np.arange(self.nu)
        for ax in range(2):
            z[self.idx_s(ax, k)] = X[:, 2 * ax]
            z[self.idx_v(ax, k)] = X[:, 2 * ax + 1]
            z[self.idx_u(ax, ku)] = U[:, ax]
        return z

    def collision_multipliers(self, y: FloatArray) -> FloatArray:
        """``ν`` of shape ``(m, 2)`` from the dual vector."""
        return np.asarray(y, dtype=float)[self.row_collision:].reshape(self.problem.m, 2).copy()

    def kkt_residuals(self, z: FloatArray, y: FloatArray) -> KKTResiduals:
        """KKT residuals of ``(z, y)`` on the current data (``l = u = b``): the formulas of
        :func:`equality_residuals`, with ``Pz, Aᵀy, Az`` from one product with the stacked
        matrix (:meth:`_build_residual_matrix`)."""
        z, y = np.asarray(z, dtype=float), np.asarray(y, dtype=float)
        n, b = self.n, self.b
        out = self._M @ np.concatenate([z, y])
        Pz, Aty, Az = out[:n], out[n:2 * n], out[2 * n:]
        # the six maxima |Az − b|, |Pz + Aᵀy|, |Pz|, |Aᵀy|, |Az|, |b| in one segmented reduction
        mx = np.maximum.reduceat(np.abs(np.concatenate([Az - b, Pz + Aty, out, b])), self._res_segments)
        rp, rd = float(mx[0]), float(mx[1])
        zPz, by = float(z @ Pz), float(b @ y)
        rg = abs(zPz + by)
        sp_ = max(1.0, float(mx[4]), float(mx[5]))
        sd = max(1.0, float(mx[2]), float(mx[3]))
        sg = max(1.0, abs(zPz), abs(by))
        return KKTResiduals(rp, rd, rg, rp / sp_, rd / sd, rg / sg)


def equality_residuals(P_full: sp.csr_matrix, A: sp.csc_matrix, AT: sp.csr_matrix, b: FloatArray, z: FloatArray,
                       y: FloatArray) -> KKTResiduals:
    """:func:`iamp.planners.qp.backends.base.kkt_residuals` for ``q = 0``, ``l = u = b`` and a
    symmetric ``P_full`` (the same formulas, without the general-form bookkeeping; the
    sweep verifies every candidate with it)."""
    Pz, Az, Aty = P_full @ z, A @ z, AT @ y
    rp = float(np.abs(Az - b).max())
    rd = float(np.abs(Pz + Aty).max())
    zPz, by = float(z @ Pz), float(b @ y)
    rg = abs(zPz + by)
    sp_ = max(1.0, float(np.abs(Az).max()), float(np.abs(b).max()))
    sd = max(1.0, float(np.abs(Pz).max()), float(np.abs(Aty).max()))
    sg = max(1.0, abs(zPz), abs(by))
    return KKTResiduals(rp, rd, rg, rp / sp_, rd / sd, rg / sg)
