r"""The scenarios of ``iamp reproduce`` and their plans.

* :func:`load_scenario` — a built-in scenario through the CLI's loader (its observed history
  fed to the shipped predictor), or its ``-poly`` version with a note;
* :func:`table1_row` — the paper's Table I row of a scenario (:math:`x_{s,1}(0)` and
  :math:`v_{s,1}(0)` from the last second of the history, a quadratic fit);
* :func:`plan_scenario` — the PMP and every QP configuration (:func:`qp_configs`) on one
  problem, every pair judged by :func:`iamp.comparison.agreement.judge.compare_problem`, each
  optimal run with the role of its constraint (:func:`constraint_roles`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.agreement.judge import QPConfig
from iamp.core.problem import Problem
from iamp.core.scenario import History
from iamp.planners.qp.diagnostics import QPDiagnostics

from .config import ProgressFn, ReproduceConfig
from .records import HistoryJSON, ScenarioEntry, ScenarioPlan, Table1Row

__all__ = ["constraint_roles", "history_speed_at_0", "load_scenario", "plan_scenario", "qp_configs", "table1_row"]


def load_scenario(name: str, notes: list[str]) -> ScenarioEntry:
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
            return ScenarioEntry(name=name, builtin=spec, scenario=scenario, problem=problem, predictions=preds,
                                 source="history" if scenario.needs_prediction else "x_poly", fallback=False)
        except (IampError, ImportError, OSError) as exc:
            msg = exc.message if hasattr(exc, "message") else str(exc)
            reason = (f"the history version '{spec}' could not be predicted with the shipped predictor "
                      f"({exc.__class__.__name__}: {msg[:120]})")
    poly = f"{name}-poly"
    if poly not in builtin_names():
        raise FileNotFoundError(f"neither '{name}' nor '{poly}' is a built-in scenario")
    scenario, problem, preds = load_problem(poly)
    notes.append(f"{name}: {reason}; used '{poly}' (vehicle 1 given directly as a documented polynomial) instead.")
    return ScenarioEntry(name=name, builtin=poly, scenario=scenario, problem=problem, predictions=preds,
                         source="x_poly", fallback=True)


def history_speed_at_0(history: History) -> float:
    """Speed at ``t = 0`` from the last second of a history (quadratic fit)."""
    t, x = np.asarray(history.t), np.asarray(history.x)
    sel = t >= -1.0 - 1e-9
    if sel.sum() < 3:
        sel = np.ones_like(t, dtype=bool)
    deg = min(2, int(sel.sum()) - 1)
    c = np.polynomial.polynomial.polyfit(t[sel], x[sel], deg)
    return float(c[1]) if deg >= 1 else 0.0


def table1_row(entry: ScenarioEntry) -> Table1Row:
    """The scenario's row of the paper's Table I, with the geometry and the trajectory the planners got."""
    sc, prob = entry.scenario, entry.problem
    v = prob.vehicles[0]
    spec_v = sc.vehicles[0]
    if spec_v.history is not None:
        x0, v0 = float(spec_v.history.x[-1]), history_speed_at_0(spec_v.history)
        hist: HistoryJSON | None = {"t": spec_v.history.t, "x": spec_v.history.x}
    else:
        x0, v0 = float(v.position(0.0)), float(v.speed(0.0))
        hist = None
    return {"v_e": prob.ego.vx0, "s_xf": prob.ego.xf, "t_f": prob.tf, "x_s0": x0, "v_s0": v0,
            "x_poly": list(v.x_poly), "history": hist, "L": v.length, "W": v.width, "S_x": v.safety_x,
            "S_y": v.safety_y, "y_s": v.y, "corner": v.corner}


# --------------------------------------------------------------------------------------
# planning, agreement, metrics
# --------------------------------------------------------------------------------------


def constraint_roles(problem: Problem, jumps: NDArray[np.float64]) -> list[str]:
    """Per vehicle, ``"safety"`` where its jump pushes the ego to the safe side of the corner, else
    ``"drag"`` (:func:`iamp.comparison.agreement.signs.constraint_is_binding_for_safety` on ``Φ_i,x``)."""
    from iamp.comparison.agreement.signs import constraint_is_binding_for_safety

    return ["safety" if constraint_is_binding_for_safety(v, j[0]) else "drag" for v, j in zip(problem.vehicles, jumps)]


def qp_configs(cfg: ReproduceConfig, problem: Problem) -> list[QPConfig]:
    """The QP configurations of ``cfg`` for ``problem`` (one or several vehicles)."""
    from iamp.comparison.agreement.judge import QPConfig

    one = problem.m == 1
    steps = cfg.steps_one if one else cfg.steps_two
    confs = [tuple(c) + ("cvxpy",) * (4 - len(c)) for c in (cfg.qp_one if one else cfg.qp_two)]
    return [QPConfig(solver=s, hold=h, steps=steps, contact=c, path=p) for s, h, c, p in confs]


def plan_scenario(name: str, problem: Problem, cfg: ReproduceConfig,
                  progress: ProgressFn | None = None) -> ScenarioPlan:
    """Plan one scenario with the PMP and every QP configuration, judge every pair.

    Uses :func:`iamp.comparison.agreement.judge.compare_problem` (the same problem object to every
    planner, identical-polynomial fingerprints, verdicts with reasons, timed plans).
    """
    from iamp.comparison.agreement.judge import compare_problem

    one = problem.m == 1
    steps = cfg.steps_one if one else cfg.steps_two
    pmp_repeats = cfg.pmp_repeats if one else cfg.pmp_repeats_two
    pc = compare_problem(problem, qp_configs(cfg, problem), name=name, repeats=cfg.plan_repeats,
                         pmp_repeats=pmp_repeats, budget_s=cfg.plan_budget_s, warmup=0, progress=progress)
    results = {r.label: r.result for r in pc.runs}
    runs = [r.to_json() for r in pc.runs]
    for d in runs:
        r = results[d["label"]]
        if r.is_optimal():
            d["constraint_role"] = constraint_roles(problem, r.jumps)
            d["solve_time_s"] = r.solve_time_s
            qp = r.diagnostics.find(QPDiagnostics)
            if qp is not None and qp.grid_best is not None:
                d["grid_best"] = qp.grid_best
    return ScenarioPlan(results=results, runs=runs, agreement=pc.agreement,
                        agreement_source="iamp.comparison.agreement.compare_problem", steps=steps)
