"""One closed-loop episode: SUMO + predictor + decision layer + planner, and its SPEC §15 result.

Timeline: SUMO runs ``warmup_s`` (the traffic settles, histories fill, SUMO drives the ego
in its lane), then the episode's clock starts at 0 and the controller acts every period
for ``duration_s``.  Everything is seeded: the same ``(traffic, seed, planner)`` gives the
same trajectory and numbers; only the plan *times* are wall-clock.  A wall-clock deadline
(``deadline_s``) can make a late plan fall back, which is the one way two runs could
differ; ``late_plans`` says whether it happened (``deadline_s=None`` removes it).
"""

from __future__ import annotations

import csv
import math
import resource
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from iamp.core.atomic import atomic_open
from iamp.core.errors import ScenarioError
from iamp.simulation.controller import Controller, ControllerConfig
from iamp.simulation.metrics import StepLog, episode_geometry, episode_metrics, percentile_stats
from iamp.simulation.missions import EGO_DEPART_M, cooperation_of, courtesy_of, mission_of
from iamp.simulation.monitor import monitor
from iamp.simulation.planning import PLANNERS
from iamp.simulation.simulator import EgoState, Simulator
from iamp.simulation.traffic import density_of


@dataclass(frozen=True)
class EpisodeSpec:
    """What defines an episode (every field goes into a campaign's manifest)."""

    traffic: str = "medium"
    seed: int = 1
    planner: str = "pmp"
    mission: str = "merge"
    cooperation: str = "default"
    sublane: bool = False
    duration_s: float = 60.0
    period_s: float = 0.1
    warmup_s: float = 5.0
    settle_s: float = 8.0
    deadline_s: float | None = None
    ego_in_forecast: bool = False

    def validate(self) -> None:
        density_of(self.traffic)
        mission_of(self.mission)
        cooperation_of(self.cooperation)
        if self.planner not in PLANNERS:
            raise ScenarioError(f"unknown planner {self.planner!r}; choose from {', '.join(PLANNERS)}", "--planner")
        for name in ("duration_s", "period_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ScenarioError(f"must be positive (got {v})", f"--{name.split('_')[0]}")
        if self.warmup_s < 3.0:
            raise ScenarioError("must be at least 3 s (the histories)", "warmup_s")


@dataclass
class EpisodeResult:
    """The SPEC §15 object (:attr:`summary`) and the step log behind it."""

    spec: EpisodeSpec
    summary: dict[str, Any]
    log: StepLog = field(repr=False)
    t0: float = 0.0


def run_episode(spec: EpisodeSpec, *, config: ControllerConfig | None = None) -> EpisodeResult:
    """Run one episode in this process (``libsumo`` allows one simulation per process).

    The warm-up lasts ``warmup_s`` and until the ego's centre reaches the mission's
    ``start_x``; the mission clock then runs until ``duration_s``, or ``settle_s`` after the
    mission is done (the target lane reached, not alternating), or 3 s after the ego stood
    still at its lane's end, or at once when its front passes that end still in its lane (SUMO
    would move it; the mission has failed).
    """
    spec.validate()
    wall0 = time.perf_counter()
    mission = mission_of(spec.mission)
    cfg = replace(config or ControllerConfig(), deadline_s=spec.deadline_s,
                  ego_in_forecast=spec.ego_in_forecast or (config is not None and config.ego_in_forecast))
    hw = mission.highway()
    sim = Simulator(spec.traffic, spec.seed, step=spec.period_s, highway=hw, ego_lane=mission.ego_lane,
                    ego_pos=EGO_DEPART_M, empty_lanes=(0,) if mission.ramp else (),
                    cooperation=cooperation_of(spec.cooperation), courtesy=courtesy_of(spec.cooperation),
                    truck=(mission.truck_ahead_m, mission.truck_speed) if mission.truck else None,
                    sublane=spec.sublane)
    sumo_s = 0.0
    log = StepLog()
    ctl: Controller | None = None
    try:
        t_start = time.perf_counter()
        sim.start()
        limit_t = spec.warmup_s + 60.0
        while sim.t < spec.warmup_s - 1e-9 or (sim.ego().x < mission.start_x and sim.t < limit_t):
            sim.advance()
            sim.observe()
        sumo_s += time.perf_counter() - t_start
        ctl = Controller(spec.planner, sim, cfg, mission=mission)
        t0 = sim.t
        ego = sim.ego()
        x_start = ego.x
        n_steps = int(round(spec.duration_s / spec.period_s))
        driven = False
        lost = False
        end_at = math.inf
        still = 0.0
        for _ in range(n_steps):
            t = sim.t - t0
            if t >= end_at - 1e-9:
                break
            obs = sim.observe()
            if not driven:
                ego = sim.ego()
                if not (math.isfinite(ego.x) and abs(ego.x) < 1e5):  # SUMO took the ego off the road
                    lost = True
                    break
            n_plans = len(ctl.n.plan_times)
            nxt = ctl.step(t, obs, ego)
            wants = ctl.mode not in ("done", "hold") and hw.lane_of(ego.y) != ctl.target
            sim.signal(ctl.target if wants else None, obs, ego)  # indicator; a courteous follower yields
            plan_time = ctl.n.plan_times[-1] if len(ctl.n.plan_times) > n_plans else math.nan
            log.t.append(t)
            log.ego.append((ego.x, ego.vx, ego.y, ego.vy, ego.ax, ego.ay))
            log.mode.append(ctl.mode if nxt is not None or ctl.name == "sumo" else "sumo")
            log.plan_time.append(plan_time)
            log.ids.append(obs.ids)
            heading = obs.heading if obs.heading is not None else np.zeros(len(obs.ids))
            log.nb.append(np.stack([obs.x, obs.y, obs.v, obs.a, obs.lane, obs.length, obs.width, heading], axis=1)
                          if obs.ids else np.zeros((0, 8)))
            log.ego_heading.append(sim.ego_heading)
            if not mission.alternating and math.isinf(end_at) and hw.lane_of(ego.y) == mission.target_lane \
                    and ctl.mode in ("done", "seek", "sumo"):
                end_at = t + spec.settle_s
            if mission.drop_x is not None and ego.x + sim.ego_length / 2 > mission.drop_x \
                    and hw.lane_of(ego.y) == mission.ego_lane and math.isinf(end_at):
                end_at = t  # the front passed the end of its lane: the mission failed (SUMO would move it)
            if mission.drop_x is not None and ego.vx < 0.5 and ego.x + sim.ego_length / 2 > mission.drop_x - 30.0:
                still += spec.period_s
                if still >= 3.0 and math.isinf(end_at):
                    end_at = t
            t_s = time.perf_counter()
            if nxt is not None:
                sim.command(nxt)
                ego, driven = nxt, True
            elif driven:
                sim.release()
                driven = False
            sim.advance()
            sumo_s += time.perf_counter() - t_s
        geometry = episode_geometry(log, (sim.ego_length, sim.ego_width))  # once for both
        metrics = episode_metrics(log, spec.period_s, (sim.ego_length, sim.ego_width),
                                  (cfg.decision.safety_x, cfg.decision.safety_y),
                                  [(c[0] - t0, c[1], c[2]) for c in sim.collisions], geometry)
        measured = monitor(log, spec.period_s, (sim.ego_length, sim.ego_width), hw.lane_of, mission.target_lane,
                           mission.deadline_s, mission.drop_x, [(c[0] - t0, c[1], c[2]) for c in sim.collisions],
                           geometry=geometry)
    finally:
        sim.close()
    assert ctl is not None
    n = ctl.n
    wall = time.perf_counter() - wall0
    summary: dict[str, Any] = {
        "planner": spec.planner, "mission": spec.mission, "traffic": spec.traffic, "seed": int(spec.seed),
        "cooperation": spec.cooperation, "sublane": bool(spec.sublane),
        "duration_s": float(spec.duration_s), "period_s": float(spec.period_s),
        "simulated_s": round(len(log.t) * spec.period_s, 10),
        "distance_to_end_m": None if mission.drop_x is None else float(mission.drop_x - x_start),
        **measured,
        "ego_lost": lost,
        "lane_change_done_s": None if not n.done_t else round(n.done_t[0], 10),
        "lane_changes": n.lane_changes,
        "collisions": measured["contacts"],
        "intrusion_s": metrics["intrusion_s"], "min_gap_m": metrics["min_gap_m"],
        "min_follower_accel": metrics["min_follower_accel"],
        "rms_accel": metrics["rms_accel"], "rms_jerk": metrics["rms_jerk"],
        "plan_time_s": percentile_stats(n.plan_times),
        "plans": n.plans, "planner_calls": n.real_calls, "executed_plans": n.executed_plans,
        "constrained_plans": n.constrained_plans, "infeasible_plans": n.infeasible_plans,
        "rejected": dict(sorted(n.rejected.items())),
        "late_plans": n.late_plans, "deadline_s": spec.deadline_s,
        "fallbacks": n.fallbacks, "aborts": n.aborts,
        "ego_in_forecast": bool(cfg.ego_in_forecast), "ego_iterations": n.ego_iterations,
        "ego_converged": n.ego_converged, "ego_replans": n.ego_replans,
        "wall_s": {"total": wall, "sumo": sumo_s, "prediction": n.prediction_s, "planning": n.planning_s},
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    return EpisodeResult(spec, summary, log, t0)


LOG_COLUMNS = ("t", "vehicle", "x", "y", "vx", "vy", "ax", "ay", "lane", "length", "width", "mode", "plan_time_s")


def write_log(result: EpisodeResult | StepLog, path: str | Path) -> None:
    """The step log (of an episode, or a :class:`StepLog` as ``iamp simulate --commonroad`` keeps
    it) as CSV, one row per vehicle and step (ego first; centres, SI units).

    Neighbours carry their speed in ``vx`` and SUMO's acceleration in ``ax``; ``vy``/``ay``
    are left empty for them.
    """
    log = result if isinstance(result, StepLog) else result.log

    def f(v: float) -> str:
        return "" if not math.isfinite(v) else f"{v:.6g}"

    with atomic_open(path, "w") as fh:
        w = csv.writer(fh)
        w.writerow(LOG_COLUMNS)
        for k, t in enumerate(log.t):
            x, vx, y, vy, ax, ay = log.ego[k]
            w.writerow([f"{t:.3f}", "ego", f"{x:.4f}", f"{y:.4f}", f(vx), f(vy), f(ax), f(ay), "", "", "",
                        log.mode[k], f(log.plan_time[k])])
            for vid, row in zip(log.ids[k], log.nb[k]):
                w.writerow([f"{t:.3f}", vid, f"{row[0]:.4f}", f"{row[1]:.4f}", f(row[2]), "", f(row[3]), "",
                            int(row[4]), f(row[5]), f(row[6]), "", ""])


def ego_state_from_log(result: EpisodeResult, k: int) -> EgoState:
    x, vx, y, vy, ax, ay = result.log.ego[k]
    return EgoState(x, vx, y, vy, ax, ay)
