"""The tactical layer of the CommonRoad closed loop (:mod:`iamp.commonroad.tactical`): a lane
change one lane at a time toward the goal's lane, into a gap that leaves RSS's stopping distance
ahead and a comfortable braking gap behind.

The generated scenario ``tests/fixtures/commonroad_goals.xml`` has three parallel lanes (centres
at d = 0, 3.6 and 7.2 m); its ego starts in the first at 15 m/s and one of its goal states lies
in the third (d 6.4 m, 6-7 s).  Needs the ``[commonroad]`` extra only.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_commonroad_interactive import HAVE_EXTRA, HAVE_SUMO, INTERACTIVE, _fixture  # the shared fixture

pytestmark = pytest.mark.skipif(not HAVE_EXTRA, reason="the [commonroad] extra is not installed "
                                                       "(pip install 'iamp[commonroad]')")


def _moving(oid: int, s: float, d: float, v: float, horizon: float = 8.0) -> Any:
    """A vehicle (4.5 m x 1.8 m) at ``(s, d)`` now, driving at ``v`` along the road."""
    from iamp.commonroad.convert import Obstacle

    t = np.arange(0.0, horizon + 1e-9, 0.1)
    n = t.size
    c = s + v * t
    return Obstacle(oid, t, c - 2.25, c + 2.25, np.full(n, d - 0.9), np.full(n, d + 0.9), 4.5, 1.8,
                    (s, v, 0.0, 0.0), 2.25, 0.0, 0, False)


def _live(obstacles: list[Any]) -> Any:
    cr = _fixture()
    return dataclasses.replace(cr, obstacles=obstacles, road_edges=[])


def _goal(cr: Any) -> Any:
    """The fixture's final state in the third lane (goal state 1)."""
    return next(c for c in cr.candidates if c.d > 5.0)


def test_lane_map_counts_the_lanes_to_the_goal() -> None:
    """The goal (d 6.4 m) is two lanes to the left of the ego's lane (d 0); the next lane toward
    it is the middle lanelet, whose centre is 3.6 m over all along."""
    from iamp.commonroad.tactical import LaneMap

    cr = _fixture()
    lanes = LaneMap(cr)
    g = _goal(cr)
    n, nxt = lanes.toward(cr.x0[0], cr.x0[2], g.s, g.d)
    assert n == 2 and nxt == 101
    assert lanes.centre(101, 150.0) == pytest.approx(3.6, abs=1e-3)
    assert lanes.toward(g.s, 7.2, g.s, g.d) == (0, None)  # in the goal's lane: nothing to change


def test_follower_gap_is_the_comfortable_braking_distance() -> None:
    """Equal speeds: half a second of the speed plus the margin; a faster rear car also needs its
    response time's closing and its braking at RSS's brake_min down to the ego's speed."""
    from iamp.commonroad.tactical import GAP_MARGIN_M, follower_gap
    from iamp.simulation.rss import DEFAULT

    assert follower_gap(20.0, 20.0) == pytest.approx(10.0 + GAP_MARGIN_M)
    assert follower_gap(20.0, 25.0) == pytest.approx(10.0 + GAP_MARGIN_M)
    closing = 10.0
    brake = closing * DEFAULT.response_time_s + closing**2 / (2 * DEFAULT.brake_min)
    assert follower_gap(30.0, 20.0) == pytest.approx(max(brake, 15.0) + GAP_MARGIN_M)


