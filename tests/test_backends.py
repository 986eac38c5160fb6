"""The one QP-backend registry (planners/backends): every backend against the exact KKT
reference and against the independent cvxpy formulation, the general form with
inequalities, status mapping, recomputed KKT residuals, and sweep certification.

No timing assertions: speed is measured by ``iamp bench``.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.comparison import cvxpy_qp
from iamp.comparison.cvxpy_qp import CvxpyQP
from iamp.core import status as st
from iamp.core.errors import MissingDependencyError
from iamp.core.tolerances import tol
from iamp.planners.examples import paper_problem, random_problem
from iamp.planners.pmp.planner import solve_fixed_times
from iamp.planners.qp.backends import (
    BACKENDS,
    ITERATIVE,
    QPSolution,
    UnsupportedProblemError,
    get_backend,
    kkt_residuals,
)
from iamp.planners.qp.backends import clarabel as clarabel_mod
from iamp.planners.qp.backends import osqp as osqp_mod
from iamp.planners.qp.backends import piqp as piqp_mod
from iamp.planners.qp.core import DiscretisedQP
from iamp.planners.qp.data import QPData
from iamp.planners.qp.planner import QPPlanner

#: agreement with the KKT reference, relative to max(1, |reference|), per backend
REF_TOL = {"kkt": 1e-10, "clarabel": 1e-9, "piqp": 1e-8, "osqp": 1e-6}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


# --------------------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------------------


def test_one_registry_one_signature():
    assert set(BACKENDS) == {"osqp", "clarabel", "piqp", "kkt"}
    d = QPData(paper_problem(1), 12, "foh")
    d.selector_update([6])
    for name, cls in BACKENDS.items():
        assert get_backend(name) is cls and cls.name == name
        sol = cls(d.P, d.q, d.A, d.b, d.b).solve()
        assert isinstance(sol, QPSolution) and sol.status == st.OPTIMAL
        assert sol.z.shape == (d.n,) and sol.y.shape == (d.n_rows,)
    with pytest.raises(ValueError, match="unknown QP backend"):
        get_backend("gurobi")


def test_missing_dependency_names_the_pip_command(monkeypatch):
    monkeypatch.setattr(piqp_mod.PIQPBackend, "distribution", "piqp-not-installed-xyz")
    with pytest.raises(MissingDependencyError, match="pip install piqp-not-installed-xyz"):
        get_backend("piqp")


# --------------------------------------------------------------------------------------
# the lane-change QP: every backend = the KKT reference = the cvxpy formulation
# --------------------------------------------------------------------------------------


@settings(max_examples=12, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([8, 24, 60]), data=hs.data())
def test_every_backend_equals_the_kkt_reference(seed, m, hold, N, data):
    p = random_problem(seed, m=m)
    nodes = data.draw(hs.lists(hs.integers(1, N - 1), min_size=m, max_size=m, unique=True))
    d = QPData(p, N, hold)
    d.selector_update(nodes)
    ref = get_backend("kkt")(d.P, d.q, d.A, d.b, d.b).solve()
    assert ref.status == st.OPTIMAL
    k = d.kkt_residuals(ref.z, ref.y)
    assert max(k.primal_rel, k.dual_rel, k.gap_rel) < 1e-12
    for name in ITERATIVE:
        sol = get_backend(name)(d.P, d.q, d.A, d.b, d.b).solve()
        assert sol.status == st.OPTIMAL, (name, sol.raw_status)
        assert _rel(sol.z, ref.z) <= REF_TOL[name], name
        assert _rel(sol.y, ref.y) <= 100 * REF_TOL[name], name


@pytest.mark.parametrize("solver", ["clarabel", "osqp", "piqp"])
@pytest.mark.parametrize("hold", ["foh", "zoh"])
@pytest.mark.parametrize("problem", [paper_problem(2), random_problem(21, m=2, side=1)], ids=["paper-2", "r21-m2"])
def test_native_core_equals_the_cvxpy_formulation(problem, hold, solver):
    N = 20
    nodes = [11, 6][: problem.m]
    cv = CvxpyQP(problem, N, hold, solver)
    qp = DiscretisedQP(problem, N, hold, "kkt")
    for nd in (nodes, [k + 3 for k in nodes], nodes):  # an update, then back
        r, c = qp.solve_nodes(nd), cv.solve_nodes(nd)
        assert r.ok and c.ok, (r.status, c.status)
        assert r.cost == pytest.approx(c.cost, rel=REF_TOL[solver])
        assert _rel(r.z, c.z) <= REF_TOL[solver]
        assert _rel(r.multipliers, c.multipliers) <= 100 * REF_TOL[solver]
        np.testing.assert_array_equal(r.contact_times, c.contact_times)
    # off the grid (aligned, non-uniform grids): a value update of P and A
    times = [2.3456, 1.1][: problem.m]
    r, c = qp.solve_times(times), cv.solve_times(times)
    assert r.cost == pytest.approx(c.cost, rel=REF_TOL[solver])


@settings(max_examples=8, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([6, 16, 40]), data=hs.data())
def test_kkt_reference_equals_the_cvxpy_formulation_on_random_problems(seed, m, hold, N, data):
    p = random_problem(seed, m=m)
    nodes = data.draw(hs.lists(hs.integers(1, N - 1), min_size=m, max_size=m, unique=True))
    r = DiscretisedQP(p, N, hold, "kkt").solve_nodes(nodes)
    c = CvxpyQP(p, N, hold, "clarabel").solve_nodes(nodes)
    assert r.ok and c.ok, (r.status, c.status)
    assert r.cost == pytest.approx(c.cost, rel=1e-9)
    assert _rel(r.z, c.z) <= 1e-8 and _rel(r.y, c.y) <= 1e-6


@pytest.mark.parametrize("solver", sorted(BACKENDS))
@pytest.mark.parametrize("problem", [paper_problem(1), random_problem(22, m=2, side=-1)], ids=["paper-1", "r22-m2"])
def test_foh_equals_pmp_and_multipliers_equal_jumps_on_every_backend(problem, solver):
    """SPEC §3 facts 1 and 3 on every backend (FOH at grid nodes is exact)."""
    N = 30
    nodes = [17, 9][: problem.m]
    res = QPPlanner(steps=N, hold="foh", solver=solver).plan_at_nodes(problem, nodes)
    assert res.status == st.OPTIMAL
    pmp = solve_fixed_times(problem, np.array(nodes) * problem.tf / N)
    assert res.cost == pytest.approx(pmp.cost(), rel=max(REF_TOL[solver], 1e-9))
    assert np.all(np.abs(res.jumps - pmp.jumps) <= 1e-4 * np.maximum(1.0, np.abs(pmp.jumps)))


def test_updates_on_a_fixed_pattern_equal_a_fresh_setup():
    p = random_problem(5, m=2)
    d = QPData(p, 16, "foh")
    d.selector_update([3, 9])
    backends = {n: get_backend(n)(d.P, d.q, d.A, d.b, d.b) for n in BACKENDS}
    pos, vals = d.selector_update([12, 4])
    for name, b in backends.items():
        b.update(Ax=vals, Ax_idx=pos, l=d.b, u=d.b)
        fresh = get_backend(name)(d.P, d.q, d.A, d.b, d.b).solve()
        assert _rel(b.solve().z, fresh.z) <= REF_TOL[name], name
    d.set_grid(np.sort(np.r_[0.0, np.random.default_rng(0).uniform(0, p.tf, 15), p.tf]))
    d.selector_update([12, 4])
    for name, b in backends.items():
        b.update(Px=d.P.data, Ax=d.A.data, l=d.b, u=d.b)
        fresh = get_backend(name)(d.P, d.q, d.A, d.b, d.b).solve()
        assert _rel(b.solve().z, fresh.z) <= REF_TOL[name], name


def test_a_sweep_reuses_one_kkt_factorisation():
    p = random_problem(3, m=2)
    planner = QPPlanner(steps=12, hold="foh", solver="kkt")
    qp = planner.build(p)
    res = planner.plan(p, qp=qp)
    assert res.status == st.OPTIMAL and res.info["candidates"]["total"] == 11 * 10
    assert qp.backend.factorisations == 1  # type: ignore[attr-defined]


def test_kkt_backend_bandwidth_is_small_and_grid_independent():
    p = paper_problem(1)
    for N in (20, 100, 400):
        b = DiscretisedQP(p, N, "foh", "kkt").backend
        assert b.bandwidth <= 8  # type: ignore[attr-defined]


# --------------------------------------------------------------------------------------
# the general form with inequalities (the avoidance QP's use of the registry)
# --------------------------------------------------------------------------------------


def _random_ineq_qp(seed: int):
    rng = np.random.default_rng(seed)
    n, me, mi = 8, 2, 6
    M = rng.normal(size=(n, n))
    P = sp.csc_matrix(np.triu(M @ M.T + np.eye(n)))
    q = rng.normal(size=n)
    A = sp.csc_matrix(rng.normal(size=(me + mi, n)))
    l = np.r_[rng.normal(size=me), -rng.uniform(0.1, 1, mi)]
    u = np.r_[l[:me], rng.uniform(0.1, 1, mi)]
    u[-1] = np.inf  # one one-sided row
    return P, q, A, l, u


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_inequality_qps_agree_across_iterative_backends(seed):
    P, q, A, l, u = _random_ineq_qp(seed)
    sols = {}
    for name in ITERATIVE:
        b = get_backend(name)(P, q, A, l, u, {"eps_abs": 1e-9} if name == "osqp" else None)
        s = b.solve()
        assert s.status == st.OPTIMAL, (name, s.raw_status)
        r = b.residuals(s)
        assert max(r.primal_rel, r.dual_rel, r.gap_rel) < 1e-6, (name, r)
        sols[name] = s
    for name in ("osqp", "piqp"):
        assert _rel(sols[name].z, sols["clarabel"].z) < 1e-6
        assert _rel(sols[name].y, sols["clarabel"].y) < 1e-5
    # a value update of the bounds on the fixed pattern
    b = get_backend("piqp")(P, q, A, l, u)
    b.update(u=u + 0.5)
    fresh = get_backend("clarabel")(P, q, A, l, u + 0.5).solve()
    assert _rel(b.solve().z, fresh.z) < 1e-6


def test_kkt_backend_refuses_inequalities_clearly():
    P, q, A, l, u = _random_ineq_qp(0)
    with pytest.raises(UnsupportedProblemError, match="equality-constrained QPs only"):
        get_backend("kkt")(P, q, A, l, u)
    b = get_backend("kkt")(P, q, A, l, l)
    with pytest.raises(UnsupportedProblemError):
        b.update(u=l + 1.0)


def test_kkt_residuals_on_known_qps():
    # min ½(x1² + x2²) s.t. x1 + x2 = 1  ->  x = (½, ½), y = −½
    P, A = sp.csc_matrix(np.eye(2)), sp.csc_matrix(np.array([[1.0, 1.0]]))
    b, q = np.array([1.0]), np.zeros(2)
    k = kkt_residuals(P, q, A, b, b, np.array([0.5, 0.5]), np.array([-0.5]))
    assert k.primal == 0 and k.dual == 0 and k.gap == pytest.approx(0, abs=1e-15)
    k = kkt_residuals(P, q, A, b, b, np.array([0.6, 0.5]), np.array([-0.5]))
    assert k.primal == pytest.approx(0.1) and k.dual == pytest.approx(0.1)
    assert k.gap == pytest.approx(0.11)  # xᵀPx + qᵀx + bᵀy = 0.61 − 0.5
    # upper triangle symmetrised
    Pu = sp.csc_matrix(np.array([[2.0, 1.0], [0.0, 2.0]]))
    assert kkt_residuals(Pu, q, A, b, b, np.array([0.5, 0.5]), np.array([-1.5])).dual == pytest.approx(0, abs=1e-15)
    # an inequality: min ½x² − x s.t. x ≤ ½  ->  x = ½, y = ½ (upper bound active)
    P1, q1, A1 = sp.csc_matrix([[1.0]]), np.array([-1.0]), sp.csc_matrix([[1.0]])
    lo, up = np.array([-np.inf]), np.array([0.5])
    k = kkt_residuals(P1, q1, A1, lo, up, np.array([0.5]), np.array([0.5]))
    assert k.primal == 0 and k.dual == 0 and k.gap == pytest.approx(0, abs=1e-15)
    # a multiplier pushing against the infinite side is caught by the gap
    assert not np.isfinite(kkt_residuals(P1, q1, A1, lo, up, np.array([0.5]), np.array([-0.5])).gap)


# --------------------------------------------------------------------------------------
# statuses: one vocabulary
# --------------------------------------------------------------------------------------


def test_status_words_map_to_one_vocabulary():
    assert osqp_mod.map_status("maximum iterations reached") == st.MAX_ITER
    assert cvxpy_qp.map_status("user_limit") == st.MAX_ITER
    assert osqp_mod.map_status("solved") == st.OPTIMAL
    assert osqp_mod.map_status("solved inaccurate") == st.INACCURATE
    assert osqp_mod.map_status("run time limit reached") == st.TIME_LIMIT
    assert osqp_mod.map_status("primal infeasible") == st.INFEASIBLE
    assert clarabel_mod.map_status("MaxTime") == st.TIME_LIMIT
    assert clarabel_mod.map_status("MaxIterations") == st.MAX_ITER
    assert clarabel_mod.map_status("AlmostSolved") == st.INACCURATE
    assert clarabel_mod.map_status("NumericalError") == st.NUMERICAL_ERROR
    assert piqp_mod.map_status("Status.PIQP_MAX_ITER_REACHED") == st.MAX_ITER
    assert piqp_mod.map_status("PIQP_NUMERICS") == st.NUMERICAL_ERROR
    assert cvxpy_qp.map_status("optimal_inaccurate") == st.INACCURATE
    for table in (osqp_mod.OSQP_STATUS, clarabel_mod.CLARABEL_STATUS, piqp_mod.PIQP_STATUS, cvxpy_qp.CVXPY_STATUS):
        assert set(table.values()) <= set(st.STATUSES)
    assert osqp_mod.map_status("something new") == st.SOLVER_ERROR


@pytest.mark.parametrize("solver, limit", [("osqp", {"max_iter": 3, "polishing": False, "eps_abs": 1e-5}),
                                           ("piqp", {"max_iter": 1})])
def test_a_real_iteration_limit_is_max_iter_without_a_cost(solver, limit):
    res = QPPlanner(steps=30, hold="foh", solver=solver, solver_settings=limit).plan_at_nodes(paper_problem(1), [15])
    assert res.status == st.MAX_ITER and res.cost is None


def test_solver_optimal_but_inaccurate_is_reported_inaccurate_with_the_check():
    loose = {"eps_abs": 1e-2, "eps_rel": 1e-2, "polishing": False, "max_iter": 200}
    res = QPPlanner(steps=20, hold="foh", solver="osqp", solver_settings=loose).plan_at_nodes(paper_problem(1), [10])
    assert res.info["solver_status"] == "solved"
    assert res.status == st.INACCURATE and res.cost is None
    c = res.info["checks"][res.info["failed_check"]]
    assert c["value"] > c["tol"] == tol("cmp_kkt_rel_osqp")


def test_clarabel_is_reused_through_its_data_update_and_osqp_warm_starts():
    p = paper_problem(1)
    c = DiscretisedQP(p, 12, "foh", "clarabel")
    solver_obj = c.backend.solver  # type: ignore[attr-defined]
    c.solve_nodes([3])
    c.solve_nodes([7])
    assert c.backend.data_update is True  # type: ignore[attr-defined]
    assert c.backend.solver is solver_obj  # type: ignore[attr-defined]  # not rebuilt
    o = DiscretisedQP(p, 12, "foh", "osqp")
    assert o.backend.warm_starts
    first = o.solve_nodes([3])
    again = o.solve_nodes([3])  # warm-started from the solution itself
    assert again.iterations <= first.iterations and again.ok


def test_bad_nodes_steps_and_holds_are_rejected():
    p = paper_problem(1)
    with pytest.raises(ValueError):
        DiscretisedQP(p, 1, "foh", "kkt")
    with pytest.raises(ValueError):
        DiscretisedQP(p, 10, "rk4", "kkt")
    q = DiscretisedQP(p, 10, "foh", "kkt")
    for bad in ([0], [10], [3, 4]):
        with pytest.raises(ValueError):
            q.solve_nodes(bad)


@pytest.mark.parametrize("form", ["csc", "csc_unsorted", "csr", "dense", "csc_int"])
def test_csc_copy_is_scipys_copy_with_sorted_indices_and_owns_its_arrays(form: str) -> None:
    """:func:`~iamp.planners.qp.backends.base.csc_copy` (how every backend takes ``P`` and ``A``):
    the arrays of ``sp.csc_matrix(M, dtype=float, copy=True)`` after ``sort_indices()`` for any
    input, and none shared with the caller's matrix (a backend's value update writes into them)."""
    from iamp.planners.qp.backends.base import csc_copy

    rng = np.random.default_rng(3)
    M = sp.random(9, 7, density=0.4, random_state=rng, format="csc")
    M.data[::3] = 0.0  # explicit zeros are kept
    if form == "csc_unsorted":
        M = sp.csc_matrix((M.data[::-1].copy(), M.indices[::-1].copy(), M.indptr.copy()), shape=M.shape)
        order = np.argsort(np.repeat(np.arange(M.shape[1]), np.diff(M.indptr)), kind="stable")
        M = sp.csc_matrix((M.data[order], M.indices[order], M.indptr), shape=M.shape)
        assert not M.has_sorted_indices
    as_int = sp.csc_matrix((np.round(M.data * 10).astype(np.int64), M.indices, M.indptr), shape=M.shape)
    given = {"csc": M, "csc_unsorted": M, "csr": M.tocsr(), "dense": M.toarray(), "csc_int": as_int}[form]
    ref = sp.csc_matrix(given, dtype=float, copy=True)
    ref.sort_indices()
    out = csc_copy(given)
    assert type(out) is sp.csc_matrix and out.shape == ref.shape and out.has_sorted_indices
    for name in ("data", "indices", "indptr"):
        a, b = getattr(out, name), getattr(ref, name)
        assert a.dtype == b.dtype and np.array_equal(a, b)
        if sp.issparse(given):
            assert not np.shares_memory(a, getattr(given, name))


@settings(max_examples=60, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), csr=hs.booleans(), wide=hs.booleans(), unsorted=hs.booleans())
def test_compressed_is_scipys_constructor(seed: int, csr: bool, wide: bool, unsorted: bool) -> None:
    """:func:`~iamp.planners.qp.backends.base.compressed` (the avoidance's rows, the backends' row
    stacks): for arrays scipy would keep as they are, the matrix ``kind((data, indices, indptr),
    shape)`` builds — the same arrays (the same objects), shape, sortedness found again, products,
    transpose and conversion — and for any other input the constructor's own result; a matrix
    it returns owns no flag of the template it was copied from."""
    from iamp.planners.qp.backends.base import compressed

    rng = np.random.default_rng(seed)
    kind = sp.csr_matrix if csr else sp.csc_matrix
    m, n = int(rng.integers(0, 30)), int(rng.integers(1, 30))
    if wide:
        m, n = n, m + 1
    M = kind(sp.random(m, n, density=float(rng.uniform(0.0, 0.6)), random_state=rng))
    data, indices, indptr = M.data.copy(), M.indices.astype(np.int32), M.indptr.astype(np.int32)
    if unsorted and data.size > 1:  # reverse each compressed row's entries: valid, unsorted
        for a, b in zip(indptr[:-1], indptr[1:]):
            data[a:b], indices[a:b] = data[a:b][::-1].copy(), indices[a:b][::-1].copy()
    ref = kind((data, indices, indptr), shape=(m, n))
    got = compressed(kind, data, indices, indptr, (m, n))
    assert type(got) is kind and got.shape == ref.shape and got.dtype == ref.dtype
    assert got.data is data and got.indices is indices and got.indptr is indptr
    assert got.has_sorted_indices == ref.has_sorted_indices
    x, w = rng.standard_normal(n), rng.standard_normal(m)
    assert np.array_equal(got @ x, ref @ x) and np.array_equal(got.T @ w, ref.T @ w)
    assert np.array_equal(got.toarray(), ref.toarray())
    other = got.tocsc() if csr else got.tocsr()
    ref_other = ref.tocsc() if csr else ref.tocsr()
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(other, name), getattr(ref_other, name))
    # inputs scipy would convert: the constructor's own result (int64 indices, int data, a short indptr)
    for args in ((data, indices.astype(np.int64), indptr), (data.astype(np.int64), indices, indptr)):
        out, exp = compressed(kind, *args, (m, n)), kind(args, shape=(m, n))
        assert out.indices.dtype == exp.indices.dtype and out.data.dtype == exp.data.dtype
        assert np.array_equal(out.toarray(), exp.toarray())
    with pytest.raises(ValueError):
        compressed(kind, data, indices, indptr[:-1], (m, n))
    if data.size:  # an index pointer that does not start at 0: refused as by the constructor
        with pytest.raises(ValueError):
            compressed(kind, data[1:], indices[1:], indptr - 1, (m, n))


def test_compressed_takes_no_constructor_for_arrays_scipy_keeps(monkeypatch: pytest.MonkeyPatch) -> None:
    """:func:`~iamp.planners.qp.backends.base.compressed` builds arrays scipy would keep without its
    constructor (the point of it), and a shape beyond 32-bit indices with the constructor: scipy
    then widens the indices to int64, and so does the result."""
    from iamp.planners.qp.backends.base import compressed

    calls = []
    for kind in (sp.csr_matrix, sp.csc_matrix):
        def counted(self: object, *a: object, _init: object = kind.__init__, **k: object) -> None:
            calls.append(1)
            _init(self, *a, **k)  # type: ignore[operator]

        monkeypatch.setattr(kind, "__init__", counted)
    i32 = np.array([0, 1], dtype=np.int32)
    out = compressed(sp.csr_matrix, np.array([2.0]), np.array([1], dtype=np.int32), i32, (1, 3))
    assert calls == [] and out.toarray().tolist() == [[0.0, 2.0, 0.0]]
    for kind, shape in ((sp.csr_matrix, (1, 2**31)), (sp.csc_matrix, (2**31, 1))):
        big = compressed(kind, np.array([2.0]), np.array([2**31 - 1], dtype=np.int32), i32, shape)
        assert big.indices.dtype == big.indptr.dtype == np.int64 and big.shape == shape
    assert len(calls) == 2


@pytest.mark.parametrize("seed", range(25))
def test_csc_rows_is_scipys_row_indexing(seed: int) -> None:
    """:func:`~iamp.planners.qp.backends.base.csc_rows` (the polish's active rows, PIQP's row split):
    the arrays of ``sp.csc_matrix(A[rows])`` for increasing ``rows``, explicit zeros kept."""
    from iamp.planners.qp.backends.base import csc_rows

    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(1, 40)), int(rng.integers(1, 30))
    A = sp.random(m, n, density=0.3, random_state=rng, format="csc")
    A.data[rng.random(A.nnz) < 0.2] = 0.0
    rows = np.sort(rng.choice(m, size=int(rng.integers(0, m + 1)), replace=False))
    got, ref = csc_rows(A, rows), sp.csc_matrix(A[rows])
    assert got.shape == ref.shape
    for name in ("data", "indices", "indptr"):
        assert getattr(got, name).dtype == getattr(ref, name).dtype
        assert np.array_equal(getattr(got, name), getattr(ref, name))
