r"""Equality vs avoidance, side by side (SPEC §9, §10): the cost of safety.

For one problem :func:`safety_comparison` runs

* the paper's equality: the PMP (exact, continuous) and the equality QP;
* the avoidance QP (:class:`~iamp.planners.avoid.planner.AvoidQPPlanner`) with the same solver,
  hold and ``N`` as the equality QP,

and reports per run its status, cost, contact / crossing times and its SPEC §9 safety report
(intrusion and overlap intervals), plus

.. math::  \Delta J_{\text{safety}} = J_{\text{avoid}} - J_{\text{eq}}

against the equality QP of the same configuration (``cost_of_safety``) and against the PMP
(``cost_of_safety_vs_pmp``).  It can be negative: the equality forces the ego through the
corner, which may be far from where it would go; the avoidance QP only keeps it out.  A
``verdict`` says in words which case the scenario is (:func:`explain`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import NotRequired, TypedDict, cast

from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.avoid.diagnostics import AvoidDiagnostics

#: Relative cost difference below which two plans count as the same optimum.
SAME_COST_REL = 1e-6


class VehicleSafetyJSON(TypedDict):
    """One vehicle of the SPEC §9 safety report (:meth:`iamp.core.safety.VehicleSafety.to_json`)."""

    name: str
    intrusion: list[list[float]]
    max_intrusion_m: float
    overlap: list[list[float]]
    min_clearance_m: float


class SafetyJSON(TypedDict):
    """The SPEC §9 safety report of a plan (:meth:`iamp.core.safety.SafetyReport.to_json`)."""

    collision_free: bool
    intrusion_free: bool
    vehicles: list[VehicleSafetyJSON]
    ego_length_m: float
    ego_width_m: float
    intrusion_tol_m: float
    method: str
    safety_tolerance_m: float
    unsafe: bool


class AvoidanceJSON(TypedDict):
    """A run's ``avoidance`` object: the avoidance plan's per-vehicle half-planes and its sweep."""

    safety: object
    vehicles: list[dict[str, object]]
    complete_sweep: object
    n_solves: object
    certificate: str | None


class RunJSON(TypedDict):
    """One run of a safety comparison (an equality or avoidance plan, SPEC §9, §10)."""

    label: str
    planner: str
    constraint: str
    solver: str | None
    hold: str | None
    steps: int | None
    status: str
    cost: float | None
    contact_times: list[float]
    time_s: float | None
    safety: SafetyJSON | None
    reason: NotRequired[str | None]
    avoidance: NotRequired[AvoidanceJSON]
    note: NotRequired[str]
    corners: NotRequired[list[str]]
    # avoid_section's runs only
    equality_label: NotRequired[str]
    cost_of_safety: NotRequired[float | None]
    cost_of_safety_vs_pmp: NotRequired[float | None]
    verdict: NotRequired[str]


class SafetyPlans(TypedDict):
    """The plans behind a :func:`safety_comparison` (not JSON)."""

    pmp: Plan
    equality: Plan
    avoid: Plan | None


class SafetyComparisonJSON(TypedDict):
    """:func:`safety_comparison`'s result as JSON (:func:`to_json`)."""

    name: str
    runs: list[RunJSON]
    cost_of_safety: float | None
    cost_of_safety_vs_pmp: float | None
    verdict: str


class SafetyComparison(SafetyComparisonJSON):
    """:func:`safety_comparison`'s result: the JSON fields and the :class:`Plan` objects."""

    plans: SafetyPlans


class AvoidSection(TypedDict):
    """``iamp compare --avoid``'s ``avoidance`` object (:func:`avoid_section`)."""

    equality: list[RunJSON]
    runs: list[RunJSON]


class ReproductionSafety(TypedDict):
    """The reproduction's safety part (:func:`reproduction_section`)."""

    json: list[SafetyComparisonJSON]
    figures: dict[str, list[Path]]
    table: str
    section: Callable[[dict[str, str], str], str]


