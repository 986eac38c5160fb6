r"""Safety and comfort of an executed episode, measured on what happened (not on plans).

Per step ``k`` the log holds the ego's centre ``(x_e, y_e)``, its body ``L_e × W_e`` and every
observed neighbour ``i`` with centre ``(x_i, y_i)``, body ``L_i × W_i``, speed and
acceleration.  With ``Δx = x_i - x_e``, ``Δy = y_i - y_e`` (bodies axis-aligned; headings
during a lane change stay below a few degrees):

* **overlap** (a collision, SPEC §9, §17): the bodies, rectangles at their headings, overlap
  (separating-axis test, :func:`separation`); ``collisions`` = the number of distinct neighbours
  the ego collided with, by SUMO's report or by overlap (the union: one crash reported both
  ways counts once).  The other measures below use the axis-aligned boxes.
* **intrusion**: the ego's point inside ``i``'s safety region by more than 1 mm,
  ``|Δx| < L_i/2 + S_x - 10⁻³`` and ``|Δy| < W_i/2 + S_y - 10⁻³``; ``intrusion_s`` = the
  time with at least one intrusion (steps × period).
* **gap** to a neighbour whose body overlaps the ego's laterally
  (``|Δy| < (W_e + W_i)/2``): ``|Δx| - (L_e + L_i)/2`` bumper to bumper; ``min_gap_m`` its
  minimum over the episode.
* **time to collision** for those neighbours: ``gap / closing speed`` when they close in
  (ego faster than one ahead, or one behind faster than the ego); ``min_ttc_s``.
* **induced braking**: the most negative acceleration of a neighbour within 50 m behind the
  ego with lateral body overlap (SUMO drivers braking for the ego).
* **comfort**: RMS of the ego's acceleration and jerk per axis from second and third
  differences of the executed positions (the same estimate for every planner, including
  the SUMO-driven parts).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class StepLog:
    """Arrays appended every step (lists of per-step arrays for the neighbours)."""

    t: list[float] = field(default_factory=list)
    ego: list[tuple[float, float, float, float, float, float]] = field(default_factory=list)
    mode: list[str] = field(default_factory=list)
    plan_time: list[float] = field(default_factory=list)
    ids: list[tuple[str, ...]] = field(default_factory=list)
    nb: list[np.ndarray] = field(default_factory=list)  # (n, 7 or 8): x, y, v, a, lane, length, width[, heading]
    #: The ego's heading per step [rad] as the simulator has it (empty: from its velocity, :func:`ego_headings`).
    ego_heading: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class StepGeometry:
    """One logged step seen from the ego (module docstring): ``dx, dy`` to every neighbour, their
    bodies ``L, W``, ``lat`` (bodies overlap laterally), ``over`` (bodies overlap: a contact),
    ``gap`` bumper to bumper and ``closing`` speed of the ``lat`` neighbours."""

    k: int
    ids: tuple[str, ...]
    nb: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    L: np.ndarray
    W: np.ndarray
    lat: np.ndarray
    over: np.ndarray
    gap: np.ndarray
    closing: np.ndarray

    def ttc(self) -> float:
        """The smallest ``gap / closing`` over the ``lat`` neighbours that close in faster than
        0.1 m/s (``inf`` if none)."""
        ok = self.closing > 0.1
        if not ok.any():
            return math.inf
        return float(np.min(np.maximum(self.gap[self.lat][ok], 0.0) / self.closing[ok]))


def step_geometry(log: StepLog, ego_size: tuple[float, float]) -> Iterator[StepGeometry]:
    """:class:`StepGeometry` of every step with at least one neighbour, in order (shared by
    :func:`episode_metrics` and :func:`iamp.simulation.monitor.monitor`)."""
    Le, We = ego_size
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    for k, (ids, nb) in enumerate(zip(log.ids, log.nb)):
        if not ids:
            continue
        xe, vxe, ye = E[k, 0], E[k, 1], E[k, 2]
        dx, dy = nb[:, 0] - xe, nb[:, 1] - ye
        L, W = nb[:, 5], nb[:, 6]
        lat = np.abs(dy) < (We + W) / 2
        over = lat & (np.abs(dx) < (Le + L) / 2)
        gap = np.abs(dx) - (Le + L) / 2
        closing = np.where(dx[lat] > 0, vxe - nb[lat, 2], nb[lat, 2] - vxe)
        yield StepGeometry(k, ids, nb, dx, dy, L, W, lat, over, gap, closing)


#: Below this speed [m/s] a velocity gives no heading (the last one is kept), as in the simulator.
HEADING_MIN_SPEED = 0.5


def ego_headings(log: StepLog) -> np.ndarray:
    """The ego's heading per step [rad]: the logged one, else the direction of its velocity
    (kept while it is slower than :data:`HEADING_MIN_SPEED`)."""
    if len(log.ego_heading) == len(log.t):
        return np.asarray(log.ego_heading, dtype=float)
    out = np.zeros(len(log.t))
    psi = 0.0
    for k, (_, vx, _, vy, _, _) in enumerate(log.ego):
        if math.hypot(vx, vy) >= HEADING_MIN_SPEED:
            psi = math.atan2(vy, max(vx, 1e-6))
        out[k] = psi
    return out


def neighbour_headings(nb: np.ndarray) -> np.ndarray:
    """The neighbours' headings of one step [rad] (column 7 when logged, else 0: along the road)."""
    return nb[:, 7].astype(float) if nb.shape[1] > 7 else np.zeros(nb.shape[0])


