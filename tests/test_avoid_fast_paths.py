"""Issue 32 item 3: the avoidance search's faster building blocks give the numbers they replace.

* :func:`~iamp.planners.avoid.bernstein.poly_bernstein` on arrays of intervals is, interval by
  interval, the scalar call bit for bit, and its coefficients reproduce the polynomial (the
  Bernstein form evaluated by de Casteljau against numpy's power form).
* :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.spec_rows` from the per-plan cache of
  row blocks equals a fresh build of the same spec (bit for bit), whatever was built before; its
  limit rows are ``[A_lim; -A_lim] z <= [hi; -lo]`` of :func:`~iamp.planners.qp.limits.limit_rows`.
* The node solver's columns of ``K⁻¹`` (kept in one array) are the sparse LU's solves of the
  unit columns, and a QP in which no row binds returns the equality optimum and multipliers of
  a fresh KKT solve.
* :func:`~iamp.planners.avoid.check.kkt_conditions` with the caller's strict lower triangle
  returns the same residuals as without it; one :class:`~iamp.planners.avoid.check.KKTCheck`
  checking two points gives each point's fresh residuals bit for bit, and they are the formula
  of the module docstring written out on dense arrays.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.planners.avoid import schur_kernel
from iamp.planners.avoid.bernstein import poly_bernstein
from iamp.planners.avoid.check import KKTCheck, kkt_conditions
from iamp.planners.avoid.continuous import ContinuousAvoidQP, _spec
from iamp.planners.avoid.schur import SchurActiveSet, kkt_matrix
from iamp.planners.examples import overtake_problem, overtake_three_problem


def de_casteljau(b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The Bernstein polynomial with coefficients ``b`` on [0, 1] at ``x``."""
    out = np.empty(x.size)
    for c, t in enumerate(x):
        w = b.astype(float).copy()
        for r in range(1, b.size):
            w[:b.size - r] = (1 - t) * w[:b.size - r] + t * w[1:b.size - r + 1]
        out[c] = w[0]
    return out


@settings(max_examples=40, deadline=None)
@given(st_h.lists(st_h.floats(-30.0, 30.0), min_size=1, max_size=4), st_h.integers(3, 6),
       st_h.lists(st_h.floats(0.0, 8.0), min_size=1, max_size=12), st_h.floats(1e-3, 2.0))
def test_poly_bernstein_on_arrays_is_the_scalar_call_and_reproduces_the_polynomial(coeffs, degree, starts, width):
    c = np.array(coeffs)
    ta = np.array(starts)
    tb = ta + width
    many = poly_bernstein(c, ta, tb, degree)
    assert many.shape == (ta.size, degree + 1)
    x = np.linspace(0.0, 1.0, 7)
    for k in range(ta.size):
        one = poly_bernstein(c, float(ta[k]), float(tb[k]), degree)
        assert np.array_equal(one, many[k])  # bit for bit
        t = ta[k] + (tb[k] - ta[k]) * x
        exact = np.polynomial.polynomial.polyval(t, c)
        scale = max(1.0, float(np.sum(np.abs(c) * max(1.0, float(tb[k])) ** np.arange(c.size))))
        assert np.allclose(de_casteljau(one, x), exact, rtol=0.0, atol=1e-11 * scale)


def _specs(m: int, draws: list[tuple[float, float, bool]]) -> list[tuple]:
    out = []
    for c in range(0, len(draws) - m + 1, m):
        lo = np.array([min(a, b) for a, b, _ in draws[c:c + m]])
        hi = np.array([max(a, b) for a, b, _ in draws[c:c + m]])
        point = draws[c][2]
        out.append(_spec([(0, 1)] * m, lo, lo if point else hi))
    return out


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.sampled_from([1, 3]), st_h.integers(5, 40), st_h.booleans(),
       st_h.lists(st_h.tuples(st_h.floats(0.0, 5.0), st_h.floats(0.0, 5.0), st_h.booleans()), min_size=3,
                  max_size=18))
def test_spec_rows_from_the_block_cache_equal_a_fresh_build(m, steps, limits, draws):
    prob = overtake_problem(limits) if m == 1 else overtake_three_problem(limits)
    used = ContinuousAvoidQP(prob, steps, "foh", "piqp")
    specs = _specs(m, draws)
    for spec in specs:  # fill the cache with blocks that later specs share
        used.spec_rows(spec)
    for spec in reversed(specs):
        fresh = ContinuousAvoidQP(prob, steps, "foh", "piqp")
        A, u, ids = used.spec_rows(spec)
        A_ref, u_ref, ids_ref = fresh.spec_rows(spec)
        assert np.array_equal(ids, ids_ref) and np.all(np.diff(ids) > 0)  # layout order
        assert np.array_equal(u, u_ref) and np.array_equal(A.indptr, A_ref.indptr)
        assert np.array_equal(A.indices, A_ref.indices) and np.array_equal(A.data, A_ref.data)
        lim = ids >= used.n_b
        assert int(lim.sum()) == used.u_lim.size
        if used.limit_rows is not None:
            lr = used.limit_rows
            A_lim = sp.vstack([lr.A, -lr.A]).toarray()
            assert np.array_equal(A[np.flatnonzero(lim)].toarray(), A_lim)
            assert np.array_equal(u[lim], np.r_[lr.hi, -lr.lo])


