"""The rows of the continuous-time avoidance QP and their solution by row generation.

* Every imposed Bernstein block of a crossing-time spec bounds the ego's margin on its
  (sub-)piece: its first and last rows are the margin at the ends of the sub-piece, and no
  margin sampled densely inside lies beyond the rows (the convex hull of the coefficients),
  checked against the trajectory itself, not against another builder of the rows.
* Row generation (the working set grown by the violated rows) gives the plan of the QP solved on
  all its rows at once: same status, cost, crossing times, certificate.
"""

from __future__ import annotations

import numpy as np
import pytest
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


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(0.0, 5.0), st_h.floats(0.0, 5.0), st_h.sampled_from([(0, 1), (1, 0)]),
       st_h.sampled_from(["foh", "zoh"]), st_h.booleans(), st_h.integers(3, 12), st_h.integers(0, 2**31 - 1))
def test_imposed_rows_bound_the_margin_on_their_sub_piece(a, b, order, hold, limits, steps, seed):
    a, b = min(a, b), max(a, b)
    prob = problem(5.0, 20.0, 118.0, 24.0, limits)
    try:
        qp = ContinuousAvoidQP(prob, steps, hold, "piqp")
    except ScenarioError:  # a bound the hold cannot impose (jerk under ZOH)
        assume(False)
    spec = ((order[0], order[1], a, b),)
    A_in, u_in, ids = qp.spec_rows(spec)
    # any trajectory of the hold: random node values projected onto the dynamics (equality rows)
    z = np.random.default_rng(seed).normal(scale=5.0, size=qp.data.n)
    E = qp.A_eq.toarray()
    z -= E.T @ np.linalg.lstsq(E @ E.T, E @ z - qp.data.b_eq, rcond=None)[0]
    traj = qp.trajectory(z)
    n = qp.degree + 1
    values = A_in @ z - u_in  # >0 : the row is broken
    bern = ids < qp.n_b
    assert np.all(ids[~bern] >= qp.n_b) and np.sum(~bern) == qp.u_lim.size  # the limit rows, always
    expected: dict[int, tuple[int, float, float]] = {}
    for plane, (ta, tb) in ((order[0], (0.0, a)), (order[1], (b, prob.tf))):
        if (plane == order[0] and a <= 0.0) or (plane == order[1] and b >= prob.tf):
            continue
        for k, l0, l1 in qp.segment_pieces(ta, tb):
            expected[(plane * qp.N + k) * n] = (plane, l0, l1)
    got = sorted({int(i) - int(i) % n for i in ids[bern]})
    assert got == sorted(expected)
    hp = qp.data.planes[0]
    for first in got:
        plane, l0, l1 = expected[first]
        k = first // n - plane * qp.N
        rows = values[np.searchsorted(ids, first):np.searchsorted(ids, first) + n]
        t = qp.data.t_nodes[k] + qp.h * np.linspace(l0, l1, 41)
        X = traj.states(t)
        broken = -hp[plane].margin(t, X[:, 2 * plane]) - 1e-9  # the rows carry 1e-9 m of slack
        scale = 1e-9 * max(1.0, float(np.abs(broken).max()))
        assert rows[0] == pytest.approx(broken[0], abs=scale) and rows[-1] == pytest.approx(broken[-1], abs=scale)
        assert broken.max() <= rows.max() + scale  # the polynomial stays in the hull of its coefficients


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-10.0, 15.0), st_h.floats(14.0, 26.0), st_h.floats(90.0, 130.0), st_h.floats(18.0, 26.0),
       st_h.sampled_from(["foh", "zoh"]), st_h.booleans(), st_h.sampled_from(["piqp", "osqp", "clarabel"]))
def test_row_generation_plan_equals_the_plan_on_every_row(x0v, speed, xf, vxf, hold, limits, solver):
    try:
        prob = problem(x0v, speed, xf, vxf, limits)
        fast = ContinuousAvoidPlanner(steps=12, hold=hold, solver=solver, max_solves=600).plan(prob)
        slow = ContinuousAvoidPlanner(steps=12, hold=hold, solver=solver, max_solves=600,
                                      row_generation=False).plan(prob)
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
