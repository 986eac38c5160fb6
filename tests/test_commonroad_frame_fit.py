"""The road frame near the ego where the chain of its lanelets does not fit one path (SPEC §16).

The frame's path is one polynomial fitted to the centre line of the ego's chain of lanelets
(:func:`iamp.commonroad.convert.road_frame`).  On DEU_A9-1_2 (public hand-crafted CommonRoad scene)
that chain is an on-ramp's curve followed by a straight lanelet of 2 km: the fit left the centre
line by 44 m, the lanes ran across the frame, and the plan of a goal without a position (keep the
ego's lane) crossed four lanes and left CommonRoad's road.  The frame is now fitted to the stretch
the ego can reach when the whole chain's fit leaves more than ``FRAME_TOL_M``.  The scene here is
built the same way (a ramp turning 0.9 rad into the right lane of a straight 3-lane road of
2 km); CommonRoad's own checker judges the plan.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import needs_commonroad

LANE_W = 3.6


def _ramp_centre(radius: float, turn: float, length: float) -> np.ndarray:
    """A ramp's centre line turning left by ``turn`` rad on a circle of ``radius`` into a straight
    line along ``x`` from the origin to ``length`` (a vertex every 50 m, as maps give them)."""
    phi = np.linspace(-turn, 0.0, 25)
    ramp = np.column_stack([radius * np.sin(phi), radius - radius * np.cos(phi)])
    x = np.r_[np.arange(50.0, length, 50.0), length]
    return np.vstack([ramp, np.column_stack([x, np.zeros(x.size)])])


def test_a_chain_that_one_path_fits_keeps_that_path() -> None:
    """A nearly straight chain (within FRAME_TOL_M of the whole fit): the frame is the whole
    chain's fit, as before, with no note."""
    from iamp.commonroad.convert import FRAME_TOL_M, road_frame
    from iamp.commonroad.frame import RoadFrame

    x = np.linspace(0.0, 400.0, 41)
    centre = np.column_stack([x, 0.5 * (x / 100.0) ** 2])
    frame, res, note = road_frame(centre, centre[3], 200.0)
    assert note is None and res <= FRAME_TOL_M
    assert frame == RoadFrame.fit(centre, degree=5)


@pytest.mark.parametrize("radius,turn,start_x", [(120.0, 0.9, 10.0), (80.0, 0.6, 40.0), (200.0, 1.2, 0.0)])
def test_a_ramp_before_a_long_road_is_fitted_near_the_ego(radius: float, turn: float, start_x: float) -> None:
    """A ramp's curve before 2 km of straight road: the whole chain's fit leaves metres; the frame
    returned is fitted near the ego and leaves the centre line much less there, its own residual
    reported, the round trip exact and the note naming both fits."""
    from iamp.commonroad.convert import FRAME_BEHIND_M, FRAME_TOL_M, densify, road_frame
    from iamp.commonroad.frame import RoadFrame

    centre = _ramp_centre(radius, turn, 2000.0)
    whole = RoadFrame.fit(centre, degree=5)
    whole_res = float(np.max(np.abs(whole.to_road(centre)[:, 1])))
    assert whole_res > 3 * FRAME_TOL_M  # the premise: one polynomial does not follow this chain
    start = np.array([start_x, 0.0])
    frame, res, note = road_frame(centre, start, 200.0)
    assert note is not None and f"{whole_res:.2f} m" in note and f"{res:.2f} m" in note
    assert f"from {FRAME_BEHIND_M:.0f} m behind it to 250 m ahead" in note  # reach 200 m + 50 m
    assert ("more than 1 m" in note) is (res > FRAME_TOL_M)
    dense = densify(centre, 1.0)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))]
    a0 = arc[np.argmin(np.linalg.norm(dense - start, axis=1))]
    near = dense[(arc >= a0 - FRAME_BEHIND_M) & (arc <= a0 + 250.0)]
    got = np.abs(frame.to_road(near)[:, 1])
    assert float(np.max(got)) == pytest.approx(res, abs=1e-9)
    assert res < 0.5 * float(np.max(np.abs(whole.to_road(near)[:, 1])))
    # where the ego drives (its start and 200 m ahead) the frame follows the lane closely
    ahead = near[np.linalg.norm(near - start, axis=1) < 200.0]
    ahead = ahead[ahead[:, 0] >= start_x]
    assert float(np.max(np.abs(frame.to_road(ahead)[:, 1]))) < FRAME_TOL_M
    sd = frame.to_road(near)
    assert np.allclose(frame.to_world(sd[:, 0], sd[:, 1]), near, atol=1e-6)


