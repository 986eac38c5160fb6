"""The native OSQP/Clarabel QP path (planners/native.py) against the cvxpy path and the PMP.

No timing assertions: speed is measured by ``iamp bench``.
"""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from iamp.planners.examples import paper_problem, random_problem
from iamp.planners.native import (NATIVE_BACKENDS, NativeQPPlanner, QPData, build_native, kkt_residuals,
                                  native_sweep)
from iamp.planners.pmp import PMPPlanner, ValueFunction
from iamp.planners.qp import QPPlanner

N = 24
CASES = [paper_problem(1), random_problem(11, m=1, side=-1), random_problem(21, m=2, side=1)]
NATIVE_TOL = {"clarabel": 1e-9, "osqp": 1e-6}
LOOSE_OSQP = {"eps_abs": 1e-2, "eps_rel": 1e-2, "polishing": False, "max_iter": 200}


def _nodes(problem, n=N):
    return [int(0.55 * n), int(0.3 * n)][: problem.m]


def _cvxpy(problem, hold, solver, nodes, n=N):
    qp = QPPlanner(steps=n, hold=hold, solver=solver).build(problem)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return qp, qp.solve_nodes(nodes)


def test_registry_has_one_backend_per_solver_with_one_signature():
    assert set(NATIVE_BACKENDS) == {"osqp", "clarabel"}
    p = CASES[0]
    for name, cls in NATIVE_BACKENDS.items():
        qp = cls(p, 12, "foh", None)
        assert qp.name == name
        r = qp.solve_nodes([6])
        assert r["status"] == "optimal"
        assert set(r) >= {"status", "cost", "nodes", "polished", "solver_time_s", "wall_time_s", "trajectory",
                          "multipliers", "contact_times", "z", "y"}
    with pytest.raises(ValueError):
        build_native(p, 12, "foh", "gurobi")


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("problem", CASES, ids=[p.name for p in CASES])
def test_native_equals_cvxpy(problem, hold, solver):
    nodes = _nodes(problem)
    nq = build_native(problem, N, hold, solver)
    qp, c = _cvxpy(problem, hold, solver, nodes)
    tol = NATIVE_TOL[solver]
    # a first candidate, then an update (the selector moves), then back
    for nd in (nodes, [k + 3 for k in nodes], nodes):
        r = nq.solve_nodes(nd)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            c = qp.solve_nodes(nd)
        assert r["status"] == c["status"] == "optimal"
        assert r["cost"] == pytest.approx(c["cost"], rel=tol)
        X, Xc = r["trajectory"].X, c["trajectory"].X
        assert np.max(np.abs(X - Xc)) <= tol * max(1.0, np.max(np.abs(Xc)))
        U, Uc = r["trajectory"].U, c["trajectory"].U
        assert np.max(np.abs(U - Uc)) <= tol * max(1.0, np.max(np.abs(Uc)))
        scale = max(1.0, np.max(np.abs(c["multipliers"])))
        assert np.max(np.abs(r["multipliers"] - c["multipliers"])) <= 100 * tol * scale
        np.testing.assert_array_equal(r["contact_times"], c["contact_times"])


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_native_off_grid_times_equal_cvxpy(solver):
    p = CASES[2]
    times = [2.3456, 1.1]
    nq = build_native(p, N, "foh", solver)
    nq.solve_nodes(_nodes(p))  # then move to an aligned non-uniform grid
    r = nq.solve_times(times)
    qp = QPPlanner(steps=N, hold="foh", solver=solver).build(p)
    c = qp.solve_times(times)
    assert r["cost"] == pytest.approx(c["cost"], rel=NATIVE_TOL[solver])
    pmp = PMPPlanner().plan(p, times)
    assert r["cost"] == pytest.approx(pmp.cost, rel=NATIVE_TOL[solver])


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
@pytest.mark.parametrize("problem", CASES[:2], ids=[p.name for p in CASES[:2]])
def test_multipliers_equal_pmp_jumps_foh(problem, solver):
    nodes = _nodes(problem)
    r = build_native(problem, N, "foh", solver).solve_nodes(nodes)
    pmp = PMPPlanner().plan(problem, np.array(nodes) * problem.tf / N)
    assert r["cost"] == pytest.approx(pmp.cost, rel=NATIVE_TOL[solver])
    scale = np.maximum(1.0, np.abs(pmp.jumps))
    assert np.all(np.abs(r["multipliers"] - pmp.jumps) <= 1e-6 * scale * (100 if solver == "osqp" else 1))