def test_free_road_lane_change_ends_in_the_next_lane_parallel_to_it() -> None:
    """Nothing around: the lane change ends at the middle lane's centre, parallel to the road,
    within the friction circle, after one of the tactical horizons."""
    from iamp.commonroad.tactical import HORIZONS_S, lane_change

    live = _live([])
    g = _goal(live)
    rp = lane_change(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert rp is not None and rp.safe and rp.candidate is not None
    assert rp.candidate.d == pytest.approx(3.6, abs=1e-3) and rp.candidate.vd == 0.0
    assert any(abs(rp.candidate.tf - T) < 1e-9 for T in HORIZONS_S)
    end = rp.trajectory.states([rp.candidate.tf])[0]
    assert end[2] == pytest.approx(3.6, abs=1e-3) and end[3] == pytest.approx(0.0, abs=1e-6)
    assert rp.peak_accel_mps2 <= live.a_max


def test_no_lane_change_into_a_wall_of_vehicles() -> None:
    """The middle lane holds a column of cars 6 m apart (1.5 m bumper to bumper) at the ego's
    speed: no gap, so no lane change (the loop brakes or keeps its plan instead)."""
    from iamp.commonroad.tactical import lane_change

    cr = _fixture()
    wall = [_moving(10 + i, cr.x0[0] + 6.0 * i, 3.6, cr.x0[1]) for i in range(-12, 13)]
    live = _live(wall)
    g = _goal(live)
    assert lane_change(live, "avoid", g.d, 0.0, g.s, g.tf) is None


def test_lane_change_fits_behind_a_car_driving_beside_the_ego() -> None:
    """A car beside the ego in the middle lane at its speed: no lane change starts toward it
    (:func:`~iamp.commonroad.tactical.beside`, USA_US101-23_1 seed 2); once it is 2 m ahead of the
    ego's front, the constant-speed lane change would end against its rear, so the lane change ends
    in a gap (behind or ahead of it) that keeps RSS's stopping distance to it, or behind it the
    comfortable follower gap."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import lane_change, rss_clear_at

    cr = _fixture()
    g = _goal(_live([]))
    level = _live([_moving(11, cr.x0[0], 3.6, cr.x0[1])])
    assert lane_change(level, "avoid", g.d, 0.0, g.s, g.tf) is None
    ahead = _moving(11, cr.x0[0] + 0.5 * cr.ego_length + 2.0 + 2.25, 3.6, cr.x0[1])
    live = _live([ahead])
    rp = lane_change(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert rp is not None and rp.candidate is not None
    T = rp.candidate.tf
    s_end = rp.trajectory.states([T])[0, 0]
    c_end = float(ahead.cubic[0]) + cr.x0[1] * T
    assert abs(s_end - c_end) >= 4.5  # not level with it
    assert not intrusions(live, rp.trajectory, T)
    assert rss_clear_at(live, rp.candidate.s, rp.candidate.vs, rp.candidate.d, T)


@settings(max_examples=12, deadline=None)
@given(st.lists(st.tuples(st.floats(-40.0, 40.0), st.floats(8.0, 22.0)), min_size=1, max_size=4))
def test_an_accepted_lane_change_keeps_clear_and_leaves_rss_room(cars: list[tuple[float, float]]) -> None:
    """Whatever the middle lane's traffic, a lane change the layer accepts keeps the body off every
    predicted vehicle over its horizon (checked again here), ends in the middle lane, and at its
    end every car ahead in that lane is at least RSS's stopping distance away (ego braking at
    0.9 a_max, the car at brake_max) and every car behind at least the follower gap."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import STOP_DECEL_FRACTION, follower_gap, lane_change
    from iamp.simulation.rss import DEFAULT, rss_distance

    cr = _fixture()
    obs = [_moving(20 + i, cr.x0[0] + ds, 3.6, v) for i, (ds, v) in enumerate(cars)]
    live = _live(obs)
    g = _goal(live)
    rp = lane_change(live, "avoid", g.d, 0.0, g.s, g.tf)
    if rp is None:
        return
    T = rp.candidate.tf
    assert not intrusions(live, rp.trajectory, T)
    s, v, d, vd = rp.trajectory.states([T])[0]
    assert d == pytest.approx(3.6, abs=1e-3) and vd == pytest.approx(0.0, abs=1e-6)
    for ds, vo in cars:
        c = cr.x0[0] + ds + vo * T
        if c > s:
            gap = c - 2.25 - (s + 0.5 * cr.ego_length)
            assert gap >= float(rss_distance(v, vo, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max)) - 1e-6
        else:
            gap = (s - 0.5 * cr.ego_length) - (c + 2.25)
            assert gap >= follower_gap(vo, v) - 1e-6


