"""More vehicles than the paper's two: the PMP plans them within its box budget (SPEC sets no
upper limit on ``[[vehicles]]``; ``iamp.core.limits`` caps ``m`` at 8)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from iamp.core.errors import ScenarioError
from iamp.core.limits import LIMITS
from iamp.planners.examples import random_problem
from iamp.planners.pmp.planner import PMPPlanner, ValueFunction


def crowd(seed: int, m: int):
    """``random_problem(seed, 4)`` plus copies of its vehicles shifted 12 m further each."""
    base = random_problem(seed, 4)
    vs = list(base.vehicles)
    k = 0
    while len(vs) < m:
        v = vs[k % 4]
        xp = list(v.x_poly)
        xp[0] += 12.0 * (k + 1)
        vs.append(dataclasses.replace(v, x_poly=tuple(xp), name=f"copy{k}"))
        k += 1
    return base.with_vehicles(vs)


@pytest.mark.parametrize("m", [5, 6])
def test_small_budget_gives_a_verified_local_plan_no_worse_than_samples(m):
    problem = crowd(1, m)
    plan = PMPPlanner(max_boxes=3000, compiled=False).plan(problem, diagnostics=False)
    assert plan.status in ("optimal", "local")
    assert all(c["ok"] for c in plan.info["checks"].values())
    assert plan.info["search"]["boxes"] <= 3000
    J = ValueFunction(problem)
    rng = np.random.default_rng(m)
    samples = np.sort(rng.uniform(0.02, 0.98, size=(4000, m)), axis=1) * problem.tf
    for perm in (rng.permutation(m) for _ in range(8)):
        vals = J(samples[:, perm])
        assert plan.cost <= float(np.min(vals[np.isfinite(vals)])) + 1e-9 * plan.cost
    assert plan.cost == pytest.approx(float(J(plan.contact_times[None, :])[0]), rel=1e-9)


def test_the_cap_is_enforced_with_the_field_named():
    with pytest.raises(ScenarioError) as err:
        crowd(0, int(LIMITS["vehicles_max"]) + 1)
    assert "vehicles" in str(err.value)


@pytest.mark.parametrize("m", [5, 7])
def test_the_budget_truncates_the_one_search_whatever_the_compiled_flag(m):
    """The box budget stops the one search (issue 32: its numba copy was removed); the
    ``compiled`` flag, kept for old callers, changes nothing, bit for bit."""
    problem = crowd(2, m)
    a = PMPPlanner(max_boxes=4000, compiled=False).plan(problem, diagnostics=False)
    b = PMPPlanner(max_boxes=4000, compiled=True).plan(problem, diagnostics=False)
    assert a.status == b.status and a.info["search"]["boxes"] == b.info["search"]["boxes"] <= 4000
    assert np.array_equal(a.contact_times, b.contact_times) and a.cost == b.cost
