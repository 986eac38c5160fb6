r"""``iamp bench``: iamp's speed numbers, its peers and limits, and their ratios, in ONE run.

Everything is measured in the same process, one after the other, so the ratios compare
numbers taken under the same machine load.  Numbers are medians of individual
:func:`time.perf_counter` samples after a warm-up (:mod:`iamp.comparison.timing`).  The spread
of every measurement (IQR/median) is checked: above :data:`BUSY_SPREAD` the output warns that
the machine was probably busy (the 2-core machines here are shared).

What is measured (one vehicle: ``paper-1-poly``; two: ``two-vehicle``; FOH, ``N = 100``):

* **PMP** — from :func:`iamp.comparison.bench.pmp.bench_pmp` when that module exists (its
  medians of a whole plan, one and two vehicles, the batch API's plans per second, and the
  compiled limit: ``pmp_to_compiled_limit`` = PMP plan / compiled-kernel plan, one vehicle),
  otherwise measured here by a fallback (whole plans and the batch API).
* **QP per candidate** (``qp_native_solve_s``) — for every backend of the registry
  (:mod:`iamp.planners.qp.backends`): the value update plus the backend's ``solve()`` for each
  candidate of a full sweep, in sweep order (OSQP warm-starts from the neighbouring node, the
  direct ``kkt`` backend re-uses its factorisation, as in a real sweep); the candidate's whole
  wall time (with verification and unpacking) is reported beside it.
* **QP grid sweep** (``qp_grid_sweep_s``) — a complete :meth:`QPPlanner.plan` (build, sweep,
  verification, certification) on each backend (``native_*``), and through the cvxpy
  cross-check (:mod:`iamp.comparison.cvxpy_qp`; ``osqp``, ``clarabel``: model build and compile
  included, since a user of that formulation pays for them).
* **Avoidance QP** (``avoid_grid_sweep_s``) — :class:`iamp.planners.avoid.planner.AvoidQPPlanner`'s
  plan, if that module exists.
* **Bounded avoidance** (``avoid_bounded``) — :mod:`iamp.comparison.bench.avoid`: the
  continuous-time avoidance plan of one binding vehicle under the passenger car's limits,
  ``N = 50``, on OSQP, Clarabel and PIQP (whole plan and one QP at its crossing time), and
  the same QP in CasADi + IPOPT (issue 19's target: the whole plan <= 2 ms on the fastest
  backend).
* **CasADi + IPOPT** — the free-contact-time problem written in ``Opti`` the way users type
  it (:mod:`.bench_casadi`: build, cold and warm solve, its discretised ``t_1`` and ``J``);
  skipped (with a note) unless ``casadi`` is installed.  ``casadi_ipopt_bounded``: the same
  with a passenger car's input box on every ``u_k``, the peer of the bounded PMP
  (``pmp_plan_s.one_vehicle_bounded``, :mod:`iamp.planners.pmp.bounded`).
* **Leader-aware prediction** (``prediction_leader_20_s``) — one batched prediction of 20
  neighbours with leaders (:mod:`.prediction`; issue 23's target 2 ms).
* **Planning with the limits imposed** (``planning_with_limits``, issue 32) —
  :mod:`iamp.comparison.bench.limits`: the certified bounded PMP (one vehicle), the bounded PMP
  with three vehicles, the continuous-time avoidance with limits (``N = 50``, one and three
  vehicles, OSQP, Clarabel, PIQP), CPU and wall medians, their targets (``targets``, with
  ``_cpu`` and ``_wall`` verdicts) and their ratios to the unbounded one-vehicle PMP plan and to
  one KKT solve of the same run (``ratios``).
* **Closed loop** (``loop_episode_s``, not with ``--quick``, needs SUMO) — one whole 60 s
  ``merge`` episode in dense traffic per iamp planner, planned with the car's limits
  (:mod:`.loop`; target ``loop_episode_<planner>_s`` <= 1 s).
* **OSQP tuning** (not with ``--quick``) — what each OSQP setting buys on the equality QP:
  verified candidates, polish successes, iterations, recomputed KKT residuals, time.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import platform
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import NotRequired, TypedDict

import numpy as np

from iamp import _blas
from iamp.comparison.timing import StatsJSON, TimingStats, VersionsJSON, measure, summarize, versions
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.qp.backends import BACKENDS, ITERATIVE
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.registry import Planner

from .avoid import AvoidBounded
from .casadi import CasadiFreeTime
from .limits import LimitsBench
from .loop import REPEATS, LoopBench
from .prediction import LeaderPredictionBench, PredictionBench

#: IQR/median above which a measurement is flagged as taken on a busy machine.
BUSY_SPREAD = 0.5
STEPS = 100
BACKEND_NAMES = ("osqp", "clarabel", "piqp", "kkt")

#: Issue 14's targets (medians on this 2-core machine when quiet).
TARGETS: dict[str, tuple[str, float]] = {
    "pmp_plan_one_vehicle_s": ("<=", 25e-6),
    "pmp_plan_two_vehicles_s": ("<=", 0.3e-3),
    # issue 19: a bounded one-vehicle PMP plan (input box active, saturated law)
    "pmp_plan_one_vehicle_bounded_s": ("<=", 100e-6),
    "pmp_batch_plans_per_s": (">=", 200_000.0),
    "qp_native_solve_kkt_s": ("<=", 0.2e-3),
    "qp_native_solve_best_iterative_s": ("<=", 0.25e-3),
    "qp_native_solve_osqp_s": ("<=", 0.5e-3),
    "qp_grid_sweep_native_best_s": ("<=", 20e-3),
    "prediction_leader_20_s": ("<=", 2e-3),  # issue 23: 20 neighbours with leaders, batched
}


# --------------------------------------------------------------------------------------
# The records
# --------------------------------------------------------------------------------------


class PMPNumbers(TypedDict):
    """The PMP medians in the SPEC §5b keys (:func:`_pmp_numbers`)."""

    source: str
    bench_pmp: dict[str, float]
    pmp_plan_s: dict[str, float]
    pmp_batch_plans_per_s: float
    pmp_to_compiled_limit: NotRequired[float]
    pmp_two_vehicles_pure_to_compiled: NotRequired[float]
    pmp_bounded_pure_to_compiled: NotRequired[float]
    stats: NotRequired[dict[str, StatsJSON]]


@dataclass(frozen=True)
class CandidateTimes:
    """One backend's per-candidate times over full sweeps (:func:`_per_candidate`): update + solve
    (``backend``), the bare ``solve()`` call (``call``), the whole candidate (``wall``), the
    candidates of the last sweep not verified, and the backend's :meth:`describe`."""

    backend: TimingStats
    call: TimingStats
    wall: TimingStats
    failed: int
    describe: dict[str, object]


