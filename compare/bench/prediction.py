"""``iamp bench``'s prediction number: 20 neighbours with leaders, one batched leader-aware call.

The case (deterministic): 20 vehicles in two lanes of 10, 3 s of history at 10 Hz (31
samples), speeds 8–20 m/s with gaps of 8–30 m, each vehicle's leader the one ahead in its lane
(the two lane heads have none and take the MTD fallback).  Timed: one
:meth:`~iamp.prediction.leader.model.LeaderPredictor.predict_batch` of all 20 over 5 s at the
0.1-s nodes (initial states, the leaders' CV forecasts, the IDM simulation, the MTD fallback).

``prediction_ego_follower_s``: one :func:`~iamp.prediction.leader.ego.predict_with_ego_leader`
(a follower at 20 m/s with a leader 40 m ahead; the ego's plan moves into the lane from 1.5 s on,
10 m ahead of it at 15 m/s) — the cost of one iteration of the closed loop's ego-in-the-forecast.
"""

from __future__ import annotations

from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.timing import StatsJSON, measure

__all__ = ["NeighboursCase", "PredictionBench", "bench_ego_follower", "bench_leader_prediction", "neighbours_case"]


class NeighboursCase(TypedDict):
    """Histories of ``n`` vehicles (rows) at the times ``t_hist`` (:func:`neighbours_case`)."""

    t_hist: NDArray[np.float64]
    X_hist: NDArray[np.float64]
    XL_hist: NDArray[np.float64]  # the leader's history (NaN: no leader)
    has_leader: NDArray[np.bool_]
    offset: NDArray[np.float64]


class PredictionBench(TypedDict):
    """The median of a timed prediction [s] and its statistics."""

    median: float
    stats: StatsJSON


class LeaderPredictionBench(PredictionBench):
    """:func:`bench_leader_prediction`: with the number of vehicles and of those with a leader."""

    vehicles: int
    with_leader: int


def neighbours_case(n: int = 20, seed: int = 0) -> NeighboursCase:
    """Histories ``(t_hist, X_hist, XL_hist, has_leader, offset)`` of ``n`` vehicles in two lanes."""
    rng = np.random.default_rng(seed)
    t = np.round(np.arange(-30, 1) * 0.1, 10)
    X = np.empty((n, t.size))
    lane_of = np.arange(n) % 2
    x_now = np.zeros(n)
    for lane in (0, 1):
        idx = np.flatnonzero(lane_of == lane)
        x_now[idx] = -np.cumsum(rng.uniform(12.0, 35.0, idx.size))
    v = rng.uniform(8.0, 20.0, n)
    a = rng.uniform(-1.0, 1.0, n)
    X[:] = x_now[:, None] + v[:, None] * t[None, :] + 0.5 * a[:, None] * t[None, :] ** 2
    XL = np.full_like(X, np.nan)
    has = np.zeros(n, dtype=bool)
    for lane in (0, 1):
        idx = np.flatnonzero(lane_of == lane)
        order = idx[np.argsort(-x_now[idx])]  # front first
        for k in range(1, order.size):
            XL[order[k]] = X[order[k - 1]]
            has[order[k]] = True
    return {"t_hist": t, "X_hist": X, "XL_hist": XL, "has_leader": has, "offset": np.full(n, 4.5)}


def bench_leader_prediction(repeats: int = 50) -> LeaderPredictionBench:
    """Median time of one batched leader-aware prediction of 20 neighbours (module docstring)."""
    from iamp.prediction.leader.model import LeaderPredictor, default_leader_model

    case = neighbours_case()
    lp = LeaderPredictor(default_leader_model(), "builtin")
    q = np.asarray(0.1 * np.arange(51), dtype=np.float64)
    XL = np.where(case["has_leader"][:, None], case["XL_hist"], 0.0)

    def run() -> object:
        return lp.predict_batch(case["t_hist"], case["X_hist"], q, 5.0, XL_hist=XL, has_leader=case["has_leader"],
                                offset=case["offset"])

    stats, _ = measure(run, repeats=repeats, warmup=3)
    return {"median": stats.median, "stats": stats.to_dict(), "vehicles": 20,
            "with_leader": int(np.sum(case["has_leader"]))}


def bench_ego_follower(repeats: int = 50) -> PredictionBench:
    """Median time of one follower forecast with the ego's plan as its leader (module docstring)."""
    from iamp.prediction.leader.ego import predict_with_ego_leader
    from iamp.prediction.leader.model import LeaderPredictor, default_leader_model

    lp = LeaderPredictor(default_leader_model(), "builtin")
    th = np.round(np.arange(-30, 1) * 0.1, 10)
    tp = np.linspace(0.0, 5.0, 51)
    yp = np.where(tp < 1.5, 3.5, 0.0)

    def run() -> object:
        return predict_with_ego_leader(lp, th, 20.0 * th, tp, 14.5 + 15.0 * tp, 5.0, plan_y=yp, target_y=0.0,
                                       leader_hist=44.5 + 20.0 * th)

    stats, _ = measure(run, repeats=repeats, warmup=3)
    return {"median": stats.median, "stats": stats.to_dict()}
