"""``iamp commonroad bench``: every scenario of a folder planned by each planner and judged by
CommonRoad's checker (:mod:`iamp.commonroad.check`).

Per planner the table counts valid / collision / infeasible / goal missed / off road (valid
with the point-mass orientation defect worked around; the raw ``valid_solution`` count beside
it), and gives the median CommonRoad cost (of the named cost function), the median iamp cost
``J = ½∫|u|²`` and the median solve time.  A plan that does not finish within ``timeout_s``
counts as ``timeout``; a planner that returns no trajectory counts as ``no plan``.
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
from iamp.commonroad.planning import RoadPlanJSON, describe, plan
from iamp.commonroad.predicted import predict_obstacles
from iamp.commonroad.solution import DEFAULT_COST_FUNCTION, build_solution, write_solution
from iamp.core.atomic import write_text

#: A planner label ending in this plans with the predicted vehicles (``avoid+predict``).
PREDICT_SUFFIX = "+predict"
CATEGORIES = ("valid", "collision", "infeasible", "goal missed", "off road", "no plan", "timeout")


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


def run_one(path: Path, planner: str, out_dir: Path | None, timeout_s: float,
            cost_function: str = DEFAULT_COST_FUNCTION) -> Row:
    """Plan, write and check one scenario (``planner`` may end in :data:`PREDICT_SUFFIX`: the
    planner sees the §7 prediction, the checker the recorded future)."""
    cr = load(path)
    base = planner.removesuffix(PREDICT_SUFFIX)
    seen = cr if base == planner else predict_obstacles(cr)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    start = time.perf_counter()
    try:
        rp = plan(seen, base)
        rp.planner = planner
    except _Timeout:
        return Row(cr.name, planner, "timeout", solve_time_s=time.perf_counter() - start)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    row = Row(cr.name, planner, "no plan", cost_iamp=rp.cost, solve_time_s=rp.solve_time_s, plan=describe(rp))
    if rp.trajectory is None or rp.candidate is None:
        return row
    solution, drift = build_solution(cr, rp.trajectory, rp.candidate.steps, cost_function)
    row.plan["zoh_drift_m"] = drift
    if out_dir is not None:
        sub = out_dir / "solutions" / planner
        sub.mkdir(parents=True, exist_ok=True)
        write_solution(solution, sub / f"{cr.name}.solution.xml", force=True)
    verdict = check(cr.scenario, cr.planning_problem_set, solution)
    row.category = verdict.category
    row.valid_raw = verdict.valid_commonroad_raw
    row.cost_commonroad = verdict.cost
    row.checks = verdict.checks
    row.colliding_obstacles = verdict.colliding_obstacles
    return row


def bench(folder: str | Path, planners: list[str], out_dir: Path | None = None, timeout_s: float = 120.0,
          progress: Callable[[str], None] | None = None) -> list[Row]:
    """Every ``*.xml`` of ``folder`` (sorted) by every planner."""
    require()
    files = sorted(Path(folder).glob("*.xml"))
    rows = []
    for f in files:
        for p in planners:
            if progress is not None:
                progress(f"{f.name} {p}")
            rows.append(run_one(f, p, out_dir, timeout_s))
    return rows


#: The planner label of the peer's rows.
PEER_LABEL = "reactive-peer"


def peer_rows(folder: str | Path, peer_dir: str | Path) -> list[Row]:
    """Rows of the peer ``commonroad-reactive-planner``, run beforehand in its own environment by
    ``scripts/commonroad_peer.py`` into ``peer_dir`` (``peer.json`` + ``<scenario>.solution.xml``),
    judged here by the same checks as iamp's plans."""
    require()
    from commonroad.common.solution import CommonRoadSolutionReader

    from iamp.core.errors import ScenarioError

    pdir = Path(peer_dir)
    index = pdir / "peer.json"
    if not index.is_file():
        raise ScenarioError("holds no peer.json (run scripts/commonroad_peer.py first)", "--peer", str(pdir))
    status = {str(r.get("scenario")): r for r in json.loads(index.read_text())}
    rows = []
    for f in sorted(Path(folder).glob("*.xml")):
        cr = load(f)
        info = status.get(f.stem, {"status": "not run"})
        row = Row(cr.name, PEER_LABEL, "no plan", solve_time_s=info.get("solve_time_s"),
                  plan={"reason": str(info.get("status"))})
        sol_path = pdir / f"{f.stem}.solution.xml"
        if sol_path.is_file():
            verdict = check(cr.scenario, cr.planning_problem_set, CommonRoadSolutionReader.open(str(sol_path)))
            row.category = verdict.category
            row.valid_raw = verdict.valid_commonroad_raw
            row.cost_commonroad = verdict.cost
            row.checks = verdict.checks
            row.colliding_obstacles = verdict.colliding_obstacles
            row.plan["reason"] = None
        rows.append(row)
    return rows


