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
6. the predictor evaluation (:func:`iamp.prediction.evaluation.evaluate.write_evaluation_report`);
7. the tables (booktabs), ``results.json`` with the raw numbers, and ``report.tex`` which
   ``\input``\ s and ``\includegraphics``\ es all of them (it compiles with ``pdflatex`` and
   the packages of ``texlive-latex-recommended``).

Every file is written atomically.  The library never prints: progress goes to the optional
``progress(step, total, message)`` callback.

This module runs the steps (:func:`reproduce`, sized by
:class:`~iamp.comparison.report.config.ReproduceConfig`); the work of each is elsewhere:
scenarios and plans :mod:`iamp.comparison.report.scenarios`, the ZOH study
:mod:`iamp.comparison.report.convergence`, timing :mod:`iamp.comparison.report.timing`, the
predictor :mod:`iamp.comparison.report.predictor`, the figures ``iamp.comparison.figures_*``,
the LaTeX :mod:`iamp.comparison.report.tables` (the tables), :mod:`iamp.comparison.report.document`
(``report.tex``) and :mod:`iamp.comparison.report.tex` (their text and number formats); the plan
metrics and the qualitative comparison are :mod:`iamp.comparison.metrics`, the paper's Table I is
:mod:`iamp.comparison.report.paper`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import cast

import numpy as np

from iamp.comparison.bounded import BoundedRow
from iamp.comparison.figures.studies import PredictionCurves
from iamp.comparison.metrics import ManoeuvreMetrics, manoeuvre_metrics, qualitative_comparison
from iamp.core.atomic import write_text as atomic_write_text
from iamp.core.plan import Plan
from iamp.planners.qp.diagnostics import QPDiagnostics

from .config import ProgressFn, ReproduceConfig
from .convergence import zoh_convergence
from .document import build_report_tex
from .machine import MACHINE_DIR, MACHINE_FILES, MACHINE_README, canonical_json, split_machine
from .paper import PAPER_TABLE_I, SCENARIOS
from .predictor import predictor_evaluation
from .records import ConfigJSON, PredictionJSON, ResultsJSON, ScenarioJSON, ScenarioPlan, ZohConvergence
from .scenarios import load_scenario, plan_scenario, qp_configs, table1_row
from .tables import (
    table_agreement,
    table_convergence,
    table_metrics,
    table_results,
    table_scenarios,
    table_timing,
)
from .tex import short_label, tex_escape
from .timing import timing_section, versions_used, whole_plan_stats

__all__ = ["ReproduceConfig", "reproduce"]


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


