r"""The convex baseline: the lane change discretised as a QP (an MPC over one horizon),
with the same equality collision constraints at grid nodes (SPEC §3).

On a grid :math:`0 = t_0 < \dots < t_N = t_f` with steps :math:`h_k`, exact discretisations
of the double integrator per axis:

* ZOH, :math:`u` constant on each interval:
  :math:`s_{k+1} = s_k + h_k v_k + \tfrac{h_k^2}{2} u_k`, :math:`v_{k+1} = v_k + h_k u_k`,
  cost :math:`\tfrac12 \sum_k h_k u_k^2`;
* FOH, :math:`u` linear between nodal values:
  :math:`s_{k+1} = s_k + h_k v_k + h_k^2 (u_k/3 + u_{k+1}/6)`,
  :math:`v_{k+1} = v_k + \tfrac{h_k}{2}(u_k + u_{k+1})`,
  cost :math:`\sum_k \tfrac{h_k}{6}(u_k^2 + u_k u_{k+1} + u_{k+1}^2)
  = \sum_k \tfrac{h_k}{8}(u_k+u_{k+1})^2 + \tfrac{h_k}{24}(u_k-u_{k+1})^2`.

The contact node of vehicle ``i`` is picked by a one-hot Parameter :math:`w_i`, so the
constraint :math:`s_x^\top w_i = \text{corner}_{x,i}`, :math:`s_y^\top w_i = \text{corner}_{y,i}`
is DPP: the problem is compiled once and re-solved for every candidate.  The steps
:math:`h_k` are Parameters too, so ``refine`` can align a non-uniform grid with an off-grid
candidate time.  The multiplier of :math:`s(t_i) - \text{corner}_i = 0` in the convention
:math:`L = J + \nu_i^\top (s(t_i) - \text{corner}_i)` is cvxpy's ``dual_value``; it equals the
PMP jump :math:`\Phi_i` (SPEC §3.3).

The QP never sees the PMP's contact times: ``grid`` sweeps every interior node (every
ordered combination of distinct nodes for several vehicles); ``refine`` then searches off
the grid, seeded by the sweep (bounded Brent for one vehicle, Nelder–Mead for several),
on grids aligned with the candidate times.
"""

from __future__ import annotations

import itertools
import time as _time
import warnings
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
from scipy import optimize

from iamp.core.problem import Problem
from iamp.core.plan import STATUS_OPTIMAL, Plan
from iamp.planners.solvers import SolverBackend, get_solver

HOLDS = ("foh", "zoh")


def _polish_status(backend: SolverBackend, stats) -> bool | None:
    """For OSQP, whether solution polishing succeeded (``None`` for other solvers)."""
    if backend.name != "osqp" or stats is None or stats.extra_stats is None:
        return None
    info = getattr(stats.extra_stats, "info", None)
    value = getattr(info, "status_polish", None)
    return None if value is None else int(value) == 1


@dataclass
class HoldTrajectory:
    """Exact continuous-time trajectory of a discrete solution under its input hold."""

    t_nodes: np.ndarray  # (N+1,)
    X: np.ndarray  # (N+1, 4) nodal states (s_x, v_x, s_y, v_y)
    U: np.ndarray  # (N, 2) for ZOH, (N+1, 2) for FOH
    hold: str

    def _locate(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self.t_nodes, t, side="right") - 1, 0, len(self.t_nodes) - 2)
        return t, k, t - self.t_nodes[k], np.diff(self.t_nodes)[k]

    def inputs(self, t) -> np.ndarray:
        t, k, dt, h = self._locate(t)
        if self.hold == "zoh":
            return self.U[k]
        return self.U[k] + (self.U[k + 1] - self.U[k]) * (dt / h)[:, None]

    def states(self, t) -> np.ndarray:
        t, k, dt, h = self._locate(t)
        s0 = self.X[k][:, [0, 2]]
        v0 = self.X[k][:, [1, 3]]
        d = dt[:, None]
        if self.hold == "zoh":
            u = self.U[k]
            v = v0 + u * d
            s = s0 + v0 * d + u * d**2 / 2
        else:
            u0, du = self.U[k], (self.U[k + 1] - self.U[k]) / h[:, None]
            v = v0 + u0 * d + du * d**2 / 2
            s = s0 + v0 * d + u0 * d**2 / 2 + du * d**3 / 6
        return np.stack([s[:, 0], v[:, 0], s[:, 1], v[:, 1]], axis=1)

    def cost(self) -> float:
        """``J = ½∫|u|²`` of the held input, exactly."""
        h = np.diff(self.t_nodes)[:, None]
        if self.hold == "zoh":
            return float(0.5 * np.sum(h * self.U**2))
        u0, u1 = self.U[:-1], self.U[1:]
        return float(np.sum(h / 6 * (u0**2 + u0 * u1 + u1**2)))


