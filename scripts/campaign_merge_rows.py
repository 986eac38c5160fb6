"""Replace the episodes of some planners in a campaign folder by those of a new run of the same campaign.

A change to the closed loop that only the iamp planners run (the baselines ``mobil`` and ``sumo``
take other paths through the controller) is measured by re-running the campaign for those planners
alone into a new folder, at the new episode format; this script then writes the published folder's
``episodes.csv`` with the new run's rows for the planners it ran and the published rows for the
others, and the new run's ``episode_format`` into the folder's manifest.  Every other key of the two
manifests must agree (the same missions, densities, cooperation, durations, RSS and courtesy
models), and the new run must hold every (mission, traffic, seed) of the folder for each of its
planners; otherwise it refuses and changes nothing.  Then re-summarise the folder::

    iamp campaign --missions merge,onramp,slow-leader --planners pmp-active,qp-avoid,free \
        --traffic light,medium,dense,los-e --seeds 50 --reference free --workers 2 --out NEW
    python scripts/campaign_merge_rows.py reports/campaign-safe NEW
    iamp campaign ... --no-run --out reports/campaign-safe   # the folder's own command

The rows keep the folder's order (by planner, then as the new run wrote them).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import tempfile
from pathlib import Path

#: Manifest keys that may differ: the planners run, and the format the new run was made at.
FREE_KEYS = ("planners", "episode_format", "reference")


def _rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        return list(reader.fieldnames or []), list(reader)


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
        f.write(text)
    os.replace(tmp, path)


def merge(folder: Path, new: Path) -> str:
    """Merge ``new``'s rows into ``folder`` (module docstring); a one-line summary."""
    old_man = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    new_man = json.loads((new / "manifest.json").read_text(encoding="utf-8"))
    differ = sorted(k for k in set(old_man) | set(new_man)
                    if k not in FREE_KEYS and old_man.get(k) != new_man.get(k))
    if differ:
        raise SystemExit(f"{new / 'manifest.json'}: differs from {folder / 'manifest.json'} in {', '.join(differ)}")
    cols, old = _rows(folder / "episodes.csv")
    new_cols, fresh = _rows(new / "episodes.csv")
    if new_cols != cols:
        raise SystemExit(f"{new / 'episodes.csv'}: its columns differ from {folder / 'episodes.csv'}")
    planners = sorted({r["planner"] for r in fresh})
    key = ("mission", "traffic", "seed")
    for p in planners:
        want = {tuple(r[k] for k in key) for r in old if r["planner"] == p}
        have = {tuple(r[k] for k in key) for r in fresh if r["planner"] == p}
        if want - have:
            raise SystemExit(f"{new / 'episodes.csv'}: planner {p} lacks {len(want - have)} of the folder's episodes")
    order = list(dict.fromkeys(r["planner"] for r in old))
    rows = []
    for p in order:
        rows += [r for r in (fresh if p in planners else old) if r["planner"] == p]
    with tempfile.TemporaryFile("w+", newline="", encoding="utf-8") as buf:
        w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
        buf.seek(0)
        text = buf.read()
    _write_atomic(folder / "episodes.csv", text)
    old_man["episode_format"] = new_man["episode_format"]
    _write_atomic(folder / "manifest.json", json.dumps(old_man, indent=1) + "\n")
    return (f"{folder}: {sum(r['planner'] in planners for r in rows)} rows of {', '.join(planners)} from {new}, "
            f"{sum(r['planner'] not in planners for r in rows)} kept; episode format {new_man['episode_format']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="the published campaign folder")
    ap.add_argument("new", type=Path, help="the new run's folder (some planners only)")
    args = ap.parse_args()
    print(merge(args.folder, args.new))


if __name__ == "__main__":
    main()
