"""The root finder's degree and Bernstein-test kernel (:func:`iamp.core.polyroots_kernel.root_degrees`)
written with ufuncs into arrays made once gives the degrees of its former form, which made a
new array per operation (kept below as the oracle), bit for bit: the same elementwise
operations in the same order, so the same sums, bounds and comparisons.  Over
hypothesis-generated coefficients with ties, signed zeros, subnormals, huge values, NaN and
infinities, in Python and compiled.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import iamp.core.polyroots as pr
from iamp.core import jit
from iamp.core import polyroots_kernel as kernel

needs_numba = pytest.mark.skipif(not jit.available(), reason="numba is not installed")


def _former(C: Any, M: Any, imag_tol: float, skip_far: bool, deg: Any) -> None:
    """``root_degrees`` before the rewrite (a new array per operation)."""
    BACKWARD_REL = kernel.BACKWARD_REL
    K, D1 = C.shape
    Ct = np.ascontiguousarray(C.T)
    absC = np.abs(Ct)
    scale = absC[0].copy()
    for k in range(1, D1):
        scale = np.maximum(scale, absC[k])
    thr = 1e-12 * scale
    d = np.zeros(K, dtype=np.int64)
    for k in range(1, D1):
        d = np.where(absC[k] > thr, k, d)
    if not skip_far or D1 < 2:
        deg[:] = d
        return
    lead = absC.ravel()[d * K + np.arange(K)]
    s0 = np.zeros(K)
    s1 = np.zeros(K)
    for k in range(D1):
        s0 = s0 + absC[k]
        s1 = s1 + k * absC[k]
    sent = (d > 0) & (lead > 0)
    amax = scale / np.where(sent, lead, 1.0)
    T = (BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
         + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)
    above = np.ones(K, dtype=np.bool_)
    below = np.ones(K, dtype=np.bool_)
    for j in range(D1):
        b = Ct[0] * M[0, j]
        for k in range(1, j + 1):
            b = b + Ct[k] * M[k, j]
        above = above & (b > T)
        below = below & (b < -T)
    skip = (above | below) & sent & np.isfinite(T)
    deg[:] = np.where(skip, 0, d)


_SPECIAL = [0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, -5e-324, 1e300, -1e300, 1e-12, np.nan, np.inf, -np.inf]


@st.composite
def _coefficients(draw: Any) -> np.ndarray:
    """Rows of ascending coefficients: mostly polynomials with roots near [0, 1] (both sides of
    the Bernstein test), some with special values (ties, signed zeros, extremes, NaN, inf)."""
    n = draw(st.integers(2, 9))
    K = draw(st.integers(1, 40))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    C = np.empty((K, n))
    for r in range(K):
        roots = rng.uniform(-0.5, 1.5, n - 1)
        scale = 10.0 ** rng.uniform(-8, 8)
        C[r] = np.polynomial.polynomial.polyfromroots(roots) * scale
        C[r] += rng.normal(0, 1e-3 * scale, n) * rng.integers(0, 2)
    specials = draw(st.lists(st.tuples(st.integers(0, K - 1), st.integers(0, n - 1), st.sampled_from(_SPECIAL)),
                             max_size=12))
    for r, k, v in specials:
        C[r, k] = v
    if draw(st.booleans()):  # duplicated rows and a zero row: ties everywhere
        C[K // 2:] = C[0]
        C[-1] = 0.0
    return np.ascontiguousarray(C)


def _degrees(fn: Any, C: np.ndarray, imag_tol: float, skip: bool) -> list[int]:
    out = np.full(C.shape[0], -7, dtype=np.int64)
    with np.errstate(all="ignore"):
        fn(C, pr._bernstein_matrix(C.shape[1] - 1), imag_tol, skip, out)
    return out.tolist()


@settings(max_examples=150, deadline=None)
@given(_coefficients(), st.sampled_from([1e-6, 0.0, 1e-3]), st.booleans())
def test_root_degrees_is_its_former_form_in_python(C: np.ndarray, imag_tol: float, skip: bool) -> None:
    expected = _degrees(_former, C, imag_tol, skip)
    assert _degrees(kernel.root_degrees, C, imag_tol, skip) == expected
    if skip:  # the test skips rows (it is not vacuous on these inputs as a whole)
        noskip = _degrees(_former, C, imag_tol, False)
        assert all(e in (0, n) for e, n in zip(expected, noskip))


@needs_numba
@settings(max_examples=150, deadline=None)
@given(_coefficients(), st.sampled_from([1e-6, 0.0, 1e-3]), st.booleans())
def test_root_degrees_compiled_is_its_former_form(C: np.ndarray, imag_tol: float, skip: bool) -> None:
    twin = jit.twin(kernel.root_degrees, cache=True)
    assert _degrees(twin, C, imag_tol, skip) == _degrees(_former, C, imag_tol, skip)


def test_the_bernstein_test_skips_rows_of_the_stress_set() -> None:
    """On polynomials without roots near [0, 1] the test skips most rows (both ways), so the
    comparisons above cover the skip path, not only the kept rows."""
    rng = np.random.default_rng(5)
    C = np.stack([np.polynomial.polynomial.polyfromroots(rng.uniform(2.0, 3.0, 6)) * s
                  for s in rng.choice([-1.0, 1.0], 200)])
    C = np.ascontiguousarray(C)
    new, old = _degrees(kernel.root_degrees, C, 1e-6, True), _degrees(_former, C, 1e-6, True)
    assert new == old
    assert old.count(0) > 150


def _documented_bound(v: float, lead: float, d: int, imag_tol: float) -> float:
    """``T`` of ``root_degrees``' docstring for the row ``v + lead x^d`` (``v, lead > 0``), written
    from the docstring: the backward error of the eigenvalues of the monic polynomial (``max |a_k|
    = v / lead``), the window's reach, the dropped coefficients and the Bernstein round-off."""
    scale, s0, s1 = max(v, lead), v + lead, d * lead
    amax = scale / lead
    return (kernel.BACKWARD_REL * 1.01 * (d + 1) * lead * (1.0 + amax) ** 2
            + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * (d + 1) * scale)


