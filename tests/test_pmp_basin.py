"""Basin exclusion boxes, the sharper pair bound and the compiled search (issue 14).

The basin box claims ``q ≥ lower`` on all of ``centre ± radius``; the tests sample it
densely, check the expansion's order of contact with ``q``, compare the search with a dense
grid (the exclusion never hides a better point), and the numba path with the numpy path
(same contact times to 1e-9, same certificate).
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core.tolerances import tol
from iamp.planners.examples import random_problem
from iamp.planners.pmp.basin import basin_box, expansion
from iamp.planners.pmp.bound import lower_bound, speed_variance_max
from iamp.planners.pmp.fixed import ValueFunction, bridge_kernel
from iamp.planners.pmp.search import global_search, newton_sigma, start_points, trusted_q

SETTINGS = settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
problems = st.tuples(st.integers(0, 10_000), st.integers(2, 3), st.sampled_from([-1, 1]))


def _minimiser(vf: ValueFunction) -> tuple[np.ndarray, float]:
    best = (np.zeros(0), np.inf)
    for s0 in start_points(vf.scaled)[:4]:
        s, q = newton_sigma(vf, s0)
        if q < best[1]:
            best = (s, q)
    return best


def _delta(vf: ValueFunction, q: float) -> float:
    return 0.25 * tol("pmp_global_certificate_rel") * (vf.scaled.jbar + 0.5 * q)


def _eval_dense(c: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``Σ c[α] h^α`` for rows ``h`` (``(n, m)``)."""
    idx = np.indices(c.shape).reshape(c.ndim, -1).T
    return np.prod(h[:, None, :] ** idx[None, :, :], axis=2) @ c.reshape(-1)


@SETTINGS
@given(problems)
def test_basin_lower_bound_holds_on_the_whole_box(case):
    seed, m, side = case
    vf = ValueFunction(random_problem(seed, m=m, side=side))
    s, q = _minimiser(vf)
    b = basin_box(vf, s, _delta(vf, q))
    if b is None:
        return
    rng = np.random.default_rng(seed)
    pts = s + b.radius * rng.uniform(-1, 1, (4000, m))
    corners = s + b.radius * (2 * np.indices((2,) * m).reshape(m, -1).T - 1)
    qs = vf.quad_sigma(np.clip(np.vstack([pts, corners]), 1e-12, 1 - 1e-12))
    assert np.min(qs) >= b.lower
    # and it is tight: within δ (plus rounding) of q at the minimiser
    assert q - _delta(vf, q) - 2e-11 * q <= b.lower <= q


@SETTINGS
@given(st.integers(0, 10_000), st.sampled_from([-1, 1]))
def test_box_bound_of_the_minorant_holds_on_random_boxes(seed, side):
    vf = ValueFunction(random_problem(seed, m=2, side=side))
    s, q = _minimiser(vf)
    b = basin_box(vf, s, _delta(vf, q))
    if b is None:
        return
    rng = np.random.default_rng(seed)
    c = np.clip(s + rng.uniform(-0.3, 0.3, (60, 2)), 0.02, 0.98)
    r = rng.uniform(1e-4, 0.05, (60, 2))
    lb = b.box_bound(c, r)
    assert np.any(np.isfinite(lb))
    for k in np.nonzero(np.isfinite(lb))[0]:
        pts = np.clip(c[k] + r[k] * rng.uniform(-1, 1, (300, 2)), 1e-9, 1 - 1e-9)
        assert lb[k] <= np.min(vf.quad_sigma(pts))


@pytest.mark.parametrize("seed,m", [(0, 2), (1, 3), (2, 2)])
def test_expansion_is_a_minorant_touching_q_to_third_order(seed, m):
    """``G ≤ q`` and ``q − G = O(|h|⁴)``: the ratio over a decade of ``|h|`` is ≈ 10⁴."""
    vf = ValueFunction(random_problem(seed, m=m))
    s, _ = _minimiser(vf)
    c = expansion(vf, s)
    d = np.random.default_rng(0).normal(size=m)
    d /= np.max(np.abs(d))
    gaps = []
    for h in (3e-2, 3e-3):
        gap = float(vf.quad_sigma((s + h * d)[None, :])[0] - _eval_dense(c, (h * d)[None, :])[0])
        assert gap >= -1e-12
        gaps.append(gap)
    assert 10**3.5 < gaps[0] / gaps[1] < 10**4.5


