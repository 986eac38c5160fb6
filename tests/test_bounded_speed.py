"""The faster bounded PMP returns the numbers of the former code (issue 19's speed work).

* the scalar kernel (:mod:`iamp.planners.pmp.saturated_kernel`) is the former Newton method
  (tests/saturated_reference.py, copied from commit 46fdb28) bit for bit on generated axes —
  multipliers, residuals, dual value, iterations, pieces — feasible, infeasible, warm and cold;
* the lean search evaluator returns the full solution's cost, jumps and contact speeds bit
  for bit, and its polynomial recurrence is numpy's ``polyval``;
* the batched Hamiltonian is the per-side one, element for element;
* the root-free ``s_y`` pieces of ``exact_peaks`` are monotone (no root of ``v_y`` inside);
* ``Problem.with_limits`` is the validated constructor's problem;
* the compiled twin (numba, opt-in) plans exactly as the pure path: status, cost, contact
  times, peaks, switching times.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from saturated_reference import reference_newton
from test_pmp_bounded import SETTINGS, bounded_problems

from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.problem import Problem
from iamp.core.status import LOCAL, OPTIMAL
from iamp.planners.examples import paper_problem, random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp import compiled as saturated_compiled
from iamp.planners.pmp.bounded import _Evaluator, _keeps_sign, _polyval, solve_bounded_fixed
from iamp.planners.pmp.saturated import (
    MAX_NEWTON,
    AxisInfeasible,
    AxisNoConvergence,
    _Axis,
    _core,
    _tuples,
    solve_axis,
    solve_axis_value,
)

f = st.floats


@st.composite
def axes(draw: st.DrawFn) -> tuple[list[float], float, float, float, float, float, list[float], float, float]:
    """One axis: 0–3 distinct contact times, boundary data, corners and a box that may be
    loose, tight, one-sided, absent or infeasible."""
    T = draw(f(1.0, 8.0))
    m = draw(st.integers(0, 3))
    times = sorted({round(draw(f(0.03, 0.97)), 3) * T for _ in range(m)})
    s0, v0 = draw(f(-5.0, 5.0)), draw(f(-3.0, 30.0))
    sf, vf = s0 + v0 * T + draw(f(-25.0, 25.0)), v0 + draw(f(-5.0, 5.0))
    corners = [s0 + v0 * t + draw(f(-15.0, 15.0)) for t in times]
    lo = draw(st.sampled_from([-math.inf, -0.3, -1.0, -3.0, -8.0]))
    hi = draw(st.sampled_from([math.inf, 0.3, 1.0, 3.0, 8.0]))
    return times, T, s0, v0, sf, vf, corners, lo, hi


@SETTINGS
@given(axes(), st.booleans(), f(-0.2, 0.2))
def test_kernel_is_the_former_newton_bit_for_bit(axis: tuple, warm: bool, shift: float) -> None:  # type: ignore[type-arg]
    times, T, s0, v0, sf, vf, corners, lo, hi = axis
    lam0 = None
    if warm:  # a warm start: the unbounded multipliers of a shifted problem
        cold = reference_newton(times, T, s0, v0 + shift, sf, vf, corners, -math.inf, math.inf)
        assume(cold is not None)
        lam0 = list(cold[1])
    ref = reference_newton(times, T, s0, v0, sf, vf, corners, lo, hi, lam0)
    ax = _Axis(times, T, s0, v0, sf, vf, corners, lo, hi)
    code, it, res, D, _, lam, F, _, ps = _core(ax, lam0, 1e-12)
    if ref is None:
        assert code == 2  # singular Gram system, both
        return
    converged, lam_r, F_r, D_r, res_r, it_r, ps_r = ref
    assert (code == 0) == converged
    assert lam == lam_r and F == F_r and it == it_r
    assert D == D_r or (math.isnan(D) and math.isnan(D_r))
    assert res == res_r or (math.isnan(res) and math.isnan(res_r))
    assert _tuples(ps) == ps_r
    assert MAX_NEWTON == 60


@SETTINGS
@given(axes())
def test_value_path_is_the_full_solution_bit_for_bit(axis: tuple) -> None:  # type: ignore[type-arg]
    """What the search uses (cost, jumps, contact speeds, multipliers) equals the full
    :class:`AxisSolution`'s, and it fails exactly where :func:`solve_axis` raises."""
    try:
        sol = solve_axis(*axis)
    except (AxisInfeasible, AxisNoConvergence):
        assert solve_axis_value(*axis) is None
        return
    value = solve_axis_value(*axis)
    assert value is not None
    assert value == (sol.cost, sol.jumps, sol.contact_speeds, sol.lam)


@SETTINGS
@given(st.lists(f(-50.0, 50.0), min_size=1, max_size=6), f(-10.0, 10.0))
def test_polyval_recurrence_is_numpys(coeffs: list[float], x: float) -> None:
    assert _polyval(coeffs, x) == float(np.polynomial.polynomial.polyval(np.asarray(x), np.asarray(coeffs)))


@SETTINGS
@given(bounded_problems(), f(0.05, 0.95))
def test_lean_evaluator_is_the_fixed_time_solution(problem: Problem, frac: float) -> None:
    """``J_b(t)`` and ``r(t)`` of the search equal the fixed-time solution's axes' costs and
    ``Σ Φ (v − ċ)`` (the same arithmetic), and ``r`` is the Hamiltonian-jump residual."""
    t = np.array([frac * problem.tf])
    J, r, _ = _Evaluator(problem)(t)
    try:
        sol = solve_bounded_fixed(problem, t)
    except (AxisInfeasible, AxisNoConvergence):
        assert not math.isfinite(J)
        return
    ax, ay = sol.axes
    assert J == ax.cost + ay.cost
    cdot = float(problem.vehicles[0].speed(float(t[0])))
    assert r[0] == ax.jumps[0] * (ax.contact_speeds[0] - cdot) + ay.jumps[0] * ay.contact_speeds[0]
    r_h, size = sol.hamiltonian_jump_terms()
    assert abs(r[0] - r_h[0]) <= 1e-9 * max(1.0, float(size[0]))


