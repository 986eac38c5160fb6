r"""Rule B1 of a bounded pair (SPEC §14, :mod:`iamp.comparison.agreement.bounded_pair`): the bounded
PMP has a verified plan and the bounded QP says ``infeasible``.

A QP on a grid (contact times on nodes, every bound at every node) can have no plan where the
continuous problem has one: ``random_problem(12)`` with the input box at 0.6 of its inputs admits
contact times only in about ``[2.0, 2.3]`` s, and the QP of ``N = 12`` steps has one node there
(``t = 2.28``, ``h = 0.57``), where the grid cannot meet the corner within the box.  Rule B1 decides
from the data: a plan of the QP's grid built from the PMP's plan (:func:`upper_plan`, the
construction of rule B6) contradicts the QP's ``infeasible`` (``disagree``); none: the pair is not
comparable, and the verdict (``agree``, the only value besides ``disagree``) says the two claims are
consistent, with the reason in ``verdict_basis`` and ``notes``.

The references are independent of the rule: the QP at every candidate node, solved on its own,
is infeasible with a verified Farkas certificate (the QP's claim is right on these grids), the
PMP's plan is a plan of the continuous problem (in the box, exact states through the corner and
the boundary values), and a plan the rule reports is a plan of the QP (the QP solved at its nodes
is optimal and costs no more)."""

from __future__ import annotations

import copy
import dataclasses
import functools
import itertools

import numpy as np
import pytest
from bounded_bracket import bounded
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.comparison.agreement.bounded_pair import (
    B1_MAX_CANDIDATES,
    box_violation,
    candidate_nodes,
    compare_bounded_pmp_qp,
    grid_plan_from_pmp,
)
from iamp.comparison.agreement.runs import QPConfig, Run, run_pmp, run_qp
from iamp.core.physical import PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp.bounded import BoundedQP

#: (seed, N, hold) measured with the bounded PMP verified and the Clarabel QP infeasible at 0.6 of the
#: inputs (``bounded(seed, 0.6)``); ``proved``: the bounded PMP certifies the box infeasible at every node.
CASES = [(12, 12, "zoh", False), (12, 6, "foh", False), (12, 8, "foh", True), (40, 24, "foh", False),
         (53, 16, "zoh", False), (73, 24, "zoh", True), (84, 12, "foh", True), (84, 24, "zoh", False)]
SEEDS = sorted({c[0] for c in CASES})


@functools.cache
def _pmp(seed: int, frac: float) -> tuple[Problem, Run]:
    """``bounded(seed, frac)`` and its bounded PMP's run, once per module (1-4 s of CPU each; never mutated)."""
    problem = bounded(seed, frac)
    return problem, run_pmp(problem, repeats=1, warmup=0)


def run_pair(seed: int, frac: float, N: int, hold: str) -> tuple[Problem, Run, Run]:
    """The problem, its bounded PMP's run and the Clarabel QP's run with ``hold`` on ``N`` steps."""
    problem, pmp = _pmp(seed, frac)
    qp = run_qp(problem, QPConfig(solver="clarabel", hold=hold, steps=N), repeats=1, warmup=0, budget_s=0.0)
    return problem, pmp, qp


def _continuous_plan_checks(problem: Problem, plan: Plan) -> None:
    """The bounded PMP's plan is a plan of the continuous problem: inside the box (exact at its
    knots), through the corner at its contact time, from x_0 to x_f."""
    assert box_violation(problem, plan) <= tol("limits_bound_rel")
    t = np.asarray(plan.contact_times, dtype=float)
    assert np.allclose(plan.states(t)[:, [0, 2]], problem.corners(t), rtol=0.0, atol=1e-7)
    ends = plan.states(np.array([0.0, float(problem.tf)]))
    assert np.allclose(ends[0], problem.ego.initial, atol=1e-7) and np.allclose(ends[1], problem.ego.final, atol=1e-7)


def _qp_certifies_every_candidate(problem: Problem, N: int, hold: str) -> None:
    """The QP of this grid, solved at every candidate node on its own, is infeasible with a
    verified Farkas certificate: the grid has no plan (one vehicle)."""
    qp = BoundedQP(problem, N, hold, "clarabel")
    for n in range(1, N):
        r = qp.solve_nodes([n])
        assert r.status == "infeasible" and r.infeasible_certified, (n, r.status)


def _stub_infeasible(qp: Run, reason: str = "no contact node admits a plan (stub)") -> Run:
    """``qp`` claiming ``infeasible`` (no plan, no cost) with ``reason``: a mutated QP run."""
    res = copy.copy(qp.result)
    res.status, res.cost, res.trajectory = "infeasible", None, None
    res.contact_times = np.full(res.problem.m, np.nan)
    res.diagnostics = dataclasses.replace(res.diagnostics, reason=reason)
    return dataclasses.replace(qp, result=res, kkt=None)


