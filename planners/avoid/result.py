r"""The plan of the avoidance QP (SPEC §10): verified from its final QP, and its text summary.

A plan is ``optimal`` only after the KKT conditions of its final QP
:math:`\min \tfrac12 z^\top P z + q^\top z` s.t. :math:`l \le Az \le u`, recomputed from the data
(:func:`~iamp.planners.avoid.check.kkt_conditions`: stationarity, primal feasibility, dual
sign, complementarity), pass ``cmp_kkt_rel_<solver>`` of the tolerance table, no relaxed row
binds (slack :math:`u_k - a_k^\top z \le` :data:`ACTIVE_SLACK_M`) and, for ``m > 1``, the sweep
was complete (else ``local``).

The plan reports (``info["avoidance"]``, the ``"avoidance"`` key of its JSON) the crossing of
every vehicle, the active set (the nodes where each inequality binds), their multipliers
:math:`y_k \ge 0`, the equivalent of the equality's multiplier per axis,
:math:`\nu_{i,a} = \sigma_a \sum_k y_k` over the imposed rows, and the largest intrusion
*between* nodes — the constraint holds at the nodes only; the intrusion between them
(measured exactly by :mod:`iamp.core.safety`) falls as ``N`` grows.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.core import status as st
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.qp.planner import HoldTrajectory

from ..qp.backends import BACKENDS
from .check import AXIS_NAMES, Candidate, FloatArray, kkt_conditions, leave_time
from .data import AvoidData
from .diagnostics import AvoidDiagnostics

__all__ = ["ACTIVE_SLACK_M", "QPSolutionData", "failed_plan", "summary_lines", "verified_plan"]


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


def failed_plan(problem: Problem, status: str, reason: str, start: float, *, solver: str, hold: str, steps: int,
                info: dict[str, Any] | None = None) -> Plan:
    """A plan without trajectory or cost, with the ``reason`` in its ``info``."""
    info = {**(info or {}), "constraint": "avoid", "reason": reason}
    return Plan(problem=problem, planner="qp", status=status, cost=None,
                contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                trajectory=None, solve_time_s=time.perf_counter() - start, solver=solver, hold=hold,
                steps=steps, diagnostics=AvoidDiagnostics.from_info(info))


def verified_plan(problem: Problem, data: AvoidData, cand: Candidate, complete: bool, info: dict[str, Any],
                  start: float, *, solver: str, hold: str, steps: int, contact: str) -> Plan:
    """The plan of the solved candidate ``cand`` on ``data``, its status from the recomputed
    checks (module docstring); ``complete``: the crossing-time sweep covered every candidate."""
    X, U = data.unpack(cand.z)
    traj = HoldTrajectory(data.t_nodes.copy(), X, U, hold)
    cost = traj.cost()
    elapsed = time.perf_counter() - start
    l, u = data.bounds(cand.on)
    kkt = kkt_conditions(data.P, data.q, data.A, l, u, cand.z, cand.y, n_eq=data.n_eq)
    limit = tol(BACKENDS[solver].tolerance_key)
    failed = [k for k, v in kkt.items() if v > limit]
    ineq_y = cand.y[data.n_eq:]
    slack = u[data.n_eq:] - (data.A @ cand.z)[data.n_eq:]
    relaxed_binding = bool(np.any((~data.effective_on(cand.on)) & (slack <= ACTIVE_SLACK_M)))
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
                contact_times=crossing, jumps=jumps, trajectory=traj, solve_time_s=elapsed, solver=solver,
                hold=hold, steps=steps)
    safety = plan.safety
    for entry, vs in zip(vehicles, safety.vehicles if safety is not None else ()):
        entry["between_node_intrusion_m"] = vs.max_intrusion_m
    if status in st.SUCCESS and safety is not None and not safety.intrusion_free:
        # SPEC §14: an avoidance plan is optimal only if its own §9 report is intrusion-free
        failed.append("intrusion")
        plan.status = st.UNSAFE
        info["unsafe_reason"] = ("the node-only constraints hold at the grid nodes, but the trajectory enters a "
                                 "safety region between them (use --safety continuous)")
    plan.residuals = {"boundary": plan.boundary_residual(), **kkt}
    info.update(kkt=kkt, kkt_tol=limit, failed_checks=failed,
                solver_status=cand.status, solver_iterations=int(cand.sol.iterations),
                qp_solution=QPSolutionData(data, l, u, cand.z, cand.y, cand.on))
    info["avoidance"] = {"constraint": "avoid", "safety": "nodes", "contact": contact, "complete_sweep": complete,
                         "n_solves": info["n_solves"], "vehicles": vehicles,
                         "kkt": kkt, "kkt_tol": limit, "failed_checks": failed,
                         "grid_best": info["grid_best"]}
    if failed:
        info["failed_check"] = failed[0]
    plan.diagnostics = AvoidDiagnostics.from_info(info)
    return plan


def summary_lines(plan: Plan) -> list[str]:
    """The text summary of an avoidance plan (the CLI prints it)."""
    diag = plan.diagnostics
    av: Any = (diag.avoidance if isinstance(diag, AvoidDiagnostics) else None) or {}
    n_solves = diag.n_solves if isinstance(diag, AvoidDiagnostics) else None
    out = [f"cost J    {plan.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]",
           f"time      {plan.solve_time_s * 1e3:.3f} ms ({n_solves} QPs; "
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
    return out + residual_and_safety_lines(plan, av)


def residual_and_safety_lines(plan: Plan, av: dict[str, Any]) -> list[str]:
    """The last lines of an avoidance plan's text summary: its KKT residuals against their
    tolerance, then the safety report's lines."""
    out: list[str] = []
    kkt = av.get("kkt", {})
    if kkt:
        out.append("residuals " + ", ".join(f"{k} {val:.1e}" for k, val in kkt.items())
                   + f" (tol {av.get('kkt_tol', 0):.0e})")
    if plan.safety is not None:
        out += plan.safety.lines()
    return out
