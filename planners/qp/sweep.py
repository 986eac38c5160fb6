r"""The contact-time grid sweep of the QP (SPEC §3.4) and what it can certify.

The sweep solves one QP per candidate (every ordered combination of distinct interior
nodes, one per vehicle) on the uniform grid and keeps the cheapest *verified* candidate.
Its accounting (:meth:`SweepResult.candidates`) is
``{"total", "solved", "failed": {status: count}, "inaccurate"}``.  Candidates go to
:meth:`~iamp.planners.qp.core.DiscretisedQP.solve_many` :data:`SWEEP_CHUNK` at a time (the
``kkt`` backend solves them as a family; progress is reported per chunk); a solver without
``solve_many`` (the cvxpy cross-check) gets them one by one.

A candidate that failed (or is inaccurate) has no verified cost, so it might have been the
best.  Each one is bounded below by the PMP cost at the same contact times
(:func:`iamp.planners.pmp.planner.solve_fixed_times`):

.. math::  J_\text{QP}(k) \;\ge\; J_\text{PMP}(t_k) ,

with equality for FOH (SPEC §3 fact 1: the FOH QP is exact) and ``≥`` for ZOH (fact 2: ZOH
only restricts the input).  A failed candidate *could beat* the best if its bound is below
the best verified cost by more than the cost tolerance ``foh_clarabel_cost_rel`` (relative
to ``max(1, J_best)``); if the bound cannot be computed (singular jump system) it is
counted as able to.  Then the sweep's best is not certified: the plan is not OPTIMAL.  A
candidate of the bounded QP whose infeasibility is certified (a verified Farkas certificate,
:mod:`iamp.planners.qp.bounded`) has no plan at all and cannot beat the best.
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from iamp.core import status as st
from iamp.core.errors import SolverError
from iamp.core.tolerances import tol

from .core import CandidateResult, CandidateSolver

Progress = Callable[[int, int], None]

#: Candidates handed to :meth:`~iamp.planners.qp.core.DiscretisedQP.solve_many` at a time
#: (between two progress calls).
SWEEP_CHUNK = 512


@dataclass
class SweepResult:
    """All candidates of one sweep and its verified best."""

    best: CandidateResult | None
    results: list[CandidateResult]
    could_beat: list[tuple[tuple[int, ...], str, float]] = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def table(self) -> list[tuple[tuple[int, ...], float]]:
        """``[(nodes, cost)]`` in sweep order (``inf`` for an unverified candidate)."""
        return [(r.nodes, r.cost) for r in self.results]

    @property
    def failures(self) -> list[tuple[tuple[int, ...], str]]:
        return [(r.nodes, r.status) for r in self.results if not r.ok]

    def candidates(self) -> dict[str, Any]:
        failed = Counter(r.status for r in self.results if r.status not in (st.OPTIMAL, st.INACCURATE))
        return {"total": len(self.results), "solved": sum(r.ok for r in self.results),
                "failed": dict(sorted(failed.items())),
                "inaccurate": sum(r.status == st.INACCURATE for r in self.results)}

    @property
    def certified(self) -> bool:
        """A verified best exists and no unverified candidate could beat it."""
        return self.best is not None and not self.could_beat

    def failure_status(self) -> str:
        """The status a non-certified sweep reports: the common status of the candidates
        that could beat the best (or of all failures if there is no best); INACCURATE when
        they differ."""
        pool = [s for _, s, _ in self.could_beat] or [s for _, s in self.failures]
        if not pool:
            return st.SOLVER_ERROR
        kinds = set(pool)
        return pool[0] if len(kinds) == 1 else st.INACCURATE


def pmp_lower_bound(qp: CandidateSolver, nodes: tuple[int, ...]) -> float:
    """``J_PMP`` at the candidate's contact times: exact FOH cost, a ZOH lower bound."""
    from iamp.planners.pmp.planner import solve_fixed_times

    try:
        return float(solve_fixed_times(qp.problem, qp.t_nodes[np.asarray(nodes, dtype=np.int64)]).cost())
    except (SolverError, ValueError):
        return -np.inf


def run_sweep(qp: CandidateSolver, progress: Progress | None = None,
              screen: Callable[[tuple[int, ...], np.ndarray], str | None] | None = None,
              known: dict[tuple[int, ...], CandidateResult] | None = None, keep_solutions: bool = False
              ) -> SweepResult:
    """Solve every candidate on the uniform grid; bound the unverified ones (module doc).

    ``screen(nodes, times)`` (the bounded QP: :meth:`iamp.planners.qp.planner.QPPlanner.sweep`)
    returns a reason when a candidate is certified infeasible without a QP solve; such a
    candidate is recorded ``infeasible`` (certified) and not solved.  ``known`` maps candidates
    already solved on ``qp``'s uniform grid to their results, which are used as they are (not
    solved again).  Only the best candidate keeps its solution's arrays (``z``, ``y``, its
    trajectory and multipliers; :meth:`~iamp.planners.qp.core.CandidateResult.drop_solution`),
    every candidate its verdict, cost and residuals: the memory of a sweep grows by about 1.7 kB
    per candidate at ``N = 100`` (16.7 kB with every solution kept); ``keep_solutions=True`` keeps every candidate's."""
    import time

    t0 = time.perf_counter()
    qp.set_uniform_grid()
    total = qp.n_candidates()
    results: list[CandidateResult] = []
    best: CandidateResult | None = None
    many = getattr(qp, "solve_many", None)  # DiscretisedQP: a family at a time (kkt)
    todo = qp.candidate_nodes()
    while True:
        chunk = list(itertools.islice(todo, SWEEP_CHUNK if many is not None else 1))
        if not chunk:
            break
        screened: dict[int, CandidateResult] = {}
        for j, nodes in enumerate(chunk):
            if known and tuple(int(k) for k in nodes) in known:
                screened[j] = known[tuple(int(k) for k in nodes)]
        if screen is not None:
            for j, nodes in enumerate(chunk):
                if j in screened:
                    continue
                times = qp.t_nodes[np.asarray(nodes, dtype=np.int64)].copy()
                why = screen(tuple(int(k) for k in nodes), times)
                if why is not None:
                    screened[j] = CandidateResult(nodes=tuple(int(k) for k in nodes), status=st.INFEASIBLE,
                                                  solver_status=st.INFEASIBLE, raw_status=why, cost=np.inf,
                                                  contact_times=times, infeasible_certified=True)
        todo_now = [c for j, c in enumerate(chunk) if j not in screened]
        solved = iter((many(todo_now) if many is not None else [qp.solve_nodes(c) for c in todo_now])
                      if todo_now else [])
        rs = [screened[j] if j in screened else next(solved) for j in range(len(chunk))]
        for r in rs:
            results.append(r)
            if r.ok and (best is None or r.cost < best.cost):
                if best is not None and not keep_solutions:
                    best.drop_solution()
                best = r
            elif not keep_solutions:
                r.drop_solution()
        if progress is not None:
            progress(len(results), total)
    out = SweepResult(best=best, results=results)
    if best is not None:
        margin = tol("foh_clarabel_cost_rel") * max(1.0, abs(best.cost))
        for r in results:
            if not r.ok and not r.infeasible_certified:  # a certified infeasible candidate cannot beat it
                lb = pmp_lower_bound(qp, r.nodes)
                if lb < best.cost - margin:
                    out.could_beat.append((r.nodes, r.status, lb))
    out.wall_time_s = time.perf_counter() - t0
    return out
