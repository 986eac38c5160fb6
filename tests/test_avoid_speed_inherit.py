"""Issue 32 item 3: a box's relaxation taken over from its parent without a solve
(:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.inherit`) is the relaxation's optimum.

Every inherited relaxation of a search is solved again from scratch, by the node solver and by the
backend alone (no warm start, no shared rows): the same cost, the same trajectory, and the
inherited multipliers pass the KKT check of that relaxation's own rows.  A plan searched without
inheriting is the same plan (status, cost, crossing times), with more QP solves.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from avoid_overtakes import generated_overtake as _overtake
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.problem import Problem
from iamp.planners.avoid import continuous as cont
from iamp.planners.avoid.check import crossing_orders, kkt_conditions
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, ContinuousAvoidQP
from iamp.planners.examples import overtake_three_problem


def _searched(problem: Problem, steps: int) -> ContinuousAvoidQP:
    """The QP of one search, with every spec it solved or inherited."""
    planner = ContinuousAvoidPlanner(steps=steps)
    orders, reason = crossing_orders(problem)
    assert reason is None
    qp = ContinuousAvoidQP(problem, steps, "foh", "clarabel")
    planner.search(qp, orders)
    return qp


def _check_inherited(problem: Problem, steps: int) -> int:
    qp = _searched(problem, steps)
    inherited = [s for s in qp.solved.values() if s.solves == 0]
    assert len(inherited) == qp.n_inherited
    fresh = ContinuousAvoidQP(problem, steps, "foh", "clarabel")
    backend = ContinuousAvoidQP(problem, steps, "foh", "clarabel", node_solver="backend")
    d = qp.data
    for sol in inherited:
        assert sol.status == st.OPTIMAL
        for other in (fresh.solve(sol.spec), backend.solve(sol.spec)):
            assert other.status == st.OPTIMAL
            assert sol.cost == pytest.approx(other.cost, rel=1e-9, abs=1e-9)
            assert np.max(np.abs(sol.z - other.z)) <= 1e-6 * max(1.0, float(np.max(np.abs(other.z))))
        A_in, u_in, _ = sol.spec_rows()
        A = np.vstack([qp.A_eq.toarray(), A_in.toarray()])
        l = np.r_[d.b_eq, np.full(A_in.shape[0], -np.inf)]
        u = np.r_[d.b_eq, u_in]
        kkt = kkt_conditions(d.P, d.q, sp.csc_matrix(A), l, u, sol.z, sol.y, d.n_eq)
        assert max(kkt.values()) <= 1e-7
    return len(inherited)


#: A one-vehicle overtake whose search inherits relaxations (the bench's overtake no longer does:
#: its multi-piece boxes are split around the candidate's piece, whose relaxations bind anew).
INHERITING = (105.0, 8.0, 22.0, False)


@pytest.mark.parametrize("three", [False, True])
def test_inherited_relaxations_of_the_overtakes_are_their_optima(three: bool) -> None:
    problem = overtake_three_problem() if three else _overtake(*INHERITING)
    assert _check_inherited(problem, 50) > 0


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.floats(105.0, 130.0), st_h.floats(7.5, 25.0), st_h.floats(14.0, 22.0), st_h.booleans())
def test_inherited_relaxations_are_their_optima(xf: float, gap: float, speed: float, limits: bool) -> None:
    _check_inherited(_overtake(xf, gap, speed, limits), 12)


def test_inheriting_gives_the_same_plan_with_fewer_solves() -> None:
    problem = _overtake(*INHERITING)
    plan = ContinuousAvoidPlanner(steps=50).plan(problem)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cont.ContinuousAvoidQP, "inherit", lambda self, spec, parent: None)
        full = ContinuousAvoidPlanner(steps=50).plan(problem)
    assert plan.status == full.status == st.OPTIMAL
    assert plan.cost == pytest.approx(full.cost, rel=1e-12)
    assert np.allclose(plan.contact_times, full.contact_times, atol=1e-9)
    n = plan.info["search"]["inherited_relaxations"]
    assert n > 0 and full.info["search"]["inherited_relaxations"] == 0
    assert plan.info["n_solves"] == full.info["n_solves"] - n
