"""``iamp commonroad bench``: every scenario of a folder planned by each planner and judged by
CommonRoad's checker (:mod:`iamp.commonroad.check`).

Per planner the table counts valid / collision / infeasible / goal missed / off road (valid
with the point-mass orientation defect worked around; the raw ``valid_solution`` count beside
it), and gives the median CommonRoad cost (of the named cost function), the median iamp cost
``J = ½∫|u|²`` and the median solve time.  A plan that does not finish within ``timeout_s``
counts as ``timeout``; a planner that returns no trajectory counts as ``no plan``.

Each plan is written as a ``PM`` or ``KS`` solution (``vehicle_model``; its benchmark ID names
model, vehicle type, cost function and scenario) and scored by CommonRoad's cost functions
``WX1``, ``SM1``, ``TR1`` (:mod:`iamp.commonroad.costs`).

**Resuming.**  With an output folder, every (scenario, planner) result is written atomically to
``rows/<planner>/<scenario>.json`` with the parameters it was made with, and the folder's
``manifest.json`` records those parameters (:data:`MANIFEST_KEYS`).  A bench run into the same
folder again skips every result already there with the same parameters, so a run stopped by
Ctrl-C continues where it stopped; a run with other parameters is refused
(:class:`BenchMismatch`) unless ``force``, which discards the old results.  Scenarios and
planners may be added; the tables cover what the run asked for.
"""

from __future__ import annotations

import json
import signal
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import TypedDict

from iamp.commonroad import require
from iamp.commonroad.check import CheckJSON, check
from iamp.commonroad.convert import load
from iamp.commonroad.costs import REPORTED as REPORTED_COSTS
from iamp.commonroad.planning import RoadPlanJSON, describe, ks_engine, plan
from iamp.commonroad.predicted import predict_obstacles
from iamp.commonroad.solution import DEFAULT_COST_FUNCTION, build_solution, write_solution
from iamp.core.atomic import write_text
from iamp.core.errors import IampError

#: A planner label ending in this plans with the predicted vehicles (``avoid+predict``).
PREDICT_SUFFIX = "+predict"
CATEGORIES = ("valid", "collision", "infeasible", "goal missed", "off road", "no plan", "timeout")
#: Version of what a bench row means (planning, solution writing, checks, costs); in the manifest,
#: so that a bench resumed into a folder of older rows refuses them (raised with every change of
#: what a row holds).  3: the road frame fitted near the ego, the corridor by adjacency (rows of
#: format 2 may hold plans of the corridor before).
BENCH_FORMAT = "3"
#: Manifest keys that define a row: a resumed bench must match them.
MANIFEST_KEYS = ("bench_format", "iamp_version", "vehicle_model", "vehicle_type", "cost_function", "timeout_s")


class BenchMismatch(IampError):
    """A bench resumed into a folder whose results were made with other parameters."""


class _Timeout(Exception):
    pass


def _alarm(signum: int, frame: FrameType | None) -> None:
    raise _Timeout()


@dataclass
class Row:
    """One scenario planned by one planner."""

    scenario: str
    planner: str
    category: str
    valid_raw: bool = False
    cost_commonroad: float | None = None
    cost_iamp: float | None = None
    solve_time_s: float | None = None
    plan: RoadPlanJSON = field(default_factory=lambda: RoadPlanJSON())
    checks: dict[str, CheckJSON] = field(default_factory=dict)
    colliding_obstacles: list[int] = field(default_factory=list)
    vehicle_model: str = "PM"
    benchmark_id: str | None = None
    costs: dict[str, float | None] = field(default_factory=dict)


def params_of(vehicle_model: str = "PM", vehicle_type: int = 2, cost_function: str = DEFAULT_COST_FUNCTION,
              timeout_s: float = 120.0) -> dict[str, object]:
    """The parameters that define a bench row (:data:`MANIFEST_KEYS`; another iamp version's rows
    are not reused)."""
    from iamp import __version__

    return {"bench_format": BENCH_FORMAT, "iamp_version": str(__version__), "vehicle_model": vehicle_model,
            "vehicle_type": int(vehicle_type),
            "cost_function": cost_function, "timeout_s": float(timeout_s)}


