r"""The closed-loop lane-change controller: observe, predict, plan, apply the first period.

Mission
-------
The ego alternates between its lane and the lane to its left (middle ↔ left): it asks for a
lane change, seeks a gap, changes lanes, holds the new lane for ``hold_s`` and asks again.
Between manoeuvres SUMO's Krauss model drives it in its lane.

The gap (what a driver does)
----------------------------
Like a driver and like SUMO's LC2013, the ego considers only the **adjacent gap** of the
target lane: the follower ``f`` = the nearest target-lane vehicle whose centre is behind
the ego's centre, the leader ``l`` = the nearest one ahead.  Each period while seeking it
plans the lane change into that gap and **accepts** the gap when the plan

* succeeded (status ``optimal``/``local``),
* stays within comfort limits ``|u_x| ≤ a_x,max``, ``|u_y| ≤ a_y,max`` over the horizon,
* keeps the ego's body clear of the *predicted* bodies of ``f``, ``l`` and the current-lane
  leader ``c`` (the SPEC §9 overlap test against the cubics), and
* ends with at least ``gap_min_m`` bumper to bumper behind ``l`` and ahead of ``f``.

Otherwise it keeps driving in its lane and tries again next period (the traffic moves the
next gap alongside).  The same rule serves every iamp planner; each judges its own plan.

The problem (the paper's two-vehicle scenario)
----------------------------------------------
``T = horizon_s`` after acceptance the ego is to be in the target lane's centre ``y_f``
with ``v_{y,f} = 0`` and

* ``v_{x,f}`` = the mean predicted speed of ``f`` and ``l`` at ``T`` (whichever exist;
  the ego's speed if neither);
* ``x_f`` = where the ego would be at constant acceleration, ``x_0 + (v_{x,0} + v_{x,f})T/2``,
  moved into the part of the predicted gap at ``T`` that leaves a time headway
  ``headway_s·v_{x,f}`` (bumper to bumper) to ``f`` and to ``l``; if the gap is shorter
  than that, its middle.

Constraints (for a change to the left, +y; mirrored to the right): ``f`` → ``front-lower``,
``c`` → ``rear-upper``, each with ``S_x, S_y`` (SPEC §8 defaults 5 m, 0.5 m), its cubic from
the shared predictor fed with the last 3 s of the vehicle's centre positions, and its
current lateral position.  A neighbour counts only within ``relevant_m`` longitudinally;
a constraint is dropped once the ego has passed its corner laterally (it has been met).

Receding horizon
----------------
Every period the problem is rebuilt from the measured state and fresh predictions with
the **remaining** horizon ``t_f = t_end - t`` (the manoeuvre's end stays fixed, so it
finishes); the first period of the new plan is applied.  Below ``min_replan_s`` the last
plan is followed to its end.  At ``t_end`` the ego is in the target lane's centre and SUMO
takes over.

Fallback (counted)
------------------
A plan that fails, or takes longer than ``deadline_s`` (wall clock; ``None`` = no
deadline), is not used: the ego keeps executing the **last feasible plan** if that plan's
remainder is still body-collision-free against the new predictions; otherwise it **brakes
in lane**: ``a_x = -brake``, and ``a_y = -k_p (y - y_lane) - k_d v_y`` returns it to the
centre of the lane it is in; after ``abort_s`` SUMO takes over and the ego seeks again.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from iamp.core.diagnostics import Diagnostics
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.scenario import History
from iamp.core.status import SUCCESS
from iamp.prediction.predictor import Predictor
from iamp.simulation.planning import PlanFn, free_plan, make_planner
from iamp.simulation.simulator import EgoState, Observation, Simulator


@dataclass(frozen=True)
class ControllerConfig:
    """Parameters of the controller (see the module docstring)."""

    horizon_s: float = 5.0
    min_replan_s: float = 0.5
    safety_x: float = 5.0
    safety_y: float = 0.5
    a_max_x: float = 3.5
    a_max_y: float = 2.0
    gap_min_m: float = 2.0
    headway_s: float = 1.0
    relevant_m: float = 50.0
    hold_s: float = 5.0
    brake: float = 3.0
    kp: float = 2.25
    kd: float = 3.0
    abort_s: float = 3.0
    deadline_s: float | None = 0.1


@dataclass
class Gap:
    """Indices (into an :class:`Observation`) of ``f``, ``l`` and ``c``; ``-1``: none."""

    follower: int
    leader: int
    current_leader: int


@dataclass
class Counters:
    plans: int = 0
    failed_plans: int = 0
    late_plans: int = 0
    constrained_plans: int = 0
    fallbacks: int = 0
    aborts: int = 0
    lane_changes: int = 0
    first_done_t: float | None = None
    plan_times: list[float] = field(default_factory=list)
    prediction_s: float = 0.0
    planning_s: float = 0.0


#: Planners that get the active-set rule (``pmp-all``/``qp-all`` do not: the paper literally).
ACTIVE_SET_PLANNERS = ("pmp", "qp", "qp-avoid")


def _poly_at(c: tuple[float, ...], t: np.ndarray) -> np.ndarray:
    return np.asarray(np.polynomial.polynomial.polyval(t, c), dtype=float)


class Controller:
    """Drives the ego's lane changes with one planner (``pmp``, ``qp``, ``qp-avoid``, ``sumo``)."""

    def __init__(self, planner: str, sim: Simulator, config: ControllerConfig | None = None,
                 predictor: Predictor | None = None) -> None:
        self.name = planner
        self.sim = sim
        self.cfg = config or ControllerConfig()
        self.plan_fn: PlanFn | None = None if planner == "sumo" else make_planner(planner)
        self.predictor = predictor or Predictor.default()
        self.n = Counters()
        self.mode = "seek"
        self.origin = sim.ego_lane
        self.target = sim.ego_lane + 1
        self.hold_until = 0.0
        self.t_end = 0.0
        self.plan: Plan | None = None
        self.plan_t0 = 0.0
        self.abort_until = 0.0
        self.requested = False

    # -- geometry -----------------------------------------------------------------------
    @property
    def direction(self) -> float:
        return 1.0 if self.target > self.origin else -1.0

    def gap(self, obs: Observation, ego: EgoState) -> Gap:
        rel = np.abs(obs.x - ego.x) <= self.cfg.relevant_m
        f = l = c = -1
        tgt = np.flatnonzero(rel & (obs.lane == self.target))
        behind = tgt[obs.x[tgt] < ego.x]
        ahead = tgt[obs.x[tgt] >= ego.x]
        if behind.size:
            f = int(behind[np.argmax(obs.x[behind])])
        if ahead.size:
            l = int(ahead[np.argmin(obs.x[ahead])])
        cur = np.flatnonzero(rel & (obs.lane == self.origin) & (obs.x > ego.x))
        if cur.size:
            c = int(cur[np.argmin(obs.x[cur])])
        return Gap(f, l, c)

    # -- prediction -----------------------------------------------------------------------
    def predict(self, obs: Observation, k: int, tf: float) -> tuple[float, ...]:
        """Cubic ``x_s(t)`` of neighbour ``k`` from its last 3 s (constant speed if shorter than the
        predictor needs)."""
        start = time.perf_counter()
        t, x = self.sim.history(obs.ids[k])
        if t.size >= 3 and -t[0] + 1e-9 >= self.predictor.min_history_s:
            poly: tuple[float, ...] = tuple(self.predictor.predict(History(t, x), tf).x_poly)
        else:
            poly = (float(obs.x[k]), float(obs.v[k]), 0.0, 0.0)
        self.n.prediction_s += time.perf_counter() - start
        return poly

    # -- the problem ------------------------------------------------------------------------
    def build(self, obs: Observation, ego: EgoState, tf: float) -> tuple[Problem | EgoBoundary, dict[str, Any]]:
        """The lane-change problem towards the adjacent gap over ``tf`` seconds."""
        cfg, d = self.cfg, self.direction
        g = self.gap(obs, ego)
        polys = {k: self.predict(obs, k, tf) for k in (g.follower, g.leader, g.current_leader) if k >= 0}
        Le = self.sim.ego_length
        T = np.array([tf])
        speeds = [float(_poly_at(tuple(np.polynomial.polynomial.polyder(polys[k])), T)[0])
                  for k in (g.follower, g.leader) if k >= 0]
        vxf = float(np.clip(np.mean(speeds), 0.0, 1.2 * self.sim.highway.speed_limit)) if speeds else ego.vx
        f_end = l_end = None
        if g.follower >= 0:
            f_end = float(_poly_at(polys[g.follower], T)[0]) + obs.length[g.follower] / 2 + Le / 2
        if g.leader >= 0:
            l_end = float(_poly_at(polys[g.leader], T)[0]) - obs.length[g.leader] / 2 - Le / 2
        lo = -np.inf if f_end is None else f_end + cfg.headway_s * vxf
        hi = np.inf if l_end is None else l_end - cfg.headway_s * vxf
        x_nat = ego.x + (ego.vx + vxf) * tf / 2
        xf = float(np.clip(x_nat, lo, hi)) if lo <= hi else (lo + hi) / 2
        yf = self.sim.highway.lane_centre(self.target)
        boundary = EgoBoundary(tf=tf, x0=ego.x, y0=ego.y, vx0=ego.vx, vy0=ego.vy, xf=xf, yf=yf, vxf=vxf, vyf=0.0)
        vehicles = []
        for k, front in ((g.follower, True), (g.current_leader, False)):
            if k < 0:
                continue
            corner = ("front-" if front else "rear-") + ("lower" if d * (1 if front else -1) > 0 else "upper")
            sv = SurroundingVehicle(polys[k], corner, float(obs.y[k]), float(obs.length[k]), float(obs.width[k]),
                                    cfg.safety_x, cfg.safety_y, name=obs.ids[k])
            if d * (ego.y - sv.corner_y) < 0:  # not yet passed laterally
                vehicles.append(sv)
        ctx = {"gap": g, "polys": polys, "f_end": f_end, "l_end": l_end}
        return (Problem(boundary, tuple(vehicles)) if vehicles else boundary), ctx

    def _call(self, prob: Problem | EgoBoundary) -> Plan:
        assert self.plan_fn is not None
        if isinstance(prob, EgoBoundary):
            return free_plan(prob, self.name)
        try:
            return self.plan_fn(prob)
        except Exception as exc:  # a planner crash is a failed plan, not a crashed episode
            return Plan(problem=prob, planner=self.name, status="solver_error", cost=None,
                        contact_times=np.full(prob.m, np.nan), jumps=np.full((prob.m, 2), np.nan),
                        trajectory=None, diagnostics=Diagnostics(error=repr(exc)))

    def _active_set(self, prob: Problem) -> Plan:
        """Impose vehicle ``i``'s constraint only where it is needed.

        Start from the unconstrained plan; add every vehicle whose safety region the current
        plan's point enters (on its continuous trajectory); re-plan; repeat until no excluded
        region is entered (at most ``m`` rounds).  For the avoidance QP this is an exact
        active-set argument: a plan optimal without some inequalities that satisfies them is
        optimal with them.  For the equality planners it is a modelling choice: without it the
        equality drags the ego to the corner of every neighbour, however far (SPEC §2
        identity 4; ``pmp-all``/``qp-all`` show that).
        """
        chosen: list[SurroundingVehicle] = []
        plan = free_plan(prob.ego, self.name)
        for _ in range(prob.m):
            if plan.trajectory is None or plan.status not in SUCCESS:
                return plan
            t = np.linspace(0.0, prob.tf, int(prob.tf / 0.05) + 1)
            X = np.asarray(plan.require_trajectory().states(t))
            hit = [v for v in prob.vehicles if v not in chosen and bool(np.any(
                (np.abs(X[:, 0] - v.position(t)) < v.length / 2 + v.safety_x)
                & (np.abs(X[:, 2] - v.y) < v.width / 2 + v.safety_y)))]
            if not hit:
                break
            chosen += hit
            plan = self._call(prob.with_vehicles([v for v in prob.vehicles if v in chosen]))
        plan.annotate(constrained=[v.name for v in chosen])
        return plan

    def solve(self, prob: Problem | EgoBoundary) -> tuple[Plan, bool]:
        """Plan (timed); returns the plan and whether it is usable (succeeded, not late)."""
        start = time.perf_counter()
        if self.name in ACTIVE_SET_PLANNERS and isinstance(prob, Problem):
            plan = self._active_set(prob)
        else:
            plan = self._call(prob)
        elapsed = time.perf_counter() - start
        self.n.plans += 1
        self.n.plan_times.append(elapsed)
        self.n.planning_s += elapsed
        ok = plan.status in SUCCESS and plan.trajectory is not None
        if not ok:
            self.n.failed_plans += 1
        elif getattr(plan.problem, "m", 0) > 0:
            self.n.constrained_plans += 1
        late = self.cfg.deadline_s is not None and elapsed > self.cfg.deadline_s
        if ok and late:
            self.n.late_plans += 1
        return plan, ok and not late

    # -- checks -----------------------------------------------------------------------------
    def clear_of_bodies(self, plan: Plan, obs: Observation, ctx: dict[str, Any], t_from: float = 0.0) -> bool:
        """SPEC §9 overlap test of the plan (from ``t_from``) against the predicted bodies."""
        tf = float(plan.problem.tf)
        t = np.linspace(t_from, tf, max(int((tf - t_from) / 0.05), 1) + 1)
        X = np.asarray(plan.require_trajectory().states(t))
        Le, We = self.sim.ego_length, self.sim.ego_width
        for k, poly in ctx["polys"].items():
            xs = _poly_at(poly, t - t_from)
            lon = np.abs(X[:, 0] - xs) < (Le + obs.length[k]) / 2
            if np.any(lon & (np.abs(X[:, 2] - obs.y[k]) < (We + obs.width[k]) / 2)):
                return False
        return True

    def acceptable(self, plan: Plan, obs: Observation, ctx: dict[str, Any]) -> bool:
        cfg = self.cfg
        tf = float(plan.problem.tf)
        U = np.asarray(plan.require_trajectory().inputs(np.linspace(0.0, tf, 51)))
        if np.max(np.abs(U[:, 0])) > cfg.a_max_x or np.max(np.abs(U[:, 1])) > cfg.a_max_y:
            return False
        xf = float(plan.problem.ego.xf)
        if ctx["l_end"] is not None and xf > ctx["l_end"] - cfg.gap_min_m:
            return False
        if ctx["f_end"] is not None and xf < ctx["f_end"] + cfg.gap_min_m:
            return False
        return self.clear_of_bodies(plan, obs, ctx)

    # -- one period ---------------------------------------------------------------------------
    def step(self, t: float, obs: Observation, ego: EgoState) -> EgoState | None:
        """The ego's state for the next step, or ``None`` when SUMO drives it this step."""
        if self.mode == "hold":
            if t + 1e-9 < self.hold_until:
                return None
            self.origin, self.target = self.target, self.origin
            self.mode, self.requested = "seek", False
        if self.name == "sumo":
            self._sumo_step(t)
            return None
        if self.mode == "abort":
            if t + 1e-9 >= self.abort_until:
                self.sim.release()
                if self.sim.highway.lane_of(ego.y) == self.target:
                    self._done(t)  # it ended up in the target lane after all
                else:
                    self.mode = "seek"
                return None
            return self._brake(ego)
        dt = self.sim.step
        if self.mode == "seek":
            prob, ctx = self.build(obs, ego, self.cfg.horizon_s)
            plan, ok = self.solve(prob)
            if not (ok and self.acceptable(plan, obs, ctx)):
                return None
            self.mode, self.plan, self.plan_t0, self.t_end = "active", plan, t, t + self.cfg.horizon_s
        else:
            tf = self.t_end - t
            if tf > self.cfg.min_replan_s:
                prob, ctx = self.build(obs, ego, tf)
                plan, ok = self.solve(prob)
                if ok:
                    self.plan, self.plan_t0 = plan, t
                else:
                    self.n.fallbacks += 1
                    if self.plan is None or not self.clear_of_bodies(self.plan, obs, ctx, t - self.plan_t0):
                        self.mode, self.abort_until, self.plan = "abort", t + self.cfg.abort_s, None
                        self.n.aborts += 1
                        return self._brake(ego)
        assert self.plan is not None
        tau = min(t + dt - self.plan_t0, float(self.plan.problem.tf))
        X = np.asarray(self.plan.require_trajectory().states(np.array([tau])))[0]
        U = np.asarray(self.plan.require_trajectory().inputs(np.array([max(tau - dt / 2, 0.0)])))[0]
        nxt = EgoState(x=float(X[0]), vx=float(X[1]), y=float(X[2]), vy=float(X[3]), ax=float(U[0]), ay=float(U[1]))
        if t + dt >= self.t_end - 1e-9:
            self._done(t + dt)
        return nxt

    def _done(self, t_done: float) -> None:
        self.n.lane_changes += 1
        if self.n.first_done_t is None:
            self.n.first_done_t = t_done
        self.mode, self.hold_until, self.plan = "hold", t_done + self.cfg.hold_s, None

    def _brake(self, ego: EgoState) -> EgoState:
        """Brake in lane towards the centre of the lane the ego is in (exact for one step of
        constant input)."""
        cfg, dt = self.cfg, self.sim.step
        y_lane = self.sim.highway.lane_centre(self.sim.highway.lane_of(ego.y))
        ax = -cfg.brake if ego.vx > cfg.brake * dt else -ego.vx / dt
        ay = -cfg.kp * (ego.y - y_lane) - cfg.kd * ego.vy
        return EgoState(x=ego.x + ego.vx * dt + ax * dt**2 / 2, vx=ego.vx + ax * dt,
                        y=ego.y + ego.vy * dt + ay * dt**2 / 2, vy=ego.vy + ay * dt, ax=ax, ay=ay)

    def _sumo_step(self, t: float) -> None:
        """The reference: LC2013 changes lanes when it judges the gap safe."""
        if not self.requested:
            self.sim.request_lane_change(self.target, 3600.0)
            self.requested = True
            return
        if self.sim.ego_lane_index() == self.target and abs(self.sim.ego_lateral_offset()) < 0.05:
            self.sim.release()
            self._done(t)
