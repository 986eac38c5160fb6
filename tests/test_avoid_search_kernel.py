"""The crossing-time search's kernels (``planners/avoid/search_kernel.py``), written once.

* The Python functions and their numba twins give the same numbers bit for bit (so no plan
  depends on whether numba is installed).
* The held position against :class:`~iamp.core.hold_trajectory.HoldTrajectory` (FOH and ZOH), the
  margins against :class:`~iamp.planners.avoid.data.HalfPlane`, and the candidate crossing times
  against the max-min of those margins computed with numpy (an independent reference).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_h

from iamp.planners.avoid import search_kernel as kernel
from iamp.planners.avoid.check import crossing_orders
from iamp.planners.avoid.continuous import ContinuousAvoidQP, _spec
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.pmp import jit


def _relaxed(m: int, steps: int, hold: str):  # type: ignore[no-untyped-def]
    """A QP and the optimum of its relaxation over the middle of the horizon (a box's ``relaxed``)."""
    prob = overtake_problem() if m == 1 else overtake_three_problem()
    if hold == "zoh":
        prob = prob.with_limits(None)
    qp = ContinuousAvoidQP(prob, steps, hold, "clarabel")
    orders, _ = crossing_orders(prob)
    first = [o[0] for o in orders]
    sol = qp.solve(_spec(first, np.full(m, 0.3 * prob.tf), np.full(m, 0.8 * prob.tf)))
    assert sol.status == "optimal"
    return qp, first, sol


def _boxes(m: int, tf: float):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    out = [(np.zeros(m), np.full(m, tf)), (np.full(m, 0.37 * tf), np.full(m, 0.37 * tf))]  # a zero-width box
    for _ in range(6):
        a, b = np.sort(rng.uniform(0.0, tf, (2, m)), axis=0)
        out.append((a, b))
    lo, hi = out[-1]
    hi = hi.copy()
    hi[0] = lo[0]  # one vehicle's interval a point, the others wide
    out.append((lo, hi))
    return out


def _call(fn, qp, first, z, lo, hi):  # type: ignore[no-untyped-def]
    m = len(first)
    d = qp.data
    out, worst, T = np.empty(m), np.empty(m), np.empty((m, 33))
    fn(np.asarray(z, dtype=float), d.t_nodes, d.N, d.block, qp.hold == "foh", np.asarray(lo, dtype=float),
       np.asarray(hi, dtype=float), np.asarray(first, dtype=np.int64).reshape(m, 2), *qp.plane_arrays(), T,
       np.empty(33), np.empty(33), out, worst)
    return out, worst, T


@pytest.mark.skipif(not jit.available(), reason="numba is not installed")
@pytest.mark.parametrize("m,hold", [(1, "foh"), (3, "foh"), (1, "zoh")])
def test_the_compiled_kernel_is_the_python_function_bit_for_bit(m: int, hold: str) -> None:
    qp, first, sol = _relaxed(m, 20, hold)
    compiled = jit.twin(kernel.candidate_tau, cache=True)
    for lo, hi in _boxes(m, qp.tf):
        a, b = _call(kernel.candidate_tau, qp, first, sol.z, lo, hi), _call(compiled, qp, first, sol.z, lo, hi)
        for x, y in zip(a, b):
            assert np.array_equal(x, y)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_held_position_and_margins_against_the_trajectory_and_the_half_planes(hold: str) -> None:
    qp, _, sol = _relaxed(3, 20, hold)
    traj = qp.trajectory(sol.z)
    d = qp.data
    arrays = qp.plane_arrays()
    t = np.r_[np.linspace(0.0, qp.tf, 97), d.t_nodes, qp.tf]
    X = traj.states(t)
    for axis in (0, 1):
        s = np.array([kernel.held_position(sol.z, d.t_nodes, d.N, d.block, hold == "foh", axis, float(x)) for x in t])
        assert np.allclose(s, X[:, 2 * axis], rtol=1e-13, atol=1e-12)
        for i, planes in enumerate(d.planes):
            want = planes[axis].margin(t, X[:, 2 * axis])
            got = np.array([kernel.plane_margin(i, axis, float(x), float(y), *arrays) for x, y in zip(t, s)])
            assert np.allclose(got, want, rtol=1e-13, atol=1e-11)


@pytest.mark.parametrize("m,rough", [(1, False), (3, False), (1, True), (3, True)])
def test_candidate_times_are_the_max_min_of_the_margins(m: int, rough: bool) -> None:
    """``rough``: a random point instead of the relaxed optimum, whose margins go up and down
    along the box (the running minima must then reach back to the box's first and last samples)."""
    qp, first, sol = _relaxed(m, 20, "foh")
    z = np.asarray(sol.z, dtype=float)
    if rough:
        z = z + np.random.default_rng(11).normal(0.0, 3.0, z.size)
    traj = qp.trajectory(z)
    for lo, hi in _boxes(m, qp.tf):
        out, worst, T = _call(kernel.candidate_tau, qp, first, z, lo, hi)
        ref_T = np.linspace(lo, hi, 33, axis=1)
        assert np.allclose(T, ref_T, rtol=0.0, atol=1e-12 * qp.tf) and np.array_equal(T[:, -1], hi)
        for i, (f, s) in enumerate(first):
            t = ref_T[i]
            X = traj.states(t)
            planes = qp.data.planes[i]
            mf, ms = planes[f].margin(t, X[:, 2 * f]), planes[s].margin(t, X[:, 2 * s])
            score = np.array([min(mf[:j + 1].min(), ms[j:].min()) for j in range(t.size)])
            assert worst[i] == pytest.approx(score.max(), rel=1e-12, abs=1e-10)
            # the chosen sample scores the maximum (to round-off)
            j = int(np.flatnonzero(T[i] == out[i])[0])
            assert score[j] >= score.max() - 1e-10


def test_valid_polys_is_the_box_containment_and_order_test() -> None:
    rng = np.random.default_rng(11)
    fns = [kernel.valid_polys] + ([jit.twin(kernel.valid_polys, cache=True)] if jit.available() else [])
    for m in (1, 2, 3):
        P = 40
        LO = np.where(rng.random((P, m)) < 0.3, -np.inf, rng.uniform(0.0, 3.0, (P, m)))
        HI = np.where(rng.random((P, m)) < 0.3, np.inf, LO + rng.uniform(0.0, 3.0, (P, m)))
        B = rng.random((P, m)) < 0.6
        O = rng.integers(0, 2, (P, m, 2))
        for _ in range(30):
            lo = rng.uniform(0.0, 3.0, m)
            hi = lo + rng.uniform(0.0, 1.0, m)
            want = rng.integers(0, 2, (m, 2))
            same = (O == want[None]).all(axis=2)
            ref = np.flatnonzero((lo >= LO).all(axis=1) & (hi <= HI).all(axis=1) & (same | ~B).all(axis=1))
            for fn in fns:
                out = np.empty(P, dtype=np.int64)
                n = fn(LO, HI, B, O, want, lo, hi, out)
                assert np.array_equal(out[:n], ref)


def test_polys_max_is_the_largest_tensor_polynomial_value() -> None:
    # against the sum over every multi-index of c_j prod_a lam_a^j_a (numpy), polynomials of zero
    # to three axes on vehicles of a three-vehicle problem, their crossing times in their pieces,
    # of 7 or 9 coefficients per axis side by side (the one-vehicle tangent polynomials have 2d + 3)
    from iamp.planners.avoid.dual import DualPolynomial, polys_values

    rng = np.random.default_rng(4)
    h = 0.1
    fns = [kernel.polys_max] + ([jit.twin(kernel.polys_max, cache=True)] if jit.available() else [])
    for _ in range(20):
        polys = []
        for _ in range(int(rng.integers(1, 5))):
            q = int(rng.integers(0, 4))
            n = int(rng.choice([7, 9]))
            vehicles = tuple(sorted(rng.choice(3, q, replace=False).tolist()))
            polys.append(DualPolynomial(vehicles, tuple(int(k) for k in rng.integers(0, 40, q)),
                                        rng.standard_normal((n,) * q), h, np.ones(3)))
        taus = rng.uniform(0.0, 4.0, (6, 3))
        for dp in polys:  # every polynomial vehicle's time in its piece
            for v, k in zip(dp.vehicles, dp.pieces):
                taus[:, v] = (k + rng.uniform(0.0, 1.0, 6)) * h
        # a polynomial whose vehicle's times a later one overwrote is evaluated off its piece:
        # still a polynomial, the reference holds there too
        ref = np.full(taus.shape[0], -np.inf)
        for dp in polys:
            lam = [(taus[:, v] - k * h) / h for v, k in zip(dp.vehicles, dp.pieces)]
            val = np.zeros(taus.shape[0])
            for j in np.ndindex(*dp.coef.shape):
                term = np.full(taus.shape[0], dp.coef[j])
                for a, e in enumerate(j):
                    term = term * lam[a] ** e
                val = val + term
            ref = np.maximum(ref, val)
        got = polys_values(polys, taus)
        assert np.allclose(got, ref, rtol=1e-12, atol=1e-10)
        for fn in fns:  # the twin: the same numbers bit for bit
            qs = np.array([dp.coef.ndim for dp in polys], dtype=np.int64)
            ns = np.array([dp.coef.shape[0] if dp.coef.ndim else 1 for dp in polys], dtype=np.int64)
            V = np.zeros((len(polys), 3), dtype=np.int64)
            K = np.zeros((len(polys), 3), dtype=np.int64)
            for p, dp in enumerate(polys):
                V[p, :len(dp.vehicles)], K[p, :len(dp.pieces)] = dp.vehicles, dp.pieces
            sizes = np.array([dp.coef.size for dp in polys])
            starts = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64)
            flat = np.concatenate([dp.coef.ravel() for dp in polys])
            out = np.empty(taus.shape[0])
            fn(flat, starts, qs, ns, V, K, h, taus, out, np.empty(3), np.empty(9 ** 3))
            assert np.array_equal(out, got)


