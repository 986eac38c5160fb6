"""Basin exclusion boxes and the sharper pair bound (issue 14).

The basin box claims ``q ≥ lower`` on all of ``centre ± radius``; the tests sample it
densely, check the expansion's order of contact with ``q`` and compare the search with a
dense grid (the exclusion never hides a better point).
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


def test_the_search_is_one_implementation_whatever_is_loaded():
    """``compiled=True`` once took a numba copy of the search that agreed to ~1e-9 only; now
    every flag runs the one search: the same plan bit for bit (issue 32)."""
    from iamp.planners.pmp.planner import PMPPlanner

    for seed in (7, 11):
        p = random_problem(seed, m=2)
        plans = [PMPPlanner(compiled=flag).plan(p, diagnostics=False) for flag in (True, None, False)]
        assert len({(tuple(pl.contact_times), pl.cost, pl.status) for pl in plans}) == 1
        assert "compiled" not in plans[0].info["search"]
