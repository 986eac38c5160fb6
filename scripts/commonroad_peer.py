"""Run the peer ``commonroad-reactive-planner`` (2025.1) on a folder of CommonRoad scenarios.

Runs in its OWN environment (the peer pins osqp < 1, which iamp's cvxpy cannot use):

    python -m venv /tmp/venv-crpeer && /tmp/venv-crpeer/bin/pip install commonroad-reactive-planner
    /tmp/venv-crpeer/bin/python scripts/commonroad_peer.py ../shared/data/commonroad/US101 OUT_DIR

Writes ``OUT_DIR/<scenario>.solution.xml`` (the planner's kinematic single-track ``KS`` solution,
cost function ``JB1``) for every scenario it finishes and ``OUT_DIR/peer.json`` (status and
planning time per scenario); ``iamp commonroad bench --peer OUT_DIR`` judges them with the same
checker as iamp's plans.  The planner's own example (``run_planner.py``) is followed: route
planner reference path, replanning every 3 steps, desired speed = the current speed (the 2024.1
example) or, with ``--desired=goal``, the goal interval's middle (the older example).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
import traceback
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

#: The desired speed: "current" (the package's 2024.1 example: keep the current speed), "goal"
#: (the middle of the goal's speed interval, the older example) or "timed" (fix 4 below: the speed
#: that reaches the goal's centre at the middle of its time window, kept inside the goal's speed
#: interval); ``--desired=goal`` on the command line.
DESIRED = "current"
#: The peer's label in iamp's bench table.
LABEL = "reactive-peer"
#: Fix 5 (``--smooth=F``): the smoothing factor of the reference path's spline (the package's
#: ``create_coordinate_system`` default is 2.0); ``None`` keeps the default.
SMOOTH: float | None = None


def _coordinate_system(ref_path: np.ndarray) -> object:
    from commonroad_rp.utility.utils_coordinate_system import create_coordinate_system


    if SMOOTH is None:
        return create_coordinate_system(ref_path)
    from commonroad_clcs.config import CLCSParams, ProcessingOption, ResamplingOption

    params = CLCSParams(processing_option=ProcessingOption.SPLINE_SMOOTHING)
    params.spline.degree_spline = 3
    params.spline.smoothing_factor = SMOOTH
    params.resampling.option = ResamplingOption.ADAPTIVE
    params.resampling.min_step = 0.5
    params.resampling.max_step = 1.0
    return create_coordinate_system(ref_path, params)

CONFIG = """planning:
  dt: 0.1
  replanning_frequency: 3
  time_steps_computation: 30
vehicle:
  id_type_vehicle: 2
debug:
  show_plots: False
  save_plots: False
  draw_traj_set: False
  multiproc: False
  num_workers: 1
sampling:
  t_min: 0.2
