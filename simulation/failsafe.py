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

* the ego **behind** a vehicle ``j`` (the ego is the rear): ``ρ = ρ_ego``, ``a_acc`` = the
  plan's own acceleration at ``t`` (positive part), ``b_min = b`` (the fail-safe's braking),
  ``b_max`` = :attr:`SafeParams.b_max_other`;
* the ego **ahead of** ``j`` (``j`` is the rear): ``ρ = ρ_other``, ``a_acc = a_acc_other``,
  ``b_min = b_min_other``, ``b_max = b`` (the ego brakes at most with its fail-safe);
* one ``b`` must satisfy both at the same ``t`` (a fail-safe that brakes hard for the car
  ahead must not be too hard for the car behind).

**Sharing a lane** is decided on bodies, not centre points: the ego's body at its heading
``ψ = atan2(v_y, v_x)`` lies inside the axis-aligned box of half extents
``(L/2 |cos ψ| + W/2 |sin ψ|, L/2 |sin ψ| + W/2 |cos ψ|)``; its lateral extent (widened
toward the centre of the lane the fail-safe returns to) and ``j``'s (widened by ``j``'s
observed lateral speed over ``t``) closer than ``margin_y`` means they share a lane.  A vehicle
sharing the lane while longitudinally overlapping has a negative gap: no ``b`` is safe.  So
bodies keep ``margin_y`` sideways unless they keep the RSS distance lengthwise.

**The lane's end** of a merge is a standing obstacle (``v_f = 0``) for as long as the ego's body
is in the ending lane: every state of the plan there must be able to stop before it.

Parameters (:class:`SafeParams`): SUMO's drivers in this loop brake in normal driving at most
their ``decel`` (4.0-5.0 m/s² for cars, 3.5 for trucks; :mod:`iamp.simulation.traffic`), so the
others' admissible braking as a front vehicle is ``b_max_other = 5``; as a rear vehicle they
are assumed to brake at least ``b_min_other = 4`` after ``ρ_other = 0.5`` s with
``a_acc_other = 1`` m/s²; the ego's response time is two control periods (``ρ_ego = 0.2`` s).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.simulation.rss import body_extents, rss_distance

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

    rho_ego: float = 0.2
    rho_other: float = 0.5
    a_acc_other: float = 1.0
    b_min_other: float = 4.0
    b_max_other: float = 5.0
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
        v = P.polyval(t, P.polyder(self.poly)) if len(self.poly) > 1 else np.zeros_like(t)
        return np.asarray(x, dtype=float), np.maximum(np.asarray(v, dtype=float), 0.0)


def body_half_extents(vx: Any, vy: Any, length: float, width: float) -> tuple[np.ndarray, np.ndarray]:
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
    ve = X[:, 1:2]
    a_e = np.maximum(ax, 0.0)[:, None]
    items: list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]] = []
    for o in others:
        xo, vo = o.xv(t)
        drift = np.clip(o.vy * t, -params.max_drift, params.max_drift)
        o_lo = o.y - o.width / 2 + np.minimum(drift, 0.0)
        o_hi = o.y + o.width / 2 + np.maximum(drift, 0.0)
        items.append((o.name, xo, vo, o_lo, o_hi, np.full(t.size, o.length), params.margin_y))
    if stop_x is not None and stop_band is not None:  # the road's end: no lateral margin beyond its band
        items.append(("lane-end", np.full(t.size, stop_x), np.zeros(t.size), np.full(t.size, stop_band[0]),
                      np.full(t.size, stop_band[1]), np.zeros(t.size), 0.0))
    for name, xo, vo, o_lo, o_hi, lo_len, m_y in items:
        share = (lo < o_hi + m_y) & (o_lo - m_y < hi)
        if not share.any():
            continue
        dx = xo - X[:, 0]
        gap = (np.abs(dx) - hx - lo_len / 2)[:, None]
        ahead = (dx > 0)[:, None]
        d_front = rss_distance(ve, vo[:, None], params.rho_ego, a_e, B, params.b_max_other)
        d_rear = rss_distance(vo[:, None], ve, params.rho_other, params.a_acc_other, params.b_min_other, B)
        need = np.where(ahead, d_front, d_rear) + params.margin_x
        good = (gap >= need) | ~share[:, None]
        newly = ok.any(axis=1) & ~(ok & good).any(axis=1)
        for k in np.flatnonzero(newly):
            culprit[k] = name
        ok &= good
    return ok, culprit


def verify_states(t: np.ndarray, X: np.ndarray, ax: np.ndarray, others: Sequence[Obstacle],
                  size: tuple[float, float], params: SafeParams, lane_centre_at: Callable[[float], float],
                  stop_x: float | None = None, stop_band: tuple[float, float] | None = None,
                  period: float = 0.1) -> Verification:
    """Verify sampled ego states (:func:`feasible_brakes` at every sample; module docstring).

    Returns
    -------
    Verification
        ``ok`` iff some fail-safe deceleration is safe at every sample.
    """
    yfs = np.array([lane_centre_at(float(v)) for v in X[:, 2]])
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
                      period: float = 0.1) -> Verification:
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
    return verify_states(tp - t_from, X, U[:, 0], others, size, params, lane_centre_at, stop_x, stop_band, period)