class CandidateJSON(TypedDict):
    """:class:`CandidateTimes` as ``qp_candidate`` reports it."""

    backend_s: StatsJSON
    solve_call_s: StatsJSON
    wall_s: StatsJSON
    failed: int
    backend: dict[str, object]


class AvoidSweep(TypedDict):
    """One backend's avoidance-QP plan (``median`` ``None`` and an ``error`` when it failed)."""

    median: float | None
    stats: NotRequired[StatsJSON]
    status: NotRequired[str]
    error: NotRequired[str]


class NoAvoidBounded(TypedDict):
    """``avoid_bounded`` when the bounded avoidance bench failed (a note says why)."""


class TuningRow(TypedDict):
    """What one OSQP setting buys (:func:`osqp_tuning`)."""

    settings: dict[str, float | int | bool]
    verified: int
    polished: int
    solver_solved: int
    candidates: int
    iterations_median: float
    iterations_max: int
    kkt_rel_median: float
    kkt_rel_max: float
    backend_s_median: float
    sweep_s: float


class Target(TypedDict):
    """A target of :data:`TARGETS` (and of the planning-with-limits and loop cases): the measured
    value against it (``None`` when the case has no time)."""

    value: float | None
    target: float
    op: str
    met: bool


class BenchMachine(TypedDict):
    """The machine of the run and its load before and after."""

    cpu_count: int | None
    platform: str
    machine: str
    python: str
    load_average_1min_before: float | None
    load_average_1min_after: float | None
    #: the CPU's model name (``/proc/cpuinfo``; None where unknown): numbers may differ in their
    #: last bits between CPUs where a library dispatches by CPU (``docs/spec.md``, "Determinism")
    cpu_model: NotRequired[str | None]
    #: numpy's AVX-512 loops active in the run (empty: its AVX2 or baseline loops, ``iamp._blas``)
    numpy_avx512: NotRequired[list[str]]
    #: the build of PIQP's bindings loaded in the run (``piqp_python_avx2`` on every CPU with AVX2,
    #: ``iamp._blas.pin_piqp``; None where PIQP did not run)
    piqp_build: NotRequired[str | None]


