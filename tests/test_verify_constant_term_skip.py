"""The root finder's degree kernel (:func:`iamp.core.polyroots_kernel.root_degrees`) decides a row
whose constant term dominates (``|c_0| > 2 S + T``, ``S`` the sum of the other magnitudes) without
its Bernstein coefficients, and writes its maxima and degrees into arrays made once: the degrees
are those of its former form (kept below as the oracle: the Bernstein coefficients of every row,
a new array per maximum and per degree), bit for bit, in Python and compiled.  Over
hypothesis-generated rows: polynomials with roots near [0, 1], rows whose constant term dominates
by little (at the test's own boundary ``|c_0| = 2 S + T`` and at the Bernstein test's, where the
oracle's coefficients lie within round-off of ``T``), ties, signed zeros, subnormals, huge
values, NaN and infinities.
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
    """``root_degrees`` before the constant-term test (the Bernstein coefficients of every row)."""
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
    t = np.empty(K)
    for k in range(D1):
        np.add(s0, absC[k], s0)
        np.multiply(absC[k], float(k), t)
        np.add(s1, t, s1)
    sent = (d > 0) & (lead > 0)
    amax = scale / np.where(sent, lead, 1.0)
    T = (BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
         + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)
    nT = -T
    above = np.ones(K, dtype=np.bool_)
    below = np.ones(K, dtype=np.bool_)
    b = np.empty(K)
    c = np.empty(K, dtype=np.bool_)
    for j in range(D1):
        np.multiply(Ct[0], M[0, j], b)
        for k in range(1, j + 1):
            np.multiply(Ct[k], M[k, j], t)
            np.add(b, t, b)
        np.greater(b, T, c)
        np.logical_and(above, c, above)
        np.less(b, nT, c)
        np.logical_and(below, c, below)
    skip = (above | below) & sent & np.isfinite(T)
    deg[:] = np.where(skip, 0, d)


def _bound(row: np.ndarray, imag_tol: float) -> float:
    """``T`` of one row as the oracle computes it (its degree, leading coefficient and sums)."""
    D1 = row.size
    absC = np.abs(row)
    scale = float(absC.max())
    d = max([k for k in range(1, D1) if absC[k] > 1e-12 * scale], default=0)
    lead = absC[d]
    s0 = s1 = 0.0
    for k in range(D1):
        s0 += absC[k]
        s1 += absC[k] * float(k)
    amax = scale / (lead if d > 0 and lead > 0 else 1.0)
    return float(kernel.BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
                 + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)


_SPECIAL = [0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, -5e-324, 1e-205, 1e205, 1e300, -1e300, 1e-12, np.nan, np.inf, -np.inf]


@st.composite
def _rows(draw: Any) -> tuple[np.ndarray, float]:
    """Rows of ascending coefficients (see the module docstring) and the ``imag_tol``."""
    n = draw(st.integers(2, 9))
    K = draw(st.integers(1, 40))
    imag_tol = draw(st.sampled_from([1e-6, 0.0, 1e-3]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    C = np.empty((K, n))
    for r in range(K):
        scale = 10.0 ** rng.uniform(-8, 8)
        kind = rng.integers(0, 4)
        if kind == 0:  # roots near [0, 1]: Bernstein coefficients on both sides of T
            C[r] = np.polynomial.polynomial.polyfromroots(rng.uniform(-0.5, 1.5, n - 1)) * scale
        else:  # a dominant constant term, by a factor about 1 (its test's boundary) or more
            C[r] = rng.normal(0.0, 1.0, n) * scale
            S = float(np.abs(C[r, 1:]).sum())
            C[r, 0] = rng.choice([-1.0, 1.0]) * (2.0 * S) * (1.0 + 10.0 ** rng.uniform(-16, 1))
            if kind == 3:  # at the Bernstein test's own boundary: c_0 = T(c) ± a few ulps
                C[r, 1:] *= 10.0 ** rng.uniform(-13, -9)
                T = _bound(C[r], imag_tol)
                C[r, 0] = np.copysign(T, C[r, 0]) * (1.0 + rng.integers(-4, 5) * 2.0**-52)
    for r, k, v in draw(st.lists(st.tuples(st.integers(0, K - 1), st.integers(0, n - 1), st.sampled_from(_SPECIAL)),
                                 max_size=10)):
        C[r, k] = v
    if draw(st.booleans()):  # scaled into the extremes: subnormal or huge rows
        with np.errstate(all="ignore"):
            C *= draw(st.sampled_from([1e-310, 1e-200, 1e200, 1e290]))
    if draw(st.booleans()):  # duplicated rows and a zero row: ties everywhere
        C[K // 2:] = C[0]
        C[-1] = 0.0
    return np.ascontiguousarray(C), imag_tol


def _degrees(fn: Any, C: np.ndarray, imag_tol: float, skip: bool) -> list[int]:
    out = np.full(C.shape[0], -7, dtype=np.int64)
    with np.errstate(all="ignore"):
        fn(C, pr._bernstein_matrix(C.shape[1] - 1), imag_tol, skip, out)
    return out.tolist()


@settings(max_examples=200, deadline=None)
@given(_rows(), st.booleans())
def test_root_degrees_are_those_of_the_bernstein_test_on_every_row(drawn: tuple[np.ndarray, float],
                                                                   skip: bool) -> None:
    C, imag_tol = drawn
    assert _degrees(kernel.root_degrees, C, imag_tol, skip) == _degrees(_former, C, imag_tol, skip)


@needs_numba
@settings(max_examples=200, deadline=None)
@given(_rows(), st.booleans())
def test_root_degrees_compiled_are_those_of_the_bernstein_test(drawn: tuple[np.ndarray, float], skip: bool) -> None:
    C, imag_tol = drawn
    twin = jit.twin(kernel.root_degrees, cache=True)
    assert _degrees(twin, C, imag_tol, skip) == _degrees(_former, C, imag_tol, skip)


def _decided_by_constant(C: np.ndarray, imag_tol: float) -> np.ndarray:
    """The rows the constant-term test decides (its condition, from the docstring)."""
    T = np.array([_bound(r, imag_tol) for r in C])
    absC = np.abs(C)
    S = absC[:, 1:].sum(axis=1)
    scale = absC.max(axis=1)
    return (absC[:, 0] > 2.0 * S + T) & (scale > 1e-200) & (scale < 1e200)


def test_the_constant_term_decides_most_rows_of_a_safety_report_and_they_have_no_roots() -> None:
    """On the one-vehicle overtake's safety rows most rows are decided by their constant term, all
    skipped by the Bernstein test too, and none has an eigenvalue in the window (the full
    computation, without any skip, finds no root on those rows)."""
    from iamp.core import intrusion, trajectory_pieces
    from iamp.planners import registry
    from iamp.planners.examples import overtake_problem

    problem = overtake_problem()
    plan = registry.make_planner("qp-avoid", steps=50, hold="foh", solver="piqp", safety="continuous").plan(problem)
    traj = plan.trajectory
    breaks = trajectory_pieces.breakpoints(traj, problem.tf)
    coeffs, _ = trajectory_pieces.taylor_pieces(traj, breaks)
    C = np.ascontiguousarray(intrusion._CutPolynomials(problem.vehicles[0], breaks, coeffs, 4.8, 1.8).rows)
    by_constant = _decided_by_constant(C, 1e-6)
    assert by_constant.mean() > 0.9
    new, old = _degrees(kernel.root_degrees, C, 1e-6, True), _degrees(_former, C, 1e-6, True)
    assert new == old
    assert all(old[r] == 0 for r in np.flatnonzero(by_constant))
    full = _degrees(_former, C, 1e-6, False)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pr, "_SKIP_FAR", False)
        rows, _ = pr.roots_in_unit_interval(C)
    assert not set(rows.tolist()) & set(np.flatnonzero(by_constant).tolist())
    assert all(full[r] > 0 for r in np.flatnonzero(by_constant))  # real polynomials, sent without the test


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=needs_numba)])
def test_rows_at_the_constant_term_boundary_keep_the_bernstein_degrees(compiled: bool) -> None:
    """``c_0`` one ulp either side of ``2 S + T`` (and of ``T`` itself): whichever test decides,
    the degrees are the oracle's, and rows well inside are decided by the constant term."""
    fn = jit.twin(kernel.root_degrees, cache=True) if compiled else kernel.root_degrees
    rows = []
    for tail in ([0.3, -0.2, 0.1], [1e-9, 0.0, 2e-9], [0.5], [-1.0, 1.0, -1.0, 1.0, -1.0]):
        base = np.array([0.0, *tail])
        T = _bound(np.array([1.0, *tail]), 1e-6)
        edge = 2.0 * float(np.abs(base[1:]).sum()) + T
        for v in (edge, T):
            for f in (1.0 - 2.0**-52, 1.0, 1.0 + 2.0**-52, 1.5):
                for sign in (1.0, -1.0):
                    row = base.copy()
                    row[0] = sign * v * f
                    rows.append(np.pad(row, (0, 6 - row.size)))
    C = np.ascontiguousarray(np.array(rows))
    assert _degrees(fn, C, 1e-6, True) == _degrees(_former, C, 1e-6, True)
    assert _decided_by_constant(C, 1e-6).sum() >= 8
