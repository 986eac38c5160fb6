r"""The planners the closed loop can use, behind one call: ``plan(problem) -> Plan``.

* ``pmp`` — :class:`iamp.planners.pmp.planner.PMPPlanner` (the paper's equality constraints, global
  contact times).
* ``qp`` — the discretised QP with the same equality constraints (SPEC §3), solved by the
  direct KKT backend (exact for an equality QP; OSQP where that backend is absent), FOH
  hold, ``N = 20`` intervals over the (shrinking) horizon, contact nodes
  by the full grid sweep.  ``N`` is small because the sweep solves ``(N-1)(N-2)`` QPs for
  two vehicles every period.
* ``qp-avoid`` — the avoidance QP of SPEC §10 (``iamp.planners.avoid.planner.AvoidQPPlanner``,
  Clarabel, FOH, ``N = 20``, grid crossing search), if that module is installed; otherwise
  :func:`make_planner` raises :class:`PlannerUnavailable`.  Clarabel, not OSQP: with the
  planner's OSQP accuracy (``eps_abs = 1e-7``) some closed-loop sweeps took seconds
  (measured: p50 1.9 s per plan over a 15 s episode, every vehicle constrained).
* ``sumo`` — no iamp planner: SUMO's own LC2013 lane change (handled by the controller).
* ``pmp-all``, ``qp-all`` — the same planners with the paper's rule taken literally: both
  corners are imposed whenever the two vehicles are there (the controller's active-set rule,
  which imposes a corner only where the unconstrained plan would enter that vehicle's
  safety region, is off).  An ablation: it shows what the equality does in closed loop.

With no vehicle left to constrain (every constraint already met or no neighbour), every
planner returns the unconstrained optimum, a cubic per axis (:class:`FreeTrajectory`):
with ``ṡ = v, v̇ = u`` and ``J = ½∫u²``, the minimiser with fixed end states is

.. math::  s(t) = s_0 + v_0 t + c_2 t^2 + c_3 t^3,\quad
           c_2 = \frac{3e - g t_f}{t_f^2},\ c_3 = \frac{-2e + g t_f}{t_f^3},\quad
           e = s_f - s_0 - v_0 t_f,\ g = v_f - v_0,

whose cost is :math:`J = \sum_{axes} (6 e^2/t_f^3 - 6 e g/t_f^2 + 2 g^2/t_f)`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.core.errors import IampError
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem
from iamp.core.status import OPTIMAL

PLANNERS = ("pmp", "qp", "qp-avoid", "sumo", "pmp-all", "qp-all")
QP_STEPS = 20


class PlannerUnavailable(IampError):
    """The planner's module is not installed in this checkout."""


def _cubic(s0: float, v0: float, sf: float, vf: float, tf: float) -> np.ndarray:
    e, g = sf - s0 - v0 * tf, vf - v0
    return np.array([s0, v0, (3 * e - g * tf) / tf**2, (-2 * e + g * tf) / tf**3])


@dataclass(frozen=True)
class FreeTrajectory:
    """The unconstrained minimum-energy trajectory (a cubic per axis), see the module doc."""

    cx: np.ndarray
    cy: np.ndarray

    @classmethod
    def of(cls, ego: EgoBoundary) -> FreeTrajectory:
        return cls(_cubic(ego.x0, ego.vx0, ego.xf, ego.vxf, ego.tf), _cubic(ego.y0, ego.vy0, ego.yf, ego.vyf, ego.tf))

    def states(self, t: Any) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        P = np.polynomial.polynomial
        dx, dy = P.polyder(self.cx), P.polyder(self.cy)
        return np.stack([P.polyval(t, self.cx), P.polyval(t, dx), P.polyval(t, self.cy), P.polyval(t, dy)], axis=1)

    def inputs(self, t: Any) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        P = np.polynomial.polynomial
        return np.stack([P.polyval(t, P.polyder(self.cx, 2)), P.polyval(t, P.polyder(self.cy, 2))], axis=1)

    def cost(self, tf: float) -> float:
        """``½∫(u_x² + u_y²)dt`` (``u`` is linear, so Simpson's rule is exact)."""
        U = self.inputs(np.array([0.0, tf / 2, tf]))
        sq = np.sum(U**2, axis=1)
        return float(0.5 * tf / 6 * (sq[0] + 4 * sq[1] + sq[2]))


@dataclass(frozen=True)
class FreeProblem:
    """Stand-in for a :class:`Problem` without vehicles (``Problem`` needs at least one)."""

    ego: EgoBoundary
    vehicles: tuple[()] = ()
    name: str = "free"

    @property
    def tf(self) -> float:
        return self.ego.tf

    @property
    def m(self) -> int:
        return 0


def free_plan(ego: EgoBoundary, planner: str) -> Plan:
    """The unconstrained optimum as a :class:`Plan` (status ``optimal``, exact)."""
    start = time.perf_counter()
    traj = FreeTrajectory.of(ego)
    cost = traj.cost(ego.tf)
    return Plan(problem=FreeProblem(ego), planner=planner, status=OPTIMAL, cost=cost,  # type: ignore[arg-type]
                contact_times=np.zeros(0), jumps=np.zeros((0, 2)), trajectory=traj,
                solve_time_s=time.perf_counter() - start, info={"free": True})


PlanFn = Callable[[Problem], Plan]


def make_planner(name: str) -> PlanFn:
    """``plan(problem) -> Plan`` for ``pmp``, ``qp`` or ``qp-avoid`` (``-all``: the same planner)."""
    name = name.removesuffix("-all")
    if name == "pmp":
        from iamp.planners.pmp.planner import PMPPlanner

        pmp = PMPPlanner()
        return lambda problem: pmp.plan(problem, diagnostics=False)
    if name == "qp":
        from iamp.planners.qp.planner import QPPlanner

        try:  # the exact KKT solve of the equality QP where the backend registry has it
            qp: Any = QPPlanner(steps=QP_STEPS, hold="foh", solver="kkt", contact="grid")
        except ValueError:  # pragma: no cover - older planner without the kkt backend
            qp = QPPlanner(steps=QP_STEPS, hold="foh", solver="osqp", contact="grid")
        return lambda problem: qp.plan(problem)
    if name == "qp-avoid":
        try:
            from iamp.planners.avoid.planner import AvoidQPPlanner  # type: ignore[import-not-found,unused-ignore]
        except ImportError as exc:
            raise PlannerUnavailable(f"planner 'qp-avoid' is unavailable: iamp.planners.avoid.planner is not installed "
                                     f"({exc})") from None
        avoid: Any = AvoidQPPlanner(steps=QP_STEPS, hold="foh", solver="clarabel")
        return lambda problem: avoid.plan(problem)
    raise IampError(f"unknown planner {name!r}; choose from {', '.join(PLANNERS)}")
