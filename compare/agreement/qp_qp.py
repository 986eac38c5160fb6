r"""The verdict on a pair of QP runs with the same hold, ``N`` and contact search.

Pairs such as OSQP vs Clarabel or native vs cvxpy (:mod:`iamp.comparison.agreement.judge`) agree
when rules 0–1 hold (same problem, both ``optimal``), each run is a KKT point at its own
solver's precision (``primal_rel``, ``dual_rel``, ``gap_rel`` ``≤ cmp_kkt_rel_<solver>``),
and, with the looser solver's limits (OSQP's when either run is OSQP):

.. math::

    \frac{|J_b - J_a|}{|J_a|} \le \text{cmp\_cost\_rel}, \qquad
    \frac{\max|X_b - X_a|}{\max(1, \max|X_a|)},\ \frac{\max|U_b - U_a|}{\max(1, \max|U_a|)}
    \le \text{cmp\_state\_rel}, \qquad
    \frac{\max|\nu_b - \nu_a|}{\max(1, \max|\nu_a|)} \le \text{cmp\_jump\_rel}

on the grid of run ``a``.  Two grid sweeps whose contact times differ by more than
``cmp_node_time_rel``:math:`\cdot t_f` picked different candidates with costs equal within
precision (a tie): only the cost is judged and a note says so.
"""

from __future__ import annotations

import numpy as np

from iamp.comparison.trajectories import hold_trajectory
from iamp.core.problem import Problem
from iamp.core.tolerances import tol

from .gaps import run_vs_run_gaps
from .records import PairJSON
from .runs import Run
from .verdict import Checks, same_problem, solver_tol

__all__ = ["compare_qp_qp"]


def compare_qp_qp(problem: Problem, a: Run, b: Run) -> PairJSON:
    """Judge two QP runs with the same hold and ``N`` (e.g. OSQP vs Clarabel)."""
    checks = Checks()
    out: PairJSON = {"a": a.label, "b": b.label, "cost_rel_gap": None, "contact_time_gap": None,
                           "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    same_problem(a, b, checks)
    if a.result.status == b.result.status == "infeasible":  # a bounded problem (SPEC §14): both certify it
        out["verdict_basis"] = "both find no grid candidate within the limits"
        return checks.finish(out)
    for r in (a, b):
        if not r.ok:
            checks.fail(f"{r.label} status {r.result.status}")
    if a.ok and b.ok and a.config is not None and b.config is not None:
        ra, rb = a.result, b.result
        ca, cb = a.config, b.config
        for r in (a, b):  # both must be KKT points at their own solver's precision
            if r.kkt is None:
                checks.fail(f"{r.label}: KKT residuals unavailable")
            else:
                for k in ("primal_rel", "dual_rel", "gap_rel", "complementarity_rel"):
                    if k in r.kkt:  # complementarity: the limit rows of a bounded QP
                        checks.check(f"{r.label}_kkt_{k}", r.kkt.get(k),
                                     solver_tol("kkt_rel", (ca if r is a else cb).solver))
        loose = "osqp" if "osqp" in (ca.solver, cb.solver) else "clarabel"
        ctol = solver_tol("cost_rel", loose)
        tn = np.asarray(hold_trajectory(ra).t_nodes)
        gaps = run_vs_run_gaps(ra, rb, tn)
        out["cost_rel_gap"] = gaps["cost_rel_gap"]
        dt = gaps["contact_time_gap"]
        out["contact_time_gap"] = dt
        checks.check("cost_rel", abs(gaps["cost_rel_gap"]), ctol)
        if dt > tol("cmp_node_time_rel") * problem.tf and ca.contact == "grid":
            checks.notes.append("different grid candidates with equal costs (a tie within solver precision)")
        else:
            dx, du, dj = gaps["state_sup_gap"], gaps["input_sup_gap"], gaps["jump_gap"]
            out["state_sup_gap"], out["input_sup_gap"], out["jump_gap"] = dx, du, dj
            Xa, Ua = ra.require_trajectory().states(tn), ra.require_trajectory().inputs(tn)
            checks.check("state_rel", dx / max(1.0, float(np.max(np.abs(Xa)))), solver_tol("state_rel", loose))
            checks.check("input_rel", du / max(1.0, float(np.max(np.abs(Ua)))), solver_tol("state_rel", loose))
            checks.check("jump_rel", dj / max(1.0, float(np.max(np.abs(ra.jumps)))), solver_tol("jump_rel", loose))
    return checks.finish(out)