@SETTINGS
@given(bounded_problems(), f(0.05, 0.95))
def test_batched_hamiltonian_is_the_per_side_one(problem: Problem, frac: float) -> None:
    t = frac * problem.tf
    try:
        sol = solve_bounded_fixed(problem, [t])
    except (AxisInfeasible, AxisNoConvergence):
        return
    pts = np.r_[t, t, np.asarray(sol.knots())]
    left = np.r_[True, False, np.zeros(len(pts) - 2, dtype=bool)]
    H = sol._hamiltonian(pts, left)
    assert H[0] == sol.hamiltonian(np.array([t]), "left")[0]
    assert H[1] == sol.hamiltonian(np.array([t]), "right")[0]
    assert np.array_equal(H[2:], sol.hamiltonian(pts[2:]))


@SETTINGS
@given(f(-5.0, 5.0), f(-5.0, 5.0), f(-5.0, 5.0), f(0.01, 3.0))
def test_pieces_skipped_by_exact_peaks_have_no_speed_root(v0: float, u0: float, c: float, h: float) -> None:
    """Where ``_keeps_sign`` lets ``exact_peaks`` skip the root finder, ``v_y`` has one strict
    sign on a dense grid of the piece and ``np.roots`` finds no root inside."""
    if not _keeps_sign(v0, u0, c, h):
        return
    d = np.linspace(0.0, h, 2001)
    q = v0 + u0 * d + c * d * d / 2
    assert np.all(q > 0) or np.all(q < 0)
    try:  # np.roots itself fails on a subnormal leading coefficient (which exact_peaks now skips)
        roots = np.roots([c / 2, u0, v0]) if c != 0 else (np.array([-v0 / u0]) if u0 != 0 else np.array([]))
    except np.linalg.LinAlgError:
        return
    inside = [float(np.real(r)) for r in np.atleast_1d(roots) if np.isreal(r) and 0 < float(np.real(r)) < h]
    assert not inside


def test_with_limits_is_the_validated_problem() -> None:
    base = random_problem(3, m=2)
    box = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)
    for limits in (box, None):
        fast = base.with_limits(limits)
        assert fast == Problem(base.ego, base.vehicles, base.name, limits)
        assert fast.limits is limits and fast.m == 2
    with pytest.raises(ScenarioError):
        base.with_limits("ax = 3")  # type: ignore[arg-type]


def _signature(plan: object) -> tuple:  # type: ignore[type-arg]
    p = plan
    info = p.info  # type: ignore[attr-defined]
    return (p.status, p.cost, [float(x) if np.isfinite(x) else None for x in p.contact_times], info.get("peaks"),  # type: ignore[attr-defined]
            info.get("bounded", {}).get("switching_times"), info.get("bounded", {}).get("newton_iterations"))


@pytest.fixture(scope="module")
def compiled() -> object:
    if not saturated_compiled.numba_available():
        pytest.skip("numba is not installed")
    if not saturated_compiled.load_axis():
        pytest.skip(f"numba failed: {saturated_compiled._STATE.get('error')}")
    saturated_compiled.unload_axis()  # each test switches it on where it compares
    return saturated_compiled


def _both(problem: Problem, planner: PMPPlanner) -> tuple[tuple, tuple]:  # type: ignore[type-arg]
    saturated_compiled.unload_axis()
    pure = _signature(planner.plan(problem))
    assert saturated_compiled.load_axis()
    try:
        fast = _signature(planner.plan(problem))
    finally:
        saturated_compiled.unload_axis()
    return pure, fast


@SETTINGS
@given(bounded_problems())
def test_compiled_path_plans_exactly_as_the_pure_path(compiled: object, problem: Problem) -> None:
    pure, fast = _both(problem, PMPPlanner(certify_bounded=False))
    assert pure == fast


def test_compiled_path_on_the_paper_and_two_vehicles_with_the_certificate(compiled: object) -> None:
    box = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)
    for problem in (paper_problem(1).with_limits(box), paper_problem(3).with_limits(box),
                    random_problem(0, m=2).with_limits(PhysicalLimits(ax=(-6.0, 3.0), ay=(-3.0, 3.0)))):
        pure, fast = _both(problem, PMPPlanner())
        assert pure == fast
        assert pure[0] in (OPTIMAL, LOCAL, "infeasible")


def test_the_certificate_of_paper_1_with_a_car_box_is_cheap_in_solves() -> None:
    """Work, not time (SPEC §17): the one-vehicle certificate bounds whole levels of contact-time
    intervals by the closed-form unbounded cost first and certifies the Taylor radius of each
    evaluated interval, so paper-1 with a car's box is certified in at most 200 axis solves
    (853 before, issue 32), with the same plan."""
    from iamp.planners.pmp.bounded import certify_global_one

    problem = paper_problem(1).with_limits(PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay))
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL and plan.cost is not None
    assert abs(plan.cost - 23.891625776124005) <= 1e-9 * plan.cost
    cert = certify_global_one(problem, plan.cost)
    assert cert["certified"] and cert["solves"] <= 200 and cert["pruned_by_unbounded"] > 0
