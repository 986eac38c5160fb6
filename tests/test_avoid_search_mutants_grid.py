"""Gaps found by mutation testing of the grid crossing-time search (``planners/avoid/search.py``).

The functions take the planner's one-candidate solve as a callable; here it is the planner's own
solve on a generated one-vehicle overtake, wrapped to record every call, and each function's
answer is compared with a brute-force evaluation of the same relaxations and candidates:

* :func:`pruned_switches` keeps exactly the switches ``j`` whose two relaxations ``R_pre(j)`` and
  ``R_suf(j)`` are both within the bound (``R_pre`` nondecreasing, ``R_suf`` nonincreasing), every
  skipped switch costs more than the bound, and its bisections only ask valid switches
  (``0 <= j <= N - 1``), each at most ``floor(log2(L)) + 1`` times for an interval of ``L``;
* :func:`seed_switches` are the three switches around the free optimum's first interior node
  outside the first half-plane (clipped to the grid).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from avoid_overtakes import generated_overtake as _overtake
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.problem import Problem
from iamp.planners.avoid.check import Candidate, crossing_orders
from iamp.planners.avoid.data import AvoidData
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.avoid.search import Phase, pruned_switches, seed_switches


class _Recorder:
    """The planner's solve on the uniform grid, every call's phases kept."""

    def __init__(self, problem: Problem, steps: int) -> None:
        self.planner = AvoidQPPlanner(safety="nodes", steps=steps)
        self.data = AvoidData(problem, np.linspace(0.0, problem.tf, steps + 1), "foh", with_limits=True)
        self.backend = self.planner._backend(self.data, np.zeros(self.data.n_rows - self.data.n_eq, dtype=bool))
        self.calls: list[tuple[Phase, ...]] = []

    def __call__(self, phases: Sequence[Phase]) -> Candidate:
        self.calls.append(tuple(phases))
        return self.planner._solve(self.data, self.backend, phases, None)

    def cost(self, phases: Sequence[Phase]) -> float:
        r = self.planner._solve(self.data, self.backend, phases, None)
        return float(r.cost) if r.status == st.OPTIMAL else np.inf


def _case(xf: float, gap: float, speed: float, limits: bool) -> tuple[Problem, list[list[tuple[int, int]]]]:
    """The generated overtake and its crossing orders (a draw without them is discarded)."""
    try:
        problem = _overtake(xf, gap, speed, limits)
        orders, reason = crossing_orders(problem)
    except ScenarioError:
        assume(False)
        raise
    assume(reason is None)
    return problem, orders


CASES = given(st_h.floats(105.0, 130.0), st_h.floats(7.5, 25.0), st_h.floats(14.0, 22.0), st_h.booleans(),
              st_h.sampled_from([8, 12, 17]))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@CASES
def test_seed_switches_surround_the_free_optimums_crossing(xf: float, gap: float, speed: float, limits: bool,
                                                           steps: int) -> None:
    problem, orders = _case(xf, gap, speed, limits)
    solve = _Recorder(problem, steps)
    first = orders[0][0][0]
    seeds = seed_switches(solve.data, solve, first)
    free = solve([])
    N = steps
    if free.status != st.OPTIMAL:
        assert seeds == [N // 2]
        return
    X, _ = solve.data.unpack(free.z)
    outside = [k for k in range(1, N) if solve.data.planes[0][first].margin(
        solve.data.t_nodes[k:k + 1], X[k:k + 1, 2 * first])[0] < 0]
    j0 = outside[0] - 1 if outside else N - 1
    assert seeds == sorted({min(max(j, 0), N - 1) for j in (j0 - 1, j0, j0 + 1)})
    assert len(seeds) >= 2 and all(0 <= j <= N - 1 for j in seeds)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@CASES
def test_pruned_switches_are_exactly_those_both_relaxations_allow(xf: float, gap: float, speed: float, limits: bool,
                                                                  steps: int) -> None:
    problem, orders = _case(xf, gap, speed, limits)
    N = steps
    solve = _Recorder(problem, N)
    first, second = orders[0][0]
    seeds = seed_switches(solve.data, solve, first)
    costs = {j: solve.cost([(first, second, j, j + 1)]) for j in range(N)}
    bound = min(costs[j] for j in seeds)
    assume(np.isfinite(bound))
    solve.calls.clear()
    kept = pruned_switches(solve.data, solve, first, second, seeds, bound)
    limit = bound * (1 + 1e-9) + 1e-12
    r_pre = [solve.cost([(first, second, j, N)]) for j in range(N)]
    r_suf = [solve.cost([(first, second, 0, j + 1)]) for j in range(N)]
    # the monotonicity the bisections rely on (more nodes imposed: no cheaper)
    assert all(a <= b * (1 + 1e-9) + 1e-9 for a, b in zip(r_pre[:-1], r_pre[1:]))
    assert all(a * (1 + 1e-9) + 1e-9 >= b for a, b in zip(r_suf[:-1], r_suf[1:]))
    hi_j = next((j for j in range(max(seeds), N) if r_pre[j] > limit), N)
    lo_cut = max((j for j in range(0, min(seeds) + 1) if r_suf[j] > limit), default=-1)
    assert kept == [j for j in range(lo_cut + 1, hi_j) if j not in seeds]
    # exact: every switch neither kept nor seeded costs more than the bound
    for j in range(N):
        if j not in kept and j not in seeds:
            assert costs[j] > bound * (1 - 1e-9) - 1e-12, (j, costs[j], bound)
    # the bisections ask valid switches only, each at most floor(log2 L) + 1 times
    pre = [p[0][2] for p in solve.calls if p[0][3] == N]
    suf = [p[0][3] - 1 for p in solve.calls if p[0][2] == 0 and p[0][3] != N]
    assert len(pre) + len(suf) == len(solve.calls)
    assert all(max(seeds) <= j <= N - 1 for j in pre) and all(0 <= j <= min(seeds) for j in suf)
    assert len(pre) <= int(np.floor(np.log2(N - max(seeds)))) + 1
    assert len(suf) <= int(np.floor(np.log2(min(seeds) + 1))) + 1