def test_bernstein_min_is_the_smallest_tensor_bernstein_coefficient() -> None:
    # against the tensor Bernstein transform by numpy (one einsum per axis) and against the
    # polynomial's minimum on a dense grid of the box (which the smallest coefficient bounds)
    from iamp.planners.avoid.dual import _bernstein_on

    rng = np.random.default_rng(8)
    n = 7
    fns = [kernel.bernstein_min] + ([jit.twin(kernel.bernstein_min, cache=True)] if jit.available() else [])
    for q in (0, 1, 2, 3):
        P = 5
        coef = rng.standard_normal((P,) + (n,) * q)
        ab = np.sort(rng.uniform(0.0, 1.0, (P, max(q, 1), 2)), axis=2)
        B = np.zeros((P, max(q, 1), n, n))
        for p in range(P):
            for a in range(q):
                B[p, a] = _bernstein_on(n - 1, float(ab[p, a, 0]), float(ab[p, a, 1]))
        ref = coef.copy()
        for a in range(q):
            ref = np.moveaxis(np.einsum("p...i,pri->p...r", np.moveaxis(ref, a + 1, -1), B[:, a]), -1, a + 1)
        want = ref.reshape(P, -1).min(axis=1)
        outs = []
        for fn in fns:
            out = np.empty(P)
            fn(coef.reshape(P, -1), q, n, B, out, np.empty(n ** q), np.empty(n ** q))
            outs.append(out)
            assert np.allclose(out, want, rtol=1e-12, atol=1e-12)
        for out in outs[1:]:
            assert np.array_equal(out, outs[0])
        if q in (1, 2):  # the smallest coefficient bounds the polynomial on its box
            g = [np.linspace(ab[0, a, 0], ab[0, a, 1], 25) for a in range(q)]
            mesh = np.meshgrid(*g, indexing="ij")
            val = np.zeros(mesh[0].shape)
            for j in np.ndindex(*coef.shape[1:]):
                term = np.full(mesh[0].shape, coef[(0,) + j])
                for a, e in enumerate(j):
                    term = term * mesh[a] ** e
                val = val + term
            assert outs[0][0] <= val.min() + 1e-12


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st_h.integers(0, 10_000), st_h.integers(1, 40), st_h.floats(-1.0, 6.0))
def test_the_screened_maximum_bound_is_the_maximum_of_every_bound(seed: int, count: int, scale: float) -> None:
    """:func:`~iamp.planners.avoid.dual.max_lower_bound` bounds only the polynomials whose value at
    the box's centre can reach the best bound so far: its answer is ``max(lower_bounds(...))``
    bit for bit, over polynomials of zero to three vehicles whose coefficients span many orders
    of magnitude (cancellation), on boxes inside and across their pieces; a polynomial's kept
    bounds are at most :data:`~iamp.planners.avoid.dual.BOUNDS_KEPT`."""
    from iamp.planners.avoid.dual import BOUNDS_KEPT, DualPolynomial, lower_bounds, max_lower_bound

    rng = np.random.default_rng(seed)
    h, n = 0.1, 7
    polys = []
    for _ in range(count):
        q = int(rng.integers(0, 4))
        vehicles = tuple(sorted(rng.choice(3, q, replace=False).tolist()))
        coef = rng.standard_normal((n,) * q) * 10.0 ** rng.uniform(-2.0, scale, (n,) * q)
        polys.append(DualPolynomial(vehicles, tuple(int(k) for k in rng.integers(0, 4, q)), coef, h, np.ones(3)))
    for _ in range(3):
        lo = rng.uniform(0.0, 0.35, 3)
        hi = lo + rng.uniform(0.0, 0.08, 3) * rng.integers(0, 2, 3)
        fresh = [DualPolynomial(p.vehicles, p.pieces, p.coef, p.h, p.mass) for p in polys]  # empty caches
        assert max_lower_bound(polys, lo, hi) == max(lower_bounds(fresh, lo, hi))
    assert max_lower_bound([], lo, hi) == -np.inf
    dp = polys[0]
    for k in range(BOUNDS_KEPT + 5):  # many boxes: the kept bounds stay few, each the same again
        box = (np.full(3, 0.001 * k), np.full(3, 0.001 * k + 0.05))
        first = lower_bounds([dp], *box)[0]
        assert len(dp._bounds) <= BOUNDS_KEPT
        assert lower_bounds([dp], *box)[0] == first


def test_the_screened_maximum_reaches_a_flat_polynomial_behind_spiky_ones() -> None:
    """Ten polynomials peak at the box's centre and fall far below it at its ends (their bound is
    low although their centre value is the highest); a constant below those peaks has the best
    bound: it must be bounded although it ranks eleventh at the centre."""
    from iamp.planners.avoid.dual import ROUND_OFF_REL, DualPolynomial, max_lower_bound

    h = 0.1
    spike = np.zeros(7)
    spike[:3] = (10.0 - 250.0, 1000.0, -1000.0)  # 10 - 1000 (λ - 1/2)²
    polys = [DualPolynomial((0,), (2,), spike * (1.0 + 0.01 * j), h, np.ones(1)) for j in range(10)]
    polys.append(DualPolynomial((), (), np.array(1.0), h, np.ones(1)))
    got = max_lower_bound(polys, np.array([0.2]), np.array([0.3]))
    assert got == 1.0 - ROUND_OFF_REL
