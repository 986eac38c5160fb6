"""One closed-loop episode: SUMO + predictor + planner, and its SPEC §11 result.

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
from iamp.simulation.metrics import StepLog, episode_metrics, percentile_stats
from iamp.simulation.planning import PLANNERS
from iamp.simulation.simulator import EgoState, Simulator
from iamp.simulation.traffic import density_of


@dataclass(frozen=True)
class EpisodeSpec:
    """What defines an episode."""

    traffic: str = "medium"
    seed: int = 1
    planner: str = "pmp"
    duration_s: float = 60.0
    period_s: float = 0.1
    warmup_s: float = 5.0
    deadline_s: float | None = 0.1

    def validate(self) -> None:
        density_of(self.traffic)
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
    """The SPEC §11 object (:attr:`summary`) and the step log behind it."""

    spec: EpisodeSpec
    summary: dict[str, Any]
    log: StepLog = field(repr=False)
    t0: float = 0.0


def run_episode(spec: EpisodeSpec, *, config: ControllerConfig | None = None) -> EpisodeResult:
    """Run one episode in this process (``libsumo`` allows one simulation per process)."""
    spec.validate()
    wall0 = time.perf_counter()
    cfg = replace(config or ControllerConfig(), deadline_s=spec.deadline_s)
    sim = Simulator(spec.traffic, spec.seed, step=spec.period_s)
    sumo_s = 0.0
    log = StepLog()
    try:
        t_start = time.perf_counter()
        sim.start()
        while sim.t < spec.warmup_s - 1e-9:
            sim.advance()
            sim.observe()
        sumo_s += time.perf_counter() - t_start
        ctl = Controller(spec.planner, sim, cfg)
        t0 = sim.t
        n_steps = int(round(spec.duration_s / spec.period_s))
        driven = False
        ego = sim.ego()
        for _ in range(n_steps):
            t = sim.t - t0
            obs = sim.observe()
            if not driven:
                ego = sim.ego()
            n_plans = ctl.n.plans
            nxt = ctl.step(t, obs, ego)
            plan_time = ctl.n.plan_times[-1] if ctl.n.plans > n_plans else math.nan
            log.t.append(t)
            log.ego.append((ego.x, ego.vx, ego.y, ego.vy, ego.ax, ego.ay))
            log.mode.append(ctl.mode if nxt is not None or ctl.name == "sumo" else "sumo")
            log.plan_time.append(plan_time)
            log.ids.append(obs.ids)
            log.nb.append(np.stack([obs.x, obs.y, obs.v, obs.a, obs.lane, obs.length, obs.width], axis=1)
                          if obs.ids else np.zeros((0, 7)))
            t_s = time.perf_counter()
            if nxt is not None:
                sim.command(nxt)
                ego, driven = nxt, True
            elif driven:
                sim.release()
                driven = False
            sim.advance()
            sumo_s += time.perf_counter() - t_s
        metrics = episode_metrics(log, spec.period_s, (sim.ego_length, sim.ego_width),
                                  (cfg.safety_x, cfg.safety_y), [(c[0] - t0, c[1], c[2]) for c in sim.collisions])
    finally:
        sim.close()
    n = ctl.n
    wall = time.perf_counter() - wall0
    summary: dict[str, Any] = {
        "planner": spec.planner, "traffic": spec.traffic, "seed": int(spec.seed),
        "duration_s": float(spec.duration_s), "period_s": float(spec.period_s),
        "lane_change_done_s": None if n.first_done_t is None else round(n.first_done_t, 10),
        "lane_changes": n.lane_changes,
        **metrics,
        "plan_time_s": percentile_stats(n.plan_times),
        "plans": n.plans, "constrained_plans": n.constrained_plans, "failed_plans": n.failed_plans,
        "late_plans": n.late_plans, "deadline_s": spec.deadline_s,
        "fallbacks": n.fallbacks, "aborts": n.aborts,
        "wall_s": {"total": wall, "sumo": sumo_s, "prediction": n.prediction_s, "planning": n.planning_s},
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    return EpisodeResult(spec, summary, log, t0)


LOG_COLUMNS = ("t", "vehicle", "x", "y", "vx", "vy", "ax", "ay", "lane", "length", "width", "mode", "plan_time_s")


def write_log(result: EpisodeResult, path: str | Path) -> None:
    """The step log as CSV, one row per vehicle and step (ego first; centres, SI units).

    Neighbours carry their speed in ``vx`` and SUMO's acceleration in ``ax``; ``vy``/``ay``
    are left empty for them.
    """
    log = result.log

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
