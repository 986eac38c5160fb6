"""The fast paths of the equality QP (issue 14) give the answers of the plain ones.

* the direct ``kkt`` backend re-uses one factorisation per grid (blocks, twin blocks
  sharing one banded LU, border columns gathered from a block solve) and a cached symbolic
  analysis: its solutions equal an LU solve of the whole KKT system (SuperLU), candidate after
  candidate, on random problems, also on a general border (several nonzeros per row);
* :class:`QPData` computes the residuals from one stacked product and tabulates the
  corners per grid: the same numbers as the plain formulas; its cached patterns are shared
  read-only and its values are not;
* the kkt sweep solves all candidates of a grid as one family: the same results as one by
  one, each candidate's residuals its own;
* the iterative backends apply their equality-only settings only to equality-only problems
  and never over an explicit setting, and their answers still verify and equal the exact
  one; an unpolished OSQP answer is reported INACCURATE, not optimal.

No timing assertions: speed is measured by ``iamp bench``.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.core import status as st
from iamp.planners.examples import paper_problem, random_problem
from iamp.planners.qp.backends import ITERATIVE, get_backend, kkt_symbolic
from iamp.planners.qp.backends import clarabel as clarabel_mod
from iamp.planners.qp.backends import osqp as osqp_mod
from iamp.planners.qp.backends import piqp as piqp_mod
from iamp.planners.qp.core import DiscretisedQP, family_residuals
from iamp.planners.qp.data import QPData, equality_residuals
from iamp.planners.qp.sweep import run_sweep

FAST = {"osqp": osqp_mod.polish_first_settings(), "clarabel": clarabel_mod.equality_settings(),
        "piqp": piqp_mod.equality_settings()}


def _lu_kkt(P_upper: sp.spmatrix, A: sp.spmatrix, b: np.ndarray, q: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(z, y)`` of ``min ½zᵀPz + qᵀz, Az = b`` from one LU of the whole KKT system
    (SuperLU, an independent solver: no blocks, no border, no band)."""
    Pu = sp.csc_matrix(P_upper)
    P = Pu + sp.triu(Pu, 1).T
    As = sp.csc_matrix(A)
    n = P.shape[0]
    K = sp.bmat([[P, As.T], [As, None]], format="csc")
    sol = spla.splu(K).solve(np.r_[-(np.zeros(n) if q is None else q), b])
    return sol[:n], sol[n:]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


# --------------------------------------------------------------------------------------
# the direct backend's re-used factorisation
# --------------------------------------------------------------------------------------


@settings(max_examples=15, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([12, 19, 32]), data=hs.data())
def test_a_sweep_on_one_factorisation_equals_an_lu_solve_candidate_by_candidate(seed, m, hold, N, data):
    """(``N − 1`` > 8 interior nodes: the selector rows are the border, kkt's default.)"""
    p = random_problem(seed, m=m)
    qp = DiscretisedQP(p, N, hold, "kkt")
    picks = data.draw(hs.lists(hs.lists(hs.integers(1, N - 1), min_size=m, max_size=m, unique=True),
                               min_size=3, max_size=6))
    for nodes in picks:  # the first solves only the columns it needs, the next ones gather
        r = qp.solve_nodes(nodes)
        z, y = _lu_kkt(qp.data.P, qp.data.A, qp.data.b)
        assert r.ok, (r.status, r.failed_check)
        assert _rel(r.z, z) <= 1e-10 and _rel(r.y, y) <= 1e-8
    b = qp.backend
    assert b.factorisations == 1  # type: ignore[attr-defined]
    assert b.blocks == 1  # type: ignore[attr-defined]  # the two axes share one banded LU
    # a new (aligned) grid: one more factorisation, the same agreement
    times = np.sort(data.draw(hs.lists(hs.floats(0.05, 0.95), min_size=m, max_size=m, unique=True))) * p.tf
    if np.min(np.diff(np.r_[0.0, times, p.tf])) > p.tf / N:
        r = qp.solve_times(times)
        z, _ = _lu_kkt(qp.data.P, qp.data.A, qp.data.b)
        assert r.ok and _rel(r.z, z) <= 1e-10
        k = times / p.tf * N  # times on the uniform grid's nodes: the same grid, no new factorisation
        on_grid = bool(np.all(np.abs(k - np.round(k)) <= 1e-9))
        assert b.factorisations == (1 if on_grid else 2)  # type: ignore[attr-defined]


