r"""``iamp bench``: the planners a car can use, with its limits imposed (issue 32 item 3).

Four cases, each planned by the registry's planner exactly as ``iamp plan`` does:

* ``bounded_pmp_one_vehicle_certified`` — the PMP on ``paper-1`` with the passenger car's input
  box (``ax`` [-6, 3], ``ay`` [-2, 2]; the unbounded plan reaches 4.7 m/s²): the saturated PMP of
  SPEC §14 with its global certificate (status ``optimal`` required);
* ``bounded_pmp_three_vehicles`` — the PMP on :func:`iamp.planners.examples.random_problem`
  ``(0, m=3)`` with the same box (``local`` allowed; on this problem the certified answer is
  ``infeasible``: no contact times admit a plan within the box, which the planner must prove);
* ``bounded_pmp_three_vehicles_feasible`` — the PMP on ``random_problem(15, m=3)`` with a box at
  85 % of its unbounded plan's peaks (:func:`iamp.planners.examples.boxed_problem`: active, and a
  plan within it exists; ``local`` allowed);
* ``avoid_limits_one_vehicle_<backend>`` — the continuous-time avoidance of SPEC §14 (FOH,
  ``N = 50``, ``--safety continuous``) on :func:`~iamp.planners.examples.overtake_problem`
  under :data:`~iamp.core.physical.PASSENGER_CAR`, per backend (OSQP, Clarabel, PIQP; status
  ``optimal`` required);
* ``avoid_limits_three_vehicles_<backend>`` — the same on
  :func:`~iamp.planners.examples.overtake_three_problem` (``optimal`` required).

Each case is planned ``repeats`` times after one warm-up (fewer once the samples exceed
``budget_s``; a single call slower than the budget is the one sample) by one planner, as the
closed loop plans; before each avoidance plan the planner forgets the half-planes' rows it kept
(``forget_vehicles``: they depend on the vehicles' motion, which moves between a loop's plans),
so a sample times a new problem on a known grid, not a repeat.  Every call records
its wall time (:func:`time.perf_counter`) and its process CPU time (:func:`time.process_time`):
the machines here are shared by several jobs, so the wall time depends on their load and the
CPU time much less.  Reported: both medians, the status, the cost and (avoidance) the number of
QP solves; the target of each case (:data:`TARGETS_S`: 2 ms, 20 ms, 5 ms, 50 ms) with
``met_cpu`` and ``met_wall`` (the median within the target **and** the status allowed), and
the ratios to two references measured in the same run with the same clocks (CPU to CPU, wall
to wall): the unbounded one-vehicle PMP plan (``paper-1``, no limits) and one KKT solve of the
equality QP (``paper-1``, FOH, ``N = 100``, the ``kkt`` backend at the PMP's contact node: value
update, solve and verification), each the median of per-call times over inner loops.
What is planned is deterministic (budgets count work, SPEC §17); only the times vary, and the
statuses and costs of the repeats are checked to be identical (``deterministic``).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from functools import partial
from typing import NotRequired, TypedDict, cast

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners import registry
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.examples import overtake_problem, overtake_three_problem

__all__ = ["ALLOWED", "SOLVERS", "STEPS", "TARGETS_S", "LimitsBench", "LimitsRow", "LimitsTarget",
           "bench_limits", "bounded_pmp_problems", "references", "target_of"]

STEPS = 50
SOLVERS = ("osqp", "clarabel", "piqp")
#: Issue 32's targets [s] per case family.
TARGETS_S: dict[str, float] = {
    "bounded_pmp_one_vehicle_certified": 2e-3,
    "bounded_pmp_three_vehicles": 20e-3,
    "bounded_pmp_three_vehicles_feasible": 20e-3,
    "avoid_limits_one_vehicle": 5e-3,
    "avoid_limits_three_vehicles": 50e-3,
}
#: The statuses a case must end in for its target to count as met.
ALLOWED: dict[str, tuple[str, ...]] = {
    "bounded_pmp_one_vehicle_certified": ("optimal",),
    "bounded_pmp_three_vehicles": ("optimal", "local", "infeasible"),
    "bounded_pmp_three_vehicles_feasible": ("optimal", "local"),
    "avoid_limits_one_vehicle": ("optimal",),
    "avoid_limits_three_vehicles": ("optimal",),
}
#: The input box of the bounded PMP cases (the passenger car's; the PMP imposes ``ax``, ``ay``).
BOX = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)


class LimitsRow(TypedDict):
    """One case: its family (a key of :data:`TARGETS_S`), problem, planner and backend, the
    medians [s] (``None`` and an ``error`` when the planner raised), the repeats, status, cost."""

    family: str
    problem: str
    planner: str
    solver: str | None
    cpu_s: float | None
    wall_s: float | None
    repeats: int
    status: str | None
    cost: float | None
    n_solves: int | None
    deterministic: bool
    error: NotRequired[str]


class LimitsTarget(TypedDict):
    """A case against its target: the CPU and wall medians, the target, the status test and the
    verdicts (a median within the target and an allowed status)."""

    cpu_s: float | None
    wall_s: float | None
    target_s: float
    status: str | None
    status_ok: bool
    met_cpu: bool
    met_wall: bool


class LimitsBench(TypedDict):
    """:func:`bench_limits`'s object (``iamp bench``'s ``planning_with_limits``)."""

    steps: int
    rows: dict[str, LimitsRow]
    targets: dict[str, LimitsTarget]
    same_optimum: dict[str, bool]
    references: dict[str, dict[str, float]]
    ratios: dict[str, dict[str, float | None]]


def bounded_pmp_problems() -> dict[str, Problem]:
    """The two bounded PMP problems (module docstring), by case name."""
    from iamp.planners.examples import boxed_problem, paper_problem, random_problem

    return {"bounded_pmp_one_vehicle_certified": paper_problem(1).with_limits(BOX),
            "bounded_pmp_three_vehicles": random_problem(0, m=3).with_limits(BOX),
            "bounded_pmp_three_vehicles_feasible": boxed_problem(random_problem(15, m=3), 0.85)}


def _timed(fn: Callable[[], Plan], repeats: int, budget_s: float,
           before: Callable[[], object] | None = None) -> tuple[list[float], list[float], list[Plan]]:
    """Wall and CPU time of each call after one warm-up (skipped when it alone exceeds the budget:
    it is then the one sample), stopping once the wall times exceed ``budget_s``; ``before`` is
    called untimed ahead of every call (the avoidance: forget the half-planes' rows)."""
    if before is not None:
        before()
    w0, c0 = time.perf_counter(), time.process_time()
    first = fn()
    w, c = time.perf_counter() - w0, time.process_time() - c0
    if w > budget_s:
        return [w], [c], [first]
    walls: list[float] = []
    cpus: list[float] = []
    plans: list[Plan] = []
    for _ in range(max(1, repeats)):
        if before is not None:
            before()
        w0, c0 = time.perf_counter(), time.process_time()
        plans.append(fn())
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
        if sum(walls) > budget_s:
            break
    return walls, cpus, plans


def _row(family: str, problem: Problem, planner: str, solver: str | None, fn: Callable[[], Plan], repeats: int,
         budget_s: float, before: Callable[[], object] | None = None) -> LimitsRow:
    row: LimitsRow = {"family": family, "problem": problem.name, "planner": planner, "solver": solver,
                      "cpu_s": None, "wall_s": None, "repeats": 0, "status": None, "cost": None, "n_solves": None,
                      "deterministic": True}
    try:
        walls, cpus, plans = _timed(fn, repeats, budget_s, before)
    except Exception as exc:  # report, never fail the bench
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    last = plans[-1]
    n_solves = last.info.get("n_solves")
    row["cpu_s"] = float(statistics.median(cpus))
    row["wall_s"] = float(statistics.median(walls))
    row["repeats"] = len(walls)
    row["status"] = str(last.status)
    row["cost"] = None if last.cost is None else float(last.cost)
    row["n_solves"] = None if n_solves is None else int(n_solves)
    row["deterministic"] = len({(str(p.status), p.cost) for p in plans}) == 1
    return row


def _same_optimum(rows: list[LimitsRow], rel: float = 1e-6) -> bool:
    """Every backend ``optimal`` and their costs equal to ``rel`` (relative)."""
    costs = [r["cost"] for r in rows if r["status"] == "optimal" and r["cost"] is not None]
    if len(costs) != len(rows) or not costs:
        return False
    lo, hi = min(costs), max(costs)
    return (hi - lo) <= rel * max(abs(lo), 1e-12)


def target_of(row: LimitsRow) -> LimitsTarget:
    """The row against the target of its family (:data:`TARGETS_S`, :data:`ALLOWED`).

    Parameters
    ----------
    row : LimitsRow
        A case of :func:`bench_limits`.

    Returns
    -------
    LimitsTarget
        The medians, the target, whether the status is allowed, and the two verdicts.
    """
    fam = row["family"]
    target = TARGETS_S[fam]
    ok = row["status"] in ALLOWED[fam]
    cpu, wall = row["cpu_s"], row["wall_s"]
    return {"cpu_s": cpu, "wall_s": wall, "target_s": target, "status": row["status"], "status_ok": ok,
            "met_cpu": bool(ok and cpu is not None and cpu <= target),
            "met_wall": bool(ok and wall is not None and wall <= target)}


def bench_limits(repeats: int = 7, budget_s: float = 3.0, solvers: tuple[str, ...] = SOLVERS) -> LimitsBench:
    """Time the cases (module docstring).

    Parameters
    ----------
    repeats : int
        Timed plans per case after the warm-up (fewer once their wall times exceed ``budget_s``).
    budget_s : float
        Wall-time budget of the samples of one case [s] (a bench setting, never a planner's).
    solvers : tuple of str
        The avoidance backends (an uninstalled one is reported with an ``error``).

    Returns
    -------
    LimitsBench
        ``rows`` (one per case), ``targets`` (one per case) and ``same_optimum`` (per vehicle
        count: every backend ``optimal`` at the same cost to 1e-6).
    """
    rows: dict[str, LimitsRow] = {}
    pmp = registry.make_planner("pmp", diagnostics=False)
    for name, prob in bounded_pmp_problems().items():
        rows[name] = _row(name, prob, "pmp", None, partial(pmp.plan, prob), repeats, budget_s)
    for fam, prob in (("avoid_limits_one_vehicle", overtake_problem()),
                      ("avoid_limits_three_vehicles", overtake_three_problem())):
        for s in solvers:
            try:
                planner = registry.make_planner("qp-avoid", steps=STEPS, hold="foh", solver=s, safety="continuous")
            except Exception as exc:  # a backend not installed: say so, never fail the bench
                rows[f"{fam}_{s}"] = {"family": fam, "problem": prob.name, "planner": "qp-avoid", "solver": s,
                                      "cpu_s": None, "wall_s": None, "repeats": 0, "status": None, "cost": None,
                                      "n_solves": None, "deterministic": True,
                                      "error": f"{type(exc).__name__}: {exc}"}
                continue
            rows[f"{fam}_{s}"] = _row(fam, prob, "qp-avoid", s, partial(planner.plan, prob), repeats, budget_s,
                                      before=cast(AvoidQPPlanner, planner).forget_vehicles)
    same = {fam: _same_optimum([r for r in rows.values() if r["family"] == fam])
            for fam in ("avoid_limits_one_vehicle", "avoid_limits_three_vehicles")}
    refs = references(repeats)
    return {"steps": STEPS, "rows": rows, "targets": {k: target_of(r) for k, r in rows.items()},
            "same_optimum": same, "references": refs, "ratios": ratios(rows, refs)}


def _per_call(fn: Callable[[], object], repeats: int, inner: int) -> dict[str, float]:
    """Median per-call wall and CPU time [s] of ``fn`` over ``repeats`` inner loops of ``inner``
    calls, after one warm-up call."""
    fn()
    walls, cpus = [], []
    for _ in range(max(1, repeats)):
        w0, c0 = time.perf_counter(), time.process_time()
        for _ in range(inner):
            fn()
        walls.append((time.perf_counter() - w0) / inner)
        cpus.append((time.process_time() - c0) / inner)
    return {"wall_s": float(statistics.median(walls)), "cpu_s": float(statistics.median(cpus))}


def references(repeats: int = 7) -> dict[str, dict[str, float]]:
    """The two references of the ratios (module docstring): ``pmp_plan`` and ``kkt_solve``.

    Parameters
    ----------
    repeats : int
        Inner loops per reference.

    Returns
    -------
    dict
        Per reference, ``wall_s`` and ``cpu_s`` (medians of the per-call times).
    """
    from iamp.planners.examples import paper_problem
    from iamp.planners.qp.core import DiscretisedQP

    one = paper_problem(1)
    pmp = registry.make_planner("pmp", diagnostics=False)
    t1 = float(pmp.plan(one).contact_times[0])
    qp = DiscretisedQP(one, 100, "foh", "kkt")
    node = (min(max(int(round(t1 / float(one.tf) * 100)), 1), 99),)
    return {"pmp_plan": _per_call(lambda: pmp.plan(one), repeats, 200),
            "kkt_solve": _per_call(lambda: qp.solve_nodes(node), repeats, 200)}


def ratios(rows: dict[str, LimitsRow], refs: dict[str, dict[str, float]]) -> dict[str, dict[str, float | None]]:
    """Each case over each reference, CPU to CPU and wall to wall.

    Parameters
    ----------
    rows : dict
        The cases of :func:`bench_limits`.
    refs : dict
        :func:`references`.

    Returns
    -------
    dict
        Per case: ``cpu_to_pmp_plan``, ``wall_to_pmp_plan``, ``cpu_to_kkt_solve``,
        ``wall_to_kkt_solve`` (``None`` where the case has no time).
    """
    out: dict[str, dict[str, float | None]] = {}
    for k, r in rows.items():
        out[k] = {}
        for ref in ("pmp_plan", "kkt_solve"):
            for clock in ("cpu", "wall"):
                v = r["cpu_s"] if clock == "cpu" else r["wall_s"]
                den = refs[ref][f"{clock}_s"]
                out[k][f"{clock}_to_{ref}"] = v / den if v is not None and den > 0 else None
    return out
