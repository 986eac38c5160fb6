"""The closed-loop campaign's tables in docs/closed-loop.md, computed from what ``iamp campaign`` wrote.

Usage::

    python scripts/campaign_tables.py            # rewrite the block between the markers
    python scripts/campaign_tables.py --check    # exit 1 if docs/closed-loop.md differs from the files

The block between ``<!-- campaign-tables:begin -->`` and ``<!-- campaign-tables:end -->`` holds

* per mission and density, per planner: successes, contacts the ego is responsible for, new
  followers braking at SUMO's emergency rate and harder than 4.5 m/s² (``reports/campaign-safe``,
  ``reports/campaign-safe-low``, ``reports/campaign-sl2015``: SPEC §17's loop);
* before and after (issue 30): the same seeds of ``reports/campaign-new`` (episode format 15.1, the
  loop the issue measured) against ``reports/campaign-safe``, per mission, density and planner.

Nothing in it is typed by hand; ``tests/test_campaign_tables.py`` fails when the page and the files
disagree.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import sys
from collections import defaultdict
from pathlib import Path
from types import ModuleType

from iamp.simulation.stats import HARD_BRAKE, is_hard_brake

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- campaign-tables:begin -->", "<!-- campaign-tables:end -->"
PAGE = Path("docs") / "closed-loop.md"
#: SUMO's emergency deceleration of its passenger cars (``emergencyDecel`` 9 m/s²; the issue counted
#: ≥ 8.9 m/s² from the logged accelerations) and the "hard braking" threshold (SUMO's ``decel``).
EMERGENCY, HARD = 8.9, HARD_BRAKE
PLANNERS = ("pmp-active", "qp-avoid", "free", "mobil", "sumo")
Rows = list[dict[str, str]]


def _num(value: str) -> float:
    return float(value) if value not in ("", "nan", "None") else 0.0


def read(path: Path) -> Rows:
    """The rows of an ``episodes.csv`` (empty when the file is absent)."""
    if not path.is_file():
        return []
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def counts(rows: Rows) -> tuple[int, int, int, int, int]:
    """``(episodes, successes, at-fault contacts, emergency-braking followers, hard-braking followers)``.

    Contacts at fault are ``contacts_at_fault`` where the monitor judged blame (format 17), else every
    contact (format 15 had no judge); a follower counts once per episode."""
    n = len(rows)
    ok = sum(r["success"] == "True" for r in rows)
    fault = sum(int(_num(r["contacts_at_fault"] if "contacts_at_fault" in r else r["contacts"])) for r in rows)
    emergency = sum(_num(r["follower_max_decel"]) >= EMERGENCY for r in rows)
    hard = sum(is_hard_brake(_num(r["follower_max_decel"])) for r in rows)
    return n, ok, fault, emergency, hard


def _cell(rows: Rows) -> str:
    if not rows:
        return "–"
    n, ok, fault, emergency, hard = counts(rows)
    return f"{ok}/{n}; {fault}; {emergency}; {hard}"


def mission_table(campaigns: list[tuple[str, Rows]]) -> list[str]:
    """Per (campaign, mission, density) and planner: ``success/episodes; at-fault contacts; emergency; hard``."""
    planners = [p for p in PLANNERS if any(r["planner"] == p for _, rows in campaigns for r in rows)]
    extra = any(label for label, _ in campaigns)
    head = "| mission, traffic | " + " | ".join(f"`{p}`" for p in planners) + (" | `sumo` SL2015 |" if extra else " |")
    out = [head, "|---|" + "---|" * (len(planners) + (1 if extra else 0))]
    by: dict[tuple[str, str, str], dict[str, Rows]] = defaultdict(lambda: defaultdict(list))
    for label, rows in campaigns:
        for r in rows:
            coop = r.get("cooperation", "default")
            key = (r["mission"], r["traffic"], coop)
            by[key]["sl2015" if label else r["planner"]].append(r)
    for (mission, traffic, coop) in sorted(by, key=lambda k: (k[2] != "default", k[0], k[1])):
        cells = by[(mission, traffic, coop)]
        name = f"{mission}, {traffic}" + ("" if coop == "default" else f", cooperation {coop}")
        row = [_cell(cells.get(p, [])) for p in planners] + ([_cell(cells.get("sl2015", []))] if extra else [])
        out.append(f"| {name} | " + " | ".join(row) + " |")
    return out


def failure_kinds(campaigns: list[tuple[str, Rows]]) -> list[str]:
    """Per campaign (cooperation) and planner, the episodes that failed, by kind: a contact; stopped
    at the lane's end (``stopped_at_end``); the ego's front past the lane's end still in its lane or
    the deadline reached while moving (the rest)."""
    out = ["| campaign, planner | failed | with a contact | stopped at the lane's end | other (deadline, past the "
           "end) |", "|---|---|---|---|---|"]
    for label, rows in campaigns:
        by: dict[str, Rows] = defaultdict(list)
        for r in rows:
            by[r["planner"]].append(r)
        for p in [q for q in PLANNERS if q in by]:
            failed = [r for r in by[p] if r["success"] != "True"]
            contact = [r for r in failed if _num(r["contacts"]) > 0]
            stopped = [r for r in failed if r not in contact and r["stopped_at_end"] == "True"]
            out.append(f"| {label}, `{p}` | {len(failed)}/{len(by[p])} | {len(contact)} | {len(stopped)} | "
                       f"{len(failed) - len(contact) - len(stopped)} |")
    return out


def before_after(before: Rows, after: Rows, missions: tuple[str, ...] = ("merge", "onramp")) -> list[str]:
    """Per mission, density and planner, the same seeds before and after: ``success; contacts
    (before: all, after: at fault); emergency-braking followers; hard-braking followers``."""
    seeds = {r["seed"] for r in after}
    keep = [r for r in before if r["seed"] in seeds]
    out = ["| mission, traffic, planner | before | after |", "|---|---|---|"]
    for mission in missions:
        for traffic in sorted({r["traffic"] for r in after if r["mission"] == mission}):
            for p in PLANNERS:
                a = [r for r in after if (r["mission"], r["traffic"], r["planner"]) == (mission, traffic, p)]
                b = [r for r in keep if (r["mission"], r["traffic"], r["planner"]) == (mission, traffic, p)]
                if a:
                    out.append(f"| {mission}, {traffic}, `{p}` | {_cell(b)} | {_cell(a)} |")
    return out


def block(root: Path = ROOT) -> str:
    """The generated Markdown between the markers."""
    rep = root / "reports"
    safe, low, sl = (read(rep / c / "episodes.csv") for c in ("campaign-safe", "campaign-safe-low", "campaign-sl2015"))
    seed_set = {r["seed"] for r in safe}
    seeds = len(seed_set)
    sl = [r for r in sl if r["seed"] in seed_set]  # the sublane campaign's episodes of the same seeds (paired)
    out = ["<!-- generated by `python scripts/campaign_tables.py` from the campaigns' episodes.csv: "
           "do not edit by hand -->", "",
           f"Per mission and density ({seeds} paired seeds; each cell: successes/episodes; contacts the ego is "
           f"responsible for; new followers braking at ≥ {EMERGENCY:g} m/s²; new followers braking harder than "
           f"{HARD:g} m/s²; `reports/campaign-safe`, `reports/campaign-safe-low`, `reports/campaign-sl2015`):", ""]
    out += mission_table([("", safe), ("", low)] + ([("SL2015", sl)] if sl else []))
    out += ["", "Failed episodes by kind:", ""]
    out += failure_kinds([("default", safe), ("cooperation low", low)] + ([("SL2015", sl)] if sl else []))
    before = read(rep / "campaign-new" / "episodes.csv")
    if before and safe:
        out += ["", f"Before and after on the same {seeds} seeds (before: `reports/campaign-new`, episode format "
                "15.1, the loop the issue measured, whose contacts had no judge: every contact counted; after: "
                "`reports/campaign-safe`):", ""]
        out += before_after(before, safe)
    return "\n".join(out)


def _readme_results() -> ModuleType:
    """scripts/readme_results.py (its block writer; the scripts are not a package)."""
    path = Path(__file__).resolve().parent / "readme_results.py"
    spec = importlib.util.spec_from_file_location("readme_results", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def render(page: str, root: Path = ROOT) -> str:
    """``page`` with its block replaced by :func:`block`."""
    return str(_readme_results().replace_block(page, BEGIN, END, block(root), str(PAGE)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help=f"exit 1 if {PAGE} is not what the files say")
    args = parser.parse_args(argv)
    return int(_readme_results().update(ROOT / PAGE, render, args.check, "campaign_tables.py"))


if __name__ == "__main__":
    sys.exit(main())
