#!/usr/bin/env python3
"""Compare two runs of the same campaign episode by episode: the verdicts per planner and how many
episodes took another course.

Usage (from the repository root)::

    python scripts/campaign_compare.py reports/campaign-safe/episodes.csv OTHER/episodes.csv

``OTHER`` is the same campaign re-made elsewhere (another machine, another commit), e.g.
``iamp campaign --missions merge,onramp,slow-leader --planners pmp-active,qp-avoid,free,mobil,sumo
--traffic medium,dense,los-e --seeds 10 --reference free --workers 2 --out OTHER``.  Only the
episodes both files have (mission, planner, traffic, seed) are compared.  Per planner it prints, as
a Markdown table, the episodes compared, the sums of the verdict columns in each run (success,
contacts, contacts at fault, executed limit violations, follower emergency brakes) and the episodes
whose course differs (another success or time to merge).
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import Counter
from pathlib import Path

KEY = ("mission", "planner", "traffic", "seed")
VERDICTS = ("success", "contacts", "contacts_at_fault", "limit_violations", "follower_emergency_brakes")


def read(path: Path) -> dict[tuple[str, ...], dict[str, str]]:
    """The episodes of ``path`` by (mission, planner, traffic, seed)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    missing = [k for k in (*KEY, *VERDICTS, "time_to_merge_s") if rows and k not in rows[0]]
    if missing:
        raise ValueError(f"{path}: no column {missing[0]!r}")
    return {tuple(r[k] for k in KEY): r for r in rows}


def _value(row: dict[str, str], column: str) -> float:  # counts and flags: whole numbers
    v = row[column]
    if column == "success":
        return float(v == "True")
    return float(v) if v not in ("", "None") else 0.0


def compare(a: dict[tuple[str, ...], dict[str, str]], b: dict[tuple[str, ...], dict[str, str]]
            ) -> dict[str, Counter[str]]:
    """Per planner: ``n``, ``a:<column>`` and ``b:<column>`` sums over the common episodes, and
    ``other_course`` (success or time to merge differ)."""
    out: dict[str, Counter[str]] = {}
    for key in sorted(set(a) & set(b)):
        ra, rb = a[key], b[key]
        c = out.setdefault(key[1], Counter())
        c["n"] += 1
        for col in VERDICTS:
            c[f"a:{col}"] += int(_value(ra, col))
            c[f"b:{col}"] += int(_value(rb, col))
        c["other_course"] += int(ra["success"] != rb["success"] or ra["time_to_merge_s"] != rb["time_to_merge_s"])
    return out


def table(result: dict[str, Counter[str]]) -> str:
    """The Markdown table of :func:`compare` (each verdict as ``first -> second``)."""
    head = ["planner", "episodes", *VERDICTS, "another course"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for planner, c in sorted(result.items()):
        cells = [planner, str(c["n"])] + [f"{c[f'a:{v}']:g} -> {c[f'b:{v}']:g}" for v in VERDICTS]
        lines.append("| " + " | ".join(cells + [str(c["other_course"])]) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path)
    ap.add_argument("second", type=Path)
    args = ap.parse_args(argv)
    try:
        result = compare(read(args.first), read(args.second))
    except (OSError, ValueError) as exc:
        print(f"campaign_compare: {exc}", file=sys.stderr)
        return 2
    print(table(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
