r"""``iamp reproduce``: the paper's experiments end to end, and the comparison beyond them.

:func:`reproduce` runs, without SUMO or internet:

1. the paper's scenarios 1–3 from their observed histories (built-ins ``paper-1..3``, fed to
   the shipped predictor; the ``paper-N-poly`` versions, with a note, when the history
   versions or the predictor are not available) and the ``two-vehicle`` scenario;
2. for each, the PMP planner and the QP baseline (FOH sweeps on Clarabel and OSQP, a ZOH
   sweep and an off-grid ``refine`` on Clarabel for one vehicle; FOH sweeps on a coarser
   grid for two vehicles, which sweep every ordered pair of nodes);
3. the figures of the paper (Figs. 4–9) and beyond it (``J(t)`` with the sweep points,
   co-states and jumps against the QP multipliers, the ZOH convergence, solve times, the
   prediction);
4. a ZOH convergence study (``N = 25 … 400`` at a fixed contact node) with measured ratios;
5. solve-time samples (median / IQR);
6. the predictor evaluation (:func:`iamp.prediction.evaluate.write_evaluation_report`);
7. the tables (booktabs), ``results.json`` with the raw numbers, and ``report.tex`` which
   ``\input``\ s and ``\includegraphics``\ es all of them (it compiles with ``pdflatex`` and
   the packages of ``texlive-latex-recommended``).

Every file is written atomically.  The library never prints: progress goes to the optional
``progress(step, total, message)`` callback.

This module runs the steps; the LaTeX is :mod:`iamp.comparison.report_tables` (the tables),
:mod:`iamp.comparison.report_document` (``report.tex``) and :mod:`iamp.comparison.report_tex`
(their text and number formats); the plan metrics and the qualitative comparison are
:mod:`iamp.comparison.metrics`, the paper's Table I is :mod:`iamp.comparison.paper`.
"""

from __future__ import annotations

import inspect
import json
import os
import platform
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from iamp.comparison.metrics import manoeuvre_metrics, qualitative_comparison
from iamp.comparison.paper import PAPER_TABLE_I, SCENARIOS
from iamp.comparison.report_document import build_report_tex
from iamp.comparison.report_tables import (
    table_agreement,
    table_convergence,
    table_metrics,
    table_results,
    table_scenarios,
    table_timing,
)
from iamp.comparison.report_tex import short_label
from iamp.comparison.timing import dist_version, sample_nodes, summarize
from iamp.core.atomic import write_text as atomic_write_text
from iamp.core.jsonable import to_jsonable
from iamp.core.problem import Problem

#: ``progress(done, total)``, the project's progress convention.
ProgressFn = Callable[[int, int], None]

__all__ = ["ReproduceConfig", "reproduce", "zoh_convergence"]


