r"""The safety monitor: measures what was executed, never decides (SPEC §15).

Input: the step log (the ego's executed centre state and heading and every observed
neighbour's centre, speed, acceleration, heading and body per step).  With ``Δx = x_i - x_e``,
``Δy = y_i - y_e``:

* **contact** (SPEC §17) — the bodies, rectangles at their headings, overlap (separating-axis
  test, :func:`iamp.simulation.metrics.separation`); ``contacts`` = distinct neighbours touched
  (``axis_aligned_contacts``: the same with boxes along the road, the measure before §17).
  SUMO's collision reports (run with ``collision.mingap-factor 0``) are compared with them:
  a SUMO report without an overlap of the bodies within one step (``sumo_only``) or an
  overlap SUMO did not report (``monitor_only``) is a **disagreement**, listed with its
  reason (SUMO checks vehicles on one lane, by their positions along it, not their bodies);
  ``success`` counts the monitor's contacts.
* **responsibility** (SPEC §17, :mod:`iamp.simulation.rss`) — every (ego, neighbour) pair is
  judged with RSS: ``rss_dangerous_s`` = the time during which some pair is dangerous and the
  ego violated its proper response since that danger's threshold time (split by the response
  the danger required: ``lateral`` — it began with a sideways approach, a cut-in;
  ``longitudinal``; ``both``); each contact is **at fault** when the ego was responsible at its
  first step, else **not at fault**; ``follower_emergency_brakes`` = the times (runs of
  consecutive steps) a neighbour braked with at least :data:`EMERGENCY_DECEL` while the ego
  was its leader (ahead of it, in its lane or beside its body, nobody in between).  The
  neighbours' lateral speeds are backward differences of their logged positions, their
  longitudinal speeds ``v cos ψ``.
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
  ``ay``, ``a_total`` or ``vx`` is broken (``jerk_violations`` counted apart);
  ``curvature_max`` = the largest curvature of the executed path (points every period, from the
  heading of the first step's velocity: :func:`iamp.simulation.kinematics.turning`) and
  ``curvature_violations`` = its turns tighter than a car's turning radius
  (:data:`~iamp.simulation.kinematics.KAPPA_MAX`; a sideways start from a standstill counts).
* **mission** — ``time_to_merge_s`` = the first time the ego's centre is in the target lane;
  ``success`` = that happened by the deadline, before the ego's front passed its lane's end,
  and no contact; ``stopped_at_end`` = never merged and stood still (``v < 0.5`` m/s) within
  30 m of the lane's end.

The monitor measures; nothing here feeds back into the episode.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.simulation.decision import limit_violation_samples
from iamp.simulation.kinematics import KAPPA_MAX, TOL_REL, start_heading, turning
from iamp.simulation.metrics import (
    StepGeometry,
    StepLog,
    ego_headings,
    episode_geometry,
    neighbour_headings,
    separation,
)
from iamp.simulation.rss import DEFAULT, Motion, PairJudgement, RssParameters, body_extents, judge_pair

#: SUMO's minGap of the ego and the average driver [m].
MIN_GAP_M = 2.5
TTC_ALARM_S = 1.5
#: A neighbour braking at least this hard [m/s²] brakes in an emergency (SPEC §17; SUMO's drivers
#: brake beyond their ``decel`` of 4.5 only in emergencies, up to ``emergencyDecel`` 9).
EMERGENCY_DECEL = 8.0


def _finite(v: float) -> float | None:
    return None if not math.isfinite(v) else float(v)


def executed_accel(E: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Second differences of the executed positions (columns 0 and 2 of ``E``), per step
    ``1..n-2``."""
    if E.shape[0] < 3:
        return np.zeros(0), np.zeros(0)
    return np.diff(E[:, 0], 2) / dt**2, np.diff(E[:, 2], 2) / dt**2


