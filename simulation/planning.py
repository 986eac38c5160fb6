r"""The planners the closed loop can use, behind one call: ``plan(problem) -> Plan``.

Every iamp planner receives the same problem from the decision layer
(:mod:`iamp.simulation.decision`): the target-lane follower, the target-lane leader and the
current-lane leader, each with its paper corner.

* ``pmp`` — :class:`iamp.planners.pmp.PMPPlanner`, the paper's equality on **every** vehicle of
  the problem (global contact times).
* ``qp`` — the discretised QP with the same equality constraints (SPEC §3), FOH, ``N = 20``
  intervals over the (shrinking) horizon, contact nodes by ``refine`` (a grid sweep over
  three vehicles would solve ~6000 QPs a period), the exact KKT backend.
* ``pmp-active`` — the PMP with SPEC §14's active set (:func:`active_set_plan`): start from the
  unconstrained plan, impose the corner of the vehicle whose safety region it enters most
  deeply, drop a vehicle whose jump has the dragging sign, repeat.  One function, so that the
  planner's own ``constraint="active"`` (being built on branch ``avoid``) can replace it.
* ``qp-avoid`` — the avoidance QP of SPEC §10/§14 (``iamp.planners.avoid.AvoidQPPlanner``,
  Clarabel, FOH, ``N = 20``, every vehicle as an inequality).
* ``free`` — no constraint at all (the ablation): the minimum-energy cubic below.
* ``mobil`` and ``sumo`` — no iamp planner (:mod:`iamp.simulation.mobil`, SUMO's LC2013).

With no vehicle left to constrain (every constraint met or no neighbour), every iamp planner
returns the unconstrained optimum, a cubic per axis (:class:`FreeTrajectory`): with
``ṡ = v, v̇ = u`` and ``J = ½∫u²``, the minimiser with fixed end states is

.. math::  s(t) = s_0 + v_0 t + c_2 t^2 + c_3 t^3,\quad
           c_2 = \frac{3e - g t_f}{t_f^2},\ c_3 = \frac{-2e + g t_f}{t_f^3},\quad
           e = s_f - s_0 - v_0 t_f,\ g = v_f - v_0,

whose cost is :math:`J = \sum_{axes} (6 e^2/t_f^3 - 6 e g/t_f^2 + 2 g^2/t_f)`.  Such a call
is not a planner call: it is not timed into ``plan_time_s``.
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
from iamp.core.status import OPTIMAL, SUCCESS

PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
#: Planners that call an iamp planner through the decision layer.
IAMP_PLANNERS = ("pmp", "qp", "pmp-active", "qp-avoid", "free")
QP_STEPS = 12
#: The PMP's branch-and-bound box budget in the loop (the library's 200 000 took 1-8 s on
#: three-vehicle lane changes; 5000 gave the same cost to 1e-12 on the cases measured, status
#: ``local`` — checked residuals, global optimality not certified — which the decision layer accepts).
PMP_BOXES = 5000


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

    @property
    def contact_times(self) -> np.ndarray:
        """No pieces: one cubic on ``[0, t_f]`` (lets the §9 report be exact)."""
        return np.zeros(0)

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


def _failed(problem: Problem, planner: str, exc: BaseException) -> Plan:
    return Plan(problem=problem, planner=planner, status="solver_error", cost=None,
                contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                trajectory=None, info={"error": repr(exc)})


def _safe(fn: PlanFn, name: str) -> PlanFn:
    """A planner crash is a failed plan, not a crashed episode."""
    def call(problem: Problem) -> Plan:
        try:
            return fn(problem)
        except Exception as exc:
            return _failed(problem, name, exc)
    return call


def enters(plan: Plan, vehicle: Any, dt: float = 0.05) -> float:
    """How deep the plan's point enters ``vehicle``'s safety region (0: not at all), sampled."""
    tf = float(plan.problem.tf)
    t = np.linspace(0.0, tf, int(tf / dt) + 1)
    X = np.asarray(plan.trajectory.states(t))
    dx = vehicle.length / 2 + vehicle.safety_x - np.abs(X[:, 0] - vehicle.position(t))
    dy = vehicle.width / 2 + vehicle.safety_y - np.abs(X[:, 2] - vehicle.y)
    depth = np.minimum(dx, dy)
    return float(max(depth.max(), 0.0))


def active_set_plan(problem: Problem, fn: PlanFn, name: str) -> Plan:
    """SPEC §14's active set around the equality planner ``fn`` (see the module docstring).

    Start from the unconstrained plan; while it enters a safety region of a vehicle not yet
    imposed, impose the one it enters most deeply and re-plan; a vehicle whose jump (the
    co-state jump ``Φ_x``) comes out with the dragging sign — the ego pulled towards the
    vehicle instead of pushed away (SPEC §2 identity 2: ``sign(Φ_x) = -s_x`` is the pushing
    sign) — is dropped and not imposed again.  Stops when no region is entered (``info
    ["active"]``: the imposed vehicles, ``info["dropped"]``: the dropped ones) or when nothing
    changes; the decision layer judges the result like any other plan.
    """
    chosen: list[Any] = []
    dropped: list[str] = []
    plan = free_plan(problem.ego, name)
    for _ in range(2 * problem.m):
        if plan.trajectory is None or plan.status not in SUCCESS:
            break
        depths = [(enters(plan, v), v) for v in problem.vehicles if v not in chosen and v.name not in dropped]
        depths = [d for d in depths if d[0] > 1e-3]
        if not depths:
            break
        chosen.append(max(depths, key=lambda d: d[0])[1])
        plan = fn(problem.with_vehicles(chosen))
        if plan.status in SUCCESS and plan.jumps is not None and len(plan.jumps) == len(chosen):
            bad = [v for v, j in zip(chosen, np.asarray(plan.jumps)) if np.isfinite(j[0]) and j[0] * v.sign_x > 1e-9]
            if bad:
                for v in bad:
                    chosen.remove(v)
                    dropped.append(str(v.name))
                plan = fn(problem.with_vehicles(chosen)) if chosen else free_plan(problem.ego, name)
    plan.info["active"] = [str(v.name) for v in chosen]
    plan.info["dropped"] = dropped
    return plan


def make_planner(name: str) -> PlanFn:
    """``plan(problem) -> Plan`` for the iamp planners (``IAMP_PLANNERS``)."""
    if name == "free":
        return lambda problem: free_plan(problem.ego, "free")
    if name in ("pmp", "pmp-active"):
        from iamp.planners.pmp import PMPPlanner

        pmp = PMPPlanner(max_boxes=PMP_BOXES)
        fn = _safe(lambda problem: pmp.plan(problem, diagnostics=False), "pmp")
        if name == "pmp":
            return fn
        return lambda problem: active_set_plan(problem, fn, "pmp-active")
    if name == "qp":
        from iamp.planners.qp import QPPlanner

        try:  # the exact KKT solve of the equality QP where the backend registry has it
            qp: Any = QPPlanner(steps=QP_STEPS, hold="foh", solver="kkt", contact="grid")
        except ValueError:  # pragma: no cover - older planner without the kkt backend
            qp = QPPlanner(steps=QP_STEPS, hold="foh", solver="osqp", contact="grid")
        return _safe(lambda problem: qp.plan(problem), "qp")
    if name == "qp-avoid":
        try:
            from iamp.planners.avoid.planner import AvoidQPPlanner  # type: ignore[import-not-found,unused-ignore]
        except ImportError as exc:
            raise PlannerUnavailable(f"planner 'qp-avoid' is unavailable: iamp.planners.avoid is not installed "
                                     f"({exc})") from None
        avoid: Any = AvoidQPPlanner(steps=QP_STEPS, hold="foh", solver="clarabel")
        return _safe(lambda problem: avoid.plan(problem), "qp-avoid")
    raise IampError(f"planner {name!r} is not an iamp planner; choose from {', '.join(IAMP_PLANNERS)}")
