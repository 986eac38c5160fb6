"""SPEC §10: the avoidance QP — safe at the nodes, OSQP = Clarabel, a global crossing time,
between-node intrusion falling with N, KKT conditions recomputed here, infeasible and refused
scenarios."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest
import scipy.sparse as sp

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.tolerances import tol
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.examples import builtin_problem, paper_problem
from iamp.planners.pmp.planner import PMPPlanner


def binding_problem(xf: float = 118.0, vxf: float = 24.0) -> Problem:
    """The ego overtakes a faster vehicle in the target lane: the free optimum would cut
    through its safety box, so the inequalities bind (at the corner)."""
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(5.0, 20.0), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding")


def node_depth(plan) -> float:
    """Largest depth of the ego's point inside any safety region, at the grid nodes."""
    t = plan.trajectory.t_nodes
    X = plan.trajectory.states(t)
    worst = -np.inf
    for v in plan.problem.vehicles:
        dx, dy = X[:, 0] - v.position(t), X[:, 2] - v.y
        depth = np.minimum(v.length / 2 + v.safety_x - np.abs(dx), v.width / 2 + v.safety_y - np.abs(dy))
        worst = max(worst, float(depth.max()))
    return worst


@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("problem", [binding_problem(), paper_problem(1), paper_problem(3)],
                         ids=["binding", "p1", "p3"])
def test_safe_at_nodes_and_osqp_agrees_with_clarabel(problem, hold):
    c = AvoidQPPlanner(safety="nodes", steps=40, hold=hold, solver="clarabel").plan(problem)
    o = AvoidQPPlanner(safety="nodes", steps=40, hold=hold, solver="osqp").plan(problem)
    # node-only safety: optimal when the plan is intrusion-free between nodes too, else unsafe (SPEC §14)
    for p in (c, o):
        assert p.status == (st.OPTIMAL if p.safety.intrusion_free else st.UNSAFE)
    assert o.cost == pytest.approx(c.cost, rel=1e-6)
    assert node_depth(c) <= 1e-6 and node_depth(o) <= 1e-6
    assert c.boundary_residual() < 1e-8


def test_binding_case_active_set_multipliers_and_cost_of_safety():
    plan = AvoidQPPlanner(safety="nodes", steps=40).plan(binding_problem())
    v = plan.info["avoidance"]["vehicles"][0]
    # the corner binds: H_y at the last node before the crossing, H_x at the first after it
    assert v["active_H_y"]["nodes"] and v["active_H_x"]["nodes"]
    assert max(v["active_H_y"]["nodes"]) < min(v["active_H_x"]["nodes"])
    assert all(y > 0 for y in v["active_H_x"]["multipliers"] + v["active_H_y"]["multipliers"])
    # a binding inequality costs something: above the free optimum (all rows relaxed)
    free = AvoidQPPlanner(safety="nodes", steps=40)._solve
    from iamp.planners.avoid.data import AvoidData

    data = AvoidData(plan.problem, np.linspace(0, 5, 41), "foh")
    backend = AvoidQPPlanner(safety="nodes", steps=40)._backend(data, data.imposed([]))
    assert plan.cost > free(data, backend, []).cost + 1e-3


def test_kkt_conditions_recomputed_independently():
    for solver in ("clarabel", "osqp"):
        plan = AvoidQPPlanner(safety="nodes", steps=30, solver=solver).plan(binding_problem())
        q = plan.info["qp_solution"]
        P = sp.csc_matrix(q.data.P)
        P = (P + sp.triu(P, 1).T).toarray()  # the whole symmetric Hessian
        A = q.data.A.toarray()
        z, y, n_eq = q.z, q.y, q.data.n_eq
        Az = A @ z
        scale = max(1.0, np.abs(P @ z).max())
        limit = tol(f"cmp_kkt_rel_{solver}")
        assert np.abs(P @ z + A.T @ y).max() / scale <= limit  # stationarity
        assert np.abs(Az[:n_eq] - q.l[:n_eq]).max() <= limit * max(1.0, np.abs(q.l[:n_eq]).max())  # equalities
        slack = q.u[n_eq:] - Az[n_eq:]
        assert slack.min() >= -limit * max(1.0, np.abs(q.u).max())  # inequalities
        assert y[n_eq:].min() >= -limit * max(1.0, np.abs(y).max())  # dual sign (upper bounds only)
        assert np.max(np.abs(y[n_eq:] * slack)) <= limit * max(1.0, z @ P @ z)  # complementarity
        assert 0.5 * z @ P @ z == pytest.approx(plan.cost, rel=1e-12)