def test_speed_variance_bound_covers_the_kernel():
    """``Var(s(σ_i) − s(σ_j)) ≤ (σ_i − σ_j)² max Var v`` on a dense grid, and the maximum
    speed variance is ``1/12``."""
    t = np.linspace(1e-3, 1 - 1e-3, 400)
    a, b = np.meshgrid(t, t, indexing="ij")
    V = bridge_kernel(a, a, 1.0) + bridge_kernel(b, b, 1.0) - 2 * bridge_kernel(a, b, 1.0)
    vmax = speed_variance_max(np.minimum(a, b), np.maximum(a, b))
    assert np.all(V <= (a - b) ** 2 * vmax * (1 + 1e-12) + 1e-300)
    assert np.isclose(float(speed_variance_max(np.array(0.0), np.array(1.0))), 1 / 12)


def test_speed_variance_max_is_the_exact_maximum_over_the_interval():
    """``max_{σ∈[a,b]} x(1 − 3x)`` with ``x = σ(1 − σ)``: never below a dense sample of the
    interval (a valid bound) and never above it by more than the sampling error (sharp)."""
    rng = np.random.default_rng(11)
    a = rng.uniform(0.0, 1.0, 500)
    b = np.minimum(a + rng.uniform(0.0, 0.6, 500), 1.0)
    got = speed_variance_max(a, b)
    for k in range(a.size):
        sig = np.linspace(a[k], b[k], 2001)
        x = sig * (1 - sig)
        sampled = float(np.max(x * (1 - 3 * x)))
        assert sampled <= got[k] * (1 + 1e-12) + 1e-15
        assert got[k] <= sampled + 1e-6


@pytest.mark.parametrize("m,seed", [(2, 5), (3, 6)])
def test_sharper_pair_bound_is_still_valid(m, seed):
    vf = ValueFunction(random_problem(seed, m=m))
    rng = np.random.default_rng(seed)
    n = 300
    c = rng.uniform(0.05, 0.95, (n, m))
    c[:, 1] = np.clip(c[:, 0] + rng.normal(0, 0.03, n), 0.02, 0.98)  # near the diagonal
    r = rng.uniform(1e-3, 0.02, (n, m))
    lb = lower_bound(vf, c, r)
    for k in range(n):
        q = vf.quad_sigma(np.clip(c[k] + r[k] * rng.uniform(-1, 1, (200, m)), 1e-9, 1 - 1e-9))
        assert lb[k] <= np.min(q) * (1 + 1e-9) + 1e-15


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10_000), st.sampled_from([-1, 1]))
def test_search_is_never_above_a_dense_grid(seed, side):
    vf = ValueFunction(random_problem(seed, m=2, side=side))
    res = global_search(vf)
    assert res.certified
    g = (np.arange(240) + 0.5) / 240
    A, B = np.meshgrid(g, g, indexing="ij")
    Z = vf.quad_sigma(np.stack([A, B], axis=-1))
    assert res.q <= float(np.min(Z)) * (1 + 1e-9)
    assert trusted_q(vf, res.sigma) == pytest.approx(res.q, rel=1e-12)


# --- the compiled path -----------------------------------------------------------------
numba = pytest.importorskip("numba")


@pytest.fixture(scope="module")
def fast():
    from iamp.planners.pmp import compiled_search as fast

    assert fast.load(), fast._STATE.get("error")
    return fast