def _score(row: Row, cr: object, solution: object) -> None:
    """The official costs of ``solution`` into ``row`` (:mod:`iamp.commonroad.costs`)."""
    from iamp.commonroad.costs import evaluate

    costs = evaluate(cr, solution, REPORTED_COSTS)  # type: ignore[arg-type]
    row.costs = {cf: c["total"] for cf, c in costs.items()}


def run_one(path: Path, planner: str, out_dir: Path | None, timeout_s: float,
            cost_function: str = DEFAULT_COST_FUNCTION, vehicle_model: str = "PM", vehicle_type: int = 2) -> Row:
    """Plan, write, check and score one scenario.

    Parameters
    ----------
    path : Path
        The scenario XML.
    planner : str
        A planner of :data:`iamp.commonroad.planning.PLANNERS`, possibly ending in
        :data:`PREDICT_SUFFIX` (the planner sees the §7 prediction, the checker the recorded future).
    out_dir : Path or None
        Where ``solutions/<planner>/<scenario>.solution.xml`` goes.
    timeout_s : float
        Wall-clock limit of the plan (a safety net; the row says ``timeout``).
    cost_function, vehicle_model, vehicle_type
        Of the written solution (:func:`iamp.commonroad.solution.build_solution`).

    Returns
    -------
    Row
        The verdict, costs and timings.
    """
    cr = load(path, vehicle_type)  # the type's body and limits in the plan too
    base = planner.removesuffix(PREDICT_SUFFIX)
    seen = cr if base == planner else predict_obstacles(cr)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    start = time.perf_counter()
    try:
        rp = plan(seen, base, engine=ks_engine(vehicle_type) if vehicle_model == "KS" else None)
        rp.planner = planner
    except _Timeout:
        return Row(cr.name, planner, "timeout", solve_time_s=time.perf_counter() - start,
                   vehicle_model=vehicle_model)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    row = Row(cr.name, planner, "no plan", cost_iamp=rp.cost, solve_time_s=rp.solve_time_s, plan=describe(rp),
              vehicle_model=vehicle_model)
    if rp.trajectory is None or rp.candidate is None:
        return row
    try:
        solution, drift = build_solution(cr, rp.trajectory, rp.candidate.steps, cost_function, vehicle_type,
                                         vehicle_model)
    except IampError as exc:  # e.g. a KS conversion that finds no admissible input: this row, not the bench
        row.plan["reason"] = f"no {vehicle_model} solution: {exc}"
        return row
    row.plan["zoh_drift_m"] = drift
    row.benchmark_id = str(solution.benchmark_id)  # type: ignore[attr-defined]
    if out_dir is not None:
        sub = out_dir / "solutions" / planner
        sub.mkdir(parents=True, exist_ok=True)
        write_solution(solution, sub / f"{cr.name}.solution.xml", force=True)
    verdict = check(cr.scenario, cr.planning_problem_set, solution, cost=False)
    row.category = verdict.category
    row.valid_raw = verdict.valid_commonroad_raw
    row.checks = verdict.checks
    row.colliding_obstacles = verdict.colliding_obstacles
    _score(row, cr, solution)
    row.cost_commonroad = row.costs.get(cost_function)
    return row


def _row_path(out_dir: Path, planner: str, scenario: str) -> Path:
    return out_dir / "rows" / planner / f"{scenario}.json"


def load_row(out_dir: Path, planner: str, scenario: str, params: dict[str, object]) -> Row | None:
    """The stored row of (``scenario``, ``planner``) if it was made with ``params``, else ``None``."""
    path = _row_path(out_dir, planner, scenario)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("params") != params:
        return None
    try:
        return Row(**data["row"])
    except TypeError:  # a row of another layout
        return None


def store_row(out_dir: Path, row: Row, params: dict[str, object], scenario: str) -> Path:
    """Write ``row`` of the scenario file ``scenario`` (its stem) with its ``params`` atomically
    (:func:`load_row` reads it back)."""
    return write_text(_row_path(out_dir, row.planner, scenario),
                      json.dumps({"params": params, "row": row.__dict__}, indent=1, default=float) + "\n")


