"""The branch-and-bound certificate: its lower bound is valid on every box, tight to second
order at a minimum, and unbounded where two contact times meet or touch the ends."""

import numpy as np
import pytest

from iamp.planners.examples import random_problem
from iamp.planners.pmp.bound import branch_and_bound, lower_bound, taylor_shift
from iamp.planners.pmp.fixed import ValueFunction
from iamp.planners.pmp.search import newton_sigma, start_points
from iamp.planners.pmp.search_kernels import DK_ABOVE, DK_BELOW, kern, kern_ds, shift_range, shift_range2


def test_taylor_shift_and_ranges_are_exact_and_enclosing():
    rng = np.random.default_rng(0)
    C = rng.normal(size=(50, 6))
    c = rng.uniform(0, 1, 50)
    r = rng.uniform(0, 0.2, 50)
    A = taylor_shift(C, c)
    h = rng.uniform(-1, 1, 50) * r
    direct = np.array([np.polynomial.polynomial.polyval(c[k] + h[k], C[k]) for k in range(50)])
    shifted = np.array([np.polynomial.polynomial.polyval(h[k], A[k]) for k in range(50)])
    assert np.allclose(direct, shifted, atol=1e-12)
    ranges = [shift_range(C[k], c[k:k + 1], r[k:k + 1]) for k in range(50)]
    lo, hi = np.array([x[0][0] for x in ranges]), np.array([x[1][0] for x in ranges])
    assert np.all(lo <= direct + 1e-12) and np.all(direct <= hi + 1e-12)
    # bivariate: s^2 t - 3 s t^2 + 1
    A2 = np.zeros((4, 4))
    A2[2, 1], A2[1, 2], A2[0, 0] = 1.0, -3.0, 1.0
    cs, ct, rs, rt = rng.uniform(0, 1, 30), rng.uniform(0, 1, 30), np.full(30, 0.05), np.full(30, 0.1)
    lo2, hi2 = shift_range2(A2, cs, ct, rs, rt)
    for k in range(30):
        s = cs[k] + rs[k] * rng.uniform(-1, 1, 40)
        t = ct[k] + rt[k] * rng.uniform(-1, 1, 40)
        v = s**2 * t - 3 * s * t**2 + 1
        assert np.all(lo2[k] <= v + 1e-12) and np.all(v <= hi2[k] + 1e-12)
    assert np.allclose(shift_range2(A2, cs, ct, 0 * rs, 0 * rt)[0], cs**2 * ct - 3 * cs * ct**2 + 1)


def test_the_kernel_derivative_coefficients_are_the_derivative_of_the_kernel():
    """``DK_BELOW``/``DK_ABOVE`` (the bivariate ``∂K/∂s`` the Fenchel bound ranges over) and
    ``kern_ds`` against a central difference of ``kern`` on both sides of the diagonal."""
    rng = np.random.default_rng(3)
    s, t = rng.uniform(0.02, 0.98, 200), rng.uniform(0.02, 0.98, 200)
    s, t = s[np.abs(s - t) > 1e-3], t[np.abs(s - t) > 1e-3]
    h = 1e-6
    fd = (kern(s + h, t) - kern(s - h, t)) / (2 * h)
    poly = np.array([sum((DK_BELOW if a <= b else DK_ABOVE)[i, j] * a**i * b**j for i in range(4) for j in range(4))
                     for a, b in zip(s, t)])
    assert np.allclose(poly, fd, atol=1e-8) and np.allclose(kern_ds(s, t), fd, atol=1e-8)


@pytest.mark.parametrize("m,seed", [(2, 0), (2, 5), (3, 1)])
def test_lower_bound_is_valid_on_random_boxes(m, seed):
    vf = ValueFunction(random_problem(seed, m=m))
    rng = np.random.default_rng(seed)
    n = 300
    c = rng.uniform(0.05, 0.95, (n, m))
    r = rng.choice([0.003, 0.02, 0.08], size=(n, 1)) * np.ones((1, m))
    lb = lower_bound(vf, c, r)
    for k in range(n):
        pts = c[k] + r[k] * rng.uniform(-1, 1, (200, m))
        pts = np.vstack([pts, c[k] + r[k] * np.sign(rng.uniform(-1, 1, (20, m)))])  # corners too
        q = vf.quad_sigma(np.clip(pts, 1e-9, 1 - 1e-9))
        assert lb[k] <= np.min(q) * (1 + 1e-9) + 1e-12, (k, lb[k], np.min(q))


def test_lower_bound_is_second_order_tight_at_a_minimum():
    vf = ValueFunction(random_problem(0, m=2))
    s, q = newton_sigma(vf, start_points(vf.scaled)[0])
    gaps = []
    for w in (1e-2, 1e-3, 1e-4):
        c = s[None, :] + np.array([[0.3 * w, -0.2 * w]])
        gaps.append(q - float(lower_bound(vf, c, np.full((1, 2), w))[0]))
    assert all(g >= -1e-12 for g in gaps)
    # gap ~ w²: a factor ~100 per factor 10 in w (first order would give ~10)
    assert gaps[1] < gaps[0] / 50 and gaps[2] < gaps[1] / 50


