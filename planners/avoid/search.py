r"""The crossing-time search of the avoidance QP (SPEC §10): certification, pruning, refinement.

For one vehicle, candidate ``j`` (a crossing between nodes ``j`` and ``j + 1``) imposes the
first half-plane at the nodes :math:`k \le j` and the second at :math:`k \ge j + 1`; its
optimal cost :math:`J(j)` is a convex QP for every ``j``.  The planner
(:class:`~iamp.planners.avoid.planner.AvoidQPPlanner`) sweeps the candidates; these functions make that
sweep cheaper without giving up its global optimum over the grid, and refine it off the grid:

* :func:`certify_free` — the QP with every inequality relaxed is a lower bound of every
  candidate, :math:`J_{\text{free}} \le J(j)`; where its optimum keeps some candidate's
  inequalities at every node, that bound is attained: it is the global optimum.
* :func:`seed_switches` and :func:`pruned_switches` — dropping one of a candidate's two sets
  of inequalities gives the relaxations :math:`R_{\text{pre}}(j) \le J(j)` (first half-plane
  only, nondecreasing in ``j``) and :math:`R_{\text{suf}}(j) \le J(j)` (second only,
  nonincreasing); with :math:`B` the best cost found, every ``j`` with
  :math:`R_{\text{pre}}(j) > B` or :math:`R_{\text{suf}}(j) > B` is skipped exactly.
* :func:`refine_crossings` — per vehicle, a bounded scalar search of :math:`\tau_i` within one
  step of the grid's crossing interval, on grids aligned with :math:`\tau_i` (the node at
  :math:`\tau_i` lies in both half-planes, as the continuous constraint requires).

Each takes the planner's one-candidate solve as a callable, so the counting of solves stays
with the planner.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import optimize

from iamp.core import status as st
from iamp.core.problem import Problem

from .check import Candidate, FloatArray
from .data import AvoidData

#: ``(first, second, last node in first, first node in second)`` of one vehicle.
Phase = tuple[int, int, int, int]
#: Solve one candidate (a phase per vehicle; no phase: every inequality relaxed).
SolveFn = Callable[[Sequence[Phase]], Candidate]
#: Solve on the grid aligned with crossing times ``τ`` and half-plane orders; ``None`` when the
#: times cannot be aligned.
SolveTimesFn = Callable[[Problem, FloatArray, Sequence[tuple[int, int]]], tuple[AvoidData, Candidate] | None]

__all__ = ["Phase", "SolveFn", "SolveTimesFn", "certify_free", "pruned_switches", "refine_crossings",
           "seed_switches"]


def seed_switches(data: AvoidData, solve: SolveFn, first: int) -> list[int]:
    """The switches around the free optimum's own crossing (solved first when pruning)."""
    N = data.N
    free = solve([])
    if free.status != st.OPTIMAL:
        return [N // 2]
    X, _ = data.unpack(free.z)
    k = data.interior
    in_first = data.planes[0][first].margin(data.t_nodes[k], X[k, 2 * first]) >= 0
    out = np.flatnonzero(~in_first)
    j0 = int(k[out[0]]) - 1 if out.size else N - 1
    return sorted({min(max(j, 0), N - 1) for j in (j0 - 1, j0, j0 + 1)})


def pruned_switches(data: AvoidData, solve: SolveFn, first: int, second: int, seeds: list[int],
                    bound: float) -> list[int]:
    r"""One vehicle, one order: the switches ``j`` still to solve after pruning, exactly.

    Candidate ``j`` imposes the first half-plane at nodes ``k <= j`` and the second at
    ``k >= j + 1``; dropping either set gives the relaxations ``R_pre(j)`` (first only,
    nondecreasing in ``j``) and ``R_suf(j)`` (second only, nonincreasing), both lower bounds
    of its cost.  With ``B`` = ``bound`` the best cost found so far (the ``seeds`` around
    the free optimum's crossing are solved first), bisection finds the smallest ``j_hi``
    with ``R_pre(j_hi) > B`` and the largest ``j_lo`` with ``R_suf(j_lo) > B``: every
    ``j >= j_hi`` or ``<= j_lo`` costs more than ``B``, so only ``j_lo < j < j_hi`` remain
    and the search stays global over the grid.
    """
    N = data.N
    if not np.isfinite(bound):
        return [j for j in range(N) if j not in seeds]
    limit = bound * (1 + 1e-9) + 1e-12

    def relax(phases: Phase) -> float:
        r = solve([phases])
        return r.cost if r.status == st.OPTIMAL else np.inf

    hi_j, a, b = N, max(seeds), N - 1  # smallest j >= max(seeds) with R_pre(j) > B (N: none)
    while a <= b:
        mid = (a + b) // 2
        if relax((first, second, mid, N)) > limit:
            hi_j, b = mid, mid - 1
        else:
            a = mid + 1
    lo_cut, a, b = -1, 0, min(seeds)  # largest j <= min(seeds) with R_suf(j) > B (-1: none)
    while a <= b:
        mid = (a + b) // 2
        if relax((first, second, 0, mid + 1)) > limit:
            lo_cut, a = mid, mid + 1
        else:
            b = mid - 1
    return [j for j in range(lo_cut + 1, hi_j) if j not in seeds]


def certify_free(data: AvoidData, solve: SolveFn, orders: Sequence[Sequence[tuple[int, int]]]
                 ) -> tuple[Candidate, list[list[int]]] | None:
    """Solve with every inequality relaxed; if that optimum (a lower bound of every
    candidate) keeps some candidate's inequalities at the nodes, it is the global optimum.
    Returns it with the chosen switches and, per vehicle, the range of valid switch nodes."""
    free = solve([])
    if free.status != st.OPTIMAL:
        return None
    X, _ = data.unpack(free.z)
    k = data.interior
    phases, ranges = [], []
    for pair, vehicle_orders in zip(data.planes, orders):
        ok = [pair[a].margin(data.t_nodes[k], X[k, 2 * a]) >= -1e-9 for a in (0, 1)]
        found = None
        for f, s2 in vehicle_orders:
            bad_f, bad_s = k[~ok[f]], k[~ok[s2]]
            j_max = int(bad_f[0]) - 1 if bad_f.size else data.N - 1
            j_min = int(bad_s[-1]) if bad_s.size else 0
            if j_min <= j_max:
                found = ((f, s2, j_min, j_min + 1), [j_min, j_max])
                break
        if found is None:
            return None
        phases.append(found[0])
        ranges.append(found[1])
    on = data.imposed(phases)
    return Candidate(tuple(phases), free.status, free.cost, free.z, free.y, on, free.sol), ranges


def refine_crossings(problem: Problem, seed: Candidate, steps: int,
                     solve_times: SolveTimesFn) -> tuple[AvoidData, Candidate, FloatArray]:
    """Per vehicle, a bounded scalar search of ``τ_i`` on grids aligned with ``τ``, from the
    grid's best candidate ``seed`` (``steps`` intervals); twice over the vehicles for ``m > 1``."""
    N, tf = int(steps), problem.tf
    h = tf / N
    taus = np.array([(p[2] + 0.5) * h for p in seed.phases])
    cache: dict[tuple[float, ...], tuple[AvoidData, Candidate]] = {}

    orders = [(p[0], p[1]) for p in seed.phases]

    def solve_at(t: FloatArray) -> tuple[AvoidData, Candidate] | None:
        key = tuple(float(x) for x in t)
        if key not in cache:
            out = solve_times(problem, t, orders)
            if out is None:
                return None
            cache[key] = out
        return cache[key]

    for _ in range(2 if problem.m > 1 else 1):
        for i in range(problem.m):
            lo = max(seed.phases[i][2] * h - h, 1e-6 * tf)
            hi = min((seed.phases[i][2] + 1) * h + h, tf * (1 - 1e-6))

            def f(x: float, i: int = i) -> float:
                t = taus.copy()
                t[i] = x
                out = solve_at(t)
                return out[1].cost if out is not None and out[1].status == st.OPTIMAL else np.inf

            with np.errstate(invalid="ignore"):  # inf at a failed trial: Brent falls back to golden section
                res = optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7 * tf})
            if np.isfinite(res.fun) and res.fun <= f(float(taus[i])):
                taus[i] = float(res.x)
    out = solve_at(taus)
    if out is None:  # pragma: no cover - the seed's own times are always valid
        raise RuntimeError("refine lost its seed")
    return out[0], out[1], taus
