"""Global contact times for several vehicles (issue 9.2, SPEC §1): the planner's cost is
never above an independent dense search of J over (0, t_f)^m.

The reference shares no code with the planner beyond the problem data: per axis the
fixed-time optimum is the clamped cubic spline through the corners (its moments from the
standard tridiagonal system, solved here), its cost ``½Σ h(M_k² + M_kM_{k+1} + M_{k+1}²)/3``;
a coarse grid over (0, t_f)^m, then scipy's Nelder-Mead from the best grid points.
"""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import optimize

from iamp.core.problem import Problem
from iamp.core.status import LOCAL, OPTIMAL
from iamp.core.tolerances import tol
from iamp.planners.examples import random_problem
from iamp.planners.pmp.planner import PMPPlanner


def spline_costs(problem: Problem, T: np.ndarray) -> np.ndarray:
    """Clamped-spline cost for every row of contact times ``T`` (``(n, m)``); inf if two
    times coincide or leave (0, t_f)."""
    T = np.atleast_2d(np.asarray(T, dtype=float))
    n, m = T.shape
    ego, tf = problem.ego, problem.tf
    order = np.argsort(T, axis=1)
    ts = np.take_along_axis(T, order, axis=1)
    knots = np.concatenate([np.zeros((n, 1)), ts, np.full((n, 1), tf)], axis=1)
    h = np.diff(knots, axis=1)
    bad = np.any(h <= 1e-9 * tf, axis=1)
    h = np.where(h <= 1e-9 * tf, 1.0, h)
    cx = np.stack([np.polynomial.polynomial.polyval(T[:, i], v.x_poly) + v.offset_x
                   for i, v in enumerate(problem.vehicles)], axis=1)
    cy = np.tile([v.corner_y for v in problem.vehicles], (n, 1))
    total = np.zeros(n)
    for c, (s0, v0, sf, vf) in ((cx, (ego.x0, ego.vx0, ego.xf, ego.vxf)), (cy, (ego.y0, ego.vy0, ego.yf, ego.vyf))):
        y = np.concatenate([np.full((n, 1), s0), np.take_along_axis(c, order, axis=1), np.full((n, 1), sf)], axis=1)
        k = m + 2
        A = np.zeros((n, k, k))
        rhs = np.zeros((n, k))
        d = np.diff(y, axis=1) / h
        A[:, 0, 0], A[:, 0, 1] = 2 * h[:, 0], h[:, 0]
        rhs[:, 0] = 6 * (d[:, 0] - v0)
        for j in range(1, k - 1):
            A[:, j, j - 1], A[:, j, j], A[:, j, j + 1] = h[:, j - 1], 2 * (h[:, j - 1] + h[:, j]), h[:, j]
            rhs[:, j] = 6 * (d[:, j] - d[:, j - 1])
        A[:, k - 1, k - 2], A[:, k - 1, k - 1] = h[:, -1], 2 * h[:, -1]
        rhs[:, k - 1] = 6 * (vf - d[:, -1])
        M = np.linalg.solve(A, rhs[..., None])[..., 0]
        total += 0.5 * np.sum(h * (M[:, :-1] ** 2 + M[:, :-1] * M[:, 1:] + M[:, 1:] ** 2) / 3, axis=1)
    return np.where(bad, np.inf, total)


def reference_minimum(problem: Problem, grid: int, polish: int = 8) -> float:
    tf, m = problem.tf, problem.m
    g = (np.arange(grid) + 0.5) / grid * tf
    pts = np.array(list(itertools.product(g, repeat=m)))
    vals = spline_costs(problem, pts)
    best = float(np.min(vals))
    for k in np.argsort(vals)[:polish]:
        res = optimize.minimize(lambda t: float(spline_costs(problem, t[None, :])[0]), pts[k], method="Nelder-Mead",
                                options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000})
        best = min(best, float(res.fun))
    return best


def test_reference_agrees_with_the_planner_at_fixed_times():
    """The independent spline cost and the planner's fixed-time solve are the same function."""
    problem = random_problem(0, m=3)
    t = np.array([[1.0, 2.5, 4.0], [3.9, 0.7, 2.2]])
    for row in t:
        plan = PMPPlanner().plan(problem, contact_times=row)
        assert plan.cost == pytest.approx(spline_costs(problem, row[None, :])[0], rel=1e-9)


@pytest.mark.parametrize("seed", [0])
def test_three_vehicles_global(seed):
    problem = random_problem(seed, m=3)
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL, plan.info
    ref = reference_minimum(problem, grid=12)
    assert plan.cost <= ref + tol("independent_cost_rel") * ref


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(1, 10))
def test_three_vehicles_global_more(seed):
    problem = random_problem(seed, m=3)
    plan = PMPPlanner().plan(problem)
    assert plan.status in (OPTIMAL, LOCAL)
    ref = reference_minimum(problem, grid=14)
    assert plan.cost <= ref + tol("independent_cost_rel") * ref


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_four_vehicles_global(seed):
    problem = random_problem(seed, m=4)
    plan = PMPPlanner().plan(problem)
    assert plan.status in (OPTIMAL, LOCAL)
    ref = reference_minimum(problem, grid=9, polish=12)
    assert plan.cost <= ref + tol("independent_cost_rel") * ref


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), side=st.sampled_from([-1, 1]))
def test_two_vehicles_never_above_the_dense_reference(seed, side):
    problem = random_problem(seed, m=2, side=side)
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL
    ref = reference_minimum(problem, grid=40, polish=4)
    assert plan.cost <= ref + tol("independent_cost_rel") * ref


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 100_000))
def test_one_vehicle_never_above_the_dense_reference(seed):
    problem = random_problem(seed, m=1)
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL
    g = np.linspace(0, problem.tf, 4001)[1:-1]
    vals = spline_costs(problem, g[:, None])
    assert plan.cost <= float(np.min(vals)) * (1 + 1e-12)
