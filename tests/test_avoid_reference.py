"""The continuous-time avoidance plans (``qp-avoid``, ``safety="continuous"``) against an
independent reference (``tests/avoid_reference.py``: its own dynamics, cost, half-planes and
limits, sampled 20 times per step, solved by Clarabel directly).

For each plan, on every backend (OSQP, Clarabel, PIQP):

* (a) the trajectory integrated here from the plan's nodal inputs meets the boundary, matches the
  plan's nodes, stays outside every safety rectangle (50 samples per step) and within the limits;
  the reported cost is ``½∫|u|²`` of those inputs;
* (b) the reference at the plan's own crossing times (a relaxation: sampled safety, exact limits)
  costs no more than the plan; and no crossing time of a scan of each vehicle's (and each order
  it may take) is cheaper in the reference by more than the search's gap plus twice the plan's own
  distance to the reference (the Bernstein rows' conservatism, measured at the plan's crossing);
* (c) ``infeasible`` only where the reference's own branch over crossing-time boxes finds no plan
  that keeps every sampled half-plane by 5 cm;
* (d) the three backends give the same status and cost (1e-6 relative);
* (e) the same call twice, and a fresh planner, give the identical plan.

Found by the sweep (``/tmp`` script over 600 generated problems, see CHANGELOG): a search whose
first candidate was infeasible compared every later relaxation with ``inf - inf = nan`` (no
incumbent, so ``U - gap(U)``) and dropped it, so a problem with a narrow window of feasible
crossing times was called ``infeasible`` (``slow_ahead`` below: FOH with the passenger car's
limits, N = 20, 30, 50).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from avoid_reference import Ref, cost_of, depth, feasible_search, integrate, limit_violation

from iamp.core import status as st
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners import examples as ex
from iamp.planners import registry
from iamp.planners.avoid.check import crossing_orders

SOLVERS = ("clarabel", "osqp", "piqp")
HP = ("H_x", "H_y")
GAP_REL = 1e-4  # the search's documented gap (docs/avoidance.md: closed to 1e-4 max(1, U))
ZOH_CAR = dataclasses.replace(PASSENGER_CAR, jerk=None)  # a jerk bound needs FOH


def slow_ahead(limits: bool = True) -> Problem:
    """A slow vehicle ahead in the ego's lane (``rear-upper``): the crossing must fall in a
    window of about 0.4 s; with the passenger car's limits the first candidate is infeasible."""
    ego = EgoBoundary(tf=5.4, x0=0.0, y0=-2.0, vx0=20.0, xf=116.3, yf=3.75, vxf=24.7)
    v = SurroundingVehicle(x_poly=(22.4, 7.4), corner="rear-upper", y=-2.0, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv2")
    return Problem(ego, (v,), "slow-ahead", limits=PASSENGER_CAR if limits else None)


def _plan(problem: Problem, N: int, hold: str, solver: str):
    return registry.make_planner("qp-avoid", steps=N, hold=hold, solver=solver, safety="continuous")


def _same(a, b) -> bool:
    if a.status != b.status or a.cost != b.cost or (a.trajectory is None) != (b.trajectory is None):
        return False
    return a.trajectory is None or (np.array_equal(a.trajectory.X, b.trajectory.X)
                                    and np.array_equal(a.trajectory.U, b.trajectory.U))


def check_against_reference(problem: Problem, N: int, hold: str, scan: int = 41) -> str:
    """Assert (a)-(e) of the module docstring; returns the plans' status."""
    plans = {}
    for s in SOLVERS:
        planner = _plan(problem, N, hold, s)
        plans[s] = planner.plan(problem)
        if s == "clarabel":  # (e)
            assert _same(planner.plan(problem), plans[s])
            assert _same(_plan(problem, N, hold, s).plan(problem), plans[s])
    # (d)
    statuses = {p.status for p in plans.values()}
    assert len(statuses) == 1, {s: p.status for s, p in plans.items()}
    status = statuses.pop()
    lim = problem.limits is not None
    R = Ref(problem, N, hold, lim)
    h = problem.tf / N
    if status == st.INFEASIBLE:  # (c)
        orders, why = crossing_orders(problem)
        if why is None:
            found, _, exhausted = feasible_search(R, orders, margin=0.05)
            assert found is None and not exhausted, (plans["clarabel"].info.get("reason"), found)
        return status
    assert status in (st.OPTIMAL, st.LOCAL)
    costs = [p.cost for p in plans.values()]
    assert max(costs) - min(costs) <= 1e-6 * max(1.0, min(costs)), costs
    t = np.linspace(0.0, problem.tf, 50 * N + 1)
    for s, p in plans.items():  # (a)
        U = np.asarray(p.trajectory.U)
        X = integrate(problem, U, N, hold, t)
        e = problem.ego
        assert np.abs(X[-1] - [e.xf, e.vxf, e.yf, e.vyf]).max() <= 1e-7 * max(1.0, abs(e.xf)), s
        Xn = integrate(problem, U, N, hold, np.asarray(p.trajectory.t_nodes))
        assert np.abs(Xn - p.trajectory.X).max() <= 1e-8 * (1.0 + np.abs(p.trajectory.X).max()), s
        assert depth(problem, t, X) <= 1e-7, s
        k = np.minimum(np.floor(t / h).astype(int), N - 1)
        r = (t - k * h) / h
        Ut = U[k] * (1 - r)[:, None] + U[np.minimum(k + 1, len(U) - 1)] * r[:, None] if hold == "foh" else U[k]
        assert limit_violation(problem, t, X, Ut, np.diff(U, axis=0) / h if hold == "foh" else None) <= 1e-7, s
        assert cost_of(U, h, hold) == pytest.approx(p.cost, rel=1e-9), s
    # (b)
    plan = plans["clarabel"]
    J = plan.cost
    orders = [(HP.index(v["first"]), HP.index(v["second"])) for v in plan.info["avoidance"]["vehicles"]]
    taus = [float(x) for x in plan.contact_times]
    at, _, _ = R.solve(orders, taus)
    assert at <= J + 1e-7 * max(1.0, J), (at, J)
    conservatism = J - at
    all_orders, _ = crossing_orders(problem)
    grid = np.unique(np.concatenate([np.linspace(0.0, problem.tf, scan),
                                     np.clip(np.array(taus)[:, None] + h * np.arange(-4, 5) / 2, 0.0,
                                             problem.tf).ravel()]))
    best = np.inf
    for iv in range(len(problem.vehicles)):
        for o in all_orders[iv]:
            for tv in grid:
                tt, oo = list(taus), list(orders)
                tt[iv], oo[iv] = float(tv), o
                best = min(best, R.solve(oo, tt)[0])
    slack = GAP_REL * max(1.0, J) + 2.0 * conservatism + 1e-7 * max(1.0, J)
    assert J - best <= slack, (J, best, conservatism)
    return status


# (1) the defect the sweep found: infeasible where a crossing window exists
@pytest.mark.parametrize("N", [20, 30, 50])
def test_a_search_without_an_incumbent_keeps_its_relaxed_boxes(N: int) -> None:
    """The first candidate of ``slow_ahead`` (FOH, limits) is infeasible; the plan must still
    be found (before the fix: ``infeasible``, 3-11 solves) and pass the reference's checks."""
    problem = slow_ahead()
    plan = _plan(problem, N, "foh", "clarabel").plan(problem)
    assert plan.status == st.OPTIMAL, plan.info.get("reason")
    assert plan.info["search"]["closed"]
    # the reference itself finds a plan keeping the half-planes by 5 cm
    found, _, _ = feasible_search(Ref(problem, N, "foh", True), crossing_orders(problem)[0], margin=0.05)
    assert found is not None
    if N == 20:
        assert check_against_reference(problem, N, "foh") == st.OPTIMAL


# (2) a fixed grid, all five checks, under 30 s
GRID = [
    ("overtake", lambda: ex.overtake_problem(), "foh"),
    ("overtake-zoh", lambda: ex.overtake_problem(False).with_limits(ZOH_CAR), "zoh"),
    ("overtake-free", lambda: ex.overtake_problem(False), "foh"),
    ("three", lambda: ex.overtake_three_problem(), "foh"),
    ("three-zoh", lambda: ex.overtake_three_problem(False), "zoh"),
    ("slow-ahead-zoh", lambda: slow_ahead(False).with_limits(ZOH_CAR), "zoh"),
    ("random-660791-m3", lambda: ex.random_problem(660791, m=3).with_limits(PASSENGER_CAR), "foh"),
    ("random-638558-m2", lambda: ex.random_problem(638558, m=2), "foh"),
]


@pytest.mark.parametrize("name,make,hold", GRID, ids=[g[0] for g in GRID])
def test_plans_agree_with_the_independent_reference(name, make, hold) -> None:
    assert check_against_reference(make(), 20, hold, scan=21) in (st.OPTIMAL, st.LOCAL, st.INFEASIBLE)


# (3) the sweep's generators, more of them (slow)
def _generated(i: int) -> tuple[Problem, int, str]:
    rng = np.random.default_rng(7000 + i)
    N = int(rng.choice([20, 30, 50]))
    hold = str(rng.choice(["foh", "zoh"]))
    base = ex.overtake_three_problem(False)
    vs = list(base.vehicles)
    for j, (dx, dv, acc) in enumerate(((8.0, 4.0, 0.4), (10.0, 4.0, 0.0), (10.0, 4.0, 0.0))):
        x0, v0 = vs[j].x_poly[:2]
        poly = (x0 + rng.uniform(-dx, dx), v0 + rng.uniform(-dv, dv))
        vs[j] = dataclasses.replace(vs[j], x_poly=poly + ((rng.uniform(-acc, acc),) if acc else ()))
    m = int(rng.integers(1, 4))
    keep = vs[:m] if rng.random() < 0.7 else [vs[1], vs[0], vs[2]][:m]
    e = base.ego
    p = Problem(dataclasses.replace(e, xf=e.xf + rng.uniform(-10, 10), vxf=e.vxf + rng.uniform(-4, 4),
                                    tf=e.tf + rng.uniform(-0.5, 1.0)), tuple(keep), f"generated-{i}")
    if rng.random() < 0.6:
        p = p.with_limits(PASSENGER_CAR if hold == "foh" else ZOH_CAR)
    return p, N, hold


@pytest.mark.slow
@pytest.mark.parametrize("i", [i for i in range(40) if i != 39])  # 39: its own xfail below (1 min a plan)
def test_generated_plans_agree_with_the_independent_reference(i: int) -> None:
    from iamp.core.errors import ScenarioError

    problem, N, hold = _generated(i)
    try:
        crossing_orders(problem)
    except ScenarioError:
        pytest.skip("the corner does not describe this draw's manoeuvre")
    check_against_reference(problem, N, hold)


# (4) what the sweep found: the two tests below once were strict xfails (the backend decided the
# plan); what is not fixed stays a strict xfail (it fails loudly once fixed)
def _binding(xf: float, vxf: float, x0v: float, speed: float) -> Problem:
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding")


def test_backends_agree_where_the_node_solver_hands_qps_to_the_backend() -> None:
    """A narrow window (J ~ 273, N = 16, FOH): the node solver stopped with ``numerical_error``
    on 35 near-infeasible QPs (a sub-piece at ``t_f`` whose rows the final state fixes, violated
    by 4e-9 m to 5 cm: the Goldfarb-Idnani curvature of such a row is round-off) and handed them to
    the backend, which decided the search (Clarabel: infeasible; PIQP: its iteration limit, then
    2000 solves and no plan; OSQP: ``optimal`` within its 1e-7 tolerance, a cost 4.7e-6 lower).
    Now the node solver proves them infeasible itself (a verified Farkas certificate,
    ``tests/test_avoid_schur.py``), no QP of the search goes to a backend, and the three plans
    are the same plan.  (Not checked against the reference's scan (b): the rows that the final
    state fixes keep every crossing before the last piece infeasible on this coarse grid, J ~ 273
    where the sampled reference costs 26 at t = 4 s; the Bernstein rows are sufficient, not
    necessary.)"""
    problem = _binding(98.25, 18.0, 11.0, 15.9375)
    plans = {s: _plan(problem, 16, "foh", s).plan(problem) for s in SOLVERS}
    assert {p.status for p in plans.values()} == {st.OPTIMAL}, {s: p.status for s, p in plans.items()}
    costs = [p.cost for p in plans.values()]
    assert max(costs) - min(costs) <= 1e-6 * min(costs), costs
    for p in plans.values():
        assert p.info["node_solver"]["backend_solves"] == 1  # the final check only
        assert _same(p, plans["clarabel"])


def test_piqp_backend_check_agrees_on_a_two_vehicle_zoh_plan() -> None:
    """PIQP's re-solve of the final QP (the backend check) passed the KKT check (largest
    complementarity product 7.3e-10 relative) but cost 1.55e-9 relative more than the node
    solver's optimum, beyond ``cmp_cost_rel_clarabel`` (1e-9): the interior point's cost exceeds the
    optimum by its duality gap ``Σ y_i s_i`` (2.0e-8; PIQP stops at ``eps_duality_gap_abs`` 1e-8),
    the sum of products each of which passes.  The check now refines each backend's answer on the
    rows it holds active (:func:`iamp.planners.qp.backends.polish.polish`) and compares that,
    KKT-checked, point: every backend agrees and the plans are the same."""
    base = ex.overtake_three_problem(False)
    ego = dataclasses.replace(base.ego, tf=5.7938562718577655, xf=118.54172148057933, vxf=20.607151079932784)
    sv2 = dataclasses.replace(base.vehicles[1], x_poly=(30.678300872659484, 13.396569739432994))
    sv1 = dataclasses.replace(base.vehicles[0], x_poly=(12.358546887888627, 17.33915842666866, -0.12583986503353872))
    problem = Problem(ego, (sv2, sv1), "two-zoh")
    plans = {s: _plan(problem, 50, "zoh", s).plan(problem) for s in SOLVERS}
    assert {p.status for p in plans.values()} == {st.OPTIMAL}, {s: p.status for s, p in plans.items()}
    for p in plans.values():
        # each backend's answer refined on the rows it holds active is the node solver's optimum
        check = p.info["backend_check"]
        assert check["agrees"]
        # refined where the backend's own answer missed the comparison tolerance (PIQP's duality
        # gap); then the refined point is the node solver's optimum
        tol_cost = check["cost_tol_rel"]
        assert check["polished"] == (abs(check.get("backend_cost", check["cost"]) - p.cost) > tol_cost * p.cost
                                     or max(check.get("backend_kkt", check["kkt"]).values()) > p.info["kkt_tol"])
        assert abs(check["cost"] - p.cost) <= (1e-12 if check["polished"] else tol_cost) * p.cost
        assert _same(p, plans["clarabel"])


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="boxes bounded by the dual polynomials alone are split without a QP: "
                   "generated problem 39 (three vehicles, ZOH, N = 50) popped 446,689 boxes for 212 QP solves "
                   "(~1 min CPU) before max_boxes, the bounds of boxes narrowed to 1e-5 s hovering just below "
                   "U - gap; now it stops at max_boxes (20 000) with its incumbent, local, not optimal")
