"""The weak-duality bounds' faster paths (issue 32): each kernel and cache gives what the numpy
expression it replaced gave, bit for bit, run as Python and compiled by numba.

* :func:`~iamp.planners.avoid.dual_kernel.binding_rows` against the decode by numpy (``flatnonzero``,
  floor division and remainder, ``row_entries``, ``bincount``);
* :func:`~iamp.planners.avoid.dual_kernel.select_rows` against ``flatnonzero`` of the mask;
* :func:`~iamp.planners.avoid.dual_kernel.kept_rows` against the masks per vehicle;
* :func:`~iamp.planners.avoid.dual_kernel.ratio_limits` against ``numpy.min`` of the masked ratios;
* :func:`~iamp.planners.avoid.dual_kernel.primal` and :func:`~iamp.planners.avoid.dual_kernel.coefficients`
  against their former loops (the same sums in the same order), and against the dense linear algebra;
* the kept arrays (``DualPolynomial.meta``, the coefficient positions, ``Packing.bound``,
  ``DualBounds.mass``) against what they stand for.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.planners import registry
from iamp.planners.avoid import dual, dual_kernel
from iamp.planners.avoid.dual import DualBounds, DualPolynomial, Packing
from iamp.planners.avoid.solve import row_entries
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.pmp import jit


def _both(name: str) -> list[Callable[..., Any]]:
    """The kernel ``name`` as Python, and its numba twin where numba is installed."""
    fn = getattr(dual_kernel, name)
    return [fn] + ([jit.twin(fn, cache=True)] if jit.available() else [])


def _bits(a: Any) -> bytes:
    """The bytes of a float or an array (bit-for-bit comparisons, NaN included)."""
    return np.ascontiguousarray(a).tobytes()


# --- binding_rows ---------------------------------------------------------------------------

@st_h.composite
def _layouts(draw: Any) -> tuple[Any, ...]:
    """Imposed rows with multipliers (some zero, negative or NaN), layout numbers (Bernstein rows
    below ``n_b``, limit rows above) and CSR arrays."""
    N, nb, m = draw(st_h.integers(1, 5)), draw(st_h.integers(1, 4)), draw(st_h.integers(1, 3))
    n_b = 2 * m * N * nb
    R = draw(st_h.integers(0, 25))
    ids = np.array(draw(st_h.lists(st_h.integers(0, n_b + 6), min_size=R, max_size=R)), dtype=np.int64)
    y = np.array(draw(st_h.lists(st_h.one_of(st_h.floats(-2.0, 5.0), st_h.just(0.0), st_h.just(np.nan)),
                                 min_size=R, max_size=R)), dtype=float)
    lens = draw(st_h.lists(st_h.integers(0, 4), min_size=R, max_size=R))
    indptr = np.concatenate(([0], np.cumsum(lens))).astype(np.int64)
    indices = np.array(draw(st_h.lists(st_h.integers(0, 40), min_size=int(indptr[-1]), max_size=int(indptr[-1]))),
                       dtype=np.int64)
    return y, ids, n_b, N, nb, m, indptr, indices


@settings(max_examples=150, deadline=None, derandomize=True)
@given(_layouts())
def test_binding_rows_is_the_numpy_decode(layout: tuple[Any, ...]) -> None:
    y_all, ids_all, n_b, N, nb, m, indptr, indices = layout
    nz = np.flatnonzero(y_all > 0)
    ids = ids_all[nz]
    bern = ids < n_b
    blk = np.where(bern, ids // (N * nb), -1)
    want = (nz, y_all[nz], bern, blk // 2, blk % 2, (ids // nb) % N, ids % nb,
            indices[row_entries(indptr, nz)[0]],
            np.bincount((blk // 2)[bern], weights=y_all[nz][bern], minlength=m).astype(float))
    for fn in _both("binding_rows"):
        got = fn(y_all, ids_all, n_b, N, nb, m, indptr, indices)
        assert len(got) == len(want)
        for g, w in zip(got, want):
            assert g.dtype == w.dtype and g.shape == w.shape and _bits(g) == _bits(w)


# --- select_rows and kept_rows ----------------------------------------------------------------

@st_h.composite
def _rows(draw: Any) -> tuple[Any, ...]:
    """Binding rows' kinds, vehicles, half-plane axes and pieces (limit rows: vehicle -1, axis 1)."""
    m, N = draw(st_h.integers(1, 3)), draw(st_h.integers(1, 8))
    S = draw(st_h.integers(0, 30))
    bern = np.array(draw(st_h.lists(st_h.booleans(), min_size=S, max_size=S)), dtype=np.bool_)
    veh = np.array(draw(st_h.lists(st_h.integers(0, m - 1), min_size=S, max_size=S)), dtype=np.int64)
    plane = np.array(draw(st_h.lists(st_h.integers(0, 3), min_size=S, max_size=S)), dtype=np.int64)
    piece = np.array(draw(st_h.lists(st_h.integers(0, N - 1), min_size=S, max_size=S)), dtype=np.int64)
    veh[~bern], plane[~bern] = -1, 1
    return m, N, bern, veh, plane, piece


