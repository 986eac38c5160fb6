"""Solution polish (:mod:`iamp.planners.qp.backends.polish`): a backend's answer refined on the
active set it identifies.

* On random strictly convex QPs with inequality rows, PIQP stopped at a loose duality gap costs
  more than the optimum (Clarabel at 1e-12, the reference); polished, its point meets the KKT
  conditions recomputed from the data to round-off and costs the reference's optimum, on the
  reference's active set.
* Two identical active rows (a singular KKT matrix if both were held) are held once.
* The polish certifies nothing itself: a wrongly identified active set gives a point that fails
  the KKT conditions (so the caller keeps the backend's answer).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from iamp.core import status as st
from iamp.planners.qp.backends import get_backend
from iamp.planners.qp.backends.base import kkt_residuals
from iamp.planners.qp.backends.polish import active_rows, polish


def random_qp(seed: int, n: int = 12, m_eq: int = 3, m_in: int = 14):  # type: ignore[no-untyped-def]
    """``min ½zᵀPz + qᵀz`` with equality rows and one-sided rows, several of them binding."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    P = M.T @ M + 0.1 * np.eye(n)
    q = rng.standard_normal(n) * 3.0
    A = rng.standard_normal((m_eq + m_in, n))
    z_free = np.linalg.solve(P, -q)
    b = A[:m_eq] @ z_free + rng.standard_normal(m_eq)
    # bounds that cut the unconstrained optimum: roughly half of the rows bind
    u_in = A[m_eq:] @ z_free - rng.uniform(-1.0, 1.0, m_in)
    l = np.r_[b, np.full(m_in, -np.inf)]
    u = np.r_[b, u_in]
    return sp.triu(sp.csc_matrix(P)).tocsc(), q, sp.csc_matrix(A), l, u


def cost(P: sp.spmatrix, q: np.ndarray, z: np.ndarray) -> float:
    full = P + sp.triu(P, 1).T
    return float(0.5 * z @ (full @ z) + q @ z)


@pytest.mark.parametrize("seed", range(8))
def test_a_loose_interior_point_answer_polishes_to_the_optimum(seed: int) -> None:
    P, q, A, l, u = random_qp(seed)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    assert ref.status == st.OPTIMAL
    loose = get_backend("piqp")(P, q, A, l, u, {"eps_abs": 1e-6, "eps_duality_gap_abs": 1e-5,
                                                 "eps_duality_gap_rel": 1e-6}).solve()
    assert loose.status == st.OPTIMAL
    J, J_loose = cost(P, q, ref.z), cost(P, q, loose.z)
    out = polish(P, q, A, l, u, loose.z, loose.y)
    assert out is not None
    r = kkt_residuals(P, q, A, l, u, out.z, out.y)
    assert max(r.primal_rel, r.dual_rel, r.gap_rel) <= 1e-12, r
    assert cost(P, q, out.z) == pytest.approx(J, rel=1e-12, abs=1e-12)
    assert abs(cost(P, q, out.z) - J) <= abs(J_loose - J)
    rows_ref, _ = active_rows(A, l, u, ref.z, ref.y)
    rows, _ = active_rows(A, l, u, loose.z, loose.y)
    assert np.array_equal(rows, rows_ref)


def test_identical_active_rows_are_held_once() -> None:
    P, q, A, l, u = random_qp(3)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    rows, _ = active_rows(A, l, u, ref.z, ref.y)
    dup = int(rows[-1])  # an active inequality row, twice (the second with a looser bound)
    A2 = sp.vstack([A, A[dup]]).tocsc()
    l2, u2 = np.r_[l, -np.inf], np.r_[u, u[dup] + 1e-14]
    y2 = np.r_[ref.y, 0.5 * ref.y[dup]]
    y2[dup] *= 0.5
    kept, bounds = active_rows(A2, l2, u2, np.r_[ref.z], y2)
    assert dup in kept and A2.shape[0] - 1 not in kept and bounds[list(kept).index(dup)] == u[dup]
    out = polish(P, q, A2, l2, u2, ref.z, y2)
    assert out is not None
    r = kkt_residuals(P, q, A2, l2, u2, out.z, out.y)
    assert max(r.primal_rel, r.dual_rel, r.gap_rel) <= 1e-12
    assert cost(P, q, out.z) == pytest.approx(cost(P, q, ref.z), rel=1e-12)


def test_a_wrong_active_set_fails_the_kkt_check() -> None:
    P, q, A, l, u = random_qp(5)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    rows, _ = active_rows(A, l, u, ref.z, ref.y)
    active_in = [int(r) for r in rows if l[r] != u[r]]
    assert active_in
    y = ref.y.copy()
    y[active_in[0]] = 0.0  # a binding row missed: the polished point violates it
    out = polish(P, q, A, l, u, ref.z + 0.0, y)
    assert out is not None
    r = kkt_residuals(P, q, A, l, u, out.z, out.y)
    assert r.primal_rel > 1e-6