def test_the_search_splits_boxes_in_proportion_to_its_solves() -> None:
    problem, N, hold = _generated(39)
    plan = _plan(problem, N, hold, "clarabel").plan(problem)
    assert plan.status == st.OPTIMAL
    s = plan.info["search"]
    assert s["boxes"] <= 50 * s["n_solves"], (s["boxes"], s["n_solves"])


def test_the_box_budget_stops_the_search_with_its_incumbent() -> None:
    """``max_boxes`` counts the boxes the branch and bound creates (SPEC §17: a budget counts work):
    generated problem 39 (its bounds hover below ``U - gap`` on ever narrower boxes, xfail above)
    stops at a small box budget with ``local``, the same incumbent as with a larger one and no
    cheaper than the search's own lower bound; the boxes of the bench overtakes stay far below the
    default budget, so their plans are unchanged by it."""
    from iamp.planners.avoid.planner import AvoidQPPlanner

    problem, N, hold = _generated(39)
    plans = [AvoidQPPlanner(steps=N, hold=hold, solver="clarabel", max_boxes=b).plan(problem) for b in (300, 1200)]
    for plan, budget in zip(plans, (300, 1200)):
        s = plan.info["search"]
        assert plan.status == st.LOCAL and not s["closed"] and s["max_boxes"] == budget
        assert budget <= s["boxes"] <= budget + 2 * 3  # a box popped before the limit adds at most its children
        assert s["lower_bound"] <= plan.cost
    assert plans[1].cost <= plans[0].cost
    for prob in (ex.overtake_problem(), ex.overtake_three_problem()):
        plan = AvoidQPPlanner(steps=50, hold="foh", solver="clarabel").plan(prob)
        assert plan.status == st.OPTIMAL and plan.info["search"]["boxes"] < 200
