"""Measurable aggressiveness and safety of a plan, and the paper's qualitative claims.

* :func:`manoeuvre_metrics` — contact time, lane-divider crossing, peak accelerations and
  jerks, the cost split by axis, and where the ego is inside a safety box or overlaps a
  vehicle's body (on a 1 ms grid);
* :func:`qualitative_comparison` — scenario 2 against 1 (the paper: more aggressive) and 3
  against 1 (the paper: more conservative), measure by measure
  (:data:`AGGRESSION_MEASURES`).

Used by :func:`iamp.comparison.report.reproduce`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from iamp.core.plan import Plan
from iamp.core.safety import INTRUSION_TOL_M, safety_report

__all__ = ["AGGRESSION_MEASURES", "INSIDE_TOL_M", "manoeuvre_metrics", "qualitative_comparison"]


def _crossing_time(t: NDArray[np.float64], y: NDArray[np.float64], level: float) -> float | None:
    """First time ``y`` crosses ``level`` (linear interpolation), or ``None``."""
    d = y - level
    idx = np.nonzero(np.sign(d[:-1]) != np.sign(d[1:]))[0]
    if idx.size == 0:
        return None
    k = idx[0]
    return float(t[k] - d[k] * (t[k + 1] - t[k]) / (d[k + 1] - d[k]))


#: Depth [m] beyond which the ego's point counts as inside a safety box (touching the corner at
#: ``t_i`` and numerical round-off are not "inside"); the one of :mod:`iamp.core.safety`.
INSIDE_TOL_M = INTRUSION_TOL_M


class ManoeuvreMetrics(TypedDict):
    """:func:`manoeuvre_metrics`: aggressiveness and safety of a plan (lists: per vehicle)."""

    J: float
    J_x: float
    J_y: float
    t_contact: list[float]
    x_contact: list[float]
    t_cross: float | None
    lane_divider_y: float
    peak_ax: float
    peak_ay: float
    peak_jerk_x: float
    peak_jerk_y: float
    min_vx: float
    max_vx: float
    final_gap_to_corner: list[float]
    vehicle_speed_0: list[float]
    vehicle_speed_tf: list[float]
    inside_safety_box: list[list[list[float]]]
    max_depth_inside_safety_box: list[float]
    body_overlap: list[list[list[float]]]


class QualitativeMeasure(TypedDict):
    """One measure of :func:`qualitative_comparison`: scenario 1's value against the other's."""

    measure: str
    label: str
    scenario_1: float
    other: float
    other_is: str


class QualitativeEntry(TypedDict):
    """:func:`qualitative_comparison` of one scenario against scenario 1."""

    paper_claim: str
    observed_majority: str
    n_more_aggressive: int
    n_more_conservative: int
    n_measures: int
    measures: list[QualitativeMeasure]
    consistent_with_paper: bool


def manoeuvre_metrics(result: Plan) -> ManoeuvreMetrics:
    """Measurable aggressiveness and safety of a plan (on a 1 ms grid).

    ``t_cross``: first crossing of the lane divider half-way between ``y0`` and vehicle 1's
    lane; ``peak_*``: max-abs acceleration / jerk; ``J_x``, ``J_y``: the cost split by axis;
    ``inside_safety_box``: time intervals where the ego's point is strictly inside a safety
    box by more than :data:`INSIDE_TOL_M` (the equality touches its corner at ``t_i`` only) and
    ``max_depth_inside_safety_box``
    the largest distance from the point to the box's boundary while inside; ``body_overlap``: where the ego's
    body (``[ego] length`` x ``width``, default 4.8 x 1.8 m) overlaps a vehicle's body.  These three are
    the plan's SPEC §9 report (:attr:`iamp.core.plan.Plan.safety`): interval ends are exact roots of
    the piecewise-polynomial trajectory, not the last sample of a grid.
    """
    prob = result.problem
    tf = prob.tf
    t = np.linspace(0.0, tf, int(round(tf * 1000)) + 1)
    X = result.require_trajectory().states(t)
    U = result.require_trajectory().inputs(t)
    jerk = np.diff(U, axis=0) / np.diff(t)[:, None]
    v1 = prob.vehicles[0]
    divider = 0.5 * (prob.ego.y0 + v1.y)
    # where the plan is unsafe: exact interval ends (roots), SPEC §9 (iamp.core.safety)
    report = getattr(result, "safety", None) or safety_report(prob, result.trajectory)
    inside = [[list(iv) for iv in v.intrusion] for v in report.vehicles]
    body = [[list(iv) for iv in v.overlap] for v in report.vehicles]
    depths = [v.max_intrusion_m for v in report.vehicles]
    w = np.diff(t)
    if result.cost is None:
        raise ValueError(f"a plan with status {result.status!r} has no cost and no manoeuvre to measure")
    return {
        "J": float(result.cost),
        "J_x": float(0.5 * np.sum(w * 0.5 * (U[:-1, 0] ** 2 + U[1:, 0] ** 2))),
        "J_y": float(0.5 * np.sum(w * 0.5 * (U[:-1, 1] ** 2 + U[1:, 1] ** 2))),
        "t_contact": [float(x) for x in result.contact_times],
        "x_contact": [float(x) for x in result.require_trajectory().states(result.contact_times)[:, 0]],
        "t_cross": _crossing_time(t, X[:, 2], divider),
        "lane_divider_y": divider,
        "peak_ax": float(np.max(np.abs(U[:, 0]))),
        "peak_ay": float(np.max(np.abs(U[:, 1]))),
        "peak_jerk_x": float(np.max(np.abs(jerk[:, 0]))),
        "peak_jerk_y": float(np.max(np.abs(jerk[:, 1]))),
        "min_vx": float(np.min(X[:, 1])),
        "max_vx": float(np.max(X[:, 1])),
        "final_gap_to_corner": [float(X[-1, 0] - v.corner_x(tf)) for v in prob.vehicles],
        "vehicle_speed_0": [float(v.speed(0.0)) for v in prob.vehicles],
        "vehicle_speed_tf": [float(v.speed(tf)) for v in prob.vehicles],
        "inside_safety_box": inside,
        "max_depth_inside_safety_box": depths,
        "body_overlap": body,
    }


#: (key, label, +1 if larger is more aggressive, −1 if smaller is)
AGGRESSION_MEASURES = (
    ("t_contact", "earlier contact time $t^*_1$", -1),
    ("t_cross", "earlier crossing of the lane divider", -1),
    ("peak_ay", "larger peak lateral acceleration $|u_y|$", +1),
    ("peak_jerk_y", "larger peak lateral jerk", +1),
    ("peak_ax", "larger peak longitudinal acceleration $|u_x|$", +1),
    ("J", "higher cost $J$", +1),
    ("final_gap_to_corner", "smaller final clearance $s_x(t_f) - \\mathrm{corner}_x(t_f)$ ahead of vehicle 1", -1),
)


def qualitative_comparison(metrics: Mapping[str, ManoeuvreMetrics]) -> dict[str, QualitativeEntry]:
    """Scenario 2 vs 1 (paper: more aggressive) and 3 vs 1 (paper: more conservative)."""
    def val(m: ManoeuvreMetrics, key: str) -> float | None:
        v = m.get(key)
        if isinstance(v, list):
            v = v[0]
        assert v is None or isinstance(v, float | int)
        return v

    out: dict[str, QualitativeEntry] = {}
    if "paper-1" not in metrics:
        return out
    base = metrics["paper-1"]
    for other, claim in (("paper-2", "more aggressive"), ("paper-3", "more conservative")):
        if other not in metrics:
            continue
        rows: list[QualitativeMeasure] = []
        n_agg = n_cons = 0
        for key, label, sign in AGGRESSION_MEASURES:
            a, b = val(base, key), val(metrics[other], key)
            if a is None or b is None:
                continue
            diff = (b - a) * sign  # > 0: 'other' more aggressive on this measure
            more = "more aggressive" if diff > 0 else ("more conservative" if diff < 0 else "equal")
            n_agg += diff > 0
            n_cons += diff < 0
            rows.append({"measure": key, "label": label, "scenario_1": a, "other": b, "other_is": more})
        n = len(rows)
        observed = ("more aggressive" if n_agg > n / 2 else "more conservative" if n_cons > n / 2 else "mixed")
        out[other] = {"paper_claim": claim, "observed_majority": observed, "n_more_aggressive": int(n_agg),
                      "n_more_conservative": int(n_cons), "n_measures": n, "measures": rows,
                      "consistent_with_paper": observed == claim}
    return out
