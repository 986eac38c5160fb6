"""The closed loop's RSS responses beyond the plan (SPEC §17): the lane keeping's lateral proper
response (``Controller._lateral_caps``) and the cars it follows beyond a fixed range
(``rss.within_rss_reach``), judged by the independent monitor on episodes where the ego had been
responsible (docs/closed-loop.md, "RSS at fault").

The lateral proper response (the judge, :func:`iamp.simulation.rss.judge_pair`): in a dangerous
run whose proper response is lateral, a car may not move toward the other faster than RSS's
fluctuation ``μ/ρ`` (0.2 m/s) unless it brakes that motion with at least ``lat_brake_min``.  The
lane keeping caps its speed toward a car that is closer than its RSS longitudinal distance and
laterally near at 0.8 ``μ/ρ``, and brakes a faster motion at its own 1.5 m/s² bound at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.controller import (
    LATERAL_ACCEL_SHARE,
    LATERAL_REST_SHARE,
    Controller,
    ControllerConfig,
    LateralCaps,
    _observed_extents,
)
from iamp.simulation.decision import Neighbour
from iamp.simulation.network import Highway
from iamp.simulation.rss import DEFAULT, safe_longitudinal_float
from iamp.simulation.simulator import EgoState

REST = LATERAL_REST_SHARE * DEFAULT.lat_margin_m / DEFAULT.response_time_s


@dataclass
class _Sim:
    ego_length: float = 4.8
    ego_width: float = 1.8
    ego_heading: float = 0.0
    step: float = 0.1
    highway: Highway = field(default_factory=Highway)


def _controller() -> Controller:
    """A controller with only what the lane keeping reads (its configuration and the ego's body)."""
    c = Controller.__new__(Controller)
    c.cfg = ControllerConfig()
    c.sim = _Sim()  # type: ignore[assignment]
    c.heading = 0.0
    return c


def car(dx: float, dy: float, v: float, vy: float = 0.0) -> Neighbour:
    return Neighbour("n", (dx, v), y=dy, length=4.8, width=1.8, lane=0, vy=vy)


EGO = EgoState(x=0.0, vx=20.0, y=0.0, vy=0.0)


def test_a_faster_car_behind_in_the_next_lane_caps_the_motion_toward_it_only() -> None:
    """30 m behind at 28 m/s (RSS distance about 62 m), 2.5 m to the right (a 0.7 m gap between
    the bodies: the ego straddles the lane line), the ego returning right at 0.3 m/s: it may move
    right at most at the cap, left freely; 130 m behind (beyond its RSS distance, 100 m) nothing; one lane
    away (3.5 m, a 1.7 m gap) the ego at rest is not capped, at 1 m/s toward it is (RSS's lateral
    distance grows with the speed toward the other)."""
    c = _controller()
    assert safe_longitudinal_float(28.0, 20.0) > 30.0
    returning = EgoState(x=0.0, vx=20.0, y=0.0, vy=-0.3)
    left, right = c._lateral_caps(returning, [car(-30.0, -2.5, 28.0)])[:2]
    assert right == pytest.approx(REST) and left == np.inf
    assert c._lateral_caps(returning, [car(-130.0, -2.5, 28.0)])[:2] == (np.inf, np.inf)
    assert c._lateral_caps(EGO, [car(-30.0, -3.5, 28.0)])[:2] == (np.inf, np.inf)
    fast = EgoState(x=0.0, vx=20.0, y=0.0, vy=-1.0)
    assert c._lateral_caps(fast, [car(-30.0, -3.5, 28.0)])[1] == pytest.approx(REST)
    # two lanes away (7 m): laterally far, no cap
    assert c._lateral_caps(fast, [car(-30.0, -7.0, 28.0)])[:2] == (np.inf, np.inf)


def test_a_level_or_overlapping_car_caps_both_sides() -> None:
    """A follower 10 m behind in the ego's lane (level within μ, or overlapping sideways while it
    changes lanes behind the ego): the judge's roles are those of the run's threshold time, so
    both sides are capped."""
    c = _controller()
    assert c._lateral_caps(EGO, [car(-15.0, 0.05, 22.0)])[:2] == (pytest.approx(REST), pytest.approx(REST))
    assert c._lateral_caps(EGO, [car(-15.0, 1.2, 22.0)])[:2] == (pytest.approx(REST), pytest.approx(REST))


def test_the_caps_measure_the_observed_state_as_the_judge_does() -> None:
    """The judge measures a pair with the logged state (SUMO's speed times ``cos ψ``, its heading);
    the prediction's cubic may start elsewhere (slow-leader light 16: a car braking at 2 m/s² while
    it changed lanes behind the aborting ego, its cubic 0.46 m/s slower than observed, so the caps
    found the pair longitudinally safe, 13.68 m against 13.42 m, where the judge's distance was
    14.49 m, lifted the cap on the side the judge blamed and the ego's return sped up: 0.6 s at
    fault).  The caps and the front danger read :attr:`Neighbour.now` where it is known: the same
    pair is capped on both sides with the observed speed and not with the predicted one."""
    c = _controller()
    ego = EgoState(x=0.0, vx=3.86, y=0.0, vy=-0.16)
    v_obs, v_pred = 7.77, 7.31
    gap = 18.52 - 4.8
    assert safe_longitudinal_float(v_obs, 3.86) > gap > safe_longitudinal_float(v_pred, 3.86)
    predicted = Neighbour("n", (-18.52, v_pred), y=1.215, length=4.8, width=1.8, lane=0, vy=1.07)
    observed = Neighbour("n", (-18.52, v_pred), y=1.215, length=4.8, width=1.8, lane=0, vy=1.07,
                         now=(-18.52, v_obs, 0.0))
    assert c._lateral_caps(ego, [predicted])[:2] == (pytest.approx(REST), np.inf)
    assert c._lateral_caps(ego, [observed])[:2] == (pytest.approx(REST), pytest.approx(REST))
    # the observed heading sets the body's extents: at 30° the body reaches 1.98 m sideways, not 0.9 m,
    # and 2.5 m to the left it overlaps the ego's sideways (both sides capped); straight, 0.7 m apart
    rest = EgoState(x=0.0, vx=3.86, y=0.0, vy=0.0)
    turned = Neighbour("n", (-18.52, v_obs), y=2.5, length=4.8, width=1.8, lane=0,
                       now=(-18.52, v_obs, float(np.radians(30.0))))
    straight = Neighbour("n", (-18.52, v_obs), y=2.5, length=4.8, width=1.8, lane=0, now=(-18.52, v_obs, 0.0))
    assert c._lateral_caps(rest, [turned])[:2] == (pytest.approx(REST), pytest.approx(REST))
    assert c._lateral_caps(rest, [straight])[:2] == (pytest.approx(REST), np.inf)
    # the front danger alike: a car ahead observed slower than its cubic starts
    ahead_obs = Neighbour("a", (20.0, 12.0), y=0.0, length=4.8, width=1.8, lane=0, now=(20.0, 9.0, 0.0))
    ahead_pred = Neighbour("a", (20.0, 12.0), y=0.0, length=4.8, width=1.8, lane=0)
    fast = EgoState(x=0.0, vx=10.0, y=0.0, vy=0.0)
    assert safe_longitudinal_float(10.0, 9.0) > 20.0 - 4.8 > safe_longitudinal_float(10.0, 12.0)
    assert c._front_danger(fast, [ahead_obs]) is ahead_obs
    assert c._front_danger(fast, [ahead_pred]) is None


def test_the_bodies_are_at_their_observed_headings_else_at_their_predicted_velocity() -> None:
    """:func:`_observed_extents` of a list mixing neighbours with and without an observed state: a
    body at its observed heading where it is known (``body_extents``), else at the heading of its
    predicted velocity now, ``atan2(v_y, v(0))`` (a cubic whose speed changes: ``v(0) = 4`` m/s, not
    its speed a second later, 10 m/s), each the number of its own call."""
    from iamp.simulation.failsafe import body_half_extents
    from iamp.simulation.rss import body_extents

    seen = Neighbour("seen", (0.0, 10.0), y=0.0, length=4.8, width=1.8, lane=0, vy=1.0,
                     now=(0.0, 10.0, float(np.radians(30.0))))
    predicted = Neighbour("pred", (0.0, 4.0, 3.0), y=0.0, length=4.6, width=2.0, lane=0, vy=2.0)
    HX, HY = _observed_extents([seen, predicted])
    hx, hy = body_extents(4.8, 1.8, np.radians(30.0))
    px, py = body_half_extents(4.0, 2.0, 4.6, 2.0)
    assert (HX[0], HY[0]) == (float(hx), float(hy))
    assert (HX[1], HY[1]) == (float(px), float(py))
    assert float(py) != float(body_half_extents(10.0, 2.0, 4.6, 2.0)[1])
    # every one known, every one predicted: the same numbers one by one
    assert _observed_extents([seen])[1][0] == HY[0] and _observed_extents([predicted])[1][0] == HY[1]


@settings(max_examples=100, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-3.0, 3.0), st.floats(1.0, 30.0))
def test_the_lane_keeping_keeps_the_cap_or_brakes_toward_it(vy0: float, offset: float, vx: float) -> None:
    """One period of :meth:`Controller._move` toward any lane centre, with the right side capped:
    the lateral speed to the right after it is at most the cap, or (already faster) smaller by the
    lane keeping's full bound 1.5 m/s² per period, more than RSS's ``lat_brake_min`` (0.8 m/s²);
    the left side is left alone."""
    c = _controller()
    ego = EgoState(x=0.0, vx=vx, y=0.0, vy=vy0, ax=0.0, ay=0.0)
    nxt = c._move(ego, 0.0, offset, caps=LateralCaps(np.inf, REST))
    free = c._move(ego, 0.0, offset)
    toward0, toward1 = -vy0, -nxt.vy
    lim = c.cfg.lane_keep_ay * 0.1
    assert toward1 <= max(REST, toward0 - min(lim, toward0 - REST)) + 1e-12
    assert toward1 <= REST + 1e-12 or toward1 <= toward0 - DEFAULT.lat_brake_min * 0.1
    if -free.vy <= REST:
        assert nxt.vy == free.vy  # a cap not reached changes nothing