def _scene(path: Path, radius: float = 120.0, turn: float = 0.9, length: float = 2000.0) -> Path:
    """The ramp (lanelet 200, turning ``turn`` rad left into lane 100) and three straight lanes of
    ``length`` m (100-102, adjacent); the ego on lane 100 at x = 10 m at 20 m/s heading along the
    road; the goal the time step 40 only (keep the lane)."""
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.common.util import Interval
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork, LaneletType
    from commonroad.scenario.scenario import Scenario, ScenarioID
    from commonroad.scenario.state import CustomState, InitialState

    def straight(d: float) -> np.ndarray:
        x = np.r_[np.arange(0.0, length, 50.0), length]
        return np.column_stack([x, np.full(x.size, d) + 0.3 * (x / 1000.0) ** 2])

    lanes = []
    for i in range(3):
        r, l_ = straight(i * LANE_W), straight((i + 1) * LANE_W)
        lanes.append(Lanelet(l_, 0.5 * (l_ + r), r, 100 + i, predecessor=[200] if i == 0 else None,
                             adjacent_left=101 + i if i < 2 else None, adjacent_left_same_direction=(i < 2) or None,
                             adjacent_right=99 + i if i > 0 else None, adjacent_right_same_direction=(i > 0) or None,
                             lanelet_type={LaneletType.HIGHWAY}))
    phi = np.linspace(-turn, 0.0, 25)

    def arc(d: float) -> np.ndarray:  # ``d`` to the left of the ramp's centre line
        rr = radius - d
        return np.column_stack([rr * np.sin(phi), 0.5 * LANE_W + radius - rr * np.cos(phi)])

    c_r, c_l = arc(-0.5 * LANE_W), arc(0.5 * LANE_W)
    c_r[-1], c_l[-1] = lanes[0].right_vertices[0], lanes[0].left_vertices[0]
    ramp = Lanelet(c_l, 0.5 * (c_l + c_r), c_r, 200, successor=[100], lanelet_type={LaneletType.ACCESS_RAMP})
    scenario = Scenario(0.1, ScenarioID(country_id="ZAM", map_name="IampRamp", map_id=1))
    scenario.add_objects(LaneletNetwork.create_from_lanelet_list([ramp, *lanes]))
    ego0 = InitialState(time_step=0, position=np.array([10.0, 0.5 * LANE_W]), orientation=0.0, velocity=20.0,
                        yaw_rate=0.0, slip_angle=0.0)
    pp = PlanningProblem(1, ego0, GoalRegion([CustomState(time_step=Interval(40, 40))]))
    CommonRoadFileWriter(scenario, PlanningProblemSet([pp]), "iamp tests", "", "", set()).write_to_file(
        str(path), OverwriteExistingFile.ALWAYS)
    return path


@needs_commonroad
def test_the_lane_is_kept_on_a_road_after_a_ramp(tmp_path: Path) -> None:
    """The goal keeps the ego's lane: the plan ends in lane 100 in the world (fitted to the whole
    chain, the frame's lane ran across the road and the plan left CommonRoad's road), is
    ``optimal`` and valid by CommonRoad's checker, its road-boundary check included."""
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan
    from iamp.commonroad.solution import build_solution

    cr = load(_scene(tmp_path / "ramp.xml"))
    assert any("fitted to the ego's lane" in n for n in cr.notes)
    # the chain's end, 2 km ahead, lies beyond the frame's path: the road does not end for the goal
    # (measured on the extrapolated path it was put at s = 670 m)
    assert cr.goal.s_max == float("inf")
    # the corridor: the three lanes (about -2 to 9 m), no map point from beyond the frame's reach
    assert -3.0 < cr.road_y[0] < 0.0 and 8.0 < cr.road_y[1] < 10.0
    rp = plan(cr)
    assert rp.status == "optimal" and rp.trajectory is not None and rp.candidate is not None
    X = rp.trajectory.states(np.array([rp.candidate.tf]))[0]
    end = cr.frame.to_world(X[0], X[2]).reshape(-1)
    assert 0.0 < end[1] - 0.3 * (end[0] / 1000.0) ** 2 < LANE_W  # in lane 100
    sol, _ = build_solution(cr, rp.trajectory, rp.candidate.steps)
    verdict = check(cr.scenario, cr.planning_problem_set, sol, cost=False)
    assert verdict.valid, verdict


