"""Which car-following law and calibration for the leader-aware predictor: measured on a vehicle split.

Usage: ``python scripts/compare_leader_laws.py DATA.csv[.gz] [--seed S]`` (NGSIM layout).  Trains the
MTD fallback and each (law, calibration) on the split's training part (80 % of the vehicles) and
prints the RMSE at 5 s on the test part's windows with a known leader, against CV.
"""

from __future__ import annotations

import argparse

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

from iamp.prediction.evaluation.evaluate import DEFAULT_CONFIG
from iamp.prediction.evaluation.leader import _rows_mask, leader_windows
from iamp.prediction.evaluation.select import train_config
from iamp.prediction.evaluation.user import HELD_OUT_FRACTION
from iamp.prediction.leader.leaders import Leaders, leaders_for
from iamp.prediction.leader.model import LeaderPredictor, train_leader_model
from iamp.prediction.loaders import load
from iamp.prediction.windows import FUTURE_S, baseline_cv, make_windows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("data")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    tracks = load([a.data], "ngsim")
    leaders = leaders_for(a.data, "ngsim", tracks)
    train, test = tracks.split_by_track(HELD_OUT_FRACTION, seed=a.seed)
    m = _rows_mask(tracks, train)
    lt = Leaders(leaders.leader[m], leaders.length[m], leaders.source)
    mtd = train_config(train, DEFAULT_CONFIG)
    win = make_windows(test)
    lw = leader_windows(tracks, leaders, win)
    k = lw.known
    cv = baseline_cv(win)
    e_cv = float(np.sqrt(np.mean((cv[k, -1] - win.X_fut[k, -1]) ** 2)))
    print(f"{a.data}: {int(k.sum())} test windows with a known leader; CV RMSE at 5 s {e_cv:.2f} m")
    for law in ("idm", "linear"):
        for cal in ("acceleration", "trajectory"):
            lm = train_leader_model(train, lt, law, fallback=mtd, calibration=cal)
            p = LeaderPredictor(lm).predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S, XL_hist=lw.XL_hist,
                                                  has_leader=k, offset=lw.offset)
            e = float(np.sqrt(np.mean((p[k, -1] - win.X_fut[k, -1]) ** 2)))
            print(f"  {law:6s} {cal:12s} RMSE at 5 s {e:.2f} m ({100 * (e / e_cv - 1):+.1f} % vs CV)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