def _first_axes(psi1: float) -> np.ndarray:
    """The first rectangle's two edge normals (rows ``(cos ψ, sin ψ)``, ``(-sin ψ, cos ψ)``; libm's
    ``cos``/``sin`` of the float ``ψ``)."""
    return np.array([[math.cos(psi1), math.sin(psi1)], [-math.sin(psi1), math.cos(psi1)]])


def _separation_rows(d: np.ndarray, a1: np.ndarray, L1: float, W1: float, L2: np.ndarray, W2: np.ndarray,
                     psi2: np.ndarray) -> np.ndarray:
    """:func:`separation` of row ``i``'s pair: the first rectangle (``L1 × W1``, edge normals ``a1[i]``,
    :func:`_first_axes`) and the other (``L2[i] × W2[i]`` at ``psi2[i]``) ``d[i]`` apart; rows of any
    number of steps at once (each row's numbers as its step alone gives them: elementwise operations,
    one ``(4, 2) @ (2,)`` product per row, a maximum per row)."""
    a2 = np.stack([np.stack([np.cos(psi2), np.sin(psi2)], axis=1),
                   np.stack([-np.sin(psi2), np.cos(psi2)], axis=1)], axis=1)  # (n, 2 axes, xy)
    axes = np.concatenate([a1, a2], axis=1)  # (n, 4, 2)
    r1 = L1 / 2 * np.abs(np.matmul(axes, a1[:, 0, :, None])[..., 0]) \
        + W1 / 2 * np.abs(np.matmul(axes, a1[:, 1, :, None])[..., 0])  # (n, 4)
    r2 = L2[:, None] / 2 * np.abs(np.einsum("nkx,nx->nk", axes, a2[:, 0])) \
        + W2[:, None] / 2 * np.abs(np.einsum("nkx,nx->nk", axes, a2[:, 1]))
    dist = np.abs(np.einsum("nkx,nx->nk", axes, d))
    return np.asarray(np.max(dist - r1 - r2, axis=1), dtype=float)


def separation(c1: np.ndarray, L1: float, W1: float, psi1: float, c2: np.ndarray, L2: np.ndarray,
               W2: np.ndarray, psi2: np.ndarray) -> np.ndarray:
    """Separating-axis test of one rectangle against several: the largest gap between their
    projections over the four edge normals [m].

    Parameters
    ----------
    c1 : numpy.ndarray
        Centre ``(x, y)`` of the first rectangle; ``L1 × W1`` its body, ``psi1`` its heading.
    c2 : numpy.ndarray
        Centres ``(n, 2)`` of the others; ``L2, W2, psi2`` arrays ``(n,)``.

    Returns
    -------
    numpy.ndarray
        ``(n,)``: negative where the bodies overlap (by at least that depth on every axis),
        positive where an axis separates them (a lower bound of their distance).
    """
    c2 = np.asarray(c2, dtype=float).reshape(-1, 2)
    L2, W2, psi2 = (np.asarray(a, dtype=float).reshape(-1) for a in (L2, W2, psi2))
    d = c2 - np.asarray(c1, dtype=float).reshape(1, 2)
    a1 = np.repeat(_first_axes(psi1)[None], c2.shape[0], axis=0)
    return _separation_rows(d, a1, L1, W1, L2, W2, psi2)


