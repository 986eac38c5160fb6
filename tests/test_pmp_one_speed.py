"""The written-out fast paths of the one-vehicle planner and the batch (issue 14) give the
numbers of the plain loops they replace, bit for bit, and the batch gives the scalar plan."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.problem import Problem
from iamp.core.status import INACCURATE, NUMERICAL_ERROR, OPTIMAL
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp.one import CHECK_NAMES, judge_kernel
from iamp.planners.pmp.planner import PMPPlanner, plan_batch
from iamp.planners.pmp.roots import ROOT_XTOL, bernstein_weights, newton_in_bracket, to_bernstein, unit_roots
from iamp.planners.pmp.solution import OneVehicleSolution, PMPSolution
from iamp.planners.pmp.verify import check_values, judge, judge_pairs


def loop_bernstein(a):
    """The generic conversion: β_j = Σ_{i≤j} w_ji a_i from 0.0 in ascending i."""
    w = bernstein_weights(len(a) - 1)
    return [sum_in_order(w[j][i] * a[i] for i in range(j + 1)) for j in range(len(a))]


def sum_in_order(terms):
    acc = 0.0
    for t in terms:
        acc += t
    return acc


def loop_newton(a, lo, hi):
    """Newton/bisection with the Horner loop (the reference for the written-out degree ≤ 6)."""
    def horner2(x):
        p = dp = 0.0
        for c in reversed(a):
            dp = dp * x + p
            p = p * x + c
        return p, dp

    plo, _ = horner2(lo)
    if plo == 0.0:
        return lo
    x = 0.5 * (lo + hi)
    for _ in range(200):
        p, dp = horner2(x)
        if p == 0.0:
            return x
        if (p > 0.0) == (plo > 0.0):
            lo, plo = x, p
        else:
            hi = x
        if hi - lo <= ROOT_XTOL:
            break
        nx = x - p / dp if dp != 0.0 else lo - 1.0
        if not lo < nx < hi:
            nx = 0.5 * (lo + hi)
        if abs(nx - x) <= ROOT_XTOL:
            return nx
        x = nx
    return x


coeffs = st.lists(st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False), min_size=2, max_size=10)


@settings(max_examples=300, deadline=None)
@given(coeffs)
def test_written_out_bernstein_and_newton_equal_the_loops(a):
    assert to_bernstein(a) == loop_bernstein(a)
    p0 = sum_in_order([0.0]) + a[0]
    p1 = sum_in_order(a)
    if p0 * p1 < 0:  # a bracket on [0, 1]
        assert newton_in_bracket(a, 0.0, 1.0) == loop_newton(a, 0.0, 1.0)


def test_unit_roots_fast_path_equals_the_subdivision():
    """One sign variation on [0, 1]: the root comes straight from Newton, as the stack would."""
    a = [-0.018208949671356743, 0.01235538746976357, 0.11826051785058442, -0.23241695267283846,
         0.14965556572231864, -0.027574926229404495, 5.551115123125783e-17]
    assert unit_roots(a) == [loop_newton(a, 0.0, 1.0)]


@pytest.mark.parametrize("values", [
    [1e-17, 1e-16, 1e-16, 1e-15, 1e-16],
    [1e-17, 2e-9, 1e-16, 1e-15, 1e-16],
    [float("nan"), 1e-16, 1e-16, 1.0, 1e-16],
    [1e-17, 1e-16, float("inf"), 1e-15, float("-inf")],
])
def test_judge_kernel_equals_the_generic_judge(values):
    k = [0.0] * 8 + values
    got = judge_kernel(k)
    assert got == judge_pairs(CHECK_NAMES, values) == judge(dict(zip(CHECK_NAMES, values)))
    if all(math.isfinite(v) and v < 1e-12 for v in values):
        assert got[1] is None and got[2] is None
    else:
        assert got[2] in (INACCURATE, NUMERICAL_ERROR) and not got[0][got[1]]["ok"]


def test_lazy_solution_equals_an_eager_one():
    plan = PMPPlanner().plan(paper_problem(1), diagnostics=False)
    sol = plan.trajectory
    assert isinstance(sol, OneVehicleSolution) and "_kernel" in sol.__dict__
    t = np.linspace(0.0, plan.problem.tf, 11)
    X = sol.states(t)  # builds a, b, z_scaled
    assert "_kernel" not in sol.__dict__
    eager = PMPSolution(sol.problem, sol.contact_times, sol.a, sol.b, sol.jumps, z_scaled=sol.z_scaled)
    assert np.array_equal(eager.states(t), X) and eager.cost() == sol.cost()
    # the eager copy the dataclass machinery makes is a plain solution with every field
    other = PMPPlanner().plan(paper_problem(1), diagnostics=False).trajectory
    copy = dataclasses.replace(other, jumps=other.jumps * 1.0)
    assert np.array_equal(copy.a, sol.a) and np.array_equal(copy.z_scaled, sol.z_scaled)
    checks, failed, _ = judge(check_values(other))
    assert failed is None, checks


@st.composite
def one_vehicle_problems(draw):
    base = random_problem(draw(st.integers(0, 10_000)))
    f = st.floats
    ego = dataclasses.replace(base.ego, tf=draw(f(1.0, 12.0)), vx0=draw(f(0.0, 35.0)), xf=draw(f(0.0, 300.0)),
                              yf=draw(f(-5.0, 5.0)), vy0=draw(f(-1.0, 1.0)), vyf=draw(f(-1.0, 1.0)))
    n = draw(st.integers(1, 6))
    poly = tuple(draw(f(-30.0, 30.0)) * 10.0 ** -k for k in range(n))
    v = dataclasses.replace(base.vehicles[0], x_poly=poly, y=draw(f(-5.0, 5.0)),
                            corner=draw(st.sampled_from(["front-lower", "front-upper", "rear-lower", "rear-upper"])))
    return Problem(ego, (v,), "gen")


@settings(max_examples=60, deadline=None)
@given(st.lists(one_vehicle_problems(), min_size=1, max_size=6))
def test_batch_gives_the_scalar_plans(problems):
    """plan_batch and PMPPlanner.plan on the same problems: same status; where optimal, the
    same contact time, cost and jumps to 1e-12 (the two paths share every product)."""
    batch = plan_batch(problems)
    planner = PMPPlanner()
    for k, p in enumerate(problems):
        ref = planner.plan(p, diagnostics=False)
        assert batch.status[k] == ref.status
        if ref.status == OPTIMAL:
            assert batch.cost[k] == pytest.approx(ref.cost, rel=1e-12, abs=1e-12)
            assert batch.contact_time[k] == pytest.approx(ref.contact_times[0], abs=1e-12 * p.tf)
            assert np.allclose(batch.jumps[k], ref.jumps[0], rtol=1e-10, atol=1e-12)
        else:
            assert np.isnan(batch.cost[k])


def test_batch_rows_equal_single_row_batches():
    problems = [random_problem(s) for s in range(40)] + [paper_problem(1), two_minima_problem()]
    whole = plan_batch(problems)
    for k, p in enumerate(problems):
        one = plan_batch([p])
        assert one.cost[0] == whole.cost[k] and one.contact_time[0] == whole.contact_time[k]
        assert np.array_equal(one.jumps[0], whole.jumps[k])
