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
takes over and the ego seeks again.  With the safe loop (SPEC §17) the fail-safe brakes at the
verified deceleration only where RSS asks braking or the state one period ahead without braking
would have no verified fail-safe (:meth:`Controller._abort_now`); it ends after its first period
without braking, or once the ego's body is inside its lane's band (:meth:`Controller._in_lane`), or at
a standstill.

Prediction (batched)
--------------------
Once per period every neighbour within ``relevant_m + 20`` m in the ego's and the target lane
(SPEC §17's loop: in every lane within ``relevant_m + 60`` m, and beyond that every one within its
RSS distance of the ego plus a margin, :func:`~iamp.simulation.rss.within_rss_reach`) is
predicted; neighbours with a full history share its sample times and go through
:meth:`~iamp.prediction.predictor.Predictor.predict_batch` in one call (the cubic fitted to the
predicted path, read back at four Chebyshev points, which determine it); a neighbour seen for
less than the predictor needs is extrapolated at constant speed.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from iamp.core.physical import PASSENGER_CAR
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem
from iamp.prediction.predictor import Predictor
from iamp.simulation.decision import (
    BODY_REGION,
    DecisionConfig,
    EgoNow,
    Gap,
    Neighbour,
    candidate_gaps,
    check_problem,
    clip_scalar,
    decide,
    end_state,
    judge,
    lane_change_problem,
)
from iamp.simulation.failsafe import Obstacle, body_half_extents, feasible_brakes, verify_trajectory
from iamp.simulation.kinematics import STEER_SHARE, start_heading
from iamp.simulation.missions import Mission, mission_of
from iamp.simulation.mobil import IDM, MOBIL, Car, mobil_accepts
from iamp.simulation.planning import EQUALITY_PLANNERS, FreeTrajectory, PlanFn, free_plan, make_planner
from iamp.simulation.rss import body_extents, longitudinal_room, safe_lateral_float, within_rss_reach
from iamp.simulation.simulator import EgoState, Observation, Simulator
from iamp.simulation.tactical import (
    TacticalConfig,
    all_horizons,
    choose_gap,
    gap_end,
    horizons_for,
    names,
    proper_response,
    rss_regions,
    seek_accel,
)

#: The share of the jerk bound the tactical layer's inputs use (:meth:`Controller._move`).
JERK_SHARE = 0.9
#: The lane keeping's lateral speed toward a car RSS constrains laterally is at most this share of
#: RSS's lateral fluctuation ``μ/ρ`` (:meth:`Controller._lateral_caps`).
LATERAL_REST_SHARE = 0.8
#: A lateral gap within this of RSS's lateral distance already caps the speed toward it [m]
#: (:meth:`Controller._lateral_caps`: the cap acts before the pair is dangerous).
LATERAL_ROOM_M = 0.5
#: The lane keeping's lateral acceleration toward a car beside the ego that RSS could constrain laterally
#: is at most this share of RSS's lateral ``a_lat,max`` (:meth:`Controller._lateral_caps`): RSS allows
#: that much for a response time after the threshold, whenever the other's own lateral motion makes
#: the pair dangerous.
LATERAL_ACCEL_SHARE = 0.75

#: The share of ``κ_max`` the tactical layer's turns use (:meth:`Controller._turn_bound`): the
#: monitor measures the executed path by its chords, whose headings are the periods' mean
#: velocities, not the velocities the bound holds.
TURN_SHARE = STEER_SHARE
#: The tactical layer bounds the turn of the ego's velocity (:meth:`Controller._turn_bound`) from
#: headings within this [rad] (45°; a drivable plan ends far inside it).
MAX_TURN_HEADING = math.pi / 4


class LateralCaps(NamedTuple):
    """What RSS's lateral proper response leaves the lane keeping (:meth:`Controller._lateral_caps`):
    the largest lateral speeds to the left and to the right (magnitudes, m/s) and the largest lateral
    accelerations toward each side (m/s²; applied where the speed toward that side would exceed
    RSS's fluctuation ``μ/ρ`` share); ``inf``: unbounded."""

    left: float
    right: float
    accel_left: float = np.inf
    accel_right: float = np.inf


NO_CAPS = LateralCaps(np.inf, np.inf)


def _rest_speed(p: Any) -> float:
    """The lateral speed the lane keeping allows toward a car RSS constrains laterally:
    :data:`LATERAL_REST_SHARE` of RSS's fluctuation ``μ/ρ`` (``p``: the RSS parameters)."""
    return float(LATERAL_REST_SHARE * p.lat_margin_m / p.response_time_s)


def _toward(ego: EgoState, n: Neighbour) -> tuple[float, float]:
    """The lateral speeds of the ego and of ``n`` toward each other (``n`` on the side of the sign of
    its offset ``n.y - ego.y``; level: the right)."""
    left = n.y - ego.y > 0
    return (ego.vy, -n.vy) if left else (-ego.vy, n.vy)


def _observed_extents(nbs: Sequence[Neighbour]) -> tuple[np.ndarray, np.ndarray]:
    """The neighbours' half extents along and across the road as the judge measures them: the body at
    its observed heading (:attr:`Neighbour.now`, :func:`iamp.simulation.rss.body_extents`), else at the
    heading of its predicted velocity (:func:`~iamp.simulation.failsafe.body_half_extents`); one call
    for all (elementwise: each the number of its own call)."""
    L = np.array([n.length for n in nbs], dtype=float)
    W = np.array([n.width for n in nbs], dtype=float)
    psi = np.array([n.now[2] if n.now is not None else np.nan for n in nbs], dtype=float)
    known = np.isfinite(psi)
    if known.all():
        return body_extents(L, W, psi)
    HX, HY = body_half_extents(np.array([n.v(0.0) for n in nbs], dtype=float),
                               np.array([n.vy for n in nbs], dtype=float), L, W)
    if known.any():
        hx, hy = body_extents(L, W, np.where(known, psi, 0.0))
        HX, HY = np.where(known, hx, HX), np.where(known, hy, HY)
    return HX, HY


@dataclass(frozen=True)
class ControllerConfig:
    """Parameters of the controller (see the module docstring)."""

    decision: DecisionConfig = field(default_factory=lambda: DecisionConfig(safety_x=BODY_REGION[0],
                                                                             safety_y=BODY_REGION[1]))
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
    idm: IDM = field(default_factory=IDM)
    mobil: MOBIL = field(default_factory=MOBIL)
    #: SPEC §17: iamp drives the ego while it seeks (:mod:`iamp.simulation.tactical`), every plan
    #: is verified with the ego's body, RSS distances and a fail-safe (:mod:`iamp.simulation.failsafe`),
    #: the last verified fail-safe runs when no plan verifies, and iamp keeps the wheel after the
    #: merge (``False``: the loop before issue 30, for comparison).
    safe: bool = True
    tactical: TacticalConfig = field(default_factory=TacticalConfig)
    #: In ``active`` the committed gap is re-planned this often; every period in between the
    #: kept plan's remainder is re-verified (SPEC §17 mode only).
    replan_every_s: float = 0.3
    #: A new plan keeps this much more than ``SafeParams.margin_x`` (a kept plan is re-checked without it) [m].
    accept_margin_x: float = 1.0
    #: Gaps planned per seek (the target gap first; SPEC §17 mode only).
    seek_gaps: int = 2
    #: ``|v_y| <= max_slip v_x`` in the lane keeping (a heading within ~6°; at a standstill no
    #: lateral motion: the 53° heading of a fail-safe that stopped while moving sideways).
    max_slip: float = 0.1
    #: Lateral acceleration bound of the lane keeping in ``seek``/``failsafe``/``done`` [m/s²].
    lane_keep_ay: float = 1.5


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
    withdrawn: int = 0          # kept plans given up before the body left the origin lane (back to seeking)


