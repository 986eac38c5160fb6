"""
Plan a scenario with the PMP and the QP
=======================================

Plan the lane change of a built-in scenario with the PMP and with the QP, through the registry.

Run: ``python examples/plan_scenario.py``
"""

from __future__ import annotations

import numpy as np

import iamp


def main() -> dict[str, iamp.Plan]:
    problem = iamp.load_scenario("paper-1-poly")  # vehicle 1 as a polynomial: no predictor needed
    plans = {
        "pmp": iamp.plan(problem),  # the indirect method: jump conditions, global contact time
        "qp": iamp.plan(problem, "qp", solver="clarabel", hold="foh", steps=100),  # the discretised baseline
    }
    for name, plan in plans.items():
        t = np.linspace(0.0, problem.tf, 5)
        print(f"{name:4s} {plan.status:8s} J = {plan.cost:.6f}  contact time t1 = {plan.contact_times[0]:.4f} s  "
              f"jump = {plan.jumps[0]}")
        print("     lateral position y(t) at t = 0, tf/4, .., tf:", np.round(plan.states(t)[:, 2], 3))
    return plans


if __name__ == "__main__":
    main()
