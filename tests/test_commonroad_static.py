"""Static obstacles and bodies that are not rectangles in CommonRoad scenarios.

Found on the public hand-crafted scenarios (``github.com/seungju-k1m/CommonRoad``,
``scenarios/hand-crafted``): iamp read only the dynamic obstacles with a rectangular body, so a
parked car (DEU_B471-1_1's obstacle 399, DEU_Muc-2_2's 200) was not there for it: the plan drove
through it and was reported ``optimal`` while CommonRoad's checker found the collision. A static
obstacle is now a box at every step, and a body of another shape (polygon, circle, a group of
them) the box of its occupancy at each step.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import needs_commonroad
from test_commonroad_limits import HEADING, LANE_W, _scene, _world

pytestmark = needs_commonroad


def _add(path: Path, kind: str, s: float, lane: int) -> Path:
    """Add to the scene one obstacle at ``s`` on lane ``lane``'s centre: a parked car (``static``),
    a standing circle of radius 1 m (``circle``: a dynamic obstacle whose body is a circle) or a
    static polygon (a 6 m x 2.4 m quadrilateral, ``polygon``)."""
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.geometry.shape import Circle, Polygon, Rectangle
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType, StaticObstacle
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory

    scenario, pps = CommonRoadFileReader(str(path)).open()
    at = _world(s, (lane + 0.5) * LANE_W)
    init = InitialState(time_step=0, position=at, orientation=HEADING, velocity=0.0, yaw_rate=0.0, slip_angle=0.0,
                        acceleration=0.0)
    if kind == "static":
        scenario.add_objects(StaticObstacle(9, ObstacleType.PARKED_VEHICLE, Rectangle(4.5, 1.9), init))
    elif kind == "polygon":
        c, sn = math.cos(HEADING), math.sin(HEADING)
        local = np.array([[-3.0, -1.2], [3.0, -1.2], [3.0, 1.2], [-3.0, 1.2]])
        world = local @ np.array([[c, sn], [-sn, c]]) + at
        init = InitialState(time_step=0, position=np.zeros(2), orientation=0.0, velocity=0.0, yaw_rate=0.0,
                            slip_angle=0.0, acceleration=0.0)
        scenario.add_objects(StaticObstacle(9, ObstacleType.CONSTRUCTION_ZONE, Polygon(world), init))
    else:
        shape = Circle(1.0)
        states = [CustomState(time_step=k, position=at, orientation=HEADING, velocity=0.0) for k in range(1, 61)]
        scenario.add_objects(DynamicObstacle(9, ObstacleType.PEDESTRIAN, shape, init,
                                             TrajectoryPrediction(Trajectory(1, states), shape)))
    CommonRoadFileWriter(scenario, pps, "iamp tests", "", "", set()).write_to_file(str(path),
                                                                                  OverwriteExistingFile.ALWAYS)
    return path


@pytest.mark.parametrize("kind", ["static", "polygon", "circle"])
def test_an_obstacle_that_does_not_move_or_is_not_a_rectangle_is_avoided(tmp_path: Path, kind: str) -> None:
    """An obstacle standing in the ego's lane between it (at rest at s = 60) and its goal (s = 95):
    iamp has its box at every step (the extremes of its shape in the road frame), and no plan iamp
    calls safe meets it by CommonRoad's checker: the free baseline through it is ``unsafe``
    naming it, and the planners' answer is never ``optimal`` with a collision."""
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan
    from iamp.commonroad.solution import build_solution

    cr = load(_add(_scene(tmp_path / "scene.xml", 95.0, 50), kind, 80.0, 0))
    ob = {o.obstacle_id: o for o in cr.obstacles}[9]
    assert ob.t.size == 51 and np.allclose(ob.t, np.arange(51) * cr.dt)
    centre = cr.frame.to_road(_world(80.0, 0.5 * LANE_W).reshape(1, 2))[0]
    if kind == "circle":  # the box of the circumscribed 24-gon: it holds the circle, and little more
        for lo_, hi_, c in ((ob.s_lo, ob.s_hi, centre[0]), (ob.d_lo, ob.d_hi, centre[1])):
            assert np.all(c - lo_ >= 1.0 - 2e-3) and np.all(hi_ - c >= 1.0 - 2e-3)
            assert np.all(c - lo_ <= 1.0 / math.cos(math.pi / 24) + 2e-3)
            assert np.all(hi_ - c <= 1.0 / math.cos(math.pi / 24) + 2e-3)
    else:
        half = {"static": (2.25, 0.95), "polygon": (3.0, 1.2)}[kind]
        assert np.allclose(ob.s_lo, centre[0] - half[0], atol=0.06)
        assert np.allclose(ob.s_hi, centre[0] + half[0], atol=0.06)
        assert np.allclose(ob.d_hi - ob.d_lo, 2 * half[1], atol=0.06)
    free = plan(cr, "free")
    assert free.status == "unsafe" and [i.obstacle.obstacle_id for i in free.intrusions] == [9]
    for planner in ("avoid", "pmp"):
        rp = plan(cr, planner)
        assert rp.trajectory is not None and rp.candidate is not None
        sol, _ = build_solution(cr, rp.trajectory, rp.candidate.steps)
        v = check(cr.scenario, cr.planning_problem_set, sol, cost=False)
        if rp.status in ("optimal", "local"):
            assert v.checks["collision"]["ok"], (planner, v.colliding_obstacles)
        else:
            assert rp.status == "unsafe" and any(i.obstacle.obstacle_id == 9 for i in rp.intrusions)


@pytest.mark.parametrize("d_end,off", [(0.0, False), (-2.6, True)])
def test_road_checked_takes_commonroads_road_boundary_verdict(tmp_path: Path, d_end: float, off: bool) -> None:
    """:func:`iamp.commonroad.planning.road_checked`, which every plan passes before it is taken
    (the public hand-crafted DEU_Muc-2_1's plan was called ``optimal`` while CommonRoad found the
    body off the road at 0.6-1.5 s, where no road-edge box was entered: two lanelets the corridor
    joins): a plan ending with its centre 2.6 m right of its lane's centre (the right edge 1.8 m
    away) gets exactly the steps CommonRoad's checker finds off the road as ``off_road_s``, is
    ``unsafe`` and not ``safe``; a plan in its lane is untouched."""
    from iamp.commonroad.convert import load
    from iamp.commonroad.goal import Candidate
    from iamp.commonroad.planning import FreeTrajectory, RoadPlan, describe, off_road_steps, road_checked

    cr = load(_scene(tmp_path / "scene.xml", 95.0, 50))
    s0, _, d0, _ = cr.x0
    T = 5.0
    cand = Candidate(steps=50, tf=T, s=s0 + 30.0, vs=2.0, d=d0 + d_end, cost0=0.0)
    traj = FreeTrajectory(T, cr.x0, (cand.s, cand.vs, cand.d, 0.0))
    rp = RoadPlan("avoid", "optimal", cand, traj, traj.cost(), 0.0)
    expected = np.flatnonzero(off_road_steps(cr, traj, 50)) * cr.dt
    assert road_checked(cr, rp) == (not off) == rp.safe
    assert bool(expected.size) == off and np.allclose(rp.off_road_s, expected)
    assert rp.status == ("unsafe" if off else "optimal") and describe(rp)["off_road_s"] == rp.off_road_s
    if off:
        assert rp.reason == (f"CommonRoad's road boundary: the body is off the road at {expected[0]:.1f}-"
                             f"{expected[-1]:.1f} s")
    none = RoadPlan("avoid", "refused", cand, None, None, 0.0)
    assert not road_checked(cr, none) and none.off_road_s == [] and none.status == "refused"
