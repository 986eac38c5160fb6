"""The bounded QP's witness (one vehicle): a verified candidate before the pre-sweep certificate.

A verified candidate proves that the bounded problem has a plan at a grid node, so no
certificate of infeasibility of every candidate (``infeasible_before_sweep``) can hold; the
planner then skips it (the closed loop's ``qp`` spent ~40 % of its planning time on it) and the
sweep reuses the witness.  The plan must be the one of the certificate-first order."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from iamp.core.physical import PhysicalLimits
from iamp.core.problem import Problem
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp import QPPlanner

N = 12


def _bounded(seed: int, scale: float) -> Problem:
    problem = random_problem(seed, m=1)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    peak = np.abs(U).max(axis=0)
    return problem.with_limits(PhysicalLimits(ax=(-scale * peak[0] - 0.1, scale * peak[0] + 0.1),
                                              ay=(-scale * peak[1] - 0.1, scale * peak[1] + 0.1),
                                              vx=(0.0, 60.0)))


def _certificate_first(problem: Problem) -> tuple[str, float | None]:
    """The former order: the certificate, then the full screened sweep on a fresh QP."""
    from iamp.planners.qp.bounded import BoundedQP, box_screen, infeasible_before_sweep
    from iamp.planners.qp.sweep import run_sweep

    if infeasible_before_sweep(problem, N, "foh", "clarabel") is not None:
        return "infeasible", None
    qp = BoundedQP(problem, N, "foh", "clarabel")
    box = box_screen(problem)
    assert box is not None
    sw = run_sweep(qp, None, lambda nodes, times: box(times))
    return ("optimal", sw.best.cost) if sw.best is not None else ("none", None)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.3, 1.2))
@example(760, 1.0)  # the sweep's best plan dips to v_x = -0.022 between nodes: limits_violated either way
def test_the_witness_gives_the_plan_of_the_certificate_first_order(seed: int, scale: float) -> None:
    problem = _bounded(seed, scale)
    plan = QPPlanner(steps=N, solver="clarabel").plan(problem)
    status, cost = _certificate_first(problem)
    if status == "optimal":
        # the same plan as the certificate-first sweep's best; the planner's final check of the limits
        # between the grid nodes (node-only rows here) then gives it the same verdict in either order
        assert plan.status in ("optimal", "limits_violated") and plan.cost is not None and cost is not None
        assert plan.status == "optimal" or "between the grid nodes" in str(plan.diagnostics.reason)
        assert plan.cost == pytest.approx(cost, rel=1e-12, abs=1e-12)
        w = plan.diagnostics.candidates["witness"]  # type: ignore[index]
        assert w["verified"] == w["certificate_skipped"]
    elif status == "infeasible":
        assert plan.status == "infeasible" and plan.cost is None
        assert not plan.diagnostics.candidates.get("witness", {}).get("verified", False)  # type: ignore[union-attr]
    else:  # no certificate and no verified candidate: no plan either way
        assert plan.status != "optimal" and plan.cost is None


def test_a_verified_witness_skips_the_certificate_and_is_not_solved_twice(monkeypatch: pytest.MonkeyPatch) -> None:
    import iamp.planners.qp.bounded as bounded

    problem = _bounded(3, 1.2)  # the limits do not bind much: every middle node has a plan

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the certificate ran although a verified candidate exists")

    monkeypatch.setattr(bounded, "infeasible_before_sweep", refuse)
    plan = QPPlanner(steps=N, solver="clarabel").plan(problem)
    assert plan.status == "optimal"
    d = plan.diagnostics
    w = d.candidates["witness"]  # type: ignore[index]
    assert w == {"nodes": [N // 2], "verified": True, "certificate_skipped": True}
    screened = sum(1 for r in (d.failures or []) if r[1] == "infeasible")
    assert d.n_solves == d.candidates["total"] - screened  # type: ignore[index]  # the witness solved once
