"""The bounded PMP's contact-time search in the right basin (issue 32 item 4).

Found by ``scripts/bounded_sweep.py`` (2026-11-29, draws of ``numpy.random.default_rng`` 7, 8 and
10 that no test had seen: boxes on one input alone, scales 0.3-1.3):

* three vehicles, a tight box on ``a_y`` alone: the search from the unbounded ``t*`` (or from the
  contact times the infeasibility cover met) ended ``local`` in a basin of another order of the
  contact times, up to 6x the cost of the FOH QP's own sweep at ``N = 8``, or ``inaccurate`` there.
  Now a grid over ``(0, t_f)^3`` starts the search where its lower bound ``J_u`` is below the best
  ``J_b`` found (``bounded._pruned_grid``).
* one vehicle, the box barely active: Brent's root of ``r`` was dropped for the unbounded ``t*``
  8.7e-8 s from it, whose ``J_b`` came out 7e-13 lower by rounding (``inaccurate``, Hamiltonian
  jump 5.4e-7).

**Reference**: the bounded FOH QP (:mod:`iamp.planners.qp`, Clarabel), a restriction of the
continuous problem: its plan's cost is an upper bound of the bounded optimum, and through the
PMP's contact times at ``N = 240`` it is at or above the PMP's cost (the fixed-time problem is
convex) and within the grid's error of it.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_bounded_random import boxed

from iamp.api import plan
from iamp.core import status as stc
from iamp.core.problem import Problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp.bounded import BoundedQP

GRID_REL = 2e-3  #: the FOH grid's error at N = 240 through the PMP's contact times (tests/test_bounded_random.py)


def _foh_through(problem: Problem, times: object, steps: int = 240) -> float | None:
    at = BoundedQP(problem, steps, "foh", "clarabel").solve_times(np.asarray(times, dtype=float))
    return float(at.cost) if at.status == stc.OPTIMAL and at.cost is not None else None


# (seed, scale of the a_y box, the former plan's status and cost)
THREE = [(979596, 0.5306671823011024, stc.LOCAL, 15318.524462059262),
         (669627, 0.6063440644587741, stc.LOCAL, 2839.7856890592957),
         (449426, 0.4187771092982902, stc.LOCAL, 25611.316262029075),
         (614271, 0.3518356525166741, stc.INACCURATE, None)]


@pytest.mark.parametrize(("seed", "scale", "was", "was_cost"), THREE)
def test_three_vehicles_under_an_ay_box_find_the_cheaper_basin(seed: int, scale: float, was: str,
                                                               was_cost: float | None) -> None:
    problem = boxed(seed, 3, scale, "ay")
    assert problem is not None and problem.limits is not None and problem.limits.ax is None
    pmp = PMPPlanner().plan(problem)
    qp = plan(problem, "qp", solver="clarabel", steps=8)
    assert qp.status in (stc.OPTIMAL, stc.LOCAL) and qp.cost is not None
    assert pmp.status == stc.LOCAL and pmp.cost is not None, (pmp.status, pmp.info.get("failed_check"))
    # at or below the QP's sweep (a restriction of the same problem), and no longer in the costlier basin
    assert pmp.cost <= qp.cost * (1 + 1e-6), (pmp.cost, qp.cost)
    if was_cost is not None:
        assert pmp.cost < 0.95 * was_cost
    # the plan is the fixed-time optimum at its contact times: the FOH QP through them agrees
    at = _foh_through(problem, pmp.contact_times)
    if at is None:  # a sliver of feasible times the N = 240 restriction misses: refine
        at = _foh_through(problem, pmp.contact_times, 960)
    assert at is not None
    assert pmp.cost * (1 - 1e-9) <= at <= pmp.cost * (1 + GRID_REL), (pmp.cost, at)
    checks = pmp.diagnostics.checks
    assert checks is not None and all(c["ok"] for c in checks.values())


def test_one_vehicle_takes_the_root_over_a_start_equal_within_rounding() -> None:
    problem = boxed(817765, 1, 0.9984842578956494)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.OPTIMAL and pmp.cost is not None, (pmp.status, pmp.info.get("failed_check"))
    checks = pmp.diagnostics.checks
    assert checks is not None and checks["hamiltonian_jump"]["ok"]
    # stationary: dJ/dt (= the Hamiltonian-jump residual, tested against central differences in
    # tests/test_pmp_bounded.py) of a cold fixed-time solve at the plan's contact time vanishes;
    # at the unbounded t* it was -2.7e-6 (8.7e-8 s from the root at dr/dt = 31.6)
    from iamp.planners.pmp.bounded import solve_bounded_fixed

    cold = solve_bounded_fixed(problem, [float(pmp.contact_times[0])])
    assert abs(float(cold.hamiltonian_jump_residual()[0])) < 1e-9
    assert abs(cold.cost - pmp.cost) <= 1e-12 * pmp.cost
    qp = plan(problem, "qp", solver="clarabel", steps=60, contact="refine")
    assert qp.cost is not None and pmp.cost <= qp.cost * (1 + 1e-9)
    at = _foh_through(problem, pmp.contact_times)
    assert at is not None and pmp.cost * (1 - 1e-9) <= at <= pmp.cost * (1 + GRID_REL)


def test_a_start_the_checks_do_not_verify_falls_back_to_the_search_without_the_finer_grid() -> None:
    """random_problem(369004, m=2) under an ``a_y`` box at 0.373 of its peaks: the finer grid's
    start leads to contact times on a curved edge of the feasible set, where the search ends
    non-stationary (``inaccurate``); the search without it is ``local`` at 2579.171, below the FOH
    QP's sweep at N = 16 (2595.263), and that plan is returned with the unverified point named."""
    problem = boxed(369004, 2, 0.3732189968128187, "ay")
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None, (pmp.status, pmp.info.get("failed_check"))
    search = pmp.info["search"]
    assert "finer_grid_unverified" in search and search["finer_grid_unverified"]["failed_check"] == "hamiltonian_jump"
    qp = plan(problem, "qp", solver="clarabel", steps=16)
    assert qp.status in (stc.OPTIMAL, stc.LOCAL) and qp.cost is not None
    assert pmp.cost <= qp.cost * (1 + 1e-6)
    at = _foh_through(problem, pmp.contact_times)
    assert at is not None and pmp.cost * (1 - 1e-9) <= at <= pmp.cost * (1 + GRID_REL)