def test_matches_an_independent_cvxpy_model_at_the_chosen_switch():
    """The same QP written from SPEC §3/§10 directly in cvxpy (FOH), at the plan's switch."""
    prob, N = binding_problem(), 30
    plan = AvoidQPPlanner(safety="nodes", steps=N).plan(prob)
    j = plan.info["grid_best"]["switch_nodes"][0]
    v = prob.vehicles[0]
    t = np.linspace(0, prob.tf, N + 1)
    h = prob.tf / N
    s = [cp.Variable(N + 1) for _ in range(2)]
    vel = [cp.Variable(N + 1) for _ in range(2)]
    u = [cp.Variable(N + 1) for _ in range(2)]
    e = prob.ego
    cons = []
    for a, (s0, v0, sf, vf) in enumerate(((e.x0, e.vx0, e.xf, e.vxf), (e.y0, e.vy0, e.yf, e.vyf))):
        cons += [s[a][1:] == s[a][:-1] + h * vel[a][:-1] + h**2 * (u[a][:-1] / 3 + u[a][1:] / 6),
                 vel[a][1:] == vel[a][:-1] + h / 2 * (u[a][:-1] + u[a][1:]),
                 s[a][0] == s0, vel[a][0] == v0, s[a][N] == sf, vel[a][N] == vf]
    ay = v.width / 2 + v.safety_y
    ax = v.length / 2 + v.safety_x
    k1, k2 = np.arange(1, j + 1), np.arange(j + 1, N)
    if k1.size:
        cons.append(s[1][k1] <= v.y - ay)  # H_y (lower) first
    cons.append(s[0][k2] >= v.position(t[k2]) + ax)  # then H_x (front)
    # FOH cost (h/6)(u_k² + u_k u_k+1 + u_k+1²) as the equivalent DCP sum of squares
    cost = sum(h / 8 * cp.sum_squares(u[a][:-1] + u[a][1:]) + h / 24 * cp.sum_squares(u[a][:-1] - u[a][1:])
               for a in range(2))
    val = cp.Problem(cp.Minimize(cost), cons).solve(solver="CLARABEL")
    assert val == pytest.approx(plan.cost, rel=1e-7)


def test_crossing_time_is_the_global_minimiser_over_a_dense_grid():
    prob = binding_problem()
    planner = AvoidQPPlanner(safety="nodes", steps=30, contact="refine")
    plan = planner.plan(prob)
    assert plan.status == st.OPTIMAL
    costs = []
    for tau in np.linspace(0.05, 4.95, 99):
        p = planner.plan_at_times(prob, [tau])
        if p.ok:
            costs.append(p.cost)
    assert plan.cost <= min(costs) * (1 + 1e-9)
    # and the grid sweep's best is the minimum of its own table
    g = AvoidQPPlanner(safety="nodes", steps=30).plan(prob)
    assert g.cost == pytest.approx(min(c for _, c in g.info["sweep"]), rel=1e-12)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_pruned_sweep_equals_the_full_sweep(hold):
    prob = binding_problem()
    pruned = AvoidQPPlanner(safety="nodes", steps=40, hold=hold).plan(prob)
    full = AvoidQPPlanner(safety="nodes", steps=40, hold=hold, prune=False).plan(prob)
    assert pruned.info["pruned"] and pruned.info["n_solves"] < full.info["n_solves"]
    assert pruned.cost == pytest.approx(full.cost, rel=1e-12)
    assert pruned.info["grid_best"]["switch_nodes"] == full.info["grid_best"]["switch_nodes"]


def test_between_node_intrusion_falls_with_n():
    prob = binding_problem()
    worst = [AvoidQPPlanner(safety="nodes", steps=N).plan(prob).info["avoidance"]["vehicles"][0]
             ["between_node_intrusion_m"] for N in (20, 40, 80)]
    assert worst[0] > worst[1] > worst[2] > 0
    assert worst[2] < 0.35 * worst[0]  # O(h): about halves per halving of h (measured 0.285, 0.149, 0.076 m)


def test_free_optimum_is_certified_and_coincides_when_no_inequality_binds():
    """Paper 1: the unconstrained optimum is safe, so the avoidance optimum is that optimum
    (J = 12.387 = 10.8 + 1.587 exactly: 6 d²/t_f³ per axis), far below the equality's 22.87."""
    plan = AvoidQPPlanner(safety="nodes", steps=100).plan(paper_problem(1))
    e = plan.problem.ego
    free = 6 * ((e.xf - e.x0 - e.vx0 * e.tf) ** 2 + (e.yf - e.y0) ** 2) / e.tf**3
    assert plan.cost == pytest.approx(free, rel=1e-9)
    assert plan.info["certificate"]
    assert plan.cost < PMPPlanner().plan(paper_problem(1)).cost
    assert plan.safety is not None and plan.safety.safe


def test_end_inside_a_safety_region_is_infeasible_with_the_reason():
    plan = AvoidQPPlanner(safety="nodes", steps=20).plan(paper_problem(2))
    assert plan.status == st.INFEASIBLE and plan.cost is None
    assert "final state" in plan.info["reason"] and "inside" in plan.info["reason"]
    assert plan.to_json()["reason"] == plan.info["reason"]