def test_compiled_kernels_equal_the_numpy_ones(fast):
    from iamp.planners.pmp import compiled_kernels as kk

    for m, seed in ((2, 3), (3, 4)):
        vf = ValueFunction(random_problem(seed, m=m))
        rng = np.random.default_rng(seed)
        c = rng.uniform(0.05, 0.95, (50, m))
        r = rng.uniform(1e-4, 0.05, (50, m))
        ws = kk.workspace(m, vf._EX.shape[1])
        lb = lower_bound(vf, c, r)
        lbc = np.array([kk.lower_bound_box(vf._EX, vf._EY, vf._DEX, vf._DEY, c[k], r[k], np.inf, ws)
                        for k in range(50)])
        assert np.allclose(lbc, lb, rtol=1e-9, atol=1e-12)
        qc = np.array([kk.quad(vf._EX, vf._EY, c[k], vf.scaled.jbar) for k in range(50)])
        assert np.allclose(qc, vf.quad_sigma(c), rtol=1e-8)  # Gaussian elimination vs LAPACK
        s, q = _minimiser(vf)
        b = basin_box(vf, s, _delta(vf, q))
        rho, low, G = kk.basin_box(vf._EX, vf._EY, vf._DEX, vf._DEY, s, _delta(vf, q), 5)
        assert b is not None and rho == pytest.approx(b.radius, rel=1e-9) and low == pytest.approx(b.lower, rel=1e-12)
        assert np.allclose(G, b.coeffs.reshape(-1), rtol=1e-12, atol=1e-12 * np.max(np.abs(G)))
        if m == 2:  # the second-order box bound, on boxes around the minimiser
            D = b.coeffs.shape[0] - 1
            expo = np.array([list(ix) + [sum(ix)] for ix in np.ndindex(*b.coeffs.shape)], dtype=np.int64)
            cb = s + rng.uniform(-0.1, 0.1, (40, m))
            rb = rng.uniform(1e-3, 0.03, (40, m))
            ref = b.box_bound(cb, rb)
            got = np.array([kk.g_bound(G, s, cb[k], rb[k], D, np.empty(G.size), np.empty((m, m)), expo,
                                       np.empty((m, D + 1))) for k in range(40)])
            got2 = np.array([kk.g_bound2(G, s, cb[k], rb[k], D, np.empty((D + 1, D + 1))) for k in range(40)])
            fin = np.isfinite(ref)
            assert np.array_equal(fin, np.isfinite(got)) and np.array_equal(fin, np.isfinite(got2)) and fin.any()
            assert np.allclose(got[fin], ref[fin], rtol=1e-9, atol=1e-9 * abs(q))
            assert np.allclose(got2[fin], ref[fin], rtol=1e-9, atol=1e-9 * abs(q))
        S = vf.scaled
        P = (S.ego, np.ascontiguousarray(S.CX), np.asarray(S.CY, float), S.jbar, tol("pmp_cost_consistency_rel"))
        assert kk.trusted(P, s, q) == q == trusted_q(vf, s)


@SETTINGS
@given(problems)
def test_compiled_search_gives_the_pure_answer(fast, case):
    seed, m, side = case
    vf = ValueFunction(random_problem(seed, m=m, side=side))
    a = global_search(vf)
    b = fast.run(vf.scaled)
    assert a.certified == b.certified
    assert np.max(np.abs(a.sigma - b.sigma)) <= 1e-9 or abs(a.q - b.q) <= 1e-9 * (vf.scaled.jbar + 0.5 * a.q)
    assert abs(a.q - b.q) <= 2 * tol("pmp_global_certificate_rel") * (vf.scaled.jbar + 0.5 * min(a.q, b.q))


def test_planner_uses_the_compiled_path_only_when_asked(fast):
    from iamp.planners.pmp.planner import PMPPlanner

    p = random_problem(7, m=2)
    on = PMPPlanner(compiled=True).plan(p, diagnostics=False)
    off = PMPPlanner(compiled=False).plan(p, diagnostics=False)
    assert on.info["search"]["compiled"] and not off.info["search"]["compiled"]
    assert on.status == off.status
    assert np.allclose(on.contact_times, off.contact_times, rtol=0, atol=1e-9 * p.tf)