def test_a_lane_change_under_way_is_given_up_when_the_car_ahead_slows() -> None:
    """USA_US101-2_1: the ego, at 18.7 m/s, changed into a lane whose car ahead (518) then braked
    from 14 to 8 m/s; finishing the lane change (its remainder still clear of the predicted boxes)
    ran into 518 at 9.1 s, the ego at fault.  A lane change is kept only while it also keeps RSS's
    stopping distance to the car ahead along the way and at its end: a car at 5 m/s ahead in the
    new lane, half that distance from the lane change's end, touches no predicted box yet ends
    it; at 1.5 times that distance it is kept."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import STOP_DECEL_FRACTION, lane_change, still_holds
    from iamp.simulation.rss import DEFAULT, rss_distance

    cr = _fixture()
    live = _live([])
    g = _goal(live)
    rp = lane_change(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert rp is not None and rp.candidate is not None
    T = rp.candidate.tf
    assert still_holds(live, rp.trajectory, T)
    s_e, v_e = (float(x) for x in rp.trajectory.states([T])[0, :2])
    need = float(rss_distance(v_e, 5.0, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max))
    assert need > 2.0
    for factor, holds in ((0.5, False), (1.5, True)):
        rear_at_T = s_e + 0.5 * cr.ego_length + factor * need
        car = _live([_moving(30, rear_at_T + 2.25 - 5.0 * T, 3.6, 5.0)])
        assert not [h for h in intrusions(car, rp.trajectory, T) if not h.obstacle.road_edge]
        assert still_holds(car, rp.trajectory, T) is holds


@pytest.mark.slow
@pytest.mark.skipif(not HAVE_SUMO or not (INTERACTIVE / "USA_US101-9_1_I-1-1").is_dir(),
                    reason="needs the [sim] extra (SUMO) and the shared interactive scenarios "
                           f"({INTERACTIVE})")
def test_a_kept_plan_toward_the_goal_comes_before_a_lane_change() -> None:
    """USA_US101-9_1 (goal 7-8 s): at 2.6 and 3.1 s the replan finds no safe plan and the previous
    plan's remainder keeps clear; a lane change offered before it (a first version of the layer)
    moved the ego out of reach of the goal (missed, 5 of 11 window steps free).  A lane change
    replaces only a new fail-safe brake: the ego keeps its plan and reaches the goal, no contact.
    (Since the road planner of a522a9a every replan of this scene finds a safe plan, so no choice is
    made at all -- the report of a522a9a lists none either; the scene still must not change lanes.)"""
    from iamp.commonroad.interactive import simulate

    r = simulate(INTERACTIVE / "USA_US101-9_1_I-1-1", tactical=True)
    assert r["goal_reached"] and r["collisions"] == 0 and r["contacts_at_fault"] == 0
    assert r["lane_changes"] == 0
    assert all(d["action"] != "lane change" for d in r["decisions"])


def test_a_lane_change_is_never_a_two_stage_plan(monkeypatch: pytest.MonkeyPatch) -> None:
    """A lane change is one plan into the next lane: the offline planner's two-stage search through a
    waypoint around a vehicle is not tried for it (taken as a lane change at 6.5 s it made 23_1's ego
    end against the car standing in its goal region, at fault)."""
    import iamp.commonroad.tactical as tactical

    calls: list[dict[str, Any]] = []
    real = tactical.plan

    def spy(*args: Any, **kwargs: Any) -> Any:
        calls.append(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(tactical, "plan", spy)
    live = _live([])
    g = _goal(live)
    assert tactical.lane_change(live, "avoid", g.d, 0.0, g.s, g.tf) is not None
    assert calls and all(c.get("via") is False for c in calls)


def _goal_lane_gap_ahead(cr: Any) -> list[Any]:
    """The goal's lane (d 7.2) holds a column of cars at 15 m/s (the ego's speed) from 30 m behind
    the ego to 12 m ahead of it, 6 m apart (1.5 m bumper to bumper), and one more 60 m ahead: the
    only gap is ahead of the column; the middle lane is empty."""
    s0 = cr.x0[0]
    return [_moving(40 + i, s0 + 6.0 * i, 7.2, 15.0, 12.0) for i in range(-5, 3)] + [_moving(60, s0 + 60.0, 7.2, 15.0,
                                                                                             12.0)]


def test_one_lane_at_a_time_ends_where_the_goal_lane_is_out_of_reach_a_sequence_does_not() -> None:
    """The cheapest lane change into the middle lane keeps the ego level with the column in the
    goal's lane; from its end no lane change into the goal's lane is accepted (the gap ahead of the
    column is 26 m ahead, out of reach within a_max in 3 s).  Planned together -- the gap first,
    then the two lane changes toward it -- the ego speeds up in the middle lane and ends in the gap,
    every lane change within a_max and RSS-clear at its end (the column's last car behind at least
    the follower gap, the car 60 m ahead at least RSS's stopping distance), the body off every
    predicted vehicle all along."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import STOP_DECEL_FRACTION, advanced, follower_gap, lane_change, sequence
    from iamp.simulation.rss import DEFAULT, rss_distance

    cr = _fixture()
    cars = _goal_lane_gap_ahead(cr)
    live = _live(cars)
    g = _goal(live)
    one = lane_change(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert one is not None and one.candidate is not None and one.candidate.d == pytest.approx(3.6, abs=1e-3)
    T1 = one.candidate.tf
    assert one.trajectory is not None
    s1, v1, d1, vd1 = (float(v) for v in one.trajectory.states([T1])[0])
    x1 = (s1, v1, d1, vd1)
    assert lane_change(advanced(live, x1, T1), "avoid", g.d, T1, g.s, g.tf) is None
    seq = sequence(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert seq is not None and len(seq.parts) == 2
    T = seq.horizon
    assert not intrusions(live, seq, T)
    t = np.linspace(0.0, T, 121)
    U = seq.inputs(t)
    assert float(np.max(np.hypot(U[:, 0], U[:, 1]))) <= live.a_max + 1e-9
    for te, lane_d in zip(seq.ends, (3.6, 7.2)):
        s, v, d, vd = seq.states([te])[0]
        assert d == pytest.approx(lane_d, abs=1e-3) and vd == pytest.approx(0.0, abs=1e-6)
        for ob in cars:
            c = ob.cubic[0] + ob.cubic[1] * te
            if abs(ob.d_lo[0] + 0.9 - d) > 1.0:
                continue
            if c > s:
                gap = c - 2.25 - (s + 0.5 * cr.ego_length)
                assert gap >= float(rss_distance(v, 15.0, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max,
                                                 DEFAULT.brake_max)) - 1e-6
            else:
                assert (s - 0.5 * cr.ego_length) - (c + 2.25) >= follower_gap(15.0, v) - 1e-6
    s_end = seq.states([T])[0, 0]
    assert s_end > cr.x0[0] + 15.0 * T + 12.0  # ahead of the column


def test_advanced_is_the_prediction_seen_later() -> None:
    """The problem advanced by T: the ego at the given state, each vehicle's box at time 0 its box
    at T, its cubic the old one shifted by T."""
    from iamp.commonroad.tactical import advanced

    live = _live([_moving(7, 50.0, 3.6, 12.0)])
    x = (80.0, 14.0, 3.6, 0.0)
    later = advanced(live, x, 2.0)
    ob, ob0 = later.obstacles[0], live.obstacles[0]
    assert later.x0 == x and not later.candidates
    assert ob.t[0] == 0.0 and ob.s_lo[0] == pytest.approx(ob0.s_lo[20]) and ob.t.size == ob0.t.size - 20
    for tau in (0.0, 1.3, 4.0):
        assert np.polyval(ob.cubic[::-1], tau) == pytest.approx(np.polyval(ob0.cubic[::-1], tau + 2.0))


def test_stages_join_their_parts() -> None:
    """A sequence's states are each part's from its start, and the parts meet end to start."""
    from iamp.commonroad.planning import FreeTrajectory
    from iamp.commonroad.tactical import Stages

    a = FreeTrajectory(2.0, (0.0, 10.0, 0.0, 0.0), (22.0, 12.0, 3.6, 0.0))
    b = FreeTrajectory(3.0, (22.0, 12.0, 3.6, 0.0), (60.0, 13.0, 7.2, 0.0))
    st_ = Stages([(0.0, a, 2.0), (2.0, b, 3.0)])
    assert st_.horizon == 5.0 and st_.ends == [2.0, 5.0]
    np.testing.assert_allclose(st_.states([1.0, 2.0, 4.0]), np.vstack([a.states([1.0]), b.states([0.0]),
                                                                       b.states([2.0])]))
    np.testing.assert_allclose(a.states([2.0]), b.states([0.0]), atol=1e-9)
    np.testing.assert_allclose(st_.inputs([0.5, 3.0]), np.vstack([a.inputs([0.5]), b.inputs([1.0])]))


def test_a_sequence_under_way_is_given_up_when_a_car_cuts_into_its_middle_lane() -> None:
    """A sequence whose final state still holds is given up when a car now stands in the middle
    lane just ahead of where its first lane change ends (RSS-clear at every lane change's end, not
    only the last)."""
    from iamp.commonroad.tactical import sequence, still_holds

    cr = _fixture()
    live = _live(_goal_lane_gap_ahead(cr))
    g = _goal(live)
    seq = sequence(live, "avoid", g.d, 0.0, g.s, g.tf)
    assert seq is not None
    T1, T = seq.ends[0], seq.horizon
    assert still_holds(live, seq, T, [T1])
    s1, v1 = (float(x) for x in seq.states([T1])[0, :2])
    # a car in the middle lane, 2 m beyond the ego's front at T1 at the ego's speed then minus 6 m/s:
    # not in the way before T1 at its predicted speed, but inside RSS's stopping distance at T1
    v_c = v1 - 6.0
    c_T1 = s1 + 0.5 * cr.ego_length + 2.0 + 2.25
    cut = _live([*_goal_lane_gap_ahead(cr), _moving(90, c_T1 - v_c * T1, 3.6, v_c, 12.0)])
    assert not still_holds(cut, seq, T, [T1])


@settings(max_examples=8, deadline=None)
@given(st.lists(st.tuples(st.floats(-40.0, 40.0), st.floats(8.0, 22.0), st.sampled_from([3.6, 7.2])),
                min_size=1, max_size=5))
def test_an_accepted_sequence_keeps_clear_and_leaves_rss_room(cars: list[tuple[float, float, float]]) -> None:
    """Whatever the traffic in the middle lane and the goal's lane, a sequence the layer accepts keeps
    the body off every predicted vehicle, stays within a_max, and at each lane change's end every
    car ahead in that lane is at least RSS's stopping distance away and every car behind at least
    the follower gap."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import STOP_DECEL_FRACTION, follower_gap, sequence
    from iamp.simulation.rss import DEFAULT, rss_distance

    cr = _fixture()
    live = _live([_moving(20 + i, cr.x0[0] + ds, d, v, 12.0) for i, (ds, v, d) in enumerate(cars)])
    g = _goal(live)
    seq = sequence(live, "avoid", g.d, 0.0, g.s, g.tf)
    if seq is None:
        return
    assert not [h for h in intrusions(live, seq, seq.horizon) if not h.obstacle.road_edge]
    U = seq.inputs(np.linspace(0.0, seq.horizon, 121))
    assert float(np.max(np.hypot(U[:, 0], U[:, 1]))) <= live.a_max + 1e-9
    for te, lane_d in zip(seq.ends, (3.6, 7.2)):
        s, v, d, _ = seq.states([te])[0]
        assert d == pytest.approx(lane_d, abs=1e-3)
        for ds, vo, dc in cars:
            if dc != lane_d:
                continue
            c = cr.x0[0] + ds + vo * te
            if c > s:
                gap = c - 2.25 - (s + 0.5 * cr.ego_length)
                assert gap >= float(rss_distance(v, vo, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max,
                                                 DEFAULT.brake_max)) - 1e-6
            else:
                assert (s - 0.5 * cr.ego_length) - (c + 2.25) >= follower_gap(vo, v) - 1e-6


def test_no_lane_change_starts_beside_a_car_of_the_lane_it_enters() -> None:
    """USA_US101-23_1 (seed 2, lane-change sequences): at 9.3 s the ego moved toward lane 4 with
    vehicle 96 there beside it, 1.8 m ahead centre to centre and 6 m/s faster, counting on it to
    pull ahead; 96 braked briefly and the ego's front corner touched its rear at 9.8 s (the ego at
    fault: a lateral move toward a car it overlapped along the road).  A free lane change into the
    second lane is refused while a car of that lane is beside the ego now, though the car (at
    25 m/s against the ego's 15) is out of the plan's way after half a second; 12 m ahead it is
    accepted (RSS needs no distance behind a faster car)."""
    from iamp.commonroad.planning import intrusions
    from iamp.commonroad.tactical import beside, lane_change, stops_behind_along

    live = _live([])
    s0, v0, d0, _ = live.x0
    rp = lane_change(live, "avoid", 3.6, 0.0)
    assert rp is not None and rp.candidate is not None
    T = rp.candidate.tf
    for ahead, ok in ((1.8, False), (12.0, True)):
        car = _live([_moving(40, s0 + ahead, 3.6, v0 + 10.0)])
        assert not [h for h in intrusions(car, rp.trajectory, T) if not h.obstacle.road_edge]
        assert beside(car, s0, 3.6, 0.0) is not ok and not beside(car, s0, d0, 0.0)
        assert stops_behind_along(car, rp.trajectory, T) is ok
        assert (lane_change(car, "avoid", 3.6, 0.0) is not None) is ok
