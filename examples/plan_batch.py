"""
Plan many lane changes at once
==============================

Plan many one-vehicle lane changes at once (vectorised PMP) and check one against a single plan.

Run: ``python examples/plan_batch.py``
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

import iamp
from iamp.planners.pmp import BatchPlan, plan_batch


def problems(n: int = 200) -> list[iamp.Problem]:
    """Paper scenario 1 with the other vehicle's speed swept from 14 to 22 m/s."""
    base = iamp.load_scenario("paper-1-poly")
    (v,) = base.vehicles
    return [base.with_vehicles([replace(v, x_poly=(v.x_poly[0], speed, 0.0, 0.0))]) for speed in np.linspace(14, 22, n)]


def main() -> tuple[list[iamp.Problem], BatchPlan]:
    probs = problems()
    batch = plan_batch(probs)
    print(f"{len(probs)} plans: statuses {sorted(set(batch.status))}, "
          f"cost from {batch.cost.min():.3f} to {batch.cost.max():.3f}")
    single = iamp.plan(probs[0])
    print(f"first problem: batch J = {batch.cost[0]:.9f}, single plan J = {single.cost:.9f}")
    return probs, batch


if __name__ == "__main__":
    main()
