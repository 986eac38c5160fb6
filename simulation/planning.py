r"""The planners the closed loop can use, behind one call: ``plan(problem) -> Plan``.

Every iamp planner receives the same problem from the decision layer
(:mod:`iamp.simulation.decision`): the target-lane follower, the target-lane leader and the
current-lane leader, each with its paper corner.

* ``pmp`` — the registry's ``pmp`` (:class:`iamp.planners.pmp.planner.PMPPlanner`), the paper's
  equality on **every** vehicle of the problem (the decision layer poses the equality planners only
  the corners in the way, :func:`iamp.simulation.decision.corners_in_the_way`; global contact times;
  the branch-and-bound box budget is :data:`PMP_BOXES`); with the limits, the saturated PMP of SPEC §14 (input box
  imposed, the other bounds checked on the plan: ``limits_violated`` if one fails).
* ``qp`` — the registry's ``qp``: the discretised QP with the same equality constraints
  (SPEC §3), FOH, ``N = QP_STEPS`` intervals over the (shrinking) horizon, contact nodes by the
  grid sweep; the limits' rows at every node need an inequality backend: :data:`QP_SOLVER`.
* ``pmp-active`` — the registry's ``pmp-active``, the PMP with SPEC §14's active set
  (:class:`iamp.planners.active_set.ActiveSetPlanner`, the one implementation): start from the
  unconstrained (bounded) plan, impose the corner of the vehicle whose safety region it enters
  most deeply, drop a vehicle whose jump has the dragging sign, repeat.
* ``qp-avoid`` — the registry's ``qp-avoid``: the avoidance QP of SPEC §10/§14, Clarabel, FOH,
  ``N = QP_STEPS``, every vehicle as an inequality.
* ``free`` — no constraint at all (the ablation): the minimum-energy cubic below.
* ``mobil`` and ``sumo`` — no iamp planner (:mod:`iamp.simulation.mobil`, SUMO's LC2013).

Every problem carries :data:`~iamp.core.physical.PASSENGER_CAR` as ``Problem.limits``
(:mod:`iamp.simulation.decision`), and every registry planner plans **with** them (issue 32 item 5: no
planner is handed the problem without its limits; the decision layer's own check of the plan's
peaks stays, as an independent test).  ``free`` and a problem with no vehicle left are the
unconstrained cubic below: the tactical layer plans only ends whose cubic keeps the ``a_x`` bounds
(:func:`iamp.simulation.tactical.within_reach`), the decision layer rejects one beyond the others.

With no vehicle left to constrain (every constraint met or no neighbour), every iamp planner
returns the unconstrained optimum, a cubic per axis (:class:`iamp.core.free.FreeTrajectory`): with
``ṡ = v, v̇ = u`` and ``J = ½∫u²``, the minimiser with fixed end states is

.. math::  s(t) = s_0 + v_0 t + c_2 t^2 + c_3 t^3,\quad
           c_2 = \frac{3e - g t_f}{t_f^2},\ c_3 = \frac{-2e + g t_f}{t_f^3},\quad
           e = s_f - s_0 - v_0 t_f,\ g = v_f - v_0,

whose cost is :math:`J = \sum_{axes} (6 e^2/t_f^3 - 6 e g/t_f^2 + 2 g^2/t_f)`.  Such a call
is not a planner call: it is not timed into ``plan_time_s``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from iamp.core.errors import IampError
from iamp.core.free import FreeTrajectory, free_plan
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners import registry

__all__ = ["COMPILED_AXIS", "EQUALITY_PLANNERS", "IAMP_PLANNERS", "PLANNERS", "PMP_BOXES", "QP_SOLVER", "QP_STEPS",
           "SIM_OPTIONS", "FreeTrajectory", "PlanFn", "free_plan", "make_planner"]

PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
#: Planners that call an iamp planner through the decision layer.
IAMP_PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free")
#: Planners that impose every vehicle of their problem as the paper's corner equality (the registry's
#: ``constraint == "equality"``): the decision layer poses them only the corners in the way
#: (:func:`iamp.simulation.decision.corners_in_the_way`).
EQUALITY_PLANNERS = tuple(p for p in IAMP_PLANNERS if p in registry.REGISTRY
                          and registry.REGISTRY[p].constraint == "equality")
QP_STEPS = 12
#: The equality QP's backend in the loop: the limits' rows are inequalities, which the direct
#: ``kkt`` backend cannot take (:func:`iamp.planners.qp.options.check_limits_solver`).
QP_SOLVER = "clarabel"
#: The PMP's branch-and-bound box budget in the loop (the library's 200 000 took 1-8 s on
#: three-vehicle lane changes; 5000 gave the same cost to 1e-12 on the 4 cases measured; 2000
#: here for time).  Status ``local`` — residuals checked, global optimality not certified —
#: which the decision layer accepts like ``optimal``.
PMP_BOXES = 2000
#: The avoidance QP's budget of QP solves in its crossing-time search (deterministic, unlike a
#: time limit; beyond it the plan is ``local``, which the decision layer judges like any other).
AVOID_SOLVES = 100
#: The closed loop's options per registry name (small grids: the planners run every period).
SIM_OPTIONS: dict[str, dict[str, Any]] = {
    "pmp": {"diagnostics": False, "max_boxes": PMP_BOXES},
    "pmp-active": {"diagnostics": False, "max_boxes": PMP_BOXES},
    "qp": {"steps": QP_STEPS, "hold": "foh", "solver": QP_SOLVER, "contact": "grid"},
    "qp-avoid": {"steps": QP_STEPS, "hold": "foh", "solver": "clarabel", "safety": "continuous",
                 "max_solves": AVOID_SOLVES},
}

PlanFn = Callable[[Problem], Plan]


def _failed(problem: Problem, planner: str, exc: BaseException) -> Plan:
    return Plan(problem=problem, planner=planner, status="solver_error", cost=None,
                contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                trajectory=None, info={"error": repr(exc)})


def _safe(fn: PlanFn, name: str) -> PlanFn:
    """A planner crash is a failed plan, not a crashed episode."""
    def call(problem: Problem) -> Plan:
        try:
            return fn(problem)
        except Exception as exc:  # any solver failure
            return _failed(problem, name, exc)
    return call


#: Planners whose plans with limits run the bounded PMP's axis solve often enough that the loop
#: compiles that solve once per process (:func:`iamp.planners.pmp.compiled.load_axis`; the same
#: source as the Python path, equal to it bit for bit — tests/test_pmp_jit.py; without numba the
#: Python path runs: the same plans).  Only the active set: its infeasibility certificates take
#: thousands of axis solves (merge, dense, seed 1: one of 5,490 solves, 0.6 s CPU compiled).  ``pmp``
#: and ``qp``, posed only the corners in the way, plan one vehicle a few times per episode (16 calls
#: there: 0.23 s compiled, about as much in Python), while loading the compiled solve costs about
#: 1 s CPU per process with numba's cache warm and 14-25 s when the cache is stale.
COMPILED_AXIS = ("pmp-active",)


def _registered(name: str) -> PlanFn:
    """The registry's planner ``name`` with the loop's options; it plans the problem as given,
    ``Problem.limits`` included."""
    if name in COMPILED_AXIS:
        from iamp.planners.pmp import compiled

        compiled.load_axis()
    known = set(registry.REGISTRY[name].option_names())
    opts = {k: v for k, v in SIM_OPTIONS.get(name, {}).items() if k in known}
    return _safe(registry.make_planner(name, **opts).plan, name)


def make_planner(name: str) -> PlanFn:
    """``plan(problem) -> Plan`` for an iamp planner of the loop.

    Parameters
    ----------
    name : str
        One of :data:`IAMP_PLANNERS`.

    Returns
    -------
    PlanFn
        The planner: it plans the problem it is given, with its ``Problem.limits``; a planner
        that raises returns a ``solver_error`` plan instead.

    Raises
    ------
    IampError
        ``name`` is not an iamp planner of the loop.
    """
    if name == "free":
        return lambda problem: free_plan(problem.ego, "free")
    if name not in IAMP_PLANNERS:
        raise IampError(f"unknown planner {name!r} (not an iamp planner); choose from {', '.join(IAMP_PLANNERS)}")
    if name in registry.REGISTRY:
        return _registered(name)
    raise IampError(f"planner {name!r} is not in the planner registry")  # pragma: no cover
