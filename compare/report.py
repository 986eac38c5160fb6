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
"""

from __future__ import annotations

import json
import math
import os
import platform
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from iamp.atomic import write_text as atomic_write_text  # re-exported for callers

__all__ = ["ReproduceConfig", "reproduce", "atomic_write_text", "PAPER_TABLE_I", "SCENARIOS"]

#: The paper's Table I (SPEC §8) and the qualitative behaviour of vehicle 1 before t = 0.
PAPER_TABLE_I = {
    "paper-1": {"scenario": 1, "v_e": 20.0, "s_xf": 85.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 18.0,
                "before": "constant speed"},
    "paper-2": {"scenario": 2, "v_e": 20.0, "s_xf": 73.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 20.0,
                "before": "decelerating"},
    "paper-3": {"scenario": 3, "v_e": 20.0, "s_xf": 90.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 13.0,
                "before": "accelerating"},
}
SCENARIOS = ("paper-1", "paper-2", "paper-3", "two-vehicle")
PAPER_FIG = {"paper-1": (4, 7), "paper-2": (5, 8), "paper-3": (6, 9)}
SOLVER_NAMES = {"clarabel": "Clarabel", "osqp": "OSQP"}


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
    qp_one: tuple = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "zoh", "grid", "cvxpy"), ("clarabel", "foh", "refine", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    qp_two: tuple = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    zoh_steps: tuple = (25, 50, 100, 200, 400)
    plan_repeats: int = 3
    plan_budget_s: float = 4.0
    pmp_repeats: int = 200
    pmp_repeats_two: int = 20
    qp_solve_repeats: int = 30
    timing_scenarios: tuple = ("paper-1", "two-vehicle")
    predictor_eval: bool = True
    predictor_select: bool | str = "auto"
    quick: bool = False

    @classmethod
    def quick_config(cls) -> "ReproduceConfig":
        return cls(steps_one=20, steps_two=8, zoh_steps=(25, 50, 100), plan_repeats=1, pmp_repeats=20,
                   pmp_repeats_two=5, qp_solve_repeats=5, predictor_select=False, quick=True)


# --------------------------------------------------------------------------------------
# small utilities
# --------------------------------------------------------------------------------------




def _jsonable(obj):
    """Recursively convert numpy types; non-finite floats become ``None``."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    return obj


_UNICODE_TEX = {"≤": "$\\le$", "≥": "$\\ge$", "Φ": "$\\Phi$", "ν": "$\\nu$", "Δ": "$\\Delta$", "·": "$\\cdot$",
                "²": "$^2$", "³": "$^3$", "∞": "$\\infty$", "−": "-", "–": "--", "—": "---", "×": "$\\times$",
                "→": "$\\to$", "≈": "$\\approx$", "∂": "$\\partial$", "λ": "$\\lambda$", "Ω": "$\\Omega$",
                "µ": "\\textmu{}", "μ": "\\textmu{}", "‖": "$\\|$", "±": "$\\pm$", "’": "'", "“": "``", "”": "''"}


def tex_escape(text: str) -> str:
    """Escape LaTeX special characters in plain text (common non-ASCII symbols become math;
    any other non-ASCII character becomes ``?`` so that pdflatex never stops on it)."""
    rep = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
           "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "<": r"\textless{}",
           ">": r"\textgreater{}", "|": r"\textbar{}"}
    out = []
    for c in str(text):
        if c in rep:
            out.append(rep[c])
        elif ord(c) < 128:
            out.append(c)
        else:
            out.append(_UNICODE_TEX.get(c, "?"))
    return "".join(out).replace("--", "-{}-")  # no en/em dashes from option names