# --- case (b): real coarse grids --------------------------------------------------------------------


@pytest.mark.parametrize(("seed", "N", "hold", "proved"), CASES)
def test_a_coarse_grid_without_a_plan_is_not_a_disagreement(seed: int, N: int, hold: str, proved: bool) -> None:
    """The bounded PMP has a plan of the continuous problem, the QP of ``N`` steps rightly has
    none (certified at every node): the pair is not a disagreement; the notes say why (the
    largest violation of the plan built from the PMP's and its node, or the box certified
    infeasible at every node time)."""
    problem, pmp, qp = run_pair(seed, 0.6, N, hold)
    assert pmp.result.status in ("optimal", "local") and qp.result.status == "infeasible"
    _continuous_plan_checks(problem, pmp.result)
    _qp_certifies_every_candidate(problem, N, hold)
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    assert pair["verdict"] == "agree" and pair["reasons"] == [], pair["reasons"]
    assert pair["verdict_basis"].startswith("not comparable (rule B1)")
    assert pair["checks"]["qp_infeasible_not_contradicted"]["ok"]
    g = pair["grid_feasibility"]
    assert (g["steps"], g["hold"], g["candidates"], g["examined"]) == (N, hold, N - 1, N - 1)
    assert g["plan_nodes"] is None and g["undecided"] == 0
    assert g["certified_no_plan"] + g["violating"] == N - 1
    assert g["proved_infeasible"] is proved and (g["certified_no_plan"] == N - 1) is proved
    if proved:
        assert any("the QP's infeasible is proved" in n for n in pair["notes"])
    else:  # a node admits a plan in the box, but the grid cannot hold it: how far, and where
        assert g["worst_violation_rel"] > tol("limits_bound_rel") and g["worst_row"] in ("ax", "ay")
        assert 0 <= g["worst_node"] <= N
        assert any(f"{g['worst_row']} row at node {g['worst_node']}" in n for n in pair["notes"])
        (n,) = g["worst_candidate"]
        t = np.linspace(0.0, problem.tf, N + 1)
        assert PMPPlanner().plan(problem, contact_times=[t[n]]).status == "optimal"  # the box admits a plan there
        # ... and the grid would hold one in the box widened by the reported violation (the plan built
        # without the box): the QP at that node, solved on its own, then has a plan
        lim = problem.limits
        assert lim is not None and lim.ax is not None and lim.ay is not None
        v = 1.01 * g["worst_violation_rel"]
        wide = problem.with_limits(dataclasses.replace(
            lim, ax=(lim.ax[0] - v * max(1.0, abs(lim.ax[0])), lim.ax[1] + v * max(1.0, abs(lim.ax[1]))),
            ay=(lim.ay[0] - v * max(1.0, abs(lim.ay[0])), lim.ay[1] + v * max(1.0, abs(lim.ay[1])))))
        assert BoundedQP(wide, N, hold, "clarabel").solve_nodes([n]).status == "optimal"


def test_the_measured_grid_edge_of_random_problem_12() -> None:
    """``random_problem(12)`` at 0.6, ZOH ``N = 12``: one node (4, t = 2.28 s) admits a plan in the
    box; the plan of the grid built from it needs ``ax`` 3.2 % beyond its bound at node 4, and
    the QP's own certificate says the node has no plan.  At ``N = 16`` the grid holds a plan and
    both are optimal (the grid's property, not the PMP's)."""
    problem, pmp, qp = run_pair(12, 0.6, 12, "zoh")
    g = compare_bounded_pmp_qp(problem, pmp, qp)["grid_feasibility"]
    assert (g["worst_candidate"], g["worst_row"], g["worst_node"]) == ([4], "ax", 4)
    assert 0.02 < g["worst_violation_rel"] < 0.05  # 0.0316 measured
    _, _, finer = run_pair(12, 0.6, 16, "zoh")
    assert finer.result.status == "optimal"
    # the violation bounds how far the grid is from holding a plan there: with ax widened by it (1 % more)
    # the plan built without the box is in the box, and the QP at node 4, solved on its own, has a plan
    # (the least widening that gives one, bisected: 0.0148, against the reported 0.0316)
    assert problem.limits is not None and problem.limits.ax is not None
    lo, hi = problem.limits.ax
    v = 1.01 * g["worst_violation_rel"]
    wide = problem.with_limits(dataclasses.replace(problem.limits, ax=(lo - v * max(1.0, abs(lo)),
                                                                       hi + v * max(1.0, abs(hi)))))
    assert BoundedQP(wide, 12, "zoh", "clarabel").solve_nodes([4]).status == "optimal"


