r"""Safe by construction: the ego's body, RSS distances and a verified fail-safe (SPEC §17).

A plan is executed only if, at every sample ``t`` of the plan (every ``dt``, both ends
included), **a fail-safe manoeuvre exists from the plan's state at** ``t`` — the ego brakes
at a constant deceleration ``b`` from :attr:`SafeParams.brakes` (at most the passenger car's
6 m/s²) in its lane, with the vehicle ahead in view — that keeps the RSS safe longitudinal
distance to **every vehicle sharing the ego's lane** at ``t`` (Pek & Althoff's online
verification: intended plan and fail-safe verified together; the fail-safe from the *end*
state is the check at ``t = t_f``, so the end state is safe beyond the horizon too).

The RSS distance (Shalev-Shwartz et al. 2017; SPEC §17), rear vehicle at ``v_r`` with response
time ``ρ``, accelerating at most ``a_acc`` during it and then braking at least ``b_min``, front
vehicle at ``v_f`` braking at most ``b_max``:

.. math::  d = \Big[v_r ρ + \tfrac12 a_{acc} ρ^2 + \frac{(v_r + ρ a_{acc})^2}{2 b_{min}}
               - \frac{v_f^2}{2 b_{max}}\Big]_+ .

* **one parameter set** (SPEC §17): the judge's :class:`~iamp.simulation.rss.RssParameters`
  (:attr:`SafeParams.rss`, by default :data:`iamp.simulation.rss.DEFAULT`) for every vehicle
  and every role — the ego behind ``j`` needs ``d(v_e, v_j)``, ``j`` behind the ego needs
  ``d(v_j, v_e)``, each with the judge's ``ρ``, ``a_acc``, ``b_min``, ``b_max`` — so a verified
  state is never RSS-dangerous for the monitor (:mod:`iamp.simulation.monitor`) and the
  fail-safe is RSS's proper response (brake with at least ``b_min`` after ``ρ`` as the rear,
  at most ``b_max`` as the front; the car's 6 m/s² ≤ ``b_max``);
* **who must keep the distance** (RSS's blame): a vehicle *behind* the ego that already shared
  its lane at the first sample while the ego does not move toward it sideways is the rear of
  an existing pair — keeping the distance is its duty, the ego's is not to brake beyond
  ``b_max`` — so no distance is required from the ego there; so is a vehicle behind that shares
  no lane with the ego at the first sample and comes into its lane by its own lateral motion
  (a cut-in behind: it moves toward the ego at more than 0.1 m/s, the ego not toward it); a
  vehicle *ahead* already closer than ``d`` at the first sample (it cut in, or braked) must not
  come closer than it is now.

**Sharing a lane** is decided on bodies, not centre points: the ego's body at its heading
``ψ = atan2(v_y, v_x)`` lies inside the axis-aligned box of half extents
``(L/2 |cos ψ| + W/2 |sin ψ|, L/2 |sin ψ| + W/2 |cos ψ|)``; its lateral extent (widened
toward the centre of the lane the fail-safe returns to) and ``j``'s (widened by ``j``'s
observed lateral speed over ``t``) closer than ``margin_y`` means they share a lane.  A vehicle
sharing the lane while longitudinally overlapping has a negative gap: no ``b`` is safe.  So
bodies keep ``margin_y`` sideways unless they keep the RSS distance lengthwise.

**The lane's end** of a merge is a standing obstacle (``v_f = 0``) for as long as the ego's body
is in the ending lane: every state of the plan there must be able to stop before it.

Parameters (:class:`SafeParams`): the RSS numbers are the judge's (above); the lane's end, a
physical obstacle rather than a road user, is checked with the ego's own response (two
control periods, ``rho_end = 0.2`` s), the plan's own acceleration and the fail-safe
decelerations :attr:`SafeParams.brakes`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.simulation.decision import poly_derivative
from iamp.simulation.rss import DEFAULT, RssParameters, body_extents, rss_distance, safe_lateral_distance

__all__ = [
    "Obstacle",
    "SafeParams",
    "Verification",
    "body_half_extents",
    "feasible_brakes",
    "verify_states",
    "verify_trajectory",
]


@dataclass(frozen=True)
class SafeParams:
    """Parameters of the verification (module docstring)."""

    #: The RSS parameters of every vehicle: the judge's (SPEC §17; one set for the loop and the monitor).
    rss: RssParameters = DEFAULT
    #: The ego's response to the lane's end (a standing obstacle, not a road user) [s].
    rho_end: float = 0.2
    #: The fail-safe decelerations tried [m/s²] (the passenger car brakes at most 6).
    brakes: tuple[float, ...] = (1.5, 2.5, 3.5, 4.5, 5.0, 6.0)
    #: Extra bumper-to-bumper distance on top of the RSS distance [m].
    margin_x: float = 0.5
    #: Lateral clearance between bodies below which they share a lane [m].
    margin_y: float = 0.4
    #: Sample step of a plan [s].
    dt: float = 0.05
    #: An observed lateral speed sweeps the other's body sideways by at most this [m] (a lane).
    max_drift: float = 3.75


@dataclass(frozen=True)
class Obstacle:
    """Another road user for the check: ``x(t)``/``v(t)`` from now, lateral centre, speed, body."""

    name: str
    poly: tuple[float, ...]
    y: float
    length: float
    width: float
    vy: float = 0.0

    def xv(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        P = np.polynomial.polynomial
        x = P.polyval(t, self.poly)
        v = P.polyval(t, poly_derivative(self.poly)) if len(self.poly) > 1 else np.zeros_like(t)
        return np.asarray(x, dtype=float), np.maximum(np.asarray(v, dtype=float), 0.0)


def body_half_extents(vx: Any, vy: Any, length: Any, width: Any) -> tuple[np.ndarray, np.ndarray]:
    """Half extents ``(h_x, h_y)`` of the axis-aligned box containing a ``length × width`` body at
    the heading of its velocity (``ψ = 0`` when it stands).

    Returns
    -------
    tuple of numpy.ndarray
        ``(L/2|cos ψ| + W/2|sin ψ|, L/2|sin ψ| + W/2|cos ψ|)``.
    """
    vx_a, vy_a = np.asarray(vx, dtype=float), np.asarray(vy, dtype=float)
    psi = np.where(np.hypot(vx_a, vy_a) > 0.5, np.arctan2(vy_a, np.maximum(vx_a, 1e-6)), 0.0)
    return body_extents(length, width, psi)


@dataclass
class Verification:
    """The verdict on a sequence of ego states: ``ok``, the first unsafe sample, the fail-safe."""

    ok: bool
    reason: str
    t_bad: float | None
    brake_first: float | None  # the smallest safe fail-safe deceleration at the first sample
    brake_next: float | None   # ... at the sample one control period later (the state executed next)



def _positions_speeds(polys: Sequence[tuple[float, ...]], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(x, max(v, 0))`` of each polynomial (a row each) at ``t``: :meth:`Obstacle.xv` for many at once,
    by Horner's rule in ``numpy.polynomial.polynomial.polyval``'s order (the same floats; shorter
    polynomials padded with leading zeros, which leave every step's value unchanged)."""
    n = max(len(p) for p in polys)
    C = np.array([tuple(p) + (0.0,) * (n - len(p)) for p in polys], dtype=float)
    Dv = np.array([poly_derivative(p) + (0.0,) * (n - len(p)) for p in polys], dtype=float)[:, :max(n - 1, 1)]

    def horner(c: np.ndarray) -> np.ndarray:
        acc = c[:, -1:] + t * 0
        for i in range(2, c.shape[1] + 1):
            acc = c[:, -i:c.shape[1] - i + 1] + acc * t
        return np.asarray(acc, dtype=float)

    return horner(C), np.maximum(horner(Dv), 0.0)


