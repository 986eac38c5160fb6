r"""The gaps between two runs (SPEC §5b): as they came out, and at the same contact times.

Run-vs-run (the headline of every ``agreement`` entry; run ``b`` against run ``a``, each at
its own contact times, states and inputs on the grid ``t_k`` of the QP run):

.. math::

    \text{cost\_rel\_gap} = \frac{J_b - J_a}{|J_a|}, \qquad
    \text{contact\_time\_gap} = \max_i |t_{b,i} - t_{a,i}|,

    \text{state\_sup\_gap} = \max_{k,j} |x_{b,j}(t_k) - x_{a,j}(t_k)|, \qquad
    \text{input\_sup\_gap} = \max_{k,j} |u_{b,j}(t_k) - u_{a,j}(t_k)|, \qquad
    \text{jump\_gap} = \max_{i,j} |\nu_{b,i,j} - \nu_{a,i,j}|

(absolute; a run's jumps are the PMP's ``Φ_i`` or a QP's multipliers ``ν_i``, so for the pair
``pmp`` / QP this is :math:`\max|\nu - \Phi(t^*)|`).

At the same contact times (key ``at_same_contact_times``, never in place of the above): the
PMP re-solved at the QP's own contact times ``t_Q`` (grid nodes) — the FOH QP's exact
reference (SPEC §3.1), the ZOH QP's up to the ``O(h²)`` excess — with the same four gaps,
the per-vehicle ``ν_i − Φ_i(t_Q)``, and ``contact_time_gap_to_grid_optimum =
max|t_Q − t_grid*|``, where ``t_grid*`` minimises the PMP's value function :math:`J(t)` over
the grid candidates (the FOH sweep's exact optimum).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from iamp.core.plan import Plan
from iamp.planners.pmp.solution import PMPSolution

from .records import RunGaps, SameContactTimes
from .verdict import plan_cost

__all__ = ["at_same_contact_times", "grid_optimum_gap", "run_vs_run_gaps"]

FloatArray = NDArray[np.float64]


def run_vs_run_gaps(a: Plan, b: Plan, t_nodes: FloatArray) -> RunGaps:
    """The headline gaps of run ``b`` against run ``a`` (module docstring), states and inputs
    compared at ``t_nodes``; both plans verified (``optimal``)."""
    Xa, Ua = a.require_trajectory().states(t_nodes), a.require_trajectory().inputs(t_nodes)
    Xb, Ub = b.require_trajectory().states(t_nodes), b.require_trajectory().inputs(t_nodes)
    J_a, J_b = plan_cost(a), plan_cost(b)
    return {"cost_rel_gap": float((J_b - J_a) / abs(J_a)),
            "contact_time_gap": float(np.max(np.abs(b.contact_times - a.contact_times))),
            "state_sup_gap": float(np.max(np.abs(Xb - Xa))),
            "input_sup_gap": float(np.max(np.abs(Ub - Ua))),
            "jump_gap": float(np.max(np.abs(b.jumps - a.jumps)))}


def at_same_contact_times(qp: Plan, pmp_at: PMPSolution | Plan, tQ: FloatArray,
                          t_nodes: FloatArray) -> SameContactTimes:
    """The QP against the PMP re-solved at its contact times ``tQ``.

    Parameters
    ----------
    qp : Plan
        The verified QP plan.
    pmp_at : PMPSolution or Plan
        :func:`iamp.planners.pmp.planner.solve_fixed_times` at ``tQ`` (``cost()``, ``states``,
        ``inputs``, ``jumps``), or the PMP's plan at ``tQ`` (the bounded problem: a plan with a
        cost and a trajectory).
    tQ : ndarray
        The QP's contact times, as nodes of its grid ``t_nodes``.
    """
    J_qp, J_at = plan_cost(qp), plan_cost(pmp_at) if isinstance(pmp_at, Plan) else pmp_at.cost()
    X_qp, U_qp = qp.require_trajectory().states(t_nodes), qp.require_trajectory().inputs(t_nodes)
    X_p, U_p = pmp_at.states(t_nodes), pmp_at.inputs(t_nodes)
    return {"reference": "PMP re-solved at the QP's contact times",
            "contact_times": [float(t) for t in tQ],
            "cost_rel_gap": float((J_qp - J_at) / abs(J_at)),
            "state_sup_gap": float(np.max(np.abs(X_qp - X_p))),
            "input_sup_gap": float(np.max(np.abs(U_qp - U_p))),
            "jump_gap": float(np.max(np.abs(qp.jumps - pmp_at.jumps))),
            "nu_minus_phi": (qp.jumps - pmp_at.jumps).tolist()}  # per vehicle (x, y), Φ at t_Q


def grid_optimum_gap(tQ: FloatArray, cands: NDArray[np.int_], J_foh: FloatArray, tf: float, steps: int) -> float:
    """``max|t_Q − t_grid*|`` with ``t_grid* = t_f/N · cands[argmin J_foh]`` on the uniform grid
    ``t_k = k t_f/N`` (``J_foh``: the PMP's value function at every grid candidate)."""
    uniform = np.linspace(0.0, tf, steps + 1)  # the QP's own grid
    t_grid_star = uniform[cands[int(np.argmin(J_foh))]]
    return float(np.max(np.abs(tQ - t_grid_star)))
