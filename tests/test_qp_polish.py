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
