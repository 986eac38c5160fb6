"""The weak-duality bounds' kernels (``planners/avoid/dual_kernel.py``), written once.

* The Python functions and their numba twins give the same numbers bit for bit, on the arguments
  the planner passes them in one- and three-vehicle plans (FOH and ZOH), so no plan depends on
  whether numba is installed.
* The one-vehicle polynomial (multipliers on their tangent) against its definition, an independent
  formulation: at crossing times ``τ`` where no multiplier is cut, ``g(y(τ); τ) = min_{Ez = e}
  ½zᵀPz + y(τ)ᵀ(G(τ)z - h(τ))`` with the rows of the candidate's spec moved to ``τ`` by the QP's own
  row builder, one sparse KKT solve per ``τ``; and the tangent against the dense linear algebra of
  its equation (``numpy.linalg.solve``).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners import registry
from iamp.planners.avoid import dual, dual_kernel
from iamp.planners.avoid.continuous import ContinuousAvoidQP
from iamp.planners.avoid.dual import DualBounds, piece_of
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.pmp import jit

KERNELS = ("slope", "tangent", "tangent_terms", "primal", "coefficients", "binding_rows", "select_rows", "kept_rows",
           "ratio_limits")


def _same(ra: object, rb: object) -> bool:
    """Whether two kernel results are the same bit for bit (scalars, arrays or tuples of them; NaN
    equal to NaN, dtypes equal)."""
    if isinstance(ra, tuple):
        return isinstance(rb, tuple) and len(ra) == len(rb) and all(_same(a, b) for a, b in zip(ra, rb))
    if isinstance(ra, np.ndarray):
        return (isinstance(rb, np.ndarray) and ra.dtype == rb.dtype and ra.shape == rb.shape
                and np.array_equal(ra.view(np.uint8), rb.view(np.uint8)))
    if isinstance(ra, float) or isinstance(rb, float):
        return bool(np.float64(ra).tobytes() == np.float64(rb).tobytes())  # type: ignore[arg-type]
    return ra == rb


def _recorded_calls(three: bool, hold: str) -> list[tuple[str, tuple]]:  # type: ignore[type-arg]
    """Every call the plan makes to the kernels of this module, its arguments copied before the call."""
    calls: list[tuple[str, tuple]] = []  # type: ignore[type-arg]
    original = dual._run

    def recording(name, module=None):  # type: ignore[no-untyped-def]
        fn = original(name) if module is None else original(name, module)
        if module is not dual_kernel:
            return fn

        def call(*args):  # type: ignore[no-untyped-def]
            calls.append((name, tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)))
            return fn(*args)
        return call

    prob = overtake_three_problem() if three else overtake_problem()
    if hold == "zoh":
        prob = prob.with_limits(None)
    dual._run = recording
    try:
        plan = registry.make_planner("qp-avoid", steps=30, hold=hold, solver="clarabel", safety="continuous").plan(prob)
    finally:
        dual._run = original
    assert plan.status == st.OPTIMAL
    return calls


@pytest.mark.skipif(not jit.available(), reason="numba is not installed")
@pytest.mark.parametrize("three,hold", [(False, "foh"), (True, "foh"), (False, "zoh")])
def test_the_compiled_kernels_are_the_python_functions_bit_for_bit(three: bool, hold: str) -> None:
    calls = _recorded_calls(three, hold)
    seen = {name for name, _ in calls}
    assert {"primal", "coefficients", "slope", "binding_rows", "select_rows", "kept_rows"} <= seen
    assert three or {"tangent", "tangent_terms", "ratio_limits"} <= seen
    twins = {name: jit.twin(getattr(dual_kernel, name), cache=True) for name in KERNELS}
    for name, args in calls:
        a = tuple(x.copy() if isinstance(x, np.ndarray) else x for x in args)
        b = tuple(x.copy() if isinstance(x, np.ndarray) else x for x in args)
        ra, rb = getattr(dual_kernel, name)(*a), twins[name](*b)
        assert _same(ra, rb), name
        for x, y in zip(a, b):
            if isinstance(x, np.ndarray):
                assert _same(x, y), name


def problem(x0v: float, speed: float, xf: float, vxf: float, limits: bool) -> Problem:
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding", limits=PASSENGER_CAR if limits else None)


def _dual_value(qp: ContinuousAvoidQP, spec_t, y_by_id: dict[int, float]) -> float:  # type: ignore[no-untyped-def]
    """``min_{Ez = e} ½zᵀPz + Σ_r y_r (a_r z - u_r)`` over the rows of ``spec_t`` named in ``y_by_id``
    (layout numbers), by one sparse KKT solve."""
    A_in, u_in, ids = qp.spec_rows(spec_t)
    at = {int(r): p for p, r in enumerate(ids)}
    assert set(y_by_id) <= set(at)
    rows = np.array([at[r] for r in y_by_id], dtype=np.int64)
    yv = np.array(list(y_by_id.values()))
    G, h = A_in[rows], u_in[rows]
    d = qp.data
    P = sp.csc_matrix(d.P)
    P = P + sp.triu(P, 1).T
    E = sp.csr_matrix(qp.A_eq)
    K = sp.bmat([[P, E.T], [E, None]], format="csc")
    x = spla.spsolve(K, np.concatenate((-(G.T @ yv), d.b_eq)))
    z = x[:d.n]
    return float(0.5 * z @ (P @ z) + yv @ (G @ z - h))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.floats(100.0, 125.0), st_h.floats(20.0, 26.0),
       st_h.booleans(), st_h.sampled_from(["foh", "zoh"]), st_h.integers(6, 30), st_h.floats(0.02, 0.98),
       st_h.floats(0.0, 1.0))
def test_the_tangent_polynomial_is_its_definition(x0v, speed, xf, vxf, limits, hold, steps, where, frac):
    try:
        qp = ContinuousAvoidQP(problem(x0v, speed, xf, vxf, limits), steps, hold, "clarabel")
    except ScenarioError:
        assume(False)
        raise
    h = qp.h
    k = min(int(where * steps), steps - 1)
    tau = (k + 0.02 + 0.96 * frac) * h
    cand = qp.solve(((1, 0, tau, tau),))
    assume(cand.status == st.OPTIMAL)
    bounds = DualBounds(qp)
    b = bounds._binding(cand)
    mu = bounds.tangent(cand, 0, k)
    la, lb = bounds.tangent_interval(cand, 0, k)
    assume(lb - la > 1e-6)
    dp = bounds.polynomial(cand, np.array([(k + la) * h]), np.array([(k + lb) * h]))
    _, _, ids = cand.spec_rows()
    lam_c = (tau - k * h) / h
    for lam in np.linspace(la, lb, 7)[1:-1]:  # inside the piece: the rows of the candidate's spec, moved
        t = (k + lam) * h
        y_t = {int(ids[r]): float(yv + (lam - lam_c) * m) for r, yv, m in zip(b.nz, b.y, mu)}
        want = _dual_value(qp, ((1, 0, float(t), float(t)),), y_t)
        got = float(dp.evaluate(np.array([[t]]))[0])
        assert got == pytest.approx(want, rel=1e-8, abs=1e-8 + dp.roundoff)


def test_the_tangent_is_the_dense_solution_of_its_equation() -> None:
    """:func:`~iamp.planners.avoid.dual_kernel.tangent` against ``numpy.linalg.solve`` of
    :math:`(G_S K^{-1}_{zz} G_S^\\top)\\dot y = G_S K^{-1}_{zz}(-\\dot G_S^\\top y) - (\\dot h - \\dot G_S z)`,
    the derivatives of the split rows taken by central differences of the QP's own rows."""
    prob = overtake_problem()
    qp = ContinuousAvoidQP(prob, 50, "foh", "clarabel")
    h = qp.h
    checked = 0
    for tau in (3.7126922784915495, 3.75, 3.705, 3.72, 3.79, 3.85, 3.93):
        cand = qp.solve(((1, 0, tau, tau),))
        if cand.status != st.OPTIMAL:
            continue
        checked += 1
        k = piece_of(tau, tau, h, qp.N)
        bounds = DualBounds(qp)
        b = bounds._binding(cand)
        mu = bounds.tangent(cand, 0, k)
        A_c, _, ids = cand.spec_rows()
        e = 1e-6 * h
        rows_p = qp.spec_rows(((1, 0, tau + e, tau + e),))
        rows_m = qp.spec_rows(((1, 0, tau - e, tau - e),))
        sel = ids[b.nz]

        def pick(rows, sel=sel):  # type: ignore[no-untyped-def]
            A, u, i = rows
            at = {int(r): p for p, r in enumerate(i)}
            p = np.array([at[int(r)] for r in sel])
            return A[p].toarray(), u[p]

        (Ap, up), (Am, um) = pick(rows_p), pick(rows_m)
        dG, dh = (Ap - Am) / (2 * e / h), (up - um) / (2 * e / h)
        G = A_c[b.nz].toarray()
        Kinv = bounds._kinv_rows(np.arange(qp.data.n))
        W = G @ Kinv @ G.T
        rhs = G @ Kinv @ -(dG.T @ b.y) - (dh - dG @ cand.z)
        want = np.linalg.solve(W, rhs)
        assert np.allclose(mu, want, rtol=1e-5, atol=1e-7 * max(1.0, float(np.abs(want).max()))), (mu, want)
    assert checked >= 4