class BenchStats(TypedDict):
    """The statistics behind the medians."""

    qp_grid_sweep_native_s: dict[str, StatsJSON]
    qp_grid_sweep_cvxpy_s: dict[str, StatsJSON]
    pmp: dict[str, StatsJSON] | None
    avoid: dict[str, AvoidSweep] | None
    prediction_leader_20: LeaderPredictionBench
    prediction_ego_follower: PredictionBench


class BenchJSON(TypedDict):
    """The ``iamp bench --json`` object (SPEC §5b keys and more; :func:`run_bench`)."""

    pmp_plan_s: dict[str, float]
    pmp_batch_plans_per_s: float
    qp_native_solve_s: dict[str, float]
    qp_grid_sweep_s: dict[str, float]
    avoid_grid_sweep_s: dict[str, float | None] | None
    prediction_leader_20_s: float
    prediction_ego_follower_s: float
    loop_episode_s: dict[str, float] | None
    loop: LoopBench | None
    planning_with_limits: LimitsBench | None
    avoid_bounded: AvoidBounded | NoAvoidBounded
    ratios: dict[str, float | None]
    versions: VersionsJSON
    machine: BenchMachine
    warnings: list[str]
    quick: bool
    steps: int
    problem: str
    best_iterative_backend: str
    best_native_sweep: str
    qp_candidate: dict[str, CandidateJSON]
    stats: BenchStats
    pmp: dict[str, object]
    failed_sweep_candidates: dict[str, int]
    casadi_ipopt: CasadiFreeTime | None
    casadi_ipopt_bounded: CasadiFreeTime | None
    osqp_tuning: list[TuningRow]
    targets: dict[str, Target]
    missed: list[str]
    notes: list[str]


# --------------------------------------------------------------------------------------
# PMP
# --------------------------------------------------------------------------------------


def _pmp_numbers(quick: bool, notes: list[str]) -> PMPNumbers:
    """The PMP medians of :func:`iamp.comparison.bench.pmp.bench_pmp` in the SPEC §5b keys."""
    from .pmp import bench_pmp

    raw = dict(bench_pmp(3 if quick else 7))
    plan_s: dict[str, float] = {
        "one_vehicle": raw["one_vehicle"], "two_vehicles": raw["two_vehicles"],
        "two_vehicles_pure": raw["two_vehicles_pure"], "one_vehicle_bounded": raw["one_vehicle_bounded"],
        "one_vehicle_bounded_certified": raw["one_vehicle_bounded_certified"],
        "fixed_t_bounded": raw["fixed_t_bounded"],
        **{k: raw[k] for k in ("two_vehicles_compiled", "one_vehicle_bounded_pure", "one_vehicle_bounded_compiled",
                               "one_vehicle_bounded_certified_pure",
                               "one_vehicle_bounded_certified_compiled") if k in raw}}
    out: PMPNumbers = {"source": "iamp.comparison.bench.pmp.bench_pmp", "bench_pmp": raw,
                           "pmp_plan_s": plan_s, "pmp_batch_plans_per_s": raw["batch_plans_per_s"]}
    if raw.get("compiled_limit_one_vehicle"):
        out["pmp_to_compiled_limit"] = raw["one_vehicle"] / raw["compiled_limit_one_vehicle"]
    else:
        notes.append("numba missing (pip install 'iamp[fast]'): no compiled limit")
    if raw.get("one_vehicle_bounded_compiled"):
        out["pmp_bounded_pure_to_compiled"] = raw["one_vehicle_bounded_pure"] / raw["one_vehicle_bounded_compiled"]
    if raw.get("two_vehicles_compiled"):
        out["pmp_two_vehicles_pure_to_compiled"] = raw["two_vehicles_pure"] / raw["two_vehicles_compiled"]
    return out


