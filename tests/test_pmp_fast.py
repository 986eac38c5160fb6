"""Root isolation without eigenvalues, the one-vehicle fast path, the batch and the optional
numba compilation of the one kernel (issue 14): same numbers as the general path, every root found."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import polynomial as P

from iamp.core.status import OPTIMAL
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp.compiled import numba_available
from iamp.planners.pmp.one import one_vehicle_data, one_vehicle_kernel
from iamp.planners.pmp.planner import PMPPlanner, ValueFunction, plan_batch, solve_fixed_times
from iamp.planners.pmp.roots import casteljau_halves, sign_variations, to_bernstein, unit_roots
from iamp.planners.pmp.verify import check_values, judge


def companion_roots(a):
    """Reference (test only): real roots in (0, 1) from numpy's companion eigenvalues."""
    r = np.roots(np.asarray(a, float)[::-1])
    return np.sort(r[(np.abs(r.imag) < 1e-9) & (r.real > 0) & (r.real < 1)].real)


def test_bernstein_coefficients_evaluate_the_polynomial():
    rng = np.random.default_rng(0)
    for n in (1, 3, 7, 20):
        a = rng.normal(size=n + 1)
        b = to_bernstein(list(a))
        x = rng.uniform(0, 1, 5)
        from math import comb

        val = sum(b[j] * comb(n, j) * x**j * (1 - x) ** (n - j) for j in range(n + 1))
        assert np.allclose(val, P.polyval(x, a), atol=1e-12)


def test_casteljau_halves_represent_each_half():
    a = [0.3, -2.0, 1.0, 4.0, -1.5]
    left, right = casteljau_halves(to_bernstein(a))
    # the left half in u ∈ [0,1] is p(u/2), the right half p((1+u)/2)
    al = [c * 0.5**k for k, c in enumerate(a)]
    assert np.allclose(left, to_bernstein(al))
    ar = P.polyval(0.5, P.polyder(a, 0))  # value at the split point
    assert right[0] == pytest.approx(ar) and left[-1] == pytest.approx(ar)


def test_sign_variations_skip_zeros():
    assert sign_variations([1.0, 0.0, -2.0, 0.0, 3.0]) == 2
    assert sign_variations([0.0, 0.0]) == 0
    assert sign_variations([-1.0, -1.0, 2.0]) == 1


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-10, 10, allow_nan=False).map(lambda x: x if abs(x) > 1e-3 else 0.0), min_size=2,
                max_size=14))
def test_unit_roots_find_every_simple_root(coeffs):
    a = np.array(coeffs)
    if np.all(a == 0) or np.max(np.abs(a)) < 1e-6:
        return
    ref = companion_roots(a)
    got = np.array(unit_roots(list(a)))
    # a root the eigenvalues see must be found, unless it is a near-multiple root
    for r in ref:
        if np.min(np.abs(ref[ref != r] - r), initial=1.0) > 1e-5 and 1e-6 < r < 1 - 1e-6:
            assert np.min(np.abs(got - r)) < 1e-8, (a, ref, got)
    for g in got:  # everything found is a root
        p = abs(P.polyval(g, a))
        assert p <= 1e-9 * np.sum(np.abs(a)), (a, g, p)


def test_unit_roots_of_known_factors():
    a = P.polyfromroots([0.1, 0.35, 0.9, 1.5, -0.2])
    assert np.allclose(unit_roots(list(a)), [0.1, 0.35, 0.9], atol=1e-13)
    close = P.polyfromroots([0.5, 0.5 + 1e-7, 0.2])
    assert len(unit_roots(list(close))) == 3
    assert unit_roots([1.0, 2.0]) == [] and unit_roots([5.0]) == []


@pytest.mark.parametrize("problem", [paper_problem(k) for k in (1, 2, 3)] + [two_minima_problem()]
                         + [random_problem(s) for s in range(6)], ids=lambda p: p.name)
