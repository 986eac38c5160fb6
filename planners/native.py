r"""The discretised QP of SPEC §3 on OSQP and Clarabel directly (no cvxpy in the loop).

The matrices are built **once per problem** with :mod:`scipy.sparse`; a candidate contact
time only changes a few numbers, and only those are sent to the solver.

The QP
------
Per axis the variables are the nodal positions ``s_0..s_N``, speeds ``v_0..v_N`` and inputs
(``u_0..u_{N-1}`` for ZOH, ``u_0..u_N`` for FOH); the vector is
``z = (s_x, v_x, u_x, s_y, v_y, u_y)``.  The problem is

.. math::

    \min_z\ \tfrac12 z^\top P z + q^\top z \quad\text{s.t.}\quad A z = b ,

with ``q = 0`` and ``½ zᵀPz = J`` exactly (no scaling):

* FOH: :math:`J = \sum_k \tfrac{h_k}{6}(u_k^2 + u_k u_{k+1} + u_{k+1}^2)`, so
  :math:`P_{kk} \mathrel{+}= h_k/3,\ P_{k+1,k+1} \mathrel{+}= h_k/3,\ P_{k,k+1} = h_k/6`;
* ZOH: :math:`J = \tfrac12\sum_k h_k u_k^2`, so :math:`P_{kk} = h_k`.

The rows of ``A z = b`` are, per axis, the exact discretisation of the double integrator
(written as ``lhs − rhs = 0`` exactly as :mod:`iamp.planners.qp` writes them to cvxpy),

.. math::

    s_{k+1} - s_k - h_k v_k - \alpha_k u_k - \beta_k u_{k+1} = 0, \qquad
    v_{k+1} - v_k - \gamma_k u_k - \delta_k u_{k+1} = 0,

(FOH: :math:`\alpha = h^2/3,\ \beta = h^2/6,\ \gamma = \delta = h/2`; ZOH:
:math:`\alpha = h^2/2,\ \gamma = h`, no :math:`u_{k+1}` term), the four boundary rows
:math:`s_0 = s(0),\ v_0 = v(0),\ s_N = s(t_f),\ v_N = v(t_f)`, and, per vehicle ``i``, two
*selector rows*

.. math::  \sum_{j=1}^{N-1} w_{ij}\, s_{x,j} = \text{corner}_{x,i}, \qquad
           \sum_{j=1}^{N-1} w_{ij}\, s_{y,j} = \text{corner}_{y,i},

whose sparsity pattern holds every interior node (explicit zeros) so that moving the
contact to node ``k`` (:math:`w_{ij} = [j = k]`) is a *value* update of ``A`` with an
unchanged pattern, plus the new corner values in ``b``.  A non-uniform (aligned) grid is
likewise a value update of ``P`` and ``A``.

Multipliers
-----------
Both solvers use the Lagrangian :math:`L = \tfrac12 z^\top P z + q^\top z + y^\top(Az - b)`
(their KKT condition is :math:`Pz + q + A^\top y = 0`), and the selector rows read
:math:`s(t_i) - \text{corner}_i`, so the multiplier of vehicle ``i``'s rows is directly
:math:`\nu_i` in the SPEC §3.3 convention :math:`L = J + \nu_i^\top (s(t_i) - \text{corner}_i)`.

Backends
--------
:data:`NATIVE_BACKENDS` maps ``"osqp"`` and ``"clarabel"`` to one class each, with one
signature: ``Backend(problem, steps, hold, settings=None)``, then ``solve_nodes(nodes)``,
``solve_times(times)``, ``set_grid(t_nodes)``, ``candidate_nodes()`` — the interface of
:class:`iamp.planners.qp.DiscretisedQP`, so :class:`NativeQPPlanner` reuses the QP planner's
sweep and refinement unchanged.

* OSQP is set up once; a candidate updates the changed entries of ``A`` (``Ax``/``Ax_idx``)
  and ``l = u = b``, and is **warm-started** from the previous candidate's primal and dual
  solution.  Settings: :func:`iamp.planners.solvers.osqp_settings` (``eps_abs = 1e-5``,
  ``eps_rel = 0``, polishing on).  The reported solver time is OSQP's ``run_time``
  (update/refactorisation + ADMM + polish) — the number cvxpy reports for OSQP too.
* Clarabel is set up once and re-used through its data-update API
  (``solver.update(A=(idx, values), b=...)``; the installed version allows it, which is
  checked with ``is_data_update_allowed()`` — if a future version refuses, the backend
  rebuilds the solver and says so in ``info["clarabel_data_update"]``).  Clarabel is an
  interior-point method and has **no warm start**: every candidate is solved from scratch,
  only the set-up (symbolic analysis, allocation) is saved.  Settings:
  :func:`iamp.planners.solvers.clarabel_settings` (tolerances 1e-12).
"""