def _run_json(label: str, plan: Plan, constraint: str) -> RunJSON:
    ok = plan.ok
    safety = plan.safety if ok else None
    out: RunJSON = {
        "label": label, "planner": plan.planner, "constraint": constraint, "solver": plan.solver, "hold": plan.hold,
        "steps": plan.steps, "status": plan.status, "cost": float(plan.cost) if ok and plan.cost is not None else None,
        "contact_times": [float(t) for t in plan.contact_times] if ok else [],
        "time_s": float(plan.solve_time_s),
        # SafetyReport.to_json has exactly SafetyJSON's keys (SPEC §9)
        "safety": cast(SafetyJSON, safety.to_json()) if safety is not None else None,
    }
    diag = plan.diagnostics
    if diag.reason:
        out["reason"] = diag.reason
    av = diag.avoidance if isinstance(diag, AvoidDiagnostics) else None
    if av is not None and ok:
        # node-only plans report between_node_intrusion_m and active rows; continuous ones
        # (SPEC §14, the default) max_intrusion_m and binding_rows
        keys = ("name", "first", "second", "crossing_time", "between_node_intrusion_m", "max_intrusion_m",
                "active_H_x", "active_H_y", "binding_rows")
        out["avoidance"] = {"safety": av.get("safety", "nodes"),
                            "vehicles": [{k: v[k] for k in keys if k in v} for v in av["vehicles"]],
                            "complete_sweep": av.get("complete_sweep"), "n_solves": av.get("n_solves"),
                            "certificate": diag.certificate if isinstance(diag, AvoidDiagnostics) else None}
    return out


def _binds(vehicle: Mapping[str, object]) -> bool:
    """Does an avoidance plan's inequality bind for this vehicle?  Node-only plans list the
    active nodes per half-plane; continuous ones (SPEC §14) count binding Bernstein rows."""
    rows = vehicle.get("binding_rows")
    if isinstance(rows, Mapping):
        return any(int(n) > 0 for n in rows.values())
    hx, hy = vehicle["active_H_x"], vehicle["active_H_y"]
    assert isinstance(hx, Mapping) and isinstance(hy, Mapping)
    return bool(hx["nodes"] or hy["nodes"])


def plan_avoid(problem: Problem, *, steps: int, hold: str, solver: str) -> tuple[Plan | None, str | None]:
    """The avoidance plan of ``problem``; when a vehicle's corner does not describe the
    manoeuvre (SPEC §10 refuses it), the plan with that vehicle's corner mirrored
    longitudinally (``front`` <-> ``rear``: merging behind instead of ahead), with a note.
    Returns ``(plan or None, note or None)``."""
    import re

    from iamp.core.errors import ScenarioError
    from iamp.core.problem import SurroundingVehicle
    from iamp.planners.avoid.planner import AvoidQPPlanner

    planner = AvoidQPPlanner(steps=steps, hold=hold, solver=solver)
    try:
        return planner.plan(problem), None
    except ScenarioError as exc:
        first = exc.message
        match = re.match(r"vehicles\[(\d+)\]", exc.field or "")
        if match is None:
            return None, first
        i = int(match.group(1))
        v = problem.vehicles[i]
        side, lat = v.corner.split("-")
        corner = f"{'rear' if side == 'front' else 'front'}-{lat}"
        mirrored = SurroundingVehicle(v.x_poly, corner, v.y, v.length, v.width, v.safety_x, v.safety_y, v.name)
        vehicles = list(problem.vehicles)
        vehicles[i] = mirrored
        try:
            plan = planner.plan(problem.with_vehicles(vehicles))
        except ScenarioError as exc2:
            return None, f"{first}; with corner {corner!r} too: {exc2.message}"
        return plan, (f"corner {v.corner!r} of {v.name} refused ({first}); planned with {corner!r} instead "
                      f"(the ego passes {'behind' if side == 'front' else 'ahead of'} it)")


def explain(eq: Plan, avoid: Plan) -> str:
    """In words: is the equality plan safe, does the avoidance optimum coincide with it, why."""
    if not avoid.ok:
        reason = avoid.status if avoid.diagnostics.reason is None else avoid.diagnostics.reason
        eq_part = ""
        if eq.ok and eq.safety is not None and not eq.safety.safe:
            eq_part = " The equality plan is unsafe: " + "; ".join(v.describe() for v in eq.safety.unsafe()) + "."
        return f"{reason[0].upper()}{reason[1:]}.{eq_part}"
    assert avoid.cost is not None
    if not eq.ok or eq.cost is None:
        return f"The equality plan failed ({eq.status}); the avoidance plan costs {avoid.cost:.6g}."
    d = avoid.cost - eq.cost
    same = abs(d) <= SAME_COST_REL * max(1.0, abs(eq.cost))
    binds = [str(v["name"]) for v in _avoidance_vehicles(avoid) if _binds(v)]
    bind_txt = (f"the inequalities bind for {', '.join(binds)}" if binds else
                "no inequality binds: the unconstrained optimum is safe")
    av_safety = avoid.safety
    if av_safety is not None and not av_safety.intrusion_free:
        depth = max(v.max_intrusion_m for v in av_safety.vehicles)
        bind_txt += (f"; between nodes it cuts the corner by up to {depth:.3g} m (the inequalities hold at the nodes "
                     "only; this falls as N grows)")
    eq_safety = eq.safety
    if eq_safety is not None and not eq_safety.safe:
        return (f"The equality plan is unsafe ({'; '.join(v.describe() for v in eq_safety.unsafe())}); the "
                f"avoidance plan keeps out of every region at the nodes ({bind_txt}); cost of safety {d:+.6g}.")
    if same:
        return (f"The equality plan is safe and the avoidance optimum coincides with it (J = {avoid.cost:.6g}): "
                f"{bind_txt}; the inequality is active only where the equality touches the corner.")
    if d < 0:
        return (f"The equality plan is safe but the avoidance optimum is cheaper by {-d:.6g}: the equality drags the "
                f"ego to the corner, which keeping out of the region does not require ({bind_txt}).")
    return (f"The equality plan is safe; the avoidance optimum costs {d:.6g} more ({bind_txt}): its crossing "
            "differs from the equality's corner touch.")