def test_corner_that_does_not_describe_the_manoeuvre_is_refused():
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=85.0, yf=3.75, vxf=20.0)
    # vehicle ahead of the ego in the target lane at t = 0, ending far ahead: the ego starts in
    # H_y only and ends in neither half-plane of front-lower, outside the region
    v = SurroundingVehicle(x_poly=(20.0, 30.0), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="ahead")
    with pytest.raises(ScenarioError, match="ahead"):
        AvoidQPPlanner(safety="nodes", steps=20).plan(Problem(ego, (v,), "bad"))


def test_two_vehicles_sweep_every_combination():
    prob = builtin_problem("two-vehicle")
    plan = AvoidQPPlanner(safety="nodes", steps=12, max_combinations=10**6).plan(prob)
    assert plan.status == st.OPTIMAL
    assert node_depth(plan) <= 1e-6
    assert len(plan.contact_times) == 2


from hypothesis import HealthCheck, assume, given, settings  # noqa: E402
from hypothesis import strategies as st_h  # noqa: E402


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.floats(-20.0, 15.0), st_h.floats(12.0, 26.0), st_h.floats(60.0, 130.0), st_h.floats(15.0, 26.0),
       st_h.sampled_from(["foh", "zoh"]))
def test_random_problems_safe_at_nodes_and_solvers_agree(x0v, speed, xf, vxf, hold):
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    prob = Problem(ego, (v,), "random")
    try:
        c = AvoidQPPlanner(safety="nodes", steps=20, hold=hold).plan(prob)
    except ScenarioError:
        assume(False)
    if c.status == st.INFEASIBLE:  # then the start or the end really is inside the region
        inside = [abs(x - float(v.position(t))) < 7.4 and abs(y - 3.75) < 1.4
                  for t, x, y in ((0.0, 0.0, -2.0), (5.0, xf, 3.75))]
        assert any(inside) and "inside" in c.info["reason"]
        return
    assert c.status == (st.OPTIMAL if c.safety.intrusion_free else st.UNSAFE)
    o = AvoidQPPlanner(safety="nodes", steps=20, hold=hold, solver="osqp").plan(prob)
    assert o.status == (st.OPTIMAL if o.safety.intrusion_free else st.UNSAFE)
    assert o.cost == pytest.approx(c.cost, rel=1e-6)
    assert node_depth(c) <= 1e-6
    # the free optimum bounds every safe plan from below: per axis, with e1 = s_f − s_0 − v_0 T and
    # e2 = v_f − v_0, min ½∫u² = (6 e1² − 6 T e1 e2 + 2 T² e2²)/T³ (FOH reproduces it exactly)
    e, T = prob.ego, prob.tf
    free = sum((6 * e1**2 - 6 * T * e1 * e2 + 2 * T**2 * e2**2) / T**3
               for e1, e2 in ((e.xf - e.x0 - e.vx0 * T, e.vxf - e.vx0), (e.yf - e.y0 - e.vy0 * T, e.vyf - e.vy0)))
    if hold == "foh":
        assert c.cost >= free * (1 - 1e-9)


def test_many_vehicles_beyond_the_full_sweep_are_local():
    prob = builtin_problem("two-vehicle")
    v1, v2 = prob.vehicles
    # sv2 made faster so that the free optimum is not safe: no certificate, a real search
    fast = SurroundingVehicle((30.0, 17.0), v2.corner, v2.y, v2.length, v2.width, v2.safety_x, v2.safety_y, v2.name)
    p = prob.with_vehicles([v1, fast])
    plan = AvoidQPPlanner(safety="nodes", steps=16, max_combinations=50, coarse=5).plan(p)
    assert plan.status in (st.LOCAL, st.OPTIMAL)
    if plan.info["certificate"] is None:
        assert plan.status == st.LOCAL and not plan.info["complete_sweep"]
    assert node_depth(plan) <= 1e-6


def test_pmp_side_avoidance_agrees_with_the_qp():
    """Stretch: the continuous-time avoidance candidates (free optimum; one touch per vehicle
    at the corner = the equality plan when its jumps have the inequality multipliers' sign)
    against the avoidance QP's global sweep refined off the grid (FOH is exact)."""
    from iamp.planners.avoid.pmp import PMPAvoidPlanner

    for prob in (binding_problem(), paper_problem(1), builtin_problem("two-vehicle")):
        pmp = PMPAvoidPlanner().plan(prob)
        qp = AvoidQPPlanner(safety="nodes", steps=40, contact="refine").plan(prob)
        assert pmp.status in (st.OPTIMAL, st.LOCAL) and qp.status == st.OPTIMAL
        assert pmp.cost == pytest.approx(qp.cost, rel=1e-9)
        assert np.allclose(pmp.contact_times, qp.contact_times, atol=1e-5)
    touch = PMPAvoidPlanner().plan(binding_problem())
    assert touch.status == st.LOCAL and touch.info["touches"].startswith("one")
    assert touch.jumps[0, 0] < 0 < touch.jumps[0, 1]  # front: σ_x = −1; lower: σ_y = +1
    assert PMPAvoidPlanner().plan(paper_problem(2)).status == st.INFEASIBLE