# --- case (a): a QP that wrongly says infeasible ----------------------------------------------------


@pytest.mark.parametrize(("seed", "frac", "N", "hold"), [(229, 0.609375, 24, "zoh"), (229, 0.609375, 24, "foh"),
                                                          (12, 0.6, 16, "zoh")])
def test_a_qp_claiming_infeasible_where_the_grid_has_a_plan_disagrees(seed: int, frac: float, N: int,
                                                                      hold: str) -> None:
    """The QP's run mutated to ``infeasible``: the rule builds a plan of its grid from the PMP's
    plan and names the QP's claim; the plan is one of the QP (solved at its nodes the QP is
    optimal and costs no more than it)."""
    problem, pmp, qp = run_pair(seed, frac, N, hold)
    assert pmp.result.status in ("optimal", "local") and qp.result.status == "optimal"
    wrong = _stub_infeasible(qp, "every candidate certified infeasible (stub)")
    pair = compare_bounded_pmp_qp(problem, pmp, wrong)
    assert pair["verdict"] == "disagree"
    (reason,) = pair["reasons"]
    assert reason.startswith("qp_infeasible_not_contradicted failed") and "reports infeasible" in reason
    assert "every candidate certified infeasible (stub)" in reason and "a plan of its grid" in reason
    g = pair["grid_feasibility"]
    assert g["plan_nodes"] is not None and g["plan_limit_violation_rel"] <= tol("limits_bound_rel")
    assert g["plan_equality_residual_rel"] <= tol("cmp_residual_rel_clarabel")
    ref = BoundedQP(problem, N, hold, "clarabel").solve_nodes(g["plan_nodes"])
    assert ref.status == "optimal" and ref.cost is not None
    assert float(ref.cost) <= g["plan_cost"] * (1 + 1e-7)
    # the unmutated pair is judged by rules B2-B6 as before
    assert compare_bounded_pmp_qp(problem, pmp, qp)["verdict"] == "agree"


def test_other_qp_failures_still_disagree() -> None:
    """A QP failure other than ``infeasible`` beside a verified PMP plan: ``disagree`` with the status."""
    problem, pmp, qp = run_pair(229, 0.609375, 24, "zoh")
    failed = _stub_infeasible(qp, "iteration limit")
    failed.result.status = "numerical_error"
    pair = compare_bounded_pmp_qp(problem, pmp, failed)
    assert pair["verdict"] == "disagree" and "grid_feasibility" not in pair
    assert any("status numerical_error" in r for r in pair["reasons"])


# --- two vehicles ------------------------------------------------------------------------------


@functools.cache
def _two_vehicles(frac: float) -> tuple[Problem, Run]:
    """``random_problem(0, m=2)`` with the input box at ``frac`` of its unbounded inputs, and its
    bounded PMP's run (``local``)."""
    problem = random_problem(0, m=2)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    problem = problem.with_limits(PhysicalLimits(
        ax=(frac * min(-0.5, float(U[:, 0].min())), frac * max(0.5, float(U[:, 0].max()))),
        ay=(frac * min(-0.5, float(U[:, 1].min())), frac * max(0.5, float(U[:, 1].max())))))
    return problem, run_pmp(problem, repeats=1, warmup=0)


def test_two_vehicles_on_a_coarse_grid() -> None:
    """Two vehicles, box at 0.8, FOH ``N = 6``: the QP is infeasible (every one of the 25 node pairs
    certified by its own Farkas certificate), the PMP has a plan; rule B1 examines all 25: the box
    certified infeasible at the node times, two vehicles on one node (distinct corners), or a built
    plan that violates a row — not a disagreement.  At ``N = 12`` the QP has a plan; claimed
    infeasible, the rule finds a plan of the grid (a plan of the QP: solved at its node pair the QP
    is optimal and costs no more)."""
    problem, pmp = _two_vehicles(0.8)
    assert pmp.result.status in ("optimal", "local")
    _continuous_plan_checks(problem, pmp.result)
    qp = run_qp(problem, QPConfig(solver="clarabel", hold="foh", steps=6), repeats=1, warmup=0, budget_s=0.0)
    assert qp.result.status == "infeasible"
    solver = BoundedQP(problem, 6, "foh", "clarabel")
    for nodes in itertools.product(range(1, 6), repeat=2):
        r = solver.solve_nodes(list(nodes))
        assert r.status == "infeasible" and r.infeasible_certified, nodes
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    assert pair["verdict"] == "agree" and pair["verdict_basis"].startswith("not comparable (rule B1)")
    g = pair["grid_feasibility"]
    assert (g["candidates"], g["examined"], g["undecided"], g["plan_nodes"]) == (25, 25, 0, None)
    assert g["certified_no_plan"] + g["violating"] == 25 and g["violating"] >= 1
    assert any("share node" in c.reason for c in grid_plan_from_pmp(  # type: ignore[operator]
        problem, pmp.result, 6, "foh", tol("cmp_residual_rel_clarabel")).candidates)
    fine = run_qp(problem, QPConfig(solver="clarabel", hold="foh", steps=12), repeats=1, warmup=0, budget_s=0.0)
    assert fine.result.status == "optimal"
    wrong = compare_bounded_pmp_qp(problem, pmp, _stub_infeasible(fine))
    assert wrong["verdict"] == "disagree"
    found = wrong["grid_feasibility"]["plan_nodes"]
    assert found is not None
    ref = BoundedQP(problem, 12, "foh", "clarabel").solve_nodes(found)
    assert ref.status == "optimal" and float(ref.cost) <= wrong["grid_feasibility"]["plan_cost"] * (1 + 1e-7)  # type: ignore[arg-type]


