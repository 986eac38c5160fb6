"""The bounded PMP where the feasible contact times are a thin curved band (issue 32 item 4).

Found by ``scripts/bounded_sweep.py`` (2026-11-29, ``default_rng`` 7-10): under a tight box on one
input alone, the contact times that admit a plan can be a band ``1e-6 .. 1e-4 t_f`` wide along
some times, whose edges move with the others, with ``J_b`` rising steeply towards them.  The
search, the edge polish and the search without the finer grid all ended ``inaccurate`` there
(Hamiltonian jump 0.26-0.31 against 1e-7): central differences ``1e-6 t_f`` wide cross the band's
edges and the curvature across it (up to ``10^7`` times that along it) swamps the Newton step.
Now ``bounded._valley_polish`` finds the stationary point; the plan is taken only when every
check passes (the Hamiltonian jump of every contact time included: no time is at an edge).

**Reference**: the bounded FOH QP (:mod:`iamp.planners.qp`, Clarabel), a restriction of the
continuous problem: its sweep's cost is an upper bound of the bounded optimum.  Through the
PMP's contact times the FOH QP is infeasible on these bands at ``N = 240`` (its grid shifts the
band by more than its width) except where it is wide enough, where it must approach the PMP's
cost from above as ``N`` grows.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_bounded_random import boxed

from iamp.api import plan
from iamp.core import status as stc
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import solve_bounded_fixed
from iamp.planners.pmp.saturated import AxisInfeasible, AxisNoConvergence
from iamp.planners.qp.bounded import BoundedQP


def _foh_through(problem: Problem, times: object, steps: int) -> float | None:
    at = BoundedQP(problem, steps, "foh", "clarabel").solve_times(np.asarray(times, dtype=float))
    return float(at.cost) if at.status == stc.OPTIMAL and at.cost is not None else None


def _verified_local(problem: Problem) -> Plan:
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None, (pmp.status, pmp.info.get("failed_check"))
    checks = pmp.diagnostics.checks
    assert checks is not None and all(c["ok"] for c in checks.values())
    t = np.array(pmp.contact_times, dtype=float)
    # a minimum over the contact times: the feasible neighbours along each time (1e-9 .. 1e-6 t_f
    # away; some fall outside the band) cost no less, to the 1e-10 the cost's checks allow
    T = float(problem.tf)
    for i in range(len(t)):
        feasible = 0
        for step in (-1e-9, 1e-9, -1e-8, 1e-8, -1e-7, 1e-7, -1e-6, 1e-6):
            near = t.copy()
            near[i] += step * T
            try:
                J = solve_bounded_fixed(problem, near).cost
            except (AxisInfeasible, AxisNoConvergence):  # beyond an edge, or a solve stalled at one
                continue
            feasible += 1
            assert J >= pmp.cost * (1 - 1e-10), (i, step, J, pmp.cost)
        assert feasible >= 1, i
    return pmp


# (seed, scale of the a_y box): the FOH QP's sweep at N = 8 plans; the PMP was inaccurate
WHERE_THE_QP_PLANS = [(960070, 0.3507096459660612), (320117, 0.5535037446918107)]


@pytest.mark.parametrize(("seed", "scale"), WHERE_THE_QP_PLANS)
def test_three_vehicles_in_a_thin_band_plan_at_or_below_the_qp(seed: int, scale: float) -> None:
    problem = boxed(seed, 3, scale, "ay")
    assert problem is not None and problem.limits is not None and problem.limits.ax is None
    cost = _verified_local(problem).cost
    assert cost is not None
    qp = plan(problem, "qp", solver="clarabel", steps=8)
    assert qp.status in (stc.OPTIMAL, stc.LOCAL) and qp.cost is not None
    assert cost <= qp.cost * (1 + 1e-6), (cost, qp.cost)


def test_three_vehicles_in_a_band_the_refined_qp_approaches_the_pmp() -> None:
    # random_problem(732748, m=3) under an a_y box at 0.3263: the QP's sweep at N = 8 has no
    # plan; through the PMP's contact times the FOH QP plans from N = 960 and falls to its cost
    problem = boxed(732748, 3, 0.3262549111792487, "ay")
    assert problem is not None
    pmp = _verified_local(problem)
    cost, t = pmp.cost, pmp.contact_times
    assert cost is not None
    coarse, fine = _foh_through(problem, t, 960), _foh_through(problem, t, 1920)
    assert coarse is not None and fine is not None
    assert cost * (1 - 1e-9) <= fine <= coarse <= cost * (1 + 2e-3), (cost, fine, coarse)

