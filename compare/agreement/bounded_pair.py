r"""The verdict on a ``pmp`` / QP pair of a problem with physical limits (SPEC §14).

With ``problem.limits`` the PMP is the bounded PMP (:mod:`iamp.planners.pmp.bounded`: the
input box ``ax``/``ay`` imposed exactly, every other bound checked on its plan) and the QP is
the bounded QP (:mod:`iamp.planners.qp.bounded`, every bound at every node).  The rules of
:mod:`iamp.comparison.agreement.pmp_qp` rest on the FOH QP being *exact* and on closed forms that
hold without bounds; here the references are the bounded PMP's:

B0. *Same problem*: the fingerprints (which include the limits) are equal.

B1. *Status*.  Both verified (PMP ``optimal`` or ``local``, QP ``optimal``): rules B2–B6.  Both
    ``infeasible``: **agree** — the PMP certifies that no contact time admits a plan within the
    box and the QP that no grid candidate does (every QP plan is a plan within the box, so the
    first implies the second).  A QP plan where the PMP certifies the box infeasible is a
    contradiction (**disagree**).  Any other status (``limits_violated``: the PMP's plan exceeds
    a bound it cannot impose; a solver failure): **disagree**, with the status as the reason.

B2. *KKT* of the QP, recomputed from the stacked matrices ``[A; A_L]`` and the returned
    ``(z, y)``: primal, dual, gap and the limit rows' complementarity below ``cmp_kkt_rel_*``.

B3. *Constraints*: the QP trajectory's boundary and corner residuals below ``cmp_residual_rel_*``.

B4. *Lower bound at the same contact times* (rigorous): every plan of the QP at its contact
    times ``t_Q`` is a plan with inputs in the box (FOH: linear between nodes that lie in the
    box; ZOH: constant), with cost exactly :math:`\tfrac12\int|u|^2`, so
    :math:`J_{QP} \ge J_b(t_Q)`, the bounded PMP re-solved at ``t_Q`` (unique: a strictly convex
    problem), within ``cmp_cost_rel_*``.  A QP plan where the bounded PMP finds the box
    infeasible at ``t_Q`` fails this rule.

B5. *The PMP's global claim*: an ``optimal`` bounded PMP is certified global over the contact
    times, so :math:`J_b(t_Q) \ge J_b^*` within ``cmp_cost_rel_*`` (a ``local`` PMP: a note).

B6. *Discretisation excess* :math:`\Delta = J_{QP} - J_b(t_Q) \ge 0` against its leading term.
    ZOH: the leading term of the ZOH gap (SPEC §3.2) of the bounded input :math:`u_b` at
    ``t_Q``, :math:`\Delta_1 = \tfrac{h^2}{24}\int_0^{t_f}|\dot u_b|^2\,dt` (exact: ``u_b`` is
    linear between its knots); :math:`\Delta/\Delta_1` in [``cmp_bounded_zoh_ratio_low``,
    ``cmp_bounded_zoh_ratio_high``] (the unbounded bracket is :math:`[1, 1/(1-\rho)]`; with
    bounds the ratio measured 0.987–1.036 at ``N`` = 25–100, ``scripts``-free:
    ``tests/test_issue29_compare.py``).  FOH represents every piecewise-linear input on the grid
    exactly (the contact times are nodes) and misses ``u_b`` only on the intervals holding a
    switching time :math:`\theta` (slope change :math:`\Delta_\theta`, at
    :math:`\theta = t_j + \alpha h`).  The FOH interpolant of ``u_b``, corrected back onto the
    equalities by an FOH input on the free set (cost :math:`O(h^4)`), is an FOH plan in the
    box whose excess is, to leading order (:func:`foh_kink_term`),

    .. math::  K_h = \sum_\theta \frac{\Delta_\theta^2 h^3}{6}\,\beta(\alpha),\qquad
               \beta = \alpha(1-\alpha)^2 \text{ (saturated after } \theta),\
               \alpha^2(1-\alpha) \text{ (before)},

    (``½∫e²`` of the interpolation error plus ``∫(u_b − w)e`` on the saturated side), so
    :math:`\Delta \le` ``cmp_bounded_foh_ratio`` :math:`\cdot K_h` (the QP minimises over all
    FOH plans; :math:`\Delta/K_h` measured 0.25–1.54 at ``N = 24`` on 60 generated problems, at
    most 1 from ``N = 48`` on, as the leading-order argument says), and :math:`\Delta = 0` to
    solver precision when no switching time falls inside an interval.  (Until 2026-11-28 the
    FOH rule was :math:`\Delta \le 0.25\,\Delta_1`; that is not a bound — the FOH excess is set
    by the switching kinks, not by :math:`\int|\dot u_b|^2` — and failed on
    ``random_problem(229)`` with limits at 0.609 of its inputs: :math:`\Delta/\Delta_1` = 0.35
    at ``N = 24``, :math:`\Delta/K_h` = 1.30, with the bounded PMP right: the FOH QP at that
    contact time converges to its :math:`J_b` from above, 5.4e-1, 4.4e-3, 1.3e-4, 1.2e-6 at
    ``N`` = 24, 96, 384, 1536.)

The headline gaps (``cost_rel_gap`` etc.) and ``at_same_contact_times`` are those of
:mod:`iamp.comparison.agreement.gaps`, against the bounded PMP.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from iamp.comparison.trajectories import hold_trajectory
from iamp.core import status as st
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.pmp.bounded import plan_knots
from iamp.planners.pmp.planner import PMPPlanner

from .gaps import at_same_contact_times, run_vs_run_gaps
from .records import PairJSON
from .runs import Run
from .signs import sign_entry
from .verdict import Checks, plan_cost, same_problem, solver_tol

__all__ = ["compare_bounded_pmp_qp", "foh_kink_term", "input_slope_energy"]


def input_slope_energy(plan: Plan) -> float:
    r""":math:`\int_0^{t_f}|\dot u|^2\,dt` of a PMP plan (bounded or not): its input is linear
    between the knots (contact and switching times), so the integral is a finite sum."""
    tf = float(plan.problem.tf)
    knots = np.array(sorted({0.0, tf, *(float(t) for t in plan_knots(plan))}))
    U = plan.require_trajectory().inputs(knots)
    dt = np.diff(knots)
    keep = dt > 0
    return float(np.sum(np.sum(np.diff(U, axis=0) ** 2, axis=1)[keep] / dt[keep]))


def foh_kink_term(plan: Plan, t_nodes: npt.NDArray[np.float64]) -> float:
    r"""The leading term :math:`K_h` of the FOH excess (rule B6): over the switching times
    :math:`\theta` of a bounded PMP plan strictly inside an interval of ``t_nodes``,
    :math:`\sum_\theta \Delta_\theta^2 h^3 \beta(\alpha)/6` with :math:`\Delta_\theta` the
    change of :math:`\dot u` at :math:`\theta`, :math:`\alpha = (\theta - t_j)/h` and
    :math:`\beta = \alpha(1-\alpha)^2` where the input saturates after :math:`\theta`,
    :math:`\alpha^2(1-\alpha)` where it saturates before (module docstring).

    Parameters
    ----------
    plan : Plan
        A PMP plan; an unbounded one (no switching times) gives ``0``.
    t_nodes : numpy.ndarray
        The QP's grid (increasing, from ``0`` to ``t_f``).

    Returns
    -------
    float
        :math:`K_h` (``0`` when no switching time lies strictly inside an interval).
    """
    nodes = np.asarray(t_nodes, dtype=float)
    total = 0.0
    for ax in getattr(plan.trajectory, "axes", ()):
        kn = np.asarray(ax.knots, dtype=float)
        u = np.asarray(ax.u, dtype=float)
        dk = np.diff(kn)
        slope = np.diff(u) / np.where(dk > 0, dk, 1.0)
        for theta, _, _, direction in ax.switching:
            j = int(np.argmin(np.abs(kn - theta)))
            i = int(np.searchsorted(nodes, theta)) - 1
            if j == 0 or j == len(kn) - 1 or i < 0 or i + 1 >= len(nodes):
                continue
            h = float(nodes[i + 1] - nodes[i])
            alpha = (theta - float(nodes[i])) / h
            if not 0.0 < alpha < 1.0:
                continue
            beta = alpha * (1 - alpha) ** 2 if direction > 0 else alpha * alpha * (1 - alpha)
            total += float(slope[j] - slope[j - 1]) ** 2 * h**3 * beta / 6
    return total


def _verified(plan: Plan) -> bool:
    return plan.status in (st.OPTIMAL, st.LOCAL) and plan.cost is not None and plan.trajectory is not None


def compare_bounded_pmp_qp(problem: Problem, pmp: Run, qp: Run) -> PairJSON:
    """Judge one ``pmp`` / QP pair of a bounded problem (rules B0–B6 of the module docstring).

    Parameters
    ----------
    problem : Problem
        With ``problem.limits``.
    pmp, qp : Run
        The bounded PMP's run and one QP configuration's run on ``problem``.

    Returns
    -------
    PairJSON
        The ``agreement`` entry: ``a``, ``b``, the gaps, ``at_same_contact_times``,
        ``bounded`` (the excess and its leading term), ``verdict_basis``, ``verdict``,
        ``reasons``, ``notes`` and every check.
    """
    checks = Checks()
    cfg = qp.config
    out: PairJSON = {"a": pmp.label, "b": qp.label, "cost_rel_gap": None, "contact_time_gap": None,
                     "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    same_problem(pmp, qp, checks)
    p_res, q_res = pmp.result, qp.result
    if p_res.status == st.INFEASIBLE and q_res.status == st.INFEASIBLE:
        out["verdict_basis"] = "both certify the bounded problem infeasible (rule B1)"
        checks.notes.append(f"pmp: {p_res.diagnostics.reason}")
        checks.notes.append(f"{qp.label}: {q_res.diagnostics.reason}")
        return checks.finish(out)
    if p_res.status == st.INFEASIBLE and _verified(q_res):
        checks.fail(f"{qp.label} found a plan within the limits where the PMP certifies the input box infeasible "
                    f"({p_res.diagnostics.reason})")
        return checks.finish(out)
    failed_before = len(checks.reasons)  # rule B0's reason does not stop the numeric rules
    if not _verified(p_res):
        checks.fail(f"pmp status {p_res.status}" + (f" ({p_res.diagnostics.reason})" if p_res.diagnostics.reason
                                                    else ""))
    if not qp.ok:
        checks.fail(f"{qp.label} status {q_res.status}" + (f" ({q_res.diagnostics.reason})"
                                                            if q_res.diagnostics.reason else ""))
    if len(checks.reasons) > failed_before or cfg is None:
        return checks.finish(out)
    if p_res.status == st.LOCAL:
        checks.notes.append("the bounded PMP is local (verified at its contact times, not certified global): "
                            "rule B5 is not applied")
    solver, hold = cfg.solver, cfg.hold
    traj = hold_trajectory(q_res)
    t_nodes = np.asarray(traj.t_nodes)
    nodes = [int(np.argmin(np.abs(t_nodes - t))) for t in q_res.contact_times]
    tQ = t_nodes[nodes]
    gaps = run_vs_run_gaps(p_res, q_res, t_nodes)
    out["cost_rel_gap"], out["contact_time_gap"] = gaps["cost_rel_gap"], gaps["contact_time_gap"]
    out["state_sup_gap"], out["input_sup_gap"] = gaps["state_sup_gap"], gaps["input_sup_gap"]
    out["jump_gap"] = gaps["jump_gap"]
    # the bounded PMP at the QP's contact times (fixed times: the unique optimum of a strictly convex problem)
    at = PMPPlanner().plan(problem, contact_times=tQ)
    ctol = solver_tol("cost_rel", solver)
    # B2: KKT with complementarity, recomputed from the stacked matrices
    if qp.kkt is None:
        checks.fail("KKT residuals unavailable")
    else:
        for k in ("primal_rel", "dual_rel", "gap_rel", "complementarity_rel"):
            value = qp.kkt.get(k)
            checks.check(f"kkt_{k}", value if isinstance(value, float) else None, solver_tol("kkt_rel", solver))
    # B3: the QP's own constraints
    bscale = max(1.0, float(np.max(np.abs(np.r_[problem.ego.initial, problem.ego.final]))))
    checks.check("boundary_residual_rel", q_res.boundary_residual() / bscale, solver_tol("residual_rel", solver))
    checks.check("collision_residual_rel", q_res.corner_residual() / bscale, solver_tol("residual_rel", solver))
    out["signs"] = [sign_entry(v, j[0]) for v, j in zip(problem.vehicles, q_res.jumps)]
    if at.trajectory is None or at.cost is None:
        checks.fail(f"the bounded PMP at the QP's contact times {[round(float(t), 9) for t in tQ]} is {at.status} "
                    f"({at.diagnostics.reason}), but the QP found a plan there within the limits (rule B4)")
        return checks.finish(out)
    J_qp, J_at, J_star = plan_cost(q_res), float(at.cost), plan_cost(p_res)
    out["at_same_contact_times"] = at_same_contact_times(q_res, at, tQ, t_nodes)
    # B4: the QP's plan is a plan within the box at t_Q
    checks.check("bounded_lower_bound_rel", (J_at - J_qp) / abs(J_at), ctol,
                 why="the QP's cost is below the bounded PMP's at the same contact times: the QP did not "
                     "solve the bounded problem")
    # B5: t* is the global minimiser of the bounded cost
    if p_res.status == st.OPTIMAL:
        checks.check("pmp_global_lower_bound", (J_star - J_at) / abs(J_star), ctol,
                     why="the QP's contact times have a lower bounded cost than t*: the bounded PMP missed the "
                         "global optimum")
    # B6: the discretisation excess against the ZOH gap's leading term
    h = float(np.max(np.diff(t_nodes)))
    lead = h * h / 24.0 * input_slope_energy(at)
    excess = J_qp - J_at
    slack = ctol * abs(J_at)
    ratio = excess / lead if lead > 0 else None
    if hold == "zoh":
        lo, hi = tol("cmp_bounded_zoh_ratio_low"), tol("cmp_bounded_zoh_ratio_high")
        checks.check("bounded_zoh_excess_in_bracket", 0.0, 0.0,
                     ok=lo * lead - slack <= excess <= hi * lead + slack,
                     why=f"excess {excess:.6g} outside [{lo:g}, {hi:g}] x the leading term {lead:.6g}")
    kink = foh_kink_term(at, t_nodes)
    if hold != "zoh":
        factor = tol("cmp_bounded_foh_ratio")
        checks.check("bounded_foh_excess_rel", (excess - factor * kink) / abs(J_at), ctol,
                     why=f"excess {excess:.6g} above {factor:g} x the FOH kink term {kink:.6g}")
    out["bounded"] = {"pmp_at_contact_times_status": at.status, "pmp_at_contact_times_cost": J_at,
                      "excess": float(excess), "leading_h2_term": float(lead),
                      "ratio_to_leading": None if ratio is None else float(ratio), "h": h,
                      "foh_kink_term": float(kink)}
    out["reference"] = "bounded PMP at the QP's contact times"
    out["verdict_basis"] = ("bounded problem: KKT with complementarity, constraint residuals, the QP's cost above the "
                            "bounded PMP's at the same contact times, the PMP's global claim, and the discretisation "
                            "excess against its leading h^2 term (rules B1-B6)")
    return checks.finish(out)
