r"""The independent cross-check: the discretised QP of SPEC §3 written in cvxpy.

Not a production path (that is :mod:`iamp.planners.qp.planner`): this is the same QP formulated a
second time, independently — as cvxpy expressions, compiled once (DPP) and re-solved per
candidate through cvxpy's own canonicalisation — so that tests and ``iamp compare`` can
check the matrices of :mod:`iamp.planners.qp.data` against it.

Per axis, with steps :math:`h_k`:

* ZOH: :math:`s_{k+1} = s_k + h_k v_k + \tfrac{h_k^2}{2} u_k`, :math:`v_{k+1} = v_k + h_k u_k`,
  cost :math:`\tfrac12 \sum_k h_k u_k^2`;
* FOH: :math:`s_{k+1} = s_k + h_k v_k + h_k^2 (u_k/3 + u_{k+1}/6)`,
  :math:`v_{k+1} = v_k + \tfrac{h_k}{2}(u_k + u_{k+1})`, cost
  :math:`\sum_k \tfrac{h_k}{8}(u_k+u_{k+1})^2 + \tfrac{h_k}{24}(u_k-u_{k+1})^2`.

The contact node of vehicle ``i`` is picked by a one-hot Parameter :math:`w_i`
(:math:`s_x^\top w_i = \text{corner}_{x,i}`, :math:`s_y^\top w_i = \text{corner}_{y,i}`); the
steps are Parameters too.  cvxpy's ``dual_value`` of ``lhs == rhs`` is the multiplier of
``lhs − rhs``, i.e. :math:`\nu_i` in the convention :math:`L = J + \nu_i^\top(s(t_i) -
\text{corner}_i)`.  Results are :class:`~iamp.planners.qp.core.CandidateResult`, verified
like the production path: the primal and dual vectors are mapped onto the rows of
:class:`~iamp.planners.qp.data.QPData` and the KKT residuals recomputed from those matrices.

With ``problem.limits`` (SPEC §14) the limit rows of :func:`iamp.planners.qp.limits.limit_rows`
(the one implementation of the rows) are added as ``lo <= A_L z <= hi`` on the same variables,
their duals mapped onto the stacked rows ``[A; A_L]`` (``y > 0`` at the upper bound), and the
KKT check adds complementarity; an infeasible candidate is certified from cvxpy's duals (the
Farkas ray, either sign).  The sweep's screens (:meth:`~iamp.planners.qp.planner.QPPlanner.sweep`)
are the planner's, shared with the native path.

cvxpy status → :mod:`iamp.core.status`: ``optimal`` → OPTIMAL; ``optimal_inaccurate`` →
INACCURATE; ``infeasible(_inaccurate)`` → INFEASIBLE; ``user_limit`` → MAX_ITER (cvxpy's word
for a solver's iteration or time limit); ``unbounded(_inaccurate)``, ``solver_error`` and
anything else → SOLVER_ERROR.
"""

from __future__ import annotations

import itertools
import math
import time
import warnings
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import cvxpy as _cvxpy
import numpy as np

from iamp.core import status as st
from iamp.core.errors import OptionError
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.qp.backends import BACKENDS, get_backend
from iamp.planners.qp.backends.base import FloatArray
from iamp.planners.qp.bounded import OSQP_SETTINGS, bounded_kkt, certified_infeasible, check_complementarity, stacked
from iamp.planners.qp.core import CandidateResult, CandidateSolver, verify
from iamp.planners.qp.data import QPData
from iamp.planners.qp.hold import HOLDS, HoldTrajectory, aligned_grid
from iamp.planners.qp.limits import LimitRows, limit_rows
from iamp.planners.qp.planner import QPPlanner

cp: Any = _cvxpy  # cvxpy's partial annotations are not what this module checks

CVXPY_STATUS: dict[str, str] = {
    "optimal": st.OPTIMAL,
    "optimal_inaccurate": st.INACCURATE,
    "infeasible": st.INFEASIBLE,
    "infeasible_inaccurate": st.INFEASIBLE,
    "user_limit": st.MAX_ITER,
    "unbounded": st.SOLVER_ERROR,
    "unbounded_inaccurate": st.SOLVER_ERROR,
    "solver_error": st.SOLVER_ERROR,
}