@settings(max_examples=100, deadline=None, derandomize=True)
@given(_rows(), st_h.integers(0, 2), st_h.integers(0, 3), st_h.integers(0, 7))
def test_select_rows_is_flatnonzero(rows: tuple[Any, ...], i: int, pl: int, k: int) -> None:
    _, _, bern, veh, plane, piece = rows
    want = np.flatnonzero(bern & (veh == i) & (plane == pl) & (piece == k))
    for fn in _both("select_rows"):
        got = fn(bern, veh, plane, piece, i, pl, k)
        assert got.dtype == want.dtype and np.array_equal(got, want)


def _kept_numpy(bern: Any, veh: Any, plane: Any, piece: Any, first: Any, second: Any, split: Any, lo: Any,
                hi: Any, h: float) -> Any:
    """The former ``keep`` of :meth:`DualBounds.polynomial`, mask by mask."""
    keep = ~bern
    tol = 1e-9 * h
    for i in range(first.size):
        mine = bern & (veh == i)
        f, s, k = first[i], second[i], split[i]
        if k >= 0:
            keep |= mine & (((plane == f) & (piece < k)) | ((plane == s) & (piece > k)))
        else:
            keep |= mine & (plane == f) & ((piece + 1) * h <= lo[i] + tol)
            keep |= mine & (plane == s) & (piece * h >= hi[i] - tol)
    return keep


@settings(max_examples=150, deadline=None, derandomize=True)
@given(_rows(), st_h.data(), st_h.floats(0.01, 1.0))
def test_kept_rows_is_the_masks_per_vehicle(rows: tuple[Any, ...], data: Any, h: float) -> None:
    m, N, bern, veh, plane, piece = rows
    first = np.array(data.draw(st_h.lists(st_h.integers(0, 3), min_size=m, max_size=m)), dtype=np.int64)
    second = np.array(data.draw(st_h.lists(st_h.integers(0, 3), min_size=m, max_size=m)), dtype=np.int64)
    split = np.array(data.draw(st_h.lists(st_h.integers(-1, N - 1), min_size=m, max_size=m)), dtype=np.int64)
    # box ends on the grid's nodes (where the tolerance decides), or anywhere
    ends = st_h.one_of(st_h.integers(0, N).map(lambda j: j * h), st_h.floats(0.0, N * h))
    lo = np.array(data.draw(st_h.lists(ends, min_size=m, max_size=m)), dtype=float)
    hi = lo + np.array(data.draw(st_h.lists(st_h.floats(0.0, N * h), min_size=m, max_size=m)))
    want = _kept_numpy(bern, veh, plane, piece, first, second, split, lo, hi, h)
    for fn in _both("kept_rows"):
        keep = np.empty(bern.size, dtype=np.bool_)
        fn(bern, veh, plane, piece, first, second, split, lo, hi, h, 1e-9 * h, keep)
        assert np.array_equal(keep, want)


# --- ratio_limits ---------------------------------------------------------------------------

_ratios = st_h.lists(st_h.tuples(st_h.one_of(st_h.floats(1e-300, 1e300), st_h.just(np.inf), st_h.just(np.nan)),
                                 st_h.one_of(st_h.floats(-1e10, 1e10), st_h.just(0.0), st_h.just(-0.0),
                                             st_h.just(np.nan))), max_size=20)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(_ratios)
