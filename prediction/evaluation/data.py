"""Synthetic tracks and the paper's three histories, for tests and demonstrations."""

from __future__ import annotations

import numpy as np

from iamp.core.scenario import History
from iamp.prediction.tracks.table import Tracks

__all__ = ["paper_histories", "synthetic_tracks"]


def paper_histories() -> dict[str, History]:
    """The three 3-s histories of SPEC §8 (0.1 s sampling, ``x(0) = -15``).

    1. constant 18 m/s;  2. braking at -1.5 m/s² to 20 m/s at ``t = 0``;
    3. accelerating at +2 m/s² to 13 m/s at ``t = 0``.
    """

    t = np.round(np.arange(-30, 1) * 0.1, 10)
    xs = {"paper-1": -15.0 + 18.0 * t,
          "paper-2": -15.0 + 20.0 * t - 0.75 * t * t,
          "paper-3": -15.0 + 13.0 * t + 1.0 * t * t}
    return {k: History(t, x, field="vehicles[0].history", source=k) for k, x in xs.items()}



def synthetic_tracks(n_tracks: int = 40, duration: float = 90.0, dt: float = 0.1, seed: int = 0) -> Tracks:
    """Synthetic highway-like tracks for tests: regime-switching, jerk-limited acceleration.

    Each track alternates phases of 2–6 s (cruise with probability 0.5, accelerate or brake
    at 0.8–2 m/s² with probability 0.25 each); the acceleration follows the phase's target
    with a 0.5 s first-order lag; speeds start in 12–30 m/s and stay within 5–33 m/s.
    """

    rng = np.random.default_rng(seed)
    cols: dict[str, list[np.ndarray]] = {k: [] for k in ("track_id", "t", "x", "v", "a", "lane")}
    n = int(round(duration / dt)) + 1
    for tid in range(n_tracks):
        target = np.zeros(n)
        k = 0
        while k < n:
            L = max(int(rng.uniform(2.0, 6.0) / dt), 1)
            mode = rng.choice([0, 1, -1], p=[0.5, 0.25, 0.25])
            target[k:k + L] = mode * rng.uniform(0.8, 2.0)
            k += L
        a, v, x = np.zeros(n), np.zeros(n), np.zeros(n)
        v[0] = rng.uniform(12.0, 30.0)
        for i in range(1, n):
            a[i] = a[i - 1] + (target[i] - a[i - 1]) * dt / 0.5
            if (v[i - 1] > 33.0 and a[i] > 0) or (v[i - 1] < 5.0 and a[i] < 0):
                a[i] = 0.0
            v[i] = max(v[i - 1] + a[i] * dt, 0.0)
            x[i] = x[i - 1] + v[i - 1] * dt + 0.5 * a[i] * dt * dt
        for key, val in zip(cols, (np.full(n, tid), dt * np.arange(n), x, v, a, np.zeros(n, dtype=int))):
            cols[key].append(val)
    c = {k: np.concatenate(v) for k, v in cols.items()}
    return Tracks(c["track_id"], c["t"], c["x"], c["v"], c["a"], c["lane"], dt=dt,
                  meta={"format": "synthetic", "name": "synthetic", "seed": seed})
