r"""Whether a path can be driven by a car: its turning radius (the closed loop's kinematic test).

The point-mass plans of SPEC §3 move ``s_x`` and ``s_y`` independently; a car cannot.  In the
kinematic single-track model (rolling wheels, no slip: the model of CommonRoad's ``KS``) the car
moves along its heading :math:`\psi`, and its path turns with the curvature

.. math::  \kappa = \frac{d\psi}{ds} = \frac{\tan\delta}{L}, \qquad |\kappa| \le \kappa_{max}
           = \frac{\tan\delta_{max}}{L},

``s`` the arc length, ``δ`` the steering angle, ``L`` the wheelbase.  So a car at a standstill
keeps its heading (it does not move sideways), and its heading turns by at most
``κ_max`` per metre it travels.  :data:`KAPPA_MAX` = 0.2 1/m: a turning radius of 5 m (a passenger
car's turning circle is 10-11 m kerb to kerb; ``L = 2.7`` m at ``δ_max = 28°`` gives 5.1 m).

**The test** (:func:`turning`), on a path given by points (a plan sampled every 10 ms, or the
positions the loop executed every period): the points closer than ``ds_min`` to the last kept one
are dropped (a standstill adds no turn); between the kept points ``p_k`` the chords have headings
``ψ_k`` and lengths ``l_k``.  Chords of length ``l = 2R sin(θ/2)`` on a circle of radius ``R`` turn
by ``θ``, so each vertex's

.. math::  \kappa_k = \frac{2 \sin(|\psi_{k+1} - \psi_k|/2)}{(l_k + l_{k+1})/2}

is ``1/R`` on a circle; the first chord of an arc leaving the heading ``ψ_0`` deviates from it by
``θ/2``, so the start counts ``2 sin|ψ_1 - ψ_0| / l_0`` (the deviation capped at 90°: a path that
starts sideways from a standstill counts ``2/l_0``, 10 1/m).  A plan's path also ends on a heading
when the car still moves there (its last velocity's direction ``ψ_f``): its last point is then kept
(in place of the last kept one when nearer than ``ds_min`` to it) and the end counts
``2 sin|ψ_f - ψ_K| / l_K`` of the last chord, as the start does (a plan that ends rolling along the
road after a lane change at a crawl straightens in its last centimetres: slow-leader light 44
turned by 22° in its last 2 cm, unseen by the chords, and the car drove straight on).  A path
passes when every value is at most ``κ_max`` (to the tolerance :data:`TOL_REL`).

**Where a plan leaves the car standing** (:func:`stop_heading`) its heading is that of its last
chord, and the car drives on from it: a plan may not leave it at more than
:data:`STOP_HEADING_MAX` to the road, the angle from which straightening on the tactical layer's
radius keeps the car within its lane.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["DS_MIN_M", "KAPPA_MAX", "LANE_ROOM_M", "MOVING_MPS", "PLAN_DT_S", "STEER_SHARE", "STOP_HEADING_MAX",
           "TOL_REL", "end_heading", "plan_turning", "sampled_turning", "start_heading", "stop_heading", "turning"]

#: The largest curvature a passenger car drives [1/m] (turning radius 5 m, module docstring).
KAPPA_MAX = 0.2
#: Points closer than this to the last kept one are dropped [m].
DS_MIN_M = 0.2
#: A value passes up to ``κ_max (1 + TOL_REL)`` (the chords' round-off).
TOL_REL = 1e-3
#: The plan's sampling step [s] for :func:`plan_turning`.
PLAN_DT_S = 0.01
#: The room [m] beside a passenger car (1.8 m wide) in the middle of a 3.75 m lane, on either side.
LANE_ROOM_M = (3.75 - 1.8) / 2
#: The share of :data:`KAPPA_MAX` the closed loop's tactical layer turns with (its ``TURN_SHARE``).
STEER_SHARE = 0.9
#: The largest angle to the road [rad] a plan may leave the car standing at (:func:`stop_heading`):
#: a car drives on along its heading, and straightening from ``ψ`` on the tactical layer's radius
#: ``R = 1/(STEER_SHARE κ_max)`` (5.6 m) drifts sideways by ``R (1 - cos ψ)``, which stays within
#: the room the lane leaves beside the car (:data:`LANE_ROOM_M`) up to 34.4°.  (Merge medium 74: a
#: plan stopped the ego at 43° in the middle of its new lane; driving on it crossed the lane's
#: line, toward a car in the next lane.)
STOP_HEADING_MAX = math.acos(1.0 - LANE_ROOM_M * STEER_SHARE * KAPPA_MAX)


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + np.pi) % (2 * np.pi) - np.pi


def turning(x: NDArray[np.float64], y: NDArray[np.float64], psi0: float | None = None,
            ds_min: float = DS_MIN_M, psi_end: float | None = None) -> NDArray[np.float64]:
    """The path's curvatures (module docstring): the start's ``2 sin|ψ_1 - ψ_0| / l_0`` first when
    ``psi0`` is given, then each vertex's :math:`\\kappa_k` [1/m], then the end's
    ``2 sin|ψ_f - ψ_K| / l_K`` when ``psi_end`` is given (the last point kept); empty for a path
    shorter than ``ds_min``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = [0]
    for k in range(1, x.size):
        if math.hypot(x[k] - x[keep[-1]], y[k] - y[keep[-1]]) >= ds_min:
            keep.append(k)
    if psi_end is not None and len(keep) > 1 and keep[-1] != x.size - 1:
        keep[-1] = x.size - 1  # the end's heading is measured on a chord that ends at the end
    px, py = x[keep], y[keep]
    if px.size < 2:
        return np.zeros(0)
    dx, dy = np.diff(px), np.diff(py)
    length = np.hypot(dx, dy)
    psi = np.arctan2(dy, dx)
    turn = np.abs(_wrap(np.diff(psi)))
    out = 2.0 * np.sin(0.5 * turn) / (0.5 * (length[:-1] + length[1:]))
    if psi0 is not None:
        dev = min(abs(float(_wrap(np.array([psi[0] - psi0]))[0])), 0.5 * np.pi)
        out = np.concatenate(([2.0 * math.sin(dev) / length[0]], out))
    if psi_end is not None:
        dev = min(abs(float(_wrap(np.array([psi_end - psi[-1]]))[0])), 0.5 * np.pi)
        out = np.concatenate((out, [2.0 * math.sin(dev) / length[-1]]))
    return out


