r"""Timing that a solver developer would accept.

Every measurement is a set of individual wall-clock samples (:func:`time.perf_counter`)
taken after ``warmup`` untimed calls, summarised by :class:`TimingStats`: median,
inter-quartile range (IQR = Q3 − Q1), 95th percentile, mean, min, max and the number of
samples.  Percentiles use numpy's default (linear interpolation between order statistics,
Hyndman–Fan type 7).  Nothing here asserts a speed; ``iamp bench`` reports numbers against
targets and the tests only check the statistics on known samples.

What is timed, separately (:func:`qp_breakdown`, :func:`time_problem`):

* **cvxpy compile** — building the cross-check :class:`~iamp.comparison.cvxpy_qp.CvxpyQP`
  and its first solve (cvxpy canonicalises the DPP problem on the first ``solve``);
* **cvxpy re-solve** — a later ``solve_nodes`` (parameters changed, problem re-used), its
  total wall time, the solver's own reported time, and the **overhead**
  ``total − solver's own time`` (cvxpy's parameter update, data copy, result unpacking);
* **native** — :class:`iamp.planners.qp.core.DiscretisedQP` on a backend of
  :mod:`iamp.planners.qp.backends`: the values updated in place, OSQP warm-started, Clarabel
  and PIQP re-used through their data updates (no warm start), ``kkt`` re-using its
  factorisation;
* **PMP plan** — :meth:`iamp.planners.pmp.planner.PMPPlanner.plan` including its global
  contact-time search;
* **full contact-time search** — a complete plan of each planner (QP: build + sweep of every
  interior node combination).

Across scenarios the summary is the shifted geometric mean (:func:`shifted_geomean`), as in
Mittelmann's benchmarks and qpbenchmark, with the shift stated in the output (default 10 ms).
Every output carries :func:`versions` and :func:`solver_settings`.
"""

from __future__ import annotations

import math
import os
import platform
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass
from importlib import metadata
from typing import NotRequired, TypedDict, TypeVar, cast

import numpy as np

from iamp.core.plan import Plan
from iamp.core.problem import Problem

T = TypeVar("T")


class StatsJSON(TypedDict):
    """:meth:`TimingStats.to_dict`: the statistics of timing samples [s] as JSON."""

    n: int
    median: float
    q1: float
    q3: float
    iqr: float
    p95: float
    mean: float
    min: float
    max: float
    warmup: int


class VersionsJSON(TypedDict):
    """:func:`versions`: library versions and the machine (``None``: not installed)."""

    python: str
    numpy: str
    scipy: str
    cvxpy: str | None
    osqp: str | None
    clarabel: str | None
    piqp: str | None
    iamp: str
    numba: str | None
    platform: str
    machine: str
    cpu_count: int | None
    implementation: str
    casadi: NotRequired[bool | None]  # ``iamp bench`` adds it


class QPBreakdown(TypedDict):
    """:func:`qp_breakdown`: per-solve timing of one QP configuration, cvxpy and native."""

    solver: str
    hold: str
    steps: int
    cvxpy_compile_s: float
    cvxpy_resolve_s: StatsJSON
    cvxpy_solver_s: StatsJSON
    cvxpy_overhead_s: StatsJSON
    cvxpy_failed: int
    native_setup_s: NotRequired[float]
    native_solve_s: NotRequired[StatsJSON]
    native_solve_call_s: NotRequired[StatsJSON]
    native_solver_s: NotRequired[StatsJSON]
    native_failed: NotRequired[int]
    native_info: NotRequired[dict[str, object]]


class GeomeanEntry(TypedDict):
    """One label of :func:`geomean_table`."""

    shifted_geomean_s: float
    n: int


class GeomeanTable(TypedDict):
    """:func:`geomean_table`: shifted geometric means across scenarios, per label."""

    shift_s: float
    means: dict[str, GeomeanEntry]

#: Default shift of the shifted geometric mean [s].
DEFAULT_SHIFT_S = 0.01


@dataclass(frozen=True)
class TimingStats:
    """Summary of timing samples (seconds).

    ``iqr = q3 − q1`` with ``q1, q3`` the 25th and 75th percentiles; ``p95`` the 95th.
    """

    n: int
    median: float
    q1: float
    q3: float
    iqr: float
    p95: float
    mean: float
    min: float
    max: float
    warmup: int = 0

    def to_dict(self) -> StatsJSON:
        return cast(StatsJSON, asdict(self))  # the fields, in order


