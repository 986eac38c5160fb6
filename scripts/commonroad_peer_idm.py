"""Run the published ``commonroad-idm-planner`` (0.2.1, PyPI) on a folder of CommonRoad scenarios.

A second peer for ``iamp commonroad bench`` (issue 33 item 6).  It runs in its OWN environment
(it needs ``commonroad-clcs``, which pins ``osqp < 1``; iamp's cvxpy needs ``osqp >= 1``):

    python -m venv /tmp/venv-cridm && /tmp/venv-cridm/bin/pip install commonroad-idm-planner
    /tmp/venv-cridm/bin/python scripts/commonroad_peer_idm.py ../shared/data/commonroad/US101 OUT_DIR

The planner is used as its own easy API does (``idm_easy_api.solve_planning_problem``: the
route planner's reference path, the IDM on it, at most 10 re-planning cycles, its steering
angles reconstructed with its default rear wheelbase) — a path-velocity decomposition that keeps
the route planner's lane and only adapts its speed.  Its states (position, velocity,
orientation, steering angle) are written unchanged as a kinematic single-track ``KS`` solution
(vehicle type 2, cost function ``WX1``): ``OUT_DIR/<scenario>.solution.xml`` for every scenario
where the planner returns a trajectory (reaching the goal or not: iamp's checker names the
failure), and ``OUT_DIR/peer.json`` (status, the planner's
own collision verdict, planning time); ``iamp commonroad bench --peer OUT_DIR`` judges and
scores them with the same checks and costs as iamp's plans.
"""

from __future__ import annotations

import json
import logging
import re
import sys
import time
import traceback
from pathlib import Path

LABEL = "idm-peer"
#: The IDM's desired speed: "default" (the package's default configuration, 30 m/s from the IDM
#: paper), "goal" (the middle of the goal's speed interval) or "timed" (the speed that covers the
#: reference path from the start to the goal's centre by the middle of the goal's time window,
#: inside the goal's speed interval); ``--desired=goal`` on the command line.
DESIRED = "default"
#: ``--headway=S``: the IDM's safe time headway (the package's default: 1.6 s, the IDM paper's).
HEADWAY: float | None = None


def _desired_speed(pp: object, reference: object, dt: float) -> float | None:
    import numpy as np

    goal = pp.goal.state_list[0]  # type: ignore[attr-defined]
    lo_hi = (goal.velocity.start, goal.velocity.end) if goal.has_value("velocity") else None
    if DESIRED == "goal" and lo_hi is not None:
        return 0.5 * (lo_hi[0] + lo_hi[1])
    if DESIRED != "timed":
        return None
    path = np.asarray(reference.reference_path, dtype=float)  # type: ignore[attr-defined]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])

    def s_of(p: object) -> float:
        return float(arc[int(np.argmin(np.linalg.norm(path - np.asarray(p, dtype=float), axis=1)))])

    shape = goal.position
    centre = np.mean([sh.center for sh in shape.shapes], axis=0) if hasattr(shape, "shapes") else shape.center
    dist = s_of(centre) - s_of(pp.initial_state.position)  # type: ignore[attr-defined]
    t_mid = 0.5 * (goal.time_step.start + goal.time_step.end) * dt
    v = max(0.5, dist / t_mid)
    if lo_hi is not None:
        v = min(max(v, lo_hi[0] + 0.2), lo_hi[1] - 0.2) if lo_hi[1] - lo_hi[0] > 0.4 else 0.5 * sum(lo_hi)
    return v


def run(path: Path, out: Path) -> dict[str, object]:
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.solution import (
        CommonRoadSolutionWriter,
        CostFunction,
        PlanningProblemSolution,
        Solution,
        VehicleModel,
        VehicleType,
    )
    from commonroad.scenario.state import KSState
    from commonroad.scenario.trajectory import Trajectory
    from commonroad_idm_planner import idm_easy_api
    from commonroad_idm_planner.configuration.planner_config import IDMConfig, IDMConfigFactory
    from commonroad_idm_planner.idm_easy_api import solve_planning_problem

    scenario, problems = CommonRoadFileReader(str(path)).open()
    pp = next(iter(problems.planning_problem_dict.values()))
    start = time.perf_counter()
    ref = idm_easy_api.generate_reference_path_from_lanelet_network_and_planning_problem(
        lanelet_network=scenario.lanelet_network, planning_problem=pp)
    v_des = _desired_speed(pp, ref, scenario.dt)

    class Factory(IDMConfigFactory):
        """The package's default configuration with the desired speed of :data:`DESIRED`."""

        @staticmethod
        def generate_default_config(ignore_static_obstacles: bool = True) -> IDMConfig:
            cfg = IDMConfigFactory.generate_default_config(ignore_static_obstacles)
            if v_des is not None:
                cfg.v_desired = v_des
            if HEADWAY is not None:
                cfg.safe_time_headway = HEADWAY
            return cfg

    idm_easy_api.IDMConfigFactory = Factory  # type: ignore[misc]
    planner = solve_planning_problem(scenario=scenario, planning_problem=pp)
    elapsed = time.perf_counter() - start
    traj = planner.trajectory_over_scenario
    collision = planner.check_collision()
    reached = bool(planner.is_goal_reached)
    row: dict[str, object] = {"scenario": path.stem, "planner": LABEL,
                              "status": "goal reached" if reached else "goal not reached",
                              "own_collision_check": bool(collision.collision_detected), "solve_time_s": elapsed,
                              "desired": DESIRED, "v_desired": v_des,
                              "headway_s": HEADWAY,
                              "steps": len(traj.state_list) - 1}
    if traj.state_list:  # written whether or not the planner reached the goal: the checker says which failure
        states = [KSState(time_step=int(s.time_step), position=s.position, velocity=float(s.velocity),
                          orientation=float(s.orientation), steering_angle=float(s.steering_angle or 0.0))
                  for s in traj.state_list]
        states[0].time_step = int(pp.initial_state.time_step)
        pps = PlanningProblemSolution(planning_problem_id=pp.planning_problem_id, vehicle_type=VehicleType.BMW_320i,
                                      vehicle_model=VehicleModel.KS, cost_function=CostFunction.WX1,
                                      trajectory=Trajectory(initial_time_step=states[0].time_step, state_list=states))
        (out / f"{path.stem}.solution.xml").write_text(
            CommonRoadSolutionWriter(Solution(scenario.scenario_id, [pps])).dump())
    return row


def main() -> int:
    global DESIRED, HEADWAY
    logging.disable(logging.WARNING)
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    for a in sys.argv[1:]:
        if a.startswith("--desired="):
            DESIRED = a.split("=", 1)[1]
        elif a.startswith("--headway="):
            HEADWAY = float(a.split("=", 1)[1])
    folder, out = Path(args[0]), Path(args[1])
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for path in sorted(folder.glob("*.xml")):
        try:
            row = run(path, out)
        except Exception as exc:  # a peer failure is a result, recorded with its reason
            said = re.sub(r"<[^>]* object at 0x[0-9a-f]+>", "the route planner", " ".join(str(exc).split()))
            row = {"scenario": path.stem, "planner": LABEL, "status": f"error: {exc.__class__.__name__}: {said}"[:300],
                   "trace": traceback.format_exc()[-1500:]}
        rows.append(row)
        sys.stderr.write(f"{path.stem}: {row['status']}\n")
        (out / "peer.json").write_text(json.dumps(rows, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