def feasible_brakes(t: np.ndarray, X: np.ndarray, ax: np.ndarray, others: Sequence[Obstacle],
                    size: tuple[float, float], params: SafeParams, y_failsafe: np.ndarray,
                    stop_x: float | None = None, stop_band: tuple[float, float] | None = None,
                    ) -> tuple[np.ndarray, list[str]]:
    """Which fail-safe decelerations keep every RSS distance at every sample.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times from now [s], shape ``(n,)``.
    X : numpy.ndarray
        The ego's centre states ``(x, v_x, y, v_y)`` at ``t``, shape ``(n, 4)``.
    ax : numpy.ndarray
        Its longitudinal acceleration at ``t``.
    others : sequence of Obstacle
    size : tuple of float
        The ego's ``(length, width)``.
    params : SafeParams
    y_failsafe : numpy.ndarray
        The centre of the lane the fail-safe keeps, per sample.
    stop_x, stop_band : float, tuple of float, optional
        A standing obstacle at ``x = stop_x`` across the lateral band ``stop_band`` (a lane's end).

    Returns
    -------
    tuple
        ``ok`` of shape ``(n, len(params.brakes))`` and, per sample, the name of a vehicle that
        excludes every deceleration (``""`` where some is safe).
    """
    L, W = size
    hx, hy = body_half_extents(X[:, 1], X[:, 3], L, W)
    y = X[:, 2]
    lo = np.minimum(y - hy, y_failsafe - W / 2)
    hi = np.maximum(y + hy, y_failsafe + W / 2)
    B = np.asarray(params.brakes, dtype=float)[None, :]
    ok = np.ones((t.size, B.size), dtype=bool)
    culprit = [""] * t.size
    ve, vye = X[:, 1], X[:, 3]
    a_e = np.maximum(ax, 0.0)[:, None]
    r = params.rss
    if others:  # every other road user at once: rows are vehicles, columns samples (elementwise as one by one)
        oy = np.array([o.y for o in others])[:, None]
        ovy = np.array([o.vy for o in others])[:, None]
        half_w = np.array([o.width / 2 for o in others])[:, None]
        drift = np.clip(ovy * t, -params.max_drift, params.max_drift)
        o_lo = (oy - half_w) + np.minimum(drift, 0.0)
        o_hi = (oy + half_w) + np.maximum(drift, 0.0)
        above = oy >= y  # the other is to the left (+y) of the ego
        lat_gap = np.where(above, o_lo - hi, lo - o_hi)
        u_ego = np.where(above, vye, -vye)      # the ego's lateral speed toward the other
        u_oth = np.where(above, -ovy, ovy)      # the other's toward the ego
        d_lat = safe_lateral_distance(u_ego, u_oth, r)
        share = lat_gap < np.maximum(d_lat, params.margin_y)
        rows = np.flatnonzero(share.any(axis=1))  # only vehicles that share the ego's lane at some sample
        if rows.size:
            share, u_ego, u_oth = share[rows], u_ego[rows], u_oth[rows]
            sel = [others[int(i)] for i in rows]
            xo, vo = _positions_speeds([o.poly for o in sel], t)
            dx = xo - X[:, 0]
            gap = np.abs(dx) - hx - np.array([o.length / 2 for o in sel])[:, None]
            ahead = dx > 0
            d_front = rss_distance(ve, vo, r.response_time_s, r.accel_max, r.brake_min, r.brake_max)
            d_rear = rss_distance(vo, ve, r.response_time_s, r.accel_max, r.brake_min, r.brake_max)
            # RSS's blame: the rear of a pair that already shared the lane keeps the distance itself
            # (unless the ego moves toward it sideways), and so does a vehicle behind that comes into
            # the ego's lane by its own lateral motion (a cut-in behind: it shares no lane at the first
            # sample and moves toward the ego, which does not move toward it); a leader already too
            # close must not come closer
            waive_rear = (share[:, :1] | (u_oth > 0.1)) & (u_ego <= 0.1)
            front_now = np.where(share[:, 0] & (dx[:, 0] > 0), gap[:, 0] - params.margin_x, np.inf)
            need = np.where(ahead, np.minimum(d_front, np.maximum(front_now, 0.0)[:, None]),
                            np.where(waive_rear, 0.0, d_rear))
            bad = ~((gap >= need + params.margin_x) | ~share)
            first = np.argmax(bad, axis=0)  # the first vehicle (in the given order) that excludes every b
            for k in np.flatnonzero(bad.any(axis=0)):
                culprit[k] = sel[first[k]].name
            ok &= ~bad.any(axis=0)[:, None]
    if stop_x is not None and stop_band is not None:  # the road's end: the ego's own response and braking
        share = (lo < stop_band[1]) & (stop_band[0] < hi)
        if share.any():
            gap = (stop_x - X[:, 0] - hx)[:, None]
            need = rss_distance(ve[:, None], 0.0, params.rho_end, a_e, B, 1.0) + params.margin_x
            good = (gap >= need) | ~share[:, None]
            newly = ok.any(axis=1) & ~(ok & good).any(axis=1)
            for k in np.flatnonzero(newly):
                culprit[k] = "lane-end"
            ok &= good
    return ok, culprit


