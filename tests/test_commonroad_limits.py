"""The CommonRoad road planner's limits: a plan that reverses is not within them, and a point-mass
start at rest is noted.

Found on the public urban NGSIM problems (Peachtree, Lankershim; ``github.com/seungju-k1m/CommonRoad``):
USA_Peach-4_8's goal lies 36 m behind the ego, which starts at rest; the unconstrained cubic
reaches it by reversing at up to 10 m/s, no vehicle's box was entered in the road frame (the
body's heading there is read from ``max(v_s, 1e-6)``), and the plan was reported ``optimal``
while CommonRoad's checker, whose ``PM`` body points along the velocity, found a collision.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import needs_commonroad
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.commonroad.goal import Candidate
from iamp.commonroad.planning import LIMIT_SAMPLES, SPEED_TOL_MPS, FreeTrajectory, RoadPlan, _heading_and_peak

HEADING = 0.3
LANE_W = 3.6


def _cubic_min_speed(T: float, x0: tuple[float, ...], xf: tuple[float, ...]) -> float:
    """The exact lowest speed along the road of the free cubic: its velocity is quadratic in t."""
    D, dv = xf[0] - x0[0] - x0[1] * T, xf[1] - x0[1]
    a, b = (3 * D - dv * T) / T**2, (dv * T - 2 * D) / T**3
    ts = [0.0, T] + ([-a / (3 * b)] if b != 0.0 and 0.0 < -a / (3 * b) < T else [])
    return min(x0[1] + 2 * a * t + 3 * b * t * t for t in ts)


@settings(max_examples=300, deadline=None)
@given(T=hs.floats(1.0, 10.0), v0=hs.floats(0.0, 30.0), vf=hs.floats(0.0, 30.0), ds=hs.floats(-60.0, 300.0),
       a_max=hs.floats(2.0, 12.0))
def test_limit_breach_is_a_reversal_or_a_peak_above_a_max(T: float, v0: float, vf: float, ds: float,
                                                         a_max: float) -> None:
    """Over generated free cubics (start and final speed at least the type's lowest, 0): the
    plan breaches its limits exactly when its peak acceleration exceeds ``a_max`` or its exact
    lowest speed along the road (the quadratic's minimum) falls below 0 by more than the
    tolerance, up to what :data:`LIMIT_SAMPLES` points can resolve."""
    x0, xf = (10.0, v0, 0.0, 0.0), (10.0 + ds, vf, 0.5, 0.0)
    traj = FreeTrajectory(T, x0, xf)
    _, peak = _heading_and_peak(traj, T)
    cand = Candidate(steps=int(round(T / 0.1)), tf=T, s=xf[0], vs=vf, d=xf[2], cost0=0.0)
    rp = RoadPlan("free", "optimal", cand, traj, traj.cost(), 0.0, peak_accel_mps2=peak)
    cr = SimpleNamespace(a_max=a_max, speed_range=(0.0, 50.0), x0=x0)
    breach = rp.limit_breach(cr)  # type: ignore[arg-type]
    low = _cubic_min_speed(T, x0, xf)
    # sampling finds the minimum to within half the velocity's second derivative (6 b) times the
    # half spacing squared
    D, dv = xf[0] - x0[0] - v0 * T, vf - v0
    resolution = 0.5 * abs(6 * (dv * T - 2 * D) / T**3) * (0.5 * T / (LIMIT_SAMPLES - 1)) ** 2
    if peak > a_max:
        assert breach is not None and "peak acceleration" in breach
    elif low < -SPEED_TOL_MPS - resolution - 1e-9:
        assert breach is not None and "reverse" in breach
    elif low >= -SPEED_TOL_MPS:
        assert breach is None
    assert rp.within_limits(cr) == (breach is None)  # type: ignore[arg-type]


def test_a_final_state_at_rest_within_round_off_of_zero_is_within_limits() -> None:
    """A final state at rest read as -1e-16 m/s (USA_Peach-4_8's candidate) does not make every
    plan to it a reversal; a start and final speed below the type's lowest widen it."""
    T = 4.0
    for vf in (-1e-16, 0.0):
        traj = FreeTrajectory(T, (0.0, 8.0, 0.0, 0.0), (16.0, vf, 0.0, 0.0))  # brakes to rest, never below
        cand = Candidate(steps=40, tf=T, s=16.0, vs=vf, d=0.0, cost0=0.0)
        rp = RoadPlan("free", "optimal", cand, traj, traj.cost(), 0.0, peak_accel_mps2=_heading_and_peak(traj, T)[1])
        cr = SimpleNamespace(a_max=11.5, speed_range=(0.0, 50.0), x0=(0.0, 8.0, 0.0, 0.0))
        assert rp.limit_breach(cr) is None  # type: ignore[arg-type]
    traj = FreeTrajectory(T, (0.0, -0.5, 0.0, 0.0), (10.0, 5.0, 0.0, 0.0))
    cand = Candidate(steps=40, tf=T, s=10.0, vs=5.0, d=0.0, cost0=0.0)
    rp = RoadPlan("free", "optimal", cand, traj, traj.cost(), 0.0, peak_accel_mps2=_heading_and_peak(traj, T)[1])
    cr = SimpleNamespace(a_max=11.5, speed_range=(0.0, 50.0), x0=(0.0, -0.5, 0.0, 0.0))
    assert rp.limit_breach(cr) is None  # type: ignore[arg-type]


def test_a_pm_start_at_rest_or_a_heading_outside_pi_is_noted_and_nothing_else() -> None:
    """The notes of :func:`iamp.commonroad.check._pm_notes`: a ``PM`` first state at rest with a
    heading away from 0, and an initial heading outside (-pi, pi] (DEU_Muc-2_x: -3.351 rad, which
    CommonRoad compares with the ``PM`` state's 2.932 as numbers); not a moving start with a heading
    inside, not a start heading 0, not a ``KS`` solution."""
    from iamp.commonroad.check import REST_MPS, _pm_notes

    def sol(model: str, vx: float, vy: float) -> SimpleNamespace:
        return SimpleNamespace(vehicle_model=SimpleNamespace(name=model),
                               trajectory=SimpleNamespace(state_list=[SimpleNamespace(velocity=vx, velocity_y=vy)]))

    def pp(heading: float) -> SimpleNamespace:
        return SimpleNamespace(initial_state=SimpleNamespace(orientation=heading))

    notes = _pm_notes(pp(-1.6264), sol("PM", 0.0, 0.0))
    assert len(notes) == 1 and "at rest" in notes[0] and "-1.6264" in notes[0] and "KS" in notes[0]
    assert _pm_notes(pp(-1.6264), sol("PM", 0.0, 2 * REST_MPS)) == []
    assert _pm_notes(pp(-1.6264), sol("KS", 0.0, 0.0)) == []
    assert _pm_notes(pp(-3.351), sol("KS", 5.0, 0.0)) == []
    assert _pm_notes(pp(0.0), sol("PM", 0.0, 0.0)) == []
    assert _pm_notes(pp(math.pi), sol("PM", -5.0, 0.0)) == []
    wrapped = _pm_notes(pp(-3.351), sol("PM", -5.0, 1.0))
    assert len(wrapped) == 1 and "-3.3510 rad lies outside (-pi, pi]" in wrapped[0] and "2.9322" in wrapped[0]
    full_turn = _pm_notes(pp(2 * math.pi), sol("PM", 0.0, 0.0))  # at rest, heading 0 written as 2 pi
    assert len(full_turn) == 1 and "outside (-pi, pi]" in full_turn[0] and "0.0000" in full_turn[0]


def _world(s: float, d: float) -> np.ndarray:
    c, sn = math.cos(HEADING), math.sin(HEADING)
    d = d + 0.5 * (s / 100.0) ** 2  # a gentle bend (see tests/test_commonroad_road_end.py)
    return np.array([s * c - d * sn, s * sn + d * c])


def _scene(path: Path, s_goal: float, step: int) -> Path:
    """Two lanes of 200 m, the ego at rest at ``s = 60`` in the right lane, heading along the road;
    the goal a 6 m by 3 m rectangle at ``s_goal`` in the same lane at time step ``step``; no vehicle."""
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.common.util import Interval
    from commonroad.geometry.shape import Rectangle
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork
    from commonroad.scenario.scenario import Scenario, ScenarioID
    from commonroad.scenario.state import CustomState, InitialState

    s = np.linspace(0.0, 200.0, 21)
    lanelets = []
    for i in range(2):
        right = np.array([_world(x, i * LANE_W) for x in s])
        left = np.array([_world(x, (i + 1) * LANE_W) for x in s])
        lanelets.append(Lanelet(left, 0.5 * (right + left), right, 100 + i,
                                adjacent_left=101 if i == 0 else None, adjacent_left_same_direction=(i == 0) or None,
                                adjacent_right=100 if i == 1 else None, adjacent_right_same_direction=(i == 1) or None))
    scenario = Scenario(0.1, ScenarioID(country_id="ZAM", map_name="IampLimits", map_id=1))
    scenario.add_objects(LaneletNetwork.create_from_lanelet_list(lanelets))
    ego0 = InitialState(time_step=0, position=_world(60.0, 0.5 * LANE_W), orientation=HEADING, velocity=0.0,
                        yaw_rate=0.0, slip_angle=0.0)
    slope = 2 * 0.5 * s_goal / 100.0 / 100.0  # the bend's slope at the goal
    goal = CustomState(time_step=Interval(step, step),
                       position=Rectangle(6.0, 3.0, _world(s_goal, 0.5 * LANE_W), HEADING + math.atan(slope)))
    pp = PlanningProblem(1, ego0, GoalRegion([goal]))
    CommonRoadFileWriter(scenario, PlanningProblemSet([pp]), "iamp tests", "", "", set()).write_to_file(
        str(path), OverwriteExistingFile.ALWAYS)
    return path


@needs_commonroad
@pytest.mark.parametrize("s_goal,forward", [(30.0, False), (25.0, False), (95.0, True)])
def test_a_goal_behind_a_start_at_rest_is_not_reached_by_reversing(tmp_path: Path, s_goal: float,
                                                                  forward: bool) -> None:
    """From rest, a goal behind the ego is reachable only by reversing: every planner's answer
    says its limits are exceeded (never ``optimal``), naming the reversal; a goal ahead is planned
    within them and valid by CommonRoad's checker."""
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import min_speed, plan
    from iamp.commonroad.solution import build_solution

    cr = load(_scene(tmp_path / "limits.xml", s_goal, 50))
    for planner in ("avoid", "pmp", "free"):
        rp = plan(cr, planner)
        assert rp.trajectory is not None and rp.candidate is not None
        if forward:
            assert rp.status == "optimal" and rp.within_limits(cr)
            assert min_speed(rp.trajectory, rp.candidate.tf) >= -SPEED_TOL_MPS
            sol, _ = build_solution(cr, rp.trajectory, rp.candidate.steps)
            v = check(cr.scenario, cr.planning_problem_set, sol, cost=False)
            assert v.checks["kinematically_feasible"]["ok"] and v.checks["road_boundary"]["ok"]
        else:
            assert rp.status == "exceeds limits" and not rp.within_limits(cr)
            assert min_speed(rp.trajectory, rp.candidate.tf) < -1.0
            assert rp.reason is not None and "reverse" in rp.reason


class _Constant:
    """A stub plan moving along the road at the constant speed ``v``."""

    def __init__(self, v: float) -> None:
        self.v = v

    def states(self, t: object) -> np.ndarray:
        n = np.atleast_1d(np.asarray(t, dtype=float)).size
        return np.tile([0.0, self.v, 0.0, 0.0], (n, 1))


def test_limit_breach_at_its_edges() -> None:
    """The breach's edges: a peak exactly at ``a_max`` and a speed exactly the tolerance below the
    lowest are within the limits, just beyond either is not; no trajectory, no breach and not
    within; a final state at rest read as -1e-16 m/s is reported against the lowest speed 0.00,
    not -0.00."""
    cand = Candidate(steps=40, tf=4.0, s=10.0, vs=0.0, d=0.0, cost0=0.0)
    cr = SimpleNamespace(a_max=6.0, speed_range=(0.0, 50.0), x0=(0.0, 0.0, 0.0, 0.0))

    def rp(v: float, peak: float, c: Candidate = cand) -> RoadPlan:
        return RoadPlan("free", "optimal", c, _Constant(v), 0.0, 0.0, peak_accel_mps2=peak)  # type: ignore[arg-type]

    assert rp(-SPEED_TOL_MPS, 6.0).limit_breach(cr) is None  # type: ignore[arg-type]
    assert rp(-SPEED_TOL_MPS, 6.0).within_limits(cr)  # type: ignore[arg-type]
    assert "peak acceleration" in (rp(0.0, np.nextafter(6.0, 7.0)).limit_breach(cr) or "")  # type: ignore[arg-type]
    assert "reverse" in (rp(np.nextafter(-SPEED_TOL_MPS, -1.0), 6.0).limit_breach(cr) or "")  # type: ignore[arg-type]
    none = RoadPlan("free", "unsafe", cand, None, None, 0.0)
    assert none.limit_breach(cr) is None and not none.within_limits(cr)  # type: ignore[arg-type]
    at_rest = dataclasses.replace(cand, vs=-1e-16)
    msg = rp(-2.0, 1.0, at_rest).limit_breach(cr)  # type: ignore[arg-type]
    assert msg is not None and "below the lowest 0.00 m/s" in msg and "-0.00" not in msg
    slow_start = SimpleNamespace(a_max=6.0, speed_range=(0.0, 50.0), x0=(0.0, -0.5, 0.0, 0.0))
    msg = rp(-2.0, 1.0).limit_breach(slow_start)  # type: ignore[arg-type]
    assert msg is not None and "falls to -2.00 m/s, below the lowest -0.50 m/s" in msg


@needs_commonroad
def test_the_free_baseline_entering_a_vehicle_is_unsafe_and_says_where(tmp_path: Path) -> None:
    """The free baseline (no vehicle imposed) is the optimum of the problem without vehicles; as a
    road plan through a vehicle it is ``unsafe`` (it was reported ``optimal``, and the text said
    'no vehicle in the way', on USA_US101-10_3 while CommonRoad's checker found a collision), and
    ``iamp commonroad plan`` names the vehicle it enters."""
    import subprocess
    import sys

    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.geometry.shape import Rectangle
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory

    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan

    path = _scene(tmp_path / "ahead.xml", 95.0, 50)
    scenario, pps = CommonRoadFileReader(str(path)).open()
    shape = Rectangle(4.5, 1.8)
    at = _world(80.0, 0.5 * LANE_W)  # standing in the ego's lane between it and the goal
    states = [CustomState(time_step=k, position=at, orientation=HEADING, velocity=0.0) for k in range(1, 61)]
    scenario.add_objects(DynamicObstacle(7, ObstacleType.CAR, shape,
                                         InitialState(time_step=0, position=at, orientation=HEADING, velocity=0.0,
                                                      yaw_rate=0.0, slip_angle=0.0, acceleration=0.0),
                                         TrajectoryPrediction(Trajectory(1, states), shape)))
    CommonRoadFileWriter(scenario, pps, "iamp tests", "", "", set()).write_to_file(str(path),
                                                                                  OverwriteExistingFile.ALWAYS)
    rp = plan(load(path), "free")
    assert rp.status == "unsafe" and not rp.safe and [i.obstacle.obstacle_id for i in rp.intrusions] == [7]
    out = subprocess.run([sys.executable, "-m", "iamp", "commonroad", "plan", str(path), "--planner", "free",
                          "--out", str(tmp_path / "sol")], capture_output=True, text=True, timeout=300)
    assert "status unsafe" in out.stdout and "enters: vehicle 7" in out.stdout
    assert "no vehicle in the way" not in out.stdout
