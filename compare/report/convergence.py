r"""The ZOH convergence study of ``iamp reproduce``: :math:`J_\mathrm{ZOH} - J_\mathrm{PMP}` at one
fixed contact time on grids of ``N`` intervals, :math:`h = t_f / N`.

The ZOH discretisation of the continuous problem is :math:`O(h^2)` in the cost: halving
:math:`h` divides the gap by about 4, and the fitted slope of :math:`\log(\text{gap})` against
:math:`\log h` is about 2.  The FOH gap, exact up to solver precision, is reported beside it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from iamp.core.problem import Problem

from .records import ZohConvergence, ZohRow

__all__ = ["zoh_convergence"]


def zoh_convergence(problem: Problem, steps: Sequence[int] = (25, 50, 100, 200, 400), t_contact: float | None = None,
                    solver: str = "clarabel") -> ZohConvergence:
    """``J_ZOH − J_PMP`` at one fixed contact time on grids ``N ∈ steps``.

    The contact time is a node of every grid (a multiple of ``t_f / gcd(steps)``, the one
    nearest to the PMP's ``t*`` unless given).  ``J_PMP`` is the fixed-time PMP cost there;
    the FOH gap is reported alongside (exact: solver precision).  ``ratio[k]`` is
    ``gap(N_k) / gap(N_{k+1})`` (4 for ``O(h²)`` when ``N`` doubles).
    """
    from iamp.planners.pmp.planner import PMPPlanner, solve_fixed_times
    from iamp.planners.qp.planner import QPPlanner

    steps = tuple(int(n) for n in steps)
    tf = problem.tf
    base = int(np.gcd.reduce(np.array(steps)))
    h0 = tf / base
    if t_contact is None:
        t_star = float(PMPPlanner().contact_times(problem)[0])
        k0 = int(min(max(round(t_star / h0), 1), base - 1))
    else:
        k0 = int(round(float(t_contact) / h0))
    t_c = k0 * h0
    rows: list[ZohRow] = []
    for N in steps:
        k = k0 * (N // base)
        t_node = np.linspace(0.0, tf, N + 1)[k]
        j_pmp = solve_fixed_times(problem, [t_node]).cost()
        z = QPPlanner(N, "zoh", solver).plan_at_nodes(problem, [k])
        f = QPPlanner(N, "foh", solver).plan_at_nodes(problem, [k])
        rows.append({"N": N, "h": tf / N, "node": k, "t_node": float(t_node), "J_pmp": j_pmp,
                     "J_zoh": z.cost if z.is_optimal() else None, "J_foh": f.cost if f.is_optimal() else None,
                     "zoh_gap": (z.cost - j_pmp) if z.is_optimal() and z.cost is not None else None,
                     "foh_gap": (f.cost - j_pmp) if f.is_optimal() and f.cost is not None else None,
                     "status_zoh": z.status, "status_foh": f.status})
    for a, b in zip(rows[:-1], rows[1:]):
        a["ratio_to_next"] = (a["zoh_gap"] / b["zoh_gap"]) if a["zoh_gap"] and b["zoh_gap"] else None
    gaps = np.array([r["zoh_gap"] if r["zoh_gap"] else np.nan for r in rows])
    hs = np.array([r["h"] for r in rows])
    ok = np.isfinite(gaps) & (gaps > 0)
    slope = float(np.polyfit(np.log(hs[ok]), np.log(gaps[ok]), 1)[0]) if ok.sum() >= 2 else None
    return {"solver": solver, "t_contact": t_c, "rows": rows, "loglog_slope": slope}
