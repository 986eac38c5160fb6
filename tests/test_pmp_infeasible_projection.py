"""A cheaper certified infeasibility of the bounded PMP with several vehicles (issue 32): if one
vehicle alone admits no plan within the input box at any contact time, no plan for all the
vehicles exists (the projection argument of
:func:`iamp.planners.pmp.bounded.infeasibility_certificate`).  The bench's three-vehicle case
was only "infeasible at the evaluated times" after more than 4000 axis solves; it is now
certified by one vehicle's 32-interval cover.  Checked independently by solving the
fixed-time problem at sampled contact times."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.planners.examples import random_problem
from iamp.planners.pmp.bounded import infeasibility_certificate, solve_bounded_fixed
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.pmp.saturated import AxisInfeasible, AxisNoConvergence

BOX = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)


def _infeasible_at(problem, t) -> bool:  # type: ignore[no-untyped-def]
    try:
        solve_bounded_fixed(problem, t)
    except AxisInfeasible:
        return True
    except AxisNoConvergence:
        return False
    return False


def test_the_bench_three_vehicle_case_is_certified_by_one_vehicle_alone() -> None:
    problem = random_problem(0, m=3).with_limits(BOX)
    plan = PMPPlanner(diagnostics=False).plan(problem)
    assert plan.status == "infeasible"
    assert plan.diagnostics.failed_check == "box_infeasible_at_every_contact_time"
    search = plan.diagnostics.search
    assert search["infeasibility_vehicle"] in (0, 1, 2) and search["infeasibility_solves"] <= 400
    # independent: the fixed-time problem is infeasible at sampled contact times, for the
    # certifying vehicle alone and for all three
    alone = problem.with_vehicles([problem.vehicles[search["infeasibility_vehicle"]]])
    rng = np.random.default_rng(0)
    T = problem.tf
    assert all(_infeasible_at(alone, [t]) for t in rng.uniform(0.01 * T, 0.99 * T, 40))
    assert all(_infeasible_at(problem, t) for t in rng.uniform(0.01 * T, 0.99 * T, (40, 3)))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 400), m=st.sampled_from([2, 3]), scale=st.sampled_from([0.3, 0.6, 1.0]))
def test_a_certificate_is_sound_and_a_feasible_time_is_feasible(seed: int, m: int, scale: float) -> None:
    """Whatever the certificate says is checked at the fixed-time problem: certified → every
    sampled choice of contact times is infeasible; a feasible ``t`` → solvable there."""
    box = PhysicalLimits(ax=(PASSENGER_CAR.ax[0] * scale, PASSENGER_CAR.ax[1] * scale),
                         ay=(PASSENGER_CAR.ay[0] * scale, PASSENGER_CAR.ay[1] * scale))
    problem = random_problem(seed, m=m).with_limits(box)
    cert = infeasibility_certificate(problem, max_solves=600)
    T = problem.tf
    if cert.certified:
        rng = np.random.default_rng(seed)
        assert all(_infeasible_at(problem, t) for t in rng.uniform(0.01 * T, 0.99 * T, (20, m)))
        if cert.vehicle is not None:
            alone = problem.with_vehicles([problem.vehicles[cert.vehicle]])
            assert all(_infeasible_at(alone, [t]) for t in np.linspace(0.01 * T, 0.99 * T, 25))
    elif cert.feasible_t is not None:
        solve_bounded_fixed(problem, cert.feasible_t)  # raises if not


@pytest.mark.parametrize("budget", [40, 4000])
def test_the_budget_counts_solves(budget: int) -> None:
    """The work budget is a count of axis solves, the projection's included: the same count
    and verdict on every run; a cover stops refining once its share is spent (its 32 initial
    intervals are always solved, two axes each)."""
    problem = random_problem(0, m=3).with_limits(BOX)
    cert = infeasibility_certificate(problem, max_solves=budget)
    assert cert == infeasibility_certificate(problem, max_solves=budget)
    assert cert.certified and cert.vehicle is not None
    assert cert.solves <= budget + 3 * 2 * 32