@dataclass(frozen=True)
class Tracks:
    """The neighbours of a log as arrays ``(steps, vehicles)`` (``nan`` where not observed)."""

    ids: tuple[str, ...]
    x: np.ndarray
    y: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lane: np.ndarray
    L: np.ndarray
    W: np.ndarray
    psi: np.ndarray


def tracks_of(log: StepLog) -> Tracks:
    """Every neighbour of ``log`` over all its steps."""
    ids = tuple(dict.fromkeys(v for step in log.ids for v in step))
    col = {v: j for j, v in enumerate(ids)}
    n, m = len(log.t), len(ids)
    # one (quantity, step, vehicle) array filled by one scatter of every logged row (a step lists a
    # vehicle once): each quantity a C-contiguous (n, m) slice, as one array per quantity was
    A = np.full((8, n, m), np.nan)
    steps = [k for k, step in enumerate(log.ids[:n]) if step]
    if steps:
        ks = np.concatenate([np.full(len(log.ids[k]), k) for k in steps])
        js = np.array([col[v] for k in steps for v in log.ids[k]])
        A[:7, ks, js] = np.concatenate([np.asarray(log.nb[k])[:, :7] for k in steps]).T
        A[7, ks, js] = np.concatenate([neighbour_headings(np.asarray(log.nb[k])) for k in steps])
    return Tracks(ids, *A)


def ego_motion(log: StepLog, ego_size: tuple[float, float]) -> Motion:
    """The ego as RSS sees it: executed centre and velocity, body extents at its heading."""
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    hx, hy = body_extents(np.full(E.shape[0], ego_size[0]), np.full(E.shape[0], ego_size[1]), ego_headings(log))
    return Motion(E[:, 0], E[:, 2], E[:, 1], E[:, 3], hx, hy)


def other_motion(tr: Tracks, j: int, dt: float) -> Motion:
    """Neighbour ``j``: longitudinal speed ``v cos ψ``, lateral speed by backward differences
    of its logged ``y`` (0 at its first observed step)."""
    y = tr.y[:, j]
    vy = np.zeros_like(y)
    vy[1:] = (y[1:] - y[:-1]) / dt
    vy[1:][np.isnan(y[:-1]) & np.isfinite(y[1:])] = 0.0
    vy[np.isnan(y)] = np.nan
    hx, hy = body_extents(tr.L[:, j], tr.W[:, j], np.nan_to_num(tr.psi[:, j]))
    return Motion(tr.x[:, j], y, tr.v[:, j] * np.cos(np.nan_to_num(tr.psi[:, j])), vy, hx, hy)


def judge_episode(log: StepLog, dt: float, ego_size: tuple[float, float], p: RssParameters = DEFAULT
                  ) -> tuple[Tracks, dict[str, PairJudgement]]:
    """RSS judgement of every (ego, neighbour) pair of an episode (:func:`iamp.simulation.rss.judge_pair`)."""
    tr = tracks_of(log)
    ego = ego_motion(log, ego_size)
    return tr, {vid: judge_pair(ego, other_motion(tr, j, dt), dt, p) for j, vid in enumerate(tr.ids)}