def summarize(samples: Iterable[float], warmup: int = 0) -> TimingStats:
    """Statistics of a non-empty sequence of samples (numpy type-7 percentiles)."""
    x = np.asarray(list(samples), dtype=float)
    if x.size == 0:
        raise ValueError("no timing samples")
    q1, med, q3, p95 = np.percentile(x, [25, 50, 75, 95])
    return TimingStats(n=int(x.size), median=float(med), q1=float(q1), q3=float(q3), iqr=float(q3 - q1),
                       p95=float(p95), mean=float(x.mean()), min=float(x.min()), max=float(x.max()),
                       warmup=int(warmup))


def measure(fn: Callable[[], T], repeats: int = 20, warmup: int = 1,
            budget_s: float | None = None) -> tuple[TimingStats, T | None]:
    """Time ``fn()``: ``warmup`` untimed calls, then up to ``repeats`` timed calls.

    If ``budget_s`` is given, stop adding samples once their sum exceeds it (at least one
    sample is always taken, and the warm-up is skipped when a single call already exceeds
    the budget — then the first call is the measurement).  Returns ``(stats, last_result)``.
    """
    if repeats < 1:
        raise ValueError("repeats must be >= 1")
    samples: list[float] = []
    result: T | None = None
    done_warmup = 0
    for _ in range(max(0, warmup)):
        t0 = time.perf_counter()
        result = fn()
        dt = time.perf_counter() - t0
        done_warmup += 1
        if budget_s is not None and dt > budget_s:
            samples.append(dt)  # too slow to afford a warm-up: keep it as the sample
            done_warmup -= 1
            return summarize(samples, done_warmup), result
    total = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        dt = time.perf_counter() - t0
        samples.append(dt)
        total += dt
        if budget_s is not None and total > budget_s:
            break
    return summarize(samples, done_warmup), result


def shifted_geomean(values: Iterable[float], shift: float = DEFAULT_SHIFT_S) -> float:
    r"""Shifted geometric mean :math:`\exp\big(\tfrac1n\sum_i \ln(v_i + s)\big) - s`.

    The shift ``s`` (seconds; default 10 ms) damps the weight of very small times, as in
    Mittelmann's and qpbenchmark's solver comparisons.  Values must be ``> −s``.
    """
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        raise ValueError("no values")
    if np.any(v + shift <= 0):
        raise ValueError("every value must exceed -shift")
    return float(np.exp(np.mean(np.log(v + shift))) - shift)