from __future__ import annotations

import time as _time

import numpy as np
import scipy.sparse as sp

from iamp.core.problem import Problem
from iamp.planners.qp import HOLDS, HoldTrajectory, QPPlanner, aligned_grid
from iamp.core.plan import STATUS_OPTIMAL
from iamp.planners.solvers import clarabel_settings, osqp_settings


# --------------------------------------------------------------------------------------
# The QP data, built once
# --------------------------------------------------------------------------------------


class QPData:
    r"""The matrices ``P, q, A, b`` of the discretised QP with a fixed sparsity pattern.

    Parameters
    ----------
    problem : Problem
    steps : int
        Number of intervals ``N``.
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
    """

    def __init__(self, problem: Problem, steps: int, hold: str = "foh"):
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
        self.q = np.zeros(self.n)
        self.nodes = None
        self.t_nodes = None
        self.b = np.zeros(self.n_rows)
        ego = problem.ego
        for ax, (s0, v0, sf, vf) in enumerate([(ego.x0, ego.vx0, ego.xf, ego.vxf),
                                               (ego.y0, ego.vy0, ego.yf, ego.vyf)]):
            r = ax * self.n_dyn + 2 * N
            self.b[r:r + 4] = (s0, v0, sf, vf)
        self.set_grid(np.linspace(0.0, problem.tf, N + 1))

    # --- indices ---------------------------------------------------------------------
    def idx_s(self, ax: int, k):
        return ax * self.block + np.asarray(k)

    def idx_v(self, ax: int, k):
        return ax * self.block + self.N + 1 + np.asarray(k)

    def idx_u(self, ax: int, k):
        return ax * self.block + 2 * (self.N + 1) + np.asarray(k)

    def _build_pattern(self) -> None:
        """COO triplets with symbolic value tags, then the CSC data permutation."""
        N, m, foh = self.N, self.problem.m, self.hold == "foh"
        k = np.arange(N)
        rows, cols, tags = [], [], []  # tag: which value formula (see set_grid)

        def add(r, c, tag):
            r, c = np.broadcast_arrays(np.asarray(r), np.asarray(c))
            rows.append(r.ravel())
            cols.append(c.ravel())
            tags.append(np.full(r.size, tag))

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
            add([rb, rb + 1, rb + 2, rb + 3],
                [self.idx_s(ax, 0), self.idx_v(ax, 0), self.idx_s(ax, N), self.idx_v(ax, N)], 0)
        interior = np.arange(1, N)
        for i in range(m):
            for ax in range(2):
                add(self.row_collision + 2 * i + ax, self.idx_s(ax, interior), 7)  # selector
        rows, cols, tags = np.concatenate(rows), np.concatenate(cols), np.concatenate(tags)
        self._coo_rows, self._coo_cols, self._coo_tags = rows, cols, tags
        # interval index of every dynamics entry (for the h-dependent values)
        local = rows % self.n_dyn
        self._coo_k = np.where(rows < self.row_collision, np.where(local < N, local, local - N), 0)
        self._coo_k = np.minimum(self._coo_k, N - 1)
        ids = sp.coo_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)),
                            shape=(self.n_rows, self.n)).tocsc()
        if ids.nnz != rows.size:  # pragma: no cover - a modelling bug
            raise RuntimeError("duplicate entries in the QP pattern")
        self._perm = ids.data.astype(np.int64) - 1  # CSC position -> COO entry
        self.A = sp.csc_matrix((np.zeros(rows.size), ids.indices.copy(), ids.indptr.copy()),
                               shape=(self.n_rows, self.n))
        # CSC data position of every selector entry: [vehicle, axis, interior node j-1]
        inv = np.empty_like(self._perm)
        inv[self._perm] = np.arange(self._perm.size)
        sel = np.flatnonzero(tags == 7)
        self._sel_pos = inv[sel].reshape(m, 2, N - 1)
        # P pattern (upper triangle)
        pr, pc, pt = [], [], []
        for ax in range(2):
            u = self.idx_u(ax, np.arange(self.nu))
            pr.append(u)
            pc.append(u)
            pt.append(np.zeros(self.nu, dtype=int))
            if foh:
                pr.append(u[:-1])
                pc.append(u[1:])
                pt.append(np.ones(N, dtype=int))
        pr, pc, pt = np.concatenate(pr), np.concatenate(pc), np.concatenate(pt)
        pids = sp.coo_matrix((np.arange(1, pr.size + 1, dtype=float), (pr, pc)), shape=(self.n, self.n)).tocsc()
        self._p_perm = pids.data.astype(np.int64) - 1
        self._p_rows, self._p_cols, self._p_tags = pr, pc, pt
        self.P = sp.csc_matrix((np.zeros(pr.size), pids.indices.copy(), pids.indptr.copy()), shape=(self.n, self.n))

    # --- values ----------------------------------------------------------------------
    def set_grid(self, t_nodes) -> None:
        """Fill the ``h``-dependent values of ``P`` and ``A`` for the grid ``t_nodes``
        (pattern unchanged); any contact selection is cleared."""
        t_nodes = np.asarray(t_nodes, dtype=float)
        if t_nodes.shape != (self.N + 1,) or np.any(np.diff(t_nodes) <= 0):
            raise ValueError("t_nodes must be N + 1 strictly increasing times")
        h = np.diff(t_nodes)
        self.t_nodes, self.h = t_nodes, h
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
        # P
        pv = np.zeros(self._p_tags.size)
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

    def selector_update(self, nodes) -> tuple[np.ndarray, np.ndarray]:
        """Set the contact of vehicle ``i`` at interior node ``nodes[i]``.

        Returns ``(positions, values)`` of the entries of ``A.data`` that changed (the old
        ones set to 0, the new ones to 1), and updates ``b`` with the corner values.
        """
        nodes = tuple(int(k) for k in nodes)
        if len(nodes) != self.problem.m or any(not 0 < k < self.N for k in nodes):
            raise ValueError(f"need {self.problem.m} interior node(s) in 1..{self.N - 1}, got {nodes}")
        pos, vals = [], []
        old = self.nodes
        for i, k in enumerate(nodes):
            if old is not None and old[i] == k:
                continue
            if old is not None:
                pos.append(self._sel_pos[i, :, old[i] - 1])
                vals.append(np.zeros(2))
            pos.append(self._sel_pos[i, :, k - 1])
            vals.append(np.ones(2))
        for i, k in enumerate(nodes):
            veh = self.problem.vehicles[i]
            self.b[self.row_collision + 2 * i] = float(veh.corner_x(self.t_nodes[k]))
            self.b[self.row_collision + 2 * i + 1] = float(veh.corner_y)
        self.nodes = nodes
        if not pos:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        pos, vals = np.concatenate(pos), np.concatenate(vals)
        self.A.data[pos] = vals
        return pos, vals

    # --- solution <-> arrays -----------------------------------------------------------
    def unpack(self, z) -> tuple[np.ndarray, np.ndarray]:
        """Primal vector → nodal states ``(N+1, 4)`` ``(s_x, v_x, s_y, v_y)`` and inputs."""
        z = np.asarray(z)
        N = self.N
        X = np.stack([z[self.idx_s(0, np.arange(N + 1))], z[self.idx_v(0, np.arange(N + 1))],
                      z[self.idx_s(1, np.arange(N + 1))], z[self.idx_v(1, np.arange(N + 1))]], axis=1)
        U = np.stack([z[self.idx_u(0, np.arange(self.nu))], z[self.idx_u(1, np.arange(self.nu))]], axis=1)
        return X, U

    def pack(self, X, U) -> np.ndarray:
        """Inverse of :meth:`unpack`."""
        z = np.empty(self.n)
        N = self.N
        for ax in range(2):
            z[self.idx_s(ax, np.arange(N + 1))] = X[:, 2 * ax]
            z[self.idx_v(ax, np.arange(N + 1))] = X[:, 2 * ax + 1]
            z[self.idx_u(ax, np.arange(self.nu))] = U[:, ax]
        return z

    def collision_multipliers(self, y) -> np.ndarray:
        """``ν`` of shape ``(m, 2)`` from the dual vector."""
        return np.asarray(y)[self.row_collision:].reshape(self.problem.m, 2).copy()

    def dual_from_cvxpy(self, qp) -> np.ndarray:
        """The dual vector of a solved :class:`~iamp.planners.qp.DiscretisedQP` in this row
        order (cvxpy's ``dual_value`` of ``lhs == rhs`` is the multiplier of ``lhs − rhs``,
        the same orientation as these rows)."""
        y = np.empty(self.n_rows)
        cons = qp.cp_problem.constraints
        N = self.N
        for ax in range(2):
            c = cons[6 * ax:6 * ax + 6]
            r0 = ax * self.n_dyn
            y[r0:r0 + N] = np.asarray(c[0].dual_value).ravel()
            y[r0 + N:r0 + 2 * N] = np.asarray(c[1].dual_value).ravel()
            y[r0 + 2 * N:r0 + 2 * N + 4] = [float(np.asarray(c[j].dual_value)) for j in range(2, 6)]
        for i, (cx, cy) in enumerate(qp.collision):
            y[self.row_collision + 2 * i] = float(cx.dual_value)
            y[self.row_collision + 2 * i + 1] = float(cy.dual_value)
        return y

    def kkt_residuals(self, z, y) -> dict:
        """KKT residuals of ``(z, y)`` for the current data; see :func:`kkt_residuals`."""
        return kkt_residuals(self.P, self.q, self.A, self.b, z, y)