def safety_comparison(problem: Problem, *, name: str | None = None, steps: int | None = None,
                      solver: str = "clarabel", hold: str = "foh") -> SafetyComparison:
    """Equality (PMP and QP) and avoidance QP runs on ``problem`` with the cost of safety.

    ``steps`` defaults to 100 for one vehicle and 20 for more (SPEC §5b's compare default).
    Returns ``{"name", "runs", "cost_of_safety", "cost_of_safety_vs_pmp", "verdict", "plans"}``;
    ``plans`` holds the :class:`Plan` objects (not JSON; see :func:`to_json`).
    """
    from iamp.planners.pmp.planner import PMPPlanner
    from iamp.planners.qp.planner import QPPlanner

    n = int(steps or (100 if problem.m == 1 else 20))
    pmp = PMPPlanner().plan(problem)
    eq = QPPlanner(steps=n, hold=hold, solver=solver).plan(problem)
    avoid, note = plan_avoid(problem, steps=n, hold=hold, solver=solver)
    cfg = f"{solver}-{hold}-{n}"
    runs = [_run_json("pmp", pmp, "equality"), _run_json(f"qp-{cfg}", eq, "equality"),
            _avoid_json(f"qp-avoid-{cfg}", avoid, note, n, hold, solver)]
    verdict = explain(eq, avoid) if avoid is not None else f"No avoidance plan: {note}."
    if note is not None and avoid is not None:
        verdict = f"{note[0].upper()}{note[1:]}. {verdict}"
    return {"name": name or problem.name, "runs": runs, "cost_of_safety": _gap(avoid, eq),
            "cost_of_safety_vs_pmp": _gap(avoid, pmp), "verdict": verdict,
            "plans": {"pmp": pmp, "equality": eq, "avoid": avoid}}


def _avoid_json(label: str, plan: Plan | None, note: str | None, steps: int, hold: str,
                solver: str) -> RunJSON:
    if plan is None:
        return {"label": label, "planner": "qp", "constraint": "avoid", "solver": solver, "hold": hold,
                "steps": steps, "status": "refused", "cost": None, "contact_times": [], "time_s": None,
                "safety": None, "reason": note}
    out = _run_json(label, plan, "avoid")
    if note is not None:
        out["note"] = note
        out["corners"] = [v.corner for v in plan.problem.vehicles]
    return out


def to_json(result: SafetyComparison) -> SafetyComparisonJSON:
    """:func:`safety_comparison`'s result without the :class:`Plan` objects."""
    return {"name": result["name"], "runs": result["runs"], "cost_of_safety": result["cost_of_safety"],
            "cost_of_safety_vs_pmp": result["cost_of_safety_vs_pmp"], "verdict": result["verdict"]}


