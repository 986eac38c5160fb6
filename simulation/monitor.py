r"""The safety monitor: measures what was executed, never decides (SPEC §15).

Input: the step log (the ego's executed centre state and every observed neighbour's centre,
speed, acceleration and body per step).  With ``Δx = x_i - x_e``, ``Δy = y_i - y_e`` (bodies
axis-aligned; headings during a lane change stay below a few degrees):

* **contact** — bodies overlap, ``|Δx| < (L_e + L_i)/2`` and ``|Δy| < (W_e + W_i)/2``, or SUMO
  reports a collision (run with ``collision.mingap-factor 0``, so only touching bodies count);
  ``contacts`` = distinct neighbours touched.
* **minGap violation** — a neighbour with lateral body overlap closer than ``MIN_GAP_M``
  bumper to bumper but not touching (SUMO's minGap rule; reported apart).
* **TTC** — for neighbours with lateral body overlap, ``gap / closing speed`` when closing;
  ``min_ttc_s`` and ``ttc_below_1_5_s`` (time with some TTC below 1.5 s).
* **the new follower's braking** — the vehicle directly behind the ego in the target lane
  at the first step the ego's centre is in that lane; ``follower_max_decel`` = its largest
  deceleration (SUMO's acceleration, sign flipped) from ``lookback_s`` before that step to
  the end of the log.
* **executed peaks and limits** — the ego's executed acceleration from second differences of
  its executed positions, ``a_k = (s_{k+1} - 2 s_k + s_{k-1})/Δt²`` per axis (the same
  estimate for every planner, SUMO-driven stretches included); ``ego_peak_accel`` =
  ``max_k |a_k|``, the per-axis extremes, the jerk peak ``max |a_{k+1} - a_k|/Δt``, and
  ``limit_violations`` = steps at which :data:`~iamp.core.physical.PASSENGER_CAR`'s ``ax``,
  ``ay``, ``a_total`` or ``vx`` is broken (``jerk_violations`` counted apart).
* **mission** — ``time_to_merge_s`` = the first time the ego's centre is in the target lane;
  ``success`` = that happened by the deadline, before the ego's front passed its lane's end,
  and no contact; ``stopped_at_end`` = never merged and stood still (``v < 0.5`` m/s) within
  30 m of the lane's end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.simulation.decision import limit_violations_of
from iamp.simulation.metrics import StepLog, step_geometry

#: SUMO's minGap of the ego and the average driver [m].
MIN_GAP_M = 2.5
TTC_ALARM_S = 1.5


def _finite(v: float) -> float | None:
    return None if not math.isfinite(v) else float(v)


def executed_accel(E: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Second differences of the executed positions (columns 0 and 2 of ``E``), per step
    ``1..n-2``."""
    if E.shape[0] < 3:
        return np.zeros(0), np.zeros(0)
    return np.diff(E[:, 0], 2) / dt**2, np.diff(E[:, 2], 2) / dt**2


def monitor(log: StepLog, dt: float, ego_size: tuple[float, float], lane_of: Callable[[float], int],
            target_lane: int, deadline_s: float, drop_x: float | None,
            sumo_collisions: Sequence[tuple[float, str, str]], limits: PhysicalLimits = PASSENGER_CAR,
            lookback_s: float = 5.0) -> dict[str, Any]:
    """The §15 measures of an executed episode (module docstring)."""
    Le = ego_size[0]
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    T = np.asarray(log.t, dtype=float)
    touched: set[str] = set()
    close: set[str] = set()
    min_ttc, ttc_steps = math.inf, 0
    for g in step_geometry(log, ego_size):
        for j in np.flatnonzero(g.over):
            touched.add(g.ids[j])
        for j in np.flatnonzero(g.lat & ~g.over & (g.gap < MIN_GAP_M)):
            close.add(g.ids[j])
        ttc = g.ttc()
        if math.isfinite(ttc):
            min_ttc = min(min_ttc, ttc)
            ttc_steps += ttc < TTC_ALARM_S
    contacts = touched | {other for _, other, _ in sumo_collisions}
    close -= contacts

    # mission
    lanes = np.array([lane_of(float(y)) for y in E[:, 2]]) if E.size else np.zeros(0, dtype=int)
    hit = np.flatnonzero(lanes == target_lane)
    k_merge = int(hit[0]) if hit.size else None
    t_merge = None if k_merge is None else float(T[k_merge])
    in_time = t_merge is not None and t_merge <= deadline_s + 1e-9
    if in_time and drop_x is not None and k_merge is not None:
        in_time = E[k_merge, 0] + Le / 2 < drop_x
    stopped = False
    if t_merge is None and drop_x is not None and E.size:
        near_end = E[:, 0] + Le / 2 > drop_x - 30.0
        stopped = bool(np.any(near_end & (E[:, 1] < 0.5)))

    # the new follower
    follower, f_decel = None, None
    if k_merge is not None:
        ids, nb = log.ids[k_merge], log.nb[k_merge]
        behind = [j for j in range(len(ids)) if int(nb[j, 4]) == target_lane and nb[j, 0] < E[k_merge, 0]]
        if behind:
            follower = ids[max(behind, key=lambda j: nb[j, 0])]
            t_from = T[k_merge] - lookback_s
            acc = [float(nb_k[list(ids_k).index(follower), 3]) for t_k, ids_k, nb_k in zip(T, log.ids, log.nb)
                   if t_k >= t_from and follower in ids_k]
            f_decel = max(0.0, -min(acc)) if acc else None

    # executed peaks
    ax, ay = executed_accel(E, dt)
    vx = E[1:-1, 1] if E.shape[0] >= 3 else np.zeros(0)
    a_abs = np.hypot(ax, ay)
    viol = 0
    if ax.size:
        for k in range(ax.size):
            viol += bool(limit_violations_of(ax[k:k + 1], ay[k:k + 1], vx[k:k + 1], limits))
    jerk = np.abs(np.diff(np.stack([ax, ay], axis=1), axis=0)) / dt if ax.size > 1 else np.zeros((0, 2))
    jerk_peak = float(jerk.max()) if jerk.size else 0.0
    jv = int(np.sum(np.any(jerk > limits.jerk, axis=1))) if (limits.jerk is not None and jerk.size) else 0
    return {
        "success": bool(in_time and not contacts),
        "time_to_merge_s": None if t_merge is None else round(t_merge, 10),
        "stopped_at_end": stopped,
        "contacts": len(contacts),
        "overlap_contacts": len(touched),
        "sumo_contacts": len({other for _, other, _ in sumo_collisions}),
        "mingap_violations": len(close),
        "min_ttc_s": _finite(min_ttc),
        "ttc_below_1_5_s": round(ttc_steps * dt, 10),
        "new_follower": follower,
        "follower_max_decel": f_decel,
        "ego_peak_accel": float(a_abs.max()) if a_abs.size else 0.0,
        "ego_ax_range": [float(ax.min()), float(ax.max())] if ax.size else [0.0, 0.0],
        "ego_ay_peak": float(np.abs(ay).max()) if ay.size else 0.0,
        "ego_jerk_peak": jerk_peak,
        "limit_violations": int(viol),
        "jerk_violations": jv,
    }