@pytest.mark.parametrize("eps,solved", [(0.5, True), (1e-3, True), (1e-7, False), (0.0, False)])
def test_the_tangent_of_rows_binding_dependently_is_refused(eps: float, solved: bool) -> None:
    """Two binding rows on the same four columns, the second the first plus ``eps`` times another
    direction, ``K⁻¹_zz`` the identity, the first row split: the tangent solves
    ``(G Gᵀ) ẏ = G(-dGᵀ y) - (dh - dG z)`` (checked against ``numpy.linalg.solve``) while the rows are
    independent enough, and is refused (False, zeros) where they are dependent (a zero pivot) or
    nearly so (``eps`` = 1e-7: a solution of about 1e14 whose residual exceeds 1e-8 (1 + |rhs|))."""
    rng = np.random.default_rng(7)
    a0, dirn = rng.normal(size=4), rng.normal(size=4)
    data = np.concatenate((a0, a0 + eps * dirn))
    indptr, indices = np.array([0, 4, 8], dtype=np.int64), np.array([0, 1, 2, 3, 0, 1, 2, 3], dtype=np.int64)
    nz, y, jidx = np.array([0, 1], dtype=np.int64), np.array([0.7, 0.4]), np.array([1, 2], dtype=np.int64)
    z = rng.normal(size=6)
    Kinv = np.eye(6)
    D, nb = 3, 4
    M, rhs_poly = rng.normal(size=(D + 1, nb, 4)), rng.normal(size=(D + 1, nb))
    cols = np.array([0, 1, 2, 3], dtype=np.int64)
    lam0 = 0.37
    out = np.full(2, np.nan)
    for fn in [dual_kernel.tangent] + ([jit.twin(dual_kernel.tangent, cache=True)] if jit.available() else []):
        ok = fn(indptr, indices, data, nz, y, jidx, z, Kinv, lam0, np.array([0], dtype=np.int64), M, rhs_poly, -1.0,
                cols, np.zeros(0, dtype=np.int64), M, rhs_poly, 1.0, cols, out)
        assert ok is solved
        if not solved:
            assert np.array_equal(out, np.zeros(2))
            continue
        basis = np.array([p * lam0 ** (p - 1) for p in range(1, D + 1)])
        dG = np.zeros((2, 6))
        dG[0, :4] = -np.einsum("p,pc->c", basis, M[1:, 1, :])
        dh = np.array([basis @ rhs_poly[1:, 1], 0.0])
        G = np.zeros((2, 6))
        G[0, :4], G[1, :4] = a0, a0 + eps * dirn
        want = np.linalg.solve(G @ G.T, G @ -(dG.T @ y) - (dh - dG @ z))
        assert np.allclose(out, want, rtol=1e-9, atol=0.0)