def _boundaries(lead: float, d: int, imag_tol: float) -> tuple[float, float]:
    """The two values of ``v`` where ``v = T(v)`` (bisection in log scale): the row's Bernstein
    coefficients (``v`` and ``v + lead``) exceed ``T`` strictly between them."""
    def crossing(a: float, b: float) -> float:  # g = v - T(v) changes sign on [a, b]
        ga = a - _documented_bound(a, lead, d, imag_tol)
        for _ in range(200):
            m = float(np.sqrt(a * b))
            gm = m - _documented_bound(m, lead, d, imag_tol)
            if (gm > 0) == (ga > 0):
                a, ga = m, gm
            else:
                b = m
        return a
    peak = lead / (2 * kernel.BACKWARD_REL * 1.01 * (d + 1))  # about where v - T(v) is largest
    assert peak - _documented_bound(peak, lead, d, imag_tol) > 0
    assert 1e-30 - _documented_bound(1e-30, lead, d, imag_tol) < 0
    return crossing(1e-30, peak), crossing(peak, 1e6 * peak)


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=needs_numba)])
@pytest.mark.parametrize("lead, d, imag_tol", [(1.0, 3, 1e-6), (0.37, 5, 1e-3), (2.5e-3, 2, 0.0), (40.0, 6, 1e-6)])
def test_the_bernstein_test_skips_exactly_where_its_documented_bound_says(compiled: bool, lead: float, d: int,
                                                                         imag_tol: float) -> None:
    """At both ends of the interval of ``v`` where ``v + lead x^d`` is skipped, one part per million
    inside is skipped (degree 0) and one part per million outside is kept (degree ``d``): the
    kernel's bound is the docstring's ``T``, each of its terms (a term off by a factor 1.5 or the
    degree's ``d + 1`` changed moves an end by more than that)."""
    fn = jit.twin(kernel.root_degrees, cache=True) if compiled else kernel.root_degrees
    lo, hi = _boundaries(lead, d, imag_tol)
    vs = [lo * (1 - 1e-6), lo * (1 + 1e-6), hi * (1 - 1e-6), hi * (1 + 1e-6)]
    C = np.zeros((len(vs), d + 1))
    C[:, 0] = vs
    C[:, d] = lead
    assert _degrees(fn, np.ascontiguousarray(C), imag_tol, True) == [d, 0, 0, d]
