"""Issue 32: the final verification of a continuous-time avoidance plan with fewer calls, the
same numbers bit for bit.

* :func:`~iamp.planners.qp.backends.base.csr_to_csc` gives the arrays of scipy's ``tocsc`` (index
  order, types and values), for sorted and unsorted CSR input and explicit zeros; ``_stacked`` and
  ``_stack_rows`` (the verified QP's and the backend's row stacks) are the ``sp.vstack``/row
  selection they stand for, converted by scipy; :class:`~iamp.planners.avoid.check.KKTCheck`'s
  ``Aᵀ`` is ``A.T``, and its products (scipy's compiled ones called directly) are ``@``'s.
* :func:`~iamp.planners.avoid.check.leave_time` (and its exact-root path ``_scan_bracket``) returns
  the former implementation's float bit for bit on random held trajectories (FOH and ZOH, either
  half-plane, either side), and :class:`~iamp.planners.avoid.check.ScanGrid` has ``linspace``'s
  size and points.
* :meth:`~iamp.planners.avoid.schur.SchurActiveSet.with_rhs` is the former ``copy.copy`` with the
  new right-hand side's equality optimum (each attribute the same object or the same bytes), and
  :class:`~iamp.planners.avoid.data.AvoidData` builds the same ``A``, ``P`` and bounds.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hs
from scipy import optimize

from iamp.core.hold_trajectory import HoldTrajectory
from iamp.core.polyroots import roots_in_unit_interval
from iamp.core.problem import SurroundingVehicle
from iamp.core.trajectory_pieces import shifted_poly
from iamp.planners.avoid.check import KKTCheck, ScanGrid, leave_time
from iamp.planners.avoid.continuous import _stacked
from iamp.planners.avoid.data import AvoidData, HalfPlane
from iamp.planners.avoid.schur import SchurActiveSet
from iamp.planners.avoid.solve import _stack_rows, row_entries
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.qp.backends.base import compressed, csr_to_csc, matvec


def _random_csr(rng: np.random.Generator, m: int, n: int, unsorted: bool, zeros: bool) -> sp.csr_matrix:
    """A random CSR matrix (int32 indices), its rows' entries reversed when ``unsorted``, some of
    its stored values exact zeros when ``zeros``."""
    M = sp.csr_matrix(sp.random(m, n, density=float(rng.uniform(0.0, 0.7)), random_state=rng))
    data, indices, indptr = M.data.copy(), M.indices.astype(np.int32), M.indptr.astype(np.int32)
    if zeros and data.size:
        data[rng.random(data.size) < 0.3] = 0.0
    if unsorted:
        for a, b in zip(indptr[:-1], indptr[1:]):
            data[a:b], indices[a:b] = data[a:b][::-1].copy(), indices[a:b][::-1].copy()
    return sp.csr_matrix((data, indices, indptr), shape=(m, n))


def _stack_rows_former(top: sp.csr_matrix, A: sp.csr_matrix, rows: np.ndarray) -> sp.csc_matrix:
    """``_stack_rows`` as it was (a stable sort by column of the row-major entries)."""
    take, lens = row_entries(A.indptr, rows)
    m, n = top.shape[0] + rows.size, top.shape[1]
    cols = np.concatenate((top.indices, A.indices[take]))
    data = np.concatenate((top.data, A.data[take]))
    row_of = np.repeat(np.arange(m), np.concatenate((np.diff(top.indptr), lens)))
    order = np.argsort(cols, kind="stable")
    idx = np.promote_types(top.indices.dtype, A.indices.dtype)
    indptr = np.concatenate(([0], np.cumsum(np.bincount(cols, minlength=n))))
    return compressed(sp.csc_matrix, data[order], row_of[order].astype(idx), indptr.astype(idx), (m, n))


def _same_arrays(got: sp.spmatrix, ref: sp.spmatrix) -> None:
    assert type(got) is type(ref) and got.shape == ref.shape
    for name in ("data", "indices", "indptr"):
        a, b = getattr(got, name), getattr(ref, name)
        assert a.dtype == b.dtype, name
        assert a.tobytes() == b.tobytes(), name  # bit for bit (signed zeros too)


@settings(max_examples=80, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m=hs.integers(0, 25), n=hs.integers(1, 25), unsorted=hs.booleans(),
       zeros=hs.booleans(), wide=hs.booleans())
def test_csr_to_csc_is_scipys_tocsc(seed: int, m: int, n: int, unsorted: bool, zeros: bool, wide: bool) -> None:
    """The arrays of ``tocsc()``: each column's entries in the order of their rows (whatever the
    order of a CSR row's entries), the index type scipy picks (int32, or int64 for int64 input),
    the values bit for bit, and the matrix they make is the same matrix (dense comparison)."""
    rng = np.random.default_rng(seed)
    A = _random_csr(rng, m, n, unsorted, zeros)
    ref = A.tocsc()
    for ptr, ind in ((A.indptr, A.indices), (A.indptr.astype(np.int64), A.indices.astype(np.int64))):
        Ax = sp.csr_matrix((A.data, ind, ptr), shape=A.shape)
        Ax.indices, Ax.indptr = ind, ptr  # keep the index type given (scipy may narrow it)
        want = Ax.tocsc()
        got_ptr, got_ind, got_data = csr_to_csc(ptr, ind, A.data, A.shape)
        # the type tocsc computes on (its matrix's constructor then narrows int64 indices that fit)
        assert got_ptr.dtype == got_ind.dtype == ptr.dtype
        assert sp.csc_matrix((got_data, got_ind, got_ptr), shape=A.shape).indices.dtype == want.indices.dtype
        assert np.array_equal(got_ptr, want.indptr) and np.array_equal(got_ind, want.indices)
        assert got_data.tobytes() == want.data.tobytes()
        assert np.array_equal(got_ptr, ref.indptr) and np.array_equal(got_ind, ref.indices)
        # sorted row indices in every column, and the same matrix
        for a, b in zip(got_ptr[:-1], got_ptr[1:]):
            assert np.all(np.diff(got_ind[a:b]) > 0)
        C = sp.csc_matrix((got_data, got_ind, got_ptr), shape=A.shape)
        assert np.array_equal(C.toarray(), A.toarray())


@settings(max_examples=60, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m1=hs.integers(0, 15), m2=hs.integers(0, 15), n=hs.integers(1, 20),
       unsorted=hs.booleans(), zeros=hs.booleans())
def test_stacked_is_vstack_then_tocsc(seed: int, m1: int, m2: int, n: int, unsorted: bool, zeros: bool) -> None:
    """``_stacked(top, below)`` is scipy's ``[top; below]`` (CSR, every stored entry kept) converted
    by ``tocsc``: the same arrays and types, marked sorted as ``tocsc`` marks them, and the same
    products (the verification's ``A z`` and ``Aᵀ y``)."""
    rng = np.random.default_rng(seed)
    top, below = _random_csr(rng, m1, n, unsorted, zeros), _random_csr(rng, m2, n, unsorted, zeros)
    indptr = np.concatenate((top.indptr, top.indptr[-1] + below.indptr[1:]))
    ref = sp.csr_matrix((np.concatenate((top.data, below.data)), np.concatenate((top.indices, below.indices)),
                         indptr), shape=(m1 + m2, n)).tocsc()
    got = _stacked(top, below)
    _same_arrays(got, ref)
    assert got.__dict__.get("_has_sorted_indices") is True and ref.__dict__.get("_has_sorted_indices") is True
    assert "_has_canonical_format" not in got.__dict__
    assert np.array_equal(got.toarray(), sp.vstack([top, below]).toarray())
    z, y = rng.standard_normal(n), rng.standard_normal(m1 + m2)
    assert (got @ z).tobytes() == (ref @ z).tobytes() and (got.T @ y).tobytes() == (ref.T @ y).tobytes()


@settings(max_examples=60, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m1=hs.integers(0, 12), m2=hs.integers(1, 20), n=hs.integers(1, 20),
       unsorted=hs.booleans(), zeros=hs.booleans(), wide=hs.booleans())
def test_stack_rows_is_row_selection_then_tocsc(seed: int, m1: int, m2: int, n: int, unsorted: bool, zeros: bool,
                                                wide: bool) -> None:
    """``_stack_rows(top, A, rows)`` (the backend's working rows) has the arrays of the former
    implementation (a stable sort by column of ``[top; A[rows]]``'s row-major entries, every
    stored entry kept, explicit zeros too): the same types and bytes, whatever the index type of
    ``A``; and it is that matrix."""
    rng = np.random.default_rng(seed)
    top, A = _random_csr(rng, m1, n, unsorted, zeros), _random_csr(rng, m2, n, unsorted, zeros)
    if wide:
        A.indices, A.indptr = A.indices.astype(np.int64), A.indptr.astype(np.int64)
    rows = np.sort(rng.choice(m2, size=int(rng.integers(1, m2 + 1)), replace=False)).astype(np.int64)
    _same_arrays(_stack_rows(top, A, rows), _stack_rows_former(top, A, rows))
    got = _stack_rows(top, A, rows)
    assert np.array_equal(got.toarray(), sp.vstack([top, A[rows]]).toarray())


@settings(max_examples=40, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m=hs.integers(1, 20), n=hs.integers(1, 15))
def test_kkt_check_transpose_is_a_T(seed: int, m: int, n: int) -> None:
    """:class:`KKTCheck`'s ``Aᵀ`` of a CSC ``A`` is ``A.T``: a CSR matrix of the same three arrays,
    so ``Aᵀ y`` is the same bit for bit."""
    rng = np.random.default_rng(seed)
    A = _stacked(_random_csr(rng, m, n, False, True), sp.csr_matrix((0, n)))
    P = sp.csc_matrix(sp.triu(sp.random(n, n, density=0.4, random_state=rng) + sp.eye(n)))
    l, u = np.full(m, -np.inf), rng.standard_normal(m)
    check = KKTCheck(P, np.zeros(n), A, l, u, 0)
    ref = A.T
    _same_arrays(check.AT, ref)
    assert check.AT.data is A.data and check.AT.indices is A.indices and check.AT.indptr is A.indptr
    y = rng.standard_normal(m)
    assert (check.AT @ y).tobytes() == (ref @ y).tobytes()


@settings(max_examples=40, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m=hs.integers(1, 20), n=hs.integers(1, 15))
def test_matvec_is_scipys_product(seed: int, m: int, n: int) -> None:
    """:func:`~iamp.planners.qp.backends.base.matvec` of a CSR, CSC and COO float matrix is
    ``M @ x`` bit for bit (explicit zeros, duplicate COO entries summed in stored order); an
    integer vector goes to ``@``."""
    rng = np.random.default_rng(seed)
    C = sp.random(m, n, density=0.4, random_state=rng, format="coo")
    C = sp.coo_matrix((np.r_[C.data, C.data[:3]], (np.r_[C.row, C.row[:3]], np.r_[C.col, C.col[:3]])), shape=(m, n))
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 8, n)
    y = rng.standard_normal(m)
    for M in (sp.csr_matrix(C), sp.csc_matrix(C), C):
        assert type(matvec(M, x)) is np.ndarray and matvec(M, x).tobytes() == (M @ x).tobytes()
    for M in (sp.csc_matrix(C).T, sp.csr_matrix(C).T, C.T):
        assert matvec(M, y).tobytes() == (M @ y).tobytes()
    xi = rng.integers(-5, 5, n)
    assert np.array_equal(matvec(sp.csr_matrix(C), xi), sp.csr_matrix(C) @ xi)