def two_sided_qp(seed: int, n: int = 10, m_eq: int = 2, m_in: int = 12):  # type: ignore[no-untyped-def]
    """Rows ``l <= a_i z <= u``, each cutting the unconstrained optimum from the side of a point
    ``z0`` that keeps them all (feasible by construction): a row with ``a_i (z0 - z_free) > 0``
    has its lower bound between the two, the others their upper bound."""
    rng = np.random.default_rng(100 + seed)
    M = rng.standard_normal((n, n))
    P = M.T @ M + 0.1 * np.eye(n)
    q = rng.standard_normal(n) * 3.0
    A = rng.standard_normal((m_eq + m_in, n))
    z_free = np.linalg.solve(P, -q)
    z0 = z_free + rng.standard_normal(n)
    b = A[:m_eq] @ z0
    at, step = A[m_eq:] @ z_free, A[m_eq:] @ (z0 - z_free)
    mid = at + rng.uniform(0.3, 0.7, m_in) * step
    l_in = np.where(step > 0, mid, mid - 10.0)
    u_in = np.where(step > 0, mid + 10.0, mid)
    return (sp.triu(sp.csc_matrix(P)).tocsc(), q, sp.csc_matrix(A), np.r_[b, l_in], np.r_[b, u_in], m_eq)


@pytest.mark.parametrize("seed", range(6))
def test_rows_at_their_lower_bound_are_held_there(seed: int) -> None:
    """Two-sided rows: a row is held at ``l`` when ``-y`` exceeds its slack ``a z - l``, at ``u``
    when ``y`` exceeds ``u - a z`` (the reference's active set, each at the bound it binds)."""
    P, q, A, l, u, m_eq = two_sided_qp(seed)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    assert ref.status == st.OPTIMAL
    rows, bounds = active_rows(A, l, u, ref.z, ref.y)
    Az = A @ ref.z
    at_l = np.flatnonzero((np.arange(l.size) >= m_eq) & (np.abs(Az - l) <= 1e-7) & (ref.y < -1e-7))
    at_u = np.flatnonzero((np.arange(l.size) >= m_eq) & (np.abs(Az - u) <= 1e-7) & (ref.y > 1e-7))
    assert at_l.size and at_u.size  # the draw exercises both sides
    assert set(at_l) | set(at_u) | set(range(m_eq)) == set(rows.tolist())
    held = dict(zip(rows.tolist(), bounds.tolist()))
    assert all(held[r] == l[r] for r in at_l) and all(held[r] == u[r] for r in at_u)
    loose = get_backend("piqp")(P, q, A, l, u, {"eps_abs": 1e-6, "eps_duality_gap_abs": 1e-5,
                                                 "eps_duality_gap_rel": 1e-6}).solve()
    out = polish(P, q, A, l, u, loose.z, loose.y)
    assert out is not None and out.status == st.OPTIMAL
    assert out.raw_status == "polished" and out.iterations == 1
    r = kkt_residuals(P, q, A, l, u, out.z, out.y)
    assert max(r.primal_rel, r.dual_rel, r.gap_rel) <= 1e-12, r
    assert cost(P, q, out.z) == pytest.approx(cost(P, q, ref.z), rel=1e-12, abs=1e-12)
    # multipliers only on the held rows, with the sign of their side
    off = np.setdiff1d(np.arange(l.size), rows)
    assert np.all(out.y[off] == 0.0)
    assert np.all(out.y[at_l] < 0) and np.all(out.y[at_u] > 0)


@pytest.mark.parametrize("side", ["upper", "lower"])
def test_of_identical_rows_the_tighter_bound_is_held_wherever_it_comes(side: str) -> None:
    """The tighter of two identical rows on one side is held (the smaller ``u``, the larger ``l``),
    whether it comes first or second; a row equal to an active one but on the other side is not
    merged with it."""
    P, q, A, l, u, m_eq = two_sided_qp(1)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    rows, _ = active_rows(A, l, u, ref.z, ref.y)
    sign = 1.0 if side == "upper" else -1.0
    r0 = next(int(r) for r in rows if r >= m_eq and sign * ref.y[r] > 0)
    for looser_first in (True, False):
        shift = sign * 1e-3  # the copy is looser: u + 1e-3 (upper), l - 1e-3 (lower)
        lc, uc = (l[r0], u[r0] + shift) if side == "upper" else (l[r0] + shift, u[r0])
        if looser_first:  # the looser copy in place of r0, the tight row appended
            A2 = sp.vstack([A, A[r0]]).tocsc()
            l2, u2 = np.r_[l, l[r0]], np.r_[u, u[r0]]
            l2[r0], u2[r0] = lc, uc
            tight, loose = A.shape[0], r0
        else:
            A2 = sp.vstack([A, A[r0]]).tocsc()
            l2, u2 = np.r_[l, lc], np.r_[u, uc]
            tight, loose = r0, A.shape[0]
        z = ref.z
        y2 = np.r_[ref.y, 0.0]
        # both copies look active: multipliers above their slacks
        y2[tight] = y2[loose] = 0.5 * ref.y[r0] + sign * 2e-3
        kept, bounds = active_rows(A2, l2, u2, z, y2)
        assert tight in kept and loose not in kept, (side, looser_first, kept)
        assert bounds[list(kept).index(tight)] == (u[r0] if side == "upper" else l[r0])