@dataclass
class ReproduceConfig:
    """Sizes of the experiments (the defaults are the full report; :meth:`quick_config` is a
    smoke run).

    ``qp_one`` / ``qp_two`` list ``(solver, hold, contact, path)`` QP configurations for one-
    and two-vehicle scenarios, on ``steps_one`` / ``steps_two`` intervals (``path``:
    ``"cvxpy"`` — :class:`~iamp.planners.qp.QPPlanner` — or ``"native"``).  Each plan is
    repeated up to ``plan_repeats`` times for its timing, stopping once the samples exceed
    ``plan_budget_s``.
    """

    steps_one: int = 100
    steps_two: int = 30
    qp_one: tuple[Any, ...] = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "zoh", "grid", "cvxpy"), ("clarabel", "foh", "refine", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    qp_two: tuple[Any, ...] = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    zoh_steps: tuple[Any, ...] = (25, 50, 100, 200, 400)
    plan_repeats: int = 3
    plan_budget_s: float = 4.0
    pmp_repeats: int = 200
    pmp_repeats_two: int = 20
    qp_solve_repeats: int = 30
    timing_scenarios: tuple[Any, ...] = ("paper-1", "two-vehicle")
    predictor_eval: bool = True
    predictor_select: bool | str = "auto"
    quick: bool = False

    @classmethod
    def quick_config(cls) -> ReproduceConfig:
        return cls(steps_one=20, steps_two=8, zoh_steps=(25, 50, 100), plan_repeats=1, pmp_repeats=20,
                   pmp_repeats_two=5, qp_solve_repeats=5, predictor_select=False, quick=True)


# --------------------------------------------------------------------------------------
# small utilities
# --------------------------------------------------------------------------------------


class _Progress:
    """Steps of :func:`reproduce` as ``progress(done, total)`` in hundredths of a step (so that a
    step whose library call reports its own progress moves the bar smoothly), and each step's
    message to ``status(message)``."""

    SCALE = 100

    def __init__(self, callback: ProgressFn | None, status: Callable[[str], None] | None, total: int) -> None:
        self.callback, self.status, self.total, self.step = callback, status, total, 0

    def __call__(self, message: str) -> None:
        """Start the next step (the previous one is done)."""
        self._report(self.step * self.SCALE)
        self.step += 1
        if self.status is not None:
            self.status(message)

    def sub(self, done: int, total: int) -> None:
        """Progress inside the current step (``done`` of ``total``)."""
        if total > 0:
            frac = min(max(done / total, 0.0), 1.0)
            self._report(int((self.step - 1 + frac) * self.SCALE))

    def finish(self) -> None:
        self._report(self.total * self.SCALE)

    def _report(self, done: int) -> None:
        if self.callback is not None:
            self.callback(done, self.total * self.SCALE)


# --------------------------------------------------------------------------------------
# scenarios
# --------------------------------------------------------------------------------------


def _load_scenario(name: str, notes: list[Any]) -> dict[str, Any]:
    """Load a built-in scenario through the CLI's loader (the shipped predictor for
    histories); fall back to ``<name>-poly`` with a note if that is impossible."""
    from iamp.core.errors import IampError
    from iamp.core.scenario import builtin_names
    from iamp.prediction.resolve import load_problem

    candidates = [name] if name in builtin_names() else []
    reason = None if candidates else f"the built-in scenario '{name}' (history version) does not exist yet"
    for spec in candidates:
        try:
            scenario, problem, preds = load_problem(spec)
            return {"name": name, "builtin": spec, "scenario": scenario, "problem": problem, "predictions": preds,
                    "source": "history" if scenario.needs_prediction else "x_poly", "fallback": False}
        except (IampError, ImportError, OSError) as exc:
            msg = exc.message if hasattr(exc, "message") else str(exc)
            reason = (f"the history version '{spec}' could not be predicted with the shipped predictor "
                      f"({exc.__class__.__name__}: {msg[:120]})")
    poly = f"{name}-poly"
    if poly not in builtin_names():
        raise FileNotFoundError(f"neither '{name}' nor '{poly}' is a built-in scenario")
    scenario, problem, preds = load_problem(poly)
    notes.append(f"{name}: {reason}; used '{poly}' (vehicle 1 given directly as a documented polynomial) instead.")
    return {"name": name, "builtin": poly, "scenario": scenario, "problem": problem, "predictions": preds,
            "source": "x_poly", "fallback": True}


def _history_speed_at_0(history: Any) -> float:
    """Speed at ``t = 0`` from the last second of a history (quadratic fit)."""
    t, x = np.asarray(history.t), np.asarray(history.x)
    sel = t >= -1.0 - 1e-9
    if sel.sum() < 3:
        sel = np.ones_like(t, dtype=bool)
    deg = min(2, int(sel.sum()) - 1)
    c = np.polynomial.polynomial.polyfit(t[sel], x[sel], deg)
    return float(c[1]) if deg >= 1 else 0.0


def _table1_row(entry: dict[str, Any]) -> dict[str, Any]:
    sc, prob = entry["scenario"], entry["problem"]
    v = prob.vehicles[0]
    spec_v = sc.vehicles[0]
    if spec_v.history is not None:
        x0, v0 = float(spec_v.history.x[-1]), _history_speed_at_0(spec_v.history)
        hist = {"t": spec_v.history.t, "x": spec_v.history.x}
    else:
        x0, v0 = float(v.position(0.0)), float(v.speed(0.0))
        hist = None
    return {"v_e": prob.ego.vx0, "s_xf": prob.ego.xf, "t_f": prob.tf, "x_s0": x0, "v_s0": v0,
            "x_poly": list[Any](v.x_poly), "history": hist, "L": v.length, "W": v.width, "S_x": v.safety_x,
            "S_y": v.safety_y, "y_s": v.y, "corner": v.corner}


# --------------------------------------------------------------------------------------
# planning, agreement, metrics
# --------------------------------------------------------------------------------------


def _roles(problem: Problem, jumps: Any) -> list[Any]:
    from iamp.comparison.signs import constraint_is_binding_for_safety

    return ["safety" if constraint_is_binding_for_safety(v, j[0]) else "drag" for v, j in zip(problem.vehicles, jumps)]


def _qp_configs(cfg: ReproduceConfig, problem: Problem) -> list[Any]:
    """The QP configurations of ``cfg`` for ``problem`` (one or several vehicles)."""
    from iamp.comparison.agreement import QPConfig

    one = problem.m == 1
    steps = cfg.steps_one if one else cfg.steps_two
    confs = [tuple(c) + ("cvxpy",) * (4 - len(c)) for c in (cfg.qp_one if one else cfg.qp_two)]
    return [QPConfig(solver=s, hold=h, steps=steps, contact=c, path=p) for s, h, c, p in confs]


def _plan_scenario(name: str, problem: Problem, cfg: ReproduceConfig,
                   progress: ProgressFn | None = None) -> dict[str, Any]:
    """Plan one scenario with the PMP and every QP configuration, judge every pair.

    Uses :func:`iamp.comparison.agreement.compare_problem` (the same problem object to every
    planner, identical-polynomial fingerprints, verdicts with reasons, timed plans).
    """
    from iamp.comparison.agreement import compare_problem

    one = problem.m == 1
    steps = cfg.steps_one if one else cfg.steps_two
    pmp_repeats = cfg.pmp_repeats if one else cfg.pmp_repeats_two
    extra: dict[str, Any] = ({"progress": progress} if progress is not None
                             and "progress" in inspect.signature(compare_problem).parameters else {})
    pc = compare_problem(problem, _qp_configs(cfg, problem), name=name, repeats=cfg.plan_repeats,
                         pmp_repeats=pmp_repeats, budget_s=cfg.plan_budget_s, warmup=0, **extra)
    results = {r.label: r.result for r in pc.runs}
    runs = [r.to_json() for r in pc.runs]
    for d in runs:
        r = results[d["label"]]
        if r.is_optimal():
            d["constraint_role"] = _roles(problem, r.jumps)
            d["solve_time_s"] = r.solve_time_s
            if "grid_best" in r.info:
                d["grid_best"] = r.info["grid_best"]
    return {"results": results, "runs": runs, "agreement": pc.agreement,
            "agreement_source": "iamp.comparison.agreement.compare_problem", "steps": steps}


# --------------------------------------------------------------------------------------
# timing
# --------------------------------------------------------------------------------------


def _next_solve(qp: Any, nodes: Iterator[Any]) -> Callable[[], object]:
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


def _summary(samples: Sequence[float]) -> dict[str, Any]:
    """:func:`iamp.comparison.timing.summarize` as a dict (``n = 0`` and ``None`` statistics for no
    samples)."""
    if len(samples) == 0:
        return {"n": 0, "median": None, "q1": None, "q3": None, "iqr": None}
    return summarize(samples).to_dict()


def _timing(entries: dict[str, Any], plans: dict[str, Any], cfg: ReproduceConfig,
            progress: ProgressFn | None = None) -> dict[str, Any]:
    """Timing: one QP solve at a changed candidate node (the cvxpy re-solve of the compiled
    problem, and the native path) per solver, as raw samples; and the whole-plan statistics
    of every run of the planning step (:func:`iamp.comparison.agreement.compare_problem`).

    The PMP is timed once only, there (a whole plan, its global contact-time search included,
    the residual report left out of the clock as for every planner). An earlier version also
    timed ``PMPPlanner.plan`` here *with* its residual report, and the report showed the two
    different measures side by side under the same name.
    """
    from iamp.comparison.cvxpy_qp import CvxpyQPPlanner
    from iamp.planners.qp_core import DiscretisedQP as build_native
    names = [n for n in cfg.timing_scenarios if n in entries]
    samples: dict[str, Any] = {}
    for k, name in enumerate(names):
        prob = entries[name]["problem"]
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
    plans_stats = {name: {d["label"]: d.get("time_s") for d in p["runs"]} for name, p in plans.items()}
    return {"samples": samples, "summary": {k: _summary(v) for k, v in samples.items()}, "full_plans": plans_stats,
            "pmp_timed_without_diagnostics": True,
            "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                        "platform": platform.platform(),
                        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}}


