"""
One closed-loop episode in SUMO traffic
=======================================

``iamp simulate`` puts the planner in a car on a SUMO highway: every control period the ego
observes the last 3 s of its neighbours, the predictor turns each history into a cubic, the
decision layer picks a gap, the planner plans the lane change and the first period of the plan
is executed only when it and its fail-safe keep RSS's safe distances (SPEC §17); an independent
monitor judges what was executed with the same RSS parameters. Here: a merge (the ego's lane
ends) in medium traffic with ``pmp-active``, the paper's PMP with the equality imposed only where
it is a real constraint. While the ego signals, the target-lane driver behind it opens a gap (a
courteous SUMO driver, braking at most 2 m/s² for it; the verification does not count on it).
Needs the ``[sim]`` extra (SUMO wheels); without it, it says so and stops.

Run: ``python examples/closed_loop_episode.py``
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from PIL import Image


def main() -> dict[str, object] | None:
    if importlib.util.find_spec("libsumo") is None:
        print("skipped: needs pip install 'iamp[sim]'")
        return None
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "episode.csv"
        # libsumo runs one simulation per process: the episode runs in its own
        run = subprocess.run([sys.executable, "-m", "iamp", "simulate", "--mission", "merge", "--traffic", "medium",
                              "--seed", "2", "--planner", "pmp-active", "--log", str(log), "--json"],
                             capture_output=True, text=True, encoding="utf-8")
        if run.returncode == 2:
            raise RuntimeError(run.stderr.strip())
        episode = json.loads(run.stdout)
        for key in ("success", "time_to_merge_s", "contacts", "contacts_at_fault", "rss_dangerous_s",
                    "follower_emergency_brakes", "follower_max_decel", "min_ttc_s", "limit_violations", "plans"):
            print(f"{key:18s} {episode.get(key)}")
        gif = Path(tmp) / "episode.gif"
        subprocess.run([sys.executable, "-m", "iamp", "plot", "--episode", str(log), "--out", str(gif), "--speed",
                        "4", "--fps", "4"], check=True, capture_output=True)
        with Image.open(gif) as im:
            frames = []
            for k in np.linspace(0, im.n_frames - 1, 3).astype(int):
                im.seek(int(k))
                frames.append(im.convert("RGB"))
    _, axes = plt.subplots(3, 1, figsize=(9, 6))
    for ax, frame in zip(axes, frames):
        ax.imshow(frame)
        ax.set_axis_off()
    return episode


if __name__ == "__main__":
    main()