def _emergency_brakes(tr: Tracks, ego: Motion, lane_of: Callable[[float], int] | None, dt: float
                      ) -> list[dict[str, Any]]:
    """Runs of steps in which a neighbour braked with at least :data:`EMERGENCY_DECEL` while the
    ego was its leader (module docstring)."""
    events: list[dict[str, Any]] = []
    open_: dict[int, dict[str, Any]] = {}  # vehicle -> its running event
    with np.errstate(invalid="ignore"):
        braking = tr.a <= -EMERGENCY_DECEL  # (steps, vehicles); nan (not observed) is not braking
    for k in range(tr.x.shape[0]):
        hard = np.flatnonzero(braking[k])
        now: dict[int, dict[str, Any]] = {}
        if hard.size:
            _, hy = body_extents(tr.L[k], tr.W[k], np.nan_to_num(tr.psi[k]))
            ego_lane = None if lane_of is None else lane_of(float(ego.y[k]))
            xe, ye = float(ego.x[k]), float(ego.y[k])
            for i in (int(i) for i in hard):
                xi, yi, li = float(tr.x[k, i]), float(tr.y[k, i]), float(tr.lane[k, i])
                if not (xe > xi and (ego_lane == li or abs(ye - yi) < float(ego.hy[k]) + hy[i])):
                    continue
                others = np.isfinite(tr.x[k]) & (tr.x[k] > xi) & (tr.x[k] < xe) \
                    & ((tr.lane[k] == li) | (np.abs(tr.y[k] - yi) < hy + hy[i]))
                others[i] = False
                if others.any():
                    continue
                ev = open_.get(i)
                if ev is None:
                    ev = {"vehicle": tr.ids[i], "t": round(k * dt, 10), "decel": 0.0}
                    events.append(ev)
                ev["decel"] = max(ev["decel"], float(-tr.a[k, i]))
                now[i] = ev
        open_ = now
    return events


def _lanes_at(tr: Tracks, j: int, k: int, ego_y: float, lane_of: Callable[[float], int] | None
              ) -> tuple[int | None, int | None]:
    lo = tr.lane[k, j]
    return (None if lane_of is None else lane_of(ego_y)), (None if not np.isfinite(lo) else int(lo))


