r"""The ego in the forecast: the target-lane follower predicted with the ego's plan as its leader.

In a merge the target-lane follower's next seconds are set by the ego.  Given the ego's intended
plan ``(t, x_e(t), y_e(t))`` and the follower's observed past, :func:`predict_with_ego_leader`
integrates the calibrated car-following law (:mod:`.car_following`) with, at every node
``τ_k = k Δ`` (``Δ`` = :data:`~iamp.prediction.leader.model.SIM_DT`), the **nearer** of

* the ego, while its body intrudes into the target lane, ``|y_e(τ_k) - y_t| < w_l/2 + W_e/2``
  (half the lane plus half the ego's width), from the first such node ``k*`` at which it is ahead
  of the follower (``x_e - (L_e + L_f)/2 > x``, tested on the follower's path without the ego,
  which is its path up to ``k*``), with gap ``s = x_e - x - (L_e + L_f)/2``;
* the follower's present leader in its lane (constant-velocity forecast of its observed past),
  with gap ``s = x_l - x - (L_l + L_f)/2``;

and the free road (no interaction term) where neither is there.  The two leaders' lengths differ,
so both are passed to the simulation as *effective* leaders ``x̃ = x - (L + L_f)/2`` with offset 0.
The result is the follower's positions at the nodes and their least-squares cubic ``x_poly``
(ascending powers, as SPEC §7's Ω) — what the planner consumes.

:func:`iterate_with_planner` closes the loop: plan against the follower's cubic, predict the
follower against that plan, re-plan, at most ``max_iter`` plans per control period, stopping when
the cubic moves less than ``tol_m``.  The closed loop calls them as described in
``docs/prediction-interaction.md`` ("The hook for the closed loop").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Generic, TypedDict, TypeVar

import numpy as np

from iamp.prediction._typing import BoolArray, FloatArray
from iamp.prediction.initial_state import smooth_histories
from iamp.prediction.leader.car_following import simulate
from iamp.prediction.leader.model import SIM_DT, LeaderPredictor

__all__ = ["LANE_WIDTH_M", "EgoLeaderForecast", "follower_poly_for_plan", "iterate_with_planner",
           "predict_follower_of_plan", "predict_with_ego_leader"]

#: Lane width used for the intrusion test when the caller gives none [m].
LANE_WIDTH_M = 3.5


@dataclass(frozen=True)
class EgoLeaderForecast:
    """The follower's forecast with the ego in it.

    Attributes
    ----------
    x_poly : tuple of 4 float
        Least-squares cubic of ``x`` over ``[0, tf]`` (ascending powers).
    t, x, v : numpy.ndarray, shape (M + 1,)
        Nodes ``0, Δ, .., tf`` and the follower's centre positions and speeds there.
    ego_leads : numpy.ndarray of bool, shape (M + 1,)
        Nodes at which the ego is the follower's (nearer) leader.
    """

    x_poly: tuple[float, ...]
    t: FloatArray
    x: FloatArray
    v: FloatArray
    ego_leads: BoolArray


def _nodes(tf: float) -> FloatArray:
    M = max(int(np.ceil(tf / SIM_DT - 1e-9)), 1)
    t: FloatArray = np.asarray(np.minimum(SIM_DT * np.arange(M + 1), tf), dtype=np.float64)
    return t


def predict_with_ego_leader(predictor: LeaderPredictor, t_hist: FloatArray, x_hist: FloatArray,
                            plan_t: FloatArray, plan_x: FloatArray, tf: float, *,
                            plan_y: FloatArray | None = None, target_y: float | None = None,
                            ego_length: float = 4.5, ego_width: float = 1.8, follower_length: float = 4.5,
                            lane_width: float = LANE_WIDTH_M, leader_hist: FloatArray | None = None,
                            leader_length: float = 4.5) -> EgoLeaderForecast:
    """The target-lane follower's forecast with the ego's plan as a leader (module docstring).

    Parameters
    ----------
    predictor : LeaderPredictor
        Its law and its smoother's jerk density are used.
    t_hist, x_hist : numpy.ndarray, shape (K,)
        The follower's observed centre positions (``t_hist <= 0``, ``K >= 3``).
    plan_t, plan_x : numpy.ndarray
        The ego's planned centre positions over ``[0, tf]`` (increasing times covering it).
    tf : float
    plan_y, target_y : numpy.ndarray and float, optional
        The ego's planned lateral positions at ``plan_t`` and the target lane's centre: the ego
        leads only where its body intrudes into the target lane.  Without them the ego leads at
        every node where it is ahead of the follower.
    ego_length, ego_width, follower_length, lane_width, leader_length : float
        [m].
    leader_hist : numpy.ndarray, shape (K,), optional
        The follower's present leader's observed centre positions at ``t_hist``.

    Returns
    -------
    EgoLeaderForecast
    """
    t = _nodes(tf)
    th = np.asarray(t_hist, dtype=float)
    pt = np.asarray(plan_t, dtype=float)
    xe = np.interp(t, pt, np.asarray(plan_x, dtype=float))
    ve = np.gradient(xe, t)
    sm = smooth_histories(th, np.asarray(x_hist, dtype=float)[None, :], predictor.model.jerk_psd)
    x0, v0 = float(sm.x[0, -1]), max(float(sm.v[0, -1]), 0.0)
    inside = np.ones(t.size, dtype=bool)
    if plan_y is not None and target_y is not None:
        ye = np.interp(t, pt, np.asarray(plan_y, dtype=float))
        inside = np.abs(ye - float(target_y)) < 0.5 * (lane_width + ego_width)
    # effective leader positions (rear minus the follower's half length): offset 0 below
    x_eff = xe - 0.5 * (ego_length + follower_length)
    if leader_hist is not None:
        xo, vo = predictor.leader_forecast_cv(th, np.asarray(leader_hist, dtype=float)[None, :], tf)
        x_cur, v_cur = xo[0, : t.size] - 0.5 * (leader_length + follower_length), vo[0, : t.size]
    else:
        x_cur, v_cur = np.full(t.size, np.inf), np.zeros(t.size)
    law = predictor.model.law

    def run(xl: FloatArray, vl: FloatArray) -> tuple[FloatArray, FloatArray]:
        far = ~np.isfinite(xl)  # a free road: the interaction term vanishes; keep the arrays finite
        xl = np.where(far, x0 + 1e6, xl)
        vl = np.where(far, v0, vl)
        xs, vs = simulate(law, np.array([x0]), np.array([v0]), xl[None, :], vl[None, :], np.zeros(1), SIM_DT)
        return xs[0], vs[0]

    # pass 1: without the ego; it starts to lead at the first node where it is in the lane ahead of
    # that path (before that node the path with the ego is this one, so the test is exact)
    x_free, v_free = run(x_cur, v_cur)
    enter = np.flatnonzero(inside & (x_eff > x_free))
    ego_leads = np.zeros(t.size, dtype=bool)
    if enter.size:
        ego_leads[enter[0]:] = inside[enter[0]:]
        ego_leads &= x_eff < x_cur
    if not ego_leads.any():
        x_f, v_f = x_free, v_free
    else:
        x_f, v_f = run(np.where(ego_leads, x_eff, x_cur), np.where(ego_leads, ve, v_cur))
    V = np.vander(t, 4, increasing=True)
    c, *_ = np.linalg.lstsq(V, x_f, rcond=None)
    return EgoLeaderForecast(tuple(float(z) for z in c), t, x_f, v_f, ego_leads)


def predict_follower_of_plan(predictor: LeaderPredictor, t_hist: FloatArray, x_hist: FloatArray,
                             plan_t: FloatArray, plan_x: FloatArray, tf: float, *, offset: float = 4.5,
                             current_leader_hist: FloatArray | None = None) -> tuple[tuple[float, ...], FloatArray]:
    """:func:`predict_with_ego_leader` with the ego leading wherever it is ahead (no lateral test).

    ``offset`` = ``(L_ego + L_follower)/2`` (both lengths taken equal to it); returns ``(x_poly, x)``.
    """
    f = predict_with_ego_leader(predictor, t_hist, x_hist, plan_t, plan_x, tf, ego_length=offset,
                                follower_length=offset, leader_hist=current_leader_hist, leader_length=offset)
    return f.x_poly, f.x


#: What the planner of :func:`iterate_with_planner` returns (and its ``predict`` takes, unpacked).
R = TypeVar("R", bound=tuple[object, ...])


class FixedPoint(TypedDict, Generic[R]):
    """:func:`iterate_with_planner`'s result: the follower's cubic, the plan made against it, the
    number of re-plans, whether the iteration converged and its residuals [m]."""

    x_poly: tuple[float, ...]
    plan: R
    iterations: int
    converged: bool
    changes_m: list[float]


def iterate_with_planner(plan: Callable[[tuple[float, ...]], R], predict: Callable[..., Iterable[float]],
                         x_poly0: tuple[float, ...], *, max_iter: int = 3, tol_m: float = 0.1,
                         tf: float = 5.0, relax: float = 1.0) -> FixedPoint[R]:
    """Fixed-point iteration plan ↔ follower prediction, at most ``max_iter`` re-plans.

    ``plan(x_poly)`` plans against the follower's cubic and returns a tuple (e.g.
    ``(plan_t, plan_x, plan_y)``); ``predict(*that)`` returns the follower's new cubic (e.g.
    ``predict_with_ego_leader(...).x_poly``).  Stops when the follower's cubic moves less than
    ``tol_m`` (max over ``[0, tf]``) or after ``max_iter`` re-plans (``max_iter + 1`` plans; the
    returned ``plan`` is made against the returned ``x_poly``, or, when converged, against a
    cubic within ``tol_m`` of it).  Returns ``{"x_poly", "plan", "iterations", "converged", "changes_m"}``.

    ``relax`` in ``(0, 1]`` damps the iteration: the next cubic is
    ``c_{k+1} = c_k + relax (P(c_k) - c_k)`` with ``P(c_k)`` the prediction against the plan made
    for ``c_k`` (1: plain fixed-point iteration).  A map that is not a contraction (the plan jumps
    between solutions as the follower's cubic moves) can oscillate undamped.  ``changes_m`` are the
    residuals ``max_t |P(c_k)(t) - c_k(t)|``; converged means the last is below ``tol_m``, and then
    ``x_poly = P(c_k)`` with ``plan`` made against ``c_k``.
    """
    if not 0.0 < relax <= 1.0:
        raise ValueError(f"relax must be in (0, 1] (got {relax!r})")
    tt = np.linspace(0.0, tf, 51)
    P = np.polynomial.polynomial
    poly = tuple(float(z) for z in x_poly0)
    changes: list[float] = []
    result = plan(poly)
    for k in range(max_iter):
        pred = tuple(float(z) for z in predict(*result))
        residual = float(np.max(np.abs(P.polyval(tt, pred) - P.polyval(tt, poly))))
        changes.append(residual)
        if residual < tol_m:
            return {"x_poly": pred, "plan": result, "iterations": k + 1, "converged": True, "changes_m": changes}
        if relax == 1.0:  # exactly P(c_k): c_k + (P(c_k) - c_k) can differ from it in the last bit
            poly = pred
        else:
            n = max(len(pred), len(poly))
            c_old = np.pad(np.asarray(poly), (0, n - len(poly)))
            c_new = np.pad(np.asarray(pred), (0, n - len(pred)))
            poly = tuple(float(z) for z in c_old + relax * (c_new - c_old))
        result = plan(poly)
    return {"x_poly": poly, "plan": result, "iterations": max_iter, "converged": False, "changes_m": changes}


def follower_poly_for_plan(predictor: LeaderPredictor, follower_hist: tuple[FloatArray, FloatArray],
                           plan_states: Callable[[FloatArray], FloatArray], tf: float, *, target_y: float,
                           ego_length: float, ego_width: float, follower_length: float,
                           leader_hist: tuple[FloatArray, FloatArray] | None = None, leader_length: float = 4.5,
                           lane_width: float = LANE_WIDTH_M) -> tuple[float, ...]:
    """The closed loop's one call: the follower's cubic given a plan (``docs/prediction-interaction.md``).

    ``follower_hist``/``leader_hist``: ``(t, x)`` observed histories (the leader's is interpolated onto
    the follower's times and dropped unless it covers them); ``plan_states(t)`` -> rows
    ``(x, vx, y, vy, ...)`` of the ego's plan (e.g. ``plan.trajectory.states``).
    """
    th, xh = (np.asarray(z, dtype=float) for z in follower_hist)
    lh = None
    if leader_hist is not None:
        lt, lx = (np.asarray(z, dtype=float) for z in leader_hist)
        if lt.size >= 2 and lt[0] <= th[0] + 1e-9 and lt[-1] >= th[-1] - 1e-9:
            lh = np.interp(th, lt, lx)
    tt = _nodes(tf)
    X = np.asarray(plan_states(tt), dtype=float)
    return predict_with_ego_leader(predictor, th, xh, tt, X[:, 0], tf, plan_y=X[:, 2], target_y=target_y,
                                   ego_length=ego_length, ego_width=ego_width, follower_length=follower_length,
                                   lane_width=lane_width, leader_hist=lh, leader_length=leader_length).x_poly