class _ScanGridFormer:
    """``ScanGrid`` as it was (``numpy.ceil``)."""

    def __init__(self, tf: float) -> None:
        self.tf = float(tf)
        self.size = max(2, int(np.ceil(self.tf / 1e-3)) + 1)
        self.step = self.tf / (self.size - 1)
        self.at = ScanGrid.at.__get__(self)
        self.full = ScanGrid.full.__get__(self)
        self.last_at_or_below = ScanGrid.last_at_or_below.__get__(self)


def _leave_time_former(traj: Any, plane: HalfPlane, tf: float) -> float:
    """``leave_time`` as it was (main a053b78)."""
    grid = _ScanGridFormer(tf)
    axis = 0 if plane.axis == "x" else 2

    def margin(x: np.ndarray) -> np.ndarray:
        return np.asarray(plane.margin(x, traj.states(x)[:, axis]), dtype=float)

    exact = _scan_bracket_former(traj, plane, grid, margin)
    if exact is None:
        inside = np.flatnonzero(margin(grid.full()) >= -1e-12)
        if inside.size == 0:
            return 0.0
        k = int(inside[-1])
    else:
        k, root = exact
        if k < 0:
            return 0.0
        if root is not None:
            return float(min(max(root, grid.at(k)), grid.at(k + 1)))
    if k == grid.size - 1:
        return float(tf)

    def g(x: float) -> float:  # the same 1e-12 m tolerance as the scan: a sign change is bracketed
        return float(margin(np.array([x]))[0]) + 1e-12

    return float(optimize.brentq(g, grid.at(k), grid.at(k + 1), xtol=1e-13))