def episode_geometry(log: StepLog, ego_size: tuple[float, float]) -> list[tuple[StepGeometry, np.ndarray]]:
    """Every :class:`StepGeometry` of :func:`step_geometry` with the oriented bodies' :func:`separation`
    of that step, computed once for :func:`episode_metrics` and :func:`iamp.simulation.monitor.monitor`
    (which pass it around instead of each recomputing it); the separations of all steps in one
    call (:func:`_separation_rows`: each row's numbers are its step's alone).

    Parameters
    ----------
    log : StepLog
    ego_size : (float, float)
        The ego's length and width [m].

    Returns
    -------
    list of (StepGeometry, numpy.ndarray)
        Per step with a neighbour, in order: its geometry and the separation of each neighbour [m].
    """
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    psi_e = ego_headings(log)
    geo = list(step_geometry(log, ego_size))
    if not geo:
        return []
    counts = [g.nb.shape[0] for g in geo]
    ks = np.repeat([g.k for g in geo], counts)
    c2 = np.concatenate([np.asarray(g.nb[:, :2], dtype=float) for g in geo])
    d = c2 - E[ks][:, [0, 2]]
    a1 = np.repeat(np.stack([_first_axes(float(psi_e[g.k])) for g in geo]), counts, axis=0)
    sep = _separation_rows(d, a1, ego_size[0], ego_size[1],
                           np.concatenate([np.asarray(g.L, dtype=float) for g in geo]),
                           np.concatenate([np.asarray(g.W, dtype=float) for g in geo]),
                           np.concatenate([neighbour_headings(g.nb) for g in geo]))
    return list(zip(geo, np.split(sep, np.cumsum(counts)[:-1])))


def percentile_stats(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"p50": None, "p95": None, "max": None}
    a = np.asarray(values)
    return {"p50": float(np.percentile(a, 50)), "p95": float(np.percentile(a, 95)), "max": float(a.max())}


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2))) if a.size else 0.0


def episode_metrics(log: StepLog, dt: float, ego_size: tuple[float, float], safety: tuple[float, float],
                    sumo_collisions: list[tuple[float, str, str]],
                    geometry: list[tuple[StepGeometry, np.ndarray]] | None = None) -> dict[str, Any]:
    """The safety and comfort numbers of SPEC §11 (plus a few more) from a step log (``geometry``:
    :func:`episode_geometry` of the log when the caller has it)."""
    Sx, Sy = safety
    overlapped: set[str] = set()
    intr_steps = 0
    min_gap, min_ttc, min_follower_a = math.inf, math.inf, math.inf
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    for g, sep in (episode_geometry(log, ego_size) if geometry is None else geometry):
        for j in np.flatnonzero(sep < 0):  # oriented bodies
            overlapped.add(g.ids[j])
        if np.any((np.abs(g.dx) < g.L / 2 + Sx - 1e-3) & (np.abs(g.dy) < g.W / 2 + Sy - 1e-3)):
            intr_steps += 1
        if g.lat.any():
            min_gap = min(min_gap, float(g.gap[g.lat].min()))
            min_ttc = min(min_ttc, g.ttc())
            behind = (g.dx[g.lat] < 0) & (g.dx[g.lat] > -50.0)
            if behind.any():
                min_follower_a = min(min_follower_a, float(g.nb[g.lat, 3][behind].min()))
    sumo_ids = {other for _, other, _ in sumo_collisions}
    x, y = E[:, 0], E[:, 2]
    ax, ay = np.diff(x, 2) / dt**2, np.diff(y, 2) / dt**2
    jx, jy = np.diff(x, 3) / dt**3, np.diff(y, 3) / dt**3

    def finite(v: float) -> float | None:
        return None if not math.isfinite(v) else v

    return {
        "collisions": len(overlapped | sumo_ids),
        "sumo_collisions": len(sumo_ids),
        "overlap_collisions": len(overlapped),
        "intrusion_s": round(intr_steps * dt, 10),
        "min_gap_m": finite(min_gap),
        "min_ttc_s": finite(min_ttc),
        "min_follower_accel": finite(min_follower_a),
        "rms_accel": [_rms(ax), _rms(ay)],
        "rms_jerk": [_rms(jx), _rms(jy)],
    }