def prepare_folder(out_dir: Path, params: dict[str, object], force: bool = False) -> dict[str, object]:
    """Check ``out_dir/manifest.json`` against ``params`` and write the manifest.

    Raises
    ------
    BenchMismatch
        When the folder holds results made with other parameters (or results without a
        manifest) and ``force`` is not set; with ``force`` those results are discarded.
    """
    import shutil

    path = out_dir / "manifest.json"
    stored = out_dir / "rows"
    old: dict[str, object] | None = None
    if path.is_file():
        try:
            loaded = json.loads(path.read_text(encoding="utf-8"))
            old = loaded if isinstance(loaded, dict) else {}
        except (OSError, ValueError) as exc:
            if not force:
                raise BenchMismatch(f"{path}: unreadable manifest ({exc}); use --force to start again") from None
            old = {}
    diff = [k for k in MANIFEST_KEYS if old is not None and old.get(k) != params.get(k)]
    orphan = old is None and stored.is_dir() and any(stored.rglob("*.json"))
    if diff or orphan:
        if not force:
            said = (", ".join(f"{k} (was {old.get(k)!r}, now {params.get(k)!r})" for k in diff) if old is not None
                    and diff else "results without a manifest")
            raise BenchMismatch(f"{path}: the bench there was made with other parameters: {said}; use the same "
                                "ones to resume, or --force to discard its results")
        for sub in ("rows", "solutions"):
            shutil.rmtree(out_dir / sub, ignore_errors=True)
    write_text(path, json.dumps(params, indent=1) + "\n")
    return params


def bench(folder: str | Path, planners: list[str], out_dir: Path | None = None, timeout_s: float = 120.0,
          progress: Callable[[str], None] | None = None, *, cost_function: str = DEFAULT_COST_FUNCTION,
          vehicle_model: str = "PM", vehicle_type: int = 2, force: bool = False) -> list[Row]:
    """Every ``*.xml`` of ``folder`` (sorted) by every planner.

    Parameters
    ----------
    folder : path
        Folder of CommonRoad scenarios.
    planners : list of str
        Planner labels (:func:`run_one`).
    out_dir : Path or None
        Output folder: solutions and resumable rows (module docstring); ``None`` keeps nothing.
    timeout_s : float
        Per plan.
    progress : callable, optional
        Called with one line per (scenario, planner), ``(skipped)`` for a stored row.
    cost_function, vehicle_model, vehicle_type
        Of the written solutions.
    force : bool
        Discard stored results made with other parameters.

    Returns
    -------
    list of Row
        In the order planner, scenario.

    Raises
    ------
    BenchMismatch
        ``out_dir`` holds results made with other parameters and ``force`` is not set.
    """
    require()
    files = sorted(Path(folder).glob("*.xml"))
    params = params_of(vehicle_model, vehicle_type, cost_function, timeout_s)
    if out_dir is not None:
        prepare_folder(out_dir, params, force)
    rows = []
    from iamp.planners.kernels import warm_kernels

    warm_kernels()  # untimed: no row's solve time carries numba's compile of a kernel
    for p in planners:  # planner by planner: an interrupted bench leaves whole planners first
        for f in files:
            stored = load_row(out_dir, p, f.stem, params) if out_dir is not None else None
            if progress is not None:
                progress(f"{f.name} {p}" + (" (stored)" if stored is not None else ""))
            if stored is not None:
                rows.append(stored)
                continue
            row = run_one(f, p, out_dir, timeout_s, cost_function, vehicle_model, vehicle_type)
            if out_dir is not None:
                store_row(out_dir, row, params, f.stem)
            rows.append(row)
    return rows


#: The planner label of the peer's rows.
PEER_LABEL = "reactive-peer"


