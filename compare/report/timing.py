r"""The timing of ``iamp reproduce``: raw samples of single QP solves, whole-plan statistics,
the machine and the versions.

:func:`timing_section` times one QP solve at a changed candidate node (the cvxpy re-solve of
the compiled problem and the native path) per solver, as raw samples (no warm-up; the figure
shows every sample), summarised by :func:`iamp.comparison.timing.summarize` (median, quartiles
:math:`q_1, q_3`, IQR :math:`= q_3 - q_1`); the whole plans were timed once, in the planning
step (:func:`iamp.comparison.report.scenarios.plan_scenario`), and are collected here.
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable, Iterator, Mapping, Sequence

from iamp.comparison.timing import StatsJSON, dist_version, sample_nodes, summarize
from iamp.planners.qp.core import CandidateSolver

from .config import ProgressFn, ReproduceConfig
from .records import EmptyStatsJSON, ScenarioEntry, ScenarioPlan, TimingSection
from .tex import short_label

__all__ = ["timing_section", "versions_used", "whole_plan_stats"]


def _next_solve(qp: CandidateSolver, nodes: Iterator[tuple[int, ...]]) -> Callable[[], object]:
    """A call that solves ``qp`` at the next candidate of ``nodes`` (one changed node per sample)."""
    return lambda: qp.solve_nodes(next(nodes))


def _samples(fn: Callable[[], object], repeats: int) -> list[float]:
    """``repeats`` wall times of ``fn()``, no warm-up (the raw samples go to the timing figure)."""
    out = []
    for _ in range(max(int(repeats), 0)):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def _summary(samples: Sequence[float]) -> StatsJSON | EmptyStatsJSON:
    """:func:`iamp.comparison.timing.summarize` as a dict (``n = 0`` and ``None`` statistics for no
    samples)."""
    if len(samples) == 0:
        return {"n": 0, "median": None, "q1": None, "q3": None, "iqr": None}
    return summarize(samples).to_dict()


def timing_section(entries: Mapping[str, ScenarioEntry], plans: Mapping[str, ScenarioPlan], cfg: ReproduceConfig,
                   progress: ProgressFn | None = None) -> TimingSection:
    """Timing: one QP solve at a changed candidate node (the cvxpy re-solve of the compiled
    problem, and the native path) per solver, as raw samples; and the whole-plan statistics
    of every run of the planning step (:func:`iamp.comparison.agreement.judge.compare_problem`).

    The PMP is timed once only, there (a whole plan, its global contact-time search included,
    the residual report left out of the clock as for every planner). An earlier version also
    timed ``PMPPlanner.plan`` here *with* its residual report, and the report showed the two
    different measures side by side under the same name.
    """
    from iamp.comparison.cvxpy_qp import CvxpyQPPlanner
    from iamp.planners.qp.core import DiscretisedQP as build_native
    names = [n for n in cfg.timing_scenarios if n in entries]
    samples: dict[str, list[float]] = {}
    for k, name in enumerate(names):
        prob = entries[name].problem
        m = prob.m
        tag = "1 vehicle" if m == 1 else f"{m} vehicles"
        steps = cfg.steps_one if m == 1 else cfg.steps_two
        nodes = sample_nodes(prob, steps, cfg.qp_solve_repeats + 1)
        for solver in ("clarabel", "osqp"):
            qp = CvxpyQPPlanner(steps, "foh", solver).build(prob)
            qp.solve_nodes(nodes[0])  # compiles the cvxpy problem
            it = iter(nodes[1:])
            samples[f"QP {solver} solve, cvxpy, N={steps} ({tag})"] = _samples(_next_solve(qp, it),
                                                                              cfg.qp_solve_repeats)
            if build_native is not None:
                nq = build_native(prob, steps, "foh", solver)
                nq.solve_nodes(nodes[0])
                it2 = iter(nodes[1:])
                samples[f"QP {solver} solve, native, N={steps} ({tag})"] = _samples(_next_solve(nq, it2),
                                                                                   cfg.qp_solve_repeats)
        if progress is not None:
            progress(k + 1, len(names))
    plans_stats = {name: {d["label"]: d.get("time_s") for d in p.runs} for name, p in plans.items()}
    return {"samples": samples, "summary": {k: _summary(v) for k, v in samples.items()}, "full_plans": plans_stats,
            "pmp_timed_without_diagnostics": True,
            "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                        "platform": platform.platform(),
                        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}}


def whole_plan_stats(timing: TimingSection, cfg: ReproduceConfig) -> dict[str, StatsJSON]:
    """``{"<scenario>: <run label>": stats}`` of the whole plans of the timing scenarios (the
    figure's left panel; the same numbers as the table's whole-plan rows)."""
    out: dict[str, StatsJSON] = {}
    for name in cfg.timing_scenarios:
        for label, st in (timing["full_plans"].get(name) or {}).items():
            if st and st.get("n"):
                out[f"{name}: {short_label(label)}"] = st
    return out


def versions_used() -> dict[str, str | None]:
    """Python's and each dependency's version (``None`` when not installed)."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("iamp", "numpy", "scipy", "cvxpy", "osqp", "clarabel", "matplotlib"):
        out[dist] = dist_version(dist)
    return out
