"""The paper's scenarios under a passenger car's limits with the bounded PMP (docs/bounded-pmp.md).

    PYTHONPATH=. python scripts/bounded_pmp_paper.py

One row per built-in scenario and limits table: ``PASSENGER_CAR`` (iamp.core.physical: ax
[-6, 3], ay [-2, 2], a_total 8, vx [0, 40], jerk 5) and its input box alone (ax, ay): the
status, the cost, the contact times, the exact peaks of the plan (or the reason it has none),
beside the unbounded plan's cost and peaks.
"""

from __future__ import annotations

from iamp.api import load_scenario
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.scenario import builtin_names
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import exact_peaks, plan_knots


def _peaks(plan) -> str:  # type: ignore[no-untyped-def]
    p = getattr(plan.diagnostics, "peaks", None) or exact_peaks(plan.trajectory, plan.problem.tf, plan_knots(plan))
    return (f"ax [{p['ax'][0]:.2f}, {p['ax'][1]:.2f}], ay [{p['ay'][0]:.2f}, {p['ay'][1]:.2f}], "
            f"|u| {p['a_total']:.2f}, vx [{p['vx'][0]:.1f}, {p['vx'][1]:.1f}], jerk {p['jerk']:.1f}")


def main() -> None:
    box = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)
    planner = PMPPlanner()
    print("| scenario | limits | status | J | t_i [s] | peaks / reason | unbounded J, peaks |")
    print("|---|---|---|---|---|---|---|")
    for name in builtin_names():
        base = load_scenario(name)
        free = planner.plan(base)
        for label, lim in (("PASSENGER_CAR", PASSENGER_CAR), ("box ax, ay", box)):
            plan = planner.plan(base.with_limits(lim))
            cost = f"{plan.cost:.3f}" if plan.cost is not None else "-"
            times = ", ".join(f"{t:.4f}" for t in plan.contact_times) if plan.trajectory is not None else "-"
            what = _peaks(plan) if plan.trajectory is not None else ""
            if plan.diagnostics.reason:
                what += (" — " if what else "") + plan.diagnostics.reason
            print(f"| {name} | {label} | {plan.status} | {cost} | {times} | {what} | "
                  f"{free.cost:.3f}: {_peaks(free)} |")


if __name__ == "__main__":
    main()