@pytest.mark.parametrize(("mission", "traffic", "seed", "before"),
                         [("slow-leader", "los-e", 69, 12.9), ("slow-leader", "medium", 29, 11.2),
                          ("merge", "medium", 9, 2.5)])
def test_episodes_where_the_ego_was_at_fault_are_not_any_more(mission: str, traffic: str, seed: int,
                                                              before: float) -> None:
    """``free`` episodes of reports/campaign-safe (15351b0) with RSS-dangerous time at fault
    ``before`` [s]: a lane change away from a follower level with the ego (LOS E 69: the judge's
    roles), a lane change in front of a car 137 m behind at 34 m/s (medium 29: beyond the fixed
    range; then the fail-safe's return toward a car in the next lane), a fast ego behind a slow car
    145 m ahead (merge medium 9).  Now none, each still a success without a contact.  (With the
    traffic at the start of episode format 17.4, LOS E 69 had 0.2 s at fault of another kind after
    its change: a car in the next lane drifting toward the ego's lane, which the tactical layer did
    not follow until its body was over the lane, :meth:`Controller._rss_leader`.)"""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission=mission, traffic=traffic, seed=seed, planner="free")).summary
    assert s["rss_dangerous_s"] == 0.0 and s["success"] and s["contacts"] == 0