def test_fast_path_equals_the_general_path(problem):
    """The scalar kernel and the general (dense) path: same contact time, cost and jumps,
    and the general verification passes on the fast path's solution."""
    fast = PMPPlanner().plan(problem, diagnostics=False)
    assert fast.status == OPTIMAL
    t = fast.contact_times
    dense = solve_fixed_times(problem, t)
    assert fast.cost == pytest.approx(dense.cost(), rel=1e-12)
    assert np.allclose(fast.jumps, dense.jumps, rtol=1e-10, atol=1e-10)
    assert fast.cost == pytest.approx(float(ValueFunction(problem)(t[None, :])[0]), rel=1e-12)
    checks, failed, _ = judge(check_values(fast.trajectory))
    assert failed is None, checks
    # the other stationary points are not better
    for s in ValueFunction(problem).stationary_points_1d():
        assert fast.cost <= float(ValueFunction(problem)(np.array([[s]]))[0]) * (1 + 1e-12)


def test_kernel_rejects_a_problem_without_interior_stationary_point():
    out = one_vehicle_kernel([0.0] * 8, [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0] * 4, 0.0)
    assert out[0] != out[0]  # NaN


def test_batch_equals_planner_bit_for_bit():
    problems = [random_problem(s) for s in range(300)] + [paper_problem(1), two_minima_problem()]
    batch = plan_batch(problems)
    planner = PMPPlanner()
    for k, p in enumerate(problems):
        ref = planner.plan(p, diagnostics=False)
        assert batch.status[k] == ref.status == OPTIMAL
        assert batch.cost[k] == ref.cost and batch.contact_time[k] == ref.contact_times[0]
        assert np.array_equal(batch.jumps[k], ref.jumps[0])


def test_batch_of_nothing_and_of_several_vehicles():
    assert plan_batch([]).cost.shape == (0,)
    with pytest.raises(ValueError):
        plan_batch([random_problem(0, m=2)])


@pytest.mark.slow
@pytest.mark.skipif(not numba_available(), reason="numba not installed")
def test_compiled_kernel_gives_identical_numbers():
    from iamp.planners.pmp.compiled import compiled_kernel

    kern = compiled_kernel()
    for p in [paper_problem(k) for k in (1, 2, 3)] + [random_problem(s) for s in range(50)] + [two_minima_problem()]:
        _, _, ego, ex, ey, cx, cy = one_vehicle_data(p)
        assert kern(ego, ex, ey, cx, cy) == one_vehicle_kernel(ego, ex, ey, cx, cy)
        a = PMPPlanner(kernel=kern).plan(p, diagnostics=False)
        b = PMPPlanner().plan(p, diagnostics=False)
        assert a.cost == b.cost and np.array_equal(a.contact_times, b.contact_times)


@pytest.mark.parametrize("roots,expected", [
    ([0.5, 0.25, 0.8], [0.25, 0.5, 0.8]),  # a root exactly at the first split point
    ([0.0, 0.3, 2.0], [0.3]),  # a root at the end of the interval (zero Bernstein end)
    ([0.75, 0.125, 1.0, -3.0], [0.125, 0.75]),  # roots at later split points and at 1
])
def test_roots_on_split_points_and_ends_are_found_once(roots, expected):
    a = P.polyfromroots(roots)
    assert np.allclose(unit_roots(list(a)), expected, atol=1e-12)
    assert len(unit_roots(list(a))) == len(expected)


def test_a_double_root_is_reported_near_its_place():
    """A double root is ill-conditioned (±sqrt(eps)); it may come back as two close roots."""
    a = P.polyfromroots([0.375, 0.375, 0.9])
    for got in (np.array(unit_roots(list(a))),):
        assert np.min(np.abs(got - 0.9)) < 1e-12 and np.min(np.abs(got - 0.375)) < 1e-7
        assert np.all(np.min(np.abs(got[:, None] - np.array([0.375, 0.9])[None, :]), axis=1) < 1e-7)