# --------------------------------------------------------------------------------------
# QP
# --------------------------------------------------------------------------------------


def _per_candidate(problem: Problem, solver: str, repeats: int) -> CandidateTimes:
    """Update+solve, solve() call and whole-candidate times over full sweeps (first = warm-up)."""
    from iamp.planners.qp.core import DiscretisedQP

    backend, call, wall, failed = [], [], [], 0
    for rep in range(repeats + 1):
        qp = DiscretisedQP(problem, STEPS, "foh", solver)
        rs = [qp.solve_nodes(nodes) for nodes in qp.candidate_nodes()]
        if rep:
            backend += [r.backend_s for r in rs]
            call += [r.solve_call_s for r in rs]
            wall += [r.wall_time_s for r in rs]
        failed = sum(not r.ok for r in rs)
    describe: dict[str, object] = qp.backend.describe()
    if solver == "kkt":
        describe["bandwidth"] = int(getattr(qp.backend, "bandwidth", -1))
    return CandidateTimes(summarize(backend), summarize(call), summarize(wall), failed, describe)


def _sweep(fn: Callable[[], Plan], repeats: int) -> tuple[TimingStats, Plan]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        stats, res = measure(fn, repeats=repeats, warmup=1, budget_s=20.0)
    assert res is not None  # measure calls fn at least once
    return stats, res


def _plan_fn(planner: Planner, problem: Problem) -> Callable[[], Plan]:
    return lambda: planner.plan(problem)


#: The extra that installs each optional QP backend's package.
BACKEND_EXTRA = {"piqp": "solvers"}


def _installed_backends(notes: list[str]) -> tuple[str, ...]:
    """The backends of :data:`BACKEND_NAMES` whose package is installed; a note for each other one
    naming the extra that adds it (a core install has no PIQP: the bench runs without it)."""
    names = []
    for s in BACKEND_NAMES:
        cls = BACKENDS[s]
        if cls.distribution and cls.version() is None:
            extra = BACKEND_EXTRA.get(s, "bench")
            notes.append(f"{cls.distribution} missing (pip install 'iamp[{extra}]'): the {s} backend is not measured")
        else:
            names.append(s)
    return tuple(names)


def _avoid(problem: Problem, repeats: int, notes: list[str]) -> dict[str, AvoidSweep] | None:
    if importlib.util.find_spec("iamp.planners.avoid.planner") is None:
        notes.append("iamp.planners.avoid.planner not found: no avoidance-QP sweep measured")
        return None
    mod = importlib.import_module("iamp.planners.avoid.planner")
    out: dict[str, AvoidSweep] = {}
    for solver in ("osqp", "clarabel", "piqp"):
        if BACKENDS[solver].version() is None and BACKENDS[solver].distribution:
            continue  # not installed: _installed_backends has said which extra adds it
        try:
            planner = mod.AvoidQPPlanner(steps=STEPS, hold="foh", solver=solver)
            stats, res = _sweep(_plan_fn(planner, problem), repeats)
            out[solver] = {"median": stats.median, "stats": stats.to_dict(), "status": str(res.status)}
        except Exception as exc:  # an optional peer: report, never fail the bench
            out[solver] = {"median": None, "error": f"{type(exc).__name__}: {exc}"}
    return out