def kkt_residuals(P, q, A, b, x, y) -> dict:
    r"""KKT residuals of an equality-constrained QP, recomputed from the data.

    For :math:`\min \tfrac12 x^\top P x + q^\top x` s.t. :math:`Ax = b` with multipliers
    ``y`` in the convention :math:`L = \tfrac12 x^\top Px + q^\top x + y^\top (Ax - b)`
    (qpbenchmark's definitions, restricted to equalities):

    .. math::

        r_p = \|Ax - b\|_\infty, \qquad
        r_d = \|Px + q + A^\top y\|_\infty, \qquad
        r_g = |x^\top P x + q^\top x + b^\top y| .

    ``P`` holds the upper triangle only (as given to OSQP and Clarabel); the full symmetric
    matrix is used.  The relative versions divide by the largest magnitude among the terms
    of each expression (at least 1), like OSQP's relative criteria:
    :math:`\max(1, \|Ax\|_\infty, \|b\|_\infty)`,
    :math:`\max(1, \|Px\|_\infty, \|q\|_\infty, \|A^\top y\|_\infty)`,
    :math:`\max(1, |x^\top Px|, |q^\top x|, |b^\top y|)`.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    Pf = P + sp.triu(P, 1).T
    Px, Ax, Aty = Pf @ x, A @ x, A.T @ y
    rp = float(np.max(np.abs(Ax - b)))
    rd = float(np.max(np.abs(Px + q + Aty)))
    xPx, qx, by = float(x @ Px), float(q @ x), float(b @ y)
    rg = abs(xPx + qx + by)
    sp_ = max(1.0, float(np.max(np.abs(Ax))), float(np.max(np.abs(b))))
    sd = max(1.0, float(np.max(np.abs(Px))), float(np.max(np.abs(q))), float(np.max(np.abs(Aty))))
    sg = max(1.0, abs(xPx), abs(qx), abs(by))
    return {"primal": rp, "dual": rd, "gap": rg,
            "primal_rel": rp / sp_, "dual_rel": rd / sd, "gap_rel": rg / sg}


# --------------------------------------------------------------------------------------
# Backends
# --------------------------------------------------------------------------------------


class _NativeQP:
    """Common driver; subclasses implement ``_setup``, ``_update`` and ``_solve``."""

    name = "native"

    def __init__(self, problem: Problem, steps: int = 100, hold: str = "foh", settings: dict | None = None):
        self.problem = problem
        self.data = QPData(problem, steps, hold)
        self.N, self.hold = self.data.N, hold
        self.settings = {**self.default_settings(), **(settings or {})}
        self.n_solves = 0
        self.info: dict = {}
        self._grid_dirty = False
        t0 = _time.perf_counter()
        self._setup()
        self.setup_time_s = _time.perf_counter() - t0

    @staticmethod
    def default_settings() -> dict:  # pragma: no cover - overridden
        return {}

    @property
    def t_nodes(self) -> np.ndarray:
        return self.data.t_nodes

    # --- the DiscretisedQP interface ----------------------------------------------------
    def set_grid(self, t_nodes) -> None:
        """Move to another grid (a value update of ``P`` and ``A``)."""
        t_nodes = np.asarray(t_nodes, dtype=float)
        if self.data.t_nodes is not None and np.array_equal(t_nodes, self.data.t_nodes):
            return
        nodes = self.data.nodes
        self.data.set_grid(t_nodes)
        self._grid_dirty = True
        if nodes is not None:  # keep the selector consistent with A
            self.data.selector_update(nodes)

    def candidate_nodes(self):
        """Every ordered combination of distinct interior nodes, one per vehicle."""
        import itertools

        return itertools.permutations(range(1, self.N), self.problem.m)

    def solve_nodes(self, nodes) -> dict:
        """Solve with the contacts at the given nodes of the current grid.

        Returns the keys of :meth:`iamp.planners.qp.DiscretisedQP.solve_nodes` plus ``z``
        and ``y`` (primal and dual vectors), ``iterations``, ``wall_time_s`` (data update +
        solve + unpacking, measured here) and ``solve_call_s`` (the solver's ``solve()`` call
        alone, measured here).  ``solver_time_s`` is what the solver reports (OSQP
        ``run_time``; Clarabel ``solve_time``, which in clarabel 0.11.1 exceeds the measured
        wall time of the ``solve()`` call several-fold, so it is not used for overheads).
        """
        t0 = _time.perf_counter()
        pos, vals = self.data.selector_update(nodes)
        self._update(pos, vals)
        self._grid_dirty = False
        status, z, y, solver_time, iters, polished, call = self._solve()
        wall = _time.perf_counter() - t0
        self.n_solves += 1
        out = {"status": status, "cost": np.inf, "nodes": tuple(int(k) for k in nodes), "polished": polished,
               "solver_time_s": solver_time, "wall_time_s": wall, "solve_call_s": call, "iterations": iters}
        if status != STATUS_OPTIMAL:
            return out
        X, U = self.data.unpack(z)
        traj = HoldTrajectory(self.data.t_nodes.copy(), X, U, self.hold)
        out.update(cost=traj.cost(), trajectory=traj, multipliers=self.data.collision_multipliers(y),
                   contact_times=self.data.t_nodes[np.asarray(nodes, dtype=int)].copy(), z=z, y=y)
        return out

    def solve_times(self, times) -> dict:
        """Solve on a grid aligned with the (off-grid) contact times ``times``."""
        t_nodes, idx = aligned_grid(times, self.problem.tf, self.N)
        self.set_grid(t_nodes)
        return self.solve_nodes(idx)

    def kkt_residuals(self, result: dict) -> dict:
        """KKT residuals of a :meth:`solve_nodes` result (on the data it was solved with,
        provided no other candidate was solved since)."""
        return self.data.kkt_residuals(result["z"], result["y"])


class OSQPBackend(_NativeQP):
    """OSQP, set up once, updated per candidate and warm-started (see the module notes)."""

    name = "osqp"

    @staticmethod
    def default_settings() -> dict:
        return osqp_settings()

    def _setup(self) -> None:
        import osqp

        d = self.data
        self.solver = osqp.OSQP()
        self.solver.setup(d.P, d.q, d.A, d.b.copy(), d.b.copy(), **self.settings)
        self._last = None
        self.info = {"warm_start": True}

    def _update(self, pos, vals) -> None:
        d = self.data
        if self._grid_dirty:
            self.solver.update(Px=d.P.data.copy(), Ax=d.A.data.copy(), l=d.b.copy(), u=d.b.copy())
        else:
            if pos.size:
                self.solver.update(Ax=vals.copy(), Ax_idx=pos.astype(np.int64))
            self.solver.update(l=d.b.copy(), u=d.b.copy())
        if self._last is not None:
            self.solver.warm_start(x=self._last[0], y=self._last[1])

    def _solve(self):
        t0 = _time.perf_counter()
        res = self.solver.solve(raise_error=False)
        call = _time.perf_counter() - t0
        info = res.info
        raw = str(info.status).lower()
        status = STATUS_OPTIMAL if raw == "solved" else raw.replace(" ", "_")
        polished = int(getattr(info, "status_polish", 0)) == 1
        z, y = np.array(res.x, dtype=float), np.array(res.y, dtype=float)
        if np.all(np.isfinite(z)) and np.all(np.isfinite(y)):
            self._last = (z, y)
        return status, z, y, float(info.run_time), int(info.iter), polished, call


class ClarabelBackend(_NativeQP):
    """Clarabel, set up once and re-used through its data-update API; no warm start."""

    name = "clarabel"

    @staticmethod
    def default_settings() -> dict:
        return clarabel_settings()

    def _make_settings(self):
        import clarabel

        s = clarabel.DefaultSettings()
        for k, v in self.settings.items():
            setattr(s, k, v)
        return s

    def _setup(self) -> None:
        import clarabel

        d = self.data
        self._cones = [clarabel.ZeroConeT(d.n_rows)]
        self.solver = clarabel.DefaultSolver(d.P, d.q, d.A, d.b.copy(), self._cones, self._make_settings())
        self.data_update = bool(self.solver.is_data_update_allowed())
        self.info = {"warm_start": False, "clarabel_data_update": self.data_update}

    def _update(self, pos, vals) -> None:
        d = self.data
        if not self.data_update:  # rebuild (documented fallback)
            import clarabel

            self.solver = clarabel.DefaultSolver(d.P, d.q, d.A, d.b.copy(), self._cones, self._make_settings())
            return
        if self._grid_dirty:
            self.solver.update(P=d.P.data.copy(), A=d.A.data.copy(), b=d.b.copy())
        else:
            if pos.size:
                self.solver.update(A=(pos.astype(np.int64), vals.copy()), b=d.b.copy())
            else:
                self.solver.update(b=d.b.copy())

    def _solve(self):
        t0 = _time.perf_counter()
        sol = self.solver.solve()
        call = _time.perf_counter() - t0
        raw = str(sol.status)
        status = STATUS_OPTIMAL if raw == "Solved" else _snake(raw)
        z, y = np.array(sol.x, dtype=float), np.array(sol.z, dtype=float)
        return status, z, y, float(sol.solve_time), int(sol.iterations), None, call


def _snake(name: str) -> str:
    out = []
    for ch in name:
        if ch.isupper() and out:
            out.append("_")
        out.append(ch.lower())
    return "".join(out)


#: The native backends, one per solver, with one signature:
#: ``NATIVE_BACKENDS[name](problem, steps, hold, settings=None)``.
NATIVE_BACKENDS: dict[str, type[_NativeQP]] = {"osqp": OSQPBackend, "clarabel": ClarabelBackend}


def build_native(problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 settings: dict | None = None) -> _NativeQP:
    """Build the native QP of ``problem`` for ``solver`` (``"osqp"`` or ``"clarabel"``)."""
    try:
        cls = NATIVE_BACKENDS[solver]
    except KeyError:
        raise ValueError(f"unknown solver {solver!r}; choose from {', '.join(NATIVE_BACKENDS)}") from None
    from iamp.planners.solvers import get_solver

    get_solver(solver)  # raises MissingDependencyError with install advice if absent
    return cls(problem, steps, hold, settings)


class NativeQPPlanner(QPPlanner):
    """:class:`~iamp.planners.qp.QPPlanner` on the native backends.

    Same parameters and the same contact-time search (``grid``: sweep every interior node
    combination; ``refine``: then off the grid); only :meth:`build` differs.  The result's
    ``info["path"]`` is ``"native"``.
    """

    def build(self, problem: Problem) -> _NativeQP:
        return build_native(problem, self.steps, self.hold, self.solver, self.solver_settings)

    def plan(self, problem: Problem, qp=None):
        res = super().plan(problem, qp)
        res.info["path"] = "native"
        return res


def native_sweep(problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 settings: dict | None = None, qp: _NativeQP | None = None) -> dict:
    """Solve the native QP at every interior node (every ordered combination for several
    vehicles) of the uniform grid.

    Returns ``{"best", "costs" (node tuple → cost), "failures", "n_solves", "wall_time_s",
    "solver_time_s" (sum of the solver-reported times), "setup_time_s"}``; ``best`` is the
    :meth:`_NativeQP.solve_nodes` result of the cheapest optimal candidate (``None`` if none).
    """
    t0 = _time.perf_counter()
    qp = qp or build_native(problem, steps, hold, solver, settings)
    qp.set_grid(np.linspace(0.0, problem.tf, qp.N + 1))
    best, costs, failures, solver_time = None, {}, [], 0.0
    for nodes in qp.candidate_nodes():
        r = qp.solve_nodes(nodes)
        solver_time += r["solver_time_s"] or 0.0
        costs[r["nodes"]] = r["cost"]
        if r["status"] != STATUS_OPTIMAL:
            failures.append((r["nodes"], r["status"]))
        elif best is None or r["cost"] < best["cost"]:
            best = r
    return {"best": best, "costs": costs, "failures": failures, "n_solves": len(costs),
            "wall_time_s": _time.perf_counter() - t0, "solver_time_s": solver_time,
            "setup_time_s": qp.setup_time_s}
