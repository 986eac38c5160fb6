"""The closed loop's traffic at its start (SPEC §15): every vehicle of the initial platoon is on
the road from the first step or never, and the slow-leader truck is ahead of the ego.

SUMO refuses to insert a vehicle whose follower could not brake for it; by default such a
vehicle waits, holds back every later vehicle of its edge, and appears seconds later at its
departure position, beside whatever is there then.  Before the fix the slow-leader truck,
written after the ego (which departs at its top speed), was refused and appeared behind the
ego (slow-leader medium 55: 144 m behind at the mission's start), and merge dense 3 had 18
vehicles appear out of nowhere around the ego.
"""

from __future__ import annotations

import importlib.util

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.skipif(importlib.util.find_spec("libsumo") is None,
                                reason="SUMO is not installed (pip install 'iamp[sim]')")


def _simulator(mission_name: str, traffic: str, seed: int):
    from iamp.simulation.missions import EGO_DEPART_M, cooperation_of, courtesy_of, mission_of
    from iamp.simulation.simulator import Simulator

    mission = mission_of(mission_name)
    return mission, Simulator(traffic, seed, step=0.1, highway=mission.highway(), ego_lane=mission.ego_lane,
                              ego_pos=EGO_DEPART_M, empty_lanes=(0,) if mission.ramp else (),
                              cooperation=cooperation_of("default"), courtesy=courtesy_of("default"),
                              truck=(mission.truck_ahead_m, mission.truck_speed) if mission.truck else None)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mission=st.sampled_from(["merge", "onramp", "slow-leader"]),
       traffic=st.sampled_from(["light", "medium", "dense", "los-e"]), seed=st.integers(1, 10_000))
def test_no_initial_vehicle_departs_after_the_start(mission, traffic, seed):
    m, sim = _simulator(mission, traffic, seed)
    sim.start()
    try:
        ls = sim._ls
        on_road = set(ls.vehicle.getIDList())
        initial = sim._initial
        # nothing of the initial platoon waits to be inserted: it is on the road or was removed
        assert not set(ls.simulation.getPendingVehicles()) & initial
        assert set(sim.not_inserted) <= initial and not set(sim.not_inserted) & on_road
        for _ in range(150):  # 15 s
            sim.advance()
            late = [v for v in ls.simulation.getDepartedIDList() if v in initial]
            assert not late, f"initial vehicles {late} departed at t = {sim.t:.1f} s"
        if m.truck:
            # the truck is on the road from the start, ahead of the ego in its lane
            assert "truck_lead" in on_road
    finally:
        sim.close()


@pytest.mark.parametrize("traffic", ["medium", "dense", "los-e"])
@pytest.mark.parametrize("seed", [3, 55])
def test_the_slow_leader_truck_departs_ahead_of_the_ego(traffic, seed):
    m, sim = _simulator("slow-leader", traffic, seed)
    sim.start()
    try:
        ls = sim._ls
        ego_front = ls.vehicle.getLanePosition("ego")
        truck_front = ls.vehicle.getLanePosition("truck_lead")
        assert ls.vehicle.getLaneIndex("truck_lead") == ls.vehicle.getLaneIndex("ego") == m.ego_lane
        # its front bumper truck_ahead_m ahead of the ego's at departure (both moved one or two steps)
        assert abs((truck_front - ego_front) - m.truck_ahead_m) < 5.0
        # and the ego, inserted after it, departs no faster than it can follow it
        assert ls.vehicle.getSpeed("ego") <= 25.0
    finally:
        sim.close()


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mission=st.sampled_from(["merge", "onramp", "slow-leader", "discretionary"]),
       traffic=st.sampled_from(["light", "medium", "dense", "los-e"]), seed=st.integers(1, 10_000))
def test_the_ego_drives_at_most_the_speed_limit_before_the_mission(mission, traffic, seed):
    """The ego's (and the truck's) speed factor is 1: SUMO draws a vType's factor from its
    ``speedDev`` (0.1 by default) unless it is set to 0, and the ego began missions at up to 1.43
    times the speed limit (merge light 9: 47.5 m/s on a 33.3 m/s road).  During the warm-up SUMO
    drives the ego at no more than the limit of its lane."""
    m, sim = _simulator(mission, traffic, seed)
    sim.start()
    try:
        ls = sim._ls
        assert ls.vehicle.getSpeedFactor("ego") == 1.0
        if m.truck:
            assert ls.vehicle.getSpeedFactor("truck_lead") == 1.0
        for _ in range(40):  # 4 s
            sim.advance()
            lane_limit = ls.lane.getMaxSpeed(ls.vehicle.getLaneID("ego"))
            assert ls.vehicle.getSpeed("ego") <= lane_limit + 1e-6
    finally:
        sim.close()
