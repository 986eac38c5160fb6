r"""The avoidance QP (SPEC §10): true collision avoidance with linear inequalities.

For each vehicle ``i`` the ego must stay out of its safety region, convexified around the
named corner: the corner names two half-planes :math:`H_x, H_y`
(:class:`~iamp.planners.avoid.data.HalfPlane`); the ego starts in one and ends in the other,
and at a crossing time :math:`\tau_i` leaves the first:

.. math::  t \le \tau_i \Rightarrow s(t) \in H_{\text{first}}, \qquad
           t \ge \tau_i \Rightarrow s(t) \in H_{\text{second}} .

For fixed :math:`\tau` this is the convex QP of SPEC §3 (same holds, same steps, same cost
:math:`J = \tfrac12\int|u|^2`) with linear inequalities at every interior grid node
(:class:`~iamp.planners.avoid.data.AvoidData`), solved through the QP backend registry
(:func:`iamp.planners.qp.backends.get_backend`, OSQP or Clarabel, general form
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
  (not certified global).  The free optimum's certificate, the exact pruning of one
  vehicle's sweep and the off-grid refinement are :mod:`iamp.planners.avoid.search`.
* ``refine``: then, per vehicle, a bounded scalar search of :math:`\tau_i` within one step of
  the grid's crossing interval, on grids aligned with :math:`\tau_i`
  (:func:`~iamp.planners.avoid.search.refine_crossings`).

The reported crossing time is the last instant the plan's continuous trajectory is in the
first half-plane (a root, to 1e-12 s).  Where the inequalities do not bind around the
crossing, every switch in a range of nodes gives the same optimum (the QP's optimum is
unique, its crossing-time *constraint* is not): the plan reports that range
(``optimal_switch_range``) and the crossing of the trajectory itself, which is the same for
all of them.

Verification
------------
A plan is ``optimal`` only after the KKT conditions of its final QP, recomputed from the data,
pass the tolerance table and, for ``m > 1``, the sweep was complete; the plan reports the
crossing of every vehicle, the active set, the multipliers and the largest intrusion between
nodes (:mod:`iamp.planners.avoid.result`, which also has the text summary
:func:`~iamp.planners.avoid.result.summary_lines`).

Where the ego's start or end state lies inside a safety region no safe plan exists: the plan
is ``infeasible`` with the reason.  Where it lies outside the region but in neither of the
corner's half-planes, :class:`~iamp.core.errors.ScenarioError` names the vehicle.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.qp.planner import HOLDS, aligned_grid

from ..qp.options import CONTACTS, check_choice
from .check import Candidate, FloatArray, crossing_orders
from .continuous import ContinuousAvoidPlanner, GridShare
from .data import AvoidData
from .options import SAFETY_MODES, AvoidOptions, check_avoid_solver, refuse_wall_clock_budget
from .result import failed_plan, verified_plan
from .search import Phase, certify_free, pruned_switches, refine_crossings, seed_switches
from .solve import BoundSolver

Progress = Callable[[int, int], None]

@dataclass
class AvoidQPPlanner:
    """The avoidance QP planner (module docstring).

    Parameters
    ----------
    steps : int
        Grid intervals ``N``.
    hold : {"foh", "zoh"}
    solver : {"osqp", "clarabel", "piqp"}
    contact : {"grid", "refine"}
        Crossing-time search.
    solver_settings : dict, optional
        Overrides of the backend's settings.
    max_combinations : int
        Largest full sweep for ``m > 1`` vehicles.
    coarse : int
        Switches per vehicle of the coarse sweep beyond ``max_combinations``.
    safety : {"continuous", "nodes"}
        ``"continuous"`` (default, SPEC §14): both half-planes at the crossing time itself and
        every piece certified by its Bernstein coefficients, the crossing times found by
        branch and bound (:class:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner`);
        ``"nodes"``: the inequalities at the grid nodes only (SPEC §10 as first written,
        kept for study: it cuts corners between nodes, and a plan that intrudes is reported
        ``unsafe``).
    prune : bool
        One vehicle: skip the switches that monotone relaxations prove no better than the
        best found (exact; see :func:`~iamp.planners.avoid.search.pruned_switches`).
        ``False`` solves every switch.
    max_solves : int
        QPs the continuous-time branch and bound may solve before it stops with ``local`` (a count
        of work, SPEC §17).
    max_boxes : int
        Crossing-time boxes the branch and bound may create before it stops with ``local`` (a
        count of work, SPEC §17).
    time_limit_s : None
        Removed wall-clock budget: any value is refused (:func:`~.options.refuse_wall_clock_budget`).
    limits_between : {"certified", "nodes"}
        The car's limits between the grid nodes, continuous-time safety only
        (:class:`~iamp.planners.avoid.options.AvoidOptions`).
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None
    max_combinations: int = 5000
    coarse: int = 24
    prune: bool = True
    safety: str = "continuous"
    max_solves: int = 2000
    max_boxes: int = 20000
    time_limit_s: None = None
    limits_between: str = "certified"
    #: the continuous-time plans' per-grid factorisations, kept across this planner's plans
    #: (:class:`~iamp.planners.avoid.continuous.GridShare`: the same plans, each grid factored once)
    _shared: GridShare = field(default_factory=GridShare, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        refuse_wall_clock_budget(self.time_limit_s)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_choice(self.contact, CONTACTS, "contact", "contact search")
        check_avoid_solver(self.solver)
        check_choice(self.safety, SAFETY_MODES, "safety", "safety mode")

    def forget_vehicles(self) -> int:
        """Forget the half-planes' rows kept from earlier plans (they depend on the vehicles'
        motion, so a closed loop's next plan, whose predictions moved, cannot reuse them; the
        per-grid factorisations stay), and each grid's sub-piece values at the box ends and
        crossing times of earlier plans (``_GridLayout.split_vals``: a new problem's crossing times
        are others): what ``iamp bench`` does before each timed plan, so that it times a new
        problem on the loop's grid, not a repeat.  The number of half-plane entries dropped."""
        for layout in self._shared.values("layout"):
            layout.split_vals.clear()
        return self._shared.forget("rhs")

    def _continuous(self) -> ContinuousAvoidPlanner:
        return ContinuousAvoidPlanner(steps=self.steps, hold=self.hold, solver=self.solver,
                                      solver_settings=self.solver_settings, max_solves=self.max_solves,
                                      max_boxes=self.max_boxes, limits_between=self.limits_between,
                                      shared=self._shared)

    # --- solving one grid ------------------------------------------------------------------
    def _backend(self, data: AvoidData, on: np.ndarray) -> BoundSolver:
        _, u = data.bounds(on)
        return BoundSolver(self.solver, data.P, data.A, data.b_eq, u[data.n_eq:], self.solver_settings)

    def _solve(self, data: AvoidData, backend: BoundSolver, phases: Sequence[Phase],
               warm: Candidate | None = None) -> Candidate:
        """Solve candidate ``phases`` (one per vehicle; none: every inequality relaxed) on the
        set-up ``backend``, a bound update; cost :math:`J = \\tfrac12 z^\\top P z`."""
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
    @classmethod
    def from_options(cls, options: AvoidOptions) -> AvoidQPPlanner:
        """The planner of the registry's validated options (:class:`~iamp.planners.avoid.options.AvoidOptions`)."""
        return cls(steps=options.steps, hold=options.hold, solver=options.solver, contact=options.contact,
                   solver_settings=options.solver_settings, safety=options.safety, max_solves=options.max_solves,
                   max_boxes=options.max_boxes, limits_between=options.limits_between)

    def plan(self, problem: Problem, progress: Progress | None = None) -> Plan:
        """Search the crossing times, solve, verify; an infeasible start/end gives an
        ``infeasible`` plan with the reason (see the module docstring)."""
        if self.safety == "continuous":
            return self._continuous().plan(problem)
        start = time.perf_counter()
        N, m = int(self.steps), problem.m
        if m == 0:
            raise ScenarioError("the QP planners need at least one vehicle (a problem with zero vehicles has no "
                                "contact time: its optimum is iamp.core.free.free_plan, or planner 'pmp')", "vehicles")
        if N < 2:
            raise ScenarioError(f"must be at least 2 (got {N})", "--steps")
        orders, reason = crossing_orders(problem)
        if reason is not None:
            return self._failed(problem, st.INFEASIBLE, reason, start)
        data = AvoidData(problem, np.linspace(0.0, problem.tf, N + 1), self.hold, with_limits=True)
        per_vehicle = [[(f, s, j, j + 1) for (f, s) in orders[i] for j in range(N)] for i in range(m)]
        total = int(np.prod([len(c) for c in per_vehicle]))
        complete = total <= self.max_combinations
        backend = self._backend(data, np.zeros(data.n_rows - data.n_eq, dtype=bool))
        table: list[tuple[Any, float]] = []
        n_solves = 0  # every QP solved: candidates, free solves, relaxations (pruning), refinement
        best: Candidate | None = None
        failures: list[tuple[Any, str]] = []

        def solve(phases: Sequence[Phase], warm: Candidate | None = None) -> Candidate:
            nonlocal n_solves
            n_solves += 1
            return self._solve(data, backend, phases, warm)

        def solve_times(prob: Problem, taus: FloatArray,
                        orders: Sequence[tuple[int, int]]) -> tuple[AvoidData, Candidate] | None:
            nonlocal n_solves
            out = self._solve_times(prob, taus, orders)
            if out is not None:  # one QP, unless the times could not be aligned (none)
                n_solves += 1
            return out

        def run(combos: Sequence[tuple[Phase, ...]]) -> None:
            nonlocal best
            for n_done, phases in enumerate(combos, 1):
                r = solve(phases, best)
                table.append(([p[2] for p in phases], r.cost))
                if r.status != st.OPTIMAL:
                    failures.append(([p[2] for p in phases], r.status))
                elif best is None or r.cost < best.cost:
                    best = r
                if progress is not None:
                    progress(n_done, len(combos))

        certified = certify_free(data, solve, orders)
        if certified is not None:
            best = certified[0]
            table.append(([p[2] for p in best.phases], best.cost))
            complete = True
        elif complete and m == 1 and self.prune:
            for first, second in orders[0]:
                seeds = seed_switches(data, solve, first)
                run([((first, second, j, j + 1),) for j in seeds])
                bound = best.cost if best is not None else np.inf
                run([((first, second, j, j + 1),) for j in pruned_switches(data, solve, first, second, seeds, bound)])
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
        info: dict[str, Any] = {"constraint": "avoid", "n_solves": n_solves, "sweep": table,
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
        if self.contact == "refine":
            final_data, final, _ = refine_crossings(problem, grid_best, self.steps, solve_times)
            info["n_solves"] = n_solves
        return self._result(problem, final_data, final, complete, info, start)

    def _solve_times(self, problem: Problem, taus: FloatArray,
                     orders: Sequence[tuple[int, int]]) -> tuple[AvoidData, Candidate] | None:
        """One QP on the grid aligned with ``taus`` (the node at ``τ_i`` in both half-planes)."""
        try:
            t_nodes, idx = aligned_grid(np.asarray(taus, dtype=float), problem.tf, int(self.steps))
        except ValueError:
            return None
        data = AvoidData(problem, t_nodes, self.hold, with_limits=True)
        phases = [(f, s, int(k), int(k)) for (f, s), k in zip(orders, idx)]
        return data, self._solve(data, self._backend(data, data.imposed(phases)), phases)

    def plan_at_times(self, problem: Problem, taus: Sequence[float]) -> Plan:
        """Solve once with the crossing times ``taus`` (no search; each vehicle's first
        half-plane order), on the grid aligned with them (``nodes``) or on the uniform grid
        with both half-planes at ``τ`` (``continuous``)."""
        if self.safety == "continuous":
            return self._continuous().plan_at_times(problem, taus)
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
        return self._result(problem, data, cand, True, info, start)

    # --- results ---------------------------------------------------------------------------
    def _failed(self, problem: Problem, status: str, reason: str, start: float,
                info: dict[str, Any] | None = None) -> Plan:
        return failed_plan(problem, status, reason, start, solver=self.solver, hold=self.hold, steps=self.steps,
                           info=info)

    def _result(self, problem: Problem, data: AvoidData, cand: Candidate, complete: bool, info: dict[str, Any],
                start: float) -> Plan:
        return verified_plan(problem, data, cand, complete, info, start, solver=self.solver, hold=self.hold,
                             steps=self.steps, contact=self.contact)


def plan_with(options: AvoidOptions, problem: Problem, /, progress: Progress | None = None) -> Plan:
    """``AvoidQPPlanner.from_options(options).plan(problem, progress=progress)``: the registry's one
    call (:func:`iamp.planners.registry.prepare`) that builds the planner and plans."""
    return AvoidQPPlanner.from_options(options).plan(problem, progress=progress)