def test_the_column_block_of_a_sweep_equals_columns_solved_one_at_a_time():
    p = random_problem(7, m=2)
    swept = DiscretisedQP(p, 24, "foh", "kkt")
    for nodes in swept.candidate_nodes():
        a = swept.solve_nodes(nodes)
        b = DiscretisedQP(p, 24, "foh", "kkt").solve_nodes(nodes)  # first use: own columns only
        assert _rel(a.z, b.z) <= 1e-12 and _rel(a.y, b.y) <= 1e-10
        if nodes[0] > 4:
            break
    assert swept.backend._col_all is not None  # type: ignore[attr-defined]


def test_a_general_border_row_takes_the_general_path():
    """Border rows with several nonzeros (a contact interpolated between two nodes): the
    Schur complement is not diagonal; still the LU answer."""
    d = QPData(random_problem(5, m=2), 20, "foh")
    d.selector_update([7, 12])
    sel = d._sel_pos  # [vehicle, axis, node - 1]
    d.A.data[sel[0, 0, 7]] = 0.5  # vehicle 0, x: half at node 7, half at node 8
    d.A.data[sel[0, 0, 6]] = 0.5
    d.A.data[sel[1, 1, 3]] = -0.25  # vehicle 1, y: another entry of the same row
    for _ in range(2):  # first use and column-block path
        b = get_backend("kkt")(d.P, d.q, d.A, d.b, d.b)
        sol = b.solve()
        sol = b.solve()
        z, y = _lu_kkt(d.P, d.A, d.b)
        assert sol.status == st.OPTIMAL
        assert _rel(sol.z, z) <= 1e-10 and _rel(sol.y, y) <= 1e-8


@settings(max_examples=10, deadline=None)
@given(seed=hs.integers(0, 10_000), n=hs.integers(4, 30), data=hs.data())
def test_random_equality_qps_equal_an_lu_solve(seed, n, data):
    """Any equality QP (one block or several, no selector structure), with a linear term."""
    rng = np.random.default_rng(seed)
    m = data.draw(hs.integers(1, n - 1))
    L = sp.random(n, n, density=0.2, random_state=rng) + sp.eye(n)
    P = sp.triu(sp.csc_matrix(L @ L.T + 0.1 * sp.eye(n)), format="csc")
    A = sp.random(m, n, density=0.3, random_state=rng, format="csc") + sp.eye(m, n, format="csc")
    b, q = rng.normal(size=m), rng.normal(size=n)
    border = {"border_row_nnz": int(data.draw(hs.integers(1, n)))}
    sol = get_backend("kkt")(P, q, sp.csc_matrix(A), b, b, border).solve()
    z, y = _lu_kkt(P, A, b, q)
    assert sol.status == st.OPTIMAL
    assert _rel(sol.z, z) <= 1e-8 and _rel(sol.y, y) <= 1e-8


def test_the_symbolic_analysis_is_cached_per_pattern_and_read_only():
    p = paper_problem(1)
    a = DiscretisedQP(p, 30, "foh", "kkt").backend
    b = DiscretisedQP(random_problem(3, m=1), 30, "foh", "kkt").backend  # same pattern
    c = DiscretisedQP(p, 31, "foh", "kkt").backend
    assert a.structure is b.structure and a.structure is not c.structure  # type: ignore[attr-defined]
    with pytest.raises(ValueError):
        a.structure.perm[0] = 1  # type: ignore[attr-defined]
    # a fresh analysis gives the same solution as the cached one
    kkt_symbolic._CACHE.clear()
    d = DiscretisedQP(p, 30, "foh", "kkt")
    assert d.backend.structure is not a.structure  # type: ignore[attr-defined]
    r1, r2 = d.solve_nodes([11]), DiscretisedQP(p, 30, "foh", "kkt").solve_nodes([11])
    np.testing.assert_array_equal(r1.z, r2.z)


# --------------------------------------------------------------------------------------
# QPData: stacked residuals, tabulated corners, cached patterns
# --------------------------------------------------------------------------------------