def avoid_section(problem: Problem, equality: Mapping[str, Plan | None], steps: Sequence[int],
                  solvers: tuple[str, ...], holds: tuple[str, ...]) -> AvoidSection:
    """``iamp compare --avoid``: an avoidance run per ``(N, solver, hold)`` beside the
    equality runs ``equality`` (label -> plan, e.g. ``{"pmp": ..., "qp-clarabel-foh-100": ...}``),
    each with its cost of safety against the equality QP of the same label (and the PMP), and
    every run's SPEC §9 safety."""
    eq_json = [_run_json(lbl, plan, "equality") for lbl, plan in equality.items() if plan is not None]
    pmp = equality.get("pmp")
    runs: list[RunJSON] = []
    for n in steps:
        for solver in solvers:
            for hold in holds:
                plan, note = plan_avoid(problem, steps=n, hold=hold, solver=solver)
                run = _avoid_json(f"qp-avoid-{solver}-{hold}-{n}", plan, note, n, hold, solver)
                eq = equality.get(f"qp-{solver}-{hold}-{n}")
                run["equality_label"] = f"qp-{solver}-{hold}-{n}" if eq is not None else "pmp"
                ref = eq if eq is not None else pmp
                run["cost_of_safety"] = _gap(plan, ref)
                run["cost_of_safety_vs_pmp"] = _gap(plan, pmp)
                run["verdict"] = (explain(ref, plan) if ref is not None and plan is not None
                                  else f"No avoidance plan: {note}." if plan is None else "")
                if note is not None and plan is not None:
                    run["verdict"] = f"{note[0].upper()}{note[1:]}. {run['verdict']}"
                runs.append(run)
    return {"equality": eq_json, "runs": runs}


def _gap(a: Plan | None, b: Plan | None) -> float | None:
    if a is None or b is None or not (a.ok and b.ok) or a.cost is None or b.cost is None:
        return None
    return float(a.cost - b.cost)


def section_lines(name: str, section: AvoidSection) -> list[str]:
    """Text lines of :func:`avoid_section`'s result."""
    out = [f"{name}: equality vs avoidance (SPEC §9, §10)"]
    for run in section["equality"] + section["runs"]:
        cost = f"J = {run['cost']:.6g}" if run["cost"] is not None else f"status {run['status']}"
        out.append(f"  {run['label']:<28} {cost:<16} {_safety_text(run)}")
        if run["constraint"] == "avoid":
            cos = run["cost_of_safety"]
            text = f"{cos:+.6g}" if cos is not None else "n/a"
            out.append(f"    cost of safety vs {run['equality_label']}: {text}")
            out.append(f"    {run['verdict']}")
    return out


def _safety_text(run: RunJSON) -> str:
    saf = run["safety"]
    if saf is None:
        return str(run.get("reason", "no plan"))
    if saf["intrusion_free"] and saf["collision_free"]:
        return "safe"
    return "; ".join(f"{v['name']} inside {_intervals(v['intrusion'])} s, overlap {_intervals(v['overlap'])} s"
                     for v in saf["vehicles"] if v["intrusion"] or v["overlap"])


def _tex(s: str) -> str:
    return s.replace("_", r"\_").replace("%", r"\%").replace("&", r"\&")


def _intervals(iv: Sequence[Sequence[float]]) -> str:
    return ", ".join(f"{a:.2f}--{b:.2f}" for a, b in iv) or "--"


def table_safety(results: Sequence[SafetyComparisonJSON]) -> str:
    """A booktabs table: per scenario and run, cost, intrusion and overlap, and the cost of safety."""
    lines = [r"\begin{tabular}{llrlll}", r"\toprule",
             r"scenario & run & $J$ & inside safety region [s] & bodies overlap [s] & $J_{\mathrm{avoid}} - "
             r"J_{\mathrm{eq}}$ \\", r"\midrule"]
    for res in results:
        for k, run in enumerate(res["runs"]):
            cost = f"{run['cost']:.3f}" if run["cost"] is not None else run["status"]
            saf = run["safety"]
            inside = "; ".join(_intervals(v["intrusion"]) for v in saf["vehicles"]) if saf else "--"
            over = "; ".join(_intervals(v["overlap"]) for v in saf["vehicles"]) if saf else "--"
            cos = ""
            if k == len(res["runs"]) - 1:
                cos = f"{res['cost_of_safety']:+.3f}" if res["cost_of_safety"] is not None else "no safe plan"
            lines.append(f"{_tex(res['name']) if k == 0 else ''} & {_tex(run['label'])} & {cost} & {inside} & "
                         f"{over} & {cos} \\\\")
        lines.append(r"\midrule" if res is not results[-1] else r"\bottomrule")
    lines.append(r"\end{tabular}")
    return "\n".join(lines) + "\n"


def summary_lines(result: SafetyComparisonJSON) -> list[str]:
    """Text lines for ``iamp compare --avoid``."""
    out = [f"{result['name']}: equality vs avoidance"]
    for run in result["runs"]:
        cost = f"J = {run['cost']:.6g}" if run["cost"] is not None else f"status {run['status']}"
        out.append(f"  {run['label']:<28} {cost:<16} {_safety_text(run)}")
    cos = result["cost_of_safety"]
    out.append("  cost of safety J_avoid - J_eq = " + (f"{cos:+.6g}" if cos is not None else "n/a (no safe plan)")
               + (f" (vs PMP {result['cost_of_safety_vs_pmp']:+.6g})" if result["cost_of_safety_vs_pmp"] is not None
                  else ""))
    out.append(f"  {result['verdict']}")
    return out