def reproduce(out_dir: str | os.PathLike[str] = "reports", progress: ProgressFn | None = None, *,
              status: Callable[[str], None] | None = None, quick: bool = False,
              config: ReproduceConfig | None = None, scenarios: Sequence[str] = SCENARIOS) -> ResultsJSON:
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
    from iamp.comparison.figures.comparison import plot_costates, plot_value_function
    from iamp.comparison.figures.studies import plot_predictions, plot_timing, plot_zoh_convergence
    from iamp.comparison.figures.trajectory import plot_positions, plot_xy_snapshots

    cfg = config or (ReproduceConfig.quick_config() if quick else ReproduceConfig())
    start = time.perf_counter()
    out = Path(out_dir)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / MACHINE_DIR).mkdir(parents=True, exist_ok=True)
    for old in RETIRED_OUTPUTS:  # an earlier layout's files (the staging folder starts as a copy)
        (out / old).unlink(missing_ok=True)
    notes: list[str] = []
    scenarios = tuple(scenarios)
    total = 1 + 2 * len(scenarios) + 7
    step = _Progress(progress, status, total)
    written: list[Path] = []

    # 1. scenarios -----------------------------------------------------------------------
    step("loading scenarios and predictions")
    entries = {name: load_scenario(name, notes) for name in scenarios}
    rows1 = {name: table1_row(e) for name, e in entries.items()}

    # 2. planning ------------------------------------------------------------------------
    runs: dict[str, dict[str, Plan]] = {}
    plans: dict[str, ScenarioPlan] = {}
    scen_out: list[ScenarioJSON] = []
    metrics: dict[str, ManoeuvreMetrics] = {}
    for name in scenarios:
        e = entries[name]
        prob = e.problem
        steps = cfg.steps_one if prob.m == 1 else cfg.steps_two
        step(f"planning {name}: PMP and QP sweeps on N = {steps} ("
             + ", ".join(short_label(c.label) for c in qp_configs(cfg, prob)) + ")")
        plan = plan_scenario(name, prob, cfg, progress=step.sub)
        plans[name] = plan
        runs[name] = plan.results
        pmp = runs[name]["pmp"]
        sweeps: dict[str, list[list[list[int] | float]]] = {
            lbl: [[list(n), c] for n, c in sw] for lbl, sw in _sweeps(runs[name]).items()}
        if pmp.is_optimal():
            metrics[name] = manoeuvre_metrics(pmp)
        pred: PredictionJSON | None = None
        if e.predictions and e.predictions[0] is not None:
            p0 = e.predictions[0]
            pred = {"x_poly": list(p0.x_poly), "t": p0.t, "x": p0.x, "v": p0.v, "a": p0.a, "model": p0.model,
                    "fit_rmse": p0.fit_rmse}
        scen_out.append({"name": name, "builtin": e.builtin, "source": e.source, "fallback": e.fallback,
                         "table1": rows1[name], "paper_table1": PAPER_TABLE_I.get(name),
                         "ego": {k: getattr(prob.ego, k) for k in ("tf", "x0", "y0", "vx0", "vy0", "xf", "yf", "vxf",
                                                                   "vyf")},
                         "vehicles": [{"name": v.name, "corner": v.corner, "y": v.y, "length": v.length,
                                       "width": v.width, "safety_x": v.safety_x, "safety_y": v.safety_y,
                                       "x_poly": list(v.x_poly)} for v in prob.vehicles],
                         "prediction": pred, "runs": plan.runs, "agreement": plan.agreement,
                         "agreement_source": plan.agreement_source, "metrics": metrics.get(name),
                         "sweeps": sweeps})

    # 3. figures -------------------------------------------------------------------------
    figs: dict[str, str] = {}

    def fig(key: str, paths: list[Path]) -> None:
        written.extend(paths)
        figs[key] = Path(os.path.relpath(paths[-1], out)).as_posix()  # the PDF

    for name in scenarios:
        step(f"figures for {name}")
        prob, pmp = entries[name].problem, runs[name]["pmp"]
        fd = out / "figures"
        fig(f"xy-{name}", plot_xy_snapshots(pmp, fd / f"xy-{name}",
                                            title=f"{name}: ego and vehicles every 0.5 s (lighter = earlier)"))
        fig(f"pos-{name}", plot_positions(pmp, fd / f"pos-{name}",
                                          title=f"{name}: optimal longitudinal and lateral position"))
        qp_runs = {short_label(lbl): r for lbl, r in runs[name].items()
                   if lbl != "pmp" and "refine" not in lbl and "native" not in lbl}
        if prob.m == 1:
            fig_sweeps = {short_label(lbl): (runs[name][lbl].steps, sw) for lbl, sw in _sweeps(runs[name]).items()
                          if runs[name][lbl].is_optimal() and runs[name][lbl].hold == "foh"
                          and "refine" not in lbl and "native" not in lbl}
            fig(f"J-{name}", plot_value_function(prob, pmp, fig_sweeps, fd / f"J-{name}",
                                                 title=f"{name}: cost against contact time"))
        fig(f"costates-{name}", plot_costates(pmp, qp_runs, fd / f"costates-{name}",
                                              title=f"{name}: PMP co-states and jumps against QP multipliers"))
    pred_entries: dict[str, PredictionCurves] = {}
    for name in scenarios[:3] if len(scenarios) >= 3 else scenarios:
        e = entries[name]
        if e.problem.m != 1:
            continue
        spec_v = e.scenario.vehicles[0]
        first = e.predictions[0] if e.predictions else None
        pred_entries[name] = {"history_t": spec_v.history.t if spec_v.history is not None else None,
                              "history_x": spec_v.history.x if spec_v.history is not None else None,
                              "pred_t": first.t if first is not None else None,
                              "pred_x": first.x if first is not None else None,
                              "x_poly": e.problem.vehicles[0].x_poly}
    if pred_entries:
        fig("predictions", plot_predictions(pred_entries, out / "figures" / "predictions",
                                            tf=entries[next(iter(pred_entries))].problem.tf))

    # safety: equality against the avoidance QP (SPEC §9, §10), a table and a figure per scenario
    from iamp.comparison.safety_compare import reproduction_section

    step("safety: equality against the avoidance QP")
    safety = reproduction_section({n: entries[n].problem for n in scenarios}, out / "figures",
                                  steps_one=cfg.steps_one, steps_two=cfg.steps_two)
    for key, paths in safety["figures"].items():
        fig(key, paths)

    # the bounded problem: the scenarios under a passenger car's limits (SPEC §14) ------------
    from iamp.comparison.bounded import bounded_rows
    from iamp.comparison.report.bounded import latex_table as bounded_latex

    step("the bounded problem: every planner under a passenger car's limits")
    bounded: list[BoundedRow] = []
    for k, name in enumerate(scenarios):
        prob = entries[name].problem
        bounded += bounded_rows(name, prob, steps=cfg.steps_one if prob.m <= 1 else cfg.steps_two)
        step.sub(k + 1, len(scenarios))

    step("ZOH convergence study (N = " + ", ".join(map(str, cfg.zoh_steps)) + ")")
    one = [name for name in scenarios if entries[name].problem.m == 1]
    conv: dict[str, ZohConvergence] = {}
    for k, name in enumerate(one):
        conv[name] = zoh_convergence(entries[name].problem, cfg.zoh_steps)
        step.sub(k + 1, len(one))
    if conv:
        fig("zoh", plot_zoh_convergence({n: ([r["h"] for r in c["rows"]], [r["zoh_gap"] or np.nan for r in c["rows"]])
                                         for n, c in conv.items()}, out / "figures" / "zoh-convergence"))

    # 5. timing --------------------------------------------------------------------------
    step("timing (single QP solves at a changed node)")
    timing = timing_section(entries, plans, cfg, progress=step.sub)
    fig("timing", plot_timing(timing["samples"], out / MACHINE_DIR / "timing",
                              whole_plans=whole_plan_stats(timing, cfg)))

    # 6. predictor evaluation --------------------------------------------------------------
    step("predictor evaluation")
    tables: dict[str, str] = {}
    predictor = predictor_evaluation(out, cfg, notes, progress=step.sub)
    if predictor is not None:
        for key in ("predictor_rmse", "predictor_selection"):
            if (out / "tables" / f"{key}.tex").is_file():
                tables[key] = f"tables/{key}.tex"
                written.append(out / "tables" / f"{key}.tex")
        written.append(out / "predictor_eval.json")

    # 7. a small closed-loop campaign, only with the [sim] extra (SPEC §11) -------------------
    from .campaign import campaign_plan_times, campaign_section, campaign_tex

    step("closed loop: a small SUMO campaign (needs the [sim] extra)")
    campaign = campaign_section(out, quick=quick, progress=step.sub)
    if campaign["available"] and "table" in campaign:
        written.append(out / campaign["table"])
    elif "note" in campaign:
        notes.append(campaign["note"])

    # 8. tables, results.json, report.tex ----------------------------------------------------
    step("tables, results.json and report.tex")
    qual = qualitative_comparison(metrics)
    tdir = out / "tables"
    for key, text in (("scenarios", table_scenarios(entries, rows1)), ("results", table_results(scen_out, cfg)),
                      ("metrics", table_metrics(metrics)), ("agreement", table_agreement(scen_out)),
                      ("convergence", table_convergence(conv)), ("safety", safety["table"]),
                      ("bounded", bounded_latex(bounded))):
        written.append(atomic_write_text(tdir / f"{key}.tex", text))
        tables[key] = f"tables/{key}.tex"
    mdir = out / MACHINE_DIR
    written.append(atomic_write_text(mdir / "timing.tex",
                                     table_timing(timing, scen_out, campaign_plan_times(campaign))))
    tables["timing"] = f"{MACHINE_DIR}/timing.tex"
    cfg_json = cast(ConfigJSON, asdict(cfg))  # ReproduceConfig's fields
    res: ResultsJSON = {"produced_by": "iamp.comparison.report.reproduce", "config": cfg_json, "notes": notes,
           "versions": versions_used(), "scenarios": scen_out, "qualitative": qual, "zoh_convergence": conv,
           "timing": timing, "predictor": predictor, "safety": safety["json"],
           "campaign": {k: v for k, v in campaign.items() if k != "table"},
           "bounded": [r.to_json() for r in bounded]}
    bounded_tex = ("\\section{The bounded problem}\nThe scenarios under a passenger car's limits (SPEC 14): "
                   "which become infeasible, what the bounds cost.\n\\inputhere{" + tables["bounded"] + "}\n\n")
    tex = build_report_tex(res, out, figs, tables, entries,
                           extra=safety["section"](figs, tables["safety"]) + campaign_tex(campaign) + bounded_tex)
    written.append(atomic_write_text(out / "report.tex", tex))
    written += [mdir / "README.md", mdir / "timing.json", mdir / "environment.tex"]
    res["outputs"] = sorted({Path(p).relative_to(out).as_posix() for p in written} | {"results.json"})
    res["runtime_s"] = time.perf_counter() - start
    kept, machine = split_machine(res)
    kept["machine_dependent"] = {"file": f"{MACHINE_DIR}/timing.json", "keys_moved_there": sorted(machine),
                                 "files": list(MACHINE_FILES)}
    atomic_write_text(out / "results.json", canonical_json(kept))
    atomic_write_text(mdir / "timing.json", canonical_json({"produced_by": res["produced_by"], "values": machine}))
    atomic_write_text(mdir / "README.md", MACHINE_README)
    atomic_write_text(mdir / "environment.tex", environment_tex(res))
    step.finish()
    return res


#: Files an earlier version of the reproduction wrote and this one writes elsewhere (removed).
RETIRED_OUTPUTS = ("tables/timing.tex", "figures/timing.png", "figures/timing.pdf")


def environment_tex(res: ResultsJSON) -> str:
    """The report's sentence on the run time and the versions (``timing/environment.tex``)."""
    versions = res["versions"]
    return (f"Generated in {res['runtime_s']:.0f}\\,s by \\texttt{{iamp reproduce}}; "
            f"Python {tex_escape(versions.get('python') or '?')}, "
            + ", ".join(f"{tex_escape(k)} {tex_escape(v)}" for k, v in versions.items() if k != "python" and v)
            + ".\n")


def _sweeps(runs: Mapping[str, Plan]) -> dict[str, list[tuple[tuple[int, ...], float]]]:
    """Each QP run's contact-node sweep (``QPDiagnostics.sweep``: ``(nodes, cost)``), by label."""
    out: dict[str, list[tuple[tuple[int, ...], float]]] = {}
    for lbl, r in runs.items():
        qp = r.diagnostics.find(QPDiagnostics) if lbl != "pmp" else None
        if qp is not None and qp.sweep is not None:
            out[lbl] = qp.sweep
    return out
