"""Issue 32 item 3: the continuous-time avoidance branch and bound prunes only what its bounds prove.

Over generated one-vehicle overtakes (with and without the car's limits), the certified plan of the
search (:class:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner`, its exact node solver, its
relaxations, dual polynomials and skipped candidates) is compared with an independent reference:
the QP at every crossing time of a dense scan, in every half-plane order, each solved by the backend
alone (row generation on Clarabel, no node solver, no bounds).  A pruning that discarded a box
holding a cheaper crossing would leave the plan above the scan's best; a lower bound that is not one
would sit above it.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st_h
from scipy import optimize

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid.check import crossing_orders
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, ContinuousAvoidQP

N = 10
SCAN = 81


def _overtake(xf: float, vxf: float, gap: float, speed: float, limits: bool) -> Problem:
    """The ego changes lane (y -2 -> 3.75) and ends ``gap`` m ahead of a vehicle in the target lane
    (its safety region reaches 7.4 m ahead of it)."""
    x0v = xf - gap - 5.0 * speed
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    p = Problem(ego, (v,), "generated overtake")
    return p.with_limits(PASSENGER_CAR) if limits else p


def _scan(problem: Problem) -> float:
    """The least cost over a dense scan of crossing times and every half-plane order, each QP
    solved by the backend alone, refined by a bounded scalar search within one scan step of the
    scan's best (an upper bound of the global optimum over crossing times, and at it to the
    scalar search's accuracy where the scan found the right basin)."""
    orders, _ = crossing_orders(problem)
    qp = ContinuousAvoidQP(problem, N, "foh", "clarabel", node_solver="backend")

    def cost(f: int, s: int, t: float) -> float:
        r = qp.solve(((f, s, float(t), float(t)),))
        return r.cost if r.status == st.OPTIMAL else np.inf

    times = np.linspace(0.0, problem.tf, SCAN)
    scanned = [(cost(f, s, t), f, s, t) for f, s in orders[0] for t in times[1:-1]]
    best, f, s, t = min(scanned)
    if not np.isfinite(best):
        return best
    step = float(times[1] - times[0])
    with np.errstate(invalid="ignore"):
        res = optimize.minimize_scalar(lambda x: cost(f, s, x), bounds=(max(t - step, 1e-9), min(t + step, problem.tf)),
                                       method="bounded", options={"xatol": 1e-10})
    return float(min(best, res.fun))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.floats(100.0, 130.0), st_h.floats(18.0, 28.0), st_h.floats(7.5, 30.0), st_h.floats(14.0, 22.0),
       st_h.booleans())
@example(118.0, 24.0, 13.0, 20.0, True)  # the binding overtake of tests/test_avoid_continuous.py, with limits
def test_certified_cost_is_no_worse_than_a_dense_scan(xf: float, vxf: float, gap: float, speed: float,
                                                      limits: bool) -> None:
    problem = _overtake(xf, vxf, gap, speed, limits)
    try:
        plan = ContinuousAvoidPlanner(steps=N).plan(problem)
    except ScenarioError:  # the corner does not describe this manoeuvre
        assume(False)
        raise
    assume(plan.status != st.INFEASIBLE)
    ref = _scan(problem)
    assume(np.isfinite(ref))  # some crossing time is feasible on this grid
    assert plan.status == st.OPTIMAL
    search = plan.info["search"]
    assert search["closed"]
    scale = max(1.0, ref)
    gap = search["gap_rel_tol"]
    # its certified lower bound is below every scanned cost (a bound, not a guess) ...
    assert search["lower_bound"] <= ref + 1e-9 * scale
    # ... and within the gap of its plan, whose cost no crossing time beats by more than the gap
    # (the search is global to the gap; the final secant search only lowers the plan's cost)
    assert search["lower_bound"] <= plan.cost + 1e-9 * scale
    assert search["lower_bound"] >= plan.cost - 1.01 * gap * max(1.0, plan.cost)
    # (a box pruned with the global crossing in it would leave the plan more than the gap above)
    assert plan.cost <= ref + gap * scale
    # and the scan, refined, is no cheaper than the certified lower bound allows: the two agree
    assert plan.cost == pytest.approx(ref, rel=gap)


@pytest.mark.parametrize("solver", ["osqp", "clarabel", "piqp"])
def test_every_backend_certifies_the_same_optimum(solver: str) -> None:
    problem = _overtake(118.0, 24.0, 13.0, 20.0, True)
    ref = ContinuousAvoidPlanner(steps=N).plan(problem)
    plan = ContinuousAvoidPlanner(steps=N, solver=solver).plan(problem)
    assert plan.status == ref.status == st.OPTIMAL
    assert plan.cost == pytest.approx(ref.cost, rel=1e-6)
    assert plan.info["backend_check"]["agrees"]


@pytest.mark.parametrize("case", ["one", "three", "generated", "sweep-30007"])
def test_a_box_popped_unchanged_keeps_its_push_bound(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A box popped while the dual store holds the polynomials it held at the box's push takes the
    bound and polynomials of its push (``_Box.store_size``): the search is the same, bit for bit,
    as one that bounds every box again at its pop, with fewer bound evaluations.  (Draw 30007 of
    ``scripts/avoid_reference_sweep.py``: a box popped after a candidate joined the store; taking
    its bound of the push there too, the search solved 13 QPs instead of 12.)"""
    from conftest import load_script

    from iamp.planners import registry
    from iamp.planners.avoid import continuous, dual
    from iamp.planners.examples import overtake_problem, overtake_three_problem

    steps, hold = 50, "foh"
    if case == "sweep-30007":
        problem, steps, hold, _ = load_script("avoid_reference_sweep").case(30007)
    else:
        problem = {"one": overtake_problem(), "three": overtake_three_problem(),
                   "generated": _overtake(112.0, 25.0, 9.0, 21.0, False)}[case]
        steps = N if case == "generated" else steps
    calls = {"n": 0}
    bound = dual.max_lower_bound

    def counted(*args: object) -> float:
        calls["n"] += 1
        return bound(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(continuous, "max_lower_bound", counted)

    def plan() -> tuple[object, ...]:
        calls["n"] = 0
        p = registry.make_planner("qp-avoid", steps=steps, hold=hold, solver="piqp", safety="continuous").plan(problem)
        X = np.asarray(p.trajectory.X) if p.trajectory is not None else np.zeros(0)
        return (p.status, p.cost, np.asarray(p.contact_times).tobytes(), X.tobytes(),
                p.diagnostics.n_solves, p.info["search"]["lower_bound"], p.info["search"]["boxes"]), calls["n"]

    reused, n_reused = plan()
    assert reused[0] == st.OPTIMAL
    # every pop bounds its box again: a store size no box was pushed with
    monkeypatch.setattr(continuous._Box, "store_size", property(lambda self: -1, lambda self, v: None))
    fresh, n_fresh = plan()
    assert reused == fresh
    assert n_reused < n_fresh
