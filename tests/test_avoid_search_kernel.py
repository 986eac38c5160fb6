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
    from iamp.planners.avoid.dual import DualPolynomial, _pack, polys_values

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
            flat, meta, W, largest = _pack(polys)
            out = np.empty(taus.shape[0])
            fn(flat, meta, W, h, taus, out, np.empty(W), np.empty(largest))
            assert np.array_equal(out, got)


def _bernstein_reference(dp, lo, hi):  # type: ignore[no-untyped-def]
    """The tensor Bernstein coefficients of ``dp`` on the box by numpy: per axis the matrix
    ``power_to_bernstein(d) @ reparametrise(d, λ_a, λ_b - λ_a)`` applied along it."""
    from iamp.planners.avoid.bernstein import power_to_bernstein, reparametrise

    ref = np.asarray(dp.coef, dtype=float)
    n = ref.shape[0] if ref.ndim else 1
    for a, (v, k) in enumerate(zip(dp.vehicles, dp.pieces)):
        la = min(max((lo[v] - k * dp.h) / dp.h, 0.0), 1.0)
        lb = min(max((hi[v] - k * dp.h) / dp.h, la), 1.0)
        B = power_to_bernstein(n - 1) @ reparametrise(n - 1, la, lb - la)
        ref = np.moveaxis(np.tensordot(B, np.moveaxis(ref, a, 0), axes=(1, 0)), 0, a)
    return ref


def _random_poly(rng, h, flat_axes=False):  # type: ignore[no-untyped-def]
    from iamp.planners.avoid.dual import DualPolynomial

    q = int(rng.integers(0, 4))
    n = int(rng.choice([7, 9])) if q == 1 else 7
    vehicles = tuple(sorted(rng.choice(3, q, replace=False).tolist()))
    coef = rng.standard_normal((n,) * q) * 10.0 ** rng.uniform(-2.0, 3.0, (n,) * q)
    if flat_axes and q:  # a vehicle that does not bind: the polynomial constant along its axis
        for a in range(q):
            if rng.uniform() < 0.5:
                index = [slice(None)] * q
                index[a] = slice(1, None)
                coef[tuple(index)] = 0.0
    return DualPolynomial(vehicles, tuple(int(k) for k in rng.integers(0, 4, q)), coef, h, np.ones(3),
                          roundoff=float(rng.uniform(0.0, 1e-9)))