@settings(max_examples=20, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([5, 17, 40]), scale=hs.floats(1e-3, 1e3), data=hs.data())
def test_stacked_residuals_equal_the_plain_formulas(seed, m, hold, N, scale, data):
    p = random_problem(seed, m=m)
    d = QPData(p, N, hold)
    d.selector_update(data.draw(hs.lists(hs.integers(1, N - 1), min_size=m, max_size=m, unique=True)))
    rng = np.random.default_rng(seed)
    z, y = scale * rng.normal(size=d.n), scale * rng.normal(size=d.n_rows)
    P_full = sp.csr_matrix(d.P + sp.triu(d.P, 1).T)
    ref = equality_residuals(P_full, d.A, sp.csr_matrix(d.A.T), d.b, z, y).as_dict()
    fast = d.kkt_residuals(z, y).as_dict()
    for k in ref:
        assert fast[k] == pytest.approx(ref[k], rel=1e-12, abs=1e-300), k


def test_tabulated_corners_are_the_vehicles_corners_at_the_nodes():
    p = random_problem(11, m=2)
    d = QPData(p, 25, "foh")
    for t_nodes in (d.t_nodes, np.sort(np.r_[0.0, np.random.default_rng(1).uniform(0, p.tf, 24), p.tf])):
        d.set_grid(t_nodes)
        for nodes in ([3, 20], [20, 3], [1, 24]):
            d.selector_update(nodes)
            for i, k in enumerate(nodes):
                assert d.b[d.row_collision + 2 * i] == float(p.vehicles[i].corner_x(d.t_nodes[k]))
                assert d.b[d.row_collision + 2 * i + 1] == float(p.vehicles[i].corner_y)


def test_cached_patterns_are_shared_read_only_and_values_are_not():
    p = paper_problem(1)
    a, b = QPData(p, 22, "zoh"), QPData(p, 22, "zoh")
    assert a._sel_pos is b._sel_pos and not a._sel_pos.flags.writeable
    assert a.A.data is not b.A.data and a.A.indices is not b.A.indices and a.A.indices.flags.writeable
    b.set_grid(np.sort(np.r_[0.0, np.random.default_rng(2).uniform(0, p.tf, 21), p.tf]))
    b.selector_update([5])
    a.selector_update([9])
    assert not np.array_equal(a.A.data, b.A.data)
    ref = QPData(p, 22, "zoh")
    ref.selector_update([9])
    np.testing.assert_array_equal(a.A.data, ref.A.data)
    np.testing.assert_array_equal(a._M.data, ref._M.data)


# --------------------------------------------------------------------------------------
# the iterative backends' equality-only settings
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ITERATIVE)
def test_equality_settings_apply_to_equality_problems_only_and_never_over_explicit_ones(name):
    d = QPData(paper_problem(1), 12, "foh")
    d.selector_update([6])
    applied = get_backend(name)(d.P, d.q, d.A, d.b, d.b).describe()["settings"]
    assert all(applied[k] == v for k, v in FAST[name].items())
    key, value = next(iter(FAST[name].items()))
    other = 0.05 if isinstance(value, float) else (not value if isinstance(value, bool) else value + 1)
    explicit = get_backend(name)(d.P, d.q, d.A, d.b, d.b, {key: other}).describe()["settings"]
    assert explicit[key] == other
    u = d.b.copy()
    u[0] += 1.0  # one inequality row
    general = get_backend(name)(d.P, d.q, d.A, d.b, u).describe()["settings"]
    assert general == {**get_backend(name).default_settings(), **general} and all(
        general.get(k) != v for k, v in FAST[name].items() if k not in get_backend(name).default_settings())


@settings(max_examples=8, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([10, 40]), data=hs.data())
def test_iterative_backends_with_their_fast_settings_verify_and_equal_the_exact_answer(seed, m, hold, N, data):
    p = random_problem(seed, m=m)
    picks = data.draw(hs.lists(hs.lists(hs.integers(1, N - 1), min_size=m, max_size=m, unique=True),
                               min_size=2, max_size=4))
    exact = DiscretisedQP(p, N, hold, "kkt")
    for name in ITERATIVE:
        qp = DiscretisedQP(p, N, hold, name)  # warm-started / updated from candidate to candidate
        for nodes in picks:
            r, e = qp.solve_nodes(nodes), exact.solve_nodes(nodes)
            assert r.ok, (name, r.status, r.failed_check, r.raw_status)
            tol = 1e-6 if name == "osqp" else 1e-8
            assert r.cost == pytest.approx(e.cost, rel=tol) and _rel(r.z, e.z) <= tol


