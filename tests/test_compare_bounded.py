"""Issue 19 item 7: the bounded problem in ``iamp compare`` / ``reproduce`` (compare/bounded.py).

The rows say what each planner did under the limits, and the numbers are the plans' own:
non-binding bounds cost nothing, binding bounds cost >= 0, an infeasible row is certified, a
judged row names the bound it exceeds, a planner that is not installed is ``not available``.
"""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.comparison import bounded as bd
from iamp.core import status as sts
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp import QPPlanner
from iamp.prediction.resolve import load_problem


def _inputs(problem):  # type: ignore[no-untyped-def]
    pmp = PMPPlanner().plan(problem)
    return pmp, pmp.inputs(np.linspace(0.0, problem.tf, 4001))


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.5, 1.5))
def test_rows_are_the_plans_own_numbers(seed: int, scale: float) -> None:
    problem = random_problem(seed)
    pmp, U = _inputs(problem)
    lim = PhysicalLimits(ax=(min(-0.1, scale * float(U[:, 0].min()) - 1e-3),
                             max(0.1, scale * float(U[:, 0].max()) + 1e-3)))
    rows = {r.planner: r for r in bd.bounded_rows("rnd", problem, lim, steps=16,
                                                  planners=("pmp", "equality"))}
    eq = rows["equality"]
    direct = QPPlanner(steps=16).plan(problem.with_limits(lim))
    free = QPPlanner(steps=16).plan(problem)
    assert eq.status == direct.status and eq.free_cost == free.cost
    if direct.status == sts.OPTIMAL:
        assert eq.cost == direct.cost
        assert eq.bound_cost_rel is not None and eq.bound_cost_rel >= -1e-9  # bounds never lower the cost
        assert eq.peaks_json["ax"]["ok"] and eq.imposed
    p = rows["pmp"]
    if p.status == sts.LIMITS_VIOLATED:
        assert p.peaks_json["ax"]["ok"] is False and p.cost is None
    elif p.status == sts.OPTIMAL:
        assert p.peaks_json["ax"]["ok"]
        if scale >= 1.0 and p.cost is not None:  # the box does not bind: the PMP's plan is unchanged
            assert p.cost == pytest.approx(pmp.cost, rel=1e-9) and abs(p.bound_cost_rel or 0.0) <= 1e-9


def test_infeasible_row_is_certified_and_explained() -> None:
    _, p, _ = load_problem("paper-3-poly")
    rows = {r.planner: r for r in bd.bounded_rows("paper-3-poly", p, PASSENGER_CAR, steps=20,
                                                  planners=("equality",))}
    r = rows["equality"]
    assert r.status == sts.INFEASIBLE and r.cost is None and r.imposed
    assert r.reason is not None and "19 of 19" in r.reason and "Farkas" in r.reason


def test_missing_planner_is_not_available(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(bd.BOUNDED_PLANNERS, "active", "iamp.planners.no_such_module")
    _, p, _ = load_problem("paper-1-poly")
    rows = bd.bounded_rows("paper-1-poly", p, PASSENGER_CAR, steps=10, planners=("active",))
    assert rows[0].status == "not available" and "no_such_module" in (rows[0].reason or "")
    assert "not available" in bd.markdown_table(rows)


@pytest.mark.skipif(importlib.util.find_spec("iamp.planners.pmp.bounded") is None,  # restructure: keep
                    reason="the bounded PMP (branch bpmp) is not on this branch")
def test_bounded_pmp_equals_bounded_qp_as_n_grows() -> None:
    """Where the bounded PMP exists: PMP = bounded QP (FOH) up to a gap that falls with N."""
    _, p, _ = load_problem("paper-1-poly")
    lim = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0))
    gaps = [bd.bounded_section("paper-1-poly", p, lim, steps=N)["pmp_vs_qp_rel_gap"] for N in (25, 100)]
    assert gaps[0] is not None and gaps[1] is not None and gaps[1] < gaps[0]


def test_cli_compare_bounded(cli) -> None:  # type: ignore[no-untyped-def]
    args = ("compare", "paper-1-poly", "--bounded", "--steps", "20", "--solvers", "clarabel", "--holds", "foh",
            "--repeats", "1", "--no-breakdown", "-q")
    r = cli(*args, "--json")
    sc = json.loads(r.stdout)["scenarios"][0]
    rows = {row["planner"]: row for row in sc["bounded"]["rows"]}
    assert sc["bounded"]["limits"]["ax"] == [-6.0, 3.0]
    assert rows["equality"]["status"] == "optimal" and rows["equality"]["limits"]["ax"]["ok"]
    assert rows["equality"]["bound_cost_rel"] > 0  # the passenger car's ax binds on paper-1-poly
    text = cli(*args).stdout
    assert "bounded problem (paper-1-poly" in text and "equality" in text