def test_the_node_solvers_columns_are_the_lu_solves_and_a_slack_qp_returns_the_equality_optimum():
    qp = ContinuousAvoidQP(overtake_problem(), 20, "foh", "piqp")
    d = qp.data
    solver = SchurActiveSet(d.P, qp.A_eq, d.b_eq)
    lu = spla.splu(kkt_matrix(d.P, qp.A_eq))
    rng = np.random.default_rng(3)
    for _ in range(20):
        cols = np.sort(rng.choice(d.n, size=4, replace=False)).astype(np.int32)
        vals = rng.normal(size=4)
        g = np.zeros(d.n + d.n_eq)
        g[cols] = vals
        ref = lu.solve(g)[:d.n]
        # w_r as the node solver's kernel forms it from the columns of K⁻¹ the row touches
        solver._columns(cols.astype(np.int64))
        w = np.zeros(d.n)
        schur_kernel._row_w(np.array([0, 4]), cols.astype(np.int64), vals, 0, solver._Kinv, w)
        assert np.allclose(w, ref, rtol=0.0, atol=1e-12 * max(1.0, np.abs(ref).max()))
    # rows that the equality optimum keeps with room to spare: nothing binds
    z0 = lu.solve(np.r_[np.zeros(d.n), d.b_eq])
    G = sp.csr_matrix(rng.normal(size=(5, d.n)))
    sol = solver.solve(G, G @ z0[:d.n] + 1.0)
    assert sol.status == st.OPTIMAL and sol.iterations == 0
    assert np.array_equal(sol.z, z0[:d.n]) and np.array_equal(sol.y[:d.n_eq], z0[d.n:])
    assert np.all(sol.y[d.n_eq:] == 0.0)
    sol.z[:] = np.nan  # the caller's copy: the stored optimum is untouched
    again = solver.solve(G, G @ z0[:d.n] + 1.0)
    assert np.array_equal(again.z, z0[:d.n])


def _three_vehicle_optimum():  # type: ignore[no-untyped-def]
    """A three-vehicle candidate's optimum (PIQP, FOH, N = 20) with its rows ``A`` and bounds ``l, u``."""
    qp = ContinuousAvoidQP(overtake_three_problem(), 20, "foh", "piqp")
    d = qp.data
    sol = qp.solve(_spec([(1, 0), (0, 1), (0, 1)], [3.7, 1.9, 3.6], [3.7, 1.9, 3.6]))
    assert sol.status == st.OPTIMAL
    A_in, u_in, _ = sol.spec_rows()
    A = sp.csc_matrix(sp.vstack([qp.A_eq, A_in]))
    l, u = np.r_[d.b_eq, np.full(u_in.size, -np.inf)], np.r_[d.b_eq, u_in]
    return qp, d, sol, A, l, u


def test_kkt_conditions_with_the_callers_lower_triangle_are_the_same_numbers():
    _, d, sol, A, l, u = _three_vehicle_optimum()
    lower = sp.triu(sp.csc_matrix(d.P), 1).T
    assert kkt_conditions(d.P, d.q, A, l, u, sol.z, sol.y, d.n_eq, lower) == kkt_conditions(
        d.P, d.q, A, l, u, sol.z, sol.y, d.n_eq)


def test_one_kkt_check_of_two_points_is_each_points_own_and_the_dense_formula():
    _, d, sol, A, l, u = _three_vehicle_optimum()
    rng = np.random.default_rng(5)
    off = sol.y - 1e-3 * (np.arange(sol.y.size) >= d.n_eq)  # negative multipliers on the free rows
    points = [(sol.z, sol.y), (sol.z + 1e-3 * rng.standard_normal(sol.z.size), off)]
    check = KKTCheck(d.P, d.q, A, l, u, d.n_eq)
    Pf = sp.csc_matrix(d.P).toarray()
    Pf = Pf + np.triu(Pf, 1).T
    Ad = A.toarray()
    for z, y in points:
        got = check(z, y)
        assert got == KKTCheck(d.P, d.q, A, l, u, d.n_eq)(z, y) == kkt_conditions(d.P, d.q, A, l, u, z, y, d.n_eq)
        Pz, Az, Aty = Pf @ z, Ad @ z, Ad.T @ y
        bound = np.abs(np.r_[l[np.isfinite(l)], u[np.isfinite(u)]]).max()
        slack = np.maximum(u[d.n_eq:] - Az[d.n_eq:], 0.0)
        ref = {"kkt_stationarity_rel": np.abs(Pz + d.q + Aty).max() / max(1.0, np.abs(Pz).max(), np.abs(Aty).max()),
               "kkt_primal_rel": np.abs(Az - np.clip(Az, l, u)).max() / max(1.0, np.abs(Az).max(), bound),
               "kkt_dual_sign_rel": max(0.0, (-y[d.n_eq:]).max()) / max(1.0, np.abs(y).max()),
               "kkt_complementarity_rel": (np.abs(y[d.n_eq:]) * slack).max() / max(1.0, abs(z @ Pz))}
        for k, v in ref.items():
            assert got[k] == pytest.approx(v, rel=1e-9, abs=1e-15), k
    assert check(*points[1])["kkt_dual_sign_rel"] > 0.0  # the second point is no optimum