def verify_states(t: np.ndarray, X: np.ndarray, ax: np.ndarray, others: Sequence[Obstacle],
                  size: tuple[float, float], params: SafeParams, lane_centre_at: Callable[[float], float],
                  stop_x: float | None = None, stop_band: tuple[float, float] | None = None,
                  period: float = 0.1, lane_centres: Callable[[np.ndarray], np.ndarray] | None = None
                  ) -> Verification:
    """Verify sampled ego states (:func:`feasible_brakes` at every sample; module docstring).

    ``lane_centres``, when given, is ``lane_centre_at`` of a whole array at once (the same floats;
    e.g. :meth:`iamp.simulation.network.Highway.lane_centres_of`).

    Returns
    -------
    Verification
        ``ok`` iff some fail-safe deceleration is safe at every sample.
    """
    yfs = (np.array([lane_centre_at(float(v)) for v in X[:, 2]]) if lane_centres is None
           else np.asarray(lane_centres(X[:, 2]), dtype=float))
    ok, culprit = feasible_brakes(t, X, ax, others, size, params, yfs, stop_x, stop_band)
    any_ok = ok.any(axis=1)
    B = np.asarray(params.brakes)

    def first_brake(k: int) -> float | None:
        return float(B[ok[k]][0]) if ok[k].any() else None

    k_next = int(np.searchsorted(t, t[0] + period - 1e-9)) if t.size else 0
    k_next = min(k_next, t.size - 1)
    if any_ok.all():
        return Verification(True, "safe", None, first_brake(0), first_brake(k_next))
    k = int(np.flatnonzero(~any_ok)[0])
    return Verification(False, "rss:" + (culprit[k] or "?"), float(t[k]), first_brake(0),
                        first_brake(k_next) if k_next < t.size else None)


def verify_trajectory(trajectory: Any, t_from: float, t_to: float, others: Sequence[Obstacle],
                      size: tuple[float, float], params: SafeParams, lane_centre_at: Callable[[float], float],
                      stop_x: float | None = None, stop_band: tuple[float, float] | None = None,
                      period: float = 0.1, lane_centres: Callable[[np.ndarray], np.ndarray] | None = None
                      ) -> Verification:
    """:func:`verify_states` on a plan's trajectory over ``[t_from, t_to]`` (plan time); the
    others' predictions start at ``t_from`` (they were made now).

    Returns
    -------
    Verification
    """
    n = max(int(np.ceil((t_to - t_from) / params.dt)), 1) + 1
    tp = np.linspace(t_from, t_to, n)
    X = np.asarray(trajectory.states(tp), dtype=float)
    U = np.asarray(trajectory.inputs(tp), dtype=float)
    return verify_states(tp - t_from, X, U[:, 0], others, size, params, lane_centre_at, stop_x, stop_band, period,
                         lane_centres)