"""


def _extend(path: np.ndarray, length: float) -> np.ndarray:
    """``path`` with straight extensions of ``length`` [m] (1 m steps) along its end tangents
    (commonroad-clcs's extend_reference_path needs the lanelet network despite its signature)."""
    d0 = path[0] - path[1]
    d1 = path[-1] - path[-2]
    d0, d1 = d0 / np.linalg.norm(d0), d1 / np.linalg.norm(d1)
    k = np.arange(1.0, length + 1.0)[:, None]
    return np.vstack([path[0] + k[::-1] * d0, path, path[-1] + k * d1])


def _timed_speed(planner: object, goal: object, count: int, dt: float) -> float | None:
    """Fix 4: the reactive planner keeps a desired speed and knows no goal time; the speed that
    puts the ego at the goal's centre (arc length on the planner's own reference path) at the
    middle of the goal's time window, clipped into the goal's speed interval (0.2 m/s inside)."""
    x0 = planner.x_0  # type: ignore[attr-defined]
    cosy = planner.coordinate_system  # type: ignore[attr-defined]
    try:
        shape = goal.position  # type: ignore[attr-defined]
        centre = (np.mean([sh.center for sh in shape.shapes], axis=0) if hasattr(shape, "shapes")
                  else shape.center)
        s_goal, _ = cosy.convert_to_curvilinear_coords(float(centre[0]), float(centre[1]))
        s_ego, _ = cosy.convert_to_curvilinear_coords(float(x0.position[0]), float(x0.position[1]))
    except Exception:
        return None
    k_mid = 0.5 * (goal.time_step.start + goal.time_step.end)  # type: ignore[attr-defined]
    t_rem = (k_mid - count) * dt
    if t_rem < 0.5:
        v = float(x0.velocity)
    else:
        v = max(0.0, (s_goal - s_ego) / t_rem)
    if goal.has_value("velocity"):  # type: ignore[attr-defined]
        lo, hi = goal.velocity.start, goal.velocity.end  # type: ignore[attr-defined]
        v = min(max(v, lo + 0.2), hi - 0.2) if hi - lo > 0.4 else 0.5 * (lo + hi)
    return v


def run(path: Path, out: Path) -> dict[str, object]:
    from commonroad.common.solution import CommonRoadSolutionWriter
    from commonroad_route_planner.reference_path_planner import ReferencePathPlanner
    from commonroad_route_planner.route_planner import RoutePlanner
    from commonroad_rp.reactive_planner import ReactivePlanner
    from commonroad_rp.utility.config import ReactivePlannerConfiguration
    from commonroad_rp.utility.evaluation import create_full_solution_trajectory, create_planning_problem_solution
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "config.yaml"
        cfg.write_text(CONFIG)
        config = ReactivePlannerConfiguration.load(cfg, path.name)
    config.general.path_scenario = str(path)
    config.update()
    start = time.perf_counter()
    network = config.scenario.lanelet_network
    routes = RoutePlanner(network, config.planning_problem).plan_routes()
    ref = ReferencePathPlanner(network, config.planning_problem, routes).plan_shortest_reference_path()
    planner = ReactivePlanner(config)
    # fix 1: ReactivePlanner.set_reference_path(path) builds its CoordinateSystem without CLCS
    # parameters, which commonroad-clcs 2025.2 rejects ('NoneType' has no 'processing_option');
    # the package's own create_coordinate_system() passes its default (a smoothing spline).
    # fix 3: the route's reference path ends at the goal, and sampled trajectories that run past it
    # leave the projection domain (CurvilinearProjectionDomainLongitudinalError); extend it by
    # 100 m straight at both ends before smoothing.
    ref_path = _extend(np.asarray(ref.reference_path, dtype=float), 100.0)
    planner.set_reference_path(coordinate_system=_coordinate_system(ref_path))
    planner.record_state_and_input(planner.x_0)
    goal = config.planning_problem.goal.state_list[0]
    k_end = int(goal.time_step.end)
    optimal = None
    status = "goal reached"
    while not planner.goal_reached():
        count = len(planner.record_state_list) - 1
        if count > k_end:
            status = "goal window passed"
            break
        if count % config.planning.replanning_frequency == 0:
            timed = _timed_speed(planner, goal, count, config.planning.dt) if DESIRED == "timed" else None
            if timed is not None:
                planner.set_desired_velocity(desired_velocity=timed, current_speed=planner.x_0.velocity)
            elif DESIRED == "goal" and goal.has_value("velocity"):
                # the goal interval's middle, as the package's older example (run_planner.py 2022)
                planner.set_desired_velocity(desired_velocity=0.5 * (goal.velocity.start + goal.velocity.end),
                                             current_speed=planner.x_0.velocity)
            else:
                planner.set_desired_velocity(current_speed=planner.x_0.velocity)
            try:
                optimal = planner.plan()
            except Exception as exc:  # recorded with the step (the CLCS projection errors)
                status = f"error at step {count}: {exc.__class__.__name__}: {exc}"
                break
            if not optimal:
                reasons = {k: v for k, v in planner.infeasible_reason_dict.items() if v}
                status = (f"no feasible sample at step {count} ({planner.infeasible_count_kinematics} of "
                          f"{planner.total_count_samples} kinematically infeasible {reasons}, "
                          f"{planner.infeasible_count_collision} colliding)")
                break
            k = 1
        else:
            k = 1 + count % config.planning.replanning_frequency
        assert optimal is not None  # fix 2: plan() returns (trajectory, lon, lat), not the example's 4-tuple
        planner.record_state_and_input(optimal[0].state_list[k])
        planner.reset(initial_state_cart=planner.record_state_list[-1],
                      initial_state_curv=(optimal[1][k], optimal[2][k]),
                      collision_checker=planner.collision_checker, coordinate_system=planner.coordinate_system)
    elapsed = time.perf_counter() - start
    row: dict[str, object] = {"scenario": path.stem, "planner": LABEL, "status": status, "solve_time_s": elapsed,
                              "desired": DESIRED, "smooth": SMOOTH,
                              "steps": len(planner.record_state_list) - 1}
    if status == "goal reached":
        traj = create_full_solution_trajectory(config, planner.record_state_list)
        sol = create_planning_problem_solution(config, traj, config.scenario, config.planning_problem)
        (out / f"{path.stem}.solution.xml").write_text(CommonRoadSolutionWriter(sol).dump())
    return row


def main() -> int:
    global DESIRED, SMOOTH
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    for a in sys.argv[1:]:
        if a.startswith("--desired="):
            DESIRED = a.split("=", 1)[1]
        elif a.startswith("--smooth="):
            SMOOTH = float(a.split("=", 1)[1])
    folder, out = Path(args[0]), Path(args[1])
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for path in sorted(folder.glob("*.xml")):
        try:
            row = run(path, out)
        except Exception as exc:  # a peer failure is a result, recorded with its reason
            row = {"scenario": path.stem, "planner": LABEL, "status": f"error: {exc.__class__.__name__}: {exc}",
                   "trace": traceback.format_exc(limit=3)}
        rows.append(row)
        sys.stderr.write(f"{path.stem}: {row['status']}\n")
        (out / "peer.json").write_text(json.dumps(rows, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
