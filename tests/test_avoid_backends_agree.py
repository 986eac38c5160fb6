"""Issue 32 item 3: OSQP, Clarabel and PIQP reach the same certified optimum of the continuous-time
avoidance QP with limits, one vehicle and three, on a fixed grid of problems: each plan is
``optimal`` (search closed, KKT within its backend's tolerance, intrusion-free), and the costs and
nodal trajectories agree within the tolerance table's QP-QP entries (OSQP's, the loosest)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from iamp.core import status as st
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner
from iamp.planners.examples import overtake_problem, overtake_three_problem

SOLVERS = ("osqp", "clarabel", "piqp")


def one(xf: float, vxf: float, x0v: float) -> Problem:
    p = overtake_problem()
    vehicle = dataclasses.replace(p.vehicles[0], x_poly=(x0v, 20.0))
    return Problem(dataclasses.replace(p.ego, xf=xf, vxf=vxf), (vehicle,), "overtake-variant", limits=p.limits)


def three(x2: float) -> Problem:
    p = overtake_three_problem()
    vs = list(p.vehicles)
    vs[1] = dataclasses.replace(vs[1], x_poly=(x2, 10.0))
    return p.with_vehicles(vs)


PROBLEMS = {  # the multipliers say which vehicles bind (N = 12)
    "one": overtake_problem,                               # sv1 binds
    "one-121-fast-end": lambda: one(121.0, 25.0, 6.0),     # sv1 binds
    "one-122-free": lambda: one(122.0, 24.0, 2.0),         # the free optimum keeps sv1's box: certified at once
    "three": overtake_three_problem,                       # sv1 and sv2 bind (92-139 solves; ~1,400 before)
    "three-31": lambda: three(31.0),                       # sv1 binds, sv2 touches
}


@pytest.mark.parametrize("name", sorted(PROBLEMS))
def test_backends_reach_the_same_certified_optimum(name):
    """With the exact node solver (default) every backend solves the final QP again and agrees
    (``backend_check``); with ``node_solver="backend"`` each backend solves every QP of the search
    itself and reaches the same optimum."""
    prob = PROBLEMS[name]()
    plans = {s: ContinuousAvoidPlanner(steps=12, solver=s).plan(prob) for s in SOLVERS}
    plans.update({f"{s}-alone": ContinuousAvoidPlanner(steps=12, solver=s, node_solver="backend").plan(prob)
                  for s in SOLVERS})
    for s, plan in plans.items():
        assert plan.status == st.OPTIMAL, (s, plan.status, plan.info.get("failed_check"))
        assert plan.info["search"]["closed"]
        assert max(plan.info["kkt"].values()) <= plan.info["kkt_tol"]
        assert plan.safety.intrusion_free
        if not s.endswith("-alone"):
            check = plan.info["backend_check"]
            assert check["agrees"] and check["status"] == st.OPTIMAL
            assert max(check["kkt"].values()) <= plan.info["kkt_tol"]
    ref = plans["clarabel"]
    X0, U0 = np.asarray(ref.trajectory.X), np.asarray(ref.trajectory.U)
    scale = max(1.0, float(np.abs(X0).max()), float(np.abs(U0).max()))
    for s, plan in plans.items():
        assert plan.cost == pytest.approx(ref.cost, rel=tol("cmp_cost_rel_osqp")), (s, plan.cost, ref.cost)
        dX = np.abs(np.asarray(plan.trajectory.X) - X0).max()
        dU = np.abs(np.asarray(plan.trajectory.U) - U0).max()
        assert max(dX, dU) <= tol("cmp_state_rel_osqp") * scale, (s, dX, dU)
