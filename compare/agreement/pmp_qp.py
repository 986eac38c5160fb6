r"""The verdict on one ``pmp`` / QP pair: rules 0–7 of :mod:`iamp.comparison.agreement.judge`.

The QP is judged at its *own* contact times ``t_Q`` against the exact reference there (FOH:
the PMP re-solved at ``t_Q``; ZOH: the closed-form optimum of
:func:`iamp.comparison.agreement.references.zoh_reference`), then its contact-time search against the
PMP's global ``t*``:

2. solver precision: :math:`|J_Q - J_{ref}|/|J_{ref}|`, :math:`\max|X_Q - X_{ref}|/\max(1,
   \max|X_{ref}|)`, the same for the inputs and for :math:`\nu - \nu_{ref}`, below the solver's
   ``cmp_cost_rel_*``, ``cmp_state_rel_*``, ``cmp_jump_rel_*``;
3. KKT residuals recomputed from the QP's matrices (``primal_rel``, ``dual_rel``, ``gap_rel``)
   below ``cmp_kkt_rel_*``;
4. boundary and corner residuals over :math:`\max(1, \max|x_0|, \max|x_f|)` below
   ``cmp_residual_rel_*``;
5. (grid) :math:`(J_{ref}(t_Q) - \min_{grid} J_{ref})/|\min_{grid} J_{ref}| \le` ``cmp_cost_rel_*``;
6. :math:`(J^* - J_{PMP}(t_Q))/|J^*| \le` ``cmp_cost_rel_*`` (``t*`` is a lower bound), and
   (grid) :math:`(J_Q - \min_{c \in \text{brackets}} J_{ref}(c))/|\cdot| \le` ``cmp_cost_rel_*``
   over the ``2^m`` node combinations bracketing ``t*``; (refine, FOH)
   :math:`|J_Q - J^*|/|J^*| \le` ``refine_cost_rel``;
7. (ZOH) :math:`J_Q \ge J_{PMP}(t_Q)` and :math:`\Delta_1 \le J_Q - J_{PMP}(t_Q) \le
   \Delta_1/(1-\rho)`, both within ``cmp_cost_rel_*``:math:`\cdot|J_{PMP}(t_Q)|`.

The gaps reported beside the verdict come from :mod:`iamp.comparison.agreement.gaps`.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.trajectories import hold_trajectory
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.pmp.planner import ValueFunction, solve_fixed_times
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.qp.hold import HoldTrajectory

from .gaps import at_same_contact_times, grid_optimum_gap, run_vs_run_gaps
from .records import ContinuousJSON, PairJSON, SameContactTimes, ZohGapJSON, ZohReference
from .references import grid_cost_table, zoh_reference
from .runs import Run
from .signs import sign_entry
from .verdict import Checks, plan_cost, pmp_own_checks, same_problem, solver_tol

__all__ = ["compare_pmp_qp"]

#: ``(steps, hold) -> (candidates, J)`` of :func:`grid_cost_table`, shared by the pairs of one problem.
#: :func:`grid_cost_table` results by ``(steps, hold)``: the candidates and their costs.
GridTables = dict[tuple[int, str], tuple[NDArray[np.int_], NDArray[np.float64]]]


def _nodes_of(traj: HoldTrajectory, times: NDArray[np.float64]) -> list[int]:
    t_nodes = np.asarray(traj.t_nodes)
    return [int(np.argmin(np.abs(t_nodes - t))) for t in times]


def _grid_table(problem: Problem, steps: int, hold: str,
                tables: GridTables | None) -> tuple[NDArray[np.int_], NDArray[np.float64]]:
    """:func:`grid_cost_table`, cached in ``tables`` by ``(steps, hold)`` when given."""
    key = (steps, hold)
    if tables is not None and key in tables:
        return tables[key]
    cands, J = grid_cost_table(problem, steps, hold)
    if tables is not None:
        tables[key] = (cands, J)
    return cands, J


def compare_pmp_qp(problem: Problem, pmp: Run, qp: Run, tables: GridTables | None = None) -> PairJSON:
    """Judge one ``pmp`` / QP pair (rules 0–7 of :mod:`iamp.comparison.agreement.judge`).

    ``tables`` caches :func:`grid_cost_table` results by ``(steps, hold)``.  Returns the
    ``agreement`` entry: ``a``, ``b``, the run-vs-run gaps, ``at_same_contact_times``, the
    reference, signs, ``continuous`` (grid brackets), ``zoh_gap`` (ZOH), ``verdict_basis``,
    ``verdict``, ``reasons``, ``notes`` and every check.
    """
    checks = Checks()
    cfg = qp.config
    out: PairJSON = {"a": pmp.label, "b": qp.label, "cost_rel_gap": None, "contact_time_gap": None,
                           "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    same_problem(pmp, qp, checks)
    if not pmp.ok:
        checks.fail(f"pmp status {pmp.result.status}")
    if not qp.ok:
        checks.fail(f"{qp.label} status {qp.result.status}")
    if not (pmp.ok and qp.ok) or cfg is None:
        return checks.finish(out)
    pmp_own_checks(pmp, checks)
    solver, hold = cfg.solver, cfg.hold
    res = qp.result
    traj = hold_trajectory(res)
    t_nodes = np.asarray(traj.t_nodes)
    N = len(t_nodes) - 1
    h_max = float(np.max(np.diff(t_nodes)))
    nodes = _nodes_of(traj, res.contact_times)
    tQ = t_nodes[nodes]
    if np.max(np.abs(tQ - res.contact_times)) > 1e-12 * problem.tf:
        checks.fail("the QP's contact times are not nodes of its grid")
    J_star, t_star = plan_cost(pmp.result), pmp.result.contact_times
    J_qp = plan_cost(res)
    # PMP at the QP's contact times (FOH's exact reference)
    pmp_at = solve_fixed_times(problem, tQ)
    J_pmp_tQ = pmp_at.cost()
    X_qp = traj.states(t_nodes)
    X_p, U_p = pmp_at.states(t_nodes), pmp_at.inputs(t_nodes)
    gaps = run_vs_run_gaps(pmp.result, res, t_nodes)  # SPEC §5b headline
    out["cost_rel_gap"], out["contact_time_gap"] = gaps["cost_rel_gap"], gaps["contact_time_gap"]
    out["state_sup_gap"], out["input_sup_gap"] = gaps["state_sup_gap"], gaps["input_sup_gap"]
    out["jump_gap"] = gaps["jump_gap"]
    same = at_same_contact_times(res, pmp_at, tQ, t_nodes)  # a separate, named key
    out["at_same_contact_times"] = same
    # the exact reference at t_Q
    z: ZohReference | None = None
    if hold == "foh":
        ref_cost, ref_X, ref_U, ref_nu = J_pmp_tQ, X_p, U_p, pmp_at.jumps
        out["reference"] = "PMP at the QP's contact times"
        U_cmp = traj.inputs(t_nodes)
    else:
        z = zoh_reference(problem, t_nodes, nodes)
        ref_cost, ref_X, ref_U, ref_nu = z["cost"], z["X"], z["U"], z["nu"]
        out["reference"] = "closed-form ZOH optimum at the QP's contact times"
        U_cmp = np.asarray(traj.U)
    # rule 2: solver precision
    checks.check("cost_vs_reference_rel", abs(J_qp - ref_cost) / abs(ref_cost), solver_tol("cost_rel", solver))
    xs = max(1.0, float(np.max(np.abs(ref_X))))
    checks.check("state_vs_reference_rel", np.max(np.abs(X_qp - ref_X)) / xs, solver_tol("state_rel", solver))
    us = max(1.0, float(np.max(np.abs(ref_U))))
    checks.check("input_vs_reference_rel", np.max(np.abs(U_cmp - ref_U)) / us, solver_tol("state_rel", solver))
    js = max(1.0, float(np.max(np.abs(ref_nu))))
    checks.check("jump_vs_reference_rel", np.max(np.abs(res.jumps - ref_nu)) / js, solver_tol("jump_rel", solver))
    # rule 3: KKT
    if qp.kkt is None:
        checks.fail("KKT residuals unavailable")
    else:
        for k in ("primal_rel", "dual_rel", "gap_rel"):
            checks.check(f"kkt_{k}", qp.kkt[k], solver_tol("kkt_rel", solver))
    # rule 4: constraints
    bscale = max(1.0, float(np.max(np.abs(np.r_[problem.ego.initial, problem.ego.final]))))
    checks.check("boundary_residual_rel", res.boundary_residual() / bscale, solver_tol("residual_rel", solver))
    checks.check("collision_residual_rel", res.corner_residual() / bscale, solver_tol("residual_rel", solver))
    out["signs"] = [sign_entry(v, j[0]) for v, j in zip(problem.vehicles, res.jumps)]
    ctol = solver_tol("cost_rel", solver)
    # rule 6 (lower bound, both contact searches): t* is the global optimum
    J_vf_tQ = float(ValueFunction(problem)(tQ[None, :])[0])
    checks.check("pmp_global_lower_bound", (J_star - J_vf_tQ) / abs(J_star), ctol,
                 why="the QP's candidate has a lower PMP cost than t*: the PMP's search missed the global optimum")
    cont: ContinuousJSON = {"h": h_max}
    if cfg.contact == "grid":
        _grid_rules(problem, N, hold, nodes, tQ, t_star, J_qp, ctol, tables, out, same, cont, checks)
    elif hold == "foh":  # refine
        checks.check("refine_cost_vs_continuous_rel", abs(J_qp - J_star) / abs(J_star), tol("refine_cost_rel"))
    if hold == "zoh" and z is not None:
        out["zoh_gap"] = _zoh_rule(J_qp, J_pmp_tQ, z, ctol, checks)
    out["continuous"] = cont
    out["verdict_basis"] = ("solver precision at the QP's own contact times (at_same_contact_times), KKT and "
                            "constraint residuals, and the contact-time search rules against the PMP's t*")
    qpd = res.diagnostics.find(QPDiagnostics)
    if qpd is not None and qpd.failures:
        checks.notes.append(f"{len(qpd.failures)} sweep candidate(s) failed "
                            f"({', '.join(sorted({str(s) for _, s in qpd.failures}))}); the best is taken "
                            "among the rest")
    return checks.finish(out)


def _grid_rules(problem: Problem, N: int, hold: str, nodes: list[int], tQ: NDArray[np.float64],
                t_star: NDArray[np.float64], J_qp: float, ctol: float, tables: GridTables | None,
                out: PairJSON, same: SameContactTimes, cont: ContinuousJSON, checks: Checks) -> None:
    """Rules 5 and 6 (upper bound) of a grid sweep; the gap to the grid optimum into ``same``."""
    cands, Jtab = _grid_table(problem, N, hold, tables)
    lookup = {tuple(c): j for c, j in zip(cands.tolist(), Jtab)}
    J_ref_tQ = lookup.get(tuple(nodes), np.inf)
    J_grid_best = float(Jtab[int(np.argmin(Jtab))])
    # t_grid*: the PMP's optimum restricted to the grid, from the FOH (exact) table
    cands_foh, J_foh = (cands, Jtab) if hold == "foh" else _grid_table(problem, N, "foh", tables)
    same["contact_time_gap_to_grid_optimum"] = grid_optimum_gap(tQ, cands_foh, J_foh, problem.tf, N)
    # rule 5: the sweep found the grid optimum of the exact sweep cost
    checks.check("search_grid_optimum_rel", (J_ref_tQ - J_grid_best) / abs(J_grid_best), ctol,
                 why="the QP's best candidate is not the grid optimum")
    # rule 6 (upper bound): the candidates bracketing t* were swept
    h = problem.tf / N
    lo = np.clip(np.floor(t_star / h).astype(int), 1, N - 1)
    hi = np.clip(np.ceil(t_star / h).astype(int), 1, N - 1)
    brackets = [c for c in itertools.product(*[sorted({int(a), int(b)}) for a, b in zip(lo, hi)])
                if len(set(c)) == len(c)]
    if brackets:
        J_bracket = min(lookup.get(tuple(c), np.inf) for c in brackets)
        checks.check("bracket_upper_bound_rel", (J_qp - J_bracket) / abs(J_bracket), ctol,
                     why="the sweep's best is worse than a grid candidate bracketing t*")
        cont["bracket_cost"] = float(J_bracket)
        cont["bracket_nodes"] = [list(c) for c in brackets]
    gap_t = out["contact_time_gap"]
    if gap_t is not None and gap_t > h * (1 + 1e-9):
        checks.notes.append(f"contact time {out['contact_time_gap']:.3g} s from t* (> h = {h:.3g} s): the grid "
                            "optimum lies in another basin with a cost within the grid resolution (near tie)")


def _zoh_rule(J_qp: float, J_pmp_tQ: float, z: ZohReference, ctol: float, checks: Checks) -> ZohGapJSON:
    """Rule 7: the ZOH cost above the PMP's at the same times, the gap inside the ``O(h²)`` bracket."""
    gap = J_qp - J_pmp_tQ
    lower, rho = z["gap_leading"], z["rho"]
    upper = lower / (1 - rho) if rho < 1 else np.inf
    slack = ctol * abs(J_pmp_tQ)
    checks.check("zoh_above_pmp", -gap / abs(J_pmp_tQ), ctol, why="ZOH cost below the PMP's at the same times")
    checks.check("zoh_gap_in_bracket", 0.0, 0.0, ok=(lower - slack <= gap <= upper + slack),
                 why=f"gap {gap:.6g} outside [{lower:.6g}, {upper:.6g}]")
    return {"gap": float(gap), "leading_h2_term": float(lower), "upper_bound": float(upper),
            "rho": float(rho), "ratio_to_leading": float(gap / lower) if lower > 0 else None}
