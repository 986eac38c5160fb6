"""
Avoid two vehicles, safe in continuous time
===========================================

The paper's equality makes the ego pass through one named corner of each vehicle's safety
region. The avoidance QP (SPEC §10) instead keeps the ego out of every safety region: the
disjunction "ahead of or behind or beside" becomes a choice of the time at which the ego
crosses into the target lane, searched by a branch and bound, and the plan is checked in
continuous time (between grid nodes too), not only at the nodes.

Run: ``python examples/plan_avoid.py``
"""

from __future__ import annotations

import iamp
from iamp.cli.plot import plan_figure


def main() -> dict[str, iamp.Plan]:
    problem = iamp.load_scenario("two-vehicle")
    plans = {
        "equality": iamp.plan(problem),  # the paper: through a corner of each vehicle's region
        "avoid": iamp.plan(problem, "qp", constraint="avoid", solver="clarabel", steps=50),
    }
    for name, plan in plans.items():
        safety = plan.safety
        deepest = max((v.max_intrusion_m for v in safety.vehicles), default=0.0)
        print(f"{name:9s} {plan.status:8s} J = {plan.cost:.4f}  intrusion-free: {safety.intrusion_free}  "
              f"(deepest intrusion {deepest:.4f} m), bodies collision-free: {safety.collision_free}")
    # drawn through pyplot, so that the gallery shows it
    plan_figure(plans["avoid"], title="two-vehicle: the avoidance QP (crossing times, no intrusion)", pyplot=True)
    return plans


if __name__ == "__main__":
    main()