def responsibility(log: StepLog, dt: float, ego_size: tuple[float, float],
                   sumo_collisions: Sequence[tuple[float, str, str]],
                   lane_of: Callable[[float], int] | None = None, rss: RssParameters = DEFAULT,
                   geometry: list[tuple[StepGeometry, np.ndarray]] | None = None) -> dict[str, Any]:
    """The SPEC §17 measures of an executed episode: oriented contacts, their blame, SUMO's
    disagreements, RSS-dangerous time, the followers' emergency brakes (module docstring).

    Parameters
    ----------
    log : StepLog
        The executed episode (any frame with ``x`` along the road and ``y`` to the left).
    dt : float
        The period [s].
    ego_size : (float, float)
        The ego's length and width [m].
    sumo_collisions : sequence of (t, vehicle, type)
        SUMO's collision reports involving the ego, on the log's clock.
    lane_of : callable, optional
        Lane index of a lateral position, in the numbering of the log's lane column (None: a
        vehicle is in the ego's path only when their bodies overlap sideways).
    rss : RssParameters
        The judge's parameters (reported under ``rss``).
    geometry : list, optional
        :func:`iamp.simulation.metrics.episode_geometry` of the log (computed when omitted).

    Returns
    -------
    dict
        The JSON-ready measures (``contacts``, ``contacts_at_fault``, ... ``rss``).
    """
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    T = np.asarray(log.t, dtype=float)
    psi_e = ego_headings(log)
    touched_aa: set[str] = set()
    touched: dict[str, int] = {}  # oriented overlap: first step
    touching: dict[str, set[int]] = {}  # oriented overlap: every step
    for g, sep in (episode_geometry(log, ego_size) if geometry is None else geometry):
        for j in np.flatnonzero(g.over):
            touched_aa.add(g.ids[j])
        for j in np.flatnonzero(sep < 0):
            touched.setdefault(g.ids[j], g.k)
            touching.setdefault(g.ids[j], set()).add(g.k)
    contacts = set(touched)
    # responsibility (RSS)
    tr, judged = judge_episode(log, dt, ego_size, rss)
    n = len(T)
    resp_any = np.zeros(n, dtype=bool)
    by_kind = {kind: np.zeros(n, dtype=bool) for kind in ("lateral", "longitudinal", "both")}
    for j_ in judged.values():
        bad = j_.dangerous & j_.ego_responsible
        resp_any |= bad
        for kd in np.flatnonzero(bad):
            by_kind[j_.response[kd]][kd] = True
    contact_list = []
    for vid, kc in sorted(touched.items(), key=lambda kv: (kv[1], kv[0])):
        j_ = judged[vid]
        kb = int(j_.blame_k[kc])
        contact_list.append({"vehicle": vid, "t": round(float(T[kc]), 10),
                             "ego_at_fault": bool(j_.ego_responsible[kc]),
                             "other_at_fault": bool(j_.other_responsible[kc]),
                             "response": j_.response[kc] or None,
                             "threshold_t": None if kb < 0 else round(float(T[kb]), 10),
                             "sumo_reported": any(o == vid for _, o, _ in sumo_collisions)})
    at_fault = sum(bool(c["ego_at_fault"]) for c in contact_list)

    # SUMO's reports against the bodies
    col = {v: j for j, v in enumerate(tr.ids)}
    first_report: dict[str, tuple[float, str]] = {}
    for t_r, other, kind in sumo_collisions:
        first_report.setdefault(other, (float(t_r), str(kind)))
    sumo_only = []
    for vid, (t_r, kind) in sorted(first_report.items(), key=lambda kv: (kv[1][0], kv[0])):
        k = int(np.argmin(np.abs(T - t_r))) if T.size else -1
        near = k >= 0 and abs(T[k] - t_r) <= dt / 2 + 1e-9
        if near and touching.get(vid, set()) & {k - 1, k, k + 1}:
            continue  # SUMO and the bodies agree (within one step)
        entry: dict[str, Any] = {"vehicle": vid, "t": round(t_r, 10), "type": kind}
        if not near:
            entry["reason"] = "reported after the last logged step (the bodies there are not in the log)"
        elif vid not in col or not np.isfinite(tr.x[k, col[vid]]):
            entry["reason"] = "the vehicle is not among the observed neighbours at that step"
        else:
            jv = col[vid]
            gap = float(separation(np.array([E[k, 0], E[k, 2]]), ego_size[0], ego_size[1], float(psi_e[k]),
                                   np.array([[tr.x[k, jv], tr.y[k, jv]]]), tr.L[k, jv], tr.W[k, jv],
                                   np.nan_to_num(tr.psi[k, jv]))[0])
            le, lo = _lanes_at(tr, jv, k, float(E[k, 2]), lane_of)
            entry.update(separation_m=round(gap, 4), ego_lane=le, other_lane=lo)
            entry["reason"] = (f"SUMO's check is lane-based (gaps along lane {le} from its positions on the lane, not "
                               f"the bodies); the bodies were {gap:.2f} m apart"
                               + ("" if le == lo else f" and their centres on lanes {le} and {lo}"))
        jr = judged.get(vid)
        if jr is not None and near:
            entry["ego_at_fault"] = bool(jr.ego_responsible[k])
        sumo_only.append(entry)
    monitor_only = []
    for vid, k0 in sorted(touched.items(), key=lambda kv: (kv[1], kv[0])):
        if vid in first_report:
            continue
        le, lo = _lanes_at(tr, col[vid], k0, float(E[k0, 2]), lane_of)
        if le is None or lo is None:
            reason = "SUMO checks pairs on one lane by their positions along it, not the bodies at their headings"
        elif le != lo:
            reason = (f"the bodies overlap across a lane boundary (the ego's centre on lane {le}, the other's on "
                      f"{lo}); SUMO checks pairs on one lane")
        else:
            reason = (f"both on lane {le}; SUMO's positions along the lane did not overlap (the bodies at their "
                      "headings do)")
        monitor_only.append({"vehicle": vid, "t": round(float(T[k0]), 10), "ego_lane": le, "other_lane": lo,
                             "reason": reason})
    brakes = _emergency_brakes(tr, ego_motion(log, ego_size), lane_of, dt)

    return {
        "contacts": len(contacts),
        "contacts_at_fault": int(at_fault),
        "contacts_not_at_fault": len(contacts) - int(at_fault),
        "contact_list": contact_list,
        "overlap_contacts": len(touched),
        "axis_aligned_contacts": len(touched_aa),
        "sumo_contacts": len(first_report),
        "sumo_only_contacts": len(sumo_only),
        "monitor_only_contacts": len(monitor_only),
        "contact_disagreements": len(sumo_only) + len(monitor_only),
        "sumo_only": sumo_only,
        "monitor_only": monitor_only,
        "rss_dangerous_s": round(float(resp_any.sum()) * dt, 10),
        "rss_dangerous_by_response_s": {kind: round(float(v.sum()) * dt, 10) for kind, v in by_kind.items()},
        "follower_emergency_brakes": len(brakes),
        "follower_emergency_brake_list": brakes,
        "rss": rss.as_dict(),
    }


