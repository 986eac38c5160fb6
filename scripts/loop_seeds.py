"""Closed-loop episodes of every mission and density for a few seeds and planners, one JSON line each.

The check of docs/closed-loop.md on seeds no campaign uses: every mission (merge, onramp,
slow-leader, discretionary) and density (light, medium, dense, LOS E), default cooperation, the
episode's SPEC §17 verdicts (success, contacts, executed limit violations, follower emergency
brakes, RSS-dangerous time at fault and by response, time to merge, executed turns tighter than a
car's turning radius)::

    python scripts/loop_seeds.py 5001,5002,5003,5004 pmp-active,qp-avoid OUT.jsonl
    python scripts/loop_seeds.py summary OUT.jsonl

Each line is what ``iamp simulate --mission M --traffic T --seed S --planner P --json`` reports
for those keys (the same episode: :func:`iamp.simulation.episode.run_episode`).
"""

from __future__ import annotations

import itertools
import json
import sys
from collections import Counter

MISSIONS = ("merge", "onramp", "slow-leader", "discretionary")
TRAFFIC = ("light", "medium", "dense", "los-e")
KEYS = ("success", "contacts", "contacts_at_fault", "limit_violations", "follower_emergency_brakes",
        "rss_dangerous_s", "rss_dangerous_by_response_s", "time_to_merge_s", "curvature_violations")


def run(seeds: list[int], planners: list[str], out: str) -> None:
    from iamp.simulation.episode import EpisodeSpec, run_episode

    with open(out, "w", encoding="utf-8") as f:
        for planner, mission, traffic, seed in itertools.product(planners, MISSIONS, TRAFFIC, seeds):
            s = run_episode(EpisodeSpec(mission=mission, traffic=traffic, seed=seed, planner=planner)).summary
            f.write(json.dumps({"planner": planner, "mission": mission, "traffic": traffic, "seed": seed,
                                **{k: s[k] for k in KEYS}}) + "\n")
            f.flush()


def summary(path: str) -> None:
    rows = [json.loads(line) for line in open(path, encoding="utf-8")]
    for planner in sorted({r["planner"] for r in rows}):
        rs = [r for r in rows if r["planner"] == planner]
        by: Counter[str] = Counter()
        for r in rs:
            by.update(r["rss_dangerous_by_response_s"])
        print(f"{planner}: {len(rs)} episodes, {sum(bool(r['success']) for r in rs)} successes, "
              f"{sum(r['contacts'] for r in rs)} contacts ({sum(r['contacts_at_fault'] for r in rs)} at fault), "
              f"{sum(1 for r in rs if r['limit_violations'])} with executed limit violations, "
              f"{sum(1 for r in rs if r.get('curvature_violations'))} with executed turns tighter than 5 m, "
              f"{sum(r['follower_emergency_brakes'] for r in rs)} follower emergency brakes, "
              f"RSS-dangerous time at fault {sum(r['rss_dangerous_s'] for r in rs):.1f} s in "
              f"{sum(1 for r in rs if r['rss_dangerous_s'] > 0)} episodes "
              f"({', '.join(f'{k} {v:.1f}' for k, v in sorted(by.items()))})")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "summary":
        summary(sys.argv[2])
    elif len(sys.argv) == 4:
        run([int(s) for s in sys.argv[1].split(",")], sys.argv[2].split(","), sys.argv[3])
    else:
        sys.exit(__doc__)
