r"""Statistics of a campaign: Wilson intervals per cell, paired comparisons between planners.

Seeds are paired (seed ``S`` is the same traffic for every planner), so two planners are
compared on the same episodes:

* **rates** (success, contact, ...): the exact **McNemar** test.  Of the ``n`` pairs, ``b``
  have the event under the reference only and ``c`` under the other planner only; under
  the null hypothesis (equal rates) ``b ~ Binomial(b + c, 1/2)``, and the two-sided p-value is

  .. math::  p = \min\Big(1,\ 2 \sum_{i=0}^{\min(b,c)} \binom{b+c}{i} 2^{-(b+c)}\Big)

  (``p = 1`` when ``b + c = 0``).  The difference of the rates ``(c - b)/n`` gets a paired
  bootstrap interval (below).
* **continuous measures** (the new follower's deceleration, time to merge, executed peak
  acceleration, plan time): the mean of the paired differences ``d_j = x_j^{other} -
  x_j^{ref}`` over the pairs where both are defined, with a **paired bootstrap** 95 %
  percentile interval: resample the ``d_j`` with replacement ``B = 2000`` times
  (``numpy.random.default_rng(0)``: the same numbers every run), take the 2.5 % and 97.5 %
  quantiles of the resampled means.
* **Wilson** score intervals for every rate of a cell (:func:`wilson`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

#: A new follower braking harder than this [m/s²] (the average driver's ``decel``; beyond it
#: SUMO's drivers brake in emergency) is a hard brake.
HARD_BRAKE = 4.5
#: SUMO reports a follower braking at exactly its ``decel`` as 4.5 ± 3e-14 m/s²; within this
#: tolerance it does not brake harder (one definition for the campaign's summary and the scripts' tables).
HARD_BRAKE_TOL = 1e-6


def is_hard_brake(decel: float | None) -> bool:
    """Whether a new follower's largest deceleration ``decel`` [m/s²] exceeds :data:`HARD_BRAKE`
    (beyond :data:`HARD_BRAKE_TOL`); ``None`` (no new follower) is not."""
    return decel is not None and decel > HARD_BRAKE + HARD_BRAKE_TOL
BOOTSTRAP = 2000
MISSION_ORDER = ("merge", "onramp", "slow-leader", "discretionary")
TRAFFIC_ORDER = ("light", "medium", "dense", "los-e")


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of ``k`` successes in ``n`` trials."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z / den * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p-value from the discordant counts ``b`` and ``c``."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0**n
    return min(1.0, 2.0 * tail)


def paired_bootstrap(d: Sequence[float], n_boot: int = BOOTSTRAP, seed: int = 0,
                     level: float = 0.95) -> tuple[float, float, float]:
    """``(mean, lo, hi)`` of the paired differences ``d`` with a percentile bootstrap interval."""
    a = np.asarray(d, dtype=float)
    if a.size == 0:
        return (math.nan, math.nan, math.nan)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, a.size, size=(n_boot, a.size))
    means = a[idx].mean(axis=1)
    q = (1 - level) / 2
    return (float(a.mean()), float(np.quantile(means, q)), float(np.quantile(means, 1 - q)))


# ---------------------------------------------------------------------------------------
# rows -> numbers
# ---------------------------------------------------------------------------------------

def _f(row: dict[str, Any], key: str) -> float | None:
    v = row.get(key, "")
    if v in ("", None, "None"):
        return None
    try:
        return float(v)
    except ValueError:
        return None


def _b(row: dict[str, Any], key: str) -> bool:
    return str(row.get(key, "")).lower() in ("true", "1")


#: Binary events per episode.
EVENTS: dict[str, Any] = {
    "success": lambda r: _b(r, "success"),
    "contact": lambda r: (_f(r, "contacts") or 0) > 0,
    "stopped_at_end": lambda r: _b(r, "stopped_at_end"),
    "mingap": lambda r: (_f(r, "mingap_violations") or 0) > 0,
    "ttc_alarm": lambda r: (_f(r, "ttc_below_1_5_s") or 0) > 0,
    "hard_brake": lambda r: is_hard_brake(_f(r, "follower_max_decel")),
    "limit_violation": lambda r: (_f(r, "limit_violations") or 0) > 0,
    # SPEC §17 (the RSS judge): absent in episodes of campaigns made before it
    "contact_at_fault": lambda r: (_f(r, "contacts_at_fault") or 0) > 0,
    "emergency_brake": lambda r: (_f(r, "follower_emergency_brakes") or 0) > 0,
    "rss_dangerous": lambda r: (_f(r, "rss_dangerous_s") or 0) > 0,
    # episode format 17.5: an executed turn tighter than a car's (simulation/kinematics.py)
    "curvature_violation": lambda r: (_f(r, "curvature_violations") or 0) > 0,
}
#: Events measured only since a later episode format: the column they need.
EVENT_COLUMNS = {"contact_at_fault": "contacts_at_fault", "emergency_brake": "follower_emergency_brakes",
                 "rss_dangerous": "rss_dangerous_s", "curvature_violation": "curvature_violations"}


def _measured(rows: Sequence[dict[str, Any]], name: str) -> bool:
    """Whether the rows measure event ``name`` (a campaign made before SPEC §17 has no RSS columns)."""
    col = EVENT_COLUMNS.get(name)
    return col is None or any(r.get(col) not in ("", None) for r in rows)
#: Continuous measures per episode (None where undefined).
MEASURES: dict[str, Any] = {
    "time_to_merge_s": lambda r: _f(r, "time_to_merge_s") if _b(r, "success") else None,
    "follower_max_decel": lambda r: _f(r, "follower_max_decel"),
    "ego_peak_accel": lambda r: _f(r, "ego_peak_accel"),
    "ego_jerk_peak": lambda r: _f(r, "ego_jerk_peak"),
    "rss_dangerous_s": lambda r: _f(r, "rss_dangerous_s"),
    "min_ttc_s": lambda r: _f(r, "min_ttc_s"),
    "plan_time_p50_s": lambda r: _f(r, "plan_time_p50_s"),
    "plan_time_max_s": lambda r: _f(r, "plan_time_max_s"),
}


def _median(vals: list[float]) -> float | None:
    return float(np.median(vals)) if vals else None


def cell_summary(rs: list[dict[str, Any]]) -> dict[str, Any]:
    """Rates (with Wilson intervals), medians and sums of one (mission, planner, traffic) cell."""
    n = len(rs)
    out: dict[str, Any] = {"episodes": n}
    for name, fn in EVENTS.items():
        if not _measured(rs, name):
            out[f"{name}_episodes"], out[f"{name}_rate"], out[f"{name}_ci"] = None, None, None
            continue
        k = sum(bool(fn(r)) for r in rs)
        out[f"{name}_episodes"] = k
        out[f"{name}_rate"] = k / n if n else None
        out[f"{name}_ci"] = wilson(k, n)
    for name, fn in MEASURES.items():
        vals = [v for v in (fn(r) for r in rs) if v is not None]
        out[f"{name}_median"] = _median(vals)
        out[f"{name}_max"] = max(vals) if vals else None
    for col in ("plans", "planner_calls", "executed_plans", "constrained_plans", "infeasible_plans", "fallbacks",
                "aborts", "limit_violations", "contacts", "contacts_at_fault", "contacts_not_at_fault",
                "follower_emergency_brakes", "contact_disagreements"):
        out[col] = int(sum(_f(r, col) or 0 for r in rs))
    p95 = [v for v in (_f(r, "plan_time_p95_s") for r in rs) if v is not None]
    out["plan_time_p95_s_median"] = _median(p95)
    wall = [v for v in (_f(r, "wall_total_s") for r in rs) if v is not None]
    sim = [v for v in (_f(r, "simulated_s") for r in rs) if v is not None]
    out["wall_s_median"] = _median(wall)
    out["wall_per_simulated_minute_s"] = (60.0 * sum(wall) / sum(sim)) if sim and sum(sim) > 0 else None
    return out


def paired(ref: dict[tuple[str, int], dict[str, Any]], other: dict[tuple[str, int], dict[str, Any]]
           ) -> dict[str, Any]:
    """Paired comparison of two planners on the episodes (keyed by ``(traffic, seed)``) both ran."""
    keys = sorted(set(ref) & set(other))
    out: dict[str, Any] = {"pairs": len(keys)}
    for name, fn in EVENTS.items():
        if not (_measured([ref[k] for k in keys], name) and _measured([other[k] for k in keys], name)):
            out[name] = None
            continue
        a = np.array([bool(fn(ref[k])) for k in keys])
        o = np.array([bool(fn(other[k])) for k in keys])
        b, c = int(np.sum(a & ~o)), int(np.sum(~a & o))
        mean, lo, hi = paired_bootstrap((o.astype(float) - a.astype(float)).tolist())
        out[name] = {"ref": int(a.sum()), "other": int(o.sum()), "b": b, "c": c, "p": mcnemar_exact(b, c),
                     "diff": mean, "ci": [lo, hi]}
    for name, fn in MEASURES.items():
        d = []
        for k in keys:
            x, y = fn(ref[k]), fn(other[k])
            if x is not None and y is not None:
                d.append(y - x)
        mean, lo, hi = paired_bootstrap(d)
        out[name] = {"n": len(d), "diff": None if not d else mean, "ci": None if not d else [lo, hi]}
    return out


def campaign_report(rows: list[dict[str, Any]], planners: Sequence[str], reference: str = "pmp"
                    ) -> dict[str, Any]:
    """Cells (per mission, traffic, planner) and paired comparisons against ``reference``
    (per mission over all densities, and per mission and density)."""
    by: dict[tuple[str, str, str], dict[tuple[str, int], dict[str, Any]]] = {}
    for r in rows:
        m = str(r.get("mission") or "discretionary")
        by.setdefault((m, str(r["planner"]), str(r["traffic"])), {})[(str(r["traffic"]), int(r["seed"]))] = r

    def order(key: tuple[str, ...]) -> tuple[int, ...]:
        m, p, t = key
        return (MISSION_ORDER.index(m) if m in MISSION_ORDER else 9,
                TRAFFIC_ORDER.index(t) if t in TRAFFIC_ORDER else 9,
                list(planners).index(p) if p in planners else 99)

    cells = []
    for key in sorted(by, key=order):
        m, p, t = key
        cells.append({"mission": m, "planner": p, "traffic": t, **cell_summary(list(by[key].values()))})
    comparisons = []
    missions = sorted({k[0] for k in by}, key=lambda m: MISSION_ORDER.index(m) if m in MISSION_ORDER else 9)
    for m in missions:
        traffics = sorted({k[2] for k in by if k[0] == m}, key=lambda t: TRAFFIC_ORDER.index(t)
                          if t in TRAFFIC_ORDER else 9)
        for p in planners:
            if p == reference:
                continue
            for scope in ["all", *traffics]:
                ts = traffics if scope == "all" else [scope]
                ref = {k: v for t in ts for k, v in by.get((m, reference, t), {}).items()}
                oth = {k: v for t in ts for k, v in by.get((m, p, t), {}).items()}
                if ref and oth:
                    comparisons.append({"mission": m, "traffic": scope, "reference": reference, "planner": p,
                                        **paired(ref, oth)})
    return {"reference": reference, "cells": cells, "paired": comparisons}
