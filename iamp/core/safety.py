r"""Where a plan is unsafe (SPEC §9), computed exactly from its piecewise-polynomial trajectory.

For vehicle :math:`i` write the ego's offset from the vehicle's centre

.. math::  d_x(t) = s_x(t) - x_{s,i}(t), \qquad d_y(t) = s_y(t) - y_{s,i},

and the half-sizes of its safety region and of the bodies' overlap box

.. math::

    A_x = L_i/2 + S_{x,i}, \quad A_y = W_i/2 + S_{y,i}, \qquad
    B_x = (L_e + L_i)/2, \quad B_y = (W_e + W_i)/2 ,

with the ego body :math:`L_e \times W_e` (``[ego] length``, ``width``; default 4.8 × 1.8 m).

* **intrusion**: the ego's point inside the safety region by more than
  :math:`\delta` = :data:`INTRUSION_TOL_M` (1 mm), i.e. the *depth*
  :math:`D(t) = \min(A_x - |d_x|,\ A_y - |d_y|) > \delta`;
* **overlap**: the bodies overlap, :math:`|d_x| < B_x` and :math:`|d_y| < B_y`;
* **max_intrusion_m**: :math:`\max(0, \max_t D(t))`;
* **min_clearance_m**: :math:`\min_t \operatorname{dist}(s(t), \text{region})` with
  :math:`\operatorname{dist} = \|(\max(|d_x| - A_x, 0), \max(|d_y| - A_y, 0))\|_2` (0 when the
  point enters the closed region).

Exactness
---------
Every planner's trajectory is piecewise polynomial, and so is :math:`x_{s,i}`.  On each piece
the ego's position is rebuilt as a cubic from the trajectory's own evaluation and checked at
the piece's end (:mod:`iamp.core.trajectory_pieces`); the interval ends are then **roots** of
polynomials, found per piece and polished by Newton steps (:mod:`iamp.core.polyroots`), and
the extremes are attained at a finite set of candidates where the true functions are
evaluated (:mod:`iamp.core.intrusion`, which lists them).  Interval ends are exact to about
1e-9 s.

Touch or unsafe
---------------
The paper's equality *touches* a corner: the exact trajectory grazes the region by about a
millimetre for a few milliseconds around the contact time.  That is reported (interval and
depth) but is not what a driver calls unsafe.  :data:`SAFETY_TOLERANCE_M` (1 cm, the
command line's ``--safety-tolerance``) separates the two: a vehicle whose region the ego enters
by at most the tolerance, with no body overlap, is a **touch**
(:meth:`VehicleSafety.touch_only`); deeper, or any overlap, is **unsafe**
(:meth:`SafetyReport.unsafe_beyond`).  The SPEC §9 keys keep their meaning (``intrusion_free``
is false for a touch); ``safety_tolerance_m`` and ``unsafe`` are added.

A trajectory whose pieces are unknown (neither ``breakpoints()``, ``t_nodes`` nor
``contact_times``) or that fails the end-of-piece check is cut into 1 ms pieces instead
(SPEC §9 allows a grid of at most 1 ms); :attr:`SafetyReport.exact` says which.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.core.intrusion import INTRUSION_TOL_M, Interval, vehicles_sets
from iamp.core.trajectory_pieces import FALLBACK_PIECE_S, breakpoints, taylor_pieces

__all__ = ["DEFAULT_EGO_LENGTH_M", "DEFAULT_EGO_WIDTH_M", "INTRUSION_TOL_M", "SAFETY_TOLERANCE_M", "SafetyReport",
           "VehicleSafety", "safety_report"]

#: Depth [m] up to which entering a safety region (without body overlap) is a *touch*, not
#: unsafe: the command line's ``--safety-tolerance`` default.  1 cm: the paper's equality
#: grazes the corner by ~1 mm (paper-1-poly: 1.1 mm for 16 ms); a real intrusion is metres.
SAFETY_TOLERANCE_M = 0.01

#: Default ego body (SPEC §9), used when the problem does not carry one.
DEFAULT_EGO_LENGTH_M, DEFAULT_EGO_WIDTH_M = 4.8, 1.8


@dataclass(frozen=True)
class VehicleSafety:
    """Safety of the plan with respect to one vehicle (SPEC §9 ``vehicles[i]``)."""

    name: str
    intrusion: tuple[Interval, ...]
    max_intrusion_m: float
    overlap: tuple[Interval, ...]
    min_clearance_m: float

    @property
    def intrusion_free(self) -> bool:
        return not self.intrusion

    @property
    def collision_free(self) -> bool:
        return not self.overlap

    @property
    def safe(self) -> bool:
        return self.intrusion_free and self.collision_free

    def touch_only(self, tolerance_m: float = SAFETY_TOLERANCE_M) -> bool:
        """``True`` when the ego enters the region, by at most ``tolerance_m``, and no body overlaps."""
        return bool(self.intrusion) and self.collision_free and self.max_intrusion_m <= tolerance_m

    def unsafe_beyond(self, tolerance_m: float = SAFETY_TOLERANCE_M) -> bool:
        """``True`` when the bodies overlap or the ego enters the region deeper than ``tolerance_m``."""
        return not self.safe and not self.touch_only(tolerance_m)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name,
                "intrusion": [[a, b] for a, b in self.intrusion],
                "max_intrusion_m": self.max_intrusion_m,
                "overlap": [[a, b] for a, b in self.overlap],
                "min_clearance_m": self.min_clearance_m}

    def describe(self) -> str:
        """One line for the text output."""
        def fmt(iv: tuple[Interval, ...]) -> str:
            return ", ".join(f"[{a:.3f}, {b:.3f}] s" for a, b in iv) or "none"
        return (f"{self.name}: inside its safety region {fmt(self.intrusion)} "
                f"(max depth {self.max_intrusion_m:.3f} m); bodies overlap {fmt(self.overlap)}")


@dataclass(frozen=True)
class SafetyReport:
    """Safety of one plan (SPEC §9): one :class:`VehicleSafety` per vehicle, in file order."""

    vehicles: tuple[VehicleSafety, ...]
    ego_length_m: float
    ego_width_m: float
    exact: bool

    @property
    def collision_free(self) -> bool:
        return all(v.collision_free for v in self.vehicles)

    @property
    def intrusion_free(self) -> bool:
        return all(v.intrusion_free for v in self.vehicles)

    @property
    def safe(self) -> bool:
        return self.collision_free and self.intrusion_free

    def unsafe(self) -> list[VehicleSafety]:
        """The vehicles whose region the ego enters or whose body it overlaps."""
        return [v for v in self.vehicles if not v.safe]

    def unsafe_beyond(self, tolerance_m: float = SAFETY_TOLERANCE_M) -> bool:
        """``True`` when some vehicle is unsafe beyond a touch (:meth:`VehicleSafety.unsafe_beyond`)."""
        return any(v.unsafe_beyond(tolerance_m) for v in self.vehicles)

    def lines(self) -> list[str]:
        """The text output: one line per unsafe vehicle with its intervals (or that it is safe)."""
        bad = self.unsafe()
        if not bad:
            return [f"safety    intrusion-free and collision-free (ego body {self.ego_length_m:g} x "
                    f"{self.ego_width_m:g} m)"]
        return [f"UNSAFE    {v.describe()}" for v in bad]

    def to_json(self) -> dict[str, Any]:
        return {"collision_free": self.collision_free, "intrusion_free": self.intrusion_free,
                "vehicles": [v.to_json() for v in self.vehicles],
                "ego_length_m": self.ego_length_m, "ego_width_m": self.ego_width_m,
                "intrusion_tol_m": INTRUSION_TOL_M,
                "method": "exact" if self.exact else "1ms-pieces",
                "safety_tolerance_m": SAFETY_TOLERANCE_M, "unsafe": self.unsafe_beyond(SAFETY_TOLERANCE_M)}


def safety_report(problem: Any, trajectory: Any, ego_length: float | None = None,
                  ego_width: float | None = None) -> SafetyReport:
    """The SPEC §9 report of ``trajectory`` (a plan's own continuous trajectory) on ``problem``.

    Parameters
    ----------
    problem : Problem
    trajectory : object
        ``states(t)``/``inputs(t)`` and one of ``breakpoints()``, ``t_nodes``,
        ``contact_times`` (the pieces on which the position is a polynomial of degree <= 3).
    ego_length, ego_width : float, optional
        The ego body; default ``problem.ego.ego_length``/``ego_width`` or 4.8 × 1.8 m.
    """
    tf = float(problem.tf)
    ego = problem.ego
    Le = float(ego_length if ego_length is not None else getattr(ego, "ego_length", DEFAULT_EGO_LENGTH_M))
    We = float(ego_width if ego_width is not None else getattr(ego, "ego_width", DEFAULT_EGO_WIDTH_M))
    breaks = breakpoints(trajectory, tf)
    exact = breaks is not None
    C = None
    if breaks is not None:
        C, mismatch = taylor_pieces(trajectory, breaks)
        if mismatch > 1e-8:
            exact = False
    if not exact:
        n = max(1, int(np.ceil(tf / FALLBACK_PIECE_S)))
        breaks = np.linspace(0.0, tf, n + 1)
        C, _ = taylor_pieces(trajectory, breaks)
    assert breaks is not None and C is not None
    sets = vehicles_sets(problem.vehicles, trajectory, breaks, C, Le, We)
    out = [VehicleSafety(str(v.name), *vs) for v, vs in zip(problem.vehicles, sets)]
    return SafetyReport(tuple(out), Le, We, exact)

