r"""The avoidance QP (SPEC §10): true collision avoidance with linear inequalities.

For each vehicle ``i`` the ego must stay out of its safety region, convexified around the
named corner: the corner names two half-planes :math:`H_x, H_y`
(:class:`~iamp.planners.avoid_data.HalfPlane`); the ego starts in one and ends in the other,
and at a crossing time :math:`\tau_i` leaves the first:

.. math::  t \le \tau_i \Rightarrow s(t) \in H_{\text{first}}, \qquad
           t \ge \tau_i \Rightarrow s(t) \in H_{\text{second}} .

For fixed :math:`\tau` this is the convex QP of SPEC §3 (same holds, same steps, same cost
:math:`J = \tfrac12\int|u|^2`) with linear inequalities at every interior grid node
(:class:`~iamp.planners.avoid_data.AvoidData`), solved through the QP backend registry
(:func:`iamp.planners.backends.get_backend`, OSQP or Clarabel, general form
:math:`l \le Az \le u`).

Crossing-time search
--------------------
* ``grid`` (global over the grid): a crossing between nodes ``j`` and ``j + 1`` imposes the
  first half-plane at nodes ``k <= j`` and the second at ``k >= j + 1``; every
  ``j = 0..N-1`` (and both orders when the start and end allow both) is one candidate, a
  bound update of one set-up solver.  A crossing *on* a node imposes both half-planes there
  and is never cheaper than the crossings beside it, so the sweep is the global minimum over
  every crossing time the grid can express.  With ``m > 1`` vehicles every combination is
  swept while there are at most ``max_combinations`` (e.g. ``N = 50`` for two vehicles);
  beyond that a coarse sweep (``coarse`` switches per vehicle, every combination) is
  followed by coordinate descent over the full grid, and the plan is reported ``local``
  (not certified global).
* ``refine``: then, per vehicle, a bounded scalar search of :math:`\tau_i` within one step of
  the grid's crossing interval, on grids aligned with :math:`\tau_i` (the node at
  :math:`\tau_i` lies in both half-planes, as the continuous constraint requires).

The reported crossing time is the last instant the plan's continuous trajectory is in the
first half-plane (a root, to 1e-12 s).  Where the inequalities do not bind around the
crossing, every switch in a range of nodes gives the same optimum (the QP's optimum is
unique, its crossing-time *constraint* is not): the plan reports that range
(``optimal_switch_range``) and the crossing of the trajectory itself, which is the same for
all of them.

Verification
------------
A plan is ``optimal`` only after the KKT conditions of its final QP, recomputed from the data
(:func:`kkt_conditions`: stationarity, primal feasibility, dual sign, complementarity), pass
``cmp_kkt_rel_<solver>`` of the tolerance table and, for ``m > 1``, the sweep was complete.
The plan reports (``info["avoidance"]``, the ``"avoidance"`` key of its JSON) the crossing
of every vehicle, the active set (the nodes where each inequality binds), their multipliers,
and the largest intrusion *between* nodes — the constraint holds at the nodes only; the
intrusion between them (measured exactly by :mod:`iamp.core.safety`) falls as ``N`` grows.

Where the ego's start or end state lies inside a safety region no safe plan exists: the plan
is ``infeasible`` with the reason.  Where it lies outside the region but in neither of the
corner's half-planes, :class:`~iamp.core.errors.ScenarioError` names the vehicle.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.avoid_check import (
    AXIS_NAMES,
    Candidate,
    FloatArray,
    crossing_orders,
    kkt_conditions,
    leave_time,
)
from iamp.planners.avoid_data import AvoidData
from iamp.planners.avoid_solve import BoundSolver
from iamp.planners.qp import HOLDS, HoldTrajectory, aligned_grid

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class QPSolutionData:
    """The final QP of a plan and its primal/dual solution (for independent checks)."""

    data: AvoidData
    l: FloatArray
    u: FloatArray
    z: FloatArray
    y: FloatArray
    imposed: np.ndarray

#: A row binds when its slack is at most this [m].
ACTIVE_SLACK_M = 1e-6


@dataclass
class AvoidQPPlanner:
    """The avoidance QP planner (module docstring).

    Parameters
    ----------
    steps : int
        Grid intervals ``N``.
    hold : {"foh", "zoh"}
    solver : {"osqp", "clarabel"}
    contact : {"grid", "refine"}
        Crossing-time search.
    solver_settings : dict, optional
        Overrides of the backend's settings.
    max_combinations : int
        Largest full sweep for ``m > 1`` vehicles.
    coarse : int
        Switches per vehicle of the coarse sweep beyond ``max_combinations``.
    prune : bool
        One vehicle: skip the switches that monotone relaxations prove no better than the
        best found (exact; see :meth:`_pruned_sweep`).  ``False`` solves every switch.
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None
    max_combinations: int = 5000
    coarse: int = 24
    prune: bool = True

    def __post_init__(self) -> None:
        if self.hold not in HOLDS:
            raise ValueError(f"unknown hold {self.hold!r}; choose from {', '.join(HOLDS)}")
        if self.contact not in ("grid", "refine"):
            raise ValueError(f"unknown contact search {self.contact!r}; choose grid or refine")
        if self.solver not in ("osqp", "clarabel"):
            raise ValueError(f"unknown solver {self.solver!r}; choose osqp or clarabel")

    # --- solving one grid ------------------------------------------------------------------
    def _backend(self, data: AvoidData, on: np.ndarray) -> BoundSolver:
        _, u = data.bounds(on)
        return BoundSolver(self.solver, data.P, data.A, data.b_eq, u[data.n_eq:], self.solver_settings)

    def _solve(self, data: AvoidData, backend: BoundSolver, phases: Sequence[tuple[int, int, int, int]],
               warm: Candidate | None = None) -> Candidate:
        on = data.imposed(phases)
        _, u = data.bounds(on)
        backend.set_upper(u[data.n_eq:])
        if warm is not None:
            backend.warm_start(warm.z, warm.y)
        sol = backend.solve()
        ok = sol.status == st.OPTIMAL and sol.finite
        # J = ½ zᵀ P z with P stored as its upper triangle
        cost = float(sol.z @ (data.P @ sol.z) - 0.5 * sol.z @ (data.P.diagonal() * sol.z)) if ok else np.inf
        return Candidate(tuple(phases), sol.status if ok or sol.status != st.OPTIMAL else st.NUMERICAL_ERROR,
                         cost, sol.z, sol.y, on, sol)

    # --- the plan ----------------------------------------------------------------------------
    def plan(self, problem: Problem, progress: Progress | None = None) -> Plan:
        """Search the crossing times, solve, verify; an infeasible start/end gives an
        ``infeasible`` plan with the reason (see the module docstring)."""
        start = time.perf_counter()
        N, m = int(self.steps), problem.m
        if N < 2:
            raise ScenarioError(f"must be at least 2 (got {N})", "--steps")
        orders, reason = crossing_orders(problem)
        if reason is not None:
            return self._failed(problem, st.INFEASIBLE, reason, start)
        data = AvoidData(problem, np.linspace(0.0, problem.tf, N + 1), self.hold)
        per_vehicle = [[(f, s, j, j + 1) for (f, s) in orders[i] for j in range(N)] for i in range(m)]
        total = int(np.prod([len(c) for c in per_vehicle]))
        complete = total <= self.max_combinations
        backend = self._backend(data, np.zeros(data.n_rows - data.n_eq, dtype=bool))
        table: list[tuple[Any, float]] = []
        self._extra_solves = 0  # free solves and relaxations (pruning), beside the candidates
        best: Candidate | None = None
        failures: list[tuple[Any, str]] = []

        def run(combos: Sequence[tuple[tuple[int, int, int, int], ...]]) -> None:
            nonlocal best
            for n_done, phases in enumerate(combos, 1):
                r = self._solve(data, backend, phases, best)
                table.append(([p[2] for p in phases], r.cost))
                if r.status != st.OPTIMAL:
                    failures.append(([p[2] for p in phases], r.status))
                elif best is None or r.cost < best.cost:
                    best = r
                if progress is not None:
                    progress(n_done, len(combos))

        certified = self._certify_free(data, backend, orders)
        if certified is not None:
            best = certified[0]
            table.append(([p[2] for p in best.phases], best.cost))
            complete = True
        elif complete and m == 1 and self.prune:
            for first, second in orders[0]:
                seeds = self._seeds(data, backend, first)
                run([((first, second, j, j + 1),) for j in seeds])
                bound = best.cost if best is not None else np.inf
                run([((first, second, j, j + 1),) for j in self._pruned(data, backend, first, second, seeds, bound)])
        elif complete:
            run(list(itertools.product(*per_vehicle)))
        else:
            step = [max(1, len(c) // self.coarse) for c in per_vehicle]
            run(list(itertools.product(*[c[::s] for c, s in zip(per_vehicle, step)])))
            for _ in range(6):  # coordinate descent over the full grid
                before = best.cost if best is not None else np.inf
                for i in range(m):
                    if best is None:
                        break
                    fixed = list(best.phases)
                    run([tuple(fixed[:i] + [p] + fixed[i + 1:]) for p in per_vehicle[i]])
                if best is None or best.cost >= before - 1e-12 * max(1.0, abs(before)):
                    break
        info: dict[str, Any] = {"constraint": "avoid", "n_solves": len(table) + self._extra_solves, "sweep": table,
                                "failures": failures,
                                "pruned": complete and m == 1 and self.prune and certified is None,
                                "complete_sweep": complete,
                                "certificate": None if certified is None else
                                "the unconstrained optimum keeps every inequality at the nodes: a lower bound "
                                "attained, so it is the global optimum over every crossing time",
                                "candidates": {"total": total, "solved": len(table) - len(failures)}}
        if best is None:
            status = failures[0][1] if failures else st.SOLVER_ERROR
            return self._failed(problem, status, "no crossing-time candidate solved", start, info)
        grid_best: Candidate = best
        info["grid_best"] = {"switch_nodes": [p[2] for p in grid_best.phases], "cost": grid_best.cost}
        if certified is not None:  # every switch in these ranges gives the same (free) optimum
            info["grid_best"]["optimal_switch_range"] = certified[1][0] if m == 1 else certified[1]
        elif m == 1:  # every switch node whose optimum ties the best (the crossing constraint is not unique)
            near = [int(k[0]) for k, c in table if c <= grid_best.cost + 1e-9 * max(1.0, grid_best.cost)]
            info["grid_best"]["optimal_switch_range"] = [min(near), max(near)]
        final_data, final = data, grid_best
        taus: FloatArray | None = None
        if self.contact == "refine":
            final_data, final, taus = self._refine(problem, grid_best)
            info["n_solves"] += int(info.pop("refine_solves", 0))
        return self._result(problem, final_data, final, taus, complete, info, start)

    def _seeds(self, data: AvoidData, backend: BoundSolver, first: int) -> list[int]:
        """The switches around the free optimum's own crossing (solved first when pruning)."""
        N = data.N
        free = self._solve(data, backend, [])
        self._extra_solves += 1
        if free.status != st.OPTIMAL:
            return [N // 2]
        X, _ = data.unpack(free.z)
        k = data.interior
        in_first = data.planes[0][first].margin(data.t_nodes[k], X[k, 2 * first]) >= 0
        out = np.flatnonzero(~in_first)
        j0 = int(k[out[0]]) - 1 if out.size else N - 1
        return sorted({min(max(j, 0), N - 1) for j in (j0 - 1, j0, j0 + 1)})

    def _pruned(self, data: AvoidData, backend: BoundSolver, first: int, second: int, seeds: list[int],
                bound: float) -> list[int]:
        r"""One vehicle, one order: the switches ``j`` still to solve after pruning, exactly.

        Candidate ``j`` imposes the first half-plane at nodes ``k <= j`` and the second at
        ``k >= j + 1``; dropping either set gives the relaxations ``R_pre(j)`` (first only,
        nondecreasing in ``j``) and ``R_suf(j)`` (second only, nonincreasing), both lower bounds
        of its cost.  With ``B`` = ``bound`` the best cost found so far (the ``seeds`` around
        the free optimum's crossing are solved first), bisection finds the smallest ``j_hi``
        with ``R_pre(j_hi) > B`` and the largest ``j_lo`` with ``R_suf(j_lo) > B``: every
        ``j >= j_hi`` or ``<= j_lo`` costs more than ``B``, so only ``j_lo < j < j_hi`` remain
        and the search stays global over the grid.
        """
        N = data.N
        if not np.isfinite(bound):
            return [j for j in range(N) if j not in seeds]
        limit = bound * (1 + 1e-9) + 1e-12

        def relax(phases: tuple[int, int, int, int]) -> float:
            r = self._solve(data, backend, [phases])
            self._extra_solves += 1
            return r.cost if r.status == st.OPTIMAL else np.inf

        hi_j, a, b = N, max(seeds), N - 1  # smallest j >= max(seeds) with R_pre(j) > B (N: none)
        while a <= b:
            mid = (a + b) // 2
            if relax((first, second, mid, N)) > limit:
                hi_j, b = mid, mid - 1
            else:
                a = mid + 1
        lo_cut, a, b = -1, 0, min(seeds)  # largest j <= min(seeds) with R_suf(j) > B (-1: none)
        while a <= b:
            mid = (a + b) // 2
            if relax((first, second, 0, mid + 1)) > limit:
                lo_cut, a = mid, mid + 1
            else:
                b = mid - 1
        return [j for j in range(lo_cut + 1, hi_j) if j not in seeds]

    def _certify_free(self, data: AvoidData, backend: BoundSolver, orders: Sequence[Sequence[tuple[int, int]]]
                      ) -> tuple[Candidate, list[list[int]]] | None:
        """Solve with every inequality relaxed; if that optimum (a lower bound of every
        candidate) keeps some candidate's inequalities at the nodes, it is the global optimum.
        Returns it with the chosen switches and, per vehicle, the range of valid switch nodes."""
        free = self._solve(data, backend, [])
        if free.status != st.OPTIMAL:
            return None
        X, _ = data.unpack(free.z)
        k = data.interior
        phases, ranges = [], []
        for pair, vehicle_orders in zip(data.planes, orders):
            ok = [pair[a].margin(data.t_nodes[k], X[k, 2 * a]) >= -1e-9 for a in (0, 1)]
            found = None
            for f, s2 in vehicle_orders:
                bad_f, bad_s = k[~ok[f]], k[~ok[s2]]
                j_max = int(bad_f[0]) - 1 if bad_f.size else data.N - 1
                j_min = int(bad_s[-1]) if bad_s.size else 0
                if j_min <= j_max:
                    found = ((f, s2, j_min, j_min + 1), [j_min, j_max])
                    break
            if found is None:
                return None
            phases.append(found[0])
            ranges.append(found[1])
        on = data.imposed(phases)
        return Candidate(tuple(phases), free.status, free.cost, free.z, free.y, on, free.sol), ranges

    def _refine(self, problem: Problem, seed: Candidate) -> tuple[AvoidData, Candidate, FloatArray]:
        """Per vehicle, a bounded scalar search of ``τ_i`` on grids aligned with ``τ``."""
        N, tf = int(self.steps), problem.tf
        h = tf / N
        taus = np.array([(p[2] + 0.5) * h for p in seed.phases])
        cache: dict[tuple[float, ...], tuple[AvoidData, Candidate]] = {}

        orders = [(p[0], p[1]) for p in seed.phases]

        def solve_at(t: FloatArray) -> tuple[AvoidData, Candidate] | None:
            key = tuple(float(x) for x in t)
            if key not in cache:
                out = self._solve_times(problem, t, orders)
                if out is None:
                    return None
                cache[key] = out
            return cache[key]

        for _ in range(2 if problem.m > 1 else 1):
            for i in range(problem.m):
                lo = max(seed.phases[i][2] * h - h, 1e-6 * tf)
                hi = min((seed.phases[i][2] + 1) * h + h, tf * (1 - 1e-6))

                def f(x: float, i: int = i) -> float:
                    t = taus.copy()
                    t[i] = x
                    out = solve_at(t)
                    return out[1].cost if out is not None and out[1].status == st.OPTIMAL else np.inf

                res = optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7 * tf})
                if np.isfinite(res.fun) and res.fun <= f(float(taus[i])):
                    taus[i] = float(res.x)
        out = solve_at(taus)
        if out is None:  # pragma: no cover - the seed's own times are always valid
            raise RuntimeError("refine lost its seed")
        return out[0], out[1], taus

    def _solve_times(self, problem: Problem, taus: FloatArray,
                     orders: Sequence[tuple[int, int]]) -> tuple[AvoidData, Candidate] | None:
        """One QP on the grid aligned with ``taus`` (the node at ``τ_i`` in both half-planes)."""
        try:
            t_nodes, idx = aligned_grid(np.asarray(taus, dtype=float), problem.tf, int(self.steps))
        except ValueError:
            return None
        data = AvoidData(problem, t_nodes, self.hold)
        phases = [(f, s, int(k), int(k)) for (f, s), k in zip(orders, idx)]
        return data, self._solve(data, self._backend(data, data.imposed(phases)), phases)

    def plan_at_times(self, problem: Problem, taus: Sequence[float]) -> Plan:
        """Solve once with the crossing times ``taus`` (no search; each vehicle's first
        half-plane order), on the grid aligned with them."""
        start = time.perf_counter()
        orders, reason = crossing_orders(problem)
        if reason is not None:
            return self._failed(problem, st.INFEASIBLE, reason, start)
        out = self._solve_times(problem, np.asarray(taus, dtype=float), [o[0] for o in orders])
        if out is None:
            raise ValueError("crossing times must be distinct and inside (0, tf)")
        data, cand = out
        info: dict[str, Any] = {"constraint": "avoid", "n_solves": 1, "sweep": [], "failures": [],
                                "grid_best": {"switch_nodes": [p[2] for p in cand.phases], "cost": cand.cost}}
        if cand.status != st.OPTIMAL:
            return self._failed(problem, cand.status, "the QP did not solve", start, info)
        return self._result(problem, data, cand, np.asarray(taus, dtype=float), True, info, start)

    # --- results ---------------------------------------------------------------------------
    def _failed(self, problem: Problem, status: str, reason: str, start: float,
                info: dict[str, Any] | None = None) -> Plan:
        info = {**(info or {}), "constraint": "avoid", "reason": reason}
        return Plan(problem=problem, planner="qp", status=status, cost=None,
                    contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                    trajectory=None, solve_time_s=time.perf_counter() - start, solver=self.solver, hold=self.hold,
                    steps=self.steps, info=info)

    def _result(self, problem: Problem, data: AvoidData, cand: Candidate, taus: FloatArray | None,
                complete: bool, info: dict[str, Any], start: float) -> Plan:
        X, U = data.unpack(cand.z)
        traj = HoldTrajectory(data.t_nodes.copy(), X, U, self.hold)
        cost = traj.cost()
        elapsed = time.perf_counter() - start
        l, u = data.bounds(cand.on)
        kkt = kkt_conditions(data.P, data.q, data.A, l, u, cand.z, cand.y, n_eq=data.n_eq)
        limit = tol(f"cmp_kkt_rel_{self.solver}")
        failed = [k for k, v in kkt.items() if v > limit]
        ineq_y = cand.y[data.n_eq:]
        slack = u[data.n_eq:] - (data.A @ cand.z)[data.n_eq:]
        relaxed_binding = bool(np.any((~cand.on) & (slack <= ACTIVE_SLACK_M)))
        if relaxed_binding:
            failed.append("relaxed_row_binding")
        vehicles, jumps, crossing = [], np.zeros((problem.m, 2)), np.zeros(problem.m)
        for i, (v, phases) in enumerate(zip(problem.vehicles, cand.phases)):
            first, second, last_first, first_second = phases
            planes = data.planes[i]
            rows_i = {a: data.row(i, a, data.interior) - data.n_eq for a in (0, 1)}
            entry: dict[str, Any] = {"name": v.name, "first": AXIS_NAMES[first], "second": AXIS_NAMES[second],
                                     "first_half_plane": planes[first].describe(),
                                     "second_half_plane": planes[second].describe()}
            for a in (0, 1):
                r = rows_i[a]
                act = cand.on[r] & (slack[r] <= ACTIVE_SLACK_M)
                nodes = data.interior[act]
                entry[f"active_{AXIS_NAMES[a]}"] = {
                    "nodes": [int(k) for k in nodes], "t": [float(data.t_nodes[k]) for k in nodes],
                    "multipliers": [float(y) for y in ineq_y[r][act]]}
                # the equivalent of ν_i (L = J + ν_i·(s − ...)): Σ_k σ y_k on the axis
                jumps[i, a] = float(planes[a].sigma * np.sum(ineq_y[r][cand.on[r]]))
            crossing[i] = leave_time(traj, planes[first], problem.tf)
            entry["crossing_time"] = float(crossing[i])
            entry["imposed_switch"] = [float(data.t_nodes[last_first]), float(data.t_nodes[first_second])]
            vehicles.append(entry)
        if failed:
            status = st.INACCURATE
        else:
            status = st.OPTIMAL if complete else st.LOCAL
        plan = Plan(problem=problem, planner="qp", status=status, cost=cost if status in st.SUCCESS else None,
                    contact_times=crossing, jumps=jumps, trajectory=traj, solve_time_s=elapsed, solver=self.solver,
                    hold=self.hold, steps=self.steps, info=info)
        safety = plan.safety
        for entry, vs in zip(vehicles, safety.vehicles if safety is not None else ()):
            entry["between_node_intrusion_m"] = vs.max_intrusion_m
        plan.residuals = {"boundary": plan.boundary_residual(), **kkt}
        info.update(kkt=kkt, kkt_tol=limit, failed_checks=failed,
                    solver_status=cand.status, solver_iterations=int(cand.sol.iterations),
                    qp_solution=QPSolutionData(data, l, u, cand.z, cand.y, cand.on))
        info["avoidance"] = {"constraint": "avoid", "contact": self.contact, "complete_sweep": complete,
                             "n_solves": info["n_solves"], "vehicles": vehicles,
                             "kkt": kkt, "kkt_tol": limit, "failed_checks": failed,
                             "grid_best": info["grid_best"]}
        if failed:
            info["failed_check"] = failed[0]
        return plan


def summary_lines(plan: Plan) -> list[str]:
    """The text summary of an avoidance plan (the CLI prints it)."""
    info = plan.info
    av = info.get("avoidance", {})
    out = [f"cost J    {plan.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]",
           f"time      {plan.solve_time_s * 1e3:.3f} ms ({info.get('n_solves')} QPs; "
           f"{'every' if av.get('complete_sweep') else 'coarse + descent over'} crossing candidate)"]
    for v in av.get("vehicles", []):
        out.append(f"vehicle {v['name']}: in {v['first']} until it crosses at t = {v['crossing_time']:.6f} s, then "
                   f"in {v['second']}")
        for key in ("active_H_x", "active_H_y"):
            act = v[key]
            if act["nodes"]:
                ts = act["t"]
                out.append(f"    {key[7:]} binds at {len(ts)} node(s) t = {ts[0]:.3f}..{ts[-1]:.3f} s, "
                           f"multipliers sum {sum(act['multipliers']):.6g}")
            else:
                out.append(f"    {key[7:]} binds at no node")
        out.append(f"    largest intrusion between nodes {v['between_node_intrusion_m']:.3g} m")
    rng = av.get("grid_best", {}).get("optimal_switch_range")
    if rng is not None:
        ranges = [rng] if not isinstance(rng[0], list) else rng
        if any(r[0] != r[1] for r in ranges):
            text = "; ".join(f"{v['name']} {r[0]}..{r[1]}" for v, r in zip(av.get("vehicles", []), ranges))
            out.append(f"note      the crossing constraint is not unique: every switch node in {text} gives the "
                       "same optimum (no inequality binds there)")
    kkt = av.get("kkt", {})
    if kkt:
        out.append("residuals " + ", ".join(f"{k} {val:.1e}" for k, val in kkt.items())
                   + f" (tol {av.get('kkt_tol', 0):.0e})")
    if plan.safety is not None:
        out += plan.safety.lines()
    return out
