"""The QP's grid sweep keeps the arrays of its best candidate only.

A three-vehicle sweep at the planner's default ``N = 100`` has 100·... = 941,094 candidates: with
every candidate's ``z``, ``y``, trajectory and multipliers kept, ``iamp plan --planner qp`` on a
three-vehicle scenario grew past 15 GB (found by a harness planning ``overtake-three`` with the
registry's defaults).  The sweep keeps every candidate's verdict, cost and residuals, and the
solution of its best alone.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.planners.examples import overtake_three_problem, random_problem
from iamp.planners.qp.core import DiscretisedQP
from iamp.planners.qp.sweep import run_sweep


@settings(max_examples=6, deadline=None)
@given(seed=hs.integers(0, 10_000), m=hs.sampled_from([1, 2, 3]), hold=hs.sampled_from(["foh", "zoh"]),
       solver=hs.sampled_from(["kkt", "clarabel"]))
def test_the_sweep_keeps_the_best_solution_and_every_verdict(seed: int, m: int, hold: str, solver: str) -> None:
    p = random_problem(seed, m=m)
    N = 11 if m == 3 else 16
    light = run_sweep(DiscretisedQP(p, N, hold, solver))
    full = run_sweep(DiscretisedQP(p, N, hold, solver), keep_solutions=True)
    assert [(r.nodes, r.status, r.cost) for r in light.results] == [(r.nodes, r.status, r.cost) for r in full.results]
    assert light.table == full.table and light.candidates() == full.candidates()
    assert light.could_beat == full.could_beat
    if full.best is None:
        assert light.best is None
        return
    b, f = light.best, full.best
    assert b.nodes == f.nodes and b.cost == f.cost
    # the best keeps its solution, bit for bit the same as when every candidate keeps its own
    assert b.z is not None and b.y is not None and b.trajectory is not None
    assert np.array_equal(b.z, f.z) and np.array_equal(b.y, f.y)
    assert np.array_equal(b.trajectory.X, f.trajectory.X) and np.array_equal(b.trajectory.U, f.trajectory.U)
    assert np.array_equal(b.multipliers, f.multipliers)
    for r in light.results:
        if r is not b:
            assert r.z is None and r.y is None and r.trajectory is None and r.multipliers is None
    # the dropped candidates kept their residuals (the planner reports the worst when none passes)
    assert [r.kkt.as_dict() if r.kkt else None for r in light.results] == \
        [r.kkt.as_dict() if r.kkt else None for r in full.results]


@pytest.mark.parametrize("solver", ["kkt", "clarabel"])
def test_a_three_vehicle_sweep_keeps_a_small_part_of_its_solutions(solver: str) -> None:
    """Memory still held after the sweep (N = 16: 2,730 candidates): the dropped arrays are freed
    (what every candidate's solution takes, less the block of the best one's family with ``kkt``,
    whose candidates are views of one array), and each candidate keeps at most 2.5 kB (its verdict,
    checks and residuals; about 1.8 kB measured) whatever the size of its solution."""
    p = overtake_three_problem(False).with_limits(None)

    def held(keep: bool) -> int:
        qp = DiscretisedQP(p, 16, "foh", solver)
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        sw = run_sweep(qp, keep_solutions=keep)
        size = tracemalloc.get_traced_memory()[0] - base
        tracemalloc.stop()
        assert len(sw.results) == 15 * 14 * 13
        arrays = sum(r.z.nbytes + r.y.nbytes + r.trajectory.X.nbytes + r.trajectory.U.nbytes
                     for r in sw.results if r.z is not None and r.trajectory is not None)
        return size, arrays

    (light, _), (full, arrays) = held(False), held(True)
    assert light <= 2500 * 15 * 14 * 13, light
    assert full - light >= 0.5 * arrays, (light, full, arrays)


class _Costs:
    """A candidate solver whose candidates cost what a list says (a stand-in for the QP: the sweep's
    choice of its best, judged independently of the QP's numbers)."""

    def __init__(self, costs: list[float | None]) -> None:
        self.costs = costs
        self.t_nodes = np.arange(len(costs) + 2, dtype=float)
        self.n_solves = 0

    def set_uniform_grid(self) -> None:
        pass

    def n_candidates(self) -> int:
        return len(self.costs)

    def candidate_nodes(self):  # type: ignore[no-untyped-def]
        return iter([(k + 1,) for k in range(len(self.costs))])

    def solve_nodes(self, nodes):  # type: ignore[no-untyped-def]
        from iamp.core import status as st
        from iamp.planners.qp.core import CandidateResult

        cost = self.costs[nodes[0] - 1]
        self.n_solves += 1
        ok = cost is not None
        r = CandidateResult(nodes=tuple(nodes), status=st.OPTIMAL if ok else st.INFEASIBLE,
                            solver_status=st.OPTIMAL if ok else st.INFEASIBLE, raw_status="stub",
                            cost=float(cost) if ok else np.inf, contact_times=self.t_nodes[list(nodes)],
                            infeasible_certified=not ok)
        r.z = r.y = np.full(3, float(nodes[0]))
        return r


@settings(max_examples=60, deadline=None)
@given(costs=hs.lists(hs.one_of(hs.none(), hs.sampled_from([1.0, 2.0, 3.0]), hs.floats(0.0, 5.0)),
                      min_size=1, max_size=12))
def test_the_best_is_the_first_cheapest_solved_candidate(costs: list[float | None]) -> None:
    """The best candidate is the first of the cheapest solved ones (ties included: the costs are drawn
    from a few values), it alone keeps its arrays, and a sweep without a solved candidate has none."""
    sw = run_sweep(_Costs(costs))  # type: ignore[arg-type]
    solved = [k for k, c in enumerate(costs) if c is not None]
    if not solved:
        assert sw.best is None
        assert all(r.z is None for r in sw.results)
        return
    first = min(solved, key=lambda k: (costs[k], k))
    assert sw.best is sw.results[first] and sw.best.nodes == (first + 1,)
    assert np.array_equal(sw.best.z, np.full(3, first + 1.0))
    assert [k for k, r in enumerate(sw.results) if r.z is not None] == [first]
