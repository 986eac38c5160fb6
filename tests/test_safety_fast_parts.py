"""The safety report's faster parts against the plain computations they replace, bit for bit.

* :func:`iamp.core.polyroots.poly_mul` (transposed, in-place sums) against the row-wise loop;
* :func:`iamp.core.trajectory_pieces.cut_times` (one sort and the merge) against ``numpy.unique``
  then the merge, with duplicates, signed zeros and close times;
* :func:`iamp.core.intrusion._runs` (flag changes) against the scan over the flags;
* :func:`iamp.core.polyroots._eigvals` (numpy's LAPACK ufunc called directly) against
  ``numpy.linalg.eigvals``, as :func:`~iamp.core.polyroots.roots_in_unit_interval` reads them;
* :func:`iamp.core.trajectory_pieces.shifted_poly` (powers computed once) against the sum
  written out;
* :func:`iamp.core.polyroots_kernel.root_degrees` (the largest by ``numpy.maximum``, the degree
  from below, the leading coefficient gathered, Bernstein sums from the first product) against
  its first formulation, with NaN, infinite, huge and signed-zero coefficients (the compiled twin
  against the Python function: ``tests/test_polyroots_kernel.py``).
"""

from __future__ import annotations

from math import comb

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import iamp.core.polyroots as pr
from iamp.core import polyroots_kernel as kernel
from iamp.core.intrusion import _runs
from iamp.core.trajectory_pieces import MERGE_S, cut_times, shifted_poly


def _bits(x: np.ndarray) -> list[int]:
    return np.ascontiguousarray(x, dtype=np.float64).view(np.int64).ravel().tolist()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(0, 40), st.integers(1, 8), st.integers(1, 8))
def test_poly_mul_is_the_row_loop(seed, rows, na, nb):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(rows, na)) * 10.0 ** rng.uniform(-8, 8, (rows, na))
    B = rng.normal(size=(rows, nb)) * 10.0 ** rng.uniform(-8, 8, (rows, nb))
    A[rng.random(A.shape) < 0.2] = 0.0
    B[rng.random(B.shape) < 0.2] = -0.0
    want = np.zeros((rows, na + nb - 1))
    for i in range(na):
        want[:, i:i + nb] += A[:, i:i + 1] * B
    got = pr.poly_mul(A, B)
    assert got.shape == want.shape and got.flags.c_contiguous
    assert _bits(got) == _bits(want)


def _cut_times_reference(breaks, p, sigma):
    a, h = breaks[:-1], np.diff(breaks)
    t = np.unique(np.concatenate((breaks, a[p] + h[p] * sigma)))
    out = t[np.concatenate(([True], np.diff(t) > MERGE_S))]
    out[-1] = breaks[-1]
    return out


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 60), st.integers(0, 80))
def test_cut_times_is_unique_then_the_merge(seed, pieces, roots):
    rng = np.random.default_rng(seed)
    breaks = np.concatenate(([0.0], np.cumsum(rng.uniform(1e-10, 0.2, pieces))))
    if rng.random() < 0.3:
        breaks[0] = -0.0
    p = rng.integers(0, pieces, roots)
    special = rng.choice([0.0, -0.0, 1.0, 0.5, 1e-9, 1 - 1e-9, 2e-9], roots)
    sigma = np.where(rng.random(roots) < 0.5, special, rng.random(roots))
    sigma = np.where(rng.random(roots) < 0.2, np.round(sigma, 2), sigma)  # duplicates
    assert _bits(cut_times(breaks, p, sigma)) == _bits(_cut_times_reference(breaks, p, sigma))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.booleans(), max_size=40))
def test_runs_are_the_scan(flags):
    cuts = np.cumsum(np.arange(len(flags) + 1) * 0.1 + 0.01)
    out, start = [], None
    for j, f in enumerate(flags):
        if f and start is None:
            start = float(cuts[j])
        if not f and start is not None:
            out.append((start, float(cuts[j])))
            start = None
    if start is not None:
        out.append((start, float(cuts[-1])))
    got = _runs(cuts, np.asarray(flags, dtype=bool))
    assert got == tuple(out)
    assert all(type(x) is float for iv in got for x in iv)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 30), st.integers(2, 9))
def test_eigvals_are_numpys(seed, k, d):
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(k, d + 1)) * 10.0 ** rng.uniform(-6, 6, (k, 1))
    C[:, d] = np.where(np.abs(C[:, d]) < 1e-300, 1.0, C[:, d])
    comp = np.zeros((k, d, d))
    comp[:, 1:, :-1] = np.eye(d - 1)
    comp[:, :, -1] = -C[:, :d] / C[:, d:d + 1]
    want = np.linalg.eigvals(comp).astype(complex)
    got = pr._eigvals(comp)
    assert _bits(got.real) == _bits(want.real)
    assert np.array_equal(np.abs(got.imag), np.abs(want.imag))  # read only through |Im|