def _avoid_bounded(quick: bool, notes: list[str]) -> AvoidBounded | None:
    """:func:`iamp.comparison.bench.avoid.bench_avoid_bounded` (``None`` if it fails: the JSON has ``{}``)."""
    from .avoid import bench_avoid_bounded

    try:
        out = bench_avoid_bounded(3 if quick else 7, 1.0 if quick else 3.0)
    except Exception as exc:  # never fail the bench
        notes.append(f"bounded avoidance failed: {type(exc).__name__}: {exc}")
        return None
    if out.get("note"):
        notes.append(f"bounded avoidance: {out['note']}")
    return out


def _casadi(problem: Problem, quick: bool, notes: list[str], box: bool = False) -> CasadiFreeTime | None:
    """CasADi ``Opti`` + IPOPT on the free-contact-time problem (:mod:`.bench_casadi`;
    ``box``: with the input box of ``problem.limits``)."""
    if importlib.util.find_spec("casadi") is None:
        notes.append("casadi not installed: the CasADi+IPOPT peer is skipped (pip install casadi)")
        return None
    from .casadi import casadi_free_time

    try:
        return casadi_free_time(problem, STEPS, 2 if quick else 5, box=box)
    except Exception as exc:  # an optional peer: report, never fail the bench
        notes.append(f"CasADi+IPOPT peer failed: {type(exc).__name__}: {exc}")
        return None


def osqp_tuning(problem: Problem) -> list[TuningRow]:
    """What each OSQP setting buys on the equality QP (one FOH sweep, ``N = 100``, per row)."""
    from iamp.planners.qp.backends.osqp import _polish_key
    from iamp.planners.qp.core import DiscretisedQP

    rows: list[TuningRow] = []
    off: dict[str, float | int | bool] = {_polish_key(): False}
    # iamp's equality-QP default (ADMM near, the polish exact) with fewer refinements or no
    # polish, then OSQP's own ADMM settings (check every 25, over-relaxation 1.6, scaling 10)
    old_admm: dict[str, float | int | bool] = {"check_termination": 25, "alpha": 1.6, "scaling": 10}
    grid: list[dict[str, float | int | bool]] = [{}, {"polish_refine_iter": 3}, {"polish_refine_iter": 1}, off]
    grid += [{**old_admm, "eps_abs": e, "polish_refine_iter": k} for e in (1e-3, 1e-5) for k in (3, 10)]
    grid += [{**old_admm, "eps_abs": 1e-5, **off}, {**old_admm, "eps_abs": 1e-7, **off}]
    for s in grid:
        qp = DiscretisedQP(problem, STEPS, "foh", "osqp", s)
        t0 = time.perf_counter()
        rs = [qp.solve_nodes(n) for n in qp.candidate_nodes()]
        total = time.perf_counter() - t0
        kkt = [r.kkt.worst_rel()[1] if r.kkt is not None else np.inf for r in rs]
        rows.append({"settings": s, "verified": sum(r.ok for r in rs), "polished": sum(bool(r.polished) for r in rs),
                     "solver_solved": sum(r.solver_status == "optimal" for r in rs), "candidates": len(rs),
                     "iterations_median": float(np.median([r.iterations for r in rs])),
                     "iterations_max": int(max(r.iterations for r in rs)),
                     "kkt_rel_median": float(np.median(kkt)), "kkt_rel_max": float(np.max(kkt)),
                     "backend_s_median": float(np.median([r.backend_s for r in rs])), "sweep_s": total})
    return rows


# --------------------------------------------------------------------------------------
# the run
# --------------------------------------------------------------------------------------


def _loop(quick: bool, notes: list[str]) -> LoopBench | None:
    """Whole closed-loop episodes (:mod:`.loop`): not with ``--quick``, and only with SUMO."""
    if quick:
        notes.append("closed-loop episodes: skipped with --quick")
        return None
    if importlib.util.find_spec("libsumo") is None:
        notes.append("closed-loop episodes: skipped (needs iamp[sim])")
        return None
    from iamp.comparison.bench.loop import bench_loop

    return bench_loop(REPEATS)


def _limits(quick: bool, notes: list[str]) -> LimitsBench | None:
    """:func:`iamp.comparison.bench.limits.bench_limits` (``None`` and a note if it fails)."""
    from .limits import bench_limits

    try:
        return bench_limits(3 if quick else 7, 1.0 if quick else 3.0)
    except Exception as exc:  # never fail the bench
        notes.append(f"planning with limits failed: {type(exc).__name__}: {exc}")
        return None