@pytest.mark.parametrize(("goal", "collisions", "off_road", "success"),
                         [(True, 0, 0, True), (True, 0, 5, False), (True, 1, 0, False), (False, 0, 0, False)])
def test_an_episode_with_a_body_off_the_road_is_no_success(goal: bool, collisions: int, off_road: int,
                                                           success: bool) -> None:
    """DEU_A9-1_2 (public interactive scene) reached its goal with five executed steps off
    CommonRoad's road and was called a success: the rule now needs every executed body on it."""
    from iamp.commonroad.interactive import succeeded

    assert succeeded(goal, collisions, off_road) is success


def test_the_text_names_the_steps_off_the_road_and_the_exit_is_5(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("commonroad")
    import iamp.commonroad
    import iamp.commonroad.interactive as interactive
    from iamp.cli.main import main

    record = {"scenario": "S", "status": "goal reached", "time_to_goal_s": 4.0, "goal_window_s": [4.0, 4.0],
              "collisions": 0, "min_ttc_s": 6.8, "ego_peak_accel": 6.0, "infeasible_plans": 8, "fallbacks": 0,
              "plan_time_s": {"median": 0.3}, "sumo_vs_recording": None, "off_road_steps": 5,
              "off_road_times_s": [3.0, 3.4], "success": interactive.succeeded(True, 0, 5)}
    monkeypatch.setattr(interactive, "simulate_with_log", lambda folder, planner, **kw: (record, None))
    monkeypatch.setattr(iamp.commonroad, "require", lambda *a, **k: None)
    monkeypatch.setattr("iamp.cli.simulate._responsibility_lines", lambda r: [])
    assert main(["simulate", "--commonroad", str(tmp_path)]) == 5
    out = capsys.readouterr().out
    assert "off road  5 executed steps at 3.0-3.4 s" in out


def test_sumo_refusing_the_ego_is_one_line_and_exit_2(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The public RUS_Bicycle-11_1: SUMO refuses to insert the ego (the scene's default vehicle type
    is a bicycle slower than the ego's initial speed) and the loop ended in "internal error"; now
    one line naming the scene file and the field, SUMO's reason, exit 2.  SUMO's refusal is
    reproduced on a shared scene by a ``vehicle.add`` that raises as SUMO's does."""
    pytest.importorskip("commonroad")
    from conftest import data_path

    folder = data_path("commonroad", "interactive-US101", "USA_US101-11_1_I-1-1")
    if not folder.is_dir():
        pytest.skip(f"the shared CommonRoad data is absent ({folder})")
    import iamp.commonroad.interactive as interactive
    from iamp.cli.main import main

    try:
        traci, sumolib = interactive._sumo()
    except Exception as exc:  # the [sim] extra absent
        pytest.skip(str(exc))

    class Refusing:
        def __getattr__(self, name: str):  # type: ignore[no-untyped-def]
            return getattr(traci.vehicle, name)

        def add(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            raise traci.TraCIException("Vehicle 'ego' has no valid route (Departure speed for vehicle 'ego' is "
                                       "too high for the vehicle type 'bicycle'.)")

    class Wrapped:
        vehicle = Refusing()

        def __getattr__(self, name: str):  # type: ignore[no-untyped-def]
            return getattr(traci, name)

    monkeypatch.setattr(interactive, "_sumo", lambda: (Wrapped(), sumolib))
    assert main(["simulate", "--commonroad", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "SUMO refuses to insert the ego" in err[0] and "bicycle" in err[0]
    assert "planningProblem.initialState" in err[0] and "Traceback" not in err[0]