def test_ratio_limits_is_numpy_min_of_the_masked_ratios(pairs: list[tuple[float, float]]) -> None:
    y = np.array([p[0] for p in pairs], dtype=float)
    mu = np.array([p[1] for p in pairs], dtype=float)
    down, up = mu < 0.0, mu > 0.0
    with np.errstate(all="ignore"):
        want_down = float(np.min(y[down] / -mu[down])) if down.any() else None
        want_up = float(np.min(y[up] / mu[up])) if up.any() else None
    for fn in _both("ratio_limits"):
        with np.errstate(all="ignore"):
            d, has_d, u, has_u = fn(y, mu)
        assert bool(has_d) == (want_down is not None) and bool(has_u) == (want_up is not None)
        if want_down is not None:
            assert _bits(float(d)) == _bits(want_down)
        if want_up is not None:
            assert _bits(float(u)) == _bits(want_up)


# --- primal and coefficients ------------------------------------------------------------------

def _primal_before(R: Any, Kinv: Any, z0: Any, hc: Any, beq_x0: float, beq_x0_abs: float, Z: Any, lin: Any) -> float:
    """:func:`~iamp.planners.avoid.dual_kernel.primal` as it was (row by row into ``Z``)."""
    n, C = Z.shape
    Z[...] = 0.0
    s, sa = np.zeros(C), np.zeros(C)
    for a in range(n):
        for c in range(C):
            w = R[a, c]
            if w != 0.0:
                for i in range(n):
                    Z[i, c] += Kinv[a, i] * w
                s[c] += z0[a] * w
                sa[c] += abs(z0[a]) * abs(w)
    for i in range(n):
        Z[i, 0] += z0[i]
    size = 0.0
    for c in range(C):
        lin[c] = s[c] + hc[c]
        size += sa[c] + beq_x0_abs
    lin[0] += beq_x0
    return size


def _coefficients_before(Z: Any, lin: Any, lin_abs: float, hc: Any, Pp: Any, Pi: Any, Px: Any, flat: Any,
                         coef: Any) -> float:
    """:func:`~iamp.planners.avoid.dual_kernel.coefficients` as it was (one pass per product)."""
    n, C = Z.shape
    PZ = np.zeros((n, C))
    w = np.zeros(n)
    for j in range(n):
        for c in range(C):
            w[j] += abs(Z[j, c])
    Pw = np.zeros(n)
    for j in range(n):
        for k in range(Pp[j], Pp[j + 1]):
            i, v = Pi[k], Px[k]
            for c in range(C):
                PZ[i, c] += v * Z[j, c]
            Pw[i] += abs(v) * w[j]
    quad = 0.0
    for i in range(n):
        quad += w[i] * Pw[i]
    hsum = 0.0
    for c in range(C):
        coef[flat[c]] += -lin[c]
        hsum += abs(hc[c])
    for c1 in range(C):
        for c2 in range(C):
            acc = 0.0
            for i in range(n):
                acc += Z[i, c1] * PZ[i, c2]
            coef[flat[C + c1 * C + c2]] += -0.5 * acc
    return 0.5 * quad + lin_abs + hsum


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st_h.integers(1, 12), st_h.integers(1, 6), st_h.integers(0, 2 ** 32 - 1), st_h.floats(0.0, 0.9))
def test_primal_and_coefficients_are_their_former_loops_and_the_dense_products(n: int, C: int, seed: int,
                                                                               sparsity: float) -> None:
    rng = np.random.default_rng(seed)
    R = rng.normal(size=(n, C)) * (rng.random((n, C)) > sparsity)
    K = rng.normal(size=(n, n))
    Kinv = K + K.T
    z0, hc = rng.normal(size=n), rng.normal(size=C)
    A = rng.normal(size=(n, n))
    P = (A @ A.T) * (rng.random((n, n)) > 0.5)
    P = np.triu(P) + np.triu(P, 1).T
    Pp = np.concatenate(([0], np.cumsum((P != 0).sum(axis=0)))).astype(np.int64)
    Pi = np.concatenate([np.flatnonzero(P[:, j]) for j in range(n)]).astype(np.int64)
    Px = np.concatenate([P[P[:, j] != 0, j] for j in range(n)])
    flat = rng.integers(0, 2 * C, size=C + C * C).astype(np.int64)
    Z0, lin0 = np.full((n, C), np.nan), np.full(C, np.nan)
    size0 = _primal_before(R, Kinv, z0, hc, 0.3, 0.4, Z0, lin0)
    coef0 = np.zeros(2 * C)
    terms0 = _coefficients_before(Z0, lin0, size0, hc, Pp, Pi, Px, flat, coef0)
    # the dense products they compute (to round-off)
    want_Z = Kinv @ R
    want_Z[:, 0] += z0
    assert np.allclose(Z0, want_Z, rtol=1e-12, atol=1e-12 * (1 + np.abs(Kinv).sum()))
    quad = want_Z.T @ P @ want_Z
    want_coef = np.zeros(2 * C)
    np.add.at(want_coef, flat[:C], -lin0)
    np.add.at(want_coef, flat[C:], -0.5 * quad.ravel())
    assert np.allclose(coef0, want_coef, rtol=1e-9, atol=1e-9 * (1 + np.abs(quad).sum()))
    for primal, coefficients in zip(_both("primal"), _both("coefficients")):
        Z, lin = np.full((n, C), np.nan), np.full(C, np.nan)
        size = primal(R, Kinv, z0, hc, 0.3, 0.4, Z, lin)
        assert _bits(size) == _bits(size0) and _bits(Z) == _bits(Z0) and _bits(lin) == _bits(lin0)
        coef = np.zeros(2 * C)
        terms = coefficients(Z, lin, size, hc, Pp, Pi, Px, flat, coef)
        assert _bits(terms) == _bits(terms0) and _bits(coef) == _bits(coef0)