def monitor(log: StepLog, dt: float, ego_size: tuple[float, float], lane_of: Callable[[float], int],
            target_lane: int, deadline_s: float, drop_x: float | None,
            sumo_collisions: Sequence[tuple[float, str, str]], limits: PhysicalLimits = PASSENGER_CAR,
            lookback_s: float = 5.0, rss: RssParameters = DEFAULT,
            geometry: list[tuple[StepGeometry, np.ndarray]] | None = None) -> dict[str, Any]:
    """The §15 and §17 measures of an executed episode (module docstring).

    Parameters
    ----------
    log : StepLog
        The executed episode.
    dt : float
        The period [s].
    ego_size : (float, float)
        The ego's length and width [m].
    lane_of : callable
        Global lane index of a lateral position.
    target_lane : int
    deadline_s : float
        The mission's deadline on the episode clock [s].
    drop_x : float or None
        Where the ego's lane ends [m] (None: it does not).
    sumo_collisions : sequence of (t, vehicle, type)
        SUMO's collision reports involving the ego, on the episode clock.
    limits : PhysicalLimits
    lookback_s : float
        How long before the merge the new follower's braking counts [s].
    rss : RssParameters
        The judge's parameters (reported under ``rss``).
    geometry : list, optional
        :func:`iamp.simulation.metrics.episode_geometry` of the log (computed when omitted).

    Returns
    -------
    dict
        The JSON-ready measures.
    """
    Le = ego_size[0]
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    T = np.asarray(log.t, dtype=float)
    geometry = episode_geometry(log, ego_size) if geometry is None else geometry
    judged = responsibility(log, dt, ego_size, sumo_collisions, lane_of, rss, geometry)
    contacts = {c["vehicle"] for c in judged["contact_list"]}
    close: set[str] = set()
    min_ttc, ttc_steps = math.inf, 0
    for g, sep in geometry:
        for j in np.flatnonzero(g.lat & (sep >= 0) & (g.gap < MIN_GAP_M)):
            close.add(g.ids[j])
        ttc = g.ttc()
        if math.isfinite(ttc):
            min_ttc = min(min_ttc, ttc)
            ttc_steps += ttc < TTC_ALARM_S
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
    viol = int(np.count_nonzero(limit_violation_samples(ax, ay, vx, limits))) if ax.size else 0
    jerk = np.abs(np.diff(np.stack([ax, ay], axis=1), axis=0)) / dt if ax.size > 1 else np.zeros((0, 2))
    jerk_peak = float(jerk.max()) if jerk.size else 0.0
    jv = int(np.sum(np.any(jerk > limits.jerk, axis=1))) if (limits.jerk is not None and jerk.size) else 0
    # the executed path's turns (a car's turning radius, :mod:`iamp.simulation.kinematics`)
    kappa = turning(E[:, 0], E[:, 2], start_heading(float(E[0, 1]), float(E[0, 3]))) if E.size else np.zeros(0)
    return {
        "success": bool(in_time and not contacts),
        "time_to_merge_s": None if t_merge is None else round(t_merge, 10),
        "stopped_at_end": stopped,
        **{k: v for k, v in judged.items()},
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
        "curvature_max": float(kappa.max()) if kappa.size else 0.0,
        "curvature_violations": int(np.sum(kappa > KAPPA_MAX * (1.0 + TOL_REL))),
    }