# --- properties ---------------------------------------------------------------------------------


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st.sampled_from(SEEDS), st.integers(3, 40), st.sampled_from(["zoh", "foh"]))
def test_rule_b1_on_generated_grids(seed: int, N: int, hold: str) -> None:
    """Property on the problems with a narrow feasible contact interval, every grid ``N``:

    * a real ``infeasible`` of the QP (certified at every node) is never called a disagreement;
    * a real ``optimal`` of the QP, mutated to ``infeasible``, is contradicted whenever rule B6
      built a plan of the QP from the PMP's plan at the QP's contact node (the rule examines
      every node of these grids, so it finds one), and any plan it reports is a plan of the QP."""
    problem, pmp, qp = run_pair(seed, 0.6, N, hold)
    if pmp.result.status not in ("optimal", "local"):
        return
    if qp.result.status == "infeasible":
        pair = compare_bounded_pmp_qp(problem, pmp, qp)
        assert pair["verdict"] == "agree", pair["reasons"]
        assert pair["grid_feasibility"]["plan_nodes"] is None
        return
    assert qp.result.status == "optimal"
    right = compare_bounded_pmp_qp(problem, pmp, qp)
    pair = compare_bounded_pmp_qp(problem, pmp, _stub_infeasible(qp))
    g = pair["grid_feasibility"]
    assert g["examined"] <= B1_MAX_CANDIDATES
    if right["bounded"][f"{hold}_upper_reason"] is None:  # type: ignore[typeddict-item]
        assert pair["verdict"] == "disagree" and g["plan_nodes"] is not None
    if g["plan_nodes"] is not None:
        ref = BoundedQP(problem, N, hold, "clarabel").solve_nodes(g["plan_nodes"])
        assert ref.status == "optimal" and float(ref.cost) <= g["plan_cost"] * (1 + 1e-7)  # type: ignore[arg-type]
    else:
        assert pair["verdict"] == "agree"


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 30), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=3), st.integers(1, 70))
def test_candidates_are_the_nearest_first(N: int, fractions: list[float], limit: int) -> None:
    """The candidates are distinct interior-node tuples, as many as the budget allows, the first
    ``2^m`` (budget permitting) those of the nodes bracketing the times, and no candidate left out
    is nearer than one taken (by the largest per-vehicle rank)."""
    t = np.linspace(0.0, 7.0, N + 1)
    times = [7.0 * f for f in fractions]
    m = len(times)
    cands = candidate_nodes(t, times, limit)
    assert len(set(cands)) == len(cands) == min(limit, (N - 1) ** m)
    assert all(len(c) == m and all(1 <= n <= N - 1 for n in c) for c in cands)
    rank = [sorted(range(1, N), key=lambda n, ti=ti: (abs(t[n] - ti), n)) for ti in times]

    def level(c: tuple[int, ...]) -> int:
        return max(rank[i].index(n) for i, n in enumerate(c))

    taken = max(level(c) for c in cands)
    every = set(itertools.product(range(1, N), repeat=m))
    assert all(level(c) >= taken for c in every - set(cands))
    near = [r[:2] for r in rank]  # the two nearest interior nodes of each vehicle
    k = min(len(cands), int(np.prod([len(x) for x in near])))
    assert set(cands[:k]) <= set(itertools.product(*near))


def test_grid_plan_search_stops_at_the_first_plan() -> None:
    """On a grid that holds the PMP's plan the search stops at the first candidate whose built
    plan meets every row (one fixed-time PMP solve per candidate examined)."""
    problem, pmp = _pmp(229, 0.609375)
    search = grid_plan_from_pmp(problem, pmp.result, 24, "zoh", tol("cmp_residual_rel_clarabel"))
    assert search.plan is search.candidates[-1] and search.plan is not None
    assert all(not c.is_plan for c in search.candidates[:-1])