def _whole_plan_stats(timing: dict[str, Any], cfg: ReproduceConfig) -> dict[str, Any]:
    """``{"<scenario>: <run label>": stats}`` of the whole plans of the timing scenarios (the
    figure's left panel; the same numbers as the table's whole-plan rows)."""
    out = {}
    for name in cfg.timing_scenarios:
        for label, st in (timing["full_plans"].get(name) or {}).items():
            if st and st.get("n"):
                out[f"{name}: {short_label(label)}"] = st
    return out


# --------------------------------------------------------------------------------------
# ZOH convergence
# --------------------------------------------------------------------------------------


def zoh_convergence(problem: Problem, steps: Sequence[int] = (25, 50, 100, 200, 400), t_contact: float | None = None,
                    solver: str = "clarabel") -> dict[str, Any]:
    """``J_ZOH − J_PMP`` at one fixed contact time on grids ``N ∈ steps``.

    The contact time is a node of every grid (a multiple of ``t_f / gcd(steps)``, the one
    nearest to the PMP's ``t*`` unless given).  ``J_PMP`` is the fixed-time PMP cost there;
    the FOH gap is reported alongside (exact: solver precision).  ``ratio[k]`` is
    ``gap(N_k) / gap(N_{k+1})`` (4 for ``O(h²)`` when ``N`` doubles).
    """
    from iamp.planners.pmp import PMPPlanner, solve_fixed_times
    from iamp.planners.qp import QPPlanner

    steps = tuple(int(n) for n in steps)
    tf = problem.tf
    base = int(np.gcd.reduce(np.array(steps)))
    h0 = tf / base
    if t_contact is None:
        t_star = float(PMPPlanner().contact_times(problem)[0])
        k0 = int(min(max(round(t_star / h0), 1), base - 1))
    else:
        k0 = int(round(float(t_contact) / h0))
    t_c = k0 * h0
    rows: list[dict[str, Any]] = []
    for N in steps:
        k = k0 * (N // base)
        t_node = np.linspace(0.0, tf, N + 1)[k]
        j_pmp = solve_fixed_times(problem, [t_node]).cost()
        z = QPPlanner(N, "zoh", solver).plan_at_nodes(problem, [k])
        f = QPPlanner(N, "foh", solver).plan_at_nodes(problem, [k])
        rows.append({"N": N, "h": tf / N, "node": k, "t_node": float(t_node), "J_pmp": j_pmp,
                     "J_zoh": z.cost if z.is_optimal() else None, "J_foh": f.cost if f.is_optimal() else None,
                     "zoh_gap": (z.cost - j_pmp) if z.is_optimal() and z.cost is not None else None,
                     "foh_gap": (f.cost - j_pmp) if f.is_optimal() and f.cost is not None else None,
                     "status_zoh": z.status, "status_foh": f.status})
    for a, b in zip(rows[:-1], rows[1:]):
        a["ratio_to_next"] = (a["zoh_gap"] / b["zoh_gap"]) if a["zoh_gap"] and b["zoh_gap"] else None
    gaps = np.array([r["zoh_gap"] if r["zoh_gap"] else np.nan for r in rows])
    hs = np.array([r["h"] for r in rows])
    ok = np.isfinite(gaps) & (gaps > 0)
    slope = float(np.polyfit(np.log(hs[ok]), np.log(gaps[ok]), 1)[0]) if ok.sum() >= 2 else None
    return {"solver": solver, "t_contact": t_c, "rows": rows, "loglog_slope": slope}


# --------------------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------------------


def _predictor_evaluation(out: Path, cfg: ReproduceConfig, notes: list[Any],
                          progress: ProgressFn | None = None) -> dict[str, Any] | None:
    """Run (or reuse) the predictor's evaluation and let it write its tables into ``out``.

    ``cfg.predictor_select``: ``True`` runs the model-selection grid (many minutes);
    ``False`` evaluates the default configuration only (tens of seconds); ``"auto"`` reuses an
    existing ``out/predictor_eval.json`` that has a selection, was computed on the same data
    set (fingerprint) and chose the shipped configuration, else behaves as ``False``.
    """
    if not cfg.predictor_eval:
        notes.append("predictor evaluation skipped (configuration).")
        return None
    try:
        from iamp.prediction import evaluate as ev
    except ImportError as exc:
        notes.append(f"predictor evaluation unavailable ({exc.__class__.__name__}: {exc}).")
        return None
    mode = cfg.predictor_select
    existing = None
    if mode == "auto":
        path = out / "predictor_eval.json"
        try:
            old = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
        except (OSError, ValueError):
            old = None
        if old and old.get("selection"):
            try:
                fp = ev._dataset_fingerprint(ev._load_default_data())
                same_data = old.get("protocol", {}).get("dataset_sha256_track_t_x") == fp
            except Exception:  # cannot check: do not reuse
                same_data = False
            if same_data and old.get("chosen") == getattr(ev, "DEFAULT_CONFIG", None):
                existing = old
    try:
        if existing is not None:
            res = ev.write_evaluation_report(out, results=existing)
            how = ("reused the existing predictor_eval.json (model selection on the validation split, same data "
                   "set, chose the shipped configuration); its tables were rewritten")
        else:
            select = mode is True
            extra: dict[str, Any] = ({"progress": progress} if progress is not None
                                     and "progress" in inspect.signature(ev.write_evaluation_report).parameters
                                     else {})
            res = ev.write_evaluation_report(out, select=select, **extra)
            how = ("ran the evaluation with model selection" if select else
                   "evaluated the shipped configuration on the test split without re-running the model-selection "
                   "grid (run `iamp evaluate-predictor --out DIR` for it; it takes many minutes)")
    except Exception as exc:  # the predictor is optional for the planners' report
        notes.append(f"predictor evaluation failed ({exc.__class__.__name__}: {str(exc)[:200]}).")
        return None
    notes.append(f"predictor evaluation: {how}.")
    return {"how": how, "chosen": res.get("chosen"), "test": res.get("test"),
            "paper_histories": res.get("paper_histories"), "seconds": res.get("seconds"),
            "selection_run": bool(res.get("selection")), "file": "predictor_eval.json"}


def _versions() -> dict[str, Any]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("iamp", "numpy", "scipy", "cvxpy", "osqp", "clarabel", "matplotlib"):
        out[dist] = dist_version(dist)
    return out


def reproduce(out_dir: str | os.PathLike[str] = "reports", progress: ProgressFn | None = None, *,
              status: Callable[[str], None] | None = None, quick: bool = False,
              config: ReproduceConfig | None = None, scenarios: Sequence[str] = SCENARIOS) -> dict[str, Any]:
    """Run the whole reproduction and write the report into ``out_dir``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created); gets ``tables/``, ``figures/``, ``report.tex``,
        ``results.json`` and (from the predictor) ``predictor_eval.json``.
    progress : callable, optional
        ``progress(done, total)`` (the project's convention), in hundredths of a step:
        ``total = 100 × number of steps``; called as each step starts and, where the work
        reports it, within a step.
    status : callable, optional
        ``status(message)``: what the step that starts now does (``"planning paper-2: ..."``).
    quick : bool
        Small grids and few repetitions (a smoke test, well under a minute plus the
        predictor evaluation); ignored if ``config`` is given.
    config : ReproduceConfig, optional
    scenarios : sequence of str
        Built-in names (history versions; ``-poly`` fallbacks are automatic).

    Returns
    -------
    dict
        The contents of ``results.json`` (plus ``outputs``: the files written).
    """
    from iamp.comparison.figures_comparison import plot_costates, plot_value_function
    from iamp.comparison.figures_studies import plot_predictions, plot_timing, plot_zoh_convergence
    from iamp.comparison.figures_trajectory import plot_positions, plot_xy_snapshots

    cfg = config or (ReproduceConfig.quick_config() if quick else ReproduceConfig())
    start = time.perf_counter()
    out = Path(out_dir)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    notes: list[Any] = []
    scenarios = tuple(scenarios)
    total = 1 + 2 * len(scenarios) + 6
    step = _Progress(progress, status, total)
    written: list[Any] = []

    # 1. scenarios -----------------------------------------------------------------------
    step("loading scenarios and predictions")
    entries = {name: _load_scenario(name, notes) for name in scenarios}
    rows1 = {name: _table1_row(e) for name, e in entries.items()}

    # 2. planning ------------------------------------------------------------------------
    runs: dict[str, Any] = {}
    plans: dict[str, Any] = {}
    scen_out: list[Any] = []
    metrics: dict[str, Any] = {}
    for name in scenarios:
        e = entries[name]
        prob = e["problem"]
        steps = cfg.steps_one if prob.m == 1 else cfg.steps_two
        step(f"planning {name}: PMP and QP sweeps on N = {steps} ("
             + ", ".join(short_label(c.label) for c in _qp_configs(cfg, prob)) + ")")
        plan = _plan_scenario(name, prob, cfg, progress=step.sub)
        plans[name] = plan
        runs[name] = plan["results"]
        pmp = runs[name]["pmp"]
        sweeps = {lbl: [[list(n), c] for n, c in r.info.get("sweep", [])]
                  for lbl, r in runs[name].items() if lbl != "pmp" and "sweep" in (r.info or {})}
        if pmp.is_optimal():
            metrics[name] = manoeuvre_metrics(pmp)
        pred = None
        if e["predictions"] and e["predictions"][0] is not None:
            p0 = e["predictions"][0]
            pred = {"x_poly": list[Any](p0.x_poly), "t": p0.t, "x": p0.x, "v": p0.v, "a": p0.a, "model": p0.model,
                    "fit_rmse": p0.fit_rmse}
        scen_out.append({"name": name, "builtin": e["builtin"], "source": e["source"], "fallback": e["fallback"],
                         "table1": rows1[name], "paper_table1": PAPER_TABLE_I.get(name),
                         "ego": {k: getattr(prob.ego, k) for k in ("tf", "x0", "y0", "vx0", "vy0", "xf", "yf", "vxf",
                                                                   "vyf")},
                         "vehicles": [{"name": v.name, "corner": v.corner, "y": v.y, "length": v.length,
                                       "width": v.width, "safety_x": v.safety_x, "safety_y": v.safety_y,
                                       "x_poly": list[Any](v.x_poly)} for v in prob.vehicles],
                         "prediction": pred, "runs": plan["runs"], "agreement": plan["agreement"],
                         "agreement_source": plan["agreement_source"], "metrics": metrics.get(name),
                         "sweeps": sweeps})

    # 3. figures -------------------------------------------------------------------------
    figs: dict[str, Any] = {}

    def fig(key: str, paths: list[Path]) -> None:
        written.extend(paths)
        figs[key] = f"figures/{Path(paths[-1]).name}"  # the PDF

    for name in scenarios:
        step(f"figures for {name}")
        prob, pmp = entries[name]["problem"], runs[name]["pmp"]
        fd = out / "figures"
        fig(f"xy-{name}", plot_xy_snapshots(pmp, fd / f"xy-{name}",
                                            title=f"{name}: ego and vehicles every 0.5 s (lighter = earlier)"))
        fig(f"pos-{name}", plot_positions(pmp, fd / f"pos-{name}",
                                          title=f"{name}: optimal longitudinal and lateral position"))
        qp_runs = {short_label(lbl): r for lbl, r in runs[name].items()
                   if lbl != "pmp" and "refine" not in lbl and "native" not in lbl}
        if prob.m == 1:
            fig_sweeps = {short_label(lbl): (r.steps, r.info["sweep"]) for lbl, r in runs[name].items()
                          if lbl != "pmp" and r.is_optimal() and r.hold == "foh" and "sweep" in r.info
                          and "refine" not in lbl and "native" not in lbl}
            fig(f"J-{name}", plot_value_function(prob, pmp, fig_sweeps, fd / f"J-{name}",
                                                 title=f"{name}: cost against contact time"))
        fig(f"costates-{name}", plot_costates(pmp, qp_runs, fd / f"costates-{name}",
                                              title=f"{name}: PMP co-states and jumps against QP multipliers"))
    pred_entries = {}
    for name in scenarios[:3] if len(scenarios) >= 3 else scenarios:
        e = entries[name]
        if e["problem"].m != 1:
            continue
        spec_v = e["scenario"].vehicles[0]
        p0 = e["predictions"][0] if e["predictions"] else None
        pred_entries[name] = {"history_t": spec_v.history.t if spec_v.history is not None else None,
                              "history_x": spec_v.history.x if spec_v.history is not None else None,
                              "pred_t": p0.t if p0 is not None else None, "pred_x": p0.x if p0 is not None else None,
                              "x_poly": e["problem"].vehicles[0].x_poly}
    if pred_entries:
        fig("predictions", plot_predictions(pred_entries, out / "figures" / "predictions",
                                            tf=entries[next(iter(pred_entries))]["problem"].tf))

    # safety: equality against the avoidance QP (SPEC §9, §10), a table and a figure per scenario
    from iamp.comparison.safety_compare import reproduction_section

    step("safety: equality against the avoidance QP")
    safety = reproduction_section({n: entries[n]["problem"] for n in scenarios}, out / "figures",
                                  steps_one=cfg.steps_one, steps_two=cfg.steps_two)
    for key, paths in safety["figures"].items():
        fig(key, paths)

    # 4. ZOH convergence -----------------------------------------------------------------
    step("ZOH convergence study (N = " + ", ".join(map(str, cfg.zoh_steps)) + ")")
    one = [name for name in scenarios if entries[name]["problem"].m == 1]
    conv = {}
    for k, name in enumerate(one):
        conv[name] = zoh_convergence(entries[name]["problem"], cfg.zoh_steps)
        step.sub(k + 1, len(one))
    if conv:
        fig("zoh", plot_zoh_convergence({n: ([r["h"] for r in c["rows"]], [r["zoh_gap"] or np.nan for r in c["rows"]])
                                         for n, c in conv.items()}, out / "figures" / "zoh-convergence"))

    # 5. timing --------------------------------------------------------------------------
    step("timing (single QP solves at a changed node)")
    timing = _timing(entries, plans, cfg, progress=step.sub)
    fig("timing", plot_timing(timing["samples"], out / "figures" / "timing",
                              whole_plans=_whole_plan_stats(timing, cfg)))

    # 6. predictor evaluation --------------------------------------------------------------
    step("predictor evaluation")
    tables: dict[str, Any] = {}
    predictor = _predictor_evaluation(out, cfg, notes, progress=step.sub)
    if predictor is not None:
        for key in ("predictor_rmse", "predictor_selection"):
            if (out / "tables" / f"{key}.tex").is_file():
                tables[key] = f"tables/{key}.tex"
                written.append(out / "tables" / f"{key}.tex")
        written.append(out / "predictor_eval.json")

    # 7. a small closed-loop campaign, only with the [sim] extra (SPEC §11) -------------------
    from iamp.comparison.report_campaign import campaign_section, campaign_tex

    step("closed loop: a small SUMO campaign (needs the [sim] extra)")
    campaign = campaign_section(out, quick=quick, progress=step.sub)
    if campaign.get("available"):
        written.append(out / campaign["table"])
    else:
        notes.append(campaign["note"])

    # 8. tables, results.json, report.tex ----------------------------------------------------
    step("tables, results.json and report.tex")
    qual = qualitative_comparison(metrics)
    tdir = out / "tables"
    for key, text in (("scenarios", table_scenarios(entries, rows1)), ("results", table_results(scen_out, cfg)),
                      ("metrics", table_metrics(metrics)), ("agreement", table_agreement(scen_out)),
                      ("timing", table_timing(timing, scen_out)),
                      ("convergence", table_convergence(conv)), ("safety", safety["table"])):
        written.append(atomic_write_text(tdir / f"{key}.tex", text))
        tables[key] = f"tables/{key}.tex"
    res = {"produced_by": "iamp.comparison.report.reproduce", "config": asdict(cfg), "notes": notes,
           "versions": _versions(), "scenarios": scen_out, "qualitative": qual, "zoh_convergence": conv,
           "timing": timing, "predictor": predictor, "safety": safety["json"],
           "campaign": {k: v for k, v in campaign.items() if k != "table"}}
    res["runtime_s"] = time.perf_counter() - start
    tex = build_report_tex(res, out, figs, tables, entries)
    tex = tex.replace("\\end{document}", safety["section"](figs, tables["safety"]) + campaign_tex(campaign)
                      + "\\end{document}", 1)
    written.append(atomic_write_text(out / "report.tex", tex))
    res["outputs"] = sorted({str(Path(p).relative_to(out)) for p in written} | {"results.json"})
    atomic_write_text(out / "results.json", json.dumps(to_jsonable(res), indent=1, allow_nan=False) + "\n")
    step.finish()
    return res
