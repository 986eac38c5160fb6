"""CommonRoad obstacles with a set-based prediction (the public US-101 ``S`` problems): each time
step's occupancy set becomes the obstacle's box, and CommonRoad's checker, which tests the ego
against the sets, judges the plan.  ``iamp commonroad plan`` had stopped with an internal error
(``'SetBasedPrediction' object has no attribute 'trajectory'``).  Needs the ``[commonroad]`` extra.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import needs_commonroad
from test_commonroad_road_end import LANE_W, _judge, _scene, _world

pytestmark = needs_commonroad


def _with_sets(path: Path, sets: dict[int, list[list[tuple[float, float, float, float]]]]) -> Path:
    """The scene of :func:`_scene` (two lanes of 300 m, the ego at 15 m/s, goal step 20) with one
    obstacle per entry of ``sets``: its occupancy at steps 1, 2, ... a group of road-frame boxes
    ``(s_lo, s_hi, d_lo, d_hi)`` (one box: a polygon; several: a shape group)."""
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.geometry.shape import Polygon, Rectangle, ShapeGroup
    from commonroad.prediction.prediction import Occupancy, SetBasedPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.state import InitialState

    base = _scene(path, 300.0, 2, 15.0, 20)
    scenario, pps = CommonRoadFileReader(str(base)).open()

    def polygon(box: tuple[float, float, float, float]) -> Polygon:
        s_lo, s_hi, d_lo, d_hi = box
        return Polygon(np.array([_world(s_lo, d_lo), _world(s_hi, d_lo), _world(s_hi, d_hi), _world(s_lo, d_hi),
                                 _world(s_lo, d_lo)]))

    for oid, steps in sets.items():
        first = steps[0][0]
        occ = [Occupancy(k + 1, polygon(group[0]) if len(group) == 1 else ShapeGroup([polygon(b) for b in group]))
               for k, group in enumerate(steps)]
        s0 = 0.5 * (first[0] + first[1])
        init = InitialState(time_step=0, position=_world(s0, 0.5 * (first[2] + first[3])), orientation=-0.72,
                            velocity=10.0, yaw_rate=0.0, slip_angle=0.0, acceleration=0.0)
        scenario.add_objects(DynamicObstacle(oid, ObstacleType.CAR, Rectangle(4.5, 1.8), init,
                                             SetBasedPrediction(1, occ)))
    CommonRoadFileWriter(scenario, pps, "iamp tests", "", "", set()).write_to_file(
        str(path), OverwriteExistingFile.ALWAYS)
    return path


def test_each_occupancy_set_is_its_box_and_the_plan_avoids_the_sets(tmp_path: Path) -> None:
    """Obstacle 7 grows in the ego's lane ahead (a polygon, then a group of two), obstacle 8 in
    the lane beside: the boxes are the sets' extremes in the road frame (to the frame's error),
    the plan is safe, and CommonRoad's checker finds no collision with the sets."""
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan

    ahead = [[(40.0 + 1.0 * k, 45.0 + 2.0 * k, 0.1, LANE_W - 0.1)] if k < 10 else
             [(40.0 + k, 44.0 + k, 0.1, 1.9), (43.0 + k, 45.0 + 2.0 * k, 1.5, LANE_W - 0.1)] for k in range(20)]
    beside = [[(25.0 + 1.5 * k, 30.0 + 1.6 * k, LANE_W + 0.2, 2 * LANE_W - 0.2)] for k in range(20)]
    cr = load(_with_sets(tmp_path / "sets.xml", {7: ahead, 8: beside}))
    ob = next(o for o in cr.obstacles if o.obstacle_id == 7)
    assert ob.t.size == 21 and np.allclose(ob.t, 0.1 * np.arange(21))
    for k, group in enumerate(ahead, start=1):  # the frame's d is 0 on the ego lane's centre
        s_lo, s_hi = min(b[0] for b in group), max(b[1] for b in group)
        d_lo, d_hi = min(b[2] for b in group) - 0.5 * LANE_W, max(b[3] for b in group) - 0.5 * LANE_W
        got = (ob.s_lo[k], ob.s_hi[k], ob.d_lo[k], ob.d_hi[k])
        assert np.allclose(got, (s_lo, s_hi, d_lo, d_hi), atol=0.05), (k, got)
    rp = plan(cr)
    assert rp.safe and rp.candidate is not None and rp.trajectory is not None
    v = _judge(cr, rp.trajectory, rp.candidate.steps)
    assert v.checks["collision"]["ok"], v.checks
    assert v.valid, v.checks


def test_a_prediction_of_another_kind_is_refused_naming_the_obstacle(tmp_path: Path) -> None:
    from types import SimpleNamespace

    from commonroad.geometry.shape import Rectangle
    from commonroad.scenario.state import InitialState

    from iamp.commonroad.convert import _obstacle_boxes, load
    from iamp.core.errors import ScenarioError

    cr = load(_with_sets(tmp_path / "sets.xml", {7: [[(40.0, 45.0, 0.1, 3.5)]]}))
    assert [o.obstacle_id for o in cr.obstacles] == [7]
    init = InitialState(time_step=0, position=_world(40.0, 1.8), orientation=-0.72, velocity=10.0)
    odd = SimpleNamespace(obstacle_id=9, obstacle_shape=Rectangle(4.5, 1.8), initial_state=init,
                          prediction=SimpleNamespace())  # neither a trajectory nor a set-based prediction
    with pytest.raises(ScenarioError, match="obstacle 9: a SimpleNamespace is not supported"):
        _obstacle_boxes(cr.frame, odd, 0.1, 20, "x.xml")
