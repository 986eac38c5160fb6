"""The bounded PMP's infeasibility certificate projected on pairs of vehicles (issue 32 item 4).

Three vehicles whose box admits no plan used to end ``infeasible`` *uncertified* when no single
vehicle alone was infeasible and the 3-dimensional cover ran out of its 4000 solves (31 of 148
generated problems, ``random_problem(seed, m=3)`` with the box at 0.40-1.20 of the unbounded
peaks; the FOH QP at ``N = 8`` found no plan on any of them).  A plan for the three vehicles is a
plan for any two of them at their contact times, so a pair certified infeasible over
``(0, t_f)²`` certifies the whole problem (:func:`~iamp.planners.pmp.bounded.infeasibility_certificate`,
``pair_solves``): 20 of those 31 were then certified (the pairs' covers since prune the full cover
too: tests/test_pmp_bounded_projected.py).

Checked against independent references: the FOH QP (a restriction of the continuous problem:
inputs in the box at the nodes are in it everywhere) finds no plan for the certified pair at
any sampled pair of contact times, nor for the three vehicles; and on a three-vehicle problem
with a plan the certificate certifies nothing.
"""

from __future__ import annotations

import numpy as np
from test_bounded_random import boxed

from iamp.api import plan
from iamp.comparison.bench.limits import bounded_pmp_problems
from iamp.core import status as stc
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp import bounded as B
from iamp.planners.qp.bounded import BoundedQP

SEED, SCALE = 707217, 0.47712408207476775


def test_a_pair_alone_certifies_three_vehicles_infeasible() -> None:
    problem = boxed(SEED, 3, SCALE)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.INFEASIBLE
    assert pmp.info["failed_check"] == "box_infeasible_at_every_contact_time"
    i, j = pmp.info["search"]["infeasibility_vehicles"]
    assert "vehicles 0 and 2" in pmp.info["reason"] and (i, j) == (0, 2)
    # without the pairs, the same budgets leave it uncertified (what the planner said before)
    assert not B.infeasibility_certificate(problem).certified
    # the pair alone: the FOH QP through sampled contact times finds no plan (a plan of the
    # continuous pair problem at those times would be one, so it must not exist)
    pair = problem.with_vehicles([problem.vehicles[i], problem.vehicles[j]])
    T = float(problem.tf)
    qp = BoundedQP(pair, 60, "foh", "clarabel")
    rng = np.random.default_rng(3)
    for t in rng.uniform(0.02 * T, 0.98 * T, size=(12, 2)):
        at = qp.solve_times(t)
        assert at.status not in (stc.OPTIMAL, stc.LOCAL), (t, at.status, at.cost)
    # the three vehicles: the QP's own sweep finds no plan either
    assert plan(problem, "qp", solver="clarabel", steps=8).status not in (stc.OPTIMAL, stc.LOCAL)


def test_the_pairs_certify_nothing_where_a_plan_exists() -> None:
    """Soundness: on the bench's three-vehicle problem with a plan (box at 85 % of the peaks),
    neither the pairs nor the cover certify infeasibility, whatever the budget."""
    problem = bounded_pmp_problems()["bounded_pmp_three_vehicles_feasible"]
    pmp = PMPPlanner().plan(problem)
    assert pmp.status in (stc.OPTIMAL, stc.LOCAL)
    proof = B.infeasibility_certificate(problem, pair_solves=B.PAIR_SOLVES)
    assert not proof.certified and proof.pair is None