@settings(max_examples=80, deadline=None)
@given(st_h.integers(0, 10_000), st_h.booleans())
def test_a_bound_is_the_smallest_tensor_bernstein_coefficient_less_the_margin(seed: int, flat: bool) -> None:
    """:func:`~iamp.planners.avoid.dual.lower_bounds` (:func:`~iamp.planners.avoid.search_kernel.poly_bounds`)
    against the tensor Bernstein transform by numpy (:func:`_bernstein_reference`), less the margin,
    to 1e-15 of the coefficients' size, for polynomials of zero to three axes with coefficients
    over five orders of magnitude, some constant along axes (dropped by the kernel, the same
    coefficients); the smallest coefficient bounds the polynomial on a dense grid of the box; the
    Python kernel and its numba twin agree bit for bit."""
    from iamp.planners.avoid.dual import ROUND_OFF_REL, _kernel_tables, _pack, lower_bounds

    rng = np.random.default_rng(seed)
    h = 0.1
    polys = [_random_poly(rng, h, flat) for _ in range(int(rng.integers(1, 5)))]
    lo = rng.uniform(0.0, 0.4, 3)
    hi = lo + rng.uniform(0.0, 0.12, 3) * rng.integers(0, 2, 3)
    got = lower_bounds(polys, lo, hi)
    for dp, g in zip(polys, got):
        m = float(np.min(_bernstein_reference(dp, lo, hi)))
        want = m - ROUND_OFF_REL * max(1.0, abs(m)) - dp.roundoff
        assert abs(g - want) <= 1e-15 * max(1.0, float(np.abs(dp.coef).sum()))
        if 1 <= len(dp.vehicles) <= 2:  # the smallest coefficient bounds the polynomial on its box
            grids = []
            for v, k in zip(dp.vehicles, dp.pieces):
                la = min(max((lo[v] - k * h) / h, 0.0), 1.0)
                grids.append(np.linspace(la, min(max((hi[v] - k * h) / h, la), 1.0), 15))
            mesh = np.meshgrid(*grids, indexing="ij")
            val = np.zeros(mesh[0].shape)
            for j in np.ndindex(*dp.coef.shape):
                term = np.full(mesh[0].shape, dp.coef[j])
                for a, e in enumerate(j):
                    term = term * mesh[a] ** e
                val = val + term
            assert g <= val.min() + 1e-9 * max(1.0, float(np.abs(dp.coef).sum()))
    fns = [kernel.poly_bounds] + ([jit.twin(kernel.poly_bounds, cache=True)] if jit.available() else [])
    outs = []
    for fn in fns:
        flat_c, meta, W, largest = _pack(polys)
        n = int(meta[:, 1].max())
        out = np.empty(len(polys))
        fn(flat_c, meta, W, np.array([dp.roundoff for dp in polys]), h, ROUND_OFF_REL, lo, hi, *_kernel_tables(n), out,
           np.empty(largest), np.empty(largest), np.empty(n), np.empty((n, n)), np.empty(W, dtype=np.int64))
        outs.append(out)
    assert np.array_equal(outs[0], np.array(got))
    for out in outs[1:]:
        assert np.array_equal(out, outs[0])


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st_h.integers(0, 10_000), st_h.integers(1, 40), st_h.floats(-1.0, 6.0))
def test_the_screened_maximum_bound_is_the_maximum_of_every_bound(seed: int, count: int, scale: float) -> None:
    """:func:`~iamp.planners.avoid.dual.max_lower_bound` bounds only the polynomials whose value at
    the box's centre can reach the best bound so far: its answer is ``max(lower_bounds(...))``
    bit for bit, over polynomials of zero to three vehicles whose coefficients span many orders
    of magnitude (cancellation), on boxes inside and across their pieces, asked again (work space
    kept between calls) the same."""
    from iamp.planners.avoid.dual import DualPolynomial, lower_bounds, max_lower_bound

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
        best = max_lower_bound(polys, lo, hi)
        assert best == max(lower_bounds(polys, lo, hi))
        assert max_lower_bound(polys, lo, hi) == best
    assert max_lower_bound([], lo, hi) == -np.inf


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st_h.integers(0, 10_000), st_h.integers(1, 12))
def test_a_search_s_packing_memo_gives_the_packing_it_computes(seed: int, count: int) -> None:
    """:class:`~iamp.planners.avoid.dual.Packing` (one search's memo of :func:`_pack`): the arrays
    of a list of polynomials are those computed without it, kept for the same list (the same
    objects), computed anew for another list of the same length or the same list after
    :attr:`~iamp.planners.avoid.dual.Packing.SIZE` other lists, and ``meta`` handed out as a copy
    (the kernels overwrite it); the bound and the values with the memo are those without it."""
    from iamp.planners.avoid.dual import DualPolynomial, Packing, _pack, max_lower_bound, polys_values

    rng = np.random.default_rng(seed)
    h, n = 0.1, 7

    def draw(k: int) -> list[DualPolynomial]:
        return [DualPolynomial((0,), (int(rng.integers(0, 4)),), rng.standard_normal(n), h, np.ones(1))
                for _ in range(k)]

    polys = draw(count)
    packing = Packing()
    plain = _pack(polys)
    first = _pack(polys, None, packing)
    for a, b in zip(plain, first):
        assert np.array_equal(np.asarray(a), np.asarray(b))
    again = _pack(polys, None, packing)
    assert again[0] is first[0]  # kept: not packed again
    assert again[1] is not first[1] and np.array_equal(again[1], first[1])  # meta: a copy each time
    first[1][:] = -1  # a kernel's overwrite of its copy leaves the kept meta alone
    assert np.array_equal(_pack(polys, None, packing)[1], plain[1])
    other = draw(count)
    assert not np.array_equal(_pack(other, None, packing)[0], first[0]) or count == 0
    # SIZE lists are kept, the oldest dropped for the next: ``polys`` and SIZE - 1 others, then one more
    fresh = Packing()
    kept = _pack(polys, None, fresh)[0]
    for _ in range(Packing.SIZE - 1):
        _pack(draw(1), None, fresh)
    assert _pack(polys, None, fresh)[0] is kept
    _pack(draw(1), None, fresh)
    assert _pack(polys, None, fresh)[0] is not kept  # dropped, packed anew: the same numbers
    assert np.array_equal(_pack(polys, None, fresh)[0], plain[0])
    lo, hi = np.array([0.05]), np.array([0.3])
    assert max_lower_bound(polys, lo, hi, packing) == max_lower_bound(polys, lo, hi)
    taus = rng.uniform(0.0, 0.4, (5, 1))
    assert np.array_equal(polys_values(polys, taus, packing=packing), polys_values(polys, taus))


def test_a_nan_bound_proves_nothing_and_mixed_widths_pack() -> None:
    """A polynomial with a NaN coefficient has a NaN bound, which the maximum skips (it proves
    nothing); polynomials of problems with different numbers of vehicles are padded to one width."""
    from iamp.planners.avoid.dual import ROUND_OFF_REL, DualPolynomial, lower_bounds, max_lower_bound

    h = 0.1
    bad = DualPolynomial((0,), (1,), np.array([np.nan] + [0.0] * 6), h, np.ones(3))
    good = DualPolynomial((), (), np.array(2.0), h, np.ones(1))
    lo, hi = np.array([0.12, 0.0, 0.0]), np.array([0.15, 0.0, 0.0])
    bounds = lower_bounds([bad, good], lo, hi)
    assert np.isnan(bounds[0]) and bounds[1] == 2.0 - 2.0 * ROUND_OFF_REL
    assert max_lower_bound([bad, good], lo, hi) == bounds[1]
    assert max_lower_bound([bad], lo, hi) == -np.inf


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
