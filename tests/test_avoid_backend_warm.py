"""The backend's re-solve of the final QP (SPEC §14, ``backend_check``) starts OSQP from the node
solver's point: the same optimum as a cold start (recomputed KKT conditions, cost), in fewer ADMM
iterations (a count of work, never a time)."""

from __future__ import annotations

import numpy as np
import pytest

from iamp.core import status as st
from iamp.core.tolerances import tol
from iamp.planners.avoid.check import crossing_orders, kkt_conditions
from iamp.planners.avoid.continuous import ContinuousAvoidQP, _spec, _stacked
from iamp.planners.examples import overtake_problem, overtake_three_problem

pytest.importorskip("osqp")


@pytest.mark.parametrize("three", [False, True])
def test_osqp_from_the_node_solvers_point_is_the_cold_optimum_in_fewer_iterations(three: bool) -> None:
    problem = overtake_three_problem() if three else overtake_problem()
    orders, _ = crossing_orders(problem)
    taus = [3.7127, 1.8559, 3.5938][:problem.m]
    qp = ContinuousAvoidQP(problem, 50, "foh", "osqp")
    sol = qp.solve(_spec([o[0] for o in orders], np.array(taus), np.array(taus)))
    assert sol.status == st.OPTIMAL
    warm = qp.backend_solve(sol)
    A_in, u_in, ids = sol.spec_rows()
    binding = np.flatnonzero(sol.y[qp.data.n_eq:] > 0)
    cold = ContinuousAvoidQP(problem, 50, "foh", "osqp")._rows_solver.solve(A_in, u_in, ids, None, binding)
    assert warm.status == cold.status == st.OPTIMAL
    d = qp.data
    A = _stacked(qp.A_eq, A_in)
    l = np.r_[d.b_eq, np.full(A_in.shape[0], -np.inf)]
    u = np.r_[d.b_eq, u_in]
    limit = tol("cmp_kkt_rel_osqp")
    for z, y in ((warm.z, warm.y), (cold.z, cold.y)):
        assert max(kkt_conditions(d.P, d.q, A, l, u, z, y, d.n_eq).values()) <= limit
        cost = 0.5 * float(z @ (d.P @ z) + z @ (d.P @ z - d.P.diagonal() * z))
        assert abs(cost - sol.cost) <= tol("cmp_cost_rel_osqp") * max(1.0, sol.cost)
    assert warm.iterations < cold.iterations