def test_lower_bound_blows_up_at_the_diagonal_and_the_ends():
    vf = ValueFunction(random_problem(2, m=2))
    near_diag = lower_bound(vf, np.array([[0.5, 0.5]]), np.full((1, 2), 1e-5))[0]
    near_end = lower_bound(vf, np.array([[1e-5, 0.5]]), np.array([[1e-5, 1e-3]]))[0]
    q_typ = float(np.min(vf.quad_sigma(np.random.default_rng(0).uniform(0.05, 0.95, (2000, 2)))))
    assert near_diag > 100 * q_typ and near_end > 100 * q_typ


def test_branch_and_bound_finds_the_global_basin_from_a_bad_start():
    vf = ValueFunction(random_problem(3, m=2))
    bad = np.array([0.9, 0.1])
    q_bad = float(vf.quad_sigma(bad[None, :])[0])
    res = branch_and_bound(vf, bad, q_bad, lambda s0: newton_sigma(vf, s0), max_boxes=200_000)
    assert res.certified
    g = (np.arange(300) + 0.5) / 300
    A, B = np.meshgrid(g, g, indexing="ij")
    Z = vf.quad_sigma(np.stack([A, B], axis=-1))
    assert res.q <= float(np.min(Z)) * (1 + 1e-9)
    assert res.q < q_bad


def _on_the_free_path(m: int, gap: float) -> ValueFunction:
    """Corners that lie (almost) on the unconstrained path: q ≈ 0 everywhere."""
    from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
    from iamp.planners.examples import DEFAULT_GEOMETRY
    from iamp.planners.pmp.fixed import hermite_cubic

    ego = EgoBoundary(tf=5.0, x0=0.0, y0=3.75, vx0=20.0, xf=105.0, yf=3.75, vxf=22.0)
    hx = hermite_cubic(ego.x0, ego.vx0, ego.xf, ego.vxf, ego.tf)
    vs = []
    for i in range(m):
        off = DEFAULT_GEOMETRY["length"] / 2 + DEFAULT_GEOMETRY["safety_x"]
        poly = tuple(hx - np.r_[off - i * gap, 0, 0, 0])
        y = 3.75 - DEFAULT_GEOMETRY["width"] / 2 - DEFAULT_GEOMETRY["safety_y"]
        vs.append(SurroundingVehicle(x_poly=poly, corner="front-upper", y=y, name=f"v{i}", **DEFAULT_GEOMETRY))
    return ValueFunction(Problem(ego, tuple(vs), "free-path"))


@pytest.mark.parametrize("m,gap", [(2, 0.01), (3, 0.02)])
def test_lower_bound_is_valid_where_q_is_tiny_and_near_the_diagonal(m, gap):
    vf = _on_the_free_path(m, gap)
    rng = np.random.default_rng(1)
    n = 200
    base = rng.uniform(0.1, 0.9, (n, 1))
    c = np.clip(base + rng.normal(0, 0.01, (n, m)), 0.02, 0.98)  # all times close together
    r = np.full((n, m), 0.01)
    lb = lower_bound(vf, c, r)
    for k in range(n):
        pts = np.clip(c[k] + r[k] * rng.uniform(-1, 1, (300, m)), 1e-9, 1 - 1e-9)
        q = vf.quad_sigma(pts)
        assert lb[k] <= np.min(q) * (1 + 1e-9) + 1e-15, (k, lb[k], np.min(q))


def test_stationarity_polynomial_matches_its_definition():
    """P = N'σ(1−σ) − 3N(1−2σ), N = ex² + ey², also for inputs of different lengths."""
    from numpy.polynomial import polynomial as Pn

    from iamp.planners.pmp.search import stationarity_poly

    long, short = [0.3, -1.2, 0.5, 0.7, -0.1], [0.2, 0.4]
    for ex, ey in ((long, short), (short, long)):
        N = Pn.polyadd(Pn.polymul(ex, ex), Pn.polymul(ey, ey))
        ref = Pn.polysub(Pn.polymul(Pn.polyder(N), [0.0, 1.0, -1.0]), Pn.polymul(3 * N, [1.0, -2.0]))
        got = np.array(stationarity_poly(ex, ey))
        assert np.allclose(got[: ref.size], ref, atol=1e-14) and not np.any(got[ref.size:])


def test_newton_converges_quadratically_near_a_minimum():
    vf = ValueFunction(random_problem(0, m=2))
    s_star, _ = newton_sigma(vf, start_points(vf.scaled)[0])
    s, _ = newton_sigma(vf, s_star + np.array([2e-3, -1e-3]), max_iter=5)
    assert np.max(np.abs(s - s_star)) < 1e-10
    assert np.max(np.abs(vf.gradient_sigma(s[None, :])[0])) < 1e-9