def _busy(stats: dict[str, TimingStats]) -> list[str]:
    return [f"{k}: IQR/median = {s.iqr / s.median:.2f}" for k, s in stats.items()
            if s.n >= 3 and s.median > 0 and s.iqr / s.median > BUSY_SPREAD]


def _compile_kernels(notes: list[str]) -> None:
    """Make the compiled kernels ready before any measurement (:func:`iamp.planners.kernels.warm_kernels`,
    untimed): numba compiles them (about 7 s of CPU on a machine whose numba cache is empty) or loads
    them from its cache, so no timed call includes a compile (a first call slower than a case's
    budget would otherwise be that case's one sample).  Without numba a note says that the kernels
    run as plain Python and how to install it."""
    from iamp.planners.kernels import warm_kernels

    t0 = time.process_time()
    if not warm_kernels():
        notes.append("numba is not installed: the compiled kernels run as plain Python "
                     "(pip install 'iamp[fast]')")
        return
    notes.append(f"compiled kernels ready before timing ({time.process_time() - t0:.1f} s CPU: numba's compile "
                 f"or its cache)")


def run_bench(quick: bool = False, progress: Callable[[int, int], None] | None = None) -> BenchJSON:
    """Measure everything; returns the ``iamp bench --json`` object (SPEC §5b keys and more).

    ``progress(done, total)`` is called between the measurements (never inside a timed loop).
    """
    from iamp.comparison.cvxpy_qp import CvxpyQPPlanner
    from iamp.planners.examples import paper_problem
    from iamp.planners.qp.planner import QPPlanner

    notes: list[str] = []
    names = _installed_backends(notes)
    iterative = tuple(s for s in ITERATIVE if s in names)

    def tick(done: int) -> None:
        if progress is not None:
            progress(done, 7)

    tick(0)
    load_before = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    _compile_kernels(notes)
    pmp = _pmp_numbers(quick, notes)
    tick(1)
    one = paper_problem(1)
    reps = 1 if quick else 3

    cand = {s: _per_candidate(one, s, reps) for s in names}
    tick(2)
    native: dict[str, TimingStats] = {}
    fails: dict[str, int] = {}
    for s in names:
        planner = QPPlanner(steps=STEPS, hold="foh", solver=s)
        native[s], res = _sweep(_plan_fn(planner, one), 3 if quick else 7)
        fails[f"native_{s}"] = _failed_candidates(res)
        if res.status != "optimal":
            notes.append(f"native {s} sweep: status {res.status} ({res.diagnostics.why or ''})")
    tick(3)
    cvx: dict[str, TimingStats] = {}
    for s in ("osqp", "clarabel"):
        planner = CvxpyQPPlanner(steps=STEPS, hold="foh", solver=s)
        cvx[s], res = _sweep(_plan_fn(planner, one), reps)
        fails[f"cvxpy_{s}"] = _failed_candidates(res)
    tick(4)
    avoid = _avoid(one, reps, notes)
    avoid_bounded = _avoid_bounded(quick, notes)
    with_limits = _limits(quick, notes)
    tick(5)
    casadi = _casadi(one, quick, notes)
    from iamp.core.physical import PASSENGER_CAR, PhysicalLimits

    casadi_bounded = _casadi(one.with_limits(PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)), quick,
                             notes, box=True)
    tick(6)
    tuning = [] if quick else osqp_tuning(one)
    from iamp.comparison.bench.prediction import bench_ego_follower, bench_leader_prediction

    lead_pred = bench_leader_prediction(20 if quick else 100)
    ego_pred = bench_ego_follower(20 if quick else 100)
    loop = _loop(quick, notes)
    tick(7)

    solve = {s: cand[s].backend.median for s in names}
    best_it = min(iterative, key=lambda s: solve[s])
    sweeps = {**{s: cvx[s].median for s in cvx}, **{f"native_{s}": native[s].median for s in native}}
    best_native = min(native, key=lambda s: native[s].median)
    pmp_one = float(pmp["pmp_plan_s"]["one_vehicle"])
    ratios: dict[str, float | None] = {
        "pmp_to_compiled_limit": pmp.get("pmp_to_compiled_limit"),
        "pmp_two_vehicles_pure_to_compiled": pmp.get("pmp_two_vehicles_pure_to_compiled"),
        "pmp_bounded_pure_to_compiled": pmp.get("pmp_bounded_pure_to_compiled"),
        "qp_best_to_kkt": solve[best_it] / solve["kkt"],
        **{f"qp_{s}_to_kkt": solve[s] / solve["kkt"] for s in iterative},
        "native_sweep_best_to_pmp_plan": native[best_native].median / pmp_one,
        "native_kkt_sweep_to_pmp_plan": native["kkt"].median / pmp_one,
        **{f"cvxpy_{s}_sweep_to_native": cvx[s].median / native[s].median for s in cvx},
        "kkt_solve_to_pmp_plan": solve["kkt"] / pmp_one,
    }
    if casadi is not None:
        ratios["casadi_ipopt_warm_to_pmp_plan"] = casadi["warm_s"] / pmp_one
        ratios["casadi_ipopt_cold_to_pmp_plan"] = casadi["cold_s"] / pmp_one
    pmp_bounded = float(pmp["pmp_plan_s"]["one_vehicle_bounded"])
    ratios["pmp_bounded_to_unbounded_plan"] = pmp_bounded / pmp_one
    ratios["pmp_bounded_certified_to_bounded_plan"] = (float(pmp["pmp_plan_s"]["one_vehicle_bounded_certified"])
                                                       / pmp_bounded)
    if casadi_bounded is not None:
        ratios["casadi_ipopt_bounded_warm_to_pmp_bounded_plan"] = casadi_bounded["warm_s"] / pmp_bounded
        ratios["casadi_ipopt_bounded_cold_to_pmp_bounded_plan"] = casadi_bounded["cold_s"] / pmp_bounded
    for case, rs in (with_limits["ratios"] if with_limits is not None else {}).items():
        for k, r in rs.items():
            ratios[f"{case}_{k}"] = r
    avoid_osqp = avoid.get("osqp") if avoid is not None else None
    if avoid_osqp is not None and (avoid_osqp_s := avoid_osqp["median"]):
        ratios["avoid_osqp_sweep_to_equality_osqp_sweep"] = avoid_osqp_s / native["osqp"].median
    values = {
        "pmp_plan_one_vehicle_s": pmp_one,
        "pmp_plan_two_vehicles_s": float(pmp["pmp_plan_s"]["two_vehicles"]),
        "pmp_plan_one_vehicle_bounded_s": pmp_bounded,
        "pmp_batch_plans_per_s": float(pmp["pmp_batch_plans_per_s"]),
        "qp_native_solve_kkt_s": solve["kkt"],
        "qp_native_solve_best_iterative_s": solve[best_it],
        "qp_native_solve_osqp_s": solve["osqp"],
        "qp_grid_sweep_native_best_s": native[best_native].median,
        "prediction_leader_20_s": float(lead_pred["median"]),
    }
    targets: dict[str, Target] = {k: {"value": float(values[k]), "target": t, "op": op,
                   "met": bool(values[k] <= t if op == "<=" else values[k] >= t)} for k, (op, t) in TARGETS.items()}
    if avoid_bounded is not None and (fastest := avoid_bounded.get("plan_fastest_s")) is not None:
        v = float(fastest)
        t = float(avoid_bounded["target_plan_s"])
        targets["avoid_bounded_plan_fastest_s"] = {"value": v, "target": t, "op": "<=", "met": bool(v <= t)}
    for case, tg in (with_limits["targets"] if with_limits is not None else {}).items():
        for clock, val, met in (("cpu", tg["cpu_s"], tg["met_cpu"]), ("wall", tg["wall_s"], tg["met_wall"])):
            targets[f"{case}_{clock}_s"] = {"value": val, "target": tg["target_s"], "op": "<=", "met": met}
    if loop is not None:
        for name, ep in loop["episode_s"].items():
            targets[f"loop_episode_{name}_s"] = {"value": float(ep), "target": loop["target_episode_s"], "op": "<=",
                                                 "met": bool(ep <= loop["target_episode_s"])}
    ab_ratios = avoid_bounded.get("ratios") if avoid_bounded is not None else None
    for k, r in (ab_ratios or {}).items():
        ratios[f"avoid_bounded_{k}"] = r
    all_stats = {**{f"qp_native_solve_{s}": cand[s].backend for s in cand},
                 **{f"qp_grid_sweep_native_{s}": native[s] for s in native},
                 **{f"qp_grid_sweep_cvxpy_{s}": cvx[s] for s in cvx}}
    busy = _busy(all_stats)
    for k, st in (pmp.get("stats") or {}).items():
        if isinstance(st, dict) and st.get("n", 0) >= 3 and st.get("median") and st["iqr"] / st["median"] > BUSY_SPREAD:
            busy.append(f"{k}: IQR/median = {st['iqr'] / st['median']:.2f}")
    ver = versions()
    ver["casadi"] = importlib.util.find_spec("casadi") is not None or None
    return {
        "pmp_plan_s": pmp["pmp_plan_s"],
        "pmp_batch_plans_per_s": float(pmp["pmp_batch_plans_per_s"]),
        "qp_native_solve_s": solve,
        "qp_grid_sweep_s": sweeps,
        "avoid_grid_sweep_s": None if avoid is None else {s: v.get("median") for s, v in avoid.items()},
        "prediction_leader_20_s": lead_pred["median"],
        "prediction_ego_follower_s": ego_pred["median"],
        "loop_episode_s": None if loop is None else loop["episode_s"],
        "loop": loop,
        "planning_with_limits": with_limits,
        "avoid_bounded": avoid_bounded if avoid_bounded is not None else NoAvoidBounded(),
        "ratios": ratios,
        "versions": ver,
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(), "machine": platform.machine(),
                    "python": platform.python_version(), "load_average_1min_before": load_before,
                    "load_average_1min_after": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
                    "cpu_model": _blas.cpu_model(), "numpy_avx512": _blas.numpy_avx512(),
                    "piqp_build": _blas.piqp_build()},
        "warnings": ([f"the machine was probably busy (spread above {BUSY_SPREAD:.0%} of the median): "
                      + "; ".join(busy)] if busy else []),
        "quick": bool(quick), "steps": STEPS, "problem": one.name,
        "best_iterative_backend": best_it, "best_native_sweep": best_native,
        "qp_candidate": {s: {"backend_s": c.backend.to_dict(), "solve_call_s": c.call.to_dict(),
                             "wall_s": c.wall.to_dict(), "failed": c.failed, "backend": c.describe}
                         for s, c in cand.items()},
        "stats": {"qp_grid_sweep_native_s": {s: v.to_dict() for s, v in native.items()},
                  "qp_grid_sweep_cvxpy_s": {s: v.to_dict() for s, v in cvx.items()},
                  "pmp": pmp.get("stats"), "avoid": avoid, "prediction_leader_20": lead_pred,
                  "prediction_ego_follower": ego_pred},
        "pmp": {k: v for k, v in pmp.items() if k not in ("pmp_plan_s", "pmp_batch_plans_per_s", "stats")},
        "failed_sweep_candidates": fails,
        "casadi_ipopt": casadi,
        "casadi_ipopt_bounded": casadi_bounded,
        "osqp_tuning": tuning,
        "targets": targets,
        "missed": [k for k, t in targets.items() if not t["met"]],
        "notes": notes,
    }


def _failed_candidates(res: Plan) -> int:
    """Sweep candidates of a QP plan that did not solve to a verified optimum."""
    qp = res.diagnostics
    if not isinstance(qp, QPDiagnostics) or qp.candidates is None:
        raise KeyError("candidates")
    return int(qp.candidates["total"] - qp.candidates["solved"])
