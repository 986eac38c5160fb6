r"""The closed-loop controller: observe, predict (batched), decide, plan, apply the first period.

Modes
-----
* ``seek`` — SUMO's Krauss drives the ego in its lane (no own lane changes).  Every
  ``seek_every_s`` (0.3 s, three periods; the same for ``mobil``) the decision layer
  (:mod:`iamp.simulation.decision`) tries the candidate gaps with the planner and accepts
  the first verified, bounded, intrusion-free plan; ``mobil`` asks MOBIL about the adjacent
  gap instead; ``sumo`` has asked LC2013 once and waits.
* ``active`` — the accepted manoeuvre.  Every period the problem into the **committed gap**
  (the same follower and leader, by name) is rebuilt from the measured state and fresh
  predictions with the remaining horizon ``t_f = t_end - t`` and planned again; the new plan
  is used if the decision layer's test (:func:`~iamp.simulation.decision.judge`) passes.
  Below ``min_replan_s`` the last plan is followed to its end.
* ``done`` / ``hold`` — the ego is in the target lane's centre; SUMO drives it.  In the
  ``discretionary`` mission the ego holds ``hold_s`` and then seeks the other lane.
* ``abort`` — see the fallback.

Fallback (counted as ``fallbacks``)
-----------------------------------
A re-plan that fails the test (or, with a deadline, arrives late) is not used: the ego keeps
executing the last accepted plan if that plan's remainder keeps its body clear of the newly
predicted bodies; otherwise it brakes in lane (``a_x = -brake``, ``a_y = -k_p(y - y_lane) -
k_d v_y`` back to the centre of the lane it is in; ``aborts``), and after ``abort_s`` SUMO
takes over and the ego seeks again.

Prediction (batched)
--------------------
Once per period every neighbour within ``relevant_m + 20`` m in the ego's and the target lane
is predicted; neighbours with a full history share its sample times and go through
:meth:`~iamp.prediction.predictor.Predictor.predict_batch` in one call (the cubic fitted to the
predicted path, read back at four Chebyshev points, which determine it); a neighbour seen for
less than the predictor needs is extrapolated at constant speed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from iamp.core.physical import PASSENGER_CAR
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem
from iamp.prediction.predictor import Predictor
from iamp.simulation.decision import (
    DecisionConfig,
    EgoNow,
    Gap,
    Neighbour,
    check_problem,
    decide,
    end_state,
    judge,
    lane_change_problem,
)
from iamp.simulation.missions import Mission, mission_of
from iamp.simulation.mobil import IDM, MOBIL, Car, mobil_accepts
from iamp.simulation.planning import FreeTrajectory, PlanFn, Screen, free_plan, make_planner
from iamp.simulation.simulator import EgoState, Observation, Simulator


@dataclass(frozen=True)
class ControllerConfig:
    """Parameters of the controller (see the module docstring)."""

    decision: DecisionConfig = field(default_factory=DecisionConfig)
    min_replan_s: float = 0.5
    seek_every_s: float = 0.3
    hold_s: float = 5.0
    brake: float = 3.0
    kp: float = 2.25
    kd: float = 3.0
    abort_s: float = 3.0
    deadline_s: float | None = None
    ego_in_forecast: bool = False  # the target-lane follower reacts to the plan (decision.decide's react)
    ego_iter: int = 3              # at most this many re-plans per gap
    ego_tol_m: float = 1.0         # the follower's cubic moved less than this: converged
    screen: bool = True            # the compiled PMP screens out plans rejected on the limits (planning.screened)
    idm: IDM = field(default_factory=IDM)
    mobil: MOBIL = field(default_factory=MOBIL)


@dataclass
class Counters:
    plans: int = 0              # every planner call (candidates and re-plans)
    real_calls: int = 0         # calls on a problem with a vehicle to constrain (or `free`)
    infeasible_plans: int = 0   # calls whose plan is not verified
    rejected: dict[str, int] = field(default_factory=dict)  # decision-layer rejections by test
    late_plans: int = 0
    constrained_plans: int = 0  # executed periods whose plan carried an imposed constraint
    executed_plans: int = 0     # executed periods driven by a plan
    fallbacks: int = 0
    aborts: int = 0
    lane_changes: int = 0
    accepted_t: list[float] = field(default_factory=list)
    done_t: list[float] = field(default_factory=list)
    plan_times: list[float] = field(default_factory=list)
    prediction_s: float = 0.0
    planning_s: float = 0.0
    ego_iterations: int = 0     # gaps planned with the follower reacting (--ego-in-forecast)
    ego_converged: int = 0      # of those, converged within ego_tol_m
    ego_replans: int = 0        # planner calls beyond the first per such gap


def imposed(plan: Plan) -> int:
    """How many constraints the plan imposed (the active set's choice when there is one)."""
    if "active" in plan.info:
        return len(plan.info["active"])
    if plan.info.get("free"):
        return 0
    return int(getattr(plan.problem, "m", 0))


def _cheb(tf: float) -> np.ndarray:
    k = np.arange(4)
    return tf / 2 * (1 - np.cos((2 * k + 1) * np.pi / 8))


class Controller:
    """Drives the ego's mission with one planner (``planning.PLANNERS``)."""

    def __init__(self, planner: str, sim: Simulator, config: ControllerConfig | None = None,
                 predictor: Predictor | None = None, mission: Mission | None = None) -> None:
        self.name = planner
        self.sim = sim
        self.cfg = config or ControllerConfig()
        self.mission = mission or mission_of("discretionary")
        self.iamp = planner not in ("sumo", "mobil")
        dcfg = self.cfg.decision
        # not with the ego in the forecast: there a rejected plan's trajectory feeds the
        # follower's next prediction, so a screened plan (equal only to ~1e-9) would change numbers
        screen = Screen(dcfg.limits, dcfg.check_dt) if self.cfg.screen and not self.cfg.ego_in_forecast else None
        self.plan_fn: PlanFn | None = make_planner(planner, screen) if self.iamp else None
        self.predictor = predictor or Predictor.default()
        self.n = Counters()
        self.mode = "seek"
        self.origin = self.mission.ego_lane
        self.target = self.mission.target_lane
        self.hold_until = 0.0
        self.t_end = 0.0
        self.plan: Plan | None = None
        self.plan_t0 = 0.0
        self.abort_until = 0.0
        self.requested = False
        self.committed: tuple[str | None, str | None] = (None, None)
        self.lateral: np.ndarray | None = None  # mobil: the lateral cubic
        self.lat_t0 = 0.0
        self.next_seek = -math.inf
        self.leader_predictor: Any = None
        if self.cfg.ego_in_forecast and self.iamp:
            from iamp.prediction.leader.model import LeaderPredictor, default_leader_model

            self.leader_predictor = LeaderPredictor(default_leader_model())

    # -- prediction ---------------------------------------------------------------------------
    def neighbours(self, obs: Observation, ego: EgoState, tf: float) -> list[Neighbour]:
        """Predicted neighbours in the ego's and the target lane near the ego (batched)."""
        start = time.perf_counter()
        lanes = (self.origin, self.target)
        near = [k for k in range(len(obs.ids))
                if int(obs.lane[k]) in lanes and abs(obs.x[k] - ego.x) <= self.cfg.decision.relevant_m + 20.0]
        polys: dict[int, tuple[float, ...]] = {}
        full: list[tuple[int, np.ndarray, np.ndarray]] = []
        need = self.predictor.min_history_s
        for k in near:
            t, x = self.sim.history(obs.ids[k])
            if t.size >= 3 and -t[0] + 1e-9 >= need:
                full.append((k, t, x))
            else:
                polys[k] = (float(obs.x[k]), float(obs.v[k]), 0.0, 0.0)
        groups: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        for item in full:
            groups.setdefault(item[1].size, []).append(item)
        q = _cheb(tf)
        for items in groups.values():
            t_h = items[0][1]
            same = [it for it in items if np.allclose(it[1], t_h, atol=1e-6)]
            rest = [it for it in items if it not in same]
            X = np.stack([it[2] for it in same])
            vals = self.predictor.predict_batch(t_h, X, q, tf, cubic=True)
            V = np.vander(q, 4, increasing=True)
            C = np.linalg.solve(V, vals.T)  # (4, B)
            for j, it in enumerate(same):
                polys[it[0]] = tuple(float(c) for c in C[:, j])
            for it in rest:  # pragma: no cover - histories with other sample times
                vals1 = self.predictor.predict_batch(it[1], it[2][None, :], q, tf, cubic=True)
                polys[it[0]] = tuple(float(c) for c in np.linalg.solve(V, vals1[0]))
        self.n.prediction_s += time.perf_counter() - start
        return [Neighbour(obs.ids[k], polys[k], float(obs.y[k]), float(obs.length[k]), float(obs.width[k]),
                          int(obs.lane[k])) for k in near]

    def ego_now(self, ego: EgoState) -> EgoNow:
        return EgoNow(ego.x, ego.vx, ego.y, ego.vy, self.sim.ego_length, self.sim.ego_width)

    def y_target(self) -> float:
        return self.sim.highway.lane_centre(self.target)

    # -- planning -------------------------------------------------------------------------------
    def _plan(self, prob: Problem | EgoBoundary) -> Plan:
        """One planner call, timed and counted (the closed-form cubic when nothing is constrained
        is not a planner call)."""
        assert self.plan_fn is not None
        start = time.perf_counter()
        if isinstance(prob, EgoBoundary):
            plan = free_plan(prob, self.name)
            if self.name != "free":
                self.n.plans += 1
                return plan
        else:
            plan = self.plan_fn(prob)
        elapsed = time.perf_counter() - start
        self.n.plans += 1
        self.n.real_calls += 1
        self.n.plan_times.append(elapsed)
        self.n.planning_s += elapsed
        if plan.status not in ("optimal", "local") or plan.trajectory is None:
            self.n.infeasible_plans += 1
        if self.cfg.deadline_s is not None and elapsed > self.cfg.deadline_s:
            self.n.late_plans += 1
            plan.annotate(late=True)
        return plan

    def _react_kw(self) -> dict[str, Any]:
        """``decide``'s keywords for the ego in the forecast (none when the option is off)."""
        if self.leader_predictor is None:
            return {}
        return {"react": self._react, "react_iter": self.cfg.ego_iter, "react_tol_m": self.cfg.ego_tol_m,
                "on_iterate": self._on_iterate}

    def _react(self, gap: Gap, plan: Plan, prob: Problem | EgoBoundary) -> tuple[float, ...]:
        """The follower's cubic reacting to ``plan`` (:func:`~iamp.prediction.leader.ego.follower_poly_for_plan`);
        its own cubic unchanged when its history is shorter than the predictor needs."""
        from iamp.prediction.leader.ego import follower_poly_for_plan

        f = gap.follower
        assert f is not None
        t, x = self.sim.history(f.name)
        if not (t.size >= 3 and -t[0] + 1e-9 >= self.predictor.min_history_s):
            return f.poly
        lead = gap.leader
        return follower_poly_for_plan(self.leader_predictor, (t, x), plan.require_trajectory().states,
                                      float(prob.tf), target_y=self.y_target(), ego_length=self.sim.ego_length,
                                      ego_width=self.sim.ego_width, follower_length=f.length,
                                      leader_hist=self.sim.history(lead.name) if lead is not None else None,
                                      leader_length=lead.length if lead is not None else 4.5)

    def _on_iterate(self, rec: dict[str, Any]) -> None:
        self.n.ego_iterations += 1
        self.n.ego_converged += int(bool(rec["converged"]))
        self.n.ego_replans += int(rec["plans"]) - 1

    def _reject(self, reason: str) -> None:
        key = reason.split(":")[0]
        self.n.rejected[key] = self.n.rejected.get(key, 0) + 1

    # -- one period -----------------------------------------------------------------------------
    def step(self, t: float, obs: Observation, ego: EgoState) -> EgoState | None:
        """The ego's state for the next step, or ``None`` when SUMO drives it this step."""
        if self.mode == "done":
            return None
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
                self.mode = "seek"
            else:
                return self._brake(ego)
            return None
        if self.name == "mobil":
            return self._mobil_step(t, obs, ego)
        dt = self.sim.step
        cfg = self.cfg.decision
        if self.mode == "seek":
            if t + 1e-9 < self.next_seek:
                return None
            self.next_seek = t + self.cfg.seek_every_s
            nbs = self.neighbours(obs, ego, cfg.horizon_s)
            verdict, all_v = decide(self.ego_now(ego), self.y_target(), self.target, self.origin, nbs,
                                    self._plan, cfg, **self._react_kw())
            for v in all_v:
                if not v.accepted:
                    self._reject(v.reason)
            if not verdict.accepted or verdict.plan is None or verdict.plan.info.get("late"):
                return None
            gap = verdict.gap or Gap(None, None)
            self.committed = (gap.follower.name if gap.follower else None, gap.leader.name if gap.leader else None)
            self.mode, self.plan, self.plan_t0, self.t_end = "active", verdict.plan, t, t + cfg.horizon_s
            self.n.accepted_t.append(t)
        else:
            tf = self.t_end - t
            if tf > self.cfg.min_replan_s:
                nbs = self.neighbours(obs, ego, tf)
                by = {n.name: n for n in nbs}
                gap = Gap(by.get(self.committed[0] or ""), by.get(self.committed[1] or ""))
                en = self.ego_now(ego)
                ahead = [n for n in nbs if n.lane == self.origin and n.x(0.0) > ego.x
                         and n.x(0.0) - ego.x <= cfg.relevant_m]
                cur = min(ahead, key=lambda n: n.x(0.0)) if ahead else None
                dcfg = replace(cfg, horizon_s=tf)
                prob = lane_change_problem(en, self.y_target(), gap, cur, dcfg, tf, end_state(en, gap, dcfg, tf))
                boundary = prob.ego if isinstance(prob, Problem) else prob
                check = check_problem(boundary, en, nbs, (self.origin, self.target), dcfg)
                plan = self._plan(prob)
                reason = judge(plan, check, dcfg)
                if reason == "accepted" and not plan.info.get("late"):
                    self.plan, self.plan_t0 = plan, t
                else:
                    self._reject(reason)
                    self.n.fallbacks += 1
                    if self.plan is None or not self._clear(self.plan, nbs, t - self.plan_t0):
                        self.mode, self.abort_until, self.plan = "abort", t + self.cfg.abort_s, None
                        self.n.aborts += 1
                        return self._brake(ego)
        assert self.plan is not None
        self.n.executed_plans += 1
        if imposed(self.plan) > 0:
            self.n.constrained_plans += 1
        tau = min(t + dt - self.plan_t0, float(self.plan.problem.tf))
        X = np.asarray(self.plan.require_trajectory().states(np.array([tau])))[0]
        U = np.asarray(self.plan.require_trajectory().inputs(np.array([max(tau - dt / 2, 0.0)])))[0]
        nxt = EgoState(x=float(X[0]), vx=float(X[1]), y=float(X[2]), vy=float(X[3]), ax=float(U[0]), ay=float(U[1]))
        if t + dt >= self.t_end - 1e-9:
            self._done(t + dt)
        return nxt

    def _clear(self, plan: Plan, nbs: list[Neighbour], t_from: float) -> bool:
        """The plan's remainder (from ``t_from``) keeps the ego's body clear of the predicted bodies."""
        tf = float(plan.problem.tf)
        if t_from >= tf:
            return True
        t = np.linspace(t_from, tf, max(int((tf - t_from) / 0.05), 1) + 1)
        X = np.asarray(plan.require_trajectory().states(t))
        Le, We = self.sim.ego_length, self.sim.ego_width
        for n in nbs:
            xs = np.polynomial.polynomial.polyval(t - t_from, n.poly)
            if np.any((np.abs(X[:, 0] - xs) < (Le + n.length) / 2) & (np.abs(X[:, 2] - n.y) < (We + n.width) / 2)):
                return False
        return True

    def _done(self, t_done: float) -> None:
        self.n.lane_changes += 1
        self.n.done_t.append(t_done)
        self.plan, self.lateral = None, None
        if self.mission.alternating:
            self.mode, self.hold_until = "hold", t_done + self.cfg.hold_s
        else:
            self.mode = "done"

    def _brake(self, ego: EgoState) -> EgoState:
        """Brake in lane towards the centre of the lane the ego is in (exact for one step of
        constant input): ``brake``, or harder (up to the passenger car's ``a_x`` bound) to stop
        1 m before the end of an ending lane, ``a = v²/(2 d)``."""
        cfg, dt = self.cfg, self.sim.step
        lane = self.sim.highway.lane_of(ego.y)
        y_lane = self.sim.highway.lane_centre(lane)
        brake = cfg.brake
        drop = self.mission.drop_x
        if drop is not None and lane == self.mission.ego_lane:  # stop before the lane's end: v²/2d
            room = drop - (ego.x + self.sim.ego_length / 2) - 1.0
            brake = max(brake, min(ego.vx**2 / (2 * max(room, 0.1)), -(PASSENGER_CAR.ax or (-6.0, 0.0))[0]))
        ax = -brake if ego.vx > brake * dt else -ego.vx / dt
        ay = -cfg.kp * (ego.y - y_lane) - cfg.kd * ego.vy
        return EgoState(x=ego.x + ego.vx * dt + ax * dt**2 / 2, vx=ego.vx + ax * dt,
                        y=ego.y + ego.vy * dt + ay * dt**2 / 2, vy=ego.vy + ay * dt, ax=ax, ay=ay)

    # -- the baselines ----------------------------------------------------------------------------
    def _cars(self, obs: Observation, ego: EgoState) -> dict[str, Car | None]:
        def nearest(lane: int, ahead: bool) -> Car | None:
            ks = [k for k in range(len(obs.ids)) if int(obs.lane[k]) == lane and (obs.x[k] > ego.x) == ahead]
            if not ks:
                return None
            k = min(ks, key=lambda j: abs(obs.x[j] - ego.x))
            return Car(float(obs.x[k]), float(obs.v[k]), float(obs.length[k]))

        return {"ol": nearest(self.origin, True), "of": nearest(self.origin, False),
                "nl": nearest(self.target, True), "nf": nearest(self.target, False)}

    def _mobil_step(self, t: float, obs: Observation, ego: EgoState) -> EgoState | None:
        """IDM + MOBIL (:mod:`iamp.simulation.mobil`) with the lateral minimum-energy cubic."""
        dt, cfg = self.sim.step, self.cfg
        idm = replace(cfg.idm, v0=self.sim.highway.speed_limit)
        cars = self._cars(obs, ego)
        me = Car(ego.x, ego.vx, self.sim.ego_length)
        if self.mode == "seek":
            if t + 1e-9 < self.next_seek:
                return None
            self.next_seek = t + cfg.seek_every_s
            start = time.perf_counter()
            ok, reason = mobil_accepts(idm, cfg.mobil, me, cars["ol"], cars["of"], cars["nl"], cars["nf"],
                                       mandatory=self.mission.lane_end_m is not None or not self.mission.alternating)
            self.n.plan_times.append(time.perf_counter() - start)
            self.n.plans += 1
            if not ok:
                self.n.rejected["mobil-" + reason] = self.n.rejected.get("mobil-" + reason, 0) + 1
                return None
            T = cfg.decision.horizon_s
            self.lateral = FreeTrajectory.of(EgoBoundary(tf=T, x0=0.0, y0=ego.y, vx0=0.0, vy0=ego.vy, xf=0.0,
                                                         yf=self.y_target(), vxf=0.0, vyf=0.0)).cy
            self.lat_t0, self.t_end, self.mode = t, t + T, "active"
            self.n.accepted_t.append(t)
        assert self.lateral is not None
        in_target = self.sim.highway.lane_of(ego.y) == self.target
        leaders = [c for c in ((None if in_target else cars["ol"]), cars["nl"]) if c is not None]
        acc = min((idm.accel(me.v, c.x - me.x - (c.length + me.length) / 2, c.v) for c in leaders),
                  default=idm.accel(me.v))
        lo, hi = PASSENGER_CAR.ax or (-math.inf, math.inf)
        ax = float(np.clip(acc, lo, hi))
        if ego.vx + ax * dt < 0:
            ax = -ego.vx / dt
        P = np.polynomial.polynomial
        tau = min(t + dt - self.lat_t0, self.t_end - self.lat_t0)
        y, vy = float(P.polyval(tau, self.lateral)), float(P.polyval(tau, P.polyder(self.lateral)))
        ay = float(P.polyval(max(tau - dt / 2, 0.0), P.polyder(self.lateral, 2)))
        self.n.executed_plans += 1
        nxt = EgoState(x=ego.x + ego.vx * dt + ax * dt**2 / 2, vx=ego.vx + ax * dt, y=y, vy=vy, ax=ax, ay=ay)
        if t + dt >= self.t_end - 1e-9:
            self._done(t + dt)
        return nxt

    def _sumo_step(self, t: float) -> None:
        """The reference: LC2013 (or SL2015) changes lanes when it judges the gap safe."""
        if not self.requested:
            self.sim.request_lane_change(self.target, 3600.0)
            self.requested = True
            self.n.accepted_t.append(t)
            return
        if self.sim.ego_lane_index() == self.target and abs(self.sim.ego_lateral_offset()) < 0.05:
            self.sim.release()
            self._done(t)