def peer_rows(folder: str | Path, peer_dir: str | Path) -> list[Row]:
    """Rows of a peer planner, run beforehand in its own environment by ``scripts/commonroad_peer.py``
    into ``peer_dir`` (``peer.json`` + ``<scenario>.solution.xml``), judged and scored here by the
    same checks and costs as iamp's plans.  The label is ``peer.json``'s ``planner`` field
    (:data:`PEER_LABEL` when absent)."""
    require()
    from iamp.commonroad.inputs import read_solution
    from iamp.core.errors import ScenarioError

    pdir = Path(peer_dir)
    index = pdir / "peer.json"
    if not index.is_file():
        raise ScenarioError("holds no peer.json (run scripts/commonroad_peer.py first)", "--peer", str(pdir))
    entries = json.loads(index.read_text())
    status = {str(r.get("scenario")): r for r in entries}
    label = next((str(r["planner"]) for r in entries if r.get("planner")), PEER_LABEL)
    rows = []
    for f in sorted(Path(folder).glob("*.xml")):
        cr = load(f)
        info = status.get(f.stem, {"status": "not run"})
        row = Row(cr.name, label, "no plan", solve_time_s=info.get("solve_time_s"),
                  plan={"reason": str(info.get("status"))})
        sol_path = pdir / f"{f.stem}.solution.xml"
        if sol_path.is_file():
            solution = read_solution(sol_path)
            verdict = check(cr.scenario, cr.planning_problem_set, solution, cost=False)
            row.category = verdict.category
            row.valid_raw = verdict.valid_commonroad_raw
            row.checks = verdict.checks
            row.colliding_obstacles = verdict.colliding_obstacles
            row.plan["reason"] = None
            pps = solution.planning_problem_solutions[0]
            row.vehicle_model = pps.vehicle_model.name
            row.benchmark_id = str(solution.benchmark_id)
            _score(row, cr, solution)
            row.cost_commonroad = row.costs.get(pps.cost_function.name)
        rows.append(row)
    return rows