# --- the kept arrays --------------------------------------------------------------------------

def _meta_before(dp: DualPolynomial) -> Any:
    """:attr:`DualPolynomial.meta` as it was built (zeros, then slices)."""
    q = dp.coef.ndim
    W = max(int(np.size(dp.mass)), q, 1)
    row = np.zeros(3 + 2 * W, dtype=np.int64)
    row[0], row[1], row[2] = q, int(dp.coef.shape[0]) if q else 1, dp.coef.size
    row[3:3 + q] = dp.vehicles
    row[3 + W:3 + W + q] = dp.pieces
    return row


@pytest.mark.parametrize("q,m", [(0, 1), (0, 3), (1, 1), (1, 3), (2, 3), (3, 3), (2, 2)])
def test_meta_is_its_layout(q: int, m: int) -> None:
    vehicles = tuple(range(m - q, m))
    dp = DualPolynomial(vehicles, tuple(2 * v + 1 for v in vehicles), np.ones((5,) * q), 0.1, np.ones(m))
    assert dp.meta.dtype == np.int64 and np.array_equal(dp.meta, _meta_before(dp))
    assert not dp.meta.flags.writeable


@pytest.mark.parametrize("q,D", [(1, 3), (1, 4), (2, 3), (3, 2), (1, 5), (2, 4)])
def test_coefficient_positions_are_the_exponents_raveled(q: int, D: int) -> None:
    flat = DualBounds._positions(q, D)
    assert flat is DualBounds._positions(q, D)  # once per process
    shape = (2 * D + 1,) * q
    C = 1 + q * D
    exps = np.zeros((C, q), dtype=np.int64)
    for v in range(q):
        exps[1 + v * D:1 + (v + 1) * D, v] = np.arange(1, D + 1)
    for c in range(C):  # the basis monomial c, then each product c1 c2: exponents add
        assert np.unravel_index(flat[c], shape) == tuple(exps[c])
        for c2 in range(C):
            assert np.unravel_index(flat[C + c * C + c2], shape) == tuple(exps[c] + exps[c2])


def test_packing_keeps_the_largest_count_and_the_roundoffs() -> None:
    rng = np.random.default_rng(3)
    polys = [DualPolynomial((0,), (k,), rng.normal(size=n), 0.1, np.ones(2), roundoff=float(rng.random()))
             for k, n in enumerate((5, 7, 3))]
    polys.append(DualPolynomial((0, 1), (1, 2), rng.normal(size=(5, 5)), 0.1, np.ones(2), roundoff=0.25))
    packing = Packing()
    assert packing.get(polys) is packing.get(polys)
    flat, meta, W, largest, n, roundoff = packing.bound(polys)
    want = dual._packed(polys, None)
    assert np.array_equal(flat, want[0]) and np.array_equal(meta, want[1]) and (W, largest) == want[2:]
    assert n == int(want[1][:, 1].max()) == 7
    assert np.array_equal(roundoff, [dp.roundoff for dp in polys])
    assert packing.bound(polys)[5] is roundoff
    lo, hi = np.array([0.1, 0.1]), np.array([0.12, 0.2])
    assert dual.max_lower_bound(polys, lo, hi, packing) == dual.max_lower_bound(polys, lo, hi)