def test_an_unpolished_osqp_answer_is_inaccurate_not_optimal():
    qp = DiscretisedQP(paper_problem(1), 40, "foh", "osqp", {"polishing": False})
    r = qp.solve_nodes([20])
    assert r.solver_status == st.OPTIMAL  # OSQP says solved (to eps_abs 0.1) ...
    assert r.status == st.INACCURATE and r.cost == np.inf and r.failed_check is not None  # ... the check does not


# --------------------------------------------------------------------------------------
# the kkt sweep's family solve (all candidates of a grid at once)
# --------------------------------------------------------------------------------------


@settings(max_examples=8, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2, 3]), hold=hs.sampled_from(["foh", "zoh"]),
       N=hs.sampled_from([8, 12, 21]))
def test_a_family_sweep_equals_the_sweep_one_candidate_at_a_time(seed, m, hold, N):
    """Every candidate: the same solution, residuals, verdict, cost and multipliers; the
    same best.  (``N = 8``: the selector rows are core rows, the family does not apply.)"""
    N = N if m < 3 else min(N, 11)  # three vehicles: (N−1)(N−2)(N−3) candidates
    p = random_problem(seed, m=m)
    fam = run_sweep(DiscretisedQP(p, N, hold, "kkt"), keep_solutions=True)
    one = DiscretisedQP(p, N, hold, "kkt")
    one.set_uniform_grid()
    ref = [one.solve_nodes(c) for c in one.candidate_nodes()]
    assert [r.nodes for r in fam.results] == [r.nodes for r in ref]
    for a, b in zip(fam.results, ref, strict=True):
        assert a.status == b.status == st.OPTIMAL
        assert _rel(a.z, b.z) <= 1e-12 and _rel(a.y, b.y) <= 1e-10
        assert a.cost == pytest.approx(b.cost, rel=1e-13)
        np.testing.assert_allclose(a.multipliers, b.multipliers, rtol=1e-9, atol=1e-12)
        for k, v in b.kkt.as_dict().items():  # round-off level both: equal up to round-off
            assert abs(a.kkt.as_dict()[k] - v) <= 1e-10 * max(1.0, abs(b.cost)), k
        assert a.kkt.worst_rel()[1] <= 1e-12
    assert fam.best.nodes == min(ref, key=lambda r: r.cost).nodes


def test_family_residuals_are_each_candidates_own_residuals():
    """Perturbed solutions (so the residuals are not ~0): the batched residuals of candidate
    ``j`` equal :meth:`QPData.kkt_residuals` with ``j``'s own selector in ``A`` and ``b``."""
    p = random_problem(8, m=2)
    d = QPData(p, 16, "foh")
    rng = np.random.default_rng(3)
    cands = [(3, 9), (9, 3), (1, 15), (7, 8)]
    Z, Y = rng.normal(size=(len(cands), d.n)), rng.normal(size=(len(cands), d.n_rows))
    veh, axis = np.repeat(np.arange(2), 2), np.tile(np.arange(2), 2)
    K = np.asarray(cands)[:, veh]
    cols = axis * d.block + K
    B1 = np.where(axis == 0, d._corner_x[veh, K], d._corner_y[veh])
    got = family_residuals(d, Z, Y, cols, B1)
    for j, c in enumerate(cands):
        d.selector_update(c)
        want = d.kkt_residuals(Z[j], Y[j]).as_dict()
        for k, v in want.items():
            assert got[j].as_dict()[k] == pytest.approx(v, rel=1e-12), (c, k)


def test_a_failing_family_falls_back_to_one_at_a_time(monkeypatch):
    p = paper_problem(1)
    qp = DiscretisedQP(p, 20, "foh", "kkt")
    monkeypatch.setattr(type(qp.backend), "solve_family", lambda *a, **k: None)
    sw = run_sweep(qp)
    assert len(sw.results) == 19 and all(r.ok for r in sw.results) and qp.n_solves == 19
