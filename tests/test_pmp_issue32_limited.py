"""Several vehicles with an active input box: the unbounded plan is only a start (issue 32).

With ``m ≥ 2`` free contact times the bounded PMP is ``local`` (no certificate over several
contact times), so :meth:`PMPPlanner._plan_limited` starts it from the unbounded search
*without* its branch-and-bound certificate (``max_boxes = 0``); the certified unbounded plan is
made only when it is the answer (the box is respected).  Work is counted, not timed: the number
of branch-and-bound runs.
"""

from __future__ import annotations

import numpy as np
import pytest

import iamp.planners.pmp.bound as bound_module
from iamp.core import status as stc
from iamp.core.problem import Problem
from iamp.planners.examples import boxed_problem, random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import plan_bounded


def boxed(problem: Problem, frac: float) -> tuple[Problem, np.ndarray]:
    """:func:`~iamp.planners.examples.boxed_problem` and the certified unbounded contact times."""
    base = PMPPlanner().plan(problem, diagnostics=False)
    assert base.status == stc.OPTIMAL
    return boxed_problem(problem, frac), base.contact_times


def count_bb(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the branch-and-bound runs (the certificate) of the search."""
    calls: list[int] = []
    real = bound_module.branch_and_bound

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(bound_module, "branch_and_bound", counted)
    return calls


@pytest.mark.parametrize("seed", [15, 1, 28])
def test_active_box_three_vehicles_skips_the_certificate(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The brief's problems (box at 85 % of the peaks): no branch and bound, the same bounded
    plan as from the certified unbounded ``t*``, status ``local`` (stated, not hidden)."""
    problem, t_cert = boxed(random_problem(seed, m=3), 0.85)
    reference = plan_bounded(problem, t_cert)
    calls = count_bb(monkeypatch)
    plan = PMPPlanner().plan(problem)
    assert calls == []
    assert plan.status == reference.status == stc.LOCAL
    assert plan.info["certified_global"] is False
    assert plan.info["unbounded"]["status"] == stc.LOCAL  # the start was not certified
    assert plan.cost == pytest.approx(reference.cost, rel=1e-9)
    np.testing.assert_allclose(plan.contact_times, reference.contact_times, atol=1e-6 * problem.tf)


def test_respected_box_is_still_certified(monkeypatch: pytest.MonkeyPatch) -> None:
    """A box the unbounded plan respects (120 % of its peaks): the certified unbounded plan is
    the answer, ``optimal``, after one uncertified look (one branch and bound in all)."""
    problem, t_cert = boxed(random_problem(15, m=2), 1.2)
    calls = count_bb(monkeypatch)
    plan = PMPPlanner().plan(problem)
    assert len(calls) == 1
    assert plan.status == stc.OPTIMAL and plan.info["certified_global"] is True
    np.testing.assert_allclose(plan.contact_times, t_cert, atol=1e-12)
    assert plan.info["bounded"]["box_active"] is False