def _median(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


#: Per planner (:func:`summary`): scenarios, the count of every category of :data:`CATEGORIES`,
#: raw-valid count, medians (functional form: the categories have spaces).
SummaryRow = TypedDict("SummaryRow", {
    "planner": str, "vehicle_model": str, "scenarios": int, "valid": int, "collision": int, "infeasible": int,
    "goal missed": int, "off road": int, "no plan": int, "timeout": int, "valid_raw": int,
    "median_cost_commonroad": float | None, "median_costs": dict[str, float | None],
    "median_cost_iamp": float | None, "median_solve_time_s": float | None, "max_solve_time_s": float | None})


def summary(rows: list[Row], planners: list[str]) -> list[SummaryRow]:
    """Per planner: the counts of every category, raw-valid count, medians over the valid rows
    (costs) or all rows (solve time)."""
    out: list[SummaryRow] = []
    for p in planners:
        rs = [r for r in rows if r.planner == p]
        ok = [r for r in rs if r.category == "valid"]
        counts = {c: sum(r.category == c for r in rs) for c in CATEGORIES}
        models = sorted({r.vehicle_model for r in rs if r.benchmark_id})
        out.append({"planner": p, "vehicle_model": "/".join(models) or "-", "scenarios": len(rs),
                    "valid": counts["valid"], "collision": counts["collision"],
                    "infeasible": counts["infeasible"], "goal missed": counts["goal missed"],
                    "off road": counts["off road"], "no plan": counts["no plan"], "timeout": counts["timeout"],
                    "valid_raw": sum(r.valid_raw for r in rs),
                    "median_cost_commonroad": _median([r.cost_commonroad for r in ok]),
                    "median_costs": {cf: _median([r.costs.get(cf) for r in ok]) for cf in REPORTED_COSTS},
                    "median_cost_iamp": _median([r.cost_iamp for r in ok]),
                    "median_solve_time_s": _median([r.solve_time_s for r in rs]),
                    "max_solve_time_s": max((r.solve_time_s or 0.0 for r in rs), default=None)})
    return out


def _fmt(v: float | None, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)


def markdown(rows: list[Row], planners: list[str], command: str) -> str:
    """The bench table (per planner) and the per-scenario rows, in Markdown."""
    costs = " | ".join(f"median {cf}" for cf in REPORTED_COSTS)
    lines = ["# CommonRoad US-101: iamp's planners judged by CommonRoad's checker", "",
             f"Command: `{command}`", "",
             "valid = every check of commonroad-drivability-checker 2025.4 passes, with the goal test's "
             "point-mass orientation defect worked around for PM solutions (`valid raw` = `valid_solution` as "
             "is). Costs: CommonRoad's cost functions as the drivability checker's evaluator defines them "
             "(iamp.commonroad.costs; medians over the valid solutions); solve times are this machine's.", "",
             f"| planner | model | valid | valid raw | collision | infeasible | goal missed | off road | no plan "
             f"| timeout | {costs} | median J | median solve [s] | max solve [s] |",
             "|---|---|---|---|---|---|---|---|---|---|" + "---|" * len(REPORTED_COSTS) + "---|---|---|"]
    for e in summary(rows, planners):
        mc = " | ".join(_fmt(e["median_costs"].get(cf), ".2f") for cf in REPORTED_COSTS)
        lines.append(f"| {e['planner']} | {e['vehicle_model']} | {e['valid']}/{e['scenarios']} | {e['valid_raw']} | "
                     f"{e['collision']} | {e['infeasible']} | {e['goal missed']} | {e['off road']} | "
                     f"{e['no plan']} | {e['timeout']} | {mc} | {_fmt(e['median_cost_iamp'])} | "
                     f"{_fmt(e['median_solve_time_s'])} | {_fmt(e['max_solve_time_s'])} |")
    head = " | ".join(REPORTED_COSTS)
    lines += ["", "## Per scenario", "",
              f"| scenario | planner | benchmark ID | verdict | colliding obstacles | imposed (obstacle:corner) | J | "
              f"{head} | solve [s] | tf [s] | reason |",
              "|---|---|---|---|---|---|---|" + "---|" * len(REPORTED_COSTS) + "---|---|---|"]
    for r in rows:
        imposed = " ".join(f"{i['obstacle']}:{i['corner']}" for i in r.plan.get("imposed", []))
        cs = " | ".join(_fmt(r.costs.get(cf), ".2f") for cf in REPORTED_COSTS)
        reason = str(r.plan.get("reason") or "-").replace("|", "/")
        lines.append(f"| {r.scenario} | {r.planner} | {r.benchmark_id or '-'} | {r.category} | "
                     f"{' '.join(map(str, r.colliding_obstacles)) or '-'} | {imposed or '-'} | {_fmt(r.cost_iamp)} | "
                     f"{cs} | {_fmt(r.solve_time_s)} | {_fmt(r.plan.get('tf'), '.1f')} | {reason} |")
    return "\n".join(lines) + "\n"


def latex(rows: list[Row], planners: list[str]) -> str:
    """The per-planner table as a LaTeX ``tabular``."""
    cols = "r" * (8 + len(REPORTED_COSTS))
    lines = [rf"\begin{{tabular}}{{ll{cols}}}", r"\hline",
             r"planner & model & valid & raw & coll. & infeas. & goal & road & none & "
             + " & ".join(REPORTED_COSTS) + r" & med. solve [s] \\", r"\hline"]
    for e in summary(rows, planners):
        mc = " & ".join(_fmt(e["median_costs"].get(cf), ".2f") for cf in REPORTED_COSTS)
        lines.append(f"{e['planner']} & {e['vehicle_model']} & {e['valid']}/{e['scenarios']} & {e['valid_raw']} & "
                     f"{e['collision']} & {e['infeasible']} & {e['goal missed']} & {e['off road']} & "
                     f"{e['no plan'] + e['timeout']} & {mc} & {_fmt(e['median_solve_time_s'])} \\\\")
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def write_reports(rows: list[Row], planners: list[str], out_dir: Path, command: str) -> list[Path]:
    """``bench.md``, ``bench.tex``, ``bench.json`` in ``out_dir`` (atomic)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    data = {"command": command, "summary": summary(rows, planners),
            "rows": [r.__dict__ for r in rows]}
    paths = [out_dir / "bench.md", out_dir / "bench.tex", out_dir / "bench.json"]
    write_text(paths[0], markdown(rows, planners, command))
    write_text(paths[1], latex(rows, planners))
    write_text(paths[2], json.dumps(data, indent=1, default=float) + "\n")
    return paths
