r"""The planners the closed loop can use, behind one call: ``plan(problem) -> Plan``.

Every iamp planner receives the same problem from the decision layer
(:mod:`iamp.simulation.decision`): the target-lane follower, the target-lane leader and the
current-lane leader, each with its paper corner.

* ``pmp`` — the registry's ``pmp`` (:class:`iamp.planners.pmp.planner.PMPPlanner`), the paper's
  equality on **every** vehicle of the problem (global contact times; the branch-and-bound box
  budget is :data:`PMP_BOXES`).
* ``qp`` — the registry's ``qp``: the discretised QP with the same equality constraints
  (SPEC §3), FOH, ``N = QP_STEPS`` intervals over the (shrinking) horizon, contact nodes by the
  grid sweep, the exact KKT backend.
* ``pmp-active`` — the registry's ``pmp-active``, the PMP with SPEC §14's active set
  (:class:`iamp.planners.active_set.ActiveSetPlanner`, the one implementation): start from the
  unconstrained plan, impose the corner of the vehicle whose safety region it enters most
  deeply, drop a vehicle whose jump has the dragging sign, repeat.
* ``qp-avoid`` — the registry's ``qp-avoid``: the avoidance QP of SPEC §10/§14, Clarabel, FOH,
  ``N = QP_STEPS``, every vehicle as an inequality.

Every problem carries :data:`~iamp.core.physical.PASSENGER_CAR` as ``Problem.limits`` (a planner
that imposes limits imposes them — the avoidance QP does; ``pmp``, ``pmp-active`` and ``qp`` are
given the problem without them, :data:`UNBOUNDED_IN_LOOP`, for time); the decision layer checks
every plan's peaks either way.
Where the registry holds an entry of the same name (``pmp-active`` and the bounded planners
from the ``avoid``/``limits``/``bpmp`` branches), :func:`make_planner` takes the registry's.
* ``free`` — no constraint at all (the ablation): the minimum-energy cubic below.
* ``mobil`` and ``sumo`` — no iamp planner (:mod:`iamp.simulation.mobil`, SUMO's LC2013).

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from iamp.core.errors import IampError
from iamp.core.free import FreeTrajectory, free_plan
from iamp.core.physical import PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.status import SUCCESS
from iamp.planners import registry
from iamp.simulation.decision import clearly_beyond_limits

__all__ = ["IAMP_PLANNERS", "PLANNERS", "PMP_BOXES", "QP_STEPS", "SCREENED", "SCREEN_MARGIN", "SIM_OPTIONS",
           "FreeTrajectory", "PlanFn", "Screen", "free_plan", "make_planner", "screened"]

PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
#: Planners that call an iamp planner through the decision layer.
IAMP_PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free")
QP_STEPS = 12
#: The PMP's branch-and-bound box budget in the loop (the library's 200 000 took 1-8 s on
#: three-vehicle lane changes; 5000 gave the same cost to 1e-12 on the 4 cases measured; 2000
#: here for time).  Status ``local`` — residuals checked, global optimality not certified —
#: which the decision layer accepts like ``optimal``.
PMP_BOXES = 2000
#: The avoidance QP's budget of QP solves in its crossing-time search (deterministic, unlike a
#: time limit; beyond it the plan is ``local``, which the decision layer judges like any other).
AVOID_SOLVES = 100
#: The closed loop's options per registry name (small grids: the planners run every period).
#: ``compiled: False`` pins the PMP's pure-Python search: the default (``None``) would switch
#: to the numba search as soon as it is loaded in the process (:func:`screened` loads it), and
#: that search agrees with the pure one only to ~1e-9, not bit for bit.
SIM_OPTIONS: dict[str, dict[str, Any]] = {
    "pmp": {"diagnostics": False, "max_boxes": PMP_BOXES, "compiled": False},
    "pmp-active": {"diagnostics": False, "max_boxes": PMP_BOXES, "compiled": False},
    "qp": {"steps": QP_STEPS, "hold": "foh", "solver": "kkt", "contact": "grid"},
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


#: Planners given the problem without ``Problem.limits`` (their plans are judged against the
#: limits by the decision layer like every other plan): the equality QP's grid sweep with the
#: limit rows needs an inequality backend, and with Clarabel it took 4-5 s per three-vehicle
#: problem (N = 12, under load 12 on 2 cores; every one infeasible within the passenger car's
#: bounds) against 0.02 s with the KKT solve; the bounded PMP (merged from main after the
#: published campaign started) took 5.6-6.8 s per three-vehicle problem (``infeasible``) and
#: ``pmp-active`` on it up to 7.5 s, against 0.3 s and 0.04 s unbounded.
UNBOUNDED_IN_LOOP = ("qp", "pmp", "pmp-active")


def _registered(name: str, screen: Screen | None = None) -> PlanFn:
    known = set(registry.REGISTRY[name].option_names())
    opts = {k: v for k, v in SIM_OPTIONS.get(name, {}).items() if k in known}
    planner = registry.make_planner(name, **opts)
    if name in UNBOUNDED_IN_LOOP:
        exact: PlanFn = lambda problem: planner.plan(problem.with_limits(None))  # noqa: E731
    else:
        exact = planner.plan
    if name in SCREENED and screen is not None:
        exact = screened(exact, lambda: _compiled_pmp(opts), screen)
    return _safe(exact, name)


@dataclass(frozen=True)
class Screen:
    """What the decision layer's limit test needs: ``limits`` sampled every ``dt``
    (:attr:`~iamp.simulation.decision.DecisionConfig.limits`, ``check_dt``)."""

    limits: PhysicalLimits
    dt: float


#: Planners whose calls go through :func:`screened` when the controller asks for it.
SCREENED = ("pmp",)
#: A screened plan must break a bound by more than this (m/s², m/s) to be returned unchecked;
#: the compiled and pure PMP plans of 1001 loop problems differed by at most 3.0e-6 in
#: ``a_x, a_y, v_x`` at the decision layer's samples (merge and discretionary, medium, seed 1).
SCREEN_MARGIN = 1e-3


def _compiled_pmp(opts: dict[str, Any]) -> PlanFn | None:
    """The PMP with the numba search (``None`` if numba cannot be loaded): loaded on first use."""
    from iamp.planners.pmp import compiled_search

    if not compiled_search.load():
        return None
    fast = registry.make_planner("pmp", **{**opts, "compiled": True})
    return lambda problem: fast.plan(problem.with_limits(None))


def screened(exact: PlanFn, make_fast: Callable[[], PlanFn | None], screen: Screen,
             margin: float = SCREEN_MARGIN) -> PlanFn:
    r"""``exact``'s decisions, faster: plan with the fast twin first and keep its plan only
    when the decision layer would reject the exact plan on the limits anyway.

    The fast planner (the PMP's numba search, :mod:`iamp.planners.pmp.compiled_search`) runs
    the same algorithm as ``exact`` in other floating-point order: the same status and
    contact times to ~1e-9 of ``t_f`` (tests/test_pmp_basin.py), not bit for bit.  Its plan
    is returned as it is iff its status is verified (``optimal``/``local``) and it breaks
    one of the decision layer's bounds by more than ``margin`` at a sample farther than 1 µs
    from each of its contact times
    (:func:`~iamp.simulation.decision.clearly_beyond_limits`).  Then the exact plan — whose
    inputs at those samples lie within ``margin/√2 - 1e-6`` of these (they differ by at most
    3e-6 on the loop's problems, :data:`SCREEN_MARGIN`) — breaks the same bound, and the
    decision layer's verdict (``limits``), the counters (a verified plan, a planner call)
    and so the episode are the same; a rejected plan is never executed.  Every other plan
    (accepted, or near a bound, or not verified) is made again by ``exact`` and returned:
    the episode sees exactly the plans it saw without the screen (also when the fast planner
    raises).  Assumed, not proved: the
    two searches end in the same basin with the same status (1001 of 1001 loop problems did;
    the episodes are compared with the screen on and off in tests/test_closed_loop.py).
    The fast planner is made on the first problem with two or more vehicles (one vehicle has
    a closed-form search, nothing to screen); without numba every call is ``exact``.
    """
    state: dict[str, PlanFn | None] = {}

    def call(problem: Problem) -> Plan:
        if problem.m < 2:
            return exact(problem)
        if "fast" not in state:
            state["fast"] = make_fast()
        fast = state["fast"]
        if fast is not None:
            try:
                plan: Plan | None = fast(problem)
            except Exception:  # the fast twin failed: the exact planner decides, as without the screen
                plan = None
            if plan is not None and plan.status in SUCCESS and plan.trajectory is not None:
                jumps = [float(t) for t in np.asarray(plan.contact_times, dtype=float).reshape(-1) if np.isfinite(t)]
                if clearly_beyond_limits(plan.trajectory, float(plan.problem.tf), screen.limits, screen.dt, margin,
                                         jumps):
                    plan.annotate(screened=True)
                    return plan
        return exact(problem)
    return call


def make_planner(name: str, screen: Screen | None = None) -> PlanFn:
    """``plan(problem) -> Plan`` for the iamp planners (:data:`IAMP_PLANNERS`); with ``screen``
    the planners of :data:`SCREENED` go through :func:`screened` (the same decisions, faster)."""
    if name == "free":
        return lambda problem: free_plan(problem.ego, "free")
    if name not in IAMP_PLANNERS:
        raise IampError(f"unknown planner {name!r} (not an iamp planner); choose from {', '.join(IAMP_PLANNERS)}")
    if name in registry.REGISTRY:
        return _registered(name, screen)
    raise IampError(f"planner {name!r} is not in the planner registry")  # pragma: no cover