def _scan_bracket_former(traj: Any, plane: HalfPlane, t: ScanGrid, margin: Any) -> tuple[int, float | None] | None:
    """``_scan_bracket`` as it was (main a053b78)."""

    nodes, X, U = (getattr(traj, name, None) for name in ("t_nodes", "X", "U"))
    hold = getattr(traj, "hold", None)
    if nodes is None or X is None or U is None or hold not in ("foh", "zoh"):
        return None
    nodes = np.asarray(nodes, dtype=float)
    h = np.diff(nodes)
    a = 0 if plane.axis == "x" else 1
    s0, v0 = X[:-1, 2 * a], X[:-1, 2 * a + 1]
    u0 = U[:h.size, a]
    du = (U[1:, a] - U[:-1, a]) / h if hold == "foh" else np.zeros(h.size)
    S = np.stack([s0, v0 * h, u0 * h**2 / 2, du * h**3 / 6], axis=1)  # s(t_k + σ h) in σ
    v = plane.vehicle
    if plane.axis == "x":
        xs = shifted_poly(v.x_poly, nodes[:-1], h, max(3, len(v.x_poly) - 1))
        half = v.length / 2 + v.safety_x
        c = -xs if plane.sigma < 0 else xs
        c[:, 0] += -half
    else:
        c = np.zeros((h.size, 4))
        c[:, 0] = -(v.y + v.width / 2 + v.safety_y) if plane.sigma < 0 else v.y - (v.width / 2 + v.safety_y)
    M = np.zeros((h.size, max(c.shape[1], 4)))
    M[:, :c.shape[1]] += c
    M[:, :4] -= plane.sigma * S
    M[:, 0] += 1e-12
    rows, sig = roots_in_unit_interval(M)
    # the margin at the scan points the answer needs (t_k and t_{k+1} around the last root, or
    # t_0 without a root) and at t_f, in one call (the trajectory is evaluated point by point:
    # the numbers of one call per point)
    if rows.size == 0:
        first, end = margin(np.array([t.at(0), t.at(t.size - 1)]))
        if end >= -1e-12:
            return int(t.size - 1), None
        return (-1, None) if first < -1e-12 else None
    last = float(np.max(nodes[:-1][rows] + np.clip(sig, 0.0, 1.0) * h[rows]))
    k = min(max(t.last_at_or_below(last), 0), t.size - 2)
    at_k, at_k1, end = margin(np.array([t.at(k), t.at(k + 1), t.at(t.size - 1)]))
    if end >= -1e-12:
        return int(t.size - 1), None
    if at_k >= -1e-12 and at_k1 < -1e-12:
        return k, last
    return None