def reproduction_section(problems: Mapping[str, Problem], fig_dir: str | PathLike[str], *, steps_one: int = 100,
                         steps_two: int = 20) -> ReproductionSafety:
    """The reproduction's safety part: :func:`safety_comparison` per scenario (equality PMP and
    QP against the avoidance QP, Clarabel FOH), one x–y figure each
    (:func:`iamp.comparison.figures.safety.plot_safety_xy`), the booktabs table (a ``table``
    float) and the LaTeX section that shows them.

    Returns ``{"json": [...], "figures": {key: paths}, "table": tex, "section": tex(figs)}``
    where ``section`` is a function of the figures' and the table's paths relative to the
    report.
    """
    from iamp.comparison.figures.safety import plot_safety_xy

    results: list[SafetyComparison] = []
    figures: dict[str, list[Path]] = {}
    for name, problem in problems.items():
        res = safety_comparison(problem, name=name, steps=steps_one if problem.m == 1 else steps_two)
        results.append(res)
        plans = res["plans"]
        drawn = {"equality (PMP)": plans["pmp"]}
        avoid = plans["avoid"]
        if avoid is not None:
            corners = ", ".join(v.corner for v in avoid.problem.vehicles)
            drawn[f"avoidance QP ({avoid.solver}, N = {avoid.steps}; {corners})"] = avoid
        figures[f"safety-{name}"] = plot_safety_xy(drawn, Path(fig_dir) / f"safety-{name}")
    table = ("% generated by iamp.comparison.safety_compare -- do not edit\n\n\\begin{table}[H]\n\\centering\n"
             "\\small\n\\caption{Equality (the paper's corner touch) against the avoidance QP (SPEC \\S10, Clarabel, "
             "FOH): cost, where the ego's point is inside a safety region by more than 1\\,mm and where the bodies "
             "overlap (exact, SPEC \\S9), and the cost of safety $J_{\\mathrm{avoid}} - J_{\\mathrm{eq}}$ against "
             "the equality QP of the same configuration.}\n\\label{tab:safety}\n" + table_safety(results)
             + "\\end{table}\n")

    def section(fig_paths: dict[str, str], table_path: str) -> str:
        out = ["\\section{Safety: equality against avoidance}",
               "The paper's equality touches the corner of the safety region at one instant and does not keep the "
               "ego out of it. Table~\\ref{tab:safety} measures every plan's intrusion and overlap exactly and "
               "sets the avoidance QP (half-plane inequalities at every node, SPEC \\S10) beside it.",
               "\\begin{itemize}"]
        out += [f"\\item {_tex(r['name'])}: {_tex(r['verdict'])}" for r in results]
        out += ["\\end{itemize}", f"\\input{{{table_path}}}"]
        for r in results:
            key = f"safety-{r['name']}"
            if key in fig_paths:
                out.append("\\begin{figure}[H]\n\\centering\n"
                           f"\\includegraphics[width=\\linewidth]{{{fig_paths[key]}}}\n"
                           f"\\caption{{{_tex(r['name'])}: equality (PMP, green) and avoidance QP (blue, dashed) "
                           "with the vehicles' safety regions (red, dashed) and bodies at six instants, to scale; a "
                           "filled marker means the ego's point is inside a region.}\n"
                           f"\\label{{fig:safety-{r['name']}}}\n\\end{{figure}}")
        return "\n".join(out) + "\n"

    return {"json": [to_json(r) for r in results], "figures": figures, "table": table, "section": section}


__all__ = [
    "SAME_COST_REL",
    "avoid_section",
    "explain",
    "reproduction_section",
    "safety_comparison",
    "section_lines",
    "summary_lines",
    "table_safety",
    "to_json",
]


def _avoidance_vehicles(plan: Plan) -> list[Mapping[str, object]]:
    """The per-vehicle records of an avoidance plan's ``avoidance`` (``KeyError`` for any other plan)."""
    diag = plan.diagnostics
    if not isinstance(diag, AvoidDiagnostics) or diag.avoidance is None:
        raise KeyError("avoidance")
    vehicles = diag.avoidance["vehicles"]
    return [v for v in vehicles if isinstance(v, Mapping)]