def dist_version(name: str) -> str | None:
    """The installed version of distribution ``name``, or ``None``."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _iamp_version() -> str:
    """The version of the iamp being run (not whatever distribution metadata is installed)."""
    from iamp._version import __version__

    return __version__


def versions() -> VersionsJSON:
    """Library versions and the machine the numbers come from."""
    import numpy
    import scipy

    try:
        import cvxpy

        cvxpy_v = getattr(cvxpy, "__version__", None)
    except ImportError:  # pragma: no cover
        cvxpy_v = None
    return {
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "cvxpy": cvxpy_v,
        "osqp": dist_version("osqp"),
        "clarabel": dist_version("clarabel"),
        "piqp": dist_version("piqp"),
        "iamp": _iamp_version(),
        "numba": dist_version("numba"),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "implementation": sys.implementation.name,
    }


def solver_settings() -> dict[str, dict[str, object]]:
    """The default settings of every QP backend (:data:`iamp.planners.qp.backends.BACKENDS`)."""
    from iamp.planners.qp.backends import BACKENDS

    return {name: cls.default_settings() for name, cls in BACKENDS.items()}


# --------------------------------------------------------------------------------------
# What is timed
# --------------------------------------------------------------------------------------


def _pmp_plan_fn(problem: Problem) -> Callable[[], Plan]:
    import inspect

    from iamp.planners.pmp.planner import PMPPlanner

    planner = PMPPlanner()
    if "diagnostics" in inspect.signature(planner.plan).parameters:
        return lambda: planner.plan(problem, diagnostics=False)
    return lambda: planner.plan(problem)


def time_pmp(problem: Problem, repeats: int = 50, warmup: int = 3) -> TimingStats:
    """The PMP plan (global contact-time search + jump-condition solve + cost); the
    residual report is left out when the planner allows it (it is a diagnostic)."""
    stats, _ = measure(_pmp_plan_fn(problem), repeats, warmup)
    return stats


def sample_nodes(problem: Problem, N: int, count: int, seed: int = 0) -> list[tuple[int, ...]]:
    """``count`` distinct candidate node tuples spread over the sweep (deterministic)."""
    rng = np.random.default_rng(seed)
    m = problem.m
    out: list[tuple[int, ...]] = []
    while len(out) < count:
        nodes = tuple(int(k) for k in rng.choice(np.arange(1, N), size=m, replace=False))
        out.append(nodes)
    return out


def qp_breakdown(problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 repeats: int = 20, native: bool = True) -> QPBreakdown:
    """Per-solve timing of one QP configuration, cvxpy and native, separated.

    Returns ``{"cvxpy_compile_s", "cvxpy_resolve_s", "cvxpy_solver_s", "cvxpy_overhead_s",
    "native_setup_s", "native_solve_s", "native_solve_call_s", "native_solver_s"}`` (each a
    stats dict except the compile and set-up times, which are single first-call
    measurements) plus the number of failed candidates among the timed ones.  The overhead
    is summarised per solve (median of ``total − solver``, not a difference of medians).
    Caveat: Clarabel 0.11.1's reported ``solve_time`` exceeds the wall time of its
    ``solve()`` call (measured ≈0.63 ms against ≈0.12 ms at ``N = 100``), so for Clarabel
    ``cvxpy_overhead_s`` *under*-states cvxpy's overhead; ``native_solve_call_s`` is the
    measured wall time of the bare ``solve()`` call.  Candidates are ``repeats`` node tuples drawn
    deterministically over the sweep, so warm starts see a realistic change of data.
    """
    import warnings

    from iamp.comparison.cvxpy_qp import CvxpyQPPlanner

    nodes = sample_nodes(problem, steps, repeats + 1)
    t0 = time.perf_counter()
    qp = CvxpyQPPlanner(steps=steps, hold=hold, solver=solver).build(problem)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        qp.solve_nodes(nodes[0])
    compile_s = time.perf_counter() - t0
    totals: list[float] = []
    own: list[float] = []
    fails = 0
    for nd in nodes[1:]:
        t0 = time.perf_counter()
        r = qp.solve_nodes(nd)
        totals.append(time.perf_counter() - t0)
        own.append(r.solver_time_s if r.solver_time_s is not None else np.nan)
        fails += r.status != "optimal"
    out: QPBreakdown = {"solver": solver, "hold": hold, "steps": int(steps), "cvxpy_compile_s": compile_s,
                        "cvxpy_resolve_s": summarize(totals).to_dict(), "cvxpy_solver_s": summarize(own).to_dict(),
                        "cvxpy_overhead_s": summarize(np.array(totals) - np.array(own)).to_dict(),
                        "cvxpy_failed": int(fails)}
    if native:
        from iamp.planners.qp.planner import QPPlanner

        t0 = time.perf_counter()
        nq = QPPlanner(steps=steps, hold=hold, solver=solver).build(problem)  # bounded with problem.limits
        nq.solve_nodes(nodes[0])
        out["native_setup_s"] = time.perf_counter() - t0
        walls: list[float] = []
        calls: list[float] = []
        own, fails = [], 0
        for nd in nodes[1:]:
            t0 = time.perf_counter()
            r = nq.solve_nodes(nd)
            walls.append(time.perf_counter() - t0)
            own.append(r.solver_time_s if r.solver_time_s is not None else np.nan)
            calls.append(r.solve_call_s)
            fails += r.status != "optimal"
        out["native_solve_s"] = summarize(walls).to_dict()
        out["native_solve_call_s"] = summarize(calls).to_dict()
        out["native_solver_s"] = summarize(own).to_dict()
        out["native_failed"] = int(fails)
        backend = getattr(nq, "backend", None)  # DiscretisedQP and BoundedQP hold their backend
        out["native_info"] = backend.describe() if backend is not None else {}
    return out


def time_search(planner_fn: Callable[[], T], repeats: int = 3, warmup: int = 1,
                budget_s: float = 30.0) -> tuple[TimingStats, T | None]:
    """Time a full contact-time search ``planner_fn() -> Plan`` (build included);
    returns ``(stats, last_result)`` (see :func:`measure` for ``budget_s``)."""
    return measure(planner_fn, repeats, warmup, budget_s)


def geomean_table(per_scenario: Mapping[str, Mapping[str, float | None]],
                  shift: float = DEFAULT_SHIFT_S) -> GeomeanTable:
    """Shifted geometric means across scenarios.

    ``per_scenario`` maps a scenario name to ``{label: median seconds}``; labels missing
    from a scenario are left out of that label's mean (the count is reported).
    """
    labels = sorted({lab for d in per_scenario.values() for lab in d})
    means: dict[str, GeomeanEntry] = {}
    out: GeomeanTable = {"shift_s": shift, "means": means}
    for lab in labels:
        vals = [float(v) for d in per_scenario.values() if (v := d.get(lab)) is not None and math.isfinite(v)]
        if vals:
            means[lab] = {"shifted_geomean_s": shifted_geomean(vals, shift), "n": len(vals)}
    return out
