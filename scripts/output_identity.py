"""Check that a refactoring leaves the CLI's JSON outputs unchanged (wall times aside).

Runs the same ``iamp`` commands against two source trees (``--before``, ``--after``: checkouts
of the repository, e.g. ``git archive 88e53ec | tar -x -C /tmp/before``) with ``PYTHONPATH`` set
to each, drops the timing fields (:data:`TIMING`), and compares the JSON documents exactly
(floats bit for bit).  Exit status 0: every output identical; 1: a difference (printed).

Usage::

    python scripts/output_identity.py --before /tmp/before --after . [--sim] [--only plan]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

SCENARIOS = ("paper-1", "paper-1-poly", "paper-2", "paper-2-poly", "paper-3", "paper-3-poly", "two-vehicle")

#: The commands compared, by label.
COMMANDS: dict[str, list[str]] = {}
for _s in SCENARIOS:
    COMMANDS[f"plan-{_s}"] = ["plan", _s, "--json"]
    COMMANDS[f"plan-{_s}-qp"] = ["plan", _s, "--planner", "qp", "--json"]
    COMMANDS[f"plan-{_s}-qp-osqp-zoh"] = ["plan", _s, "--planner", "qp", "--solver", "osqp", "--hold", "zoh",
                                          "--steps", "40", "--json"]
    COMMANDS[f"plan-{_s}-qp-avoid"] = ["plan", _s, "--planner", "qp", "--constraint", "avoid", "--json"]
    COMMANDS[f"compare-{_s}"] = ["compare", _s, "--json"]
COMMANDS["plan-two-vehicle-refine"] = ["plan", "two-vehicle", "--planner", "qp", "--contact", "refine", "--json"]
COMMANDS["predict-paper-2"] = ["predict", "paper-2", "--json"]
#: Closed-loop episodes (``--sim``: need SUMO; ``--no-deadline`` makes them independent of speed).
SIM_COMMANDS = {f"simulate-{p}": ["simulate", "--planner", p, "--duration", "12", "--seed", "3", "--no-deadline",
                                  "--json"] for p in ("pmp", "qp", "pmp-active", "qp-avoid", "free", "sumo")}

#: Keys whose values are wall times, memory or machine facts (everything else is compared).
TIMING = re.compile(r"^(solve_time_s|time_s|plan_time_s|wall_s|max_rss_mb|budget_s|timing|timing_summary|machine|"
                    r"versions|platform|cpu_count)$")


def strip(doc: Any, dropped: set[str]) -> Any:
    """``doc`` without the keys matching :data:`TIMING` (their names are collected in ``dropped``)."""
    if isinstance(doc, dict):
        out = {}
        for k, v in doc.items():
            if TIMING.search(str(k)):
                dropped.add(str(k))
            else:
                out[k] = strip(v, dropped)
        return out
    if isinstance(doc, list):
        return [strip(v, dropped) for v in doc]
    return doc


def run(tree: Path, argv: list[str]) -> tuple[int, str, str]:
    env = dict(os.environ, PYTHONPATH=str(tree), MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, "-m", "iamp.cli", *argv], cwd=tree, env=env, capture_output=True,
                       text=True, timeout=1800)
    return p.returncode, p.stdout, p.stderr


def first_difference(a: Any, b: Any, path: str = "") -> str | None:
    """The path of the first difference between two JSON documents (``None``: equal)."""
    if type(a) is not type(b):
        return f"{path}: {type(a).__name__} != {type(b).__name__}"
    if isinstance(a, dict):
        if list(a) != list(b):
            return f"{path}: keys {sorted(set(a) ^ set(b)) or 'in another order'}"
        for k in a:
            d = first_difference(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{path}: length {len(a)} != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            d = first_difference(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} != {b!r}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--sim", action="store_true", help="also the closed-loop episodes (SUMO)")
    ap.add_argument("--only", default="", help="only the commands whose label contains this text")
    args = ap.parse_args()
    commands = dict(COMMANDS, **(SIM_COMMANDS if args.sim else {}))
    bad = 0
    dropped: set[str] = set()
    for label, argv in commands.items():
        if args.only not in label:
            continue
        rb, ob, eb = run(args.before.resolve(), argv)
        ra, oa, ea = run(args.after.resolve(), argv)
        if rb != ra:
            print(f"DIFF {label}: exit {rb} != {ra}\n  before: {eb.strip()[-300:]}\n  after: {ea.strip()[-300:]}")
            bad += 1
            continue
        try:
            jb, ja = strip(json.loads(ob), dropped), strip(json.loads(oa), dropped)
        except json.JSONDecodeError:
            same = ob == oa
            print(f"{'same' if same else 'DIFF'} {label}: exit {rb}, not JSON ({eb.strip()[-200:]})")
            bad += not same
            continue
        d = first_difference(jb, ja)
        print(f"{'same' if d is None else 'DIFF'} {label}: exit {rb}" + (f" at {d}" if d else ""))
        bad += d is not None
    print(f"{len([c for c in commands if args.only in c])} commands, {bad} differ; "
          f"timing keys dropped: {', '.join(sorted(dropped)) or 'none'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
