"""The avoidance planner forgets its half-planes' rows on request (what ``iamp bench`` does before
each timed plan, so that it times a new problem on a known grid, not a repeat)."""

from __future__ import annotations

import numpy as np

from iamp.comparison.bench import limits as bench_limits
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.examples import overtake_problem


def test_forget_vehicles_drops_rows_and_keeps_the_plan() -> None:
    planner = AvoidQPPlanner(steps=20, hold="foh", solver="clarabel")
    prob = overtake_problem()
    first = planner.plan(prob)
    layouts = planner._shared.values("layout")
    assert len(layouts) == 1 and layouts[0].split_vals  # the plan split pieces at its box ends
    assert planner.forget_vehicles() == 2 * len(prob.vehicles)  # one entry per half-plane
    assert not layouts[0].split_vals  # a new problem's crossing times are others: not timed as hits
    assert planner.forget_vehicles() == 0
    second = planner.plan(prob)  # built again from the problem: the same plan
    assert str(first.status) == str(second.status) == "optimal"
    assert first.cost == second.cost
    np.testing.assert_array_equal(first.trajectory.X, second.trajectory.X)
    np.testing.assert_array_equal(first.contact_times, second.contact_times)
    # the grid's factorisation is kept
    assert planner._shared.forget("schur") == 1


def test_bench_calls_before_ahead_of_every_timed_call() -> None:
    calls: list[str] = []

    def fn() -> str:
        calls.append("plan")
        return "p"

    def before() -> None:
        calls.append("forget")

    _, cpus, plans = bench_limits._timed(fn, 3, 1e9, before)  # type: ignore[arg-type]
    assert len(cpus) == 3 and len(plans) == 3
    assert calls == ["forget", "plan"] * 4  # the warm-up and three timed calls