def aligned_grid(times, tf: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """A piecewise-uniform grid of ``steps`` intervals with nodes at every contact time.

    Returns ``(t_nodes, node_index_of_each_time)``.  Steps are allotted to the pieces in
    proportion to their lengths (largest remainder), at least one per piece.
    """
    times = np.asarray(times, dtype=float)
    order = np.argsort(times)
    bps = np.r_[0.0, times[order], tf]
    lengths = np.diff(bps)
    if np.any(lengths <= 0):
        raise ValueError("contact times must be distinct and inside (0, tf)")
    if steps < len(lengths):
        raise ValueError(f"need at least {len(lengths)} steps for {len(times)} contact times")
    raw = lengths / tf * steps
    n = np.maximum(1, np.floor(raw).astype(int))
    while n.sum() > steps:
        n[np.argmax(n - raw)] -= 1
    while n.sum() < steps:
        n[np.argmax(raw - n)] += 1
    nodes = [np.linspace(bps[j], bps[j + 1], n[j] + 1)[:-1] for j in range(len(n))] + [np.array([tf])]
    t_nodes = np.concatenate(nodes)
    idx_sorted = np.cumsum(n)[:-1]
    idx = np.empty(len(times), dtype=int)
    idx[order] = idx_sorted
    t_nodes[idx] = times  # exact
    return t_nodes, idx


class DiscretisedQP:
    """The QP of one problem, compiled once (DPP) and re-solved per candidate.

    Parameters
    ----------
    problem : Problem
    steps : int
        Number of intervals ``N``.
    hold : {"foh", "zoh"}
    solver : str or SolverBackend
        ``"osqp"`` or ``"clarabel"`` (see :data:`iamp.planners.solvers.SOLVERS`).
    """

    def __init__(self, problem: Problem, steps: int = 100, hold: str = "foh",
                 solver: str | SolverBackend = "clarabel"):
        if hold not in HOLDS:
            raise ValueError(f"unknown hold {hold!r}; choose from {', '.join(HOLDS)}")
        if int(steps) != steps or steps < problem.m + 1:
            raise ValueError(f"steps must be an integer >= {problem.m + 1} (got {steps})")
        self.problem, self.N, self.hold = problem, int(steps), hold
        self.backend = get_solver(solver) if isinstance(solver, str) else solver
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
        cons = []
        cost = 0
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
        self.cp_problem = cp.Problem(cp.Minimize(cost), cons)
        if not self.cp_problem.is_dpp():  # pragma: no cover - a modelling bug, not user input
            raise RuntimeError("the QP is not DPP")
        self.n_solves = 0
        self.set_grid(np.linspace(0.0, problem.tf, N + 1))

    # --- parameters --------------------------------------------------------------------
    def set_grid(self, t_nodes) -> None:
        t_nodes = np.asarray(t_nodes, dtype=float)
        h = np.diff(t_nodes)
        self.t_nodes = t_nodes
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

    def set_contact_nodes(self, nodes) -> None:
        """Put vehicle ``i``'s contact at grid node ``nodes[i]`` (``0 < k < N``)."""
        for i, k in enumerate(nodes):
            w = np.zeros(self.N + 1)
            w[int(k)] = 1.0
            self.select[i].value = w
            veh = self.problem.vehicles[i]
            self.corner_x[i].value = float(veh.corner_x(self.t_nodes[int(k)]))
            self.corner_y[i].value = float(veh.corner_y)

    # --- solving -----------------------------------------------------------------------
    def solve_nodes(self, nodes) -> dict:
        """Solve with the contacts at the given nodes of the current grid.

        Returns a dict with ``status``, ``cost`` (``J`` of the held input; ``inf`` unless
        optimal), ``solver_time_s`` (the solver's own time), and the solution arrays.
        """
        self.set_contact_nodes(nodes)
        b = self.backend
        try:
            with warnings.catch_warnings():  # cvxpy warns on inaccurate solutions; we report the status
                warnings.simplefilter("ignore")
                self.cp_problem.solve(solver=b.cvxpy_name, warm_start=True, **b.settings)
            status = self.cp_problem.status
        except cp.error.SolverError:
            status = "solver_error"
        self.n_solves += 1
        stats = self.cp_problem.solver_stats
        out = {"status": "optimal" if status == cp.OPTIMAL else str(status), "cost": np.inf,
               "nodes": tuple(int(k) for k in nodes), "polished": _polish_status(b, stats),
               "solver_time_s": getattr(stats, "solve_time", None) if stats is not None else None}
        if status != cp.OPTIMAL:
            return out
        X = np.stack([self.s[0].value, self.v[0].value, self.s[1].value, self.v[1].value], axis=1)
        U = np.stack([self.u[0].value, self.u[1].value], axis=1)
        nu = np.array([[float(cx.dual_value), float(cy.dual_value)] for cx, cy in self.collision])
        traj = HoldTrajectory(self.t_nodes.copy(), X, U, self.hold)
        out.update(cost=traj.cost(), trajectory=traj, multipliers=nu,
                   contact_times=self.t_nodes[np.asarray(nodes, dtype=int)].copy())
        return out

    def solve_times(self, times) -> dict:
        """Solve on a grid aligned with the (off-grid) contact times ``times``."""
        t_nodes, idx = aligned_grid(times, self.problem.tf, self.N)
        self.set_grid(t_nodes)
        return self.solve_nodes(idx)

    def candidate_nodes(self):
        """Every ordered combination of distinct interior nodes, one per vehicle."""
        return itertools.permutations(range(1, self.N), self.problem.m)


@dataclass
class QPPlanner:
    """The QP/MPC baseline planner with its own contact-time search.

    Parameters
    ----------
    steps : int
        Grid intervals ``N``.
    hold : {"foh", "zoh"}
    solver : {"osqp", "clarabel"}
    contact : {"grid", "refine"}
        ``grid``: best of the sweep over every interior node (combination); ``refine``:
        then an off-grid scalar search seeded by the sweep, on aligned grids.
    solver_settings : dict, optional
        Overrides of the backend's settings (e.g. ``{"eps_abs": 1e-3}`` for a loose OSQP).
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict | None = None
    refine_xtol: float = 1e-9

    def __post_init__(self):
        if self.contact not in ("grid", "refine"):
            raise ValueError(f"unknown contact search {self.contact!r}; choose grid or refine")
        if self.hold not in HOLDS:
            raise ValueError(f"unknown hold {self.hold!r}; choose from {', '.join(HOLDS)}")

    def build(self, problem: Problem) -> DiscretisedQP:
        backend = get_solver(self.solver, **(self.solver_settings or {}))
        return DiscretisedQP(problem, self.steps, self.hold, backend)

    def sweep(self, qp: DiscretisedQP) -> tuple[dict, list]:
        """Solve one QP per candidate node combination; return the best and all costs."""
        qp.set_grid(np.linspace(0.0, qp.problem.tf, qp.N + 1))
        best, table, failures = None, [], []
        self.unpolished = 0
        for nodes in qp.candidate_nodes():
            r = qp.solve_nodes(nodes)
            self.unpolished += r["polished"] is False
            table.append((r["nodes"], r["cost"]))
            if r["status"] != STATUS_OPTIMAL:
                failures.append((r["nodes"], r["status"]))
            elif best is None or r["cost"] < best["cost"]:
                best = r
        return best, table, failures

    def _refine(self, qp: DiscretisedQP, seed: dict) -> dict:
        tf, h = qp.problem.tf, qp.problem.tf / qp.N
        t0 = seed["contact_times"]
        lo = np.maximum(t0 - h, 1e-6 * tf)
        hi = np.minimum(t0 + h, tf * (1 - 1e-6))
        best = {"r": seed}

        def f(t):
            try:
                r = qp.solve_times(np.atleast_1d(t))
            except ValueError:
                return np.inf
            if r["status"] == STATUS_OPTIMAL and r["cost"] < best["r"]["cost"]:
                best["r"] = r
            return r["cost"] if r["status"] == STATUS_OPTIMAL else np.inf

        if qp.problem.m == 1:
            optimize.minimize_scalar(f, bounds=(lo[0], hi[0]), method="bounded",
                                     options={"xatol": self.refine_xtol * tf})
        else:
            simplex = np.vstack([t0] + [t0 + 0.5 * h * np.eye(qp.problem.m)[k] for k in range(qp.problem.m)])
            optimize.minimize(f, t0, method="Nelder-Mead",
                              options={"initial_simplex": simplex, "xatol": self.refine_xtol * tf,
                                       "fatol": 1e-14, "maxiter": 2000})
        return best["r"]

    def plan(self, problem: Problem, qp: DiscretisedQP | None = None) -> Plan:
        """Sweep (and optionally refine) the contact times, then report the best QP."""
        start = _time.perf_counter()
        qp = qp or self.build(problem)
        best, table, failures = self.sweep(qp)
        info = {"n_solves": qp.n_solves, "sweep": table, "failures": failures, "unpolished": self.unpolished}
        if best is None:
            status = failures[0][1] if failures else "no_candidate"
            return Plan(problem=problem, planner="qp", status=status, cost=None,
                              contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                              trajectory=None, solve_time_s=_time.perf_counter() - start, solver=self.solver,
                              hold=self.hold, steps=self.steps, info=info)
        info["grid_best"] = {"contact_times": best["contact_times"].tolist(), "cost": best["cost"]}
        if self.contact == "refine":
            best = self._refine(qp, best)
            info["n_solves"] = qp.n_solves
        elapsed = _time.perf_counter() - start
        res = Plan(problem=problem, planner="qp", status=STATUS_OPTIMAL, cost=best["cost"],
                         contact_times=best["contact_times"], jumps=best["multipliers"],
                         trajectory=best["trajectory"], solve_time_s=elapsed, solver=self.solver,
                         hold=self.hold, steps=self.steps, info=info)
        res.residuals = {"boundary": res.boundary_residual(), "interior_constraint": res.corner_residual()}
        return res

    def plan_at_nodes(self, problem: Problem, nodes) -> Plan:
        """Solve once with the contacts at given nodes of the uniform grid (no search)."""
        start = _time.perf_counter()
        qp = self.build(problem)
        r = qp.solve_nodes(nodes)
        return self._result(problem, r, start)

    def plan_at_times(self, problem: Problem, times) -> Plan:
        """Solve once on a grid aligned with given contact times (no search)."""
        start = _time.perf_counter()
        qp = self.build(problem)
        r = qp.solve_times(times)
        return self._result(problem, r, start)

    def _result(self, problem, r, start) -> Plan:
        ok = r["status"] == STATUS_OPTIMAL
        res = Plan(problem=problem, planner="qp", status=r["status"], cost=r["cost"] if ok else None,
                         contact_times=r.get("contact_times", np.full(problem.m, np.nan)),
                         jumps=r.get("multipliers", np.full((problem.m, 2), np.nan)),
                         trajectory=r.get("trajectory"), solve_time_s=_time.perf_counter() - start,
                         solver=self.solver, hold=self.hold, steps=self.steps,
                         info={"solver_time_s": r["solver_time_s"], "polished": r["polished"]})
        if ok:
            res.residuals = {"boundary": res.boundary_residual(), "interior_constraint": res.corner_residual()}
        return res
