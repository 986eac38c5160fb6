"""Issue 32 item 5 / SPEC §14: the continuous-time avoidance QP keeps the speed range for every
``t``, not only at its grid nodes.

With FOH the input is piecewise linear, so on each piece the speed is the quadratic
:math:`v(\\tau) = v_k + u_k\\tau + (u_{k+1} - u_k)\\tau^2/(2h)`.  The check here is independent of
the planner's rows (:func:`iamp.planners.qp.limits.limit_rows`, ``between="certified"``): it
evaluates the executed trajectory densely and at the exact interior extremum of every piece
(:math:`\\tau^* = -u_k h / (u_{k+1} - u_k)`), from the plan's nodal states and inputs.  The
generated problems drive the speed into its bound (the end position needs a higher mean speed
than the ends allow), where the plan with the bound at the nodes only overshoots between them
(:func:`test_nodes_only_overshoots`, the witness that the property can fail).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.physical import PhysicalLimits
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid.continuous import GAP_REL, ContinuousAvoidPlanner

SOLVERS = ("osqp", "clarabel", "piqp")
#: The bound's tolerance [m/s]: the backends' primal feasibility, far below the 2-9 mm/s the
#: node-only plans overshoot by.
TOL = 1e-6


def speed_problem(tf: float, v0: float, vf: float, margin: float, push: float, upper: bool, lane_change: bool,
                  jerk: float | None) -> Problem:
    """The ego must reach ``x_f`` whose mean speed lies beyond the speed bound's side ``upper``
    (``push`` of the way from the ends' mean to the bound), the bound ``margin`` beyond the
    ends' speeds; a vehicle far behind in the target lane (the avoidance rows are imposed but
    do not bind)."""
    mean = (v0 + vf) / 2
    if upper:
        bound = max(v0, vf) + margin
        vx = (0.0, bound)
    else:
        bound = min(v0, vf) - margin
        vx = (bound, 60.0)
    xf = tf * (mean + push * (bound - mean))
    ego = EgoBoundary(tf=tf, x0=0.0, y0=-2.0, vx0=v0, xf=xf, yf=3.75 if lane_change else -2.0, vxf=vf)
    v = SurroundingVehicle(x_poly=(-60.0, 12.0), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "speed-bound",
                   limits=PhysicalLimits(ax=(-6.0, 4.0), ay=(-2.0, 2.0), vx=vx, jerk=jerk))


def speed_extremes(plan) -> tuple[float, float]:
    """The executed speed's minimum and maximum over ``[0, t_f]``: at the nodes, at every piece's
    interior stationary point (exact), and on a dense grid (2001 points)."""
    tr = plan.trajectory
    t, X, U = np.asarray(tr.t_nodes), np.asarray(tr.X), np.asarray(tr.U)
    vals = [X[:, 1]]
    h = np.diff(t)
    du = U[1:, 0] - U[:-1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(np.abs(du) > 1e-15, -U[:-1, 0] * h / du, -1.0)
    inside = (tau > 0) & (tau < h)
    k = np.flatnonzero(inside)
    vals.append(X[k, 1] + U[k, 0] * tau[k] + du[k] * tau[k] ** 2 / (2 * h[k]))
    # the same extremum from the trajectory itself (its own evaluation of the piece)
    if k.size:
        vals.append(np.asarray(plan.states(t[k] + tau[k]))[:, 1])
    dense = np.asarray(plan.states(np.linspace(0.0, float(t[-1]), 2001)))[:, 1]
    vals.append(dense)
    allv = np.concatenate(vals)
    return float(allv.min()), float(allv.max())


def overshoot(plan, vx: tuple[float, float]) -> float:
    lo, hi = speed_extremes(plan)
    return max(vx[0] - lo, hi - vx[1])


problems = st_h.builds(
    speed_problem, tf=st_h.floats(4.0, 8.0), v0=st_h.floats(15.0, 25.0), vf=st_h.floats(15.0, 25.0),
    margin=st_h.floats(0.3, 3.0), push=st_h.floats(0.6, 0.95), upper=st_h.booleans(), lane_change=st_h.booleans(),
    jerk=st_h.one_of(st_h.none(), st_h.floats(3.0, 10.0)))


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(prob=problems, steps=st_h.integers(6, 12))
def test_optimal_plan_keeps_speed_range_in_continuous_time(prob, steps):
    """An ``optimal`` plan with limits never leaves the speed range (dense and exact extremum),
    costs at least the node-only plan (a tightening, to the search's gap), and the three
    backends agree on it."""
    vx = prob.limits.vx
    nodes = ContinuousAvoidPlanner(steps=steps, limits_between="nodes").plan(prob)
    costs = {}
    for s in SOLVERS:
        plan = ContinuousAvoidPlanner(steps=steps, solver=s).plan(prob)
        if plan.status != st.OPTIMAL:
            continue
        assert overshoot(plan, vx) <= TOL, (s, overshoot(plan, vx))
        assert plan.info["limits_between"] == "certified"
        assert plan.info["limit_rows"].get("vx_between") == steps
        assert plan.safety.intrusion_free
        if nodes.status == st.OPTIMAL:
            assert plan.cost >= nodes.cost - 2 * GAP_REL * max(1.0, nodes.cost), (s, plan.cost, nodes.cost)
        costs[s] = plan.cost
    if len(costs) >= 2:
        ref = max(costs.values())
        assert all(abs(c - ref) <= 2 * GAP_REL * max(1.0, ref) for c in costs.values()), costs


@pytest.mark.parametrize("upper", [True, False])
def test_nodes_only_overshoots(upper):
    """The witness: with the speed bound at the nodes only the plan leaves the range between
    them (so the property above can fail); certified, the same problem keeps it and costs more."""
    prob = speed_problem(tf=6.0, v0=20.0, vf=22.0, margin=1.0, push=0.8, upper=upper, lane_change=True, jerk=None)
    nodes = ContinuousAvoidPlanner(steps=8, limits_between="nodes").plan(prob)
    cert = ContinuousAvoidPlanner(steps=8).plan(prob)
    assert nodes.status == st.OPTIMAL and cert.status == st.OPTIMAL
    assert overshoot(nodes, prob.limits.vx) > 1e-4
    assert overshoot(cert, prob.limits.vx) <= TOL
    assert cert.cost > nodes.cost


def lateral_problem(tf: float, vy0: float, margin: float) -> Problem:
    """The ego starts moving towards the upper edge of the ``y`` range (``v_{y,0} > 0``) and must
    end ``margin`` below it: the lateral cubic overshoots between nodes unless held."""
    ego = EgoBoundary(tf=tf, x0=0.0, y0=1.0, vx0=20.0, xf=20.0 * tf, yf=3.75, vxf=20.0, vy0=vy0)
    v = SurroundingVehicle(x_poly=(-60.0, 12.0), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "y-bound",
                   limits=PhysicalLimits(ax=(-6.0, 4.0), ay=(-4.0, 4.0), y=(0.5, 3.75 + margin)))


def lateral_extremes(plan) -> tuple[float, float]:
    """``s_y``'s minimum and maximum: nodes, every piece's stationary points (roots of the
    piece's quadratic ``v_y``, exact) and 2001 samples."""
    tr = plan.trajectory
    t, X, U = np.asarray(tr.t_nodes), np.asarray(tr.X), np.asarray(tr.U)
    times = [np.linspace(0.0, float(t[-1]), 2001)]
    for k in range(t.size - 1):
        h = t[k + 1] - t[k]
        roots = np.roots([(U[k + 1, 1] - U[k, 1]) / (2 * h), U[k, 1], X[k, 3]])
        roots = roots[np.isreal(roots)].real
        times.append(t[k] + roots[(roots > 0) & (roots < h)])
    y = np.r_[X[:, 2], np.asarray(plan.states(np.concatenate(times)))[:, 2]]
    return float(y.min()), float(y.max())


@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(tf=st_h.floats(3.0, 6.0), vy0=st_h.floats(2.0, 4.0), margin=st_h.floats(0.0, 0.25),
       steps=st_h.integers(6, 12))
def test_optimal_plan_keeps_y_range_in_continuous_time(tf, vy0, margin, steps):
    """The ``y`` range holds for every ``t`` too (cubic per FOH piece, two certified rows)."""
    prob = lateral_problem(tf, vy0, margin)
    lo, hi = prob.limits.y
    plan = ContinuousAvoidPlanner(steps=steps).plan(prob)
    if plan.status == st.OPTIMAL:
        ymin, ymax = lateral_extremes(plan)
        assert max(lo - ymin, ymax - hi) <= TOL, (ymin, ymax)
        assert plan.info["limit_rows"].get("y_between") == 2 * steps


def test_nodes_only_crosses_the_y_bound():
    """The witness for ``y``: node-only rows let the cubic cross the edge between nodes."""
    prob = lateral_problem(5.0, 3.0, 0.1)
    hi = prob.limits.y[1]
    nodes = ContinuousAvoidPlanner(steps=8, limits_between="nodes").plan(prob)
    cert = ContinuousAvoidPlanner(steps=8).plan(prob)
    assert nodes.status == st.OPTIMAL and cert.status == st.OPTIMAL
    assert lateral_extremes(nodes)[1] - hi > 1e-4
    assert lateral_extremes(cert)[1] - hi <= TOL
    assert cert.cost > nodes.cost


def test_loop_case_infeasible_on_the_coarse_grid_says_so():
    """A problem of the closed loop (merge, LOS E, seed 4: the ego brakes to 2 m/s over 3.2 m
    behind a stopping queue, passenger car's limits): on 12 pieces the node-only plan leaves the
    speed range between nodes (the loop rejected it, ``limits:vx``); with the certified rows the
    12-piece problem is ``infeasible`` and its reason says on which grid and with which rows (a
    speed kept >= 0 at 40 points per piece is infeasible too, so here it is not the rows'
    conservatism); 16 pieces plan within the range."""
    from iamp.core.physical import PASSENGER_CAR

    ego = EgoBoundary(tf=7.0, x0=681.4544784691064, y0=-9.375001814294114, vx0=4.7669342889060475,
                      xf=684.6884264913502, yf=-5.625, vxf=2.0624984395531927, vy0=2.1958012846751507e-06)
    v80 = SurroundingVehicle(x_poly=(664.8367203657294, 1.781235437229206, -0.04686212814886611,
                                     0.0011645854313450173), corner="front-lower", y=-5.62, length=4.8, width=1.8,
                             safety_x=4.879849541359546, safety_y=1.2, name="v80")
    v78 = SurroundingVehicle(x_poly=(686.4921866718731, 3.313512913229905, -0.04686212814887602,
                                     0.001164585431346577), corner="rear-lower", y=-5.62, length=4.6, width=1.8,
                             safety_x=5.685567996086142, safety_y=1.2, name="v78")
    prob = Problem(ego, (v80, v78), "loop-los-e-4", limits=PASSENGER_CAR)
    nodes = ContinuousAvoidPlanner(steps=12, max_solves=100, limits_between="nodes").plan(prob)
    assert nodes.status == st.OPTIMAL and overshoot(nodes, PASSENGER_CAR.vx) > 1e-2
    coarse = ContinuousAvoidPlanner(steps=12, max_solves=100).plan(prob)
    assert coarse.status == st.INFEASIBLE
    assert "on this grid of 12 pieces, the vx bound certified between the nodes" in coarse.info["reason"]
    fine = ContinuousAvoidPlanner(steps=16, max_solves=100).plan(prob)
    assert fine.status == st.OPTIMAL and overshoot(fine, PASSENGER_CAR.vx) <= TOL
