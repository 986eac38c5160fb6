"""A standing vehicle beside the ego's path may turn its nose in (``iamp simulate --commonroad``).

SUMO's lane-change model turns a standing car toward the next lane: in USA_US101-24_2 with SUMO
seed 2, vehicle 31 stood (0 m/s) half across the lane line and turned from -0.04 to -0.16 rad in
2.5 s while the ego passed it at 18 m/s 0.16 m away; the contact followed (not at fault by RSS).
The rule (:data:`iamp.commonroad.interactive.TURN_IN_MPS`): the box of a vehicle observed at most
:data:`~iamp.commonroad.interactive.STANDING_MPS` fast grows across the road, both sides, by
``TURN_IN_MPS * t`` up to :data:`~iamp.commonroad.interactive.TURN_IN_MAX_M`; every plan the
loop executes keeps clear of it, so the ego passes such a car with that margin or not at all.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from conftest import data_path
from hypothesis import given, settings
from hypothesis import strategies as st
from test_commonroad_interactive import HAVE_EXTRA, HAVE_SUMO, INTERACTIVE, _fixture, needs_extra


def _observed(speed: float, d: float = 3.6) -> Any:
    from iamp.commonroad.interactive import _observed_obstacle
    from iamp.prediction.predictor import Predictor

    cr = _fixture()
    hist_t = [0.0, 0.5, 1.0, 1.5]
    hist_s = [100.0 + speed * t for t in hist_t]
    t = np.arange(0.0, 6.01, 0.1)
    ob = _observed_obstacle(cr, 31, hist_t, hist_s, (120.0, 125.0, d - 1.0, d + 1.0), speed, t,
                            Predictor.default())
    return ob, t


@needs_extra
@settings(deadline=None, max_examples=40)
@given(st.floats(0.0, 30.0))
def test_only_a_standing_vehicles_box_grows_across_the_road(speed: float) -> None:
    """At t = 0 the box is the observed one; a vehicle at most STANDING_MPS fast grows by
    TURN_IN_MPS * t on both sides (at most TURN_IN_MAX_M), a faster one keeps its width."""
    from iamp.commonroad.interactive import STANDING_MPS, TURN_IN_MAX_M, TURN_IN_MPS

    ob, t = _observed(speed)
    side = np.minimum(TURN_IN_MPS * t, TURN_IN_MAX_M) if speed <= STANDING_MPS else np.zeros_like(t)
    assert ob.d_lo[0] == pytest.approx(2.6) and ob.d_hi[0] == pytest.approx(4.6)
    assert np.allclose(ob.d_lo, 2.6 - side) and np.allclose(ob.d_hi, 4.6 + side)


@needs_extra
@pytest.mark.parametrize(("d_ego", "passes"), [(0.0, True), (1.3, False)])
def test_a_plan_passing_close_beside_a_standing_car_is_not_clear(d_ego: float, passes: bool) -> None:
    """The ego (1.61 m wide in 24_2; the fixture's type here) drives straight at 18 m/s past a car
    standing with its centre 3.6 m to the left: at d = 0 (its lane's centre) it keeps clear of the
    grown box; at d = 1.3 m (where 24_2's ego passed vehicle 31, its goal's centre line) its body
    comes within TURN_IN_MAX_M of the car and the plan is not clear."""
    from iamp.commonroad.planning import FreeTrajectory, intrusions

    cr = _fixture()
    s0 = cr.x0[0]
    ob, _ = _observed(0.0)
    ob = dataclasses.replace(ob, s_lo=ob.s_lo - 120.0 + s0 + 30.0, s_hi=ob.s_hi - 120.0 + s0 + 30.0)
    live = dataclasses.replace(cr, x0=(s0, 18.0, d_ego, 0.0), obstacles=[ob], road_edges=[])
    traj = FreeTrajectory(4.0, live.x0, (s0 + 72.0, 18.0, d_ego, 0.0))
    hits = intrusions(live, traj, 4.0)
    assert (not hits) == passes
    # the same plan beside the car's observed (not grown) box would have passed in both cases
    still = dataclasses.replace(ob, d_lo=np.full_like(ob.d_lo, ob.d_lo[0]), d_hi=np.full_like(ob.d_hi, ob.d_hi[0]))
    assert not intrusions(dataclasses.replace(live, obstacles=[still]), traj, 4.0)


@pytest.mark.slow
@pytest.mark.skipif(not HAVE_EXTRA or not HAVE_SUMO or not (INTERACTIVE / "USA_US101-24_2_I-1-1").is_dir(),
                    reason="needs the [commonroad] extra, SUMO and "
                           f"{data_path('commonroad', 'interactive-US101', 'USA_US101-24_2_I-1-1')}")
def test_24_2_seed_2_passes_the_standing_car_with_room() -> None:
    """USA_US101-24_2, SUMO seed 2 (about 60 s): before, the ego passed vehicle 31 at 18 m/s, its
    body 0.07-0.08 m into 31's turned body at 10.0-10.6 s (the contact, not at fault); now it
    passes 0.69-0.80 m from it, reaches the goal and touches nothing.  SUMO's routes as shipped
    (``repair_routes=False``): 31 stands at the end of edge 92, which its refused route repeats;
    with the repaired routes it drives on (``tests/test_interactive_routes.py``)."""
    from iamp.commonroad.interactive import simulate_with_log

    r, log = simulate_with_log(INTERACTIVE / "USA_US101-24_2_I-1-1", seed=2, repair_routes=False)
    assert r["goal_reached"] and r["collisions"] == 0 and r["contacts_not_at_fault"] == 0
    half_w = 0.5 * 1.61
    gaps = []
    for i, ids in enumerate(log.ids):
        if "31" not in ids:
            continue
        s, _, d = log.ego[i][:3]
        row = log.nb[i][ids.index("31")]
        if abs(row[0] - s) < 0.5 * (row[5] + 4.508):  # alongside
            heading = row[7]
            near = row[1] - 0.5 * row[6] * np.cos(heading) - 0.5 * row[5] * abs(np.sin(heading))
            gaps.append(near - (d + half_w))
    assert gaps and min(gaps) > 0.5
