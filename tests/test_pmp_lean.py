"""The m >= 2 plan path (issue 14): the jump system against the numpy code it replaced, the plan's
checks are :func:`check_values` (the one self-check; its scalar copy was removed in issue 32)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.planners.examples import random_problem
from iamp.planners.pmp.fixed import horner_rows, jump_system_sigma
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.pmp.scale import scale_problem
from iamp.planners.pmp.solution import PMPSolution
from iamp.planners.pmp.verify import check_values, judge

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


def _old_jump_system(S, sig):  # type: ignore[no-untyped-def]
    m = S.m
    x0, vx0, xf, vxf, y0, vy0, yf, vyf = S.ego
    M = np.empty((m + 2, m + 2))
    M[:m, 0] = sig**2 / 2
    M[:m, 1] = sig**3 / 6
    M[:m, 2:] = -np.maximum(sig[:, None] - sig[None, :], 0.0) ** 3 / 6
    M[m] = np.r_[0.5, 1.0 / 6.0, -((1.0 - sig) ** 3) / 6]
    M[m + 1] = np.r_[1.0, 0.5, -((1.0 - sig) ** 2) / 2]
    cx = horner_rows(S.CX, sig)
    rhs = np.empty((m + 2, 2))
    rhs[:m, 0] = cx - x0 - vx0 * sig
    rhs[:m, 1] = S.CY - y0 - vy0 * sig
    rhs[m] = [xf - x0 - vx0, yf - y0 - vy0]
    rhs[m + 1] = [vxf - vx0, vyf - vy0]
    return M, rhs


@given(st.integers(0, 10_000), st.integers(2, 3), st.lists(st.floats(0.02, 0.98), min_size=3, max_size=3))
@settings(max_examples=60, deadline=None)
def test_the_scalar_jump_system_is_the_numpy_one_bit_for_bit(seed: int, m: int, frac: list[float]) -> None:
    """At arbitrary distinct contact times: the scalar jump system is the numpy one bit for bit."""
    prob = random_problem(seed, m=m)
    S = scale_problem(prob)
    sig = np.sort(np.array(frac[:m]))
    if np.min(np.diff(sig)) < 0.02:
        return
    M, rhs = jump_system_sigma(S, sig)
    M0, rhs0 = _old_jump_system(S, sig)
    assert np.array_equal(M, M0) and np.array_equal(rhs, rhs0)


@given(st.integers(0, 10_000))
@settings(max_examples=15, deadline=None)
def test_the_plan_reports_check_values_and_its_verdict(seed: int) -> None:
    prob = random_problem(seed, m=2)
    plan = PMPPlanner().plan(prob, diagnostics=False)
    if plan.trajectory is None:
        return
    a = check_values(plan.trajectory, plan.trajectory.scaled, True)
    assert list(plan.info["checks"]) == list(a)
    for k, v in a.items():
        assert plan.info["checks"][k]["value"] == v
    assert judge(a)[1] == plan.info["failed_check"]
    if plan.cost is not None:
        assert plan.cost == plan.trajectory.cost()


def _residuals_one_call_at_a_time(sol: PMPSolution) -> tuple[dict[str, float], np.ndarray]:
    """The physical residuals as they were computed before the walk's restructuring (issue 18):
    every evaluation of the trajectory a call of its own, the problem read per use."""
    prob, t = sol.problem, sol.contact_times
    ends = sol.states(np.array([0.0, prob.tf]))
    boundary = max(np.max(np.abs(ends[0] - prob.ego.initial)), np.max(np.abs(ends[1] - prob.ego.final)))
    X = sol.states(t)
    interior = np.max(np.abs(X[:, [0, 2]] - prob.corners(t)))
    ts = np.linspace(0.0, prob.tf, 201)
    U, p = sol.inputs(ts), sol.costates(ts)
    h_min = np.max(np.abs(U + p[:, [1, 3]]))
    pl, pr = sol.costates(t, "left"), sol.costates(t, "right")
    jump = max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - sol.jumps)), np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])))
    xdot = np.array([float(v.speed(ti)) for v, ti in zip(prob.vehicles, t)])
    hj = sol.hamiltonian(t, "left") - sol.hamiltonian(t, "right") - xdot * sol.jumps[:, 0]
    return {"linear_system": sol.system_residual(), "boundary": float(boundary), "interior_constraint": float(interior),
            "h_minimisation": float(h_min), "costate_jump": float(jump),
            "hamiltonian_jump": float(np.max(np.abs(hj)))}, hj


@given(st.integers(0, 10_000), st.integers(1, 3))
@settings(max_examples=40, deadline=None)
def test_one_pass_residuals_and_one_vehicle_checks_are_the_old_numbers(seed: int, m: int) -> None:
    """The plan's residuals (one read of the problem, one evaluation of the trajectory at every
    point) are the per-call numbers bit for bit, for m = 1..3; the one-vehicle plan's full
    self-check is the generic :func:`check_values` bit for bit, with its verdict."""
    prob = random_problem(seed, m=m)
    plan = PMPPlanner().plan(prob)
    sol = plan.trajectory
    if not isinstance(sol, PMPSolution) or plan.residuals is None:
        return
    with np.errstate(all="ignore"):
        ref, hj = _residuals_one_call_at_a_time(sol)
    assert all((math.isnan(a) and math.isnan(b)) or a == b for a, b in zip(plan.residuals.values(), ref.values()))
    assert list(plan.residuals) == list(ref)
    assert np.array_equal(plan.diagnostics.hamiltonian_jump_residuals, hj, equal_nan=True)
    if m == 1:
        generic = check_values(sol, scale_problem(prob), True)
        checks = plan.diagnostics.checks
        assert checks is not None and list(checks) == list(generic)
        for k, v in generic.items():
            assert checks[k]["value"] == v or (math.isnan(v) and math.isnan(checks[k]["value"])), k
        assert judge(generic)[1] == plan.diagnostics.failed_check
