r"""``iamp bench``: the bounded avoidance plan (SPEC §14, issue 19) and its CasADi + IPOPT peer.

Problem: :func:`overtake_problem` — the ego overtakes a vehicle in the target lane, whose
safety box the free optimum would cut (the avoidance rows bind), under the passenger car's
limits (:data:`iamp.core.physical.PASSENGER_CAR`; its lateral bound binds too); one vehicle,
FOH, ``N = 50``, ``--safety continuous``.

Measured, per backend (OSQP, Clarabel, PIQP), medians of repeats:

* ``plan_s`` — a whole :class:`~iamp.planners.avoid.planner.AvoidQPPlanner` plan: the branch and
  bound over the crossing time (every QP built and solved), the KKT check, the exact-roots
  safety report;
* ``qp_s`` — ONE QP at the plan's crossing time: Bernstein rows, limit rows, solver set-up and
  solve (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.solve`); ``qp_solve_call_s``
  the solver's ``solve()`` call alone.

The peer is the same fixed-crossing-time QP (the identical ``P``, equality and inequality rows)
written in CasADi ``Opti`` and solved by IPOPT (``ipopt.tol = 1e-10``): ``casadi_solve_s`` is
its ``solve()`` from a zero start on the built problem (the build is timed apart), and its
cost is reported beside iamp's.  A whole plan of the peer would add the crossing-time search
IPOPT cannot do (the problem is not smooth in the crossing time): the ratio compares one QP to
one QP.
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from functools import partial
from typing import Any, NotRequired, TypedDict

import numpy as np
import scipy.sparse as sp

from iamp.comparison.timing import StatsJSON, measure
from iamp.core.plan import Plan
from iamp.planners.avoid.diagnostics import AvoidDiagnostics
from iamp.planners.examples import overtake_problem

STEPS = 50
SOLVERS = ("osqp", "clarabel", "piqp")
#: Issue 19's target for the whole bounded plan on the fastest backend.
TARGET_PLAN_S = 2e-3


class BackendRow(TypedDict):
    """One backend of :func:`bench_avoid_bounded`: the whole plan, then one QP at its crossing time
    (``plan_s`` ``None`` and an ``error`` when the backend failed)."""

    plan_s: float | None
    plan_stats: NotRequired[StatsJSON]
    status: NotRequired[str]
    cost: NotRequired[float | None]
    n_solves: NotRequired[int | None]
    error: NotRequired[str]
    qp_s: NotRequired[float]
    qp_cost: NotRequired[float]
    qp_status: NotRequired[str]


class CasadiQP(TypedDict):
    """IPOPT on the same QP (:func:`_casadi_qp`)."""

    build_s: float
    solve_s: float
    cost: float
    iterations: int
    return_status: str
    variables: int
    constraints: int


class PeerError(TypedDict):
    """An optional peer that failed."""

    error: str


class AvoidBounded(TypedDict):
    """:func:`bench_avoid_bounded`'s numbers (``iamp bench``'s ``avoid_bounded``)."""

    problem: str
    steps: int
    hold: str
    safety: str
    backends: dict[str, BackendRow]
    target_plan_s: float
    note: NotRequired[str]
    crossing_spec: NotRequired[list[list[float]]]
    fastest_backend: NotRequired[str]
    plan_fastest_s: NotRequired[float]
    target_met: NotRequired[bool]
    qp_fastest_backend: NotRequired[str]
    qp_fastest_s: NotRequired[float]
    casadi_ipopt: NotRequired[CasadiQP | PeerError | None]
    ratios: NotRequired[dict[str, float]]


def _spec_of(plan: Plan) -> tuple[tuple[int, int, float, float], ...]:
    from iamp.planners.avoid.check import AXIS_NAMES

    return tuple((AXIS_NAMES.index(v["first"]), AXIS_NAMES.index(v["second"]), float(v["crossing_time"]),
                  float(v["crossing_time"])) for v in (_avoid_diagnostics(plan).avoidance or {})["vehicles"])


def _casadi_qp(P_upper: sp.spmatrix, A: sp.spmatrix, n_eq: int, rhs: np.ndarray, repeats: int) -> CasadiQP:
    """IPOPT on ``min ½ zᵀPz`` s.t. ``A[:n_eq] z = rhs[:n_eq]``, ``A[n_eq:] z <= rhs[n_eq:]``."""
    import casadi as ca

    def dm(M: sp.spmatrix) -> Any:  # a casadi.DM (its stubs type mtimes by overloads)
        C = sp.csc_matrix(M)
        return ca.DM(ca.Sparsity(C.shape[0], C.shape[1], C.indptr.tolist(), C.indices.tolist()), C.data.tolist())

    P = sp.csc_matrix(P_upper)
    P_full = P + sp.triu(P, 1).T
    t0 = time.perf_counter()
    opti = ca.Opti()
    z = opti.variable(P.shape[0])
    opti.minimize(0.5 * ca.mtimes([z.T, dm(P_full), z]))
    opti.subject_to(ca.mtimes(dm(A[:n_eq]), z) == ca.DM(rhs[:n_eq]))
    opti.subject_to(ca.mtimes(dm(A[n_eq:]), z) <= ca.DM(rhs[n_eq:]))
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "tol": 1e-10})
    build = time.perf_counter() - t0
    times, sol = [], None
    for _ in range(max(1, repeats)):
        opti.set_initial(z, np.zeros(P.shape[0]))
        t0 = time.perf_counter()
        sol = opti.solve()
        times.append(time.perf_counter() - t0)
    assert sol is not None
    return {"build_s": build, "solve_s": float(statistics.median(times)), "cost": float(sol.value(opti.f)),
            "iterations": int(sol.stats()["iter_count"]), "return_status": str(sol.stats()["return_status"]),
            "variables": int(P.shape[0]), "constraints": int(A.shape[0])}


def bench_avoid_bounded(repeats: int = 7, budget_s: float = 3.0) -> AvoidBounded:
    """The bounded avoidance numbers (module docstring); never raises for a missing backend.

    Each measurement stops adding repeats once their sum exceeds ``budget_s`` (a whole plan can
    take seconds; then one call, without warm-up, is the measurement)."""
    from iamp.planners.avoid.continuous import ContinuousAvoidQP
    from iamp.planners.avoid.planner import AvoidQPPlanner

    prob = overtake_problem()
    out: AvoidBounded = {"problem": "overtake (binding, passenger car limits)", "steps": STEPS, "hold": "foh",
                           "safety": "continuous", "backends": {}, "target_plan_s": TARGET_PLAN_S}
    spec = None
    for s in SOLVERS:
        try:
            planner = AvoidQPPlanner(steps=STEPS, hold="foh", solver=s)
            stats, plan = measure(partial(planner.plan, prob), repeats=repeats, warmup=1, budget_s=budget_s)
            assert plan is not None
            row: BackendRow = {"plan_s": stats.median, "plan_stats": stats.to_dict(), "status": str(plan.status),
                                   "cost": plan.cost, "n_solves": _avoid_diagnostics(plan).n_solves}
            if plan.status == "optimal" and spec is None:
                spec = _spec_of(plan)
            out["backends"][s] = row
        except Exception as exc:  # an optional backend: report, never fail the bench
            out["backends"][s] = {"plan_s": None, "error": f"{type(exc).__name__}: {exc}"}
    if spec is None:
        out["note"] = "no backend planned 'optimal': no fixed-crossing-time QP timed"
        return out
    out["crossing_spec"] = [list(x) for x in spec]
    qp_data: tuple[sp.spmatrix, sp.spmatrix, int, np.ndarray] | None = None
    for s in SOLVERS:
        row = out["backends"][s]
        if row.get("plan_s") is None:
            continue
        qp = ContinuousAvoidQP(prob, STEPS, "foh", s)
        stats, sol = measure(partial(qp.solve, spec), repeats=repeats, warmup=1, budget_s=budget_s)
        assert sol is not None
        row["qp_s"] = stats.median
        row["qp_cost"] = sol.cost
        row["qp_status"] = str(sol.status)
        qp_data = (qp.data.P, sol.A, qp.data.n_eq, sol.u)
    ok = {s: p for s, r in out["backends"].items() if (p := r.get("plan_s")) and r.get("status") == "optimal"}
    if ok:
        best = min(ok, key=lambda k: ok[k])
        out["fastest_backend"] = best
        out["plan_fastest_s"] = ok[best]
        out["target_met"] = bool(ok[best] <= TARGET_PLAN_S)
        qps = {s: q for s, r in out["backends"].items() if (q := r.get("qp_s"))}
        out["qp_fastest_backend"] = min(qps, key=lambda k: qps[k])
        out["qp_fastest_s"] = qps[out["qp_fastest_backend"]]
    if importlib.util.find_spec("casadi") is None:
        out["casadi_ipopt"] = None
        out["note"] = "casadi not installed: the CasADi+IPOPT peer is skipped (pip install casadi)"
        return out
    try:
        assert qp_data is not None  # a backend planned 'optimal' (spec), so its QP was timed
        P, A, n_eq, rhs = qp_data
        cas = _casadi_qp(P, A, n_eq, rhs, max(1, repeats // 2))
        out["casadi_ipopt"] = cas
        if "qp_fastest_s" in out:
            out["ratios"] = {"casadi_ipopt_qp_to_iamp_qp": cas["solve_s"] / out["qp_fastest_s"],
                             "casadi_ipopt_qp_to_iamp_plan": cas["solve_s"] / out["plan_fastest_s"]}
    except Exception as exc:  # an optional peer: report, never fail the bench
        out["casadi_ipopt"] = {"error": f"{type(exc).__name__}: {exc}"}
    return out


def _avoid_diagnostics(plan: Plan) -> AvoidDiagnostics:
    """The diagnostics of an avoidance plan (``TypeError`` for any other plan)."""
    if not isinstance(plan.diagnostics, AvoidDiagnostics):
        raise TypeError(f"not an avoidance plan: {type(plan.diagnostics).__name__}")
    return plan.diagnostics