def _sci(x, digits: int = 1) -> str:
    """A number for a table cell: ``$1.2\\times10^{-9}$``, ``0.0312``, ``0`` or ``--``."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "--"
    x = float(x)
    if x == 0:
        return "0"
    if 1e-2 <= abs(x) < 1e4:
        return f"{x:.{digits + 2}g}"
    e = int(math.floor(math.log10(abs(x))))
    m = x / 10**e
    if round(abs(m), digits) >= 10:
        m, e = m / 10, e + 1
    return f"${m:.{digits}f}\\times10^{{{e}}}$"


def _fmt_time(s) -> str:
    """Seconds → a readable duration for a table."""
    if s is None or not math.isfinite(s):
        return "--"
    if s < 1e-3:
        return f"{s * 1e6:.0f}\\,\\textmu s" if s >= 1e-5 else f"{s * 1e6:.1f}\\,\\textmu s"
    if s < 1.0:
        return f"{s * 1e3:.2f}\\,ms" if s < 1e-2 else f"{s * 1e3:.1f}\\,ms"
    return f"{s:.2f}\\,s"


def _label(solver, hold, steps, contact="grid", path="cvxpy") -> str:
    """The run label of SPEC §5b (``qp-clarabel-foh-100``; ``-refine``, ``-native`` appended
    as :class:`iamp.compare.agreement.QPConfig` does)."""
    parts = ["qp", solver, hold, str(steps)]
    if contact != "grid":
        parts.append(contact)
    if path != "cvxpy":
        parts.append(path)
    return "-".join(parts)


def _pretty(label: str) -> str:
    if label == "pmp":
        return "PMP (jump conditions)"
    parts = label.split("-")
    if parts[0] != "qp" or len(parts) < 4:
        return tex_escape(label)
    s = f"QP {SOLVER_NAMES.get(parts[1], parts[1])} {parts[2].upper()} $N={parts[3]}$"
    extra = [p for p in parts[4:]]
    return s + "".join(f", {tex_escape(p)}" for p in extra)


class _Progress:
    def __init__(self, callback, total):
        self.callback, self.total, self.step = callback, total, 0

    def __call__(self, message: str):
        self.step += 1
        if self.callback is not None:
            self.callback(self.step, self.total, message)


# --------------------------------------------------------------------------------------
# scenarios
# --------------------------------------------------------------------------------------


def _load_scenario(name: str, notes: list) -> dict:
    """Load a built-in scenario through the CLI's loader (the shipped predictor for
    histories); fall back to ``<name>-poly`` with a note if that is impossible."""
    from iamp.cli import load_problem
    from iamp.errors import IampError
    from iamp.scenario import builtin_names

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


def _history_speed_at_0(history) -> float:
    """Speed at ``t = 0`` from the last second of a history (quadratic fit)."""
    t, x = np.asarray(history.t), np.asarray(history.x)
    sel = t >= -1.0 - 1e-9
    if sel.sum() < 3:
        sel = np.ones_like(t, dtype=bool)
    deg = min(2, int(sel.sum()) - 1)
    c = np.polynomial.polynomial.polyfit(t[sel], x[sel], deg)
    return float(c[1]) if deg >= 1 else 0.0


def _table1_row(entry: dict) -> dict:
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
            "x_poly": list(v.x_poly), "history": hist, "L": v.length, "W": v.width, "S_x": v.safety_x,
            "S_y": v.safety_y, "y_s": v.y, "corner": v.corner}


# --------------------------------------------------------------------------------------
# planning, agreement, metrics
# --------------------------------------------------------------------------------------


def _roles(problem, jumps) -> list:
    from iamp.compare.signs import constraint_is_binding_for_safety

    return ["safety" if constraint_is_binding_for_safety(v, j[0]) else "drag" for v, j in zip(problem.vehicles, jumps)]


def _run_json(label, res, problem, config=None) -> dict:
    """A run in the keys of SPEC §5b (used when :mod:`iamp.compare.agreement` is absent)."""
    ok = res.is_optimal()
    d = {"label": label, "planner": res.planner, "solver": res.solver, "hold": res.hold, "steps": res.steps,
         "path": config[3] if config else None, "contact": config[2] if config else None,
         "status": res.status, "cost": res.cost if ok else None,
         "contact_times": list(map(float, res.contact_times)) if ok else [],
         "jumps": [list(map(float, j)) for j in res.jumps] if ok else [],
         "residuals": {k: float(v) for k, v in res.residuals.items()} if ok else {},
         "time_s": _summary([res.solve_time_s])}
    if res.planner == "qp":
        failures = res.info.get("failures", [])
        d["n_solves"] = int(res.info.get("n_solves", 0))
        d["failed_candidates"] = len(failures)
        d["failed_statuses"] = sorted({str(st) for _, st in failures})
        d["unpolished_candidates"] = int(res.info.get("unpolished", 0) or 0)
    return d


def _agreement_fallback(problem, pmp, qp, label: str) -> dict:
    """PMP vs one QP run when :mod:`iamp.compare.agreement` is not available.

    Same headline keys as that module: ``cost_rel_gap`` (signed, against the PMP solved at
    the QP's own contact times ``t_Q`` — FOH's exact reference), ``state_sup_gap`` (nodal
    states, same reference), ``jump_gap`` (``max |ν − Φ(t_Q)|``) and ``continuous`` (gaps to
    the PMP optimum ``J*``, ``t*``).  ``contact_time_gap`` is measured to ``t*`` here.
    """
    from iamp.planners.pmp import ValueFunction, solve_fixed_times
    from iamp.tolerances import tol

    out = {"a": "pmp", "b": label, "cost_rel_gap": None, "contact_time_gap": None, "state_sup_gap": None,
           "jump_gap": None, "reasons": [], "notes": ["judged by iamp.compare.report's fallback"]}
    if not (pmp.is_optimal() and qp.is_optimal()):
        out["verdict"] = "disagree"
        out["reasons"].append(f"status pmp {pmp.status}, {label} {qp.status}")
        return out
    tf = problem.tf
    tn = np.asarray(qp.trajectory.t_nodes)
    same = solve_fixed_times(problem, qp.contact_times)
    j_same = same.cost()
    out["cost_rel_gap"] = (qp.cost - j_same) / abs(j_same)
    out["contact_time_gap"] = float(np.max(np.abs(qp.contact_times - pmp.contact_times)))
    out["state_sup_gap"] = float(np.max(np.abs(qp.trajectory.states(tn) - same.states(tn))))
    out["jump_gap"] = float(np.max(np.abs(qp.jumps - same.jumps)))
    h = float(np.max(np.diff(tn)))
    out["continuous"] = {"cost_rel_gap": (qp.cost - pmp.cost) / abs(pmp.cost),
                         "contact_time_gap": out["contact_time_gap"], "h": h}
    solver = qp.solver or "clarabel"
    if qp.hold == "foh":
        checks = {"cost": (abs(out["cost_rel_gap"]), tol(f"foh_{solver}_cost_rel")),
                  "jump": (out["jump_gap"] / max(1.0, float(np.max(np.abs(same.jumps)))), tol(f"dual_{solver}_rel")),
                  "state": (out["state_sup_gap"], tol(f"foh_{solver}_state_abs"))}
    else:
        checks = {"zoh_above_pmp": (-out["cost_rel_gap"], 1e-9)}
    sweep = qp.info.get("sweep")
    if sweep and qp.hold == "foh":
        J = ValueFunction(problem)
        pts = [(nodes, c) for nodes, c in sweep if np.isfinite(c)]
        T = np.array([[k * tf / qp.steps for k in nodes] for nodes, _ in pts])  # the sweep's uniform grid
        Jc = J(T)
        best_grid = float(np.min(Jc))
        checks["search_grid_optimum"] = ((j_same - best_grid) / abs(best_grid), tol(f"foh_{solver}_cost_rel"))
    for k, (v, lim) in checks.items():
        if not (np.isfinite(v) and v <= lim):
            out["reasons"].append(f"{k}: {v:.3g} > {lim:.3g}")
    out["verdict"] = "agree" if not out["reasons"] else "disagree"
    return out


def _plan_scenario(name: str, problem, cfg: ReproduceConfig) -> dict:
    """Plan one scenario with the PMP and every QP configuration, judge every pair.

    Uses :func:`iamp.compare.agreement.compare_problem` (the same problem object to every
    planner, identical-polynomial fingerprints, verdicts with reasons, timed plans); falls
    back to plain planning and :func:`_agreement_fallback` if that module is unavailable.
    """
    one = problem.m == 1
    steps = cfg.steps_one if one else cfg.steps_two
    confs = [tuple(c) + ("cvxpy",) * (4 - len(c)) for c in (cfg.qp_one if one else cfg.qp_two)]
    pmp_repeats = cfg.pmp_repeats if one else cfg.pmp_repeats_two
    try:
        from iamp.compare.agreement import QPConfig, compare_problem
    except ImportError:
        compare_problem = None
    if compare_problem is not None:
        qconfs = [QPConfig(solver=s, hold=h, steps=steps, contact=c, path=p) for s, h, c, p in confs]
        pc = compare_problem(problem, qconfs, name=name, repeats=cfg.plan_repeats, pmp_repeats=pmp_repeats,
                             budget_s=cfg.plan_budget_s, warmup=0)
        results = {r.label: r.result for r in pc.runs}
        runs = [r.to_json() for r in pc.runs]
        agreement = pc.agreement
        source = "iamp.compare.agreement.compare_problem"
    else:
        from iamp.planners.pmp import PMPPlanner
        from iamp.planners.qp import QPPlanner

        results = {"pmp": PMPPlanner().plan(problem)}
        runs = [_run_json("pmp", results["pmp"], problem)]
        for conf in confs:
            s, h, c, p = conf
            label = _label(s, h, steps, c, p)
            if p == "native":
                try:
                    from iamp.planners.native import NativeQPPlanner as cls
                except ImportError:
                    continue
            else:
                cls = QPPlanner
            results[label] = cls(steps=steps, hold=h, solver=s, contact=c).plan(problem)
            runs.append(_run_json(label, results[label], problem, conf))
        agreement = [_agreement_fallback(problem, results["pmp"], r, lbl) for lbl, r in results.items()
                     if lbl != "pmp"]
        source = "iamp.compare.report fallback (iamp.compare.agreement unavailable)"
    for d in runs:
        r = results[d["label"]]
        if r.is_optimal():
            d["constraint_role"] = _roles(problem, r.jumps)
            d["solve_time_s"] = r.solve_time_s
            if "grid_best" in r.info:
                d["grid_best"] = r.info["grid_best"]
    return {"results": results, "runs": runs, "agreement": agreement, "agreement_source": source,
            "steps": steps}


def _crossing_time(t, y, level):
    """First time ``y`` crosses ``level`` (linear interpolation), or ``None``."""
    d = y - level
    idx = np.nonzero(np.sign(d[:-1]) != np.sign(d[1:]))[0]
    if idx.size == 0:
        return None
    k = idx[0]
    return float(t[k] - d[k] * (t[k + 1] - t[k]) / (d[k + 1] - d[k]))


def _intervals(t, mask):
    """``[[start, end], ...]`` of the runs where ``mask`` holds."""
    out = []
    k = 0
    while k < len(mask):
        if mask[k]:
            j = k
            while j + 1 < len(mask) and mask[j + 1]:
                j += 1
            out.append([float(t[k]), float(t[j])])
            k = j + 1
        else:
            k += 1
    return out


#: Depth [m] beyond which the ego's point counts as inside a safety box (touching the corner at
#: ``t_i`` and numerical round-off are not "inside").
INSIDE_TOL_M = 1e-3


def manoeuvre_metrics(result) -> dict:
    """Measurable aggressiveness and safety of a plan (on a 1 ms grid).

    ``t_cross``: first crossing of the lane divider half-way between ``y0`` and vehicle 1's
    lane; ``peak_*``: max-abs acceleration / jerk; ``J_x``, ``J_y``: the cost split by axis;
    ``inside_safety_box``: time intervals where the ego's point is strictly inside a safety
    box by more than :data:`INSIDE_TOL_M` (the equality touches its corner at ``t_i`` only) and
    ``max_depth_inside_safety_box``
    the largest distance from the point to the box's boundary while inside; ``body_overlap``: where an ego body
    of vehicle 1's size overlaps a vehicle's body.
    """
    prob = result.problem
    tf = prob.tf
    t = np.linspace(0.0, tf, int(round(tf * 1000)) + 1)
    X = result.trajectory.states(t)
    U = result.trajectory.inputs(t)
    jerk = np.diff(U, axis=0) / np.diff(t)[:, None]
    v1 = prob.vehicles[0]
    divider = 0.5 * (prob.ego.y0 + v1.y)
    inside, body, depths = [], [], []
    for v in prob.vehicles:
        dx = X[:, 0] - v.position(t)
        dy = X[:, 2] - v.y
        depth = np.minimum(v.length / 2 + v.safety_x - np.abs(dx), v.width / 2 + v.safety_y - np.abs(dy))
        m_box = depth > INSIDE_TOL_M
        depths.append(float(max(np.max(depth), 0.0)))
        m_body = (np.abs(dx) < v.length) & (np.abs(dy) < v.width)
        inside.append(_intervals(t, m_box))
        body.append(_intervals(t, m_body))
    w = np.diff(t)
    return {
        "J": float(result.cost),
        "J_x": float(0.5 * np.sum(w * 0.5 * (U[:-1, 0] ** 2 + U[1:, 0] ** 2))),
        "J_y": float(0.5 * np.sum(w * 0.5 * (U[:-1, 1] ** 2 + U[1:, 1] ** 2))),
        "t_contact": [float(x) for x in result.contact_times],
        "x_contact": [float(x) for x in result.trajectory.states(result.contact_times)[:, 0]],
        "t_cross": _crossing_time(t, X[:, 2], divider),
        "lane_divider_y": divider,
        "peak_ax": float(np.max(np.abs(U[:, 0]))),
        "peak_ay": float(np.max(np.abs(U[:, 1]))),
        "peak_jerk_x": float(np.max(np.abs(jerk[:, 0]))),
        "peak_jerk_y": float(np.max(np.abs(jerk[:, 1]))),
        "min_vx": float(np.min(X[:, 1])),
        "max_vx": float(np.max(X[:, 1])),
        "final_gap_to_corner": [float(X[-1, 0] - v.corner_x(tf)) for v in prob.vehicles],
        "vehicle_speed_0": [float(v.speed(0.0)) for v in prob.vehicles],
        "vehicle_speed_tf": [float(v.speed(tf)) for v in prob.vehicles],
        "inside_safety_box": inside,
        "max_depth_inside_safety_box": depths,
        "body_overlap": body,
    }


#: (key, label, +1 if larger is more aggressive, −1 if smaller is)
AGGRESSION_MEASURES = (
    ("t_contact", "earlier contact time $t^*_1$", -1),
    ("t_cross", "earlier crossing of the lane divider", -1),
    ("peak_ay", "larger peak lateral acceleration $|u_y|$", +1),
    ("peak_jerk_y", "larger peak lateral jerk", +1),
    ("peak_ax", "larger peak longitudinal acceleration $|u_x|$", +1),
    ("J", "higher cost $J$", +1),
    ("final_gap_to_corner", "smaller final clearance $s_x(t_f) - \\mathrm{corner}_x(t_f)$ ahead of vehicle 1", -1),
)


def qualitative_comparison(metrics: dict) -> dict:
    """Scenario 2 vs 1 (paper: more aggressive) and 3 vs 1 (paper: more conservative)."""
    def val(m, key):
        v = m.get(key)
        return v[0] if isinstance(v, list) else v

    out = {}
    if "paper-1" not in metrics:
        return out
    base = metrics["paper-1"]
    for other, claim in (("paper-2", "more aggressive"), ("paper-3", "more conservative")):
        if other not in metrics:
            continue
        rows, n_agg, n_cons = [], 0, 0
        for key, label, sign in AGGRESSION_MEASURES:
            a, b = val(base, key), val(metrics[other], key)
            if a is None or b is None:
                continue
            diff = (b - a) * sign  # > 0: 'other' more aggressive on this measure
            more = "more aggressive" if diff > 0 else ("more conservative" if diff < 0 else "equal")
            n_agg += diff > 0
            n_cons += diff < 0
            rows.append({"measure": key, "label": label, "scenario_1": a, "other": b, "other_is": more})
        n = len(rows)
        observed = ("more aggressive" if n_agg > n / 2 else "more conservative" if n_cons > n / 2 else "mixed")
        out[other] = {"paper_claim": claim, "observed_majority": observed, "n_more_aggressive": int(n_agg),
                      "n_more_conservative": int(n_cons), "n_measures": n, "measures": rows,
                      "consistent_with_paper": observed == claim}
    return out


# --------------------------------------------------------------------------------------
# timing
# --------------------------------------------------------------------------------------


def _samples(fn, repeats: int) -> list[float]:
    out = []
    for _ in range(max(int(repeats), 0)):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def _summary(samples) -> dict:
    """Median / quartiles of timing samples (:func:`iamp.compare.timing.summarize` if present)."""
    s = np.asarray(samples, dtype=float)
    if s.size == 0:
        return {"n": 0, "median": None, "q1": None, "q3": None, "iqr": None}
    try:
        from iamp.compare.timing import summarize
    except ImportError:
        q1, med, q3 = np.percentile(s, [25, 50, 75])
        return {"n": int(s.size), "median": float(med), "q1": float(q1), "q3": float(q3), "iqr": float(q3 - q1),
                "min": float(s.min()), "max": float(s.max())}
    return summarize(s).to_dict()


def _node_tuples(N: int, m: int, count: int, seed: int = 0) -> list:
    """``count`` deterministic candidate node tuples spread over the sweep."""
    rng = np.random.default_rng(seed)
    return [tuple(int(k) for k in rng.choice(np.arange(1, N), size=m, replace=False)) for _ in range(count)]


def _timing(entries: dict, plans: dict, cfg: ReproduceConfig) -> dict:
    """Timing samples: the PMP plan, and one QP solve at a changed candidate node (cvxpy
    re-solve of the compiled problem, and the native path) per solver; plus the full-plan
    statistics of every run from the planning step."""
    from iamp.planners.pmp import PMPPlanner
    from iamp.planners.qp import QPPlanner

    try:
        from iamp.planners.native import build_native
    except ImportError:
        build_native = None
    samples: dict = {}
    for name in cfg.timing_scenarios:
        if name not in entries:
            continue
        prob = entries[name]["problem"]
        m = prob.m
        tag = "1 vehicle" if m == 1 else f"{m} vehicles"
        planner = PMPPlanner()
        planner.plan(prob)
        samples[f"PMP plan ({tag})"] = _samples(lambda: planner.plan(prob),
                                                cfg.pmp_repeats if m == 1 else cfg.pmp_repeats_two)
        steps = cfg.steps_one if m == 1 else cfg.steps_two
        nodes = _node_tuples(steps, m, cfg.qp_solve_repeats + 1)
        for solver in ("clarabel", "osqp"):
            qp = QPPlanner(steps, "foh", solver).build(prob)
            qp.solve_nodes(nodes[0])  # compiles the cvxpy problem
            it = iter(nodes[1:])
            samples[f"QP {solver} solve, cvxpy, N={steps} ({tag})"] = _samples(lambda: qp.solve_nodes(next(it)),
                                                                              cfg.qp_solve_repeats)
            if build_native is not None:
                nq = build_native(prob, steps, "foh", solver)
                nq.solve_nodes(nodes[0])
                it2 = iter(nodes[1:])
                samples[f"QP {solver} solve, native, N={steps} ({tag})"] = _samples(
                    lambda: nq.solve_nodes(next(it2)), cfg.qp_solve_repeats)
    plans_stats = {name: {d["label"]: d.get("time_s") for d in p["runs"]} for name, p in plans.items()}
    return {"samples": samples, "summary": {k: _summary(v) for k, v in samples.items()}, "full_plans": plans_stats,
            "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                        "platform": platform.platform(),
                        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}}


# --------------------------------------------------------------------------------------
# ZOH convergence
# --------------------------------------------------------------------------------------


def zoh_convergence(problem, steps=(25, 50, 100, 200, 400), t_contact=None, solver: str = "clarabel") -> dict:
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
    rows = []
    for N in steps:
        k = k0 * (N // base)
        t_node = np.linspace(0.0, tf, N + 1)[k]
        j_pmp = solve_fixed_times(problem, [t_node]).cost()
        z = QPPlanner(N, "zoh", solver).plan_at_nodes(problem, [k])
        f = QPPlanner(N, "foh", solver).plan_at_nodes(problem, [k])
        rows.append({"N": N, "h": tf / N, "node": k, "t_node": float(t_node), "J_pmp": j_pmp,
                     "J_zoh": z.cost if z.is_optimal() else None, "J_foh": f.cost if f.is_optimal() else None,
                     "zoh_gap": (z.cost - j_pmp) if z.is_optimal() else None,
                     "foh_gap": (f.cost - j_pmp) if f.is_optimal() else None,
                     "status_zoh": z.status, "status_foh": f.status})
    for a, b in zip(rows[:-1], rows[1:]):
        a["ratio_to_next"] = (a["zoh_gap"] / b["zoh_gap"]) if a["zoh_gap"] and b["zoh_gap"] else None
    gaps = np.array([r["zoh_gap"] if r["zoh_gap"] else np.nan for r in rows])
    hs = np.array([r["h"] for r in rows])
    ok = np.isfinite(gaps) & (gaps > 0)
    slope = float(np.polyfit(np.log(hs[ok]), np.log(gaps[ok]), 1)[0]) if ok.sum() >= 2 else None
    return {"solver": solver, "t_contact": t_c, "rows": rows, "loglog_slope": slope}


# --------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------

_GEN = "% generated by iamp.compare.report.reproduce -- do not edit\n"


def _poly_tex(c) -> str:
    terms = []
    for k, a in enumerate(c):
        if a == 0 and k > 0:
            continue
        mag = f"{abs(a):.4g}"
        var = "" if k == 0 else ("t" if k == 1 else f"t^{k}")
        body = f"{mag}\\,{var}" if var else mag
        if not terms:
            terms.append(("-" if a < 0 else "") + body)
        else:
            terms.append(("- " if a < 0 else "+ ") + body)
    return "$" + " ".join(terms) + "$"


def table_scenarios(entries: dict, rows: dict) -> str:
    paper = [n for n in SCENARIOS[:3] if n in rows]
    any_e = rows[paper[0]] if paper else next(iter(rows.values()))
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\small",
             "\\caption{Scenario settings: the paper's Table~I (left of the bar) and the vehicle-1 trajectory "
             "$x_{s,1}(t)$ the planners received (right). The paper leaves the geometry open; the documented "
             f"defaults are $L={any_e['L']:g}$\\,m, $W={any_e['W']:g}$\\,m, $S_x={any_e['S_x']:g}$\\,m, "
             f"$S_y={any_e['S_y']:g}$\\,m, $y_{{s,1}}={any_e['y_s']:g}$\\,m (corner \\texttt{{{any_e['corner']}}}); "
             "common: $s_{x0}=0$, $s_{y0}=-2$\\,m, $s_{yf}=3.75$\\,m, $v_{x0}=v_{xf}=v_e$, $v_{y0}=v_{yf}=0$. "
             "$x_{s,1}(0)$ and $v_{s,1}(0)$ are read from the observed history (or from the polynomial when the "
             "scenario gives one).}",
             "\\label{tab:scenarios}",
             "\\resizebox{\\linewidth}{!}{%",
             "\\begin{tabular}{lrrrrrl|ll}", "\\toprule",
             "Scenario & $v_e$ [m/s] & $s_{xf}$ [m] & $t_f$ [s] & $x_{s,1}(0)$ [m] & $v_{s,1}(0)$ [m/s] & "
             "vehicle 1 before $t=0$ & $x_{s,1}(t)$ [m] given to the planners & source \\\\", "\\midrule"]
    for name in paper:
        r, p = rows[name], PAPER_TABLE_I[name]
        src = entries[name]["source"]
        how = ("predicted (MTD)" if src == "history"
               else f"given (\\texttt{{{tex_escape(entries[name]['builtin'])}}})")
        lines.append(f"{p['scenario']} & {r['v_e']:g} & {r['s_xf']:g} & {r['t_f']:g} & {r['x_s0']:.2f} & "
                     f"{r['v_s0']:.2f} & {p['before']} & {_poly_tex(r['x_poly'])} & {how} \\\\")
    lines += ["\\midrule",
              "\\multicolumn{9}{l}{Paper's Table~I values: $x_{s,1}(0)=-15$\\,m in all three; "
              "$v_{s,1}(0) = 18, 20, 13$\\,m/s; $s_{xf} = 85, 73, 90$\\,m; $v_e=20$\\,m/s; $t_f=5$\\,s.} \\\\",
              "\\bottomrule", "\\end{tabular}}", "\\end{table}", ""]
    if "two-vehicle" in entries:
        prob = entries["two-vehicle"]["problem"]
        lines += ["\\begin{table}[H]", "\\centering", "\\small",
                  "\\caption{The two-vehicle scenario (beyond the paper's simulations; its Fig.~2): vehicle 1 behind "
                  "in the target lane, vehicle 2 ahead in the current lane. Ego: "
                  f"$v_e={prob.ego.vx0:g}$\\,m/s, $s_{{xf}}={prob.ego.xf:g}$\\,m, $t_f={prob.tf:g}$\\,s.}}",
                  "\\label{tab:two-vehicle}",
                  "\\begin{tabular}{llrrrrrl}", "\\toprule",
                  "Vehicle & corner & $y_s$ [m] & $L$ & $W$ & $S_x$ & $S_y$ & $x_s(t)$ [m] \\\\", "\\midrule"]
        for i, v in enumerate(prob.vehicles):
            lines.append(f"{i + 1} ({tex_escape(v.name)}) & \\texttt{{{v.corner}}} & {v.y:g} & {v.length:g} & "
                         f"{v.width:g} & {v.safety_x:g} & {v.safety_y:g} & {_poly_tex(v.x_poly)} \\\\")
        lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def table_results(scen: list, cfg: ReproduceConfig) -> str:
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\footnotesize",
             "\\caption{Results per scenario and planner. $J=\\frac12\\int_0^{t_f}(u_x^2+u_y^2)\\,dt$ "
             "[m$^2$/s$^3$] on each planner's own solution; $t_i$ the contact time with vehicle $i$; for the PMP "
             "the co-state jumps $\\Phi_i$, for the QP the multipliers $\\nu_i$ of $s(t_i)-\\mathrm{corner}_i=0$ "
             "(SPEC~\\S3.3: $\\nu_i=\\Phi_i$ at equal contact times). Role: \\emph{safety} when the equality pushes "
             "the ego to the safe side of the corner (for a front corner $\\Phi_{i,x}<0$), \\emph{drag} when it "
             "pulls the ego towards the obstacle. The QP sweeps every interior grid node "
             f"($N={cfg.steps_one}$ for one vehicle; every ordered pair of nodes on $N={cfg.steps_two}$ for two "
             "vehicles, to keep the report to minutes); \\emph{refine} then searches off the grid.}",
             "\\label{tab:results}",
             "\\begin{tabular}{llrrrrl}", "\\toprule",
             "Scenario & Planner & $J$ & $t_i$ [s] & $\\Phi_{i,x}$ / $\\nu_{i,x}$ & $\\Phi_{i,y}$ / $\\nu_{i,y}$ & "
             "role \\\\", "\\midrule"]
    for si, s in enumerate(scen):
        if si:
            lines.append("\\midrule")
        for ri, run in enumerate(s["runs"]):
            name = tex_escape(s["name"]) if ri == 0 else ""
            if run["status"] != "optimal":
                lines.append(f"{name} & {_pretty(run['label'])} & \\multicolumn{{5}}{{l}}{{status "
                             f"{tex_escape(run['status'])} (no cost reported)}} \\\\")
                continue
            for i, (t, j) in enumerate(zip(run["contact_times"], run["jumps"])):
                head = (f"{name} & {_pretty(run['label'])} & {run['cost']:.4f}" if i == 0 else " & & ")
                lines.append(f"{head} & {t:.4f} & {j[0]:.4f} & {j[1]:.4f} & {run['constraint_role'][i]} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def _intervals_tex(iv) -> str:
    if not iv:
        return "none"
    return ", ".join(f"{a:.2f}--{b:.2f}" for a, b in iv)


def table_metrics(metrics: dict) -> str:
    names = [n for n in SCENARIOS[:3] if n in metrics]
    rows = [("$J$ [m$^2$/s$^3$]", lambda m: f"{m['J']:.2f}"),
            ("$J_x$ / $J_y$ (longitudinal / lateral)", lambda m: f"{m['J_x']:.2f} / {m['J_y']:.2f}"),
            ("contact time $t^*_1$ [s]", lambda m: f"{m['t_contact'][0]:.3f}"),
            ("$s_x(t^*_1)$ [m]", lambda m: f"{m['x_contact'][0]:.2f}"),
            ("lane-divider crossing [s]", lambda m: "--" if m["t_cross"] is None else f"{m['t_cross']:.3f}"),
            ("peak $|u_y|$ [m/s$^2$]", lambda m: f"{m['peak_ay']:.2f}"),
            ("peak lateral jerk [m/s$^3$]", lambda m: f"{m['peak_jerk_y']:.2f}"),
            ("peak $|u_x|$ [m/s$^2$]", lambda m: f"{m['peak_ax']:.2f}"),
            ("min / max $v_x$ [m/s]", lambda m: f"{m['min_vx']:.2f} / {m['max_vx']:.2f}"),
            ("$s_x(t_f) - $ corner$_x(t_f)$ [m]", lambda m: f"{m['final_gap_to_corner'][0]:.2f}"),
            ("ego inside safety box [s]", lambda m: _intervals_tex(m["inside_safety_box"][0])),
            ("max depth inside the box [m]", lambda m: f"{m['max_depth_inside_safety_box'][0]:.3f}"),
            ("ego body overlaps vehicle 1 [s]", lambda m: _intervals_tex(m["body_overlap"][0]))]
    head = " & ".join(f"Scenario {PAPER_TABLE_I[n]['scenario']}" for n in names)
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\small",
             "\\caption{Measurable aggressiveness and safety of the PMP plans (1\\,ms grid). The lane divider is "
             "half-way between $s_{y0}$ and $y_{s,1}$. The equality constraint touches the safety box's corner at "
             "$t^*_1$ only; the last two rows check the box and the bodies (ego drawn with vehicle 1's $L\\times W$) "
             "over the whole horizon.}",
             "\\label{tab:metrics}",
             "\\begin{tabular}{l" + "r" * len(names) + "}", "\\toprule", f"Measure & {head} \\\\", "\\midrule"]
    for label, fn in rows:
        lines.append(f"{label} & " + " & ".join(fn(metrics[n]) for n in names) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def _short(label: str) -> str:
    return "PMP" if label == "pmp" else (label[3:] if label.startswith("qp-") else label)


def table_agreement(scen: list) -> str:
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\footnotesize",
             "\\caption{Agreement of the planners, pair by pair (\\texttt{iamp.compare.agreement}). A QP is judged "
             "against its exact reference at its \\emph{own} contact times $t_Q$ (grid nodes): for FOH the PMP solved "
             "at $t_Q$, for ZOH the closed-form ZOH optimum. $\\Delta J$: signed relative cost gap to the PMP at $t_Q$ "
             "(the $O(h^2)$ excess for ZOH); $\\|\\Delta x\\|_\\infty$: nodal states; $|\\nu-\\Phi|$: multipliers "
             "against the PMP jumps at $t_Q$; $|\\Delta t|$: distance of $t_Q$ to the PMP's optimum restricted to the "
             "grid. Right block: against the continuous PMP optimum $(t^*, J^*)$ --- the price of the grid. "
             "\\emph{agree} means every check of the module passed (solver precision, recomputed KKT residuals, "
             "constraint residuals, the sweep found the grid optimum, $J_\\mathrm{ZOH}$ inside its $O(h^2)$ "
             "bracket).}",
             "\\label{tab:agreement}",
             "\\resizebox{\\linewidth}{!}{%",
             "\\begin{tabular}{llrrrr|rrl}", "\\toprule",
             "Scenario & pair & $\\Delta J$ at $t_Q$ & $\\|\\Delta x\\|_\\infty$ & $|\\nu-\\Phi|$ & $|\\Delta t|$ grid & "
             "$(J-J^*)/J^*$ & $|t_Q-t^*|$ & verdict \\\\", "\\midrule"]
    for si, s in enumerate(scen):
        if si:
            lines.append("\\midrule")
        for ri, a in enumerate(s["agreement"]):
            name = tex_escape(s["name"]) if ri == 0 else ""
            pair = f"\\texttt{{{tex_escape(_short(a['a']))}}} vs \\texttt{{{tex_escape(_short(a['b']))}}}"
            cont = a.get("continuous") or {}
            verdict = tex_escape(a.get("verdict", "--"))
            if a.get("verdict") not in ("agree", None):
                verdict = f"\\textbf{{{verdict}}}"
            lines.append(f"{name} & {pair} & {_sci(a.get('cost_rel_gap'))} & {_sci(a.get('state_sup_gap'))} & "
                         f"{_sci(a.get('jump_gap'))} & {_sci(a.get('contact_time_gap'))} & "
                         f"{_sci(cont.get('cost_rel_gap'))} & {_sci(cont.get('contact_time_gap'))} & {verdict} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}}", "\\end{table}", ""]
    return "\n".join(lines)


def agreement_notes(scen: list) -> list:
    """``(scenario, pair, kind, text)`` for every reason and note of the agreement checks."""
    out = []
    for s in scen:
        for a in s["agreement"]:
            pair = f"{_short(a['a'])} vs {_short(a['b'])}"
            out += [(s["name"], pair, "reason", r) for r in a.get("reasons", [])]
            out += [(s["name"], pair, "note", n) for n in a.get("notes", [])]
    return out


def table_timing(timing: dict, scen: list) -> str:
    m = timing["machine"]
    load = m.get("load_average_1min")
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\small",
             "\\caption{Wall time: median and quartiles over $n$ samples on this machine "
             f"(Python {tex_escape(m['python'])}, {m['cpu_count']} CPU cores"
             + (f", 1-min load average {load:.1f} when the samples ended" if load is not None else "") +
             "). Top: one PMP plan (global contact-time search included) and one QP solve at a changed candidate "
             "node --- through cvxpy (compiled once, parameters changed) and through the native solver interface. "
             "Bottom: whole plans including the QP's contact-time sweep (few samples; a sweep is timed once if it "
             "takes longer than the budget). Measurements, not guarantees.}",
             "\\label{tab:timing}",
             "\\begin{tabular}{lrrrr}", "\\toprule",
             "What is timed & $n$ & median & $q_1$ & $q_3$ \\\\", "\\midrule"]
    for k, st in timing["summary"].items():
        if st["n"]:
            lines.append(f"{tex_escape(k)} & {st['n']} & {_fmt_time(st['median'])} & {_fmt_time(st['q1'])} & "
                         f"{_fmt_time(st['q3'])} \\\\")
    lines.append("\\midrule")
    lines.append("\\multicolumn{5}{l}{\\emph{whole plans}} \\\\")
    for s in scen:
        for d in s["runs"]:
            st = d.get("time_s")
            if not st or not st.get("n"):
                continue
            lines.append(f"{tex_escape(s['name'])}: {_pretty(d['label'])} & {st['n']} & {_fmt_time(st['median'])} & "
                         f"{_fmt_time(st['q1'])} & {_fmt_time(st['q3'])} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def table_convergence(conv: dict) -> str:
    names = list(conv)
    first = conv[names[0]]
    lines = [_GEN, "\\begin{table}[H]", "\\centering", "\\small",
             "\\caption{ZOH convergence: $J_\\mathrm{ZOH}-J_\\mathrm{PMP}$ at one fixed contact node per scenario "
             "(Clarabel), with the ratio to the next row (4 for $O(h^2)$ when $N$ doubles) and the FOH gap "
             "(exact up to solver precision). Contact times: " +
             ", ".join(f"{tex_escape(n)} $t={conv[n]['t_contact']:.2f}$\\,s" for n in names) +
             "; fitted log--log slopes: " +
             ", ".join(f"{conv[n]['loglog_slope']:.3f}" if conv[n]["loglog_slope"] is not None else "--"
                       for n in names) + ".}",
             "\\label{tab:convergence}",
             "\\begin{tabular}{rr" + "rr" * len(names) + "r}", "\\toprule",
             " & & " + " & ".join(f"\\multicolumn{{2}}{{c}}{{{tex_escape(n)}}}" for n in names) +
             f" & FOH gap ({tex_escape(names[0])}) \\\\",
             "$N$ & $h$ [s] & " + " & ".join("ZOH gap & ratio" for _ in names) + " & \\\\", "\\midrule"]
    for k, r in enumerate(first["rows"]):
        cells = []
        for n in names:
            rr = conv[n]["rows"][k]
            cells.append(_sci(rr["zoh_gap"], 2))
            cells.append("--" if rr.get("ratio_to_next") is None else f"{rr['ratio_to_next']:.3f}")
        lines.append(f"{r['N']} & {r['h']:.4f} & " + " & ".join(cells) + f" & {_sci(r['foh_gap'])} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------
# report.tex
# --------------------------------------------------------------------------------------


def _figure(path: str, caption: str, label: str, width: str = "\\linewidth") -> str:
    return ("\\begin{figure}[H]\n\\centering\n"
            f"\\includegraphics[width={width}]{{{path}}}\n\\caption{{{caption}}}\n\\label{{{label}}}\n"
            "\\end{figure}\n")


def _qualitative_tex(qual: dict, metrics: dict | None = None) -> str:
    if not qual:
        return "The qualitative comparison needs scenarios 1--3.\n"
    out = ["The paper reports that the ego plans a \\emph{more aggressive} manoeuvre in scenario~2 and a "
           "\\emph{more conservative} one in scenario~3 than in scenario~1, without defining the terms. We measure "
           "aggressiveness by seven quantities of the PMP plan (Table~\\ref{tab:metrics}): an earlier contact time "
           "$t^*_1$, an earlier crossing of the lane divider, a larger peak lateral acceleration, a larger peak "
           "lateral jerk, a larger peak longitudinal acceleration, a higher cost $J$ and a smaller final clearance "
           "ahead of vehicle 1's safety region each count as more aggressive. (The paper chose $s_{xf}$ per "
           "scenario \\emph{to ensure a safety distance at the final time}, so the last measure is set largely by "
           "Table~I itself.)\n\\begin{itemize}"]
    for other, q in qual.items():
        k = PAPER_TABLE_I[other]["scenario"]
        detail = "; ".join(f"{r['label']}: {r['other_is']} ({r['scenario_1']:.3g} vs {r['other']:.3g})"
                           for r in q["measures"])
        verdict = ("consistent with the paper" if q["consistent_with_paper"] else
                   "\\textbf{not} what the paper reports")
        out.append(f"\\item Scenario {k} vs scenario 1 (paper: {q['paper_claim']}): more aggressive on "
                   f"{q['n_more_aggressive']} and more conservative on {q['n_more_conservative']} of "
                   f"{q['n_measures']} measures, so by majority \\emph{{{q['observed_majority']}}} --- {verdict}. "
                   f"Details (scenario 1 vs {k}): {detail}."
                   + (_speeds_tex(metrics, other, k) if metrics else ""))
    out.append("\\end{itemize}\n")
    return "\n".join(out)


def _speeds_tex(metrics: dict, other: str, k: int) -> str:
    a, b = metrics.get("paper-1"), metrics.get(other)
    if not a or not b:
        return ""
    return (f" Speeds: vehicle 1 is predicted from {b['vehicle_speed_0'][0]:.1f} to {b['vehicle_speed_tf'][0]:.1f}\\,m/s "
            f"(scenario 1: {a['vehicle_speed_0'][0]:.1f} to {a['vehicle_speed_tf'][0]:.1f}\\,m/s) and the ego's "
            f"$v_x$ spans {b['min_vx']:.1f}--{b['max_vx']:.1f}\\,m/s (scenario 1: {a['min_vx']:.1f}--{a['max_vx']:.1f}"
            "\\,m/s).")


def _safety_tex(metrics: dict) -> str:
    """One paragraph: does the single-instant equality keep the ego out of the box?"""
    items = []
    for name in SCENARIOS:
        m = metrics.get(name)
        if m is None:
            continue
        for i, (box, depth, body) in enumerate(zip(m["inside_safety_box"], m["max_depth_inside_safety_box"],
                                                  m["body_overlap"])):
            if box or body:
                items.append(f"\\item {tex_escape(name)}, vehicle {i + 1}: the ego's point is inside the safety box "
                             f"during {_intervals_tex(box)}\\,s (up to {depth:.2g}\\,m deep)"
                             + (f", and the bodies overlap during {_intervals_tex(body)}\\,s --- a collision"
                                if body else "") + ".")
    head = ("\\paragraph{Safety over the whole horizon.} The paper's constraint is an equality at one free instant "
            "$t_i$: the ego touches the corner of the safety region then, and nothing is required before or after. ")
    if not items:
        return head + "In this run the ego stays outside every safety box over the whole horizon.\n"
    return (head + "In this run it does not keep the ego out of the safety region everywhere:\n\\begin{itemize}\n"
            + "\n".join(items) + "\n\\end{itemize}\n")


def _meaning_tex(vehicle, phi_x: float, i: int) -> str:
    from iamp.compare.signs import constraint_is_binding_for_safety

    if phi_x == 0:
        return f"$\\Phi_{{{i},x}}=0$: the corner lies on the unconstrained path."
    side = "ahead of" if phi_x > 0 else "behind"
    role = ("a real safety constraint (it pushes the ego to the safe side of the corner)"
            if constraint_is_binding_for_safety(vehicle, phi_x)
            else "not a safety constraint: it drags the ego towards the obstacle")
    return (f"$\\Phi_{{{i},x}}={phi_x:.4g}{'>' if phi_x > 0 else '<'}0$: without the equality the ego would be "
            f"{side} the {vehicle.corner.split('-')[0]} corner of vehicle {i}; the equality is {role}.")


def build_report_tex(res: dict, out: Path, figs: dict, tables: dict, entries: dict) -> str:
    cfg = res["config"]
    metrics_by_name = {s["name"]: s["metrics"] for s in res["scenarios"] if s.get("metrics")}
    L = ["% generated by iamp.compare.report.reproduce -- do not edit",
         "\\documentclass[10pt,a4paper]{article}",
         "\\usepackage[margin=2cm]{geometry}",
         "\\usepackage{lmodern}",
         "\\usepackage[T1]{fontenc}",
         "\\usepackage{textcomp}",
         "\\usepackage{amsmath}",
         "\\usepackage{booktabs}",
         "\\usepackage{graphicx}",
         "\\usepackage{float}",
         "\\usepackage{caption}",
         "\\captionsetup{font=small}",
         "% tables written by other modules may ask for [t]; keep them where they are input",
         "\\makeatletter",
         "\\newcommand{\\inputhere}[1]{\\begingroup\\renewenvironment{table}[1][]"
         "{\\@float{table}[H]}{\\end@float}\\input{#1}\\endgroup}",
         "\\makeatother",
         "\\title{Interaction-aware lane-change planning: reproduction report}",
         f"\\author{{generated by \\texttt{{iamp reproduce}}{' (quick mode)' if cfg['quick'] else ''}}}",
         "\\date{}",
         "\\begin{document}",
         "\\maketitle",
         "This report reproduces the simulations of \\emph{Interaction-Aware Vehicle Motion Planning with "
         "Collision Avoidance Constraints in Highway Traffic} (Kim, Kim and Han): the PMP planner with "
         "interior-point collision constraints at free contact times, fed by the MTD Markov-chain predictor, on "
         "the paper's three scenarios (Table~I, Figs.~4--9), and goes beyond them: a two-vehicle scenario, the "
         "discretised QP (the MPC baseline) on Clarabel and OSQP, the cost as a function of the contact time, "
         "co-state jumps against QP multipliers, the ZOH discretisation error and solve times. All numbers are "
         "in \\texttt{results.json}.",
         ""]
    if res["notes"]:
        L.append("\\paragraph{Notes on this run.}")
        L.append("\\begin{itemize}\\raggedright\\sloppy")
        L += [f"\\item {tex_escape(n)}" for n in res["notes"]]
        L.append("\\end{itemize}")
    L += ["\\section{Scenarios}", f"\\input{{{tables['scenarios']}}}"]
    if "predictions" in figs:
        L.append(_figure(figs["predictions"], "Vehicle 1 in the paper's scenarios: observed 3\\,s history, the "
                         "predictor's expected trajectory and the least-squares cubic handed to both planners.",
                         "fig:predictions", "0.75\\linewidth"))
    L += ["\\section{Results}", f"\\input{{{tables['results']}}}", "\\paragraph{What the jumps mean.}",
          "\\begin{itemize}"]
    for s in res["scenarios"]:
        pmp = next((r for r in s["runs"] if r["label"] == "pmp"), None)
        if pmp is None or pmp["status"] != "optimal":
            continue
        prob = entries[s["name"]]["problem"]
        for i, (v, j) in enumerate(zip(prob.vehicles, pmp["jumps"])):
            L.append(f"\\item {tex_escape(s['name'])}: {_meaning_tex(v, j[0], i + 1)}")
    L.append("\\end{itemize}")
    L += [f"\\input{{{tables['metrics']}}}", _safety_tex(metrics_by_name),
          "\\subsection{Scenario 2 more aggressive, scenario 3 more conservative?}", _qualitative_tex(res["qualitative"], metrics_by_name)]
    L.append("\\section{The paper's figures}")
    for name in SCENARIOS[:3]:
        if f"xy-{name}" not in figs:
            continue
        k = PAPER_TABLE_I[name]["scenario"]
        f4, _ = PAPER_FIG[name]
        behaviour = {1: "travels at a constant velocity", 2: "decelerates", 3: "accelerates"}[k]
        L.append(_figure(figs[f"xy-{name}"], f"(Paper Fig.~{f4}.) Ego (green) and vehicle 1 (orange) every 0.5\\,s "
                         f"in the $(x,y)$ plane, where vehicle 1 {behaviour} in the adjacent lane (scenario {k}). "
                         "Thin red boxes: the safety regions $x_{s,1}(t)\\pm(L/2+S_x)$ by $y_{s,1}\\pm(W/2+S_y)$; "
                         "dashed: the safety region and body at $t^*_1$; star: the contact corner. Lane lines "
                         "half-way between the lane centres $s_{y0}$ and $y_{s,1}$.", f"fig:xy-{name}"))
    for name in SCENARIOS[:3]:
        if f"pos-{name}" not in figs:
            continue
        k = PAPER_TABLE_I[name]["scenario"]
        _, f7 = PAPER_FIG[name]
        L.append(_figure(figs[f"pos-{name}"], f"(Paper Fig.~{f7}.) Optimal longitudinal and lateral position "
                         f"(scenario {k}); the safety-critical lines at $t^*_1$ are dashed in red (vertical at "
                         "$t^*_1$, horizontal at the corner coordinate).", f"fig:pos-{name}", "0.7\\linewidth"))
    if "xy-two-vehicle" in figs:
        L.append("\\section{Two vehicles}")
        L.append(_figure(figs["xy-two-vehicle"], "Two-vehicle scenario: ego, vehicle 1 (behind, target lane) and "
                         "vehicle 2 (ahead, current lane) every 0.5\\,s with their safety regions.",
                         "fig:xy-two-vehicle"))
        L.append(_figure(figs["pos-two-vehicle"], "Two-vehicle scenario: positions with the safety-critical lines "
                         "at both contact times.", "fig:pos-two-vehicle", "0.7\\linewidth"))
    L.append("\\section{PMP against the discretised QP}")
    L.append(f"\\input{{{tables['agreement']}}}")
    an = agreement_notes(res["scenarios"])
    if an:
        L.append("\\paragraph{Reasons and notes of the agreement checks.}")
        L.append("\\begin{itemize}\\raggedright")
        for name, pair, kind, text in an[:40]:
            L.append(f"\\item {tex_escape(name)}, {tex_escape(pair)} ({kind}): {tex_escape(text)}")
        if len(an) > 40:
            L.append(f"\\item \\dots\\ and {len(an) - 40} more in \\texttt{{results.json}}.")
        L.append("\\end{itemize}")
    for name in SCENARIOS[:3]:
        if f"J-{name}" in figs:
            L.append(_figure(figs[f"J-{name}"], f"{tex_escape(name)}: the fixed-contact-time optimal cost $J(t)$ "
                             "(closed form of the PMP conditions), the PMP's global $t^*$ and the QP's FOH sweep "
                             f"points ($N={cfg['steps_one']}$; Clarabel and OSQP). Every FOH sweep point lies on "
                             "$J(t)$; the sweep's best is the best grid node, within $h/2$ of $t^*$.",
                             f"fig:J-{name}"))
    for name in SCENARIOS:
        if f"costates-{name}" in figs:
            L.append(_figure(figs[f"costates-{name}"], f"{tex_escape(name)}: co-states $p_1..p_4$ of the PMP "
                             "with their jumps at $t_i$ (red), and the jumps $\\Phi_i$ against the QP multipliers "
                             "$\\nu_i$ of the collision constraint, each at its planner's own contact time "
                             "($\\nu_x$ vs the $p_1$ jump, $\\nu_y$ vs the $p_3$ jump). The grey curve is "
                             "$\\Phi(t)$ of the PMP solved at a fixed contact time $t$: the QP's $\\nu$ lies on it.",
                             f"fig:costates-{name}", "0.85\\linewidth"))
    L += ["\\subsection{ZOH discretisation error}", f"\\input{{{tables['convergence']}}}"]
    if "zoh" in figs:
        L.append(_figure(figs["zoh"], "ZOH gap $J_\\mathrm{ZOH}-J_\\mathrm{PMP}$ at the same contact node against "
                         "$h$; dashed: slope 2.", "fig:zoh", "0.6\\linewidth"))
    L += ["\\subsection{Solve times}", f"\\input{{{tables['timing']}}}"]
    if "timing" in figs:
        L.append(_figure(figs["timing"], "Solve-time distributions per planner configuration (log scale).",
                         "fig:timing", "0.8\\linewidth"))
    L.append("\\section{The predictor}")
    if tables.get("predictor_rmse"):
        L += ["The predictor's own evaluation (\\texttt{predictor\\_eval.json}), written by "
              "\\texttt{iamp.prediction.evaluate}:", "", f"\\inputhere{{{tables['predictor_rmse']}}}"]
        if tables.get("predictor_selection"):
            L += [f"\\inputhere{{{tables['predictor_selection']}}}"]
    else:
        L.append("The predictor evaluation was not available for this run (see the notes above).")
    L += ["\\section{Reproducibility}",
          f"Generated in {res['runtime_s']:.0f}\\,s by \\texttt{{iamp reproduce}}; "
          f"Python {tex_escape(res['versions'].get('python', '?'))}, "
          + ", ".join(f"{tex_escape(k)} {tex_escape(v)}" for k, v in res["versions"].items() if k != "python" and v)
          + ". One-vehicle QP sweeps on $N=" + str(cfg["steps_one"]) + "$, two-vehicle on $N=" + str(cfg["steps_two"])
          + "$; ZOH study on $N\\in\\{" + ", ".join(map(str, cfg["zoh_steps"])) + "\\}$.",
          "\\end{document}", ""]
    return "\n".join(L)


# --------------------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------------------


def _predictor_evaluation(out: Path, cfg: ReproduceConfig, notes: list) -> dict | None:
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
            res = ev.write_evaluation_report(out, select=select)
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


def _versions() -> dict:
    from importlib import metadata

    out = {"python": platform.python_version()}
    for dist in ("iamp", "numpy", "scipy", "cvxpy", "osqp", "clarabel", "matplotlib"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def reproduce(out_dir="reports", progress=None, *, quick: bool = False, config: ReproduceConfig | None = None,
              scenarios=SCENARIOS) -> dict:
    """Run the whole reproduction and write the report into ``out_dir``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created); gets ``tables/``, ``figures/``, ``report.tex``,
        ``results.json`` and (from the predictor) ``predictor_eval.json``.
    progress : callable, optional
        ``progress(step, total, message)``, called at the start of every step.
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
    from iamp.compare import figures as F

    cfg = config or (ReproduceConfig.quick_config() if quick else ReproduceConfig())
    start = time.perf_counter()
    out = Path(out_dir)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    notes: list = []
    scenarios = tuple(scenarios)
    total = 1 + 2 * len(scenarios) + 4
    step = _Progress(progress, total)
    written: list = []

    # 1. scenarios -----------------------------------------------------------------------
    step("loading scenarios and predictions")
    entries = {name: _load_scenario(name, notes) for name in scenarios}
    rows1 = {name: _table1_row(e) for name, e in entries.items()}

    # 2. planning ------------------------------------------------------------------------
    runs: dict = {}
    plans: dict = {}
    scen_out: list = []
    metrics: dict = {}
    for name in scenarios:
        e = entries[name]
        prob = e["problem"]
        one = prob.m == 1
        steps = cfg.steps_one if one else cfg.steps_two
        configs = [tuple(c) + ("cvxpy",) * (4 - len(c)) for c in (cfg.qp_one if one else cfg.qp_two)]
        step(f"planning {name}: PMP and QP sweeps on N = {steps} ("
             + ", ".join(_short(_label(sv, h, steps, c, pa)) for sv, h, c, pa in configs) + ")")
        plan = _plan_scenario(name, prob, cfg)
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
            pred = {"x_poly": list(p0.x_poly), "t": p0.t, "x": p0.x, "v": p0.v, "a": p0.a, "model": p0.model,
                    "fit_rmse": p0.fit_rmse}
        scen_out.append({"name": name, "builtin": e["builtin"], "source": e["source"], "fallback": e["fallback"],
                         "table1": rows1[name], "paper_table1": PAPER_TABLE_I.get(name),
                         "ego": {k: getattr(prob.ego, k) for k in ("tf", "x0", "y0", "vx0", "vy0", "xf", "yf", "vxf",
                                                                   "vyf")},
                         "vehicles": [{"name": v.name, "corner": v.corner, "y": v.y, "length": v.length,
                                       "width": v.width, "safety_x": v.safety_x, "safety_y": v.safety_y,
                                       "x_poly": list(v.x_poly)} for v in prob.vehicles],
                         "prediction": pred, "runs": plan["runs"], "agreement": plan["agreement"],
                         "agreement_source": plan["agreement_source"], "metrics": metrics.get(name),
                         "sweeps": sweeps})
        if plan["agreement_source"].startswith("iamp.compare.report") and "agreement-module" not in notes:
            notes.append("agreement-module")

    # 3. figures -------------------------------------------------------------------------
    figs: dict = {}

    def fig(key, paths):
        written.extend(paths)
        figs[key] = f"figures/{Path(paths[-1]).name}"  # the PDF

    for name in scenarios:
        step(f"figures for {name}")
        prob, pmp = entries[name]["problem"], runs[name]["pmp"]
        fd = out / "figures"
        fig(f"xy-{name}", F.plot_xy_snapshots(pmp, fd / f"xy-{name}",
                                              title=f"{name}: ego and vehicles every 0.5 s (lighter = earlier)"))
        fig(f"pos-{name}", F.plot_positions(pmp, fd / f"pos-{name}",
                                            title=f"{name}: optimal longitudinal and lateral position"))
        qp_runs = {_short(lbl): r for lbl, r in runs[name].items()
                   if lbl != "pmp" and "refine" not in lbl and "native" not in lbl}
        if prob.m == 1:
            sweeps = {_short(lbl): (r.steps, r.info["sweep"]) for lbl, r in runs[name].items()
                      if lbl != "pmp" and r.is_optimal() and r.hold == "foh" and "sweep" in r.info
                      and "refine" not in lbl and "native" not in lbl}
            fig(f"J-{name}", F.plot_value_function(prob, pmp, sweeps, fd / f"J-{name}",
                                                   title=f"{name}: cost against contact time"))
        fig(f"costates-{name}", F.plot_costates(pmp, qp_runs, fd / f"costates-{name}",
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
        fig("predictions", F.plot_predictions(pred_entries, out / "figures" / "predictions",
                                              tf=entries[next(iter(pred_entries))]["problem"].tf))

    # 4. ZOH convergence -----------------------------------------------------------------
    step("ZOH convergence study (N = " + ", ".join(map(str, cfg.zoh_steps)) + ")")
    conv = {name: zoh_convergence(entries[name]["problem"], cfg.zoh_steps)
            for name in scenarios if entries[name]["problem"].m == 1}
    if conv:
        fig("zoh", F.plot_zoh_convergence({n: ([r["h"] for r in c["rows"]], [r["zoh_gap"] or np.nan for r in c["rows"]])
                                           for n, c in conv.items()}, out / "figures" / "zoh-convergence"))

    # 5. timing --------------------------------------------------------------------------
    step("timing (PMP plans and single QP solves)")
    timing = _timing(entries, plans, cfg)
    fig("timing", F.plot_timing(timing["samples"], out / "figures" / "timing"))

    # 6. predictor evaluation --------------------------------------------------------------
    step("predictor evaluation")
    tables: dict = {}
    predictor = _predictor_evaluation(out, cfg, notes)
    if predictor is not None:
        for key in ("predictor_rmse", "predictor_selection"):
            if (out / "tables" / f"{key}.tex").is_file():
                tables[key] = f"tables/{key}.tex"
                written.append(out / "tables" / f"{key}.tex")
        written.append(out / "predictor_eval.json")

    # 7. tables, results.json, report.tex ----------------------------------------------------
    step("tables, results.json and report.tex")
    notes = [n for n in notes if n != "agreement-module"] + (
        ["iamp.compare.agreement was not available: the runs were planned directly and judged by "
         "iamp.compare.report's simpler fallback checks."] if "agreement-module" in notes else [])
    qual = qualitative_comparison(metrics)
    tdir = out / "tables"
    for key, text in (("scenarios", table_scenarios(entries, rows1)), ("results", table_results(scen_out, cfg)),
                      ("metrics", table_metrics(metrics)), ("agreement", table_agreement(scen_out)),
                      ("timing", table_timing(timing, scen_out)),
                      ("convergence", table_convergence(conv) if conv else _GEN + "% no one-vehicle scenario\n")):
        written.append(atomic_write_text(tdir / f"{key}.tex", text))
        tables[key] = f"tables/{key}.tex"
    res = {"produced_by": "iamp.compare.report.reproduce", "config": asdict(cfg), "notes": notes,
           "versions": _versions(), "scenarios": scen_out, "qualitative": qual, "zoh_convergence": conv,
           "timing": timing, "predictor": predictor}
    res["runtime_s"] = time.perf_counter() - start
    tex = build_report_tex(res, out, figs, tables, entries)
    written.append(atomic_write_text(out / "report.tex", tex))
    res["outputs"] = sorted({str(Path(p).relative_to(out)) for p in written} | {"results.json"})
    atomic_write_text(out / "results.json", json.dumps(_jsonable(res), indent=1, allow_nan=False) + "\n")
    return res
