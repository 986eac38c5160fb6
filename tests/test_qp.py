"""SPEC §3: the discretised QP against the PMP (facts 1–4), OSQP and Clarabel."""

import numpy as np
import pytest

from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp import PMPPlanner, ValueFunction
from iamp.planners.qp import QPPlanner, aligned_grid
from iamp.core.tolerances import tol

PMP = PMPPlanner()
CASES_1 = [paper_problem(1), paper_problem(2), paper_problem(3), random_problem(11, m=1, side=-1),
           random_problem(12, m=1, side=1), two_minima_problem()]
CASES_2 = [random_problem(21, m=2, side=1), random_problem(22, m=2, side=-1)]


def ids(ps):
    return [p.name for p in ps]


def grid_nodes_near(problem, N, frac):
    return [int(round(f * N)) for f in frac]


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
@pytest.mark.parametrize("problem", CASES_1 + CASES_2, ids=ids(CASES_1 + CASES_2))
def test_fact1_foh_equals_pmp_at_grid_times_and_fact3_duals_equal_jumps(problem, solver):
    N = 40
    nodes = grid_nodes_near(problem, N, [0.55, 0.3][: problem.m])
    qp = QPPlanner(steps=N, hold="foh", solver=solver).plan_at_nodes(problem, nodes)
    assert qp.status == "optimal"
    t = np.array(nodes) * problem.tf / N
    pmp = PMP.plan(problem, t)
    rel = tol(f"foh_{solver}_cost_rel")
    assert qp.cost == pytest.approx(pmp.cost, rel=rel)
    tk = np.linspace(0, problem.tf, N + 1)
    assert np.max(np.abs(qp.trajectory.states(tk) - pmp.trajectory.states(tk))) <= tol(f"foh_{solver}_state_abs") * max(1, pmp.cost)
    assert np.max(np.abs(qp.trajectory.inputs(tk) - pmp.trajectory.inputs(tk))) <= tol(f"foh_{solver}_state_abs") * max(1, pmp.cost)
    scale = np.maximum(1.0, np.abs(pmp.jumps))
    assert np.all(np.abs(qp.jumps - pmp.jumps) <= tol(f"dual_{solver}_rel") * scale), (qp.jumps, pmp.jumps)


@pytest.mark.parametrize("problem", CASES_1[:4], ids=ids(CASES_1[:4]))
def test_fact2_zoh_above_pmp_with_second_order_gap(problem):
    frac = 0.5
    gaps = []
    for N in (20, 40, 80, 160):
        k = int(frac * N)
        zoh = QPPlanner(steps=N, hold="zoh", solver="clarabel").plan_at_nodes(problem, [k])
        pmp = PMP.plan(problem, [k * problem.tf / N])
        assert zoh.status == "optimal"
        assert zoh.cost >= pmp.cost - 1e-9 * pmp.cost
        gaps.append(zoh.cost - pmp.cost)
    ratios = np.array(gaps[:-1]) / np.array(gaps[1:])
    assert np.all(ratios > tol("zoh_ratio_low")) and np.all(ratios < tol("zoh_ratio_high")), ratios


@pytest.mark.parametrize("problem", CASES_1, ids=ids(CASES_1))
def test_fact4_foh_sweep_best_is_pmp_restricted_to_grid(problem):
    N = 100
    res = QPPlanner(steps=N, hold="foh", solver="clarabel").plan(problem)
    tk = np.arange(1, N) * problem.tf / N
    J = ValueFunction(problem)(tk[:, None])
    k = int(np.argmin(J))
    assert res.contact_times[0] == pytest.approx(tk[k], abs=1e-12)
    assert res.cost == pytest.approx(J[k], rel=tol("foh_clarabel_cost_rel"))
    # every swept candidate equals the PMP cost at that candidate
    swept = np.array([c for _, c in res.info["sweep"]])
    assert np.allclose(swept, J, rtol=tol("foh_clarabel_cost_rel"))
    # and nu = Phi there
    pmp = PMP.plan(problem, [tk[k]])
    assert np.allclose(res.jumps, pmp.jumps, rtol=tol("dual_clarabel_rel"), atol=tol("dual_clarabel_rel"))


@pytest.mark.parametrize("problem", CASES_1[:3], ids=ids(CASES_1[:3]))
def test_osqp_sweep_within_1e5(problem):
    N = 100
    res = QPPlanner(steps=N, hold="foh", solver="osqp").plan(problem)
    tk = np.arange(1, N) * problem.tf / N
    J = ValueFunction(problem)(tk[:, None])
    assert res.cost == pytest.approx(J.min(), rel=tol("sweep_osqp_cost_rel"))
    assert res.contact_times[0] == pytest.approx(tk[np.argmin(J)], abs=1e-12)


@pytest.mark.parametrize("problem", [CASES_1[0], CASES_1[3], CASES_1[5]], ids=ids([CASES_1[0], CASES_1[3], CASES_1[5]]))
def test_refine_reaches_continuous_optimum(problem):
    res = QPPlanner(steps=60, hold="foh", solver="clarabel", contact="refine").plan(problem)
    pmp = PMP.plan(problem)
    assert res.cost == pytest.approx(pmp.cost, rel=tol("refine_cost_rel"))
    assert res.contact_times[0] == pytest.approx(pmp.contact_times[0], abs=1e-3)


def test_two_vehicle_sweep_covers_every_ordered_pair():
    problem = CASES_2[0]
    N = 12
    res = QPPlanner(steps=N, hold="foh", solver="clarabel").plan(problem)
    nodes = [n for n, _ in res.info["sweep"]]
    assert len(nodes) == (N - 1) * (N - 2)
    assert len(set(nodes)) == len(nodes) and all(a != b for a, b in nodes)
    tk = np.arange(N + 1) * problem.tf / N
    J = np.array([ValueFunction(problem)(tk[list(n)][None, :])[0] for n in nodes])
    assert res.cost == pytest.approx(J.min(), rel=1e-9)


def test_two_vehicle_refine_matches_pmp():
    problem = CASES_2[1]
    res = QPPlanner(steps=16, hold="foh", solver="clarabel", contact="refine").plan(problem)
    pmp = PMP.plan(problem)
    assert res.cost == pytest.approx(pmp.cost, rel=tol("refine_cost_rel"))
    assert np.allclose(res.contact_times, pmp.contact_times, atol=1e-3)


def test_solver_failure_is_a_status_not_a_cost():
    problem = CASES_1[0]
    planner = QPPlanner(steps=40, hold="foh", solver="osqp",
                        solver_settings={"max_iter": 3, "polishing": False, "eps_abs": 1e-12})
    res = planner.plan_at_nodes(problem, [20])
    assert res.status != "optimal"
    assert res.cost is None
    out = res.to_json("x", 40)
    assert out["cost"] is None and out["status"] == res.status


def test_aligned_grid_places_contact_times_on_nodes():
    t_nodes, idx = aligned_grid([3.3, 1.234], 5.0, 50)
    assert len(t_nodes) == 51 and t_nodes[0] == 0 and t_nodes[-1] == 5.0
    assert t_nodes[idx[0]] == 3.3 and t_nodes[idx[1]] == 1.234
    assert np.all(np.diff(t_nodes) > 0)
