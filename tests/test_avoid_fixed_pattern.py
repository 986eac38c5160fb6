"""The avoidance QP on one fixed pattern (values and bounds updated per crossing-time box) is the
QP rebuilt from its own rows: same rows, same optimum, same plan (cost, crossing times, status)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, ContinuousAvoidQP


def problem(x0v: float, speed: float, xf: float, vxf: float, limits: bool) -> Problem:
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding", limits=PASSENGER_CAR if limits else None)


def nontrivial_rows(A, u) -> np.ndarray:
    """Rows ``[a | u]`` of ``A z <= u`` that are not ``0 <= 1``, sorted (a multiset of rows)."""
    D = np.hstack([A.toarray(), u[:, None]])
    keep = np.abs(D[:, :-1]).max(axis=1) > 0
    D = np.round(D[keep], 12)
    return D[np.lexsort(D.T[::-1])]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.floats(0.0, 5.0), st_h.floats(0.0, 5.0), st_h.sampled_from([(0, 1), (1, 0)]),
       st_h.sampled_from(["foh", "zoh"]), st_h.booleans(), st_h.integers(3, 12))
def test_fixed_pattern_rows_are_the_rebuilt_rows(a, b, order, hold, limits, steps):
    a, b = min(a, b), max(a, b)
    prob = problem(5.0, 20.0, 118.0, 24.0, limits)
    try:
        qp = ContinuousAvoidQP(prob, steps, hold, "piqp")
    except ScenarioError:  # a bound the hold cannot impose (jerk under ZOH)
        assume(False)
    spec = ((order[0], order[1], a, b),)
    A_rows, u_rows, _ = qp.spec_rows(spec)
    Ax, u_fix = qp.fixed_data(spec)
    A_fix = qp._fx_A.copy()
    A_fix.data[:] = Ax
    n_eq = qp.A_eq.shape[0]
    # the equality rows are unchanged; the inequality rows are the same multiset (padding 0 <= 1)
    assert (A_fix[:n_eq] != qp.A_eq).nnz == 0
    old = nontrivial_rows(sp.vstack([A_rows, qp.A_lim]).tocsr(), np.r_[u_rows, qp.u_lim])
    new = nontrivial_rows(A_fix[n_eq:], u_fix)
    assert old.shape == new.shape
    np.testing.assert_allclose(new, old, rtol=0, atol=1e-11)
    # every padding row is 0 <= 1
    pad = np.abs(A_fix[n_eq:].toarray()).max(axis=1) == 0
    assert np.all(u_fix[pad] == 1.0)


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.floats(-10.0, 15.0), st_h.floats(14.0, 26.0), st_h.floats(90.0, 130.0), st_h.floats(18.0, 26.0),
       st_h.sampled_from(["foh", "zoh"]), st_h.booleans(), st_h.sampled_from(["piqp", "osqp"]))
def test_fast_plan_equals_the_rebuilt_plan(x0v, speed, xf, vxf, hold, limits, solver):
    try:
        prob = problem(x0v, speed, xf, vxf, limits)
        fast = ContinuousAvoidPlanner(steps=12, hold=hold, solver=solver, max_solves=400).plan(prob)
        slow = ContinuousAvoidPlanner(steps=12, hold=hold, solver=solver, max_solves=400,
                                      fixed_pattern=False).plan(prob)
    except ScenarioError:
        assume(False)
    assert fast.status == slow.status
    if fast.cost is None:
        assert slow.cost is None
        return
    assert fast.cost == pytest.approx(slow.cost, rel=1e-6)
    assert fast.info["search"]["closed"] == slow.info["search"]["closed"]
    # crossing times: equal, or both give the same J (a flat J(τ) near its minimum)
    if not np.allclose(fast.contact_times, slow.contact_times, atol=1e-4):
        again = ContinuousAvoidPlanner(steps=12, hold=hold, solver=solver).plan_at_times(prob, fast.contact_times)
        assert again.cost == pytest.approx(slow.cost, rel=1e-6)
    if fast.status == st.OPTIMAL:
        assert fast.safety is not None and fast.safety.intrusion_free