@settings(max_examples=200, deadline=None)
@given(tf=hs.floats(1e-6, 60.0, allow_nan=False))
def test_scan_grid_is_linspace(tf: float) -> None:
    """``ScanGrid``'s size is ``max(2, ceil(t_f / 1e-3) + 1)`` as numpy computes it, and its
    points are ``linspace``'s."""
    grid, old = ScanGrid(tf), _ScanGridFormer(tf)
    assert grid.size == old.size and type(grid.size) is int and grid.step == old.step
    full = np.linspace(0.0, tf, grid.size)
    for k in (0, 1, grid.size // 2, grid.size - 2, grid.size - 1):
        assert grid.at(k) == full[k]


def _trajectory(rng: np.random.Generator, N: int, hold: str, axis: str, centre: float) -> HoldTrajectory:
    """A held trajectory whose ``axis`` position wanders about ``centre`` (random nodes and inputs:
    the margin's polynomial per piece is what the trajectory evaluates, consistent or not)."""
    tf = float(rng.uniform(2.0, 12.0))
    t = np.linspace(0.0, tf, N + 1)
    X = rng.standard_normal((N + 1, 4))
    a = 0 if axis == "x" else 2
    X[:, a] = centre + np.cumsum(rng.standard_normal(N + 1)) * float(rng.uniform(0.05, 1.5))
    X[:, a + 1] *= float(rng.uniform(0.1, 3.0))
    U = rng.standard_normal((N + 1 if hold == "foh" else N, 2)) * float(rng.uniform(0.0, 2.0))
    return HoldTrajectory(t, X, U, hold)


@settings(max_examples=120, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), N=hs.integers(2, 30), foh=hs.booleans(), axis=hs.sampled_from(["x", "y"]),
       corner=hs.sampled_from(["front-lower", "front-upper", "rear-lower", "rear-upper"]),
       quadratic=hs.booleans())