def test_a_car_about_to_be_too_close_keeps_the_speed_toward_it_from_growing() -> None:
    """A car in the next lane behind, 4 m/s faster than the ego: its gap is 1 m beyond RSS's
    distance now and closes by 2 m in a response time.  The lane keeping may keep its speed toward
    it (0.5 m/s) but not raise it (the judge allows 0.2 m/s² toward the other for a response time
    after the pair turns dangerous; the return to a lane's centre accelerated at 1.3 m/s² the step
    it did, slow-leader medium 45); safe for longer than a response time it is free; unsafe
    already, RSS's fluctuation; a level car about to be unsafe caps only the side it is on."""
    c = _controller()
    ego = EgoState(x=0.0, vx=20.0, y=0.0, vy=-0.5)
    d = safe_longitudinal_float(24.0, 20.0)
    dx = -(d + 1.0 + 4.8)  # bumper gap d + 1 m: safe now, unsafe within ρ at 4 m/s closing (2 m)
    assert c._lateral_caps(ego, [car(dx, -2.5, 24.0)])[:2] == (np.inf, pytest.approx(0.5))
    still = EgoState(x=0.0, vx=20.0, y=0.0, vy=0.0)
    assert c._lateral_caps(still, [car(dx, -2.5, 24.0)])[:2] == (np.inf, pytest.approx(REST))
    # safe for longer than a response time (3 m beyond the distance at 4 m/s closing): free
    assert c._lateral_caps(ego, [car(-(d + 3.0 + 4.8), -2.5, 24.0)])[:2] == (np.inf, np.inf)
    # a car as fast as the ego with the same gap stays safe: free
    assert c._lateral_caps(ego, [car(dx, -2.5, 20.0)])[:2] == (np.inf, np.inf)
    # unsafe now: RSS's fluctuation
    assert c._lateral_caps(ego, [car(-(d - 1.0 + 4.8), -2.5, 24.0)])[:2] == (np.inf, pytest.approx(REST))
    # level (5 cm to the left) and about to be unsafe: its side only; unsafe: both sides
    assert c._lateral_caps(still, [car(dx, 0.05, 24.0)])[:2] == (pytest.approx(REST), np.inf)
    assert c._lateral_caps(still, [car(-(d - 1.0 + 4.8), 0.05, 24.0)])[:2] == (pytest.approx(REST), pytest.approx(REST))


@pytest.mark.parametrize(("mission", "traffic", "seed"),
                         [("slow-leader", "dense", 2), ("slow-leader", "dense", 89), ("merge", "medium", 85)])
