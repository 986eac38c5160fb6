"""SPEC §3: the discretised QP against the PMP (facts 1–4), OSQP and Clarabel."""

import numpy as np
import pytest

from iamp.core.tolerances import tol
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp.planner import PMPPlanner, ValueFunction
from iamp.planners.qp.planner import QPPlanner, aligned_grid

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
    lim = tol(f"foh_{solver}_state_abs") * max(1, pmp.cost)
    assert np.max(np.abs(qp.trajectory.states(tk) - pmp.trajectory.states(tk))) <= lim
    assert np.max(np.abs(qp.trajectory.inputs(tk) - pmp.trajectory.inputs(tk))) <= lim
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


# --------------------------------------------------------------------------------------
# a sweep certifies its best (issue 9.3): failed candidates that could beat it
# --------------------------------------------------------------------------------------


def _fail_on(qp, bad_nodes, make_failure):
    """Make the candidates ``bad_nodes`` of the sweep fail as ``make_failure(data)`` says."""
    d = qp.data
    orig = qp.backend.solve

    def solve():
        return make_failure(d) if d.nodes in bad_nodes else orig()

    qp.backend.solve = solve


def _piqp_limited(d):
    from iamp.planners.qp.backends import get_backend

    return get_backend("piqp")(d.P, d.q, d.A, d.b, d.b, {"max_iter": 1}).solve()


def _clarabel_time_limit(d):
    # Clarabel solves this equality QP at its initial point (0 iterations), so no real time or
    # iteration limit makes it fail; the outcome is injected as Clarabel reports a MaxTime stop:
    # status TIME_LIMIT with a non-converged iterate.
    from dataclasses import replace

    from iamp.planners.qp.backends import get_backend

    sol = get_backend("clarabel")(d.P, d.q, d.A, d.b, d.b).solve()
    return replace(sol, status="time_limit_reached", raw_status="MaxTime", z=sol.z * 0.9, y=sol.y * 0.5)


@pytest.mark.parametrize("solver, failure", [("clarabel", _clarabel_time_limit), ("piqp", _piqp_limited)])
def test_failed_candidates_that_could_beat_the_best_make_the_sweep_not_optimal(solver, failure):
    problem = paper_problem(1)
    N = 40
    tk = np.arange(1, N) * problem.tf / N
    J = ValueFunction(problem)(tk[:, None])
    k_best = int(np.argmin(J)) + 1
    planner = QPPlanner(steps=N, hold="foh", solver=solver)
    qp = planner.build(problem)
    bad = {(k,) for k in range(k_best - 2, k_best + 3)}  # the true best and its neighbours
    _fail_on(qp, bad, failure)
    res = planner.plan(problem, qp=qp)
    assert res.status != "optimal" and res.cost is None
    assert res.info["failed_check"] == "sweep_candidates" and "could beat" in res.info["why"]
    c = res.info["candidates"]
    assert c["total"] == N - 1 and c["solved"] == N - 1 - len(bad)
    assert sum(c["failed"].values()) + c["inaccurate"] == len(bad)
    assert {tuple(x["nodes"]) for x in res.info["could_beat"]} <= bad
    # the bound is the PMP cost at the failed node (exact for FOH)
    lb = {tuple(x["nodes"]): x["lower_bound"] for x in res.info["could_beat"]}
    assert lb[(k_best,)] == pytest.approx(J[k_best - 1], rel=1e-12)
    out = res.to_json("x", N)
    assert out["status"] != "optimal" and out["cost"] is None


def test_failed_candidates_that_cannot_beat_the_best_leave_it_optimal():
    problem = paper_problem(1)
    N = 40
    tk = np.arange(1, N) * problem.tf / N
    J = ValueFunction(problem)(tk[:, None])
    worst = {(int(k) + 1,) for k in np.argsort(J)[-5:]}  # the five most expensive nodes
    planner = QPPlanner(steps=N, hold="foh", solver="clarabel")
    qp = planner.build(problem)
    _fail_on(qp, worst, _clarabel_time_limit)
    res = planner.plan(problem, qp=qp)
    assert res.status == "optimal"
    assert res.cost == pytest.approx(J.min(), rel=tol("foh_clarabel_cost_rel"))
    assert res.info["candidates"] == {"total": N - 1, "solved": N - 6, "failed": {"time_limit_reached": 5},
                                      "inaccurate": 0}
    assert res.info["checks"]["sweep_candidates"]["ok"] and res.info["failed_check"] is None


def test_zoh_failures_are_bounded_by_the_pmp_cost():
    """ZOH: the PMP cost at the same node is a lower bound (fact 2), so a failed node whose
    bound lies above the best cannot beat it."""
    problem = paper_problem(2)
    N = 30
    planner = QPPlanner(steps=N, hold="zoh", solver="kkt")
    full = planner.plan(problem)
    k_best = full.info["grid_best"]["contact_times"][0] * N / problem.tf
    far = {(1,), (2,), (N - 1,)}
    assert round(k_best) not in {1, 2, N - 1}
    qp = planner.build(problem)
    _fail_on(qp, far, _clarabel_time_limit)
    res = planner.plan(problem, qp=qp)
    assert res.status == "optimal" and res.cost == pytest.approx(full.cost, rel=1e-12)


@pytest.mark.parametrize("solver", ["kkt", "piqp"])
def test_new_backends_sweep_to_the_grid_restricted_pmp(solver):
    problem = CASES_1[5]
    N = 60
    res = QPPlanner(steps=N, hold="foh", solver=solver).plan(problem)
    tk = np.arange(1, N) * problem.tf / N
    J = ValueFunction(problem)(tk[:, None])
    assert res.status == "optimal"
    assert res.cost == pytest.approx(J.min(), rel=1e-9)
    assert res.contact_times[0] == pytest.approx(tk[np.argmin(J)], abs=1e-12)
    swept = np.array([c for _, c in res.info["sweep"]])
    assert np.allclose(swept, J, rtol=1e-9)
    assert res.info["candidates"] == {"total": N - 1, "solved": N - 1, "failed": {}, "inaccurate": 0}


@pytest.mark.parametrize("name", [1, 3])
def test_refine_is_optimal_only_when_the_pmp_certifies_its_contact_times_global(name):
    """Issue 19 item 6: FOH refine is ``optimal`` only when its cost reaches the PMP's certified
    global J* (FOH is exact, so J_QP(t) = J(t) >= J*); ZOH refine is ``local``."""
    prob = paper_problem(name)
    pmp = PMPPlanner().plan(prob)
    foh = QPPlanner(hold="foh", steps=40, contact="refine").plan(prob)
    cert = foh.info["refine_certificate"]
    assert cert["pmp_cost"] == pytest.approx(pmp.cost, rel=1e-12)
    assert cert["global"] == (foh.cost <= pmp.cost * (1 + cert["tol_rel"]) + cert["tol_rel"])
    assert (foh.status == "optimal") == cert["global"]
    assert foh.cost >= pmp.cost * (1 - 1e-9)
    zoh = QPPlanner(hold="zoh", steps=40, contact="refine").plan(prob)
    assert zoh.status == "local" and not zoh.info["refine_certificate"]["global"]
