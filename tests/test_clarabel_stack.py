"""Clarabel's stacked constraint matrix: the shortcut for a row split that keeps every row in place
(equalities first, then upper sides only: the avoidance QP's rows) equals the long way, stacking
the row slices ``[A[eq]; A[up]; -A[lo]]`` and their source positions, array for array."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hst

pytest.importorskip("clarabel")

from iamp.planners.qp.backends.clarabel import ClarabelBackend


def _long_way(A: sp.csc_matrix, l: np.ndarray, u: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    eq = np.flatnonzero(l == u)
    up = np.flatnonzero((l != u) & np.isfinite(u))
    lo = np.flatnonzero((l != u) & np.isfinite(l))
    tag = sp.csc_matrix((np.arange(1.0, A.nnz + 1.0), A.indices, A.indptr), shape=A.shape)
    T = sp.vstack([tag[eq], tag[up], -tag[lo]], format="csc")
    perm = np.abs(T.data).astype(np.int64) - 1
    sign = np.sign(T.data)
    return sp.csc_matrix((A.data[perm] * sign, T.indices, T.indptr), shape=T.shape), perm, sign


@settings(max_examples=60, deadline=None)
@given(seed=hst.integers(0, 2**31 - 1), in_place=hst.booleans())
def test_the_stacked_matrix_equals_the_slices_stack(seed: int, in_place: bool) -> None:
    rng = np.random.default_rng(seed)
    n, n_eq, n_in = int(rng.integers(2, 8)), int(rng.integers(1, 5)), int(rng.integers(1, 8))
    m = n_eq + n_in
    dense = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.5)
    dense[:, 0] += 1.0  # no empty row
    A = sp.csc_matrix(dense)
    zero = rng.random(A.nnz) < 0.2  # explicit zeros stay in the pattern
    A.data[zero] = 0.0
    b = rng.normal(size=n_eq)
    if in_place:
        l = np.r_[b, np.full(n_in, -np.inf)]
        u = np.r_[b, rng.normal(size=n_in)]
    else:  # rows out of place: lower sides, two-sided and free rows, equalities last
        kind = rng.integers(0, 4, size=n_in)
        lo_in = np.where((kind == 1) | (kind == 2), rng.normal(size=n_in) - 2.0, -np.inf)
        up_in = np.where((kind == 0) | (kind == 2), rng.normal(size=n_in) + 2.0, np.inf)
        l, u = np.r_[lo_in, b], np.r_[up_in, b]
        A = sp.csc_matrix(sp.vstack([A[n_eq:], A[:n_eq]]))
        A.data[:] = np.where(rng.random(A.nnz) < 0.2, 0.0, A.data)
    be = ClarabelBackend(sp.identity(n, format="csc"), np.zeros(n), A, l, u)
    got, rhs = be._stacked()
    want, perm, sign = _long_way(be.A, be.l, be.u)
    assert got.shape == want.shape
    assert np.array_equal(got.indptr, want.indptr) and np.array_equal(got.indices, want.indices)
    assert np.array_equal(got.data, want.data)  # explicit zeros included
    assert got.indices.dtype == want.indices.dtype and got.indptr.dtype == want.indptr.dtype
    assert np.array_equal(be._perm, perm) and np.array_equal(be._sign, sign)
    assert np.array_equal(rhs, be._rhs())
    # a value update gathers the same numbers as stacking the slices again
    new = rng.normal(size=be.A.nnz)
    be.update(Ax=new)
    want2, _, _ = _long_way(be.A, be.l, be.u)
    assert np.array_equal(be.A.data[be._perm] * be._sign, want2.data)
