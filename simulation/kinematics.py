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
starts sideways from a standstill counts ``2/l_0``, 10 1/m).  A path passes when every value is
at most ``κ_max`` (to the tolerance :data:`TOL_REL`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["DS_MIN_M", "KAPPA_MAX", "MOVING_MPS", "PLAN_DT_S", "TOL_REL", "plan_turning", "sampled_turning",
           "start_heading", "turning"]

#: The largest curvature a passenger car drives [1/m] (turning radius 5 m, module docstring).
KAPPA_MAX = 0.2
#: Points closer than this to the last kept one are dropped [m].
DS_MIN_M = 0.2
#: A value passes up to ``κ_max (1 + TOL_REL)`` (the chords' round-off).
TOL_REL = 1e-3
#: The plan's sampling step [s] for :func:`plan_turning`.
PLAN_DT_S = 0.01


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + np.pi) % (2 * np.pi) - np.pi


def turning(x: NDArray[np.float64], y: NDArray[np.float64], psi0: float | None = None,
            ds_min: float = DS_MIN_M) -> NDArray[np.float64]:
    """The path's curvatures (module docstring): the start's ``2 sin|ψ_1 - ψ_0| / l_0`` first when
    ``psi0`` is given, then each vertex's :math:`\\kappa_k` [1/m]; empty for a path shorter than
    ``ds_min``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = [0]
    for k in range(1, x.size):
        if math.hypot(x[k] - x[keep[-1]], y[k] - y[keep[-1]]) >= ds_min:
            keep.append(k)
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
    (:func:`start_heading`)."""
    return turning(X[:, 0], X[:, 2], start_heading(float(X[0, 1]), float(X[0, 3]),
                                                   0.0 if heading is None else heading))