def test_leave_time_is_the_former(seed: int, N: int, foh: bool, axis: str, corner: str, quadratic: bool) -> None:
    """``leave_time`` returns the former implementation's float, bit for bit (the exact-root path,
    the scan and Brent's method), and it is a time in ``[0, t_f]``, before ``t_f`` only when the
    trajectory ends outside the half-plane (margin below -1e-12)."""
    rng = np.random.default_rng(seed)
    x_poly = (float(rng.uniform(-20, 20)), float(rng.uniform(0, 25)))
    if quadratic:
        x_poly += (float(rng.uniform(-1, 1)),)
    v = SurroundingVehicle(x_poly=x_poly, corner=corner, y=float(rng.uniform(-4, 4)), length=4.8, width=1.8,
                           safety_x=float(rng.uniform(0, 5)), safety_y=0.5)
    plane = HalfPlane(v, axis)
    traj = _trajectory(rng, N, "foh" if foh else "zoh", axis, float(plane.bound(np.array([0.0]))[0]) * plane.sigma)
    tf = float(traj.t_nodes[-1])
    new, old = leave_time(traj, plane, tf), _leave_time_former(traj, plane, tf)
    assert type(new) is float and np.float64(new).tobytes() == np.float64(old).tobytes()
    assert 0.0 <= new <= tf
    if new < tf:  # the trajectory ends outside the half-plane
        end = traj.states(np.array([tf]))[:, 0 if axis == "x" else 2]
        assert float(plane.margin(np.array([tf]), end)[0]) < -1e-12


@pytest.mark.parametrize("three", [False, True])
def test_leave_time_of_plans_is_the_former(three: bool) -> None:
    """On the overtakes' plans (one and three vehicles), every vehicle's leave time is the former
    implementation's, bit for bit."""
    from iamp.planners import registry

    problem = overtake_three_problem() if three else overtake_problem()
    plan = registry.make_planner("qp-avoid", steps=30, hold="foh", solver="piqp", safety="continuous").plan(problem)
    for v in problem.vehicles:
        for axis in ("x", "y"):
            plane = HalfPlane(v, axis)
            new = leave_time(plan.trajectory, plane, problem.tf)
            old = _leave_time_former(plan.trajectory, plane, problem.tf)
            assert np.float64(new).tobytes() == np.float64(old).tobytes()


