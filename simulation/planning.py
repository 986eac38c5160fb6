r"""The planners the closed loop can use, behind one call: ``plan(problem) -> Plan``.

* ``pmp`` — :class:`iamp.planners.pmp.planner.PMPPlanner` (the paper's equality constraints, global
  contact times).
* ``qp`` — the discretised QP with the same equality constraints (SPEC §3), solved by the
  direct KKT backend (exact for an equality QP), FOH
  hold, ``N = 20`` intervals over the (shrinking) horizon, contact nodes
  by the full grid sweep.  ``N`` is small because the sweep solves ``(N-1)(N-2)`` QPs for
  two vehicles every period.
* ``qp-avoid`` — the avoidance QP of SPEC §10 (``iamp.planners.avoid.planner.AvoidQPPlanner``,
  Clarabel, FOH, ``N = 20``, grid crossing search).  Clarabel, not OSQP: with the
  planner's OSQP accuracy (``eps_abs = 1e-7``) some closed-loop sweeps took seconds
  (measured: p50 1.9 s per plan over a 15 s episode, every vehicle constrained).
* ``sumo`` — no iamp planner: SUMO's own LC2013 lane change (handled by the controller).
* ``pmp-all``, ``qp-all`` — the same planners with the paper's rule taken literally: both
  corners are imposed whenever the two vehicles are there (the controller's active-set rule,
  which imposes a corner only where the unconstrained plan would enter that vehicle's
  safety region, is off).  An ablation: it shows what the equality does in closed loop.

With no vehicle left to constrain (every constraint already met or no neighbour), every
planner returns the unconstrained optimum, a cubic per axis (:class:`iamp.core.free.FreeTrajectory`,
:func:`iamp.core.free.free_plan`, on a :class:`Problem` with zero vehicles):
with ``ṡ = v, v̇ = u`` and ``J = ½∫u²``, the minimiser with fixed end states is

.. math::  s(t) = s_0 + v_0 t + c_2 t^2 + c_3 t^3,\quad
           c_2 = \frac{3e - g t_f}{t_f^2},\ c_3 = \frac{-2e + g t_f}{t_f^3},\quad
           e = s_f - s_0 - v_0 t_f,\ g = v_f - v_0,

whose cost is :math:`J = \sum_{axes} (6 e^2/t_f^3 - 6 e g/t_f^2 + 2 g^2/t_f)`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from iamp.core.errors import IampError
from iamp.core.free import FreeTrajectory, free_plan
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners import registry

__all__ = ["ALL_VARIANTS", "PLANNERS", "QP_STEPS", "SIM_OPTIONS", "FreeTrajectory", "PlanFn", "free_plan",
           "make_planner"]

#: Registry names whose ``-all`` variant constrains every vehicle (the paper literally, no active set).
ALL_VARIANTS = ("pmp", "qp")
#: The closed loop's planners: every registry entry, SUMO's own lane change, and the ``-all`` variants.
PLANNERS = (*registry.names(), "sumo", *(f"{n}-all" for n in ALL_VARIANTS))
QP_STEPS = 20


PlanFn = Callable[[Problem], Plan]


#: The closed loop's options per registry name (small grids: the sweep runs every period).
SIM_OPTIONS: dict[str, dict[str, Any]] = {
    "pmp": {"diagnostics": False},
    "qp": {"steps": QP_STEPS, "hold": "foh", "solver": "kkt", "contact": "grid"},
    "qp-avoid": {"steps": QP_STEPS, "hold": "foh", "solver": "clarabel"},
}


def make_planner(name: str) -> PlanFn:
    """``plan(problem) -> Plan`` for ``pmp``, ``qp`` or ``qp-avoid`` (``-all``: the same planner),
    from the planner registry (:mod:`iamp.planners.registry`) with :data:`SIM_OPTIONS`."""
    base = name.removesuffix("-all")
    if base not in registry.REGISTRY:
        raise IampError(f"unknown planner {name!r}; choose from {', '.join(PLANNERS)}")
    planner = registry.make_planner(base, **SIM_OPTIONS.get(base, {}))
    return lambda problem: planner.plan(problem)