def test_native_sweep_equals_cvxpy_sweep_and_the_grid_restricted_pmp():
    p = CASES[0]
    n = 30
    tk = np.arange(1, n) * p.tf / n
    J = ValueFunction(p)(tk[:, None])
    for solver in ("clarabel", "osqp"):
        s = native_sweep(p, n, "foh", solver)
        assert s["n_solves"] == n - 1
        ok = {k: c for k, c in s["costs"].items() if np.isfinite(c)}
        assert len(ok) >= n - 1 - len(s["failures"])
        for (k,), c in ok.items():
            assert c == pytest.approx(J[k - 1], rel=NATIVE_TOL[solver])
        assert s["best"]["nodes"] == (int(np.argmin(J)) + 1,)
    res_native = NativeQPPlanner(steps=n, hold="foh", solver="clarabel").plan(p)
    res_cvxpy = QPPlanner(steps=n, hold="foh", solver="clarabel").plan(p)
    assert res_native.info["path"] == "native"
    assert res_native.cost == pytest.approx(res_cvxpy.cost, rel=1e-9)
    np.testing.assert_allclose(res_native.contact_times, res_cvxpy.contact_times, atol=1e-12)


def test_two_vehicle_native_sweep_covers_every_ordered_pair():
    p = CASES[2]
    n = 8
    s = native_sweep(p, n, "foh", "clarabel")
    assert len(s["costs"]) == (n - 1) * (n - 2)
    tk = np.arange(n + 1) * p.tf / n
    vf = ValueFunction(p)
    best = min(vf(tk[list(k)][None, :])[0] for k in s["costs"])
    assert s["best"]["cost"] == pytest.approx(best, rel=1e-9)


def test_kkt_residuals_on_a_known_qp():
    # min ½(x1² + x2²) s.t. x1 + x2 = 1  ->  x = (½, ½), y = −½
    P = sp.csc_matrix(np.eye(2))
    A = sp.csc_matrix(np.array([[1.0, 1.0]]))
    b, q = np.array([1.0]), np.zeros(2)
    k = kkt_residuals(P, q, A, b, np.array([0.5, 0.5]), np.array([-0.5]))
    assert k["primal"] == 0 and k["dual"] == 0 and k["gap"] == pytest.approx(0, abs=1e-15)
    k = kkt_residuals(P, q, A, b, np.array([0.6, 0.5]), np.array([-0.5]))
    assert k["primal"] == pytest.approx(0.1)
    assert k["dual"] == pytest.approx(0.1)
    # gap = xᵀPx + qᵀx + bᵀy = 0.61 − 0.5
    assert k["gap"] == pytest.approx(0.11)
    # P given as its upper triangle is symmetrised
    Pu = sp.csc_matrix(np.array([[2.0, 1.0], [0.0, 2.0]]))
    k = kkt_residuals(Pu, q, A, b, np.array([0.5, 0.5]), np.array([-1.5]))
    assert k["dual"] == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_kkt_small_for_tight_settings_and_for_the_mapped_cvxpy_solution(solver):
    p = CASES[2]
    nodes = _nodes(p)
    nq = build_native(p, N, "foh", solver)
    r = nq.solve_nodes(nodes)
    k = nq.kkt_residuals(r)
    assert max(k["primal_rel"], k["dual_rel"], k["gap_rel"]) < 1e-10
    # the cvxpy solution mapped onto the native matrices is a KKT point of the same QP
    qp, c = _cvxpy(p, "foh", solver, nodes)
    data = QPData(p, N, "foh")
    data.selector_update(nodes)
    kc = data.kkt_residuals(data.pack(c["trajectory"].X, c["trajectory"].U), data.dual_from_cvxpy(qp))
    assert max(kc["primal_rel"], kc["dual_rel"], kc["gap_rel"]) < 1e-10


def test_kkt_large_for_loose_osqp():
    p = CASES[0]
    nq = build_native(p, N, "foh", "osqp", settings=LOOSE_OSQP)
    r = nq.solve_nodes(_nodes(p))
    assert r["z"] is not None
    k = nq.kkt_residuals(r)
    assert max(k["dual_rel"], k["gap_rel"]) > 1e-7


def test_solver_failure_is_a_status_not_a_cost():
    p = CASES[0]
    nq = build_native(p, N, "foh", "osqp", settings={"max_iter": 3, "polishing": False, "eps_abs": 1e-12})
    r = nq.solve_nodes(_nodes(p))
    assert r["status"] != "optimal"
    assert r["cost"] == np.inf and "trajectory" not in r


def test_clarabel_is_reused_through_its_data_update_and_osqp_warm_starts():
    p = CASES[0]
    c = build_native(p, 12, "foh", "clarabel")
    assert c.info["clarabel_data_update"] is True and c.info["warm_start"] is False
    solver_obj = c.solver
    c.solve_nodes([3])
    c.solve_nodes([7])
    assert c.solver is solver_obj  # not rebuilt
    o = build_native(p, 12, "foh", "osqp")
    assert o.info["warm_start"] is True
    o.solve_nodes([3])
    assert o._last is not None


def test_bad_nodes_and_steps_are_rejected():
    p = CASES[0]
    with pytest.raises(ValueError):
        build_native(p, 1, "foh", "clarabel")
    with pytest.raises(ValueError):
        build_native(p, 10, "rk4", "clarabel")
    q = build_native(p, 10, "foh", "clarabel")
    for bad in ([0], [10], [3, 4]):
        with pytest.raises(ValueError):
            q.solve_nodes(bad)
