"""The node solver's kernel (``planners/avoid/schur_kernel.py``), written once.

* Its Python function and its numba twin give the same numbers bit for bit on the QPs of a
  search (cold, warm-started, with a cutoff), so no plan depends on whether numba is installed.
* Its small dense algebra (Cholesky factor and solve) against numpy's, and its optimum against
  the KKT conditions recomputed from the data and an independent backend solve of the same QP.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from schur_args import kernel_args

from iamp.planners.avoid import schur_kernel as kernel
from iamp.planners.avoid.check import crossing_orders
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, ContinuousAvoidQP
from iamp.planners.avoid.schur import CHECK_TOL
from iamp.planners.avoid.solve import GENERATION_TOL, RowGeneration
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.pmp import jit


def _args(qp: ContinuousAvoidQP, spec, start=None, cutoff=None):  # type: ignore[no-untyped-def]
    _, u, _ = qp.spec_rows(spec)
    assert qp.schur is not None
    return kernel_args(qp, spec, start, cutoff, cap=min(u.size, qp.schur.n) + 1)


def _specs(m: int):  # type: ignore[no-untyped-def]
    prob = overtake_problem() if m == 1 else overtake_three_problem()
    qp = ContinuousAvoidQP(prob, 20, "foh", "clarabel")
    tf = prob.tf
    orders, _ = crossing_orders(prob)
    first = [o[0] for o in orders]
    best = ContinuousAvoidPlanner(steps=20).plan(prob).contact_times  # the search's crossings
    taus = [np.asarray(best, dtype=float), np.full(m, 0.74 * tf), np.linspace(0.3, 0.8, m) * tf]
    specs = [tuple((f, s, float(t), float(t)) for (f, s), t in zip(first, tau)) for tau in taus]
    specs.append(tuple((f, s, 0.5 * tf, 0.9 * tf) for f, s in first))  # a relaxation
    return qp, specs


@pytest.mark.skipif(not jit.available(), reason="numba is not installed")
@pytest.mark.parametrize("m", [1, 3])
def test_the_compiled_kernel_is_the_python_function_bit_for_bit(m: int) -> None:
    qp, specs = _specs(m)
    compiled = jit.twin(kernel.active_set, cache=True)
    first = qp.solve(specs[0])
    runs = 0
    for spec in specs:
        _, _, ids = qp.spec_rows(spec)
        # cold, warm from the first candidate's binding rows, and with a cutoff below its cost
        warm = np.flatnonzero(np.isin(ids, first.active()))
        for start, cutoff in ((None, None), (warm, None), (None, 0.5 * first.cost)):
            a, b = _args(qp, spec, start, cutoff), _args(qp, spec, start, cutoff)
            ra, rb = kernel.active_set(*a), compiled(*b)
            assert tuple(int(x) for x in ra) == tuple(int(x) for x in rb)
            for x, y in zip(a[-4:], b[-4:]):  # z, lam, rows, out
                assert np.array_equal(x, y), (spec, start, cutoff)
            runs += 1
    assert runs == 3 * len(specs)


def test_cholesky_and_the_small_solve_against_numpy() -> None:
    rng = np.random.default_rng(3)
    for k in (1, 2, 5, 9):
        B = rng.standard_normal((k, k + 3))
        S = np.zeros((12, 12))
        S[:k, :k] = B @ B.T + 1e-3 * np.eye(k)
        L = np.zeros((12, 12))
        assert kernel._cholesky(S, k, L)
        assert np.allclose(L[:k, :k], np.linalg.cholesky(S[:k, :k]), rtol=1e-12, atol=1e-12)
        b = np.r_[rng.standard_normal(k), np.zeros(12 - k)]
        x = np.zeros(12)
        assert kernel._solve(S, k, b, x, np.zeros((12, 12)))
        assert np.allclose(S[:k, :k] @ x[:k], b[:k], rtol=1e-10, atol=1e-10)
        P = rng.standard_normal((k, k))  # not symmetric: partial pivoting
        S2 = np.zeros((12, 12))
        S2[:k, :k] = P
        assert kernel._solve(S2, k, b, x, np.zeros((12, 12)))
        assert np.allclose(P @ x[:k], b[:k], rtol=1e-8, atol=1e-8)
    S = np.array([[1.0, 2.0], [2.0, 1.0]])  # indefinite
    assert not kernel._cholesky(S, 2, np.zeros((2, 2)))
    assert not kernel._solve(np.ones((2, 2)), 2, np.ones(2), np.zeros(2), np.zeros((2, 2)))  # singular


@pytest.mark.parametrize("m", [1, 3])
def test_the_node_solvers_optimum_is_the_backends_and_meets_the_kkt_conditions(m: int) -> None:
    qp, specs = _specs(m)
    s = qp.schur
    assert s is not None
    solved = 0
    for spec in specs:
        A, u, ids = qp.spec_rows(spec)
        sol = s.solve(A, u)
        ref = RowGeneration("clarabel", qp.data.P, qp.A_eq, qp.data.b_eq, every_row=True).solve(A, u, ids)
        if sol.status == "numerical_error":  # a nearly dependent row: the search asks the backend
            assert ref.status == "infeasible"
            continue
        assert sol.status == ref.status  # an infeasible crossing for both, or the same optimum
        if sol.status != "optimal":
            continue
        solved += 1
        assert s.residual(A, u, sol.z, sol.y) <= CHECK_TOL
        P = sp.csr_matrix(s.P_full)
        cost, ref_cost = 0.5 * sol.z @ (P @ sol.z), 0.5 * ref.z @ (P @ ref.z)
        assert cost == pytest.approx(ref_cost, rel=1e-7, abs=1e-9)
        assert np.max(A @ sol.z - u) <= GENERATION_TOL
        lam = sol.y[qp.data.n_eq:]
        assert lam.min() >= 0.0 and np.all(lam[(u - A @ sol.z) > 1e-6] == 0.0)
    assert solved >= 1


def test_the_kkt_residual_is_the_sparse_matrix_formula() -> None:
    """The node solver's KKT residual (a kernel over the CSR arrays) against the same formula with
    scipy's sparse products, on every solution of a three-vehicle search: equal (the same sums in
    the same order), and large for a perturbed solution."""
    prob = overtake_three_problem()
    qp = ContinuousAvoidQP(prob, 20, "foh", "clarabel")
    ContinuousAvoidPlanner(steps=20).search(qp, crossing_orders(prob)[0])
    s = qp.schur
    assert s is not None
    checked = 0
    for sol in qp.solved.values():
        if sol.status != "optimal":
            continue
        A, u, _ = sol.spec_rows()
        z, y = sol.z, sol.y
        lam = y[s.n_eq:]
        Pz, At = s.P_full @ z, s.A_eq_T @ y[:s.n_eq]
        Gt = sp.csr_matrix(A).T @ lam
        primal = max(float(np.abs(s.A_eq @ z - s.b_eq).max(initial=0.0)), float((A @ z - u).max(initial=0.0)))
        scale = max(1.0, float(np.abs(Pz).max()), float(np.abs(At).max()), float(np.abs(Gt).max(initial=0.0)))
        ref = max(primal, float(np.abs(Pz + At + Gt).max()) / scale, float(-lam.min(initial=0.0)))
        assert s.residual(A, u, z, y) == ref
        assert ref <= CHECK_TOL
        assert s.residual(A, u, z + 1e-3, y) > 1e-4  # off the equality rows
        checked += 1
    assert checked >= 3


_PLAN = """
import sys
import iamp.planners.pmp.jit as jit
if sys.argv[1] == "python":
    jit.available = lambda: False  # as without numba installed
from iamp.planners.avoid import AvoidQPPlanner, schur
from iamp.planners.examples import overtake_three_problem
assert schur._PYTHON == (sys.argv[1] == "python")
p = AvoidQPPlanner(steps=20, solver="clarabel").plan(overtake_three_problem())
print(p.status, repr(p.cost), [repr(float(t)) for t in p.contact_times], p.info["n_solves"])
"""


@pytest.mark.skipif(not jit.available(), reason="numba is not installed")
def test_a_plan_is_the_same_with_and_without_numba() -> None:
    """The whole three-vehicle plan (status, cost, crossing times, solves) in a process that runs
    the node solver as Python and in one that runs its numba twin: identical."""
    import subprocess
    import sys

    out = [subprocess.run([sys.executable, "-c", _PLAN, mode], capture_output=True, text=True, check=True,
                          timeout=600).stdout for mode in ("python", "numba")]
    assert out[0] == out[1]
    assert out[0].startswith("optimal")
