"""Each run of RSS-dangerous time the ego is responsible for, in the episodes of a campaign.

For every episode of ``EPISODES.csv`` (``iamp campaign``'s ``episodes.csv``) with RSS time at fault
for PLANNER, the episode is run again (the same episode: :func:`iamp.simulation.episode.run_episode`)
and the independent judge's pair judgements (:func:`iamp.simulation.monitor.judge_episode`) are
read: per run of steps at the ego's fault, the other vehicle, the run's length, its threshold step
(``kb = -1``: the pair was dangerous from its first common step), the response the danger required,
the ego's mode at the threshold and over the run, the longitudinal and lateral gaps against RSS's
distances at the run's first step, and the ego's lateral speeds from the threshold on::

    python scripts/rss_runs.py reports/campaign-safe/episodes.csv pmp-active [--top 20]

(docs/closed-loop.md, "RSS at fault where the ego starts and returns", was classified with it.)
"""

from __future__ import annotations

import argparse
import csv

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("episodes")
    ap.add_argument("planner")
    ap.add_argument("--top", type=int, default=0, help="only the episodes with the most time at fault")
    a = ap.parse_args()
    from iamp.simulation.episode import EpisodeSpec, run_episode
    from iamp.simulation.monitor import ego_motion, judge_episode

    with open(a.episodes, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["planner"] == a.planner and float(r["rss_dangerous_s"] or 0) > 0]
    rows.sort(key=lambda r: -float(r["rss_dangerous_s"]))
    for r in rows[: a.top or None]:
        spec = EpisodeSpec(mission=r["mission"], traffic=r["traffic"], seed=int(r["seed"]), planner=a.planner)
        log = run_episode(spec).log
        size = (4.8, 1.8)
        _, pairs = judge_episode(log, spec.period_s, size)
        ego = ego_motion(log, size)
        for vid, j in pairs.items():
            bad = j.dangerous & j.ego_responsible
            if not bad.any():
                continue
            ks = np.flatnonzero(bad)
            for run in np.split(ks, np.flatnonzero(np.diff(ks) > 1) + 1):
                k0, kb = int(run[0]), int(j.blame_k[run[0]])
                modes = sorted({log.mode[k] for k in range(max(kb, 0), min(int(run[-1]) + 1, len(log.mode)))})
                vy = [round(float(ego.vy[k]), 2) for k in range(max(kb, 0), k0 + 1)][:6]
                print(f"{r['mission']} {r['traffic']} {r['seed']} {vid}: {len(run) * spec.period_s:.1f} s, "
                      f"threshold step {kb}, first step {k0}, response {j.response[k0]}, "
                      f"mode at threshold {log.mode[max(kb, 0)]}, modes {modes}, "
                      f"lon gap {j.lon_gap[k0]:.1f} / RSS {j.d_lon[k0]:.1f} m, "
                      f"lat gap {j.lat_gap[k0]:.2f} / RSS {j.d_lat[k0]:.2f} m, ego v_y {vy}", flush=True)


if __name__ == "__main__":
    main()