def test_a_lane_change_does_not_start_beside_a_car_rss_constrains(mission: str, traffic: str, seed: int) -> None:
    """Episodes of the campaign of fce4332 where the ego started a lane change while a follower in
    its own lane was closer than its RSS distance (level with the ego: the judge gives the pair the
    side they separate to, and the follower changed lanes too, so the ego's start moved toward it;
    2.0, 2.2 and 1.6 s at fault with ``pmp-active``).  The loop now does not start a change while
    :meth:`Controller._lateral_caps` caps the target lane's side (rejection ``rss-lateral``): none at
    fault, still a success without a contact."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission=mission, traffic=traffic, seed=seed, planner="pmp-active")).summary
    assert s["rss_dangerous_s"] == 0.0 and s["success"] and s["contacts"] == 0
    assert s["rejected"].get("rss-lateral", 0) > 0


_RoadSim = _Sim  # the lane keeping reads the highway's lane width too


def test_the_tactical_layer_follows_a_car_cutting_in_before_its_body_is_over_the_lane() -> None:
    """A car 30 m ahead in the next lane moving toward the ego's lane at 1 m/s (its lateral gap
    0.8 m, below RSS's lateral distance of that speed) is followed like the lane's leader; the same
    car keeping its lane (no lateral speed: RSS's lateral distance about 0.16 m) or moving away is
    not; a nearer leader in the lane stays the leader."""
    c = _controller()
    c.sim = _RoadSim()  # type: ignore[assignment]
    y = c.sim.highway.lane_centre(1)
    ego = EgoState(x=0.0, vx=20.0, y=y, vy=0.0)
    cutting = Neighbour("cut", (30.0, 18.0), y=y - 2.6, length=4.8, width=1.8, lane=0, vy=1.0)
    keeping = Neighbour("keep", (30.0, 18.0), y=y - 2.6, length=4.8, width=1.8, lane=0, vy=0.0)
    away = Neighbour("away", (30.0, 18.0), y=y - 2.6, length=4.8, width=1.8, lane=0, vy=-1.0)
    assert c._rss_leader(ego, [cutting]) is cutting
    assert c._rss_leader(ego, [keeping]) is None and c._rss_leader(ego, [away]) is None
    near = Neighbour("lead", (15.0, 18.0), y=y, length=4.8, width=1.8, lane=1, vy=0.0)
    assert c._rss_leader(ego, [cutting, near]) is near
    # behind the ego: never a leader
    behind = Neighbour("behind", (-30.0, 18.0), y=y - 2.6, length=4.8, width=1.8, lane=0, vy=1.0)
    assert c._rss_leader(ego, [behind]) is None


@settings(max_examples=300, deadline=None)
@given(vy=st.floats(-1.5, 1.5),
       cars=st.lists(st.tuples(st.floats(-60.0, 80.0), st.sampled_from([-1.0, 1.0]),
                               st.floats(-1.0, 1.0).filter(lambda e: abs(e) > 1e-9),  # no exact tie
                               st.floats(-1.5, 1.5), st.floats(1.6, 2.6), st.floats(0.0, 35.0)),
                     min_size=0, max_size=6))
def test_the_followed_car_is_the_nearest_of_the_lane_leader_and_the_cars_rss_finds_laterally_near(
        vy: float, cars: list[tuple[float, float, float, float, float, float]]) -> None:
    """:meth:`Controller._rss_leader` against its statement, computed here from RSS's lateral
    distance: of the vehicles ahead, those whose body overlaps the ego's lane band (less 0.2 m) and
    those whose lateral gap to the ego is below RSS's lateral distance of their lateral speeds
    toward each other, the nearest; none without such a vehicle.  Each car is placed on a side with
    its lateral gap within 1 m of that distance (``excess``), where the two sets part."""
    from iamp.simulation.rss import safe_lateral_distance

    c = _controller()
    c.sim = _RoadSim()  # type: ignore[assignment]
    hw = c.sim.highway
    y = hw.lane_centre(1)
    ego = EgoState(x=0.0, vx=20.0, y=y, vy=vy)
    nbs, want = [], []
    for i, (dx, side, excess, nvy, w, v) in enumerate(cars):
        toward_ego, toward_other = (vy, -nvy) if side > 0 else (-vy, nvy)
        d_lat = float(safe_lateral_distance(toward_ego, toward_other, DEFAULT))
        dy = side * ((w + 1.8) / 2 + d_lat + excess)
        n = Neighbour(f"n{i}", (dx, v), y=y + dy, length=4.8, width=w, lane=hw.lane_of(y + dy), vy=nvy)
        nbs.append(n)
        in_band = abs(dy) < hw.lane_width / 2 + w / 2 - 0.2
        if dx > 0 and (in_band or abs(dy) - (w + 1.8) / 2 < d_lat):
            want.append(n)
    got = c._rss_leader(ego, nbs)
    if not want:
        assert got is None
    else:
        assert got is not None and got.x(0.0) == min(n.x(0.0) for n in want)


def test_the_fail_safe_brakes_at_least_as_rss_s_proper_response_behind_a_car_too_close() -> None:
    """During the fail-safe (``abort``) the ego brakes at least ``brake_min`` while the car it
    follows is closer than RSS's distance (merge light 68: 2.3 s at fault braking at the verified
    fail-safe's 1.5 m/s² behind a car 69 m ahead where RSS asked 72 m); beyond it, 0 (the
    fail-safe's own deceleration applies)."""
    from iamp.simulation.network import Highway
    from iamp.simulation.rss import safe_longitudinal_float

    c = _controller()
    c.sim.highway = Highway()  # type: ignore[attr-defined]
    ego = EgoState(x=0.0, vx=21.7, y=c.sim.highway.lane_centre(1), vy=0.0)  # type: ignore[attr-defined]
    d = safe_longitudinal_float(21.7, 13.5, DEFAULT)
    half = (4.8 + c.sim.ego_length) / 2
    near = car(d + half - 1.0, ego.y, 13.5)
    far = car(d + half + 1.0, ego.y, 13.5)
    assert c._proper_brake(ego, [near]) == DEFAULT.brake_min
    assert c._proper_brake(ego, [far]) == 0.0
    assert c._proper_brake(ego, []) == 0.0


ACCEL = LATERAL_ACCEL_SHARE * DEFAULT.lat_accel_max


def test_a_car_beside_not_longitudinally_safe_caps_the_acceleration_toward_it() -> None:
    """A car of the next lane 30 m behind at 28 m/s (not longitudinally safe), its lateral gap 2.6 m
    (farther than RSS's lateral distance plus the room at these lateral speeds: no speed cap),
    changing lanes toward the ego at 0.3 m/s (beyond RSS's fluctuation μ/ρ = 0.2 m/s): the lateral
    acceleration toward it is capped at ``LATERAL_ACCEL_SHARE`` of RSS's ``a_lat,max``, the other
    side is not; the same car keeping its lane (or moving at μ/ρ), beyond a lane width, or
    longitudinally safe caps nothing."""
    c = _controller()
    caps = c._lateral_caps(EGO, [car(-30.0, -(1.8 + 2.6), 28.0, vy=0.3)])
    assert caps == (np.inf, np.inf, np.inf, pytest.approx(ACCEL))
    assert c._lateral_caps(EGO, [car(-30.0, 1.8 + 2.6, 28.0, vy=-0.3)]) == (np.inf, np.inf, pytest.approx(ACCEL),
                                                                           np.inf)
    assert c._lateral_caps(EGO, [car(-30.0, -(1.8 + 2.6), 28.0)]) == (np.inf,) * 4
    assert c._lateral_caps(EGO, [car(-30.0, -(1.8 + 2.6), 28.0, vy=0.2)]) == (np.inf,) * 4
    assert c._lateral_caps(EGO, [car(-30.0, -(1.8 + 2.6), 28.0, vy=-0.3)]) == (np.inf,) * 4
    lane = c.sim.highway.lane_width
    # beyond a lane width at its heading (0.6° at 0.3 m/s sideways and 28 m/s: 2.5 cm wider than straight)
    assert c._lateral_caps(EGO, [car(-30.0, -(1.8 + lane + 0.01), 28.0, vy=0.3)])[3] == pytest.approx(ACCEL)
    assert c._lateral_caps(EGO, [car(-30.0, -(1.8 + lane + 0.04), 28.0, vy=0.3)]) == (np.inf,) * 4
    assert c._lateral_caps(EGO, [car(-130.0, -(1.8 + 2.6), 28.0, vy=0.3)]) == (np.inf,) * 4
    # the bodies overlapping sideways, not longitudinally safe: both sides, speed and acceleration
    assert c._lateral_caps(EGO, [car(-15.0, 1.2, 22.0)]) == (pytest.approx(REST), pytest.approx(REST),
                                                                pytest.approx(ACCEL), pytest.approx(ACCEL))


@settings(max_examples=400, deadline=None)
@given(u0=st.floats(-0.5, 1.5), a0=st.floats(-0.5, 1.5), toward=st.floats(0.0, 4.0), vx=st.floats(1.0, 30.0),
       dx=st.floats(-50.0, 20.0), side=st.sampled_from([-1.0, 1.0]), gap=st.floats(-0.5, 4.5),
       nvy=st.floats(-1.5, 1.5), v=st.floats(10.0, 35.0))
def test_the_lane_keeping_never_accelerates_toward_a_car_faster_than_rss_allows_at_a_threshold(
        u0: float, a0: float, toward: float, vx: float, dx: float, side: float, gap: float, nvy: float,
        v: float) -> None:
    """The judge's rule for the first period of a dangerous run whose response is lateral
    (:func:`iamp.simulation.rss._complies`, the period starting at the threshold time): the speed toward
    the other after it at most ``max(u0 + a_lat,max dt, μ/ρ)``.  Whatever the lane keeping's target and
    state (``u0``, ``a0``: the lateral speed and input toward the car's side; ``toward``: the lane centre
    that far toward it), one period of :meth:`Controller._move` under :meth:`Controller._lateral_caps`
    keeps it toward every car within a lane width that is not longitudinally safe and moves toward
    the ego beyond RSS's fluctuation (the pair may turn dangerous in that period by the other's own
    lateral motion)."""
    from iamp.simulation.rss import longitudinal_room

    c = _controller()
    vy0 = side * u0
    ego = EgoState(x=0.0, vx=vx, y=0.0, vy=vy0, ax=0.0, ay=side * a0)
    n = Neighbour("n", (dx, v), y=side * ((1.8 + 1.8) / 2 + gap), length=4.8, width=1.8, lane=0, vy=nvy)
    nxt = c._move(ego, 0.0, side * toward, caps=c._lateral_caps(ego, [n]))
    lon_gap, d_lon = longitudinal_room(dx, 4.8, v, vx, 4.8, DEFAULT)
    rest = DEFAULT.lat_margin_m / DEFAULT.response_time_s
    if (lon_gap > 0 and lon_gap >= d_lon) or gap > c.sim.highway.lane_width or -side * nvy <= rest:
        return
    toward0, toward1 = side * vy0, side * nxt.vy
    assert toward1 <= max(toward0 + DEFAULT.lat_accel_max * 0.1, rest) + 1e-12


@pytest.mark.parametrize(("traffic", "seed", "before"), [("los-e", 7003, 6.1), ("dense", 7005, 6.8)])
def test_the_fail_safe_return_does_not_accelerate_toward_a_car_changing_lanes_behind(
        traffic: str, seed: int, before: float) -> None:
    """Discretionary episodes of seeds no campaign uses (docs/closed-loop.md): after an abort the
    fail-safe's return to its lane accelerated sideways (0.27 and 1.5 m/s²) toward a car of the lane
    beyond that started a lane change behind the ego into that lane in the same period, ``before``
    seconds at fault with ``pmp-active``.  With the acceleration cap of :meth:`Controller._lateral_caps`:
    none, still a success without a contact."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission="discretionary", traffic=traffic, seed=seed, planner="pmp-active")).summary
    assert s["rss_dangerous_s"] == 0.0 and s["success"] and s["contacts"] == 0


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_the_acceleration_cap_adds_its_own_share_per_period_above_the_rest_share(side: float) -> None:
    """One period of :meth:`Controller._move` with an acceleration cap on one side and the lane keeping
    pulling hard toward it (its lane centre 3 m away): moving toward it at 0.5 m/s, the speed toward
    it grows by exactly the cap times the period; from below the rest share 0.8 μ/ρ, it reaches it (the
    judge's fluctuation allows it whatever the acceleration); moving away, nothing changes; the
    other side's cap leaves it alone."""
    c = _controller()
    caps = LateralCaps(np.inf, np.inf, ACCEL, np.inf) if side > 0 else LateralCaps(np.inf, np.inf, np.inf, ACCEL)
    other = LateralCaps(np.inf, np.inf, np.inf, ACCEL) if side > 0 else LateralCaps(np.inf, np.inf, ACCEL, np.inf)
    moving = EgoState(x=0.0, vx=20.0, y=0.0, vy=side * 0.5, ax=0.0, ay=side * 1.0)
    nxt = c._move(moving, 0.0, side * 3.0, caps=caps)
    assert side * nxt.vy == pytest.approx(0.5 + ACCEL * 0.1, abs=1e-12)
    assert side * nxt.ay == pytest.approx(ACCEL, abs=1e-12)
    free = c._move(moving, 0.0, side * 3.0)
    assert side * free.vy > 0.5 + 0.2 * 0.1  # the lane keeping alone: faster than RSS allows
    assert c._move(moving, 0.0, side * 3.0, caps=other) == free
    slow = EgoState(x=0.0, vx=20.0, y=0.0, vy=side * 0.1, ax=0.0, ay=side * 1.5)
    assert side * c._move(slow, 0.0, side * 3.0).vy > REST
    assert side * c._move(slow, 0.0, side * 3.0, caps=caps).vy == pytest.approx(REST, abs=1e-12)
    away = EgoState(x=0.0, vx=20.0, y=0.0, vy=-side * 0.5, ax=0.0, ay=side * 1.0)
    assert c._move(away, 0.0, side * 3.0, caps=caps) == c._move(away, 0.0, side * 3.0)


def test_the_gaps_are_the_bodies_at_their_headings() -> None:
    """The judge measures the gaps between the bodies at their headings (``rss.body_extents``), and
    so do the caps.  The ego stopped 33° to the road after merging at a crawl (onramp LOS E 9003,
    the simulator keeps the heading it stopped with): its body reaches 2.07 m sideways, not 0.9 m.
    A car of the next lane 19 m behind at 13 m/s (not longitudinally safe), 3.7 m to the left:
    straight, the gap 1.9 m is beyond RSS's lateral distance plus the room, no cap; at 33° it is
    0.73 m, the speed toward it capped at the rest share; nearer than RSS's lateral distance,
    no motion toward it at all (RSS lets a car drift at its fluctuation; the ego crept its nose into a
    passing car that way); the side away from it is free in every case."""
    c = _controller()
    psi = np.radians(33.0)
    ego = EgoState(x=0.0, vx=0.0, y=0.0, vy=0.0)
    behind = car(-(19.0 + 4.8), 3.7, 13.0)
    c.sim = _Sim(ego_heading=0.0)  # type: ignore[assignment]
    assert c._lateral_caps(ego, [behind])[:2] == (np.inf, np.inf)
    c.sim = _Sim(ego_heading=float(psi))  # type: ignore[assignment]
    hy = 2.4 * np.sin(psi) + 0.9 * np.cos(psi)
    assert 3.7 - hy - 0.9 == pytest.approx(0.73, abs=0.01)
    assert c._lateral_caps(ego, [behind])[:2] == (pytest.approx(REST), np.inf)
    assert c._lateral_caps(ego, [car(-(19.0 + 4.8), hy + 0.9 + 0.15, 13.0)])[:2] == (0.0, np.inf)
    # longitudinally safe (far behind): no cap whatever the heading
    assert c._lateral_caps(ego, [car(-200.0, hy + 0.9 + 0.15, 13.0)])[:2] == (np.inf, np.inf)
    # the mirror image: the car on the right, the ego turned right
    c.sim = _Sim(ego_heading=float(-psi))  # type: ignore[assignment]
    assert c._lateral_caps(ego, [car(-(19.0 + 4.8), -3.7, 13.0)])[:2] == (np.inf, pytest.approx(REST))


@pytest.mark.parametrize(("mission", "traffic", "seed", "before"),
                         [("onramp", "los-e", 9003, 0.9), ("discretionary", "light", 9001, 0.1)])
def test_episodes_at_fault_with_the_body_at_its_heading_are_not_any_more(mission: str, traffic: str, seed: int,
                                                                        before: float) -> None:
    """Seeds no campaign uses, ``free`` (the same for ``pmp-active`` and ``qp-avoid``), with RSS time at
    fault ``before`` [s] when the caps took the bodies straight: the ego stopped 33° to the road at the
    end of the ramp and straightened toward a car of the next lane closing from behind (9003); the
    abort's return moved away from a car whose body, at the ego's heading, overlapped it sideways, at
    more than RSS's fluctuation (9001).  Now none, a success without a contact."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission=mission, traffic=traffic, seed=seed, planner="free")).summary
    assert s["rss_dangerous_s"] == 0.0 and s["success"] and s["contacts"] == 0


def test_the_front_danger_is_rss_s_rear_car_situation() -> None:
    """:meth:`Controller._front_danger`: a vehicle ahead closer, bumper to bumper, than RSS's
    longitudinal distance of the two speeds and laterally nearer than RSS's lateral distance (the
    bodies at their headings) — the situation in which RSS asks the rear car, the ego, to brake with
    ``brake_min``; the nearest such vehicle; none behind, beyond the distance, or a lane away.  Each
    threshold is probed 5 cm either side; the others' predictions accelerate (their speed now is
    the one that counts) and the ego is away from the origin."""
    c = _controller()
    c.sim = _RoadSim()  # type: ignore[assignment]
    y = c.sim.highway.lane_centre(1)
    x0 = 250.0
    ego = EgoState(x=x0, vx=30.0, y=y, vy=0.0)
    d = safe_longitudinal_float(30.0, 20.0)

    def ahead(name: str, gap: float, dy: float = 0.0, vy: float = 0.0, lane: int = 1) -> Neighbour:
        # a bumper gap ``gap`` ahead at 20 m/s now, accelerating at 1 m/s²
        return Neighbour(name, (x0 + gap + 4.8, 20.0, 0.5), y=y + dy, length=4.8, width=1.8, lane=lane, vy=vy)

    near, far = ahead("near", d - 0.05), ahead("far", d + 0.05)
    assert c._front_danger(ego, [near]) is near and c._proper_brake(ego, [near]) == DEFAULT.brake_min
    assert c._front_danger(ego, [far]) is None
    # overlapping the ego's body from just ahead (centres 0.5 m apart): dangerous
    touching = Neighbour("touch", (x0 + 0.5, 20.0, 0.5), y=y, length=4.8, width=1.8, lane=1, vy=0.0)
    assert c._front_danger(ego, [touching]) is touching
    # a lane away, keeping its lane (1.95 m between the bodies, RSS's lateral distance 0.1 m): none
    beside = ahead("beside", d - 0.05, 3.75, lane=2)
    assert c._front_danger(ego, [beside]) is None
    # moving toward the ego's lane: dangerous once the gap is below RSS's lateral distance of that speed
    from iamp.simulation.rss import safe_lateral_distance

    for vy in (-1.0, -2.0):
        d_lat = float(safe_lateral_distance(0.0, -vy, DEFAULT))
        psi = np.arctan2(vy, 20.0)  # its body at its heading reaches further sideways
        hy = 2.4 * abs(np.sin(psi)) + 0.9 * abs(np.cos(psi))
        inside = ahead("in", d - 0.05, 0.9 + hy + d_lat - 0.05, vy=vy, lane=2)
        outside = ahead("out", d - 0.05, 0.9 + hy + d_lat + 0.05, vy=vy, lane=2)
        assert c._front_danger(ego, [inside]) is inside and c._front_danger(ego, [outside]) is None
    # behind the ego, however close: not the ego's to brake for
    behind = Neighbour("behind", (x0 - 10.0, 35.0), y=y, length=4.8, width=1.8, lane=1, vy=0.0)
    assert c._front_danger(ego, [behind]) is None
    nearer = ahead("nearer", d - 10.0)
    assert c._front_danger(ego, [near, nearer]) is nearer and c._front_danger(ego, [nearer, near]) is nearer
    # the ego turned 20° reaches 2.56 m ahead, not 2.4 m: a car 8 cm beyond the distance of a straight
    # body is inside it; and 1.67 m sideways, not 0.9 m: the car a lane away overlaps its band
    c.sim.ego_heading = 0.35
    hx = 2.4 * np.cos(0.35) + 0.9 * np.sin(0.35)
    assert hx - 2.4 > 0.13
    turned = ahead("turned", d + 0.08)
    assert c._front_danger(ego, [turned]) is turned
    assert c._front_danger(ego, [ahead("clear", d + 0.08 + (hx - 2.4))]) is None
    assert c._front_danger(EgoState(x=x0, vx=30.0, y=y + 1.5, vy=0.0), [beside]) is beside
    assert c._front_danger(ego, [beside]) is None  # turned, from its lane's centre: 1.18 m between the bodies
    # turned, its half width at the heading (1.67 m) against RSS's lateral distance, 5 cm either side
    hy = 2.4 * np.sin(0.35) + 0.9 * np.cos(0.35)
    d_lat0 = float(safe_lateral_distance(0.0, 0.0, DEFAULT))
    for off, want in ((0.9 + hy + d_lat0 + 0.05, None), (0.9 + hy + d_lat0 - 0.05, beside)):
        assert c._front_danger(EgoState(x=x0, vx=30.0, y=beside.y - off, vy=0.0), [beside]) is want
    # a car level with the ego (the same centre x) is not ahead of it
    level = Neighbour("level", (x0, 20.0, 0.5), y=y, length=4.8, width=1.8, lane=1, vy=0.0)
    assert c._front_danger(ego, [level]) is None


@pytest.mark.parametrize(("traffic", "seed", "left"), [("light", 7105, True), ("medium", 7103, True)])
def test_a_plan_that_does_not_brake_behind_a_car_rss_finds_too_close_is_left(traffic: str, seed: int,
                                                                              left: bool) -> None:
    """Discretionary light 7105 (a seed no campaign uses): 80 m behind a car at 35 m/s that slowed a
    little, the ego, at 31 m/s, was 1-2 m inside RSS's distance while its lane change carried it out
    of that car's lane; the verification lets a leader already too close come no closer, RSS asks
    the rear car to brake: 1.4 s (``free``) and 2.5 s (``pmp-active``, ``qp-avoid``) at fault.  The
    loop now leaves a plan that does not brake with ``brake_min`` while :meth:`Controller._front_danger`
    finds a car (rejection ``rss-front``; the following brakes): none at fault, still a success.
    Discretionary medium 7103 meets the situation too (``left``: plans left)."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission="discretionary", traffic=traffic, seed=seed, planner="free")).summary
    assert s["rss_dangerous_s"] == 0.0 and s["success"] and s["contacts"] == 0
    assert (s["rejected"].get("rss-front", 0) > 0) is left
