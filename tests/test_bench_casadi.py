"""The CasADi + IPOPT peer of ``iamp bench`` solves the same free-contact-time problem.

Its ZOH inputs are continuous-time inputs and its interior-point constraint holds exactly at
the free node, so every IPOPT solution is a feasible point of the problem the PMP solves
globally: ``J_casadi >= J_pmp`` (up to IPOPT's tolerance), with the gap ``O(h^2)``.
"""

from __future__ import annotations

import pytest

from iamp.planners.examples import paper_problem, random_problem
from iamp.planners.pmp.planner import PMPPlanner

pytest.importorskip("casadi")

from iamp.comparison.bench.casadi import casadi_free_time


@pytest.mark.parametrize("problem", [paper_problem(1), *(random_problem(s, m=1) for s in (1, 2, 3))],
                         ids=["paper-1", "seed1", "seed2", "seed3"])
def test_casadi_is_a_feasible_point_of_the_pmp_problem(problem):
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == "optimal"
    res = casadi_free_time(problem, steps=40, repeats=1)
    assert res["return_status"] == "Solve_Succeeded"
    J = float(pmp.cost)
    assert res["cost"] >= J - 1e-7 * abs(J)
    assert res["cost"] <= J * 1.05  # a 40-step ZOH is close to the continuous optimum


def test_casadi_gap_shrinks_like_h_squared():
    problem = paper_problem(1)
    pmp = PMPPlanner().plan(problem)
    J = float(pmp.cost)
    t = float(pmp.contact_times[0])
    coarse = casadi_free_time(problem, steps=20, repeats=1)
    fine = casadi_free_time(problem, steps=80, repeats=1)
    gap_c, gap_f = coarse["cost"] - J, fine["cost"] - J
    assert gap_f > 0 and gap_c > 0
    assert 8.0 < gap_c / gap_f < 24.0  # h divided by 4: gap divided by ~16
    assert abs(fine["contact_time"] - t) < abs(coarse["contact_time"] - t) + 1e-9


def test_casadi_refuses_more_than_one_vehicle():
    with pytest.raises(ValueError):
        casadi_free_time(random_problem(0, m=2), steps=10, repeats=1)
