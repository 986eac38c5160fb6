"""Issue 19 / SPEC §14: the bounded avoidance QP imposes every given bound at every node on
every backend (OSQP, Clarabel, PIQP), with ``--safety continuous`` and ``nodes``, and the
backends agree.

The bounds are re-checked here from the plan's nodal states and inputs, independently of the
rows of :mod:`iamp.planners.qp.limits`: ``ax``/``ay`` on ``u``, the friction circle
``|u| <= a_total`` (the inscribed 16-gon lies inside it), ``vx`` on the nodal speeds, the FOH
jerk ``|u_{k+1} - u_k| <= J h`` per axis; a plan called ``optimal`` is also intrusion-free
(SPEC §9, exact roots) and costs at least the unbounded plan."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid import AvoidQPPlanner

SOLVERS = ("osqp", "clarabel", "piqp")
TOL = 1e-6


def binding_problem(xf: float = 118.0, vxf: float = 24.0, speed: float = 20.0) -> Problem:
    """The ego overtakes a vehicle in the target lane; the free optimum cuts its box."""
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(5.0, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding")


def violations(plan, lim: PhysicalLimits) -> dict[str, float]:
    """Largest nodal violation of each given bound, recomputed from the trajectory."""
    tr = plan.trajectory
    U, X = np.asarray(tr.U), np.asarray(tr.X)
    out: dict[str, float] = {}
    if lim.ax is not None:
        out["ax"] = float(max(lim.ax[0] - U[:, 0].min(), U[:, 0].max() - lim.ax[1]))
    if lim.ay is not None:
        out["ay"] = float(max(lim.ay[0] - U[:, 1].min(), U[:, 1].max() - lim.ay[1]))
    if lim.a_total is not None:
        out["a_total"] = float(np.hypot(U[:, 0], U[:, 1]).max() - lim.a_total)
    if lim.vx is not None:
        out["vx"] = float(max(lim.vx[0] - X[:, 1].min(), X[:, 1].max() - lim.vx[1]))
    if lim.jerk is not None:
        h = np.diff(np.asarray(tr.t_nodes))
        out["jerk"] = float((np.abs(np.diff(U, axis=0)) / h[:, None]).max() - lim.jerk)
    return out


limits_strategy = st_h.builds(
    lambda axl, axh, ay, at, vx, jerk: PhysicalLimits(ax=(-axl, axh), ay=(-ay, ay), a_total=at,
                                                      vx=None if vx is None else (0.0, vx), jerk=jerk),
    st_h.floats(2.0, 8.0), st_h.floats(1.0, 4.0), st_h.floats(0.8, 3.0),
    st_h.one_of(st_h.none(), st_h.floats(2.0, 9.0)), st_h.one_of(st_h.none(), st_h.floats(24.5, 40.0)),
    st_h.one_of(st_h.none(), st_h.floats(1.0, 12.0)))


@pytest.mark.parametrize("safety", ["continuous", "nodes"])
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lim=limits_strategy, xf=st_h.floats(105.0, 125.0))
def test_every_bound_holds_at_every_node_on_every_backend(safety, lim, xf):
    prob = binding_problem(xf=xf)
    unbounded = AvoidQPPlanner(steps=16, safety=safety).plan(prob)
    plans = {s: AvoidQPPlanner(steps=16, solver=s, safety=safety).plan(prob.with_limits(lim)) for s in SOLVERS}
    costs = {}
    for s, plan in plans.items():
        if plan.status == st.OPTIMAL:
            v = violations(plan, lim)
            assert max(v.values(), default=-1.0) <= TOL, (s, v)
            assert plan.safety.intrusion_free
            assert max(plan.info["avoidance"]["kkt"].values()) <= plan.info["avoidance"]["kkt_tol"]
            if unbounded.status == st.OPTIMAL:
                assert plan.cost >= unbounded.cost * (1 - 1e-7)
            costs[s] = plan.cost
    if len(costs) >= 2:
        ref = costs.get("clarabel", next(iter(costs.values())))
        for s, c in costs.items():
            assert c == pytest.approx(ref, rel=1e-5), (s, costs)
    # infeasibility is a property of the problem, not of the backend
    infeasible = {s for s, p in plans.items() if p.status == st.INFEASIBLE}
    assert not (infeasible and costs), ({s: p.status for s, p in plans.items()})


@pytest.mark.parametrize("safety", ["continuous", "nodes"])
@pytest.mark.parametrize("solver", SOLVERS)
def test_passenger_car_binding_case_is_within_bounds(solver, safety):
    """The template's passenger car on the binding overtake (lateral bound binds: the unbounded
    plan needs |u_y| > 2 m/s²)."""
    prob = binding_problem()
    plan = AvoidQPPlanner(steps=30, solver=solver, safety=safety).plan(prob.with_limits(PASSENGER_CAR))
    if safety == "nodes" and plan.status == st.UNSAFE:  # cuts a corner between nodes: said so
        assert not plan.safety.intrusion_free
        plan = AvoidQPPlanner(steps=30, solver=solver).plan(prob.with_limits(PASSENGER_CAR))
    free = AvoidQPPlanner(steps=30).plan(prob)
    assert np.abs(np.asarray(free.trajectory.U)[:, 1]).max() > 2.0
    assert plan.status == st.OPTIMAL, plan.info.get("why")
    assert max(violations(plan, PASSENGER_CAR).values()) <= TOL
    assert plan.cost > free.cost