def _median(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


#: Per planner (:func:`summary`): scenarios, the count of every category of :data:`CATEGORIES`,
#: raw-valid count, medians (functional form: the categories have spaces).
SummaryRow = TypedDict("SummaryRow", {
    "planner": str, "scenarios": int, "valid": int, "collision": int, "infeasible": int, "goal missed": int,
    "off road": int, "no plan": int, "timeout": int, "valid_raw": int, "median_cost_commonroad": float | None,
    "median_cost_iamp": float | None, "median_solve_time_s": float | None, "max_solve_time_s": float | None})


def summary(rows: list[Row], planners: list[str]) -> list[SummaryRow]:
    """Per planner: the counts of every category, raw-valid count, medians."""
    out: list[SummaryRow] = []
    for p in planners:
        rs = [r for r in rows if r.planner == p]
        counts = {c: sum(r.category == c for r in rs) for c in CATEGORIES}
        out.append({"planner": p, "scenarios": len(rs), "valid": counts["valid"], "collision": counts["collision"],
                    "infeasible": counts["infeasible"], "goal missed": counts["goal missed"],
                    "off road": counts["off road"], "no plan": counts["no plan"], "timeout": counts["timeout"],
                    "valid_raw": sum(r.valid_raw for r in rs),
                    "median_cost_commonroad": _median([r.cost_commonroad for r in rs if r.category == "valid"]),
                    "median_cost_iamp": _median([r.cost_iamp for r in rs if r.category == "valid"]),
                    "median_solve_time_s": _median([r.solve_time_s for r in rs]),
                    "max_solve_time_s": max((r.solve_time_s or 0.0 for r in rs), default=None)})
    return out


def _fmt(v: float | None, spec: str = ".3f") -> str:
    return "-" if v is None else format(v, spec)


def markdown(rows: list[Row], planners: list[str], command: str) -> str:
    lines = ["# CommonRoad US-101: iamp's planners judged by CommonRoad's checker", "",
             f"Command: `{command}`", "",
             "valid = every check of commonroad-drivability-checker 2025.4 passes, with the goal test's "
             "point-mass orientation defect worked around (`valid raw` = `valid_solution` as is).", "",
             "| planner | valid | valid raw | collision | infeasible | goal missed | off road | no plan | timeout "
             "| median CR cost | median J | median solve [s] | max solve [s] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for e in summary(rows, planners):
        lines.append(f"| {e['planner']} | {e['valid']}/{e['scenarios']} | {e['valid_raw']} | {e['collision']} | "
                     f"{e['infeasible']} | {e['goal missed']} | {e['off road']} | {e['no plan']} | {e['timeout']} | "
                     f"{_fmt(e['median_cost_commonroad'])} | {_fmt(e['median_cost_iamp'])} | "
                     f"{_fmt(e['median_solve_time_s'])} | {_fmt(e['max_solve_time_s'])} |")
    lines += ["", "## Per scenario", "",
              "| scenario | planner | verdict | colliding obstacles | imposed (obstacle:corner) | J | CR cost | "
              "solve [s] | tf [s] | reason |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        imposed = " ".join(f"{i['obstacle']}:{i['corner']}" for i in r.plan.get("imposed", []))
        lines.append(f"| {r.scenario} | {r.planner} | {r.category} | "
                     f"{' '.join(map(str, r.colliding_obstacles)) or '-'} | {imposed or '-'} | {_fmt(r.cost_iamp)} | "
                     f"{_fmt(r.cost_commonroad)} | {_fmt(r.solve_time_s)} | {_fmt(r.plan.get('tf'), '.1f')} | "
                     f"{r.plan.get('reason') or '-'} |")
    return "\n".join(lines) + "\n"


def latex(rows: list[Row], planners: list[str]) -> str:
    lines = [r"\begin{tabular}{lrrrrrrrrr}", r"\hline",
             r"planner & valid & raw & coll. & infeas. & goal & road & none & med. CR cost & med. solve [s] \\",
             r"\hline"]
    for e in summary(rows, planners):
        lines.append(f"{e['planner']} & {e['valid']}/{e['scenarios']} & {e['valid_raw']} & {e['collision']} & "
                     f"{e['infeasible']} & {e['goal missed']} & {e['off road']} & {e['no plan'] + e['timeout']} & "
                     f"{_fmt(e['median_cost_commonroad'])} & {_fmt(e['median_solve_time_s'])} \\\\")
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