#: Below this speed [m/s] a car's heading is the one it had when it last moved (:func:`start_heading`).
MOVING_MPS = 0.05


def start_heading(vx: float, vy: float, standing: float = 0.0) -> float:
    """The heading a path starts from: the velocity's direction when the car moves (above
    :data:`MOVING_MPS`), else ``standing`` (the heading it stopped with; 0, along the road, by
    default)."""
    return math.atan2(vy, vx) if math.hypot(vx, vy) > MOVING_MPS else standing


def plan_turning(trajectory: Any, tf: float, heading: float | None = None, dt: float = PLAN_DT_S
                 ) -> NDArray[np.float64]:
    """:func:`turning` of a plan's path on ``[0, tf]`` sampled every ``dt`` (and at both ends),
    :func:`sampled_turning` of those states."""
    n = max(int(math.ceil(tf / dt)), 1) + 1
    return sampled_turning(np.asarray(trajectory.states(np.linspace(0.0, tf, n)), dtype=float), heading)


def sampled_turning(X: NDArray[np.float64], heading: float | None = None) -> NDArray[np.float64]:
    """:func:`turning` of a path given by sampled states ``X`` (rows ``s_x, v_x, s_y, v_y``), from
    the heading of its first velocity, or ``heading`` (the car's) when it stands there
    (:func:`start_heading`), to the heading of its last velocity when the car still moves there
    (above :data:`MOVING_MPS`; a path that ends at a standstill ends on the heading of its last
    chord)."""
    return turning(X[:, 0], X[:, 2], start_heading(float(X[0, 1]), float(X[0, 3]),
                                                   0.0 if heading is None else heading), psi_end=end_heading(X))


def end_heading(X: NDArray[np.float64]) -> float | None:
    """The heading of the last velocity of sampled states ``X`` (rows ``s_x, v_x, s_y, v_y``) where
    the car still moves there (above :data:`MOVING_MPS`), else None (it ends standing)."""
    vxf, vyf = float(X[-1, 1]), float(X[-1, 3])
    return math.atan2(vyf, vxf) if math.hypot(vxf, vyf) > MOVING_MPS else None


def stop_heading(X: NDArray[np.float64], ds_min: float = DS_MIN_M) -> float:
    """The angle to the road [rad] (``|ψ|`` folded into ``[0, π/2]``) of the heading a path given
    by sampled states ``X`` (rows ``s_x, v_x, s_y, v_y``) leaves the car standing at: its last
    chord of at least ``ds_min`` (to its last point); 0 when it ends moving (above
    :data:`MOVING_MPS`: its end heading is tested by :func:`sampled_turning`) or moves less than
    ``ds_min`` (it keeps the heading it had)."""
    if end_heading(X) is not None:
        return 0.0
    x, y = np.asarray(X[:, 0], dtype=float), np.asarray(X[:, 2], dtype=float)
    far = np.flatnonzero(np.hypot(x - x[-1], y - y[-1]) >= ds_min)
    if far.size == 0:
        return 0.0
    k = int(far[-1])
    psi = abs(math.atan2(y[-1] - y[k], x[-1] - x[k]))
    return min(psi, math.pi - psi)