def imposed(plan: Plan) -> int:
    """How many constraints the plan imposed (the active set's choice when there is one)."""
    if "active" in plan.info:
        return len(plan.info["active"])
    if plan.info.get("free"):
        return 0
    return int(getattr(plan.problem, "m", 0))


@functools.lru_cache(maxsize=64)
def _cheb(tf: float) -> tuple[np.ndarray, np.ndarray]:
    """The four Chebyshev points of ``[0, tf]`` at which a cubic is read back, and their Vandermonde
    matrix (read-only; once per horizon: the safe loop asks for one horizon every period)."""
    k = np.arange(4)
    q = tf / 2 * (1 - np.cos((2 * k + 1) * np.pi / 8))
    V = np.vander(q, 4, increasing=True)
    q.setflags(write=False)
    V.setflags(write=False)
    return q, V


class Controller:
    """Drives the ego's mission with one planner (``planning.PLANNERS``)."""

    def __init__(self, planner: str, sim: Simulator, config: ControllerConfig | None = None,
                 predictor: Predictor | None = None, mission: Mission | None = None) -> None:
        self.name = planner
        self.sim = sim
        self.cfg = config or ControllerConfig()
        if planner in EQUALITY_PLANNERS and not self.cfg.decision.equality:  # the corners in the way only
            self.cfg = replace(self.cfg, decision=replace(self.cfg.decision, equality=True))
        self.mission = mission or mission_of("discretionary")
        self.iamp = planner not in ("sumo", "mobil")
        self.plan_fn: PlanFn | None = make_planner(planner) if self.iamp else None
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
        self.target_gap: tuple[str | None, str | None] | None = None
        self.fs_brake: float | None = None   # the deceleration of the last verified fail-safe
        self.fs_braking = True  # whether the fail-safe's last period braked (:meth:`_abort_now`)
        self.fs_lane: int = self.origin
        self.prev_y: dict[str, float] = {}
        self.following = False  # iamp drives the ego in its lane (done / hold) with the tactical IDM
        #: The ego's heading [rad]: its velocity's direction when it moves, else the one it stopped
        #: with (a car keeps its heading standing, :mod:`iamp.simulation.kinematics`).
        self.heading = 0.0
        if self.cfg.ego_in_forecast and self.iamp:
            from iamp.prediction.leader.model import LeaderPredictor, default_leader_model

            self.leader_predictor = LeaderPredictor(default_leader_model())

    # -- prediction ---------------------------------------------------------------------------
    def neighbours(self, obs: Observation, ego: EgoState, tf: float, all_lanes: bool = False) -> list[Neighbour]:
        """Predicted neighbours in the ego's and the target lane (every lane with ``all_lanes``)
        near the ego (batched)."""
        start = time.perf_counter()
        lanes = (self.origin, self.target)
        xs, ln = obs.x.tolist(), obs.lane.tolist()  # Python floats: the same comparisons
        reach = self.cfg.decision.relevant_m + (60.0 if all_lanes else 20.0)
        ex = ego.x
        rss = self.cfg.tactical.safe.rss if self.cfg.safe else None
        vs, lens = obs.v.tolist(), obs.length.tolist()
        # beyond ``reach``, a vehicle within its RSS distance of the ego (a fast car from behind, a
        # slow one ahead of a fast ego: the judge sees them)
        near = [k for k in range(len(obs.ids)) if (all_lanes or ln[k] in lanes)
                and (abs(xs[k] - ex) <= reach
                     or (rss is not None and within_rss_reach(xs[k] - ex, lens[k], vs[k], ego.vx,
                                                              self.sim.ego_length, rss)))]
        polys: dict[int, tuple[float, ...]] = {}
        full: list[tuple[int, np.ndarray, np.ndarray]] = []
        need = self.predictor.min_history_s
        for k, (t, x) in zip(near, self.sim.histories_of([obs.ids[k] for k in near])):
            if t.size >= 3 and -float(t[0]) + 1e-9 >= need:
                full.append((k, t, x))
            else:
                polys[k] = (float(obs.x[k]), float(obs.v[k]), 0.0, 0.0)
        groups: dict[int, list[tuple[int, np.ndarray, np.ndarray]]] = {}
        for item in full:
            groups.setdefault(item[1].size, []).append(item)
        q, V = _cheb(float(tf))
        for items in groups.values():
            t_h = items[0][1]
            # np.allclose(t, t_h, atol=1e-6) per history, for the group in one call (the same test);
            # histories of one length are the same observation times: one shared array (histories_of)
            if all(it[1] is t_h for it in items):
                close = np.ones(len(items), dtype=bool)
            else:
                close = np.isclose(np.stack([it[1] for it in items]), t_h, atol=1e-6).all(axis=1)
            same = [it for it, ok in zip(items, close) if ok]
            rest = [it for it, ok in zip(items, close) if not ok]
            X = np.stack([it[2] for it in same])
            vals = self.predictor.predict_batch(t_h, X, q, tf, cubic=True)
            C = np.linalg.solve(V, vals.T)  # (4, B)
            for it, row in zip(same, C.T.tolist()):  # Python floats, as float() of each
                polys[it[0]] = tuple(row)
            for it in rest:  # pragma: no cover - histories with other sample times
                vals1 = self.predictor.predict_batch(it[1], it[2][None, :], q, tf, cubic=True)
                polys[it[0]] = tuple(float(c) for c in np.linalg.solve(V, vals1[0]))
        self.n.prediction_s += time.perf_counter() - start
        y, length, width, lane = obs.y.tolist(), obs.length.tolist(), obs.width.tolist(), obs.lane.tolist()
        psi = obs.heading.tolist() if obs.heading is not None else [0.0] * len(obs.ids)
        return [Neighbour(obs.ids[k], polys[k], y[k], length[k], width[k], lane[k], self._vy(obs.ids[k], y[k]),
                          now=(xs[k], vs[k] * math.cos(psi[k]), psi[k]))
                for k in near]

    def _vy(self, vid: str, y: float) -> float:
        """The neighbour's lateral speed from its last observed ``y`` (0 below 0.1 m/s)."""
        prev = self.prev_y.get(vid)
        if not self.cfg.safe or prev is None:
            return 0.0
        vy = (y - prev) / self.sim.step
        return vy if abs(vy) >= 0.1 else 0.0

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
        self.heading = start_heading(ego.vx, ego.vy, self.heading)
        if self.cfg.safe and self.name != "sumo":
            try:
                return self._safe_step(t, obs, ego)
            finally:
                self.prev_y = dict(zip(obs.ids, obs.y.tolist()))  # Python floats: float() of each
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
        return self._execute(t, dt)

    def _execute(self, t: float, dt: float) -> EgoState:
        """The state the current plan reaches at ``t + dt`` (its input at the period's middle), counted
        as an executed plan; the mission ends with the plan's last period."""
        assert self.plan is not None
        self.n.executed_plans += 1
        if imposed(self.plan) > 0:
            self.n.constrained_plans += 1
        tau, tau_u = self._period_times(t, dt)
        X = np.asarray(self.plan.require_trajectory().states(np.array([tau])))[0]
        U = np.asarray(self.plan.require_trajectory().inputs(np.array([tau_u])))[0]
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

    # -- SPEC §17: safe by construction ----------------------------------------------------------
    def _obstacles(self, nbs: list[Neighbour]) -> list[Obstacle]:
        return [Obstacle(n.name, n.poly, n.y, n.length, n.width, n.vy) for n in nbs]

    def _stop(self) -> tuple[float | None, tuple[float, float] | None]:
        """The origin lane's end as a standing obstacle across its band (merge, onramp)."""
        drop = self.mission.drop_x
        if drop is None:
            return None, None
        hw = self.sim.highway
        yc = hw.lane_centre(self.mission.ego_lane)
        return drop, (yc - hw.lane_width / 2, yc + hw.lane_width / 2)

    def _lane_centre_at(self, y: float) -> float:
        hw = self.sim.highway
        return hw.lane_centre(hw.lane_of(y))

    def _verify(self, plan: Plan, obstacles: list[Obstacle], t_from: float = 0.0, accept: bool = False
                ) -> tuple[str, float | None]:
        """``("accepted", b)`` when the plan's remainder from ``t_from`` verifies
        (:func:`~iamp.simulation.failsafe.verify_trajectory`; ``b``: the fail-safe deceleration of
        the state executed next), else ``("rss:<vehicle>", None)``.  A new plan (``accept``) must
        keep ``accept_margin_x`` more than a kept plan re-checked (hysteresis: a prediction that
        moves by less does not undo a plan the moment after it was accepted)."""
        stop_x, band = self._stop()
        params = self.cfg.tactical.safe
        if accept:
            params = replace(params, margin_x=params.margin_x + self.cfg.accept_margin_x)
        tf = float(plan.problem.tf)
        if t_from >= tf - 1e-9:
            t_from = max(tf - 1e-6, 0.0)
        v = verify_trajectory(plan.require_trajectory(), t_from, tf, obstacles,
                              (self.sim.ego_length, self.sim.ego_width), params,
                              self._lane_centre_at, stop_x, band, self.sim.step, self.sim.highway.lane_centres_of)
        return ("accepted", v.brake_next) if v.ok else (v.reason, None)

    def _continues(self, plan: Plan, ego: EgoState) -> str:
        """``"accepted"`` when the re-plan's first executed input (at half a period) is within one
        period of the jerk bound of the executed acceleration on both axes (SPEC §17: a re-plan
        continues the executed acceleration), else ``"jerk"`` (the kept plan continues instead)."""
        jerk = self.cfg.decision.limits.jerk
        if jerk is None:
            return "accepted"
        dt = self.sim.step
        U = np.asarray(plan.require_trajectory().inputs(np.array([dt / 2])))[0]
        step = jerk * dt * (1 + 1e-9)
        return "accepted" if abs(float(U[0]) - ego.ax) <= step and abs(float(U[1]) - ego.ay) <= step else "jerk"

    def _in_origin_lane(self, ego: EgoState) -> bool:
        """The ego's body (at its heading, plus ``margin_y``) is still inside its origin lane's band."""
        return self._in_lane(ego, self.origin)

    def _in_lane(self, ego: EgoState, lane: int) -> bool:
        """The ego's body (at its heading, plus ``margin_y``) is inside lane ``lane``'s band."""
        hw = self.sim.highway
        yc = hw.lane_centre(lane)
        _, hy = body_half_extents(ego.vx, ego.vy, self.sim.ego_length, self.sim.ego_width)
        return bool(abs(ego.y - yc) + float(hy) + self.cfg.tactical.safe.margin_y < hw.lane_width / 2)

    def _brakes_now(self, ego: EgoState, obstacles: list[Obstacle]) -> float | None:
        """The smallest fail-safe deceleration safe from the present state (``None``: none is)."""
        ok = self._fail_safes([ego], [0.0], obstacles)
        B = np.asarray(self.cfg.tactical.safe.brakes)
        return float(B[ok[0]][0]) if ok[0].any() else None

    def _fail_safes(self, states: Sequence[EgoState], ax: Sequence[float], obstacles: list[Obstacle]) -> np.ndarray:
        """:func:`~iamp.simulation.failsafe.feasible_brakes` of the ego's ``states``, one period apart
        from now (their longitudinal inputs ``ax``), the fail-safe keeping the lane ``fs_lane`` and
        stopping before the lane's end while in the ending lane: which decelerations are safe at each."""
        stop_x, band = self._stop()
        X = np.array([[s.x, s.vx, s.y, s.vy] for s in states])
        yfs = np.full(len(states), self.sim.highway.lane_centre(self.fs_lane))
        ok, _ = feasible_brakes(self.sim.step * np.arange(len(states)), X, np.asarray(ax, dtype=float), obstacles,
                                (self.sim.ego_length, self.sim.ego_width), self.cfg.tactical.safe, yfs, stop_x, band)
        return np.asarray(ok)

    def _lateral_caps(self, ego: EgoState, nbs: list[Neighbour]) -> LateralCaps:
        """What RSS's lateral proper response leaves the lane keeping, per side (:class:`LateralCaps`).

        The gaps are those of the bodies at their headings, as the judge measures them
        (:func:`iamp.simulation.rss.body_extents`): the ego's heading as the simulator sets it (kept
        at a standstill), the others' from their velocities
        (:func:`~iamp.simulation.failsafe.body_half_extents`).

        *Speed*: toward a vehicle beside the ego that is closer than its RSS longitudinal distance
        (so only the lateral distance keeps the pair safe) and whose lateral gap is within the RSS
        lateral distance of the speeds toward each other plus :data:`LATERAL_ROOM_M`, at most RSS's
        lateral fluctuation ``μ/ρ`` (the judge's ``rest``: :func:`iamp.simulation.rss.judge_pair`),
        with a margin, and none where the gap is already below that lateral distance; else
        unbounded.  A pair level within ``μ``, or whose bodies overlap
        sideways, caps both sides (the judge takes the roles of the dangerous run's threshold time,
        which may be a side it no longer has: a car changing lanes behind the ego crosses it).
        Without it the fail-safe's return to its lane's centre and the lane keeping after a
        withdrawn change moved at 0.3-0.9 m/s toward a car in the next lane closing from behind,
        which RSS blames on the ego.

        *Acceleration*: toward a vehicle not longitudinally safe for a response time whose lateral
        gap is within a lane width and that moves toward the ego faster than RSS's fluctuation
        ``μ/ρ`` (a lane change toward it), at most :data:`LATERAL_ACCEL_SHARE` of RSS's
        ``a_lat,max`` wherever the speed toward it would exceed the speed cap's ``μ/ρ`` share.  Such a
        pair turns dangerous by *the other's* lateral motion (its lateral speed raises the RSS lateral
        distance by up to ~0.4 m per period, faster than :data:`LATERAL_ROOM_M` foresees), and RSS
        then judges the ego's lateral acceleration toward it in that very period against
        ``a_lat,max`` (discretionary LOS E 7003 and dense 7005: the fail-safe's return to its lane
        accelerated at 0.27 and 1.5 m/s² toward a car of the lane beyond whose lane change behind it
        had begun 2-5 periods earlier at 0.6 m/s, 6.1 and 6.8 s at fault).  A car keeping its lane
        does not cap the acceleration (capped for every car within a lane width, the return to a
        lane's centre slowed in 7 of 1,800 campaign episodes, which then failed).
        """
        if not self.cfg.safe:
            return NO_CAPS
        p = self.cfg.tactical.safe.rss
        moving = p.lat_margin_m / p.response_time_s  # RSS's fluctuation μ/ρ: beyond it, a lane change
        rest = _rest_speed(p)
        accel = LATERAL_ACCEL_SHARE * p.lat_accel_max
        # the bodies at their headings, as the judge measures the gaps (:func:`iamp.simulation.rss.body_extents`):
        # the ego's as the simulator sets it (kept at a crawl: a car that stopped turned toward the next lane
        # still reaches into it, 2 m for a 4.8 m car at 33°), the others' from their velocities
        hx_e, hy_e = self._ego_half_extents()
        lane_width = self.sim.highway.lane_width
        caps = [np.inf, np.inf, np.inf, np.inf]  # speed left, right; acceleration left, right
        HX, HY = _observed_extents(nbs)
        for n, hx_n, hy_n in zip(nbs, HX.tolist(), HY.tolist()):
            x_n, v_n = n.x_now(), n.v_now()
            dx = x_n - ego.x
            lon_gap, d_lon = longitudinal_room(dx, 2 * hx_n, v_n, ego.vx, 2 * hx_e, p)
            # the gap one response time ahead at today's speeds (closing: the rear car faster)
            closing = (ego.vx - v_n) if dx > 0 else (v_n - ego.vx)
            soon = lon_gap - max(closing, 0.0) * p.response_time_s
            if lon_gap > 0 and soon >= d_lon:
                continue  # longitudinally safe, and still for a response time: no lateral constraint
            dy = n.y - ego.y
            gap = abs(dy) - (hy_n + hy_e)
            unsafe = not (lon_gap > 0 and lon_gap >= d_lon)
            if unsafe and (abs(dy) <= p.lat_margin_m or gap < 0.0):
                # level, or the bodies overlapping sideways (one may be crossing behind the other):
                # the judge's roles are those of the run's threshold time, unknown here
                return LateralCaps(rest, rest, accel, accel)
            side = 0 if dy > 0 else 1
            u_ego, u_oth = _toward(ego, n)
            if gap <= lane_width and u_oth > moving:
                caps[2 + side] = accel
            d_lat = safe_lateral_float(max(u_ego, rest), u_oth, p)
            if gap <= d_lat + LATERAL_ROOM_M:
                # unsafe: at most RSS's fluctuation; about to be (within a response time): no faster
                # than now toward it (the judge allows RSS's lateral acceleration, 0.2 m/s², for a
                # response time after the threshold; the lane keeping's return accelerated at 1.3 m/s²
                # toward a car closing from behind the step it became unsafe: slow-leader medium 45)
                cap = rest if unsafe else max(rest, u_ego)
                if unsafe and gap < d_lat:
                    # already within RSS's lateral distance: no nearer at all (RSS lets a car drift at its
                    # fluctuation; a car stopped turned toward the next lane crept its nose into a passing
                    # car that way, onramp LOS E 9003)
                    cap = 0.0
                caps[side] = min(caps[side], cap)
        return LateralCaps(*caps)

    def _ego_half_extents(self) -> tuple[float, float]:
        """The ego body's half extents along and across the road at its heading as the simulator sets
        it (kept at a crawl): ``L/2 |cos ψ| + W/2 |sin ψ|``, ``L/2 |sin ψ| + W/2 |cos ψ|``, as the judge
        measures the bodies (:func:`iamp.simulation.rss.body_extents`)."""
        psi = self.sim.ego_heading
        c, s = abs(math.cos(psi)), abs(math.sin(psi))
        Le, We = self.sim.ego_length, self.sim.ego_width
        return Le / 2 * c + We / 2 * s, Le / 2 * s + We / 2 * c

    def _front_danger(self, ego: EgoState, nbs: list[Neighbour]) -> Neighbour | None:
        """The nearest vehicle ahead with which the ego is RSS-dangerous as the rear car, as the judge
        measures it (:func:`iamp.simulation.rss.judge_pair`): the bumper gap below RSS's longitudinal
        distance of their speeds (:func:`~iamp.simulation.rss.longitudinal_room`) and the lateral gap
        of the bodies at their headings below RSS's lateral distance of their lateral speeds toward
        each other; None when there is none (or without the safe loop).  RSS's proper response is
        then the rear car's: brake with at least ``brake_min``."""
        if not self.cfg.safe:
            return None
        p = self.cfg.tactical.safe.rss
        hx_e, hy_e = self._ego_half_extents()
        found: Neighbour | None = None
        for n in nbs:
            x_n, v_n = n.x_now(), n.v_now()
            dx = x_n - ego.x
            if dx <= 0.0 or (found is not None and dx >= found.x_now() - ego.x):
                continue
            # first with the body's largest half extent at any heading (the half diagonal, plus 1 nm
            # for round-off): a gap safe with it is safe at the body's own heading
            reach = 0.5 * math.hypot(n.length, n.width) + 1e-9
            lon_lo, d_lon = longitudinal_room(dx, 2 * reach, v_n, ego.vx, 2 * hx_e, p)
            if lon_lo >= d_lon:
                continue
            if abs(n.y - ego.y) - (reach + hy_e) >= safe_lateral_float(*_toward(ego, n), p):
                continue
            HX, HY = _observed_extents([n])
            hx_n, hy_n = float(HX[0]), float(HY[0])
            lon_gap, d_lon = longitudinal_room(dx, 2 * hx_n, v_n, ego.vx, 2 * hx_e, p)
            if lon_gap >= d_lon:
                continue
            if abs(n.y - ego.y) - (hy_n + hy_e) < safe_lateral_float(*_toward(ego, n), p):
                found = n
        return found

    def _move(self, ego: EgoState, ax: float, y_c: float, urgent: bool = False,
              caps: LateralCaps = NO_CAPS) -> EgoState:
        """One period of constant input: ``a_x`` (within the car's range, never reversing) and the
        lane keeping toward ``y_c`` (bounded; at a crawl the lateral speed is only brought to 0: a car
        does not move sideways without moving forward — the abort's drift of issue 30 item 4).

        Both inputs change by at most one period of the jerk bound (SPEC §14's ``jerk``, issue 30
        item 4: the tactical layer's terms switch, e.g. the gap term at its -3 m/s² clip or IDM
        taking over after a plan at +1.5 m/s²), except that an ``urgent`` brake (a fail-safe,
        RSS's proper response) is applied at once; releasing it is rate-limited too.
        :data:`JERK_SHARE` of the bound leaves room for the 0.1 mm resolution of the positions the
        monitor differentiates twice (±0.4 m/s³)."""
        dt, cfg = self.sim.step, self.cfg
        lo, hi = PASSENGER_CAR.ax or (-6.0, 3.0)
        ax = clip_scalar(ax, lo, hi)
        jerk = cfg.decision.limits.jerk
        step = JERK_SHARE * jerk * dt if jerk is not None else np.inf
        ax = clip_scalar(ax, ego.ax - (np.inf if urgent else step), ego.ax + step)
        if ego.vx + ax * dt < 0.0:
            ax = -ego.vx / dt
        lim = cfg.lane_keep_ay
        if ego.vx < 1.0:
            ay = -ego.vy / dt
        else:  # lane keeping, rate-limited like a_x (at a crawl the lateral speed is stopped at once)
            ay = -cfg.kp * (ego.y - y_c) - cfg.kd * ego.vy
            ay = clip_scalar(ay, ego.ay - step, ego.ay + step)
        # a car moves sideways only while it moves forward: |v_y| <= tan(psi_max) v_x after the period
        cap = self.cfg.max_slip * (ego.vx + ax * dt)
        ay = clip_scalar(clip_scalar(ay, (-cap - ego.vy) / dt, (cap - ego.vy) / dt), -lim, lim)
        # a car turns only while it moves (:meth:`_turn_bound`); RSS's proper response below overrides it
        ay = self._turn_bound(ego, ax, ay)
        # RSS's lateral proper response (:meth:`_lateral_caps`): toward a side with an acceleration
        # cap, the lateral speed gains at most that cap per period once above the rest share
        rest = _rest_speed(cfg.tactical.safe.rss)
        if ego.vy + ay * dt > max(ego.vy + caps.accel_left * dt, rest):
            ay = max(min(ay, caps.accel_left), (rest - ego.vy) / dt)
        if -(ego.vy + ay * dt) > max(-ego.vy + caps.accel_right * dt, rest):
            ay = min(max(ay, -caps.accel_right), (-rest - ego.vy) / dt)
        # toward a side with a speed cap, the lateral speed is brought below it at the lane keeping's
        # bound, at once (as an urgent brake)
        if ego.vy + ay * dt > caps[0]:
            ay = max(-lim, min(ay, (caps[0] - ego.vy) / dt))
        if ego.vy + ay * dt < -caps[1]:
            ay = min(lim, max(ay, (-caps[1] - ego.vy) / dt))
        ax = self._heading_brake(ego, ax, ay)
        return EgoState(x=ego.x + ego.vx * dt + ax * dt**2 / 2, vx=ego.vx + ax * dt,
                        y=ego.y + ego.vy * dt + ay * dt**2 / 2, vy=ego.vy + ay * dt, ax=ax, ay=ay)

    def _heading_brake(self, ego: EgoState, ax: float, ay: float) -> float:
        """``a_x`` such that the velocity after the period keeps the turn bound of :meth:`_turn_bound`
        when the lateral input ``ay`` is not the one it chose (RSS's lateral proper response, or the
        lane keeping's bound, cut the lateral speed): a car's lateral speed is ``v sin ψ``, so with
        its heading turning at most :data:`TURN_SHARE` ``κ_max`` per metre it sheds lateral speed by
        braking along its heading, down to a standstill (merge medium 74: the ego, stopped at 38° to
        the road after a lane change at a crawl, restarted under a lateral cap toward a car in the
        next lane and turned on a 1 m radius).  No more than the car's brake (:data:`PASSENGER_CAR`'s
        ``a_x``); unchanged from a heading :meth:`_turn_bound` does not bound."""
        dt = self.sim.step
        vx1, vy1 = ego.vx + ax * dt, ego.vy + ay * dt
        window = self._turn_window(ego, vx1, vy1)
        if window is None:
            return ax
        psi0, turn, least = window
        psi1 = math.atan2(vy1, vx1)
        if psi0 - turn - 1e-12 <= psi1 <= psi0 + turn + 1e-12:
            return ax
        # the heading the lateral speed ``vy1`` allows: the nearest to ``ψ0`` within the smallest turn
        # (the one of a car that stops in the period, ``speed1 = 0``)
        psi = psi0 - least if psi1 < psi0 else psi0 + least
        if psi * vy1 > 0.0 and abs(psi) > 1e-9:
            vx_new = vy1 / math.tan(psi)
        else:  # a lateral speed of the other sign, or none, from a heading off the road: stop
            vx_new = 0.0
        if vx_new >= vx1:  # braking would turn it further (a lateral speed the turn bound left)
            return ax
        vx_new = max(vx_new, 0.0)
        lo = (PASSENGER_CAR.ax or (-6.0, 3.0))[0]
        return float(max((vx_new - ego.vx) / dt, lo, -ego.vx / dt))

    def _turn_window(self, ego: EgoState, vx1: float, vy1: float) -> tuple[float, float, float] | None:
        """The turn a car may make in the period to the velocity ``(vx1, vy1)``: its heading ``ψ0``
        (:func:`~iamp.simulation.kinematics.start_heading`), the largest turn, :data:`TURN_SHARE`
        ``κ_max`` times the distance travelled (the mean of both speeds times the period), and the
        turn of a car that stops in the period (its distance at half today's speed); None where no
        turn is bounded (``κ_max`` not tested, not moving forward after the period, or a heading
        beyond :data:`MAX_TURN_HEADING`, which no drivable plan leaves: handed over from SUMO)."""
        kappa = self.cfg.decision.kappa_max
        if kappa is None or vx1 <= 0.0:
            return None
        psi0 = start_heading(ego.vx, ego.vy, self.heading)
        if abs(psi0) > MAX_TURN_HEADING:
            return None
        dt, speed0 = self.sim.step, math.hypot(ego.vx, ego.vy)
        return (psi0, TURN_SHARE * kappa * 0.5 * (speed0 + math.hypot(vx1, vy1)) * dt,
                TURN_SHARE * kappa * 0.5 * speed0 * dt)

    def _turn_bound(self, ego: EgoState, ax: float, ay: float) -> float:
        """``a_y`` such that the velocity's heading turns by at most :data:`TURN_SHARE` ``κ_max`` per
        metre travelled in the period (a car turns only while it moves, :mod:`iamp.simulation.kinematics`): the
        lane keeping, the fail-safe and RSS's lateral response steer, they do not slide."""
        dt = self.sim.step
        vx1, vy1 = ego.vx + ax * dt, ego.vy + ay * dt
        window = self._turn_window(ego, vx1, vy1)
        if window is None:
            return ay
        psi0, turn, _ = window
        psi1 = math.atan2(vy1, vx1)
        if psi0 - turn <= psi1 <= psi0 + turn:
            return ay
        # the turn allowed grows with the speed after the period, and the bounded heading changes
        # that speed (``v_x / cos ψ`` at the kept ``v_x``): bounded with the least speed the kept
        # ``v_x`` allows, ``v_x`` itself, so that the turn holds at whatever speed results (the
        # window of ``psi1``'s own speed let a turn toward the road exceed the bound by 8e-6 rad
        # at v_x = 1 m/s)
        kappa = self.cfg.decision.kappa_max
        assert kappa is not None  # a window exists only with a turn bound (:meth:`_turn_window`)
        turn = TURN_SHARE * kappa * 0.5 * (math.hypot(ego.vx, ego.vy) + vx1) * dt
        bounded = min(max(psi1, psi0 - turn), psi0 + turn)
        # the longitudinal input kept: the lateral speed that puts the velocity on the bounded
        # heading, within the lane keeping's lateral bound
        lim = self.cfg.lane_keep_ay
        return clip_scalar((vx1 * math.tan(bounded) - ego.vy) / dt, -lim, lim)

    def _lane_leader(self, ego: EgoState, nbs: list[Neighbour]) -> Neighbour | None:
        """The nearest vehicle ahead whose body overlaps the ego's lane band."""
        hw = self.sim.highway
        yc = hw.lane_centre(hw.lane_of(ego.y))
        ahead = [n for n in nbs if n.x(0.0) > ego.x and abs(n.y - yc) < hw.lane_width / 2 + n.width / 2 - 0.2]
        return min(ahead, key=lambda n: n.x(0.0)) if ahead else None

    def _rss_leader(self, ego: EgoState, nbs: list[Neighbour]) -> Neighbour | None:
        """The vehicle the tactical layer follows: the nearest ahead of the lane's leader
        (:meth:`_lane_leader`) and, with the safe loop, any vehicle ahead whose lateral gap to the
        ego is below RSS's lateral distance of their lateral speeds toward each other (a car cutting
        in, its body not yet over the ego's lane: RSS's longitudinal proper response applies to it,
        the rear car braking at ``brake_min`` when closer than its longitudinal distance; slow-leader
        LOS E 69 at fault 0.2 s behind a car in the next lane drifting toward the ego's)."""
        lead = self._lane_leader(ego, nbs)
        if not self.cfg.safe:
            return lead
        p = self.cfg.tactical.safe.rss
        We = self.sim.ego_width
        for n in nbs:
            dx = n.x(0.0) - ego.x
            if dx <= 0 or (lead is not None and n.x(0.0) >= lead.x(0.0)):
                continue
            if abs(n.y - ego.y) - (n.width + We) / 2 < safe_lateral_float(*_toward(ego, n), p):
                lead = n
        return lead

    def _tactical_accel(self, ego: EgoState, nbs: list[Neighbour], lane: int, target: Gap | None = None) -> float:
        """The tactical layer's longitudinal input in lane ``lane`` (:func:`~iamp.simulation.tactical.seek_accel`:
        behind its RSS leader, the lane's end a standing obstacle while in the ending lane, and there,
        while seeking or aborting, at most a little faster than the target lane beside the ego)."""
        stop_x = self.mission.drop_x if lane == self.mission.ego_lane else None
        lane_speed = None
        if stop_x is not None and self.mode in ("seek", "abort"):  # the target lane's speed beside the ego
            beside = [n.v(0.0) for n in nbs
                      if n.lane == self.target and abs(n.x(0.0) - ego.x) <= self.cfg.tactical.match_m]
            lane_speed = float(np.mean(beside)) if beside else None
        return float(seek_accel(self.ego_now(ego), self._rss_leader(ego, nbs), stop_x, target,
                                self.sim.highway.speed_limit, self.cfg.tactical, lane_speed))

    def _follow(self, ego: EgoState, nbs: list[Neighbour], target: Gap | None = None) -> EgoState:
        """The tactical IDM in the ego's lane (the lane's end a standing obstacle while in it)."""
        hw = self.sim.highway
        lane = hw.lane_of(ego.y)
        a = self._tactical_accel(ego, nbs, lane, target)
        if self._front_danger(ego, nbs) is not None:  # RSS-dangerous as the judge measures it
            a = min(a, -self.cfg.tactical.safe.rss.brake_min)
        urgent = a <= -self.cfg.tactical.safe.rss.brake_min  # RSS's proper response (or harder)
        return self._move(ego, a, hw.lane_centre(lane), urgent, self._lateral_caps(ego, nbs))

    def _safe_step(self, t: float, obs: Observation, ego: EgoState) -> EgoState | None:
        """One period of the SPEC §17 loop (module docstring)."""
        dt, cfg, tac = self.sim.step, self.cfg.decision, self.cfg.tactical
        en = self.ego_now(ego)
        nbs = self.neighbours(obs, ego, max(all_horizons(en, tac)), all_lanes=True)
        if self.mode in ("done", "hold"):
            if self.mode == "hold" and t + 1e-9 >= self.hold_until:
                self.origin, self.target = self.target, self.origin
                self.mode, self.next_seek, self.target_gap = "seek", t, None
            else:
                return self._follow(ego, nbs)
        if self.mode == "abort":  # the last verified fail-safe
            nxt = self._abort_now(ego, self._obstacles(nbs), nbs)
            # ended after a period it did not need to brake (Pek & Althoff: the fail-safe runs while no
            # other input keeps a verified fail-safe; from there the ego seeks again, as after a
            # standstill, and the lane keeping returns it), back in its lane (the body with margin_y
            # inside its band, the test of a withdrawn change), or stopped (it cannot move sideways
            # standing)
            if self._in_lane(ego, self.fs_lane) or ego.vx < 0.5 or not self.fs_braking:
                if self.fs_lane == self.target:
                    self._done(t + dt)
                else:
                    self.mode, self.next_seek = "seek", t + dt
            return nxt
        if self.name == "mobil":
            return self._mobil_safe(t, obs, ego, nbs)
        if self.mode == "seek":
            target = [n for n in nbs if n.lane == self.target]
            wide = replace(cfg, max_gaps=10, relevant_m=cfg.relevant_m + 40.0, rss=tac.safe.rss)
            gaps = [self._with_lane_speed(g) for g in candidate_gaps(en, target, wide)]
            drop = self.mission.drop_x
            x_limit = None if drop is None else drop - self.sim.ego_length
            chosen = choose_gap(en, gaps, self.target_gap, tac, x_limit)
            self.target_gap = names(chosen) if chosen is not None else None
            if t + 1e-9 < self.next_seek:
                return self._follow(ego, nbs, chosen)
            self.next_seek = t + self.cfg.seek_every_s
            if self.cfg.safe:
                # RSS's lateral proper response toward the target lane's side (:meth:`_lateral_caps`):
                # a lane change does not start while a vehicle RSS constrains laterally on that side (or
                # level with the ego: a tailgater in its lane, who may change lanes too) holds it
                left = self.y_target() > ego.y
                cap = self._lateral_caps(ego, nbs)[0 if left else 1]
                if np.isfinite(cap):
                    self._reject("rss-lateral")
                    return self._follow(ego, nbs, chosen)
                if self._front_danger(ego, nbs) is not None:
                    # nor while RSS asks the ego to brake behind a vehicle ahead (the following brakes)
                    self._reject("rss-front")
                    return self._follow(ego, nbs, chosen)
            # the verification's road users (built where a plan is verified: not needed to follow in lane)
            obstacles = self._obstacles(nbs)
            order = ([chosen] if chosen is not None else []) + [g for g in gaps  # candidate_gaps(en, target, wide)
                                                                 if chosen is None or names(g) != names(chosen)]
            cur = [n for n in nbs if n.lane == self.origin]
            verdict, all_v = decide(en, self.y_target(), self.target, self.origin, cur + target, self._plan, cfg,
                                    verify=lambda p: self._verify(p, obstacles, accept=True)[0],
                                    ends=lambda g: horizons_for(en, g, cfg, tac, a0=ego.ax,
                                                                dy=self.y_target() - ego.y),
                                    gaps=order[: self.cfg.seek_gaps],
                                    region=rss_regions(en, tac), heading=self.heading)
            for v in all_v:
                if not v.accepted:
                    self._reject(v.reason)
            if not verdict.accepted or verdict.plan is None or verdict.plan.info.get("late"):
                return self._follow(ego, nbs, chosen)
            gap = verdict.gap or Gap(None, None)
            self.committed = names(gap)
            self.mode, self.plan, self.plan_t0 = "active", verdict.plan, t
            self.t_end = t + float(verdict.plan.problem.tf)
            self.next_seek = t + self.cfg.replan_every_s
            self.fs_brake = self._verify(verdict.plan, obstacles)[1]
            self.n.accepted_t.append(t)
        else:
            assert self.plan is not None
            obstacles = self._obstacles(nbs)
            tf = self.t_end - t
            kept = False
            due = t + 1e-9 >= self.next_seek
            if tf > self.cfg.min_replan_s and due:
                self.next_seek = t + self.cfg.replan_every_s
                gap = self._with_lane_speed(self._committed_gap(en, nbs))
                cur = [n for n in nbs if n.lane == self.origin and n.x(0.0) > ego.x
                       and n.x(0.0) - ego.x <= cfg.relevant_m]
                lead = min(cur, key=lambda n: n.x(0.0)) if cur else None
                end = gap_end(en, gap, tf, cfg, tac, a0=ego.ax, dy=self.y_target() - ego.y)
                reason = "no-safe-end"
                if end is not None:
                    dcfg = replace(cfg, horizon_s=tf)
                    prob = lane_change_problem(en, self.y_target(), gap, lead, dcfg, tf, end, rss_regions(en, tac))
                    plan = self._plan(prob)
                    reason = judge(plan, None, dcfg, lambda p: self._verify(p, obstacles)[0], self.heading)
                    if reason == "accepted":
                        reason = self._continues(plan, ego)
                    if reason == "accepted" and not plan.info.get("late"):
                        self.plan, self.plan_t0, kept = plan, t, True
                        self.fs_brake = self._verify(plan, obstacles)[1]
                if not kept:
                    self._reject(reason)
                    self.n.fallbacks += 1
            if not kept:  # the kept plan's remainder, re-verified against the fresh predictions
                ok, b = self._verify(self.plan, obstacles, t - self.plan_t0)
                if ok != "accepted" and self._in_origin_lane(ego):
                    # the body has not reached the target lane: withdraw to seeking (the tactical IDM
                    # in the lane is the fail-safe there)
                    self.mode, self.plan, self.next_seek = "seek", None, t + self.cfg.seek_every_s
                    self.n.withdrawn += 1
                    return self._follow(ego, nbs)
                if ok != "accepted":
                    self.mode, self.plan = "abort", None
                    self.fs_lane = self.sim.highway.lane_of(ego.y)
                    self.n.aborts += 1
                    return self._abort_now(ego, obstacles, nbs)
                self.fs_brake = b if b is not None else self.fs_brake
            if self._front_danger(ego, nbs) is not None and self._plan_accel(t) > -self.cfg.tactical.safe.rss.brake_min:
                # RSS-dangerous behind a vehicle ahead (it braked, or the ego closed in during the change)
                # and the plan does not brake with RSS's proper response: the fail-safe does (the
                # verification lets a leader already too close come no closer, RSS asks the rear car to
                # brake: discretionary light 7105, 1.4-2.5 s at fault 80 m behind a car slowing at 35 m/s)
                self._reject("rss-front")
                if self._in_origin_lane(ego):
                    self.mode, self.plan, self.next_seek = "seek", None, t + self.cfg.seek_every_s
                    self.n.withdrawn += 1
                    return self._follow(ego, nbs)
                self.mode, self.plan = "abort", None
                self.fs_lane = self.sim.highway.lane_of(ego.y)
                self.n.aborts += 1
                return self._abort_now(ego, obstacles, nbs)
        return self._execute(t, dt)

    def _committed_gap(self, en: EgoNow, nbs: list[Neighbour]) -> Gap:
        """The committed gap now (SPEC §17's loop): its follower and leader by name, and where the
        change was committed with an open end (no follower, or no leader) the target lane's vehicle
        that bounds the gap there now.  The seek delimits gaps by the target lane's vehicles near the
        ego (:func:`~iamp.simulation.decision.candidate_gaps`: within ``relevant_m + 40`` m or their
        RSS reach); a slower car far ahead, or a faster one far behind, comes near during the change.
        It then bounds the gap as it would bound a gap chosen now (the gap of the partition whose
        named end is the committed one; with both ends open, the gap around the ego), and it stays
        committed by name.  Before, the re-plan kept planning into the open end and ignored it, and only
        the re-verification saw it: merge light 30004 aborted twice halfway across, behind a car
        braking 120 m ahead and then in front of one closing from 110 m behind, and stopped at the
        lane's end."""
        f_name, l_name = self.committed
        by = {n.name: n for n in nbs}
        gap = Gap(by.get(f_name or ""), by.get(l_name or ""))
        if f_name is not None and l_name is not None:
            return gap
        cfg, tac = self.cfg.decision, self.cfg.tactical
        target = [n for n in nbs if n.lane == self.target]
        wide = replace(cfg, max_gaps=len(target) + 1, relevant_m=cfg.relevant_m + 40.0, rss=tac.safe.rss)
        for g in candidate_gaps(en, target, wide):
            gf, gl = names(g)
            if f_name is not None:
                match = gf == f_name
            elif l_name is not None:
                match = gl == l_name
            else:
                match = ((g.follower is None or g.follower.x(0.0) <= en.x)
                         and (g.leader is None or g.leader.x(0.0) > en.x))
            if match:
                self.committed = (gf, gl)
                return g
        return gap

    def _with_lane_speed(self, gap: Gap) -> Gap:
        """``gap`` with the lane's speed where it has neither follower nor leader: the road's speed
        limit (:class:`~iamp.simulation.decision.Gap`; a plan into an empty lane ends at the speed
        traffic from beyond the view arrives at, as far as it can reach it)."""
        if gap.follower is None and gap.leader is None:
            return replace(gap, speed=float(self.sim.highway.speed_limit))
        return gap

    def _period_times(self, t: float, dt: float) -> tuple[float, float]:
        """Plan times of the period from ``t``: its end (the state :meth:`_execute` reaches, at most the
        plan's horizon) and its middle (the input applied, at least 0)."""
        assert self.plan is not None
        tau = min(t + dt - self.plan_t0, float(self.plan.problem.tf))
        return tau, max(tau - dt / 2, 0.0)

    def _plan_accel(self, t: float) -> float:
        """The plan's longitudinal input over the period from ``t``, as :meth:`_execute` applies it."""
        assert self.plan is not None
        tau_u = self._period_times(t, self.sim.step)[1]
        return float(np.asarray(self.plan.require_trajectory().inputs(np.array([tau_u])))[0, 0])

    def _abort_now(self, ego: EgoState, obstacles: list[Obstacle], nbs: list[Neighbour]) -> EgoState:
        """One period of the fail-safe (its first, and each while aborting), back toward the centre
        of the lane ``fs_lane``: brake at the last verified deceleration, at least RSS's proper
        response; but where RSS asks no braking (:meth:`_proper_brake` is 0) and the state one
        period ahead without braking (the tactical layer's deceleration in that lane, or none) still
        has a verified fail-safe (:func:`~iamp.simulation.failsafe.feasible_brakes` at that state),
        that period is driven instead (Pek & Althoff's online verification: any input whose next
        state has a verified fail-safe may be applied; the fail-safe runs when none has) and the
        fail-safe ends after it (:attr:`fs_braking` False; :meth:`_safe_step`).  Braking
        to a standstill when nothing asks for it stopped the ego on the highway with cars closing
        from behind, its lateral return slowed by RSS's lateral caps beside them (slow-leader light
        29006: from 9.9 m/s to 0.4 m/s in 6.3 s, 1.2 m from the lane's centre, the change then late)."""
        b = self._brakes_now(ego, obstacles)
        if b is not None:
            self.fs_brake = b
        proper = self._proper_brake(ego, nbs)
        b = max(self.fs_brake if self.fs_brake is not None else 3.5, proper)
        y_c = self.sim.highway.lane_centre(self.fs_lane)
        caps = self._lateral_caps(ego, nbs)
        if proper <= 0.0:
            a = min(0.0, self._tactical_accel(ego, nbs, self.fs_lane))
            if a > -b:
                nxt = self._move(ego, a, y_c, caps=caps)
                if self._failsafe_after(ego, nxt, obstacles):
                    self.fs_braking = False
                    return nxt
        self.fs_braking = True
        return self._move(ego, -b, y_c, urgent=True, caps=caps)

    def _failsafe_after(self, ego: EgoState, nxt: EgoState, obstacles: list[Obstacle]) -> bool:
        """Whether the state ``nxt`` one period ahead of ``ego`` has a verified fail-safe
        (:meth:`_fail_safes` of both states: the first decides which vehicles already shared the lane)."""
        return bool(self._fail_safes([ego, nxt], [ego.ax, nxt.ax], obstacles)[1].any())

    def _proper_brake(self, ego: EgoState, nbs: list[Neighbour]) -> float:
        """RSS's longitudinal proper response during the fail-safe: ``brake_min`` while the vehicle
        the tactical layer follows (:meth:`_rss_leader`) is closer than RSS's distance, else 0 (the
        fail-safe's own deceleration, verified against the others' admissible braking, may be
        gentler than the response RSS asks of the rear car: merge light 68, 2.3 s at fault braking
        at 1.5 m/s² behind a car 69 m ahead where RSS asked 72 m)."""
        if not self.cfg.safe:
            return 0.0
        p = self.cfg.tactical.safe.rss
        if self._front_danger(ego, nbs) is not None:  # dangerous as the judge measures it
            return float(p.brake_min)
        return proper_response(self.ego_now(ego), self._rss_leader(ego, nbs), p)

    def _mobil_safe(self, t: float, obs: Observation, ego: EgoState, nbs: list[Neighbour]) -> EgoState | None:
        """IDM + MOBIL for a mandatory change (:mod:`iamp.simulation.mobil`): IDM drives the ego in
        its lane behind its leader and the lane's end (a standing virtual obstacle) while MOBIL
        is asked every ``seek_every_s``; then the lateral cubic with IDM behind the nearer leader."""
        if self.mode == "seek":
            if t + 1e-9 >= self.next_seek:
                self.next_seek = t + self.cfg.seek_every_s
                if self._mobil_decide(t, obs, ego):
                    return self._mobil_step(t, obs, ego)
            return self._follow_idm(ego, nbs)
        return self._mobil_step(t, obs, ego)

    def _follow_idm(self, ego: EgoState, nbs: list[Neighbour]) -> EgoState:
        """Treiber's IDM (:attr:`ControllerConfig.idm`) in the ego's lane, the lane's end a standing
        obstacle while in it (the MOBIL baseline's longitudinal model)."""
        hw = self.sim.highway
        lane = hw.lane_of(ego.y)
        idm = replace(self.cfg.idm, v0=hw.speed_limit)
        lead = self._lane_leader(ego, nbs)
        acc = [idm.accel(ego.vx)]
        if lead is not None:
            acc.append(idm.accel(ego.vx, lead.x(0.0) - ego.x - (lead.length + self.sim.ego_length) / 2,
                                 lead.v(0.0)))
        if self.mission.drop_x is not None and lane == self.mission.ego_lane:
            acc.append(idm.accel(ego.vx, self.mission.drop_x - ego.x - self.sim.ego_length / 2, 0.0))
        return self._move(ego, min(acc), hw.lane_centre(lane))

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
            if not self._mobil_decide(t, obs, ego):
                return None
        assert self.lateral is not None
        in_target = self.sim.highway.lane_of(ego.y) == self.target
        leaders = [c for c in ((None if in_target else cars["ol"]), cars["nl"]) if c is not None]
        if cfg.safe and not in_target and self.mission.drop_x is not None:  # the lane's end: a standing obstacle
            leaders.append(Car(self.mission.drop_x + self.sim.ego_length / 2, 0.0, self.sim.ego_length))
        acc = min((idm.accel(me.v, c.x - me.x - (c.length + me.length) / 2, c.v) for c in leaders),
                  default=idm.accel(me.v))
        lo, hi = PASSENGER_CAR.ax or (-math.inf, math.inf)
        ax = clip_scalar(acc, lo, hi)
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

    def _mobil_decide(self, t: float, obs: Observation, ego: EgoState) -> bool:
        """Ask MOBIL about the adjacent gap; on acceptance start the lateral cubic (mode ``active``)."""
        cfg = self.cfg
        idm = replace(cfg.idm, v0=self.sim.highway.speed_limit)
        cars = self._cars(obs, ego)
        me = Car(ego.x, ego.vx, self.sim.ego_length)
        start = time.perf_counter()
        ok, reason = mobil_accepts(idm, cfg.mobil, me, cars["ol"], cars["of"], cars["nl"], cars["nf"],
                                   mandatory=self.mission.lane_end_m is not None or not self.mission.alternating,
                                   lane_end=self.mission.drop_x if cfg.safe else None, biased=cfg.safe)
        self.n.plan_times.append(time.perf_counter() - start)
        self.n.plans += 1
        if not ok:
            self.n.rejected["mobil-" + reason] = self.n.rejected.get("mobil-" + reason, 0) + 1
            return False
        T = cfg.decision.horizon_s
        self.lateral = FreeTrajectory.of(EgoBoundary(tf=T, x0=0.0, y0=ego.y, vx0=0.0, vy0=ego.vy, xf=0.0,
                                                     yf=self.y_target(), vxf=0.0, vyf=0.0)).cy
        self.lat_t0, self.t_end, self.mode = t, t + T, "active"
        self.n.accepted_t.append(t)
        return True

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