def test_with_rhs_is_the_former_copy() -> None:
    """``with_rhs`` is ``copy.copy`` of the solver with the new ``b_eq`` and its equality optimum:
    every other attribute the same object (the factorisation and the solved columns shared), the
    optimum the LU's solve of ``(0, b_eq)`` bit for bit, and the solutions of a QP the same."""
    import copy

    problem = overtake_problem()
    d = AvoidData(problem, np.linspace(0.0, problem.tf, 21), "foh")
    A_eq = sp.csr_matrix(d.A[:d.n_eq])
    base = SchurActiveSet(d.P, A_eq, d.b_eq)
    rng = np.random.default_rng(5)
    b = d.b_eq + rng.standard_normal(d.b_eq.size) * 0.1
    new = base.with_rhs(b)
    old = copy.copy(base)
    old.b_eq = np.asarray(b, dtype=float)
    old._x0 = np.asarray(base.lu.solve(np.r_[np.zeros(base.n), old.b_eq]), dtype=float)
    old.z0 = old._x0[:base.n].copy()
    old.columns = 0
    assert type(new) is SchurActiveSet and new is not base
    assert new.__dict__.keys() == old.__dict__.keys()
    for k, v in old.__dict__.items():
        w = new.__dict__[k]
        if isinstance(v, np.ndarray) and k in ("b_eq", "_x0", "z0"):
            assert w.dtype == v.dtype and w.tobytes() == v.tobytes() and w is not base.__dict__[k]
        else:
            assert w is v or w == v, k
    assert new.z0.tobytes() == np.asarray(base.lu.solve(np.r_[np.zeros(base.n), b]))[:base.n].tobytes()
    A_in = sp.csr_matrix(d.A[d.n_eq:])
    u_in = d.bounds(np.ones(d.n_rows - d.n_eq, dtype=bool))[1][d.n_eq:]
    r_new, r_old = new.solve(A_in, u_in), old.solve(A_in, u_in)
    assert r_new.status == r_old.status
    assert r_new.z.tobytes() == r_old.z.tobytes() and r_new.y.tobytes() == r_old.y.tobytes()
    with pytest.raises(ValueError):
        base.with_rhs(np.zeros(3))


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_avoid_data_builds_the_same_matrices(hold: str) -> None:
    """``AvoidData`` with ``h``, ``α``, ``γ`` computed where the matrices are built: the dynamics
    rows are the module docstring's (``α = h²/3`` FOH, ``h²/2`` ZOH; ``γ = h/2``, ``h``), on a
    non-uniform grid too, and a grid kept in a share gives the same arrays."""
    from iamp.planners.avoid.continuous import GridShare

    problem = overtake_three_problem()
    rng = np.random.default_rng(3)
    t = np.concatenate(([0.0], np.sort(rng.uniform(0.0, problem.tf, 9)), [problem.tf]))
    d = AvoidData(problem, t, hold)
    h = np.diff(t)
    alpha, gamma = (h**2 / 3, h / 2) if hold == "foh" else (h**2 / 2, h)
    A = d.A.toarray()
    for axi in range(2):
        for k in range(d.N):
            rp, rv = axi * (2 * d.N + 4) + k, axi * (2 * d.N + 4) + d.N + k
            assert A[rp, d.idx_s(axi, k + 1)] == 1.0 and A[rp, d.idx_s(axi, k)] == -1.0
            assert A[rp, d.idx_v(axi, k)] == -h[k] and A[rp, d.idx_u(axi, k)] == -alpha[k]
            assert A[rv, d.idx_u(axi, k)] == -gamma[k]
            if hold == "foh":
                assert A[rp, d.idx_u(axi, k + 1)] == -h[k] ** 2 / 6 and A[rv, d.idx_u(axi, k + 1)] == -h[k] / 2
    share = GridShare()
    first = AvoidData(problem, t, hold, shared=share)
    again = AvoidData(problem, t, hold, shared=share)
    assert again.A is first.A and again.P is first.P
    for name in ("data", "indices", "indptr"):
        assert getattr(first.A, name).tobytes() == getattr(d.A, name).tobytes()
        assert getattr(first.P, name).tobytes() == getattr(d.P, name).tobytes()


@settings(max_examples=40, deadline=None)
@given(seed=hs.integers(0, 2**31 - 1), m=hs.integers(1, 20), n=hs.integers(1, 15), unsorted=hs.booleans())
def test_csc_copy_keeps_a_known_sorted_flag_only(seed: int, m: int, n: int, unsorted: bool) -> None:
    """:func:`~iamp.planners.qp.backends.base.csc_copy` of a CSC matrix that knows its indices are
    sorted (``_stack_rows``' result, a matrix after ``sort_indices``) has the arrays of the copy
    of the same matrix without that knowledge, and is itself known sorted; an unsorted matrix is
    sorted as before (its flag, ``False``, is found again)."""
    from iamp.planners.qp.backends.base import csc_copy

    rng = np.random.default_rng(seed)
    top, A = _random_csr(rng, m, n, unsorted, True), _random_csr(rng, m, n, unsorted, True)
    rows = np.arange(m, dtype=np.int64)
    known = _stack_rows(top, A, rows)
    assert known.__dict__.get("_has_sorted_indices") is True
    fresh = compressed(sp.csc_matrix, known.data.copy(), known.indices.copy(), known.indptr.copy(), known.shape)
    assert "_has_sorted_indices" not in fresh.__dict__
    a, b = csc_copy(known), csc_copy(fresh)
    _same_arrays(a, b)
    assert a.__dict__.get("_has_sorted_indices") is True and b.has_sorted_indices
    assert "_has_canonical_format" not in a.__dict__
    C = sp.csc_matrix(A.T)  # rows reversed in each column when unsorted
    if not C.has_sorted_indices:
        out = csc_copy(C)
        ref = sp.csc_matrix(C, dtype=float, copy=True)
        ref.sort_indices()
        _same_arrays(out, ref)