def test_no_polish_from_a_point_that_is_not_finite_or_a_singular_active_set() -> None:
    P, q, A, l, u = random_qp(2)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    for bad_z in (True, False):
        z = ref.z.copy()
        y = ref.y.copy()
        (z if bad_z else y)[0] = np.nan
        assert polish(P, q, A, l, u, z, y) is None
    # an active row twice, the copy scaled (not identical: both held): the KKT matrix is singular
    rows, _ = active_rows(A, l, u, ref.z, ref.y)
    r0 = next(int(r) for r in rows if l[r] != u[r])
    A2 = sp.vstack([A, 2.0 * A[r0]]).tocsc()
    l2, u2 = np.r_[l, -np.inf], np.r_[u, 2.0 * u[r0]]
    y2 = np.r_[ref.y, ref.y[r0]]
    assert polish(P, q, A2, l2, u2, ref.z, y2) is None


def test_a_violated_row_without_a_multiplier_is_not_held() -> None:
    """An iterate that violates a row a little (ADMM's, to its tolerance) but gives it no
    multiplier does not name it active: its slack is negative, so ``0 > slack`` alone would."""
    P, q, A, l, u, m_eq = two_sided_qp(0)
    ref = get_backend("clarabel")(P, q, A, l, u).solve()
    rows, _ = active_rows(A, l, u, ref.z, ref.y)
    Az = A @ ref.z
    free_rows = [r for r in range(m_eq, l.size) if r not in set(rows.tolist())]
    assert len(free_rows) >= 2
    l2, u2 = l.copy(), u.copy()
    up, lo = free_rows[0], free_rows[1]
    u2[up] = Az[up] - 1e-7  # violated from above
    l2[lo] = Az[lo] + 1e-7  # violated from below
    y = ref.y.copy()
    y[[up, lo]] = 0.0
    kept, _ = active_rows(A, l2, u2, ref.z, y)
    assert up not in kept and lo not in kept
    assert np.array_equal(kept, rows)


def _active_rows_by_csr(A: sp.spmatrix, l: np.ndarray, u: np.ndarray, z: np.ndarray, y: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The rule of the module docstring, row by row on CSR arrays (the reference)."""
    R = sp.csr_matrix(A)
    Az = R @ z
    rows, bounds, seen = [], [], {}
    for r in range(R.shape[0]):
        if l[r] == u[r]:
            rows.append(r)
            bounds.append(u[r])
            continue
        side = 1 if (y[r] > 0 and y[r] > u[r] - Az[r]) else -1 if (y[r] < 0 and -y[r] > Az[r] - l[r]) else 0
        if side == 0:
            continue
        b = u[r] if side > 0 else l[r]
        a, e = R.indptr[r], R.indptr[r + 1]
        key = (tuple(R.indices[a:e]), tuple(R.data[a:e]), side)
        if key not in seen:
            seen[key] = len(rows)
            rows.append(r)
            bounds.append(b)
        elif side * b < side * bounds[seen[key]]:
            rows[seen[key]], bounds[seen[key]] = r, b
    order = np.argsort(rows)
    return np.asarray(rows, dtype=np.int64)[order], np.asarray(bounds)[order]


@pytest.mark.parametrize("seed", range(40))
def test_active_rows_and_their_matrix_from_the_csc_arrays_are_those_of_the_csr_rows(seed: int) -> None:
    """``active_rows`` reads ``A``'s CSC arrays and the polish gathers the held rows from them: the
    same rows, bounds (duplicate rows, explicit zeros, equalities) and ``A[rows]`` arrays as the
    CSR reference, and the product ``Az`` the same bits as the CSR product."""
    from iamp.planners.qp.backends.base import csc_rows

    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(4, 40)), int(rng.integers(3, 30))
    R = sp.random(m, n, density=0.3, random_state=rng, format="csr")
    R = sp.csr_matrix(R[rng.integers(0, m, size=m)])  # repeated rows
    R.data[rng.random(R.nnz) < 0.2] = 0.0  # explicit zeros
    A = R.tocsc()
    z, y = rng.normal(size=n), rng.normal(size=m)
    Az = R @ z
    assert np.array_equal(A @ z, Az)
    n_eq = int(rng.integers(0, m))
    u = np.r_[Az[:n_eq], Az[n_eq:] + np.where(rng.random(m - n_eq) < 0.5, 0.0, rng.random(m - n_eq))]
    l = np.r_[Az[:n_eq], np.where(rng.random(m - n_eq) < 0.5, -np.inf, Az[n_eq:] - rng.random(m - n_eq))]
    rows, bounds = active_rows(A, l, u, z, y)
    rows_ref, bounds_ref = _active_rows_by_csr(A, l, u, z, y)
    assert np.array_equal(rows, rows_ref) and np.array_equal(bounds, bounds_ref)
    sub, ref = csc_rows(A, rows), sp.csc_matrix(R[rows])
    assert sub.shape == ref.shape
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(sub, name), getattr(ref, name))
