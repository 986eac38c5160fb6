"""Issue 32: the final verification of a continuous-time avoidance plan with fewer calls, the
same numbers bit for bit.

* :func:`~iamp.planners.qp.backends.base.csr_to_csc` gives the arrays of scipy's ``tocsc`` (index
  order, types and values), for sorted and unsorted CSR input and explicit zeros; ``_stacked`` and
  ``_stack_rows`` (the verified QP's and the backend's row stacks) are the ``sp.vstack``/row
  selection they stand for, converted by scipy; :class:`~iamp.planners.avoid.check.KKTCheck`'s
  ``Aᵀ`` is ``A.T``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.planners.avoid.check import KKTCheck
from iamp.planners.avoid.continuous import _stacked
from iamp.planners.avoid.solve import _stack_rows, row_entries
from iamp.planners.qp.backends.base import compressed, csr_to_csc


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
