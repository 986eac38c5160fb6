"""The README's headline results, computed from what the shipped code wrote (issue 29 item 6).

Usage::

    python scripts/readme_results.py            # rewrite the block between the markers in README.md
    python scripts/readme_results.py --check    # exit 1 if README.md differs from what the files say

The block between ``<!-- results:begin -->`` and ``<!-- results:end -->`` is generated from
``reports/results.json`` (written by ``iamp reproduce``) and the closed-loop campaigns' ``episodes.csv``
(written by ``iamp campaign``: ``reports/campaign-safe`` and ``reports/campaign-safe-low``, SPEC §17's
loop, where present, else ``reports/campaign-new``); nothing in it is typed by hand. ``tests/test_readme.py`` fails
when the README and these files disagree.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

from iamp.simulation.stats import HARD_BRAKE, is_hard_brake

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"


def _run(runs: list[dict[str, object]], prefix: str) -> dict[str, object] | None:
    return next((r for r in runs if str(r["label"]).startswith(prefix)), None)


def reproduction_table(results: dict[str, object]) -> list[str]:
    """The paper's scenarios: PMP, the FOH QP's agreement, and the avoidance QP (SPEC §2, §3, §9, §10)."""
    lines = ["| scenario | PMP cost $J$ | contact time $t^*$ [s] | FOH QP (Clarabel), relative gap | "
             "PMP plan intrusion-free | avoidance QP cost (intrusion-free) |",
             "|---|---|---|---|---|---|"]
    for s in results["safety"]:  # type: ignore[union-attr]
        runs = s["runs"]
        pmp, qp, avoid = _run(runs, "pmp"), _run(runs, "qp-clarabel-foh"), _run(runs, "qp-avoid-clarabel")
        if pmp is None or qp is None or avoid is None:
            continue
        gap = abs(float(qp["cost"]) - float(pmp["cost"])) / float(pmp["cost"])  # type: ignore[arg-type]
        t = ", ".join(f"{float(x):.3f}" for x in pmp["contact_times"])  # type: ignore[union-attr]
        lines.append(f"| {s['name']} | {float(pmp['cost']):.3f} | {t} | {float(qp['cost']):.3f}, {gap:.1e} | "  # type: ignore[arg-type]
                     f"{'yes' if pmp['safety']['intrusion_free'] else 'no'} | "  # type: ignore[index]
                     f"{float(avoid['cost']):.3f} ({'yes' if avoid['safety']['intrusion_free'] else 'no'}) |")  # type: ignore[arg-type,index]
    return lines


def campaign_table(episodes: Path, root: Path = ROOT) -> list[str]:
    """Closed loop: per planner over every mission, density and seed of the published campaign."""
    rows = list(csv.DictReader(episodes.open(newline="", encoding="utf-8")))
    by: dict[str, list[dict[str, str]]] = defaultdict(list)
    for r in rows:
        by[r["planner"]].append(r)
    missions = sorted({r["mission"] for r in rows})
    seeds = len({r["seed"] for r in rows})
    manifest = episodes.parent / "manifest.json"
    fmt = json.loads(manifest.read_text(encoding="utf-8")).get("episode_format", "?") if manifest.is_file() else "?"
    older = fmt != "?" and tuple(int(x) for x in str(fmt).split(".")) < (17,)
    note = (" It was made by the loop before SPEC §17's verified plans and fail-safe; what the verified loop "
            "measures is in `docs/closed-loop.md`." if older else "")
    lines = [f"Closed loop (`{episodes.relative_to(root).as_posix()}`, episode format {fmt}: missions "
             f"{', '.join(missions)}; {seeds} paired seeds per density).{note}", "",
             "| planner | episodes | success | episodes with a contact | executed limit violations (episodes) |",
             "|---|---|---|---|---|"]
    for planner in sorted(by):
        eps = by[planner]
        n = len(eps)
        ok = sum(r["success"] == "True" for r in eps)
        contact = sum(int(r["contacts"] or 0) > 0 for r in eps)
        limits = sum(int(r["limit_violations"] or 0) > 0 for r in eps)
        lines.append(f"| {planner} | {n} | {ok} ({100 * ok / n:.1f} %) | {contact} ({100 * contact / n:.1f} %) | "
                     f"{limits} |")
    return lines


#: The campaigns of SPEC §17's loop shown in the README, in this order (each a folder under reports/).
SAFE_CAMPAIGNS = ("campaign-safe", "campaign-safe-low")


def _num(value: str) -> float:
    return float(value) if value not in ("", "nan") else 0.0


def command(meta: dict[str, object], folder: Path, root: Path, seeds: int) -> str:
    """The ``iamp campaign`` command that makes (or resumes) ``folder`` from its manifest, in backquotes."""
    def joined(key: str) -> str:
        value = meta.get(key) or []
        return ",".join(str(v) for v in value) if isinstance(value, list) else str(value)

    parts = ["iamp campaign", f"--missions {joined('missions')}", f"--planners {joined('planners')}",
             f"--traffic {joined('traffic')}"]
    if meta.get("cooperation", "default") != "default":
        parts.append(f"--cooperation {meta['cooperation']}")
    if meta.get("sublane"):
        parts.append("--sublane")
    parts.append(f"--seeds {seeds}")
    summary = folder / "summary.json"
    if summary.is_file():
        reference = json.loads(summary.read_text(encoding="utf-8")).get("reference")
        if reference:
            parts.append(f"--reference {reference}")
    parts.append(f"--out {folder.relative_to(root).as_posix()}")
    return "`" + " ".join(parts) + "`"


def safety_table(campaigns: list[Path], root: Path = ROOT, sublane: Path | None = None) -> list[str]:
    """Closed loop of SPEC §17, per campaign (cooperation) and planner, with RSS's responsibility
    columns: contacts split by blame, the new follower's emergency (>= 8 m/s²) and hard
    (> :data:`HARD_BRAKE` m/s²) braking, the time in a dangerous situation the ego is responsible
    for, executed limit violations and (episode format 17.5 on) executed turns tighter than a car's
    5 m radius (``–`` where a campaign did not measure them). ``sublane``: the ``episodes.csv`` of the ``sumo`` baseline
    with SL2015 (``iamp campaign --sublane``), a row ``sumo (SL2015)`` of the default-cooperation
    table over the episodes of the same missions, densities and seeds."""
    lines: list[str] = []
    for episodes in campaigns:
        rows = list(csv.DictReader(episodes.open(newline="", encoding="utf-8")))
        manifest = episodes.parent / "manifest.json"
        meta = json.loads(manifest.read_text(encoding="utf-8")) if manifest.is_file() else {}
        fmt, coop = meta.get("episode_format", "?"), meta.get("cooperation", "?")
        rho = (meta.get("rss") or {}).get("response_time_s", "?")
        missions = sorted({r["mission"] for r in rows})
        traffic = sorted({r["traffic"] for r in rows})
        seeds = len({r["seed"] for r in rows})
        turns = bool(rows) and "curvature_violations" in rows[0]  # measured since episode format 17.5
        lines += [f"Closed loop with verified plans (`{episodes.relative_to(root).as_posix()}`, episode format {fmt}; "
                  f"missions {', '.join(missions)}; traffic {', '.join(traffic)}; cooperation {coop}; {seeds} paired "
                  f"seeds; RSS judge with response time {rho} s; {command(meta, episodes.parent, root, seeds)}):", "",
                  "| planner | episodes | success | contacts at fault | contacts not at fault | follower emergency "
                  f"brakes | new follower braking > {HARD_BRAKE:g} m/s² (episodes) | RSS-dangerous time at fault [s] | "
                  "executed limit violations (episodes) |"
                  + (" executed turns < 5 m radius (episodes) |" if turns else ""),
                  "|---|---|---|---|---|---|---|---|---|" + ("---|" if turns else "")]
        by: dict[str, list[dict[str, str]]] = defaultdict(list)
        for r in rows:
            by[r["planner"]].append(r)
        if sublane is not None and coop == "default":
            grid = {(r["mission"], r["traffic"], r["seed"]) for r in rows}
            for r in csv.DictReader(sublane.open(newline="", encoding="utf-8")):
                if (r["mission"], r["traffic"], r["seed"]) in grid:
                    by["sumo (SL2015)"].append(r)
        for planner in sorted(by):
            eps = by[planner]
            n = len(eps)
            ok = sum(r["success"] == "True" for r in eps)
            fault = sum(int(_num(r["contacts_at_fault"])) for r in eps)
            other = sum(int(_num(r["contacts_not_at_fault"])) for r in eps)
            emergency = sum(int(_num(r["follower_emergency_brakes"])) for r in eps)
            hard = sum(is_hard_brake(_num(r["follower_max_decel"])) for r in eps)
            danger = sum(_num(r["rss_dangerous_s"]) for r in eps)
            limits = sum(_num(r["limit_violations"]) > 0 for r in eps)
            turn = (f" {sum(_num(r.get('curvature_violations') or '') > 0 for r in eps)} |"
                    if turns and all(r.get("curvature_violations") not in (None, "") for r in eps) else
                    (" – |" if turns else ""))
            lines.append(f"| {planner} | {n} | {ok} ({100 * ok / n:.1f} %) | {fault} | {other} | {emergency} | "
                         f"{hard} | {danger:.1f} | {limits} |{turn}")
        lines.append("")
    return lines[:-1]


def block(root: Path = ROOT) -> str:
    """The generated Markdown between the markers."""
    results = json.loads((root / "reports" / "results.json").read_text(encoding="utf-8"))
    out = ["<!-- generated by `python scripts/readme_results.py` from reports/results.json and the campaign's "
           "episodes.csv: do not edit by hand -->", "",
           "The paper's scenarios (`iamp reproduce`; `reports/results.json`):", ""]
    out += reproduction_table(results)
    safe = [root / "reports" / c / "episodes.csv" for c in SAFE_CAMPAIGNS]
    safe = [p for p in safe if p.is_file()]
    episodes = root / "reports" / "campaign-new" / "episodes.csv"
    sublane = root / "reports" / "campaign-sl2015" / "episodes.csv"
    if safe:
        out += [""] + safety_table(safe, root, sublane if sublane.is_file() else None)
    elif episodes.is_file():
        out += [""] + campaign_table(episodes, root)
    return "\n".join(out)


def replace_block(text: str, begin: str, end: str, body: str, where: str) -> str:
    """``text`` with what lies between the markers ``begin`` and ``end`` replaced by ``body``."""
    head, sep, rest = text.partition(begin)
    if not sep or end not in rest:
        raise SystemExit(f"{where} has no {begin} ... {end} block")
    _, _, tail = rest.partition(end)
    return f"{head}{begin}\n{body}\n{end}{tail}"


def update(path: Path, render_fn: Callable[[str], str], check: bool, script: str) -> int:
    """Rewrite ``path`` with ``render_fn`` (``check``: exit status 1 when it would change, nothing written)."""
    old = path.read_text(encoding="utf-8")
    new = render_fn(old)
    if check:
        if new != old:
            print(f"{path.name}'s generated block differs from the reports: run python scripts/{script}",
                  file=sys.stderr)
            return 1
        return 0
    path.write_text(new, encoding="utf-8")
    return 0


def render(readme: str, root: Path = ROOT) -> str:
    """``readme`` with its results block replaced by :func:`block`."""
    return replace_block(readme, BEGIN, END, block(root), "README.md")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if README.md is not what the files say")
    args = parser.parse_args(argv)
    return update(ROOT / "README.md", render, args.check, "readme_results.py")


if __name__ == "__main__":
    sys.exit(main())