def test_eigvals_of_a_non_finite_matrix_are_numpys_error():
    comp = np.array([[[0.0, np.nan], [1.0, 0.0]]])
    try:
        np.linalg.eigvals(comp)
    except np.linalg.LinAlgError as e:
        want = str(e)
    try:
        pr._eigvals(comp)
    except np.linalg.LinAlgError as e:
        assert str(e) == want
    else:
        raise AssertionError("no error")


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6), st.integers(1, 50))
def test_shifted_poly_is_the_sum(seed, ncoef, pieces):
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(size=ncoef) * 10.0 ** rng.uniform(-3, 3, ncoef)
    coeffs[rng.random(ncoef) < 0.3] = 0.0
    coeffs[rng.random(ncoef) < 0.2] = 1.0  # a unit coefficient is a term like any other
    degree = max(3, ncoef - 1)
    a = np.sort(rng.uniform(0, 10, pieces))
    h = rng.uniform(0.01, 0.5, pieces)
    c = np.zeros(degree + 1)
    c[:ncoef] = coeffs
    want = np.zeros((pieces, degree + 1))
    for k in range(degree + 1):
        acc = np.zeros(pieces)
        for j in range(k, degree + 1):
            if c[j] != 0.0:
                acc += c[j] * comb(j, k) * a ** (j - k)
        want[:, k] = acc * h**k
    assert _bits(shifted_poly(tuple(coeffs), a, h, degree)) == _bits(want)
    # and the polynomial itself: p(a + h σ) at a few σ, to the round-off of the two sums
    sig = np.array([0.0, 0.37, 1.0])
    got = np.polynomial.polynomial.polyval(sig, shifted_poly(tuple(coeffs), a, h, degree).T)
    ref = np.polynomial.polynomial.polyval(a[:, None] + h[:, None] * sig, c)
    scale = np.polynomial.polynomial.polyval(np.abs(a[:, None]) + h[:, None], np.abs(c)) + 1.0
    assert np.all(np.abs(got - ref) <= 1e-9 * scale)


def _root_degrees_reference(C, M, imag_tol, skip_far):
    """The degrees and Bernstein test as first written (each row's largest by comparisons, its
    degree from the top, its leading coefficient by selection, sums from 0): the reference."""
    Ct = np.ascontiguousarray(C.T)
    absC = np.abs(Ct)
    K, D1 = C.shape
    scale = absC[0].copy()
    for k in range(1, D1):
        col = absC[k]
        scale = np.where((col > scale) | (col != col), col, scale)
    d = np.zeros(K, dtype=np.int64)
    found = np.zeros(K, dtype=bool)
    for k in range(D1 - 1, -1, -1):
        big = (absC[k] > 1e-12 * scale) & ~found
        d = np.where(big, k, d)
        found |= big
    if not skip_far:
        return d
    lead, s0, s1 = np.zeros(K), np.zeros(K), np.zeros(K)
    for k in range(D1):
        lead = np.where(d == k, absC[k], lead)
        s0 = s0 + absC[k]
        s1 = s1 + k * absC[k]
    sent = (d > 0) & (lead > 0)
    amax = scale / np.where(sent, lead, 1.0)
    T = (kernel.BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
         + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)
    above, below = np.ones(K, dtype=bool), np.ones(K, dtype=bool)
    for j in range(D1):
        b = np.zeros(K)
        for k in range(j + 1):
            b = b + Ct[k] * M[k, j]
        above &= b > T
        below &= b < -T
    return np.where((above | below) & sent & np.isfinite(T), 0, d)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 9), st.booleans())
def test_root_degrees_are_the_reference(seed, degree, skip):
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(200, degree + 1)) * 10.0 ** rng.uniform(-12, 12, (200, degree + 1))
    for value, share in ((np.nan, 0.02), (np.inf, 0.02), (0.0, 0.1), (-0.0, 0.1), (1e300, 0.02)):
        C[rng.random(C.shape) < share] = value
    M = pr._bernstein_matrix(degree)
    got = np.empty(200, dtype=np.int64)
    with np.errstate(all="ignore"):
        kernel.root_degrees(C, M, 1e-6, skip, got)
        want = _root_degrees_reference(C, M, 1e-6, skip)
    assert got.tolist() == want.tolist()