@pytest.mark.parametrize("three", [False, True])
def test_the_kept_mass_and_halves_are_what_they_stand_for(three: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """On every solution a plan decodes: the mass kept on its binding rows is ``numpy.bincount`` of
    the multipliers per vehicle, and the kept halves and columns are those of the masks."""
    seen: list[tuple[DualBounds, Any]] = []
    decode = DualBounds._decode

    def recording(self: DualBounds, sol: Any) -> Any:
        seen.append((self, sol))
        return decode(self, sol)

    monkeypatch.setattr(DualBounds, "_decode", recording)
    prob = overtake_three_problem() if three else overtake_problem()
    plan = registry.make_planner("qp-avoid", steps=30, hold="foh", solver="clarabel", safety="continuous").plan(prob)
    assert plan.status == st.OPTIMAL and len(seen) >= 2
    binding = 0
    for bounds, sol in seen:
        b = bounds._binding(sol)
        assert bounds.mass(sol) is b.mass and not b.mass.flags.writeable
        want = np.bincount(b.veh[b.bern], weights=b.y[b.bern], minlength=len(sol.spec)).astype(float)
        assert _bits(b.mass) == _bits(want)
        binding += bool((want > 0).any())
        for i, (f, s, a, _) in enumerate(sol.spec):
            k = dual.piece_of(float(a), float(a), bounds.qp.h, bounds.qp.N)
            if k is None:
                continue
            halves = bounds._halves(sol, b, i, k)
            assert bounds._halves(sol, b, i, k) is halves
            for (rows, _, _, _, _), pl in zip(halves, (f, s)):
                mask = b.bern & (b.veh == i) & (b.plane == pl) & (b.piece == k)
                assert np.array_equal(rows, np.flatnonzero(mask))
            assert np.array_equal(bounds._entries(b, i, k), np.concatenate((b.cols, halves[0][4], halves[1][4])))
    assert binding >= 1


@pytest.mark.parametrize("split, lo, hi, first_kept, second_kept", [
    (-1, 2.0, 2.0, [0, 1], [2, 3]),  # the box at node 2: first-half-plane pieces end by it, second ones start there
    (-1, 1.5, 2.5, [0], [3]),  # inside pieces 1 and 2: neither piece is kept
    (1, 1.2, 1.8, [0], [2, 3]),  # the box in piece 1: the pieces before it and after it
    (0, 0.0, 0.5, [], [1, 2, 3]),
])
def test_kept_rows_at_the_nodes_themselves(split: int, lo: float, hi: float, first_kept: list[int],
                                           second_kept: list[int]) -> None:
    """One vehicle, four unit pieces, a binding row of each half-plane on each piece and a limit row,
    tolerance 0: a piece is kept exactly when it ends at or before ``lo`` (first half-plane) or
    starts at or after ``hi`` (second), or lies before or after the box's piece; the limit row
    always."""
    plane = np.array([0, 0, 0, 0, 1, 1, 1, 1, 0], dtype=np.int64)
    piece = np.array([0, 1, 2, 3, 0, 1, 2, 3, 0], dtype=np.int64)
    bern = np.array([True] * 8 + [False])
    veh = np.array([0] * 8 + [-1], dtype=np.int64)
    first, second = np.array([0], dtype=np.int64), np.array([1], dtype=np.int64)
    want = np.zeros(9, dtype=bool)
    want[first_kept] = True
    want[[4 + p for p in second_kept]] = True
    want[8] = True
    for fn in _both("kept_rows"):
        keep = np.empty(9, dtype=np.bool_)
        fn(bern, veh, plane, piece, first, second, np.array([split], dtype=np.int64), np.array([lo]),
           np.array([hi]), 1.0, 0.0, keep)
        assert keep.tolist() == want.tolist()