@pytest.mark.parametrize("three", [False, True])
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_avoid_data_bounds_are_the_rows(three: bool, hold: str) -> None:
    """``AvoidData``'s row bounds ``c_on`` (written block by block) are each half-plane's ``c(t)``
    at the interior nodes in the rows :meth:`~iamp.planners.avoid.data.AvoidData.row` names, and
    ``b_eq`` holds the boundary values in each axis's four boundary rows, as the former fancy
    indexing wrote them."""
    problem = overtake_three_problem() if three else overtake_problem()
    d = AvoidData(problem, np.linspace(0.0, problem.tf, 17), hold)
    c_on = np.zeros(d.n_rows - d.n_eq)
    for i, pair in enumerate(d.planes):
        for a, hp in enumerate(pair):
            c_on[d.row(i, a, d.interior) - d.n_eq] = hp.bound(d.t_nodes[d.interior])
    assert d.c_on.tobytes() == c_on.tobytes()
    ego, N = problem.ego, d.N
    b_eq = np.zeros(d.n_eq)
    for axi, vals in enumerate(((ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf))):
        b_eq[axi * (2 * N + 4) + 2 * N + np.arange(4)] = vals
    assert d.b_eq.tobytes() == b_eq.tobytes()


def test_diagnostics_field_names_are_the_dataclass_fields() -> None:
    """``field_names`` (kept per class) is every family's typed fields, each class its own."""
    from dataclasses import fields

    from iamp.core.diagnostics import Diagnostics
    from iamp.planners.avoid.diagnostics import AvoidDiagnostics
    from iamp.planners.qp.diagnostics import QPDiagnostics

    for cls in (Diagnostics, QPDiagnostics, AvoidDiagnostics, Diagnostics, AvoidDiagnostics):
        want = tuple(f.name for f in fields(cls) if f.name not in ("extra", "order"))
        assert cls.field_names() == want
    assert "safety_mode" in AvoidDiagnostics.field_names() and "safety_mode" not in Diagnostics.field_names()
    info = {"safety_mode": "continuous", "kkt": {"a": 1.0}, "unknown_key": 3, "reason": None}
    d = AvoidDiagnostics.from_info(info)
    assert d.safety_mode == "continuous" and d.extra == {"unknown_key": 3} and d.as_info() == info


def test_without_scipy_s_private_routines_the_public_api_gives_the_same_arrays(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where scipy has no ``scipy.sparse._sparsetools`` (a private module another scipy may move),
    ``csr_to_csc`` and ``matvec`` fall back on ``tocsc`` and ``@``: the same arrays and numbers as the
    direct calls."""
    from iamp.planners.qp.backends import base

    rng = np.random.default_rng(35)
    A = sp.random(40, 30, density=0.2, format="csr", random_state=rng)
    x = rng.standard_normal(30)
    fast = csr_to_csc(A.indptr, A.indices, A.data, A.shape)
    direct = [matvec(M, x) for M in (A, A.tocsc(), A.tocoo())]
    monkeypatch.setattr(base, "_sparsetools", None)
    monkeypatch.setattr(base, "_MATVEC", {})
    slow = csr_to_csc(A.indptr, A.indices, A.data, A.shape)
    for a, b in zip(fast, slow):
        assert np.array_equal(a, b)
    for M, want in zip((A, A.tocsc(), A.tocoo()), direct):
        assert np.array_equal(matvec(M, x), want) and np.array_equal(want, M @ x)
