"""The corridor planner of ``iamp.commonroad.planning`` (issue 33, item 2): the whole horizon on
the time steps, every recorded box on a side chosen from a guess, the final state free in the
goal; an overtaking in the ego's own lane, which one corner per vehicle cannot describe."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
from conftest import needs_commonroad
from hypothesis import given
from hypothesis import strategies as st

FIXTURE = Path(__file__).parent / "fixtures" / "commonroad_goals.py"


def _overtake(tmp_path: Path, goal_s: float = 104.0, goal_len: float = 4.0, ego_v: float = 15.0) -> Path:
    """The fixture's three straight lanes, the ego in the right lane at 15 m/s and a car 15 m
    ahead of it in that lane at 10 m/s; the goal: the right lane ahead of the car at steps 60-62
    (the car's front is at 97.25 m at step 60), 12-18 m/s.  The ego starts behind the car and
    ends ahead of it in its lane."""
    sys.path.insert(0, str(FIXTURE.parent))
    from commonroad.common.util import Interval
    from commonroad.geometry.shape import Rectangle
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory
    from commonroad_goals import HEADING, LANE_W, build, world
    from test_commonroad_goals import _write

    scenario, _ = build()
    scenario.remove_obstacle(scenario.obstacle_by_id(10))
    states = [CustomState(time_step=k, position=world(35.0 + 1.0 * k, 0.5 * LANE_W), orientation=HEADING,
                          velocity=10.0) for k in range(1, 81)]
    shape = Rectangle(4.5, 1.8)
    init = InitialState(time_step=0, position=world(35.0, 0.5 * LANE_W), orientation=HEADING, velocity=10.0,
                        yaw_rate=0.0, slip_angle=0.0, acceleration=0.0)
    scenario.add_objects(DynamicObstacle(20, ObstacleType.CAR, shape, init,
                                         TrajectoryPrediction(Trajectory(1, states), shape)))
    ego0 = InitialState(time_step=0, position=world(20.0, 0.5 * LANE_W), orientation=HEADING, velocity=ego_v,
                        yaw_rate=0.0, slip_angle=0.0)
    goal = CustomState(time_step=Interval(60, 62), velocity=Interval(12.0, 18.0),
                       position=Rectangle(goal_len, 2.0, world(goal_s, 0.5 * LANE_W), HEADING))
    pps = PlanningProblemSet([PlanningProblem(1, ego0, GoalRegion([goal]))])
    return _write(scenario, pps, tmp_path / "overtake.xml")


@needs_commonroad
def test_an_overtaking_in_the_ego_lane_is_planned_on_the_time_steps(tmp_path: Path) -> None:
    """The car is behind-to-ahead of the ego in the same lane: no corner of it describes the
    manoeuvre (§10's half-planes are crossed twice), so the active set alone leaves the plan in
    the car.  The corridor planner passes it in the next lane (the plan's largest offset is
    beyond the car's side by the body's margin) and comes back ahead of it; CommonRoad's
    checker finds the plan valid."""
    from test_commonroad_goals import _judge

    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import intrusions, plan

    cr = load(_overtake(tmp_path))
    before = plan(cr, via=False, corridor=False)
    assert not before.safe and any(i.obstacle.obstacle_id == 20 for i in before.intrusions)
    rp = plan(cr, via=False)
    assert rp.safe and rp.iamp_status == "corridor" and rp.candidate is not None, rp.reason
    assert rp.trajectory is not None and not intrusions(cr, rp.trajectory, rp.candidate.tf)
    t = np.arange(rp.candidate.steps + 1) * cr.dt
    X = rp.trajectory.states(t)
    assert float(np.max(np.abs(X[:, 2] - X[0, 2]))) > 1.8 + 0.15  # left its lane to pass
    assert abs(X[-1, 2] - X[0, 2]) < 1.0  # and came back into it
    U = rp.trajectory.inputs(t[:-1])
    assert float(np.max(np.hypot(U[:, 0], U[:, 1]))) <= cr.a_max + 1e-9
    verdict = _judge(cr, rp)
    assert verdict.valid, verdict


@needs_commonroad
def test_the_corridor_moves_a_final_state_at_the_cars_margin_into_the_goal(tmp_path: Path) -> None:
    """The ego at the car's speed (10 m/s) 15 m behind it; the goal (steps 60-62) begins inside
    the car and reaches 8 m ahead of it.  The final-state search offers the cheapest clear poses,
    just ahead of the car's front by the body's margin (s = 99.7-101.7): a plan ending there
    must already be ahead of the car while it comes back into the lane, and the ego closes on it
    at 4-5 m/s, so no plan to those poses exists (planned with the final state pinned there, the
    corridor's plans stay in the car).  The corridor planner's final state is free inside the
    goal's rows: it ends farther ahead, inside every goal element (the goal's own test), safe;
    CommonRoad's checker finds the plan valid."""
    from test_commonroad_goals import _judge

    import iamp.commonroad.planning as planning
    from iamp.commonroad.convert import load

    cr = load(_overtake(tmp_path, goal_s=100.25, goal_len=10.0, ego_v=10.0))
    found = planning.search_final_states(cr)
    assert found is not None and found.candidates
    rp = planning.plan(cr)
    assert rp.safe and rp.iamp_status == "corridor" and rp.candidate is not None, rp.reason
    c = rp.candidate
    assert cr.goal.verify(cr.goal.elements[c.element], c.steps, (c.s, c.vs, c.d, c.vd)) is None
    searched = next(x for x in found.candidates if x.steps == c.steps)
    assert c.s > searched.s + 1.0  # farther ahead than the search's pose at the car's margin
    assert _judge(cr, rp).valid
    pinned = planning.corridor_qp

    def at_the_search_pose(cr_: Any, cand: Any, G: Any, rows: Any = None, engine: Any = None) -> Any:
        return pinned(cr_, cand, G, None, engine)

    planning.corridor_qp = at_the_search_pose  # type: ignore[assignment]
    try:
        assert not planning.plan(cr).safe
    finally:
        planning.corridor_qp = pinned


def _box(oid: int, t: np.ndarray, s0: float, v: float, d: np.ndarray) -> Any:
    from iamp.commonroad.convert import Obstacle

    return Obstacle(oid, t, s0 + v * t - 2.25, s0 + v * t + 2.25, d - 0.9, d + 0.9, 4.5, 1.8, (s0, v, 0.0, 0.0),
                    2.25, 0.0, 1, bool(np.ptp(d) > 1.0))


def test_a_lane_changer_is_met_in_each_lane_only_while_it_is_there() -> None:
    """A car beside the ego in the next lane (d = 3.6) that changes into a third lane (d = 7.2)
    at 2-3 s, level with the ego all along.  Its box over the whole horizon spans both lanes
    (d from 2.7 to 8.1): a plan that wants the next lane after 3 s is shut out by that box.  The
    corridor's rows take its box at each step: while it is in the next lane the ego keeps below
    it, and after it has left, a row keeps the ego below its box in the third lane, not below the
    next lane's."""
    from iamp.commonroad.planning import corridor_sides

    t = np.arange(0.0, 6.01, 0.1)
    d = 3.6 + 3.6 * np.clip(t - 2.0, 0.0, 1.0)
    car = _box(7, t, 0.0, 15.0, d)
    cr = SimpleNamespace(all_obstacles=[car], dt=0.1)
    K = 60
    G = np.column_stack([15.0 * t[:K + 1], np.full(K + 1, 15.0), np.zeros(K + 1), np.zeros(K + 1)])
    sx, sy = np.full(K + 1, 2.5), np.full(K + 1, 1.2)
    rows = {k: (axis, sign, bound) for k, axis, sign, bound in corridor_sides(cr, G, sx, sy)}  # type: ignore[arg-type]
    assert rows[10] == (2, -1.0, 3.6 - 0.9 - 1.2)  # below it in the next lane
    assert math.isclose(rows[50][2], 7.2 - 0.9 - 1.2)  # later: below it in the third lane
    assert rows[50][:2] == (2, -1.0)
    # the union box would shut the next lane for the whole horizon
    assert float(car.d_lo.min()) - 1.2 < 3.6 - 1.2 < float(car.d_hi.max())


def test_a_step_plan_is_the_point_mass_model() -> None:
    """The corridor's plan holds its inputs on each step: its states at the steps are the exact
    point-mass integration, its inputs constant inside a step, and its cost ½∫|u|²."""
    from iamp.commonroad.planning import StepTrajectory

    rng = np.random.default_rng(3)
    u = rng.normal(size=(20, 2))
    tr = StepTrajectory((1.0, 10.0, -0.5, 0.2), 0.1, u)
    x = np.array([1.0, 10.0, -0.5, 0.2])
    for k in range(20):
        x = np.array([x[0] + x[1] * 0.1 + 0.005 * u[k, 0], x[1] + 0.1 * u[k, 0],
                      x[2] + x[3] * 0.1 + 0.005 * u[k, 1], x[3] + 0.1 * u[k, 1]])
        assert np.allclose(tr.states([0.1 * (k + 1)])[0], x)
        assert np.allclose(tr.inputs([0.1 * k + 0.03, 0.1 * k + 0.07]), u[k])
    assert math.isclose(tr.cost(), 0.5 * float(np.sum(u**2)) * 0.1)


@needs_commonroad
def test_a_corridor_plan_for_a_steered_car_keeps_its_engine_limit(tmp_path: Path) -> None:
    """The KS model accelerates at most :math:`a_{max} v_{switch}/v` above :math:`v_{switch}`.
    From 10 to 30 m/s in the overtaking fixture's 6.2 s on an empty road, the point-mass corridor
    plan (constant 3.2 m/s²) exceeds that limit at speed; with the vehicle type's limit
    (``engine``) it accelerates early, while slow, and stays within the rows' share of it at
    every step (the world speed at both ends of the step), reaching the same final state."""
    import dataclasses

    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import CORRIDOR_ENGINE_SHARE, corridor_qp, ks_engine

    cr = dataclasses.replace(load(_overtake(tmp_path, ego_v=10.0)), obstacles=[])
    c0 = cr.candidates[0]
    K, T = c0.steps, c0.steps * cr.dt
    s0, vs0, d0, _ = cr.x0
    vf = 30.0
    cand = dataclasses.replace(c0, s=s0 + 0.5 * (vs0 + vf) * T, vs=vf, d=d0, vd=0.0)
    t = np.arange(K + 1) * cr.dt
    acc = (vf - vs0) / T
    G = np.stack([s0 + vs0 * t + 0.5 * acc * t**2, vs0 + acc * t, np.full_like(t, d0), np.zeros_like(t)], axis=1)
    a_max, v_switch = ks_engine(2)[:2]

    def worst(engine: tuple[float, float] | None) -> float:
        tr = corridor_qp(cr, cand, G, None, engine)
        assert tr is not None
        assert np.allclose(tr.p[-1], (cand.s, cand.d), atol=1e-4) and np.allclose(tr.v[-1], (vf, 0.0), atol=1e-4)
        speed = np.hypot(tr.v[:, 0], tr.v[:, 1])
        v = np.maximum(speed[:-1], speed[1:])
        along = (tr.u * tr.v[:-1]).sum(axis=1) / speed[:-1]  # the acceleration along the world velocity
        return float(np.max(np.maximum(tr.u[:, 0], along) / np.minimum(a_max, a_max * v_switch / v)))

    assert worst(None) > 1.1  # the point mass accelerates beyond the engine at speed
    assert worst((a_max, v_switch)) <= CORRIDOR_ENGINE_SHARE + 1e-6


@given(st.floats(1.0, 20.0), st.floats(0.5, 30.0), st.floats(0.1, 80.0), st.floats(0.01, 80.0))
def test_an_engine_tangent_never_allows_more_than_the_engine(a_max: float, v_switch: float, v0: float,
                                                             v: float) -> None:
    """The row :math:`a + c v \\le e` lies below :math:`a_{max} v_{switch}/v` at every speed
    (a tangent of a convex function) and touches it at :math:`v_0` (at least :math:`v_{switch}`)."""
    from iamp.commonroad.planning import engine_tangent

    c, e = engine_tangent(a_max, v_switch, v0)
    assert e - c * v <= a_max * v_switch / v * (1 + 1e-12)
    t0 = max(v0, v_switch)
    assert math.isclose(e - c * t0, a_max * v_switch / t0, rel_tol=1e-12)