#: iamp backend name -> cvxpy solver name (``kkt`` has no cvxpy counterpart).
CVXPY_NAMES = {"osqp": "OSQP", "clarabel": "CLARABEL", "piqp": "PIQP"}


def map_status(raw: str) -> str:
    """cvxpy's status word → the iamp vocabulary."""
    return CVXPY_STATUS.get(str(raw), st.SOLVER_ERROR)


class CvxpyQP:
    """The QP of one problem in cvxpy, compiled once (DPP), re-solved per candidate.

    Same interface as :class:`iamp.planners.qp.core.DiscretisedQP` (``set_grid``,
    ``solve_nodes``, ``solve_times``, ``candidate_nodes``), so
    :class:`~iamp.planners.qp.planner.QPPlanner`'s sweep and refinement run on it unchanged.
    """

    def __init__(self, problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 settings: Mapping[str, object] | None = None) -> None:
        if hold not in HOLDS:
            raise ValueError(f"unknown hold {hold!r}; choose from {', '.join(HOLDS)}")
        if solver not in CVXPY_NAMES:
            raise ValueError(f"solver {solver!r} has no cvxpy path; choose from {', '.join(CVXPY_NAMES)}")
        if int(steps) != steps or steps < problem.m + 1:
            raise ValueError(f"steps must be an integer >= {problem.m + 1} (got {steps})")
        t_start = time.perf_counter()
        cls = get_backend(solver)
        self.solver, self.cvxpy_name = solver, CVXPY_NAMES[solver]
        self.settings = {**cls.default_settings(), **dict(settings or {})}
        if solver == "piqp":
            self.settings.pop("compute_timings", None)
        self.tolerance = tol(cls.tolerance_key)
        self.problem, self.N, self.hold = problem, int(steps), hold
        self.data = QPData(problem, self.N, hold)  # for the KKT check only
        N, m, ego = self.N, problem.m, problem.ego
        self.h = cp.Parameter(N, nonneg=True)
        self.h_sq_a = cp.Parameter(N, nonneg=True)  # ZOH: h²/2; FOH: h²/3
        self.h_sq_b = cp.Parameter(N, nonneg=True)  # FOH: h²/6 (unused for ZOH)
        self.w1 = cp.Parameter(N, nonneg=True)  # cost weights (sqrt)
        self.w2 = cp.Parameter(N, nonneg=True)
        self.select = [cp.Parameter(N + 1, nonneg=True) for _ in range(m)]
        self.corner_x = [cp.Parameter() for _ in range(m)]
        self.corner_y = [cp.Parameter() for _ in range(m)]
        nu = N if hold == "zoh" else N + 1
        self.s = [cp.Variable(N + 1), cp.Variable(N + 1)]  # x, y
        self.v = [cp.Variable(N + 1), cp.Variable(N + 1)]
        self.u = [cp.Variable(nu), cp.Variable(nu)]
        cons: list[Any] = []
        cost: Any = 0
        bc = [(ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf)]
        for ax in range(2):
            s, v, u = self.s[ax], self.v[ax], self.u[ax]
            if hold == "zoh":
                cons += [s[1:] == s[:-1] + cp.multiply(self.h, v[:-1]) + cp.multiply(self.h_sq_a, u),
                         v[1:] == v[:-1] + cp.multiply(self.h, u)]
                cost += cp.sum_squares(cp.multiply(self.w1, u))
            else:
                cons += [s[1:] == s[:-1] + cp.multiply(self.h, v[:-1]) + cp.multiply(self.h_sq_a, u[:-1])
                         + cp.multiply(self.h_sq_b, u[1:]),
                         v[1:] == v[:-1] + cp.multiply(self.h / 2, u[:-1] + u[1:])]
                cost += (cp.sum_squares(cp.multiply(self.w1, u[:-1] + u[1:]))
                         + cp.sum_squares(cp.multiply(self.w2, u[:-1] - u[1:])))
            s0, v0, sf, vf = bc[ax]
            cons += [s[0] == s0, v[0] == v0, s[N] == sf, v[N] == vf]
        self.collision = []
        for i in range(m):
            cx = self.s[0] @ self.select[i] - self.corner_x[i] == 0
            cy = self.s[1] @ self.select[i] - self.corner_y[i] == 0
            self.collision.append((cx, cy))
            cons += [cx, cy]
        self.rows: LimitRows | None = None
        if problem.limits is not None and not problem.limits.empty:  # SPEC §14: the bounded QP
            # the rows of iamp.planners.qp.limits on z in QPData's layout (one implementation of the
            # rows; the dynamics, cost and corners above are this module's own), bounds at the nodes
            self.rows = limit_rows(self.data, self.data.t_nodes, hold, problem.limits)
            z = cp.hstack([self.s[0], self.v[0], self.u[0], self.s[1], self.v[1], self.u[1]])
            self.limit_lo = cp.Parameter(self.rows.n_rows)
            self.limit_hi = cp.Parameter(self.rows.n_rows)
            AL = self.rows.A @ z
            self.limit_cons = (AL <= self.limit_hi, AL >= self.limit_lo)
            cons += list(self.limit_cons)
            if solver == "osqp":  # infeasibility certificates accurate enough to verify, as on the native path
                self.settings = {**cls.default_settings(), **OSQP_SETTINGS, **dict(settings or {})}
        self.cp_problem = cp.Problem(cp.Minimize(cost), cons)
        if not self.cp_problem.is_dpp():  # pragma: no cover - a modelling bug, not user input
            raise RuntimeError("the QP is not DPP")
        self.n_solves = 0
        self._t_nodes = np.linspace(0.0, problem.tf, N + 1)
        self.set_grid(self._t_nodes)
        self.setup_time_s = time.perf_counter() - t_start

    @property
    def t_nodes(self) -> FloatArray:
        return self._t_nodes

    def set_grid(self, t_nodes: Sequence[float] | FloatArray) -> None:
        t = np.asarray(t_nodes, dtype=float)
        h = np.diff(t)
        self._t_nodes = t.copy()
        self.data.set_grid(t)
        if self.rows is not None:
            self.rows.set_grid(t)
            self.limit_lo.value, self.limit_hi.value = self.rows.lo, self.rows.hi
        self.h.value = h
        if self.hold == "zoh":
            self.h_sq_a.value = h**2 / 2
            self.h_sq_b.value = np.zeros_like(h)
            self.w1.value = np.sqrt(h / 2)
            self.w2.value = np.zeros_like(h)
        else:
            self.h_sq_a.value = h**2 / 3
            self.h_sq_b.value = h**2 / 6
            self.w1.value = np.sqrt(h / 8)
            self.w2.value = np.sqrt(h / 24)

    def set_uniform_grid(self) -> None:
        self.set_grid(np.linspace(0.0, self.problem.tf, self.N + 1))

    def candidate_nodes(self) -> Iterator[tuple[int, ...]]:
        return itertools.permutations(range(1, self.N), self.problem.m)

    def n_candidates(self) -> int:
        return math.perm(self.N - 1, self.problem.m)

    def _set_contacts(self, nodes: tuple[int, ...]) -> None:
        for i, k in enumerate(nodes):
            w = np.zeros(self.N + 1)
            w[k] = 1.0
            self.select[i].value = w
            veh = self.problem.vehicles[i]
            self.corner_x[i].value = float(veh.corner_x(self._t_nodes[k]))
            self.corner_y[i].value = float(veh.corner_y)

    def dual_vector(self) -> FloatArray:
        """The dual vector of the last solve in :class:`QPData`'s row order."""
        y = np.empty(self.data.n_rows)
        cons = self.cp_problem.constraints
        N, nd = self.N, self.data.n_dyn
        for ax in range(2):
            c = cons[6 * ax:6 * ax + 6]
            r0 = ax * nd
            y[r0:r0 + N] = np.asarray(c[0].dual_value).ravel()
            y[r0 + N:r0 + 2 * N] = np.asarray(c[1].dual_value).ravel()
            y[r0 + 2 * N:r0 + 2 * N + 4] = [float(np.asarray(c[j].dual_value)) for j in range(2, 6)]
        for i, (cx, cy) in enumerate(self.collision):
            y[self.data.row_collision + 2 * i] = float(cx.dual_value)
            y[self.data.row_collision + 2 * i + 1] = float(cy.dual_value)
        if self.rows is None:
            return y
        upper, lower = self.limit_cons  # y > 0 at the upper bound, < 0 at the lower (QPData's rows first)
        return np.asarray(np.r_[y, np.asarray(upper.dual_value, dtype=float).ravel()
                                - np.asarray(lower.dual_value, dtype=float).ravel()], dtype=float)

    def _duals_or_none(self) -> FloatArray | None:
        """The dual vector of the last solve, or None when cvxpy left a dual unset."""
        try:
            y = self.dual_vector()
        except (TypeError, ValueError):
            return None
        return y if np.all(np.isfinite(y)) else None

    def solve_nodes(self, nodes: Sequence[int]) -> CandidateResult:
        t0 = time.perf_counter()
        nd = self.data.check_nodes(nodes)
        self._set_contacts(nd)
        self.data.selector_update(nd)
        try:
            with warnings.catch_warnings():  # cvxpy warns on inaccurate solutions; the status says it
                warnings.simplefilter("ignore")
                # bounded: no warm start (after an infeasible candidate OSQP's iterate is a divergent ray,
                # from which a feasible neighbour ran out of iterations: measured on the template, N = 20)
                self.cp_problem.solve(solver=self.cvxpy_name, warm_start=self.rows is None, **self.settings)
            raw = str(self.cp_problem.status)
        except cp.error.SolverError:
            raw = "solver_error"
        self.n_solves += 1
        stats = self.cp_problem.solver_stats
        solver_time = getattr(stats, "solve_time", None) if stats is not None else None
        times = self._t_nodes[np.asarray(nd, dtype=np.int64)].copy()
        r = CandidateResult(nodes=nd, status=map_status(raw), solver_status=map_status(raw), raw_status=raw,
                            cost=np.inf, contact_times=times, solver_time_s=solver_time)
        if self.s[0].value is not None and raw in ("optimal", "optimal_inaccurate"):
            val = [np.asarray(x.value, dtype=float) for x in (self.s[0], self.v[0], self.s[1], self.v[1])]
            X = np.stack(val, axis=1)
            U = np.stack([np.asarray(self.u[0].value, dtype=float), np.asarray(self.u[1].value, dtype=float)], axis=1)
            r.z, r.y = self.data.pack(X, U), self.dual_vector()
            if self.rows is None:
                r.kkt = self.data.kkt_residuals(r.z, r.y)
                r.status, r.checks, r.failed_check = verify(r.kkt, self.tolerance, r.solver_status)
            else:
                r.kkt, comp = bounded_kkt(self.data, self.rows, r.z, r.y)
                r.status, r.checks, r.failed_check = verify(r.kkt, self.tolerance, r.solver_status)
                r.status, r.failed_check = check_complementarity(r.checks, r.status, r.failed_check, comp,
                                                                 self.tolerance)
            if r.ok:
                r.trajectory = HoldTrajectory(self._t_nodes.copy(), X, U, self.hold)
                r.cost = r.trajectory.cost()
                r.multipliers = np.array([[float(cx.dual_value), float(cy.dual_value)] for cx, cy in self.collision])
        elif self.rows is not None and r.status == st.INFEASIBLE:  # cvxpy's duals hold the Farkas ray
            A, lo, hi = stacked(self.data, self.rows)
            r.infeasible_certified, farkas = certified_infeasible(A, lo, hi, self._duals_or_none())
            r.checks.update(farkas)
        r.wall_time_s = time.perf_counter() - t0
        return r

    def solve_times(self, times: Sequence[float] | FloatArray) -> CandidateResult:
        t_nodes, idx = aligned_grid(times, self.problem.tf, self.N)
        self.set_grid(t_nodes)
        return self.solve_nodes([int(k) for k in idx])


class CvxpyQPPlanner(QPPlanner):
    """:class:`~iamp.planners.qp.planner.QPPlanner` on the cvxpy formulation (cross-check only)."""

    path = "cvxpy"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.solver not in CVXPY_NAMES:
            raise ValueError(f"solver {self.solver!r} has no cvxpy path; choose from {', '.join(CVXPY_NAMES)}")

    def build(self, problem: Problem) -> CandidateSolver:
        if problem.limits is not None and not problem.limits.empty and self.limits_between != "nodes":
            raise OptionError("the cvxpy cross-check imposes the vx and y bounds at the grid nodes only; use the "
                              "native path for limits_between='certified'", "limits_between")
        return CvxpyQP(problem, self.steps, self.hold, self.solver, self.solver_settings)


__all__ = ["BACKENDS", "CVXPY_STATUS", "CvxpyQP", "CvxpyQPPlanner", "map_status"]
