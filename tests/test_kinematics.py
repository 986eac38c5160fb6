"""A path a car can drive (:mod:`iamp.simulation.kinematics`): the curvature measured from points,
the plans the closed loop refuses, and the tactical layer's steering.

Before: plans accepted at a crawl turned on radii down to 0.4 m, and the ego slid sideways at a
standstill (merge dense 2: heading 87° at 0.8 m/s; 6 of 18 dense and LOS E episodes turned
tighter than 5 m), because the point-mass plans move ``s_x`` and ``s_y`` independently.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.problem import EgoBoundary
from iamp.simulation.decision import DecisionConfig, judge
from iamp.simulation.kinematics import KAPPA_MAX, TOL_REL, plan_turning, start_heading, turning
from iamp.simulation.planning import free_plan


def _controller(heading: float) -> Any:
    """A controller with the default configuration, a 0.1 s period and ``heading``, for its
    one-period steering methods (no simulator)."""
    from iamp.simulation.controller import Controller, ControllerConfig

    class _Sim:
        step = 0.1

    ctl = Controller.__new__(Controller)
    ctl.cfg = ControllerConfig()
    ctl.heading = heading
    ctl.sim = _Sim()
    return ctl


@settings(max_examples=80, deadline=None)
@given(radius=st.floats(2.0, 500.0), step=st.floats(0.21, 3.0), psi0=st.floats(-math.pi, math.pi),
       sweep=st.floats(0.3, 3.0), left=st.booleans())
def test_the_curvature_of_a_circular_arc_is_one_over_its_radius(radius, step, psi0, sweep, left):
    """Points every ``step`` metres of arc on a circle of radius ``R`` leaving the heading ``ψ_0``:
    every vertex and the start measure ``1/R`` (chords ``2R sin(θ/2)`` turn by ``θ`` and leave the
    tangent by ``θ/2``), to round-off."""
    n = max(3, int(sweep * radius / step))
    s = np.arange(n + 1) * step
    sign = 1.0 if left else -1.0
    ang = sign * s / radius
    # centre to the left (right) of the heading psi0
    cx, cy = -sign * radius * math.sin(psi0), sign * radius * math.cos(psi0)
    x = cx + sign * radius * np.sin(psi0 + ang)
    y = cy - sign * radius * np.cos(psi0 + ang)
    k = turning(x, y, psi0)
    assert k.size == n
    np.testing.assert_allclose(k, 1.0 / radius, rtol=1e-6, atol=1e-9)


def test_a_straight_path_and_a_standstill_do_not_turn_and_a_sideways_start_does():
    x = np.linspace(0.0, 30.0, 61)
    assert np.all(turning(x, np.zeros_like(x), 0.0) < 1e-12)
    # standing still (all points within ds_min) then driving straight on: no turn
    xs = np.concatenate((np.zeros(20), np.linspace(0.0, 10.0, 21)))
    assert np.all(turning(xs, np.zeros_like(xs), 0.0) < 1e-12)
    # sliding sideways from a standstill: the start turns by pi/2 over the first chord
    y = np.linspace(0.0, 1.0, 11)
    k = turning(np.zeros_like(y), y, 0.0)
    assert k[0] == pytest.approx(2.0 / 0.2)
    assert turning(np.zeros(5), np.zeros(5), 0.0).size == 0


def test_the_start_heading_is_the_velocity_s_direction_or_the_road_s():
    assert start_heading(10.0, 10.0) == pytest.approx(math.pi / 4)
    assert start_heading(0.0, 0.01) == 0.0  # a standstill: along the road
    assert start_heading(0.0, 0.5) == pytest.approx(math.pi / 2)


def test_judge_refuses_a_lane_change_from_a_crawl_and_accepts_it_at_speed():
    """The same 3.5 m lane change in 5 s: from 25 m/s its path turns on radii of hundreds of
    metres; from 0.5 m/s it starts almost sideways (``kinematics``)."""
    cfg = DecisionConfig()
    fast = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.0, xf=125.0, yf=3.5, vxf=25.0, vyf=0.0)
    plan = free_plan(fast, "free")
    assert judge(plan, None, cfg) == "accepted"
    assert float(plan_turning(plan.require_trajectory(), 5.0).max()) < 0.01
    crawl = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=0.5, vy0=0.0, xf=6.0, yf=3.5, vxf=2.0, vyf=0.0)
    slow = free_plan(crawl, "free")
    assert float(plan_turning(slow.require_trajectory(), 5.0).max()) > KAPPA_MAX * (1 + TOL_REL)
    assert judge(slow, None, cfg) == "kinematics"
    from dataclasses import replace

    assert judge(slow, None, replace(cfg, kappa_max=None)) == "accepted"  # the test is the turning radius


@settings(max_examples=120, deadline=None)
@given(vx=st.floats(0.0, 35.0), psi=st.floats(-0.3, 0.3), ax=st.floats(-6.0, 3.0), ay=st.floats(-4.0, 4.0))
def test_the_tactical_layer_turns_the_velocity_by_at_most_kappa_max_per_metre(vx, psi, ax, ay):
    """:meth:`Controller._turn_bound`: from a velocity on heading ``ψ`` (``v_y = v_x tan ψ``), the
    next period's velocity turns by at most ``TURN_SHARE κ_max`` times the distance travelled (the
    mean speed times the period); an input that turns less is kept as it is."""
    from iamp.simulation.controller import TURN_SHARE
    from iamp.simulation.simulator import EgoState

    ctl = _controller(0.0)
    vy = vx * math.tan(psi)
    ego = EgoState(x=0.0, vx=vx, y=0.0, vy=vy, ax=0.0, ay=0.0)
    vx1 = vx + ax * 0.1
    out = ctl._turn_bound(ego, ax, ay)
    vy1 = vy + out * 0.1
    if vx1 <= 0.0 or math.hypot(vx1, vy + ay * 0.1) == 0.0:
        return
    turn = TURN_SHARE * KAPPA_MAX * 0.5 * (math.hypot(vx, vy) + math.hypot(vx1, vy + ay * 0.1)) * 0.1
    psi0 = start_heading(vx, vy)
    # within the bound, or the lateral input at the lane keeping's bound on the way to it
    assert abs(math.atan2(vy1, vx1) - psi0) <= turn + 1e-9 or abs(out) == pytest.approx(ctl.cfg.lane_keep_ay)
    if abs(math.atan2(vy + ay * 0.1, vx1) - psi0) <= turn:
        assert out == ay


def test_the_monitor_counts_the_executed_turns_tighter_than_a_car_s():
    """``curvature_max``/``curvature_violations`` of an episode: a lane change at 20 m/s passes;
    the same log with the ego sliding sideways while standing counts its turns."""
    from iamp.simulation.metrics import StepLog
    from iamp.simulation.monitor import monitor

    def log_of(rows):
        log = StepLog()
        for k, r in enumerate(rows):
            log.t.append(0.1 * k)
            log.ego.append(tuple(r))
            log.mode.append("active")
            log.plan_time.append(float("nan"))
            log.ids.append(())
            log.nb.append(np.zeros((0, 8)))
        return log

    t = np.arange(61) * 0.1
    y = 3.5 * (10 * (t / 6) ** 3 - 15 * (t / 6) ** 4 + 6 * (t / 6) ** 5)  # quintic lane change
    vy = np.gradient(y, t)
    smooth = [(20.0 * tk, 20.0, yk, vyk, 0.0, 0.0) for tk, yk, vyk in zip(t, y, vy)]
    lane = lambda yy: int(round(yy / 3.5))  # noqa: E731
    out = monitor(log_of(smooth), 0.1, (4.8, 1.8), lane, 1, 60.0, None, [])
    assert out["curvature_violations"] == 0 and 0.0 < out["curvature_max"] < 0.01
    stand = [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)] * 5
    slide = stand + [(0.0, 0.0, yk, 0.5, 0.0, 0.0) for yk in np.linspace(0.05, 3.0, 60)]
    out = monitor(log_of(slide), 0.1, (4.8, 1.8), lane, 1, 60.0, None, [])
    assert out["curvature_violations"] >= 1 and out["curvature_max"] == pytest.approx(2.0 / 0.2)


def _nb(name: str, x: float, v: float):
    from iamp.simulation.decision import Neighbour

    return Neighbour(name, (x, v, 0.0, 0.0), 3.75, 4.6, 1.8, 1)


def test_at_a_crawl_the_longer_horizons_are_planned_with_the_road_a_lane_change_needs():
    """Below ``crawl_speed`` the horizons ``crawl_horizons`` join; an end point nearer than
    ``sqrt(6 |Δy| / κ_max)`` (10.6 m for 3.75 m) is moved that far ahead inside the gap, and a
    horizon whose gap has no such room is not planned.  At speed nothing changes."""
    from iamp.simulation.decision import EgoNow, Gap
    from iamp.simulation.tactical import TacticalConfig, all_horizons, horizons_for

    cfg, dcfg = TacticalConfig(), DecisionConfig()
    need = math.sqrt(6 * 3.75 / KAPPA_MAX)
    crawl = EgoNow(0.0, 1.0, 0.0, 0.0)
    assert all_horizons(crawl, cfg) == cfg.horizons + cfg.crawl_horizons
    assert all_horizons(EgoNow(0.0, 20.0, 0.0, 0.0), cfg) == cfg.horizons
    # a standing target lane with a long gap beside the ego
    gap = Gap(_nb("f", -60.0, 0.0), _nb("l", 80.0, 0.0))
    out = horizons_for(crawl, gap, dcfg, cfg, dy=3.75)
    assert out and all(T in cfg.crawl_horizons for T, _ in out)
    for _, (xf, _) in out:
        assert xf - crawl.x >= need - 1e-9
        assert 6 * 3.75 / (xf - crawl.x) ** 2 <= KAPPA_MAX + 1e-12
    # the leader 12 m ahead: the gap has no 10.6 m of room ahead of the ego, nothing is planned
    assert horizons_for(crawl, Gap(_nb("f", -60.0, 0.0), _nb("l", 12.0, 0.0)), dcfg, cfg, dy=3.75) == []
    # without dy (the old call) the crawl horizons are planned with their own end points
    assert horizons_for(crawl, gap, dcfg, cfg) != []


def test_inside_its_gap_the_ego_rolls_and_may_use_the_room_before_its_lane_s_end():
    """Inside the target gap's safe interval with ``roll_room_m`` of it ahead, the gap term's speed
    is at least ``roll_speed`` and the lane's end bounds the ego ``roll_end_m`` before it instead of
    ``end_room_m``; outside, the gap term and the end room are as before."""
    from iamp.simulation.decision import EgoNow, Gap
    from iamp.simulation.tactical import TacticalConfig, lane_end_accel, seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(0.0, 0.0, 0.0, 0.0)
    standing = Gap(_nb("f", -60.0, 0.0), _nb("l", 80.0, 0.0))
    end = 30.0  # the lane ends 30 m ahead: within end_room_m + ..., beyond roll_end_m
    a = seek_accel(ego, None, end, standing, 33.3, cfg)
    assert a == pytest.approx(min(cfg.k_speed * cfg.roll_speed, cfg.gap_accel[1],
                                  lane_end_accel(0.0, end - cfg.roll_end_m - ego.length / 2, cfg)))
    assert a > 0.0
    # no room ahead in the gap (its leader 12 m ahead): no rolling, the end room as before
    tight = Gap(_nb("f", -60.0, 0.0), _nb("l", 12.0, 0.0))
    assert seek_accel(ego, None, end, tight, 33.3, cfg) <= 0.0
    # the end room: standing 10 m before the end with no gap, the ego does not move
    assert seek_accel(EgoNow(end - 10.0, 0.0, 0.0, 0.0), None, end, None, 33.3, cfg) <= 0.0


def test_a_vertex_turns_by_its_angle_over_the_mean_of_its_chords_and_a_reversal_counts():
    """Chords of 1 m and 2 m meeting at an angle θ: ``2 sin(θ/2) / 1.5``; a path that starts
    backwards from the heading counts as a sideways start (the deviation capped at 90°: ``2/l_0``)."""
    theta = 0.3
    x = np.array([0.0, 1.0, 1.0 + 2.0 * math.cos(theta), 1.0 + 2.0 * math.cos(theta) + 0.5])
    y = np.array([0.0, 0.0, 2.0 * math.sin(theta), 2.0 * math.sin(theta)])
    k = turning(x, y, 0.0, ds_min=0.1)
    assert k[0] == pytest.approx(0.0, abs=1e-12)
    assert k[1] == pytest.approx(2.0 * math.sin(theta / 2) / 1.5, rel=1e-12)
    assert k[2] == pytest.approx(2.0 * math.sin(theta / 2) / 1.25, rel=1e-12)
    # leaving the heading -0.2 by 0.2 over a first chord of 1 m (the second 2 m long)
    assert turning(x, y, -0.2, ds_min=0.1)[0] == pytest.approx(2.0 * math.sin(0.2) / 1.0, rel=1e-12)
    back = turning(-np.linspace(0.0, 1.0, 6), np.zeros(6), 0.0)
    assert back[0] == pytest.approx(2.0 / 0.2)


def test_a_plan_from_a_standstill_starts_from_the_heading_the_car_stopped_with():
    """A straight plan along the road from a standstill: from the road's heading (None: 0) it
    does not turn; from a car standing at 0.3 rad it starts off its heading by 0.3 rad."""
    stand = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=0.0, vy0=0.0, xf=20.0, yf=0.0, vxf=8.0, vyf=0.0)
    tr = free_plan(stand, "free").require_trajectory()
    assert float(plan_turning(tr, 5.0).max()) < 1e-9
    assert float(plan_turning(tr, 5.0, heading=0.0).max()) < 1e-9
    k = plan_turning(tr, 5.0, heading=0.3)
    assert k[0] > KAPPA_MAX and k[0] == pytest.approx(2.0 * math.sin(0.3) / 0.2, rel=0.05)


@settings(max_examples=80, deadline=None)
@given(radius=st.floats(2.0, 500.0), step=st.floats(0.21, 3.0), psi0=st.floats(-math.pi, math.pi),
       sweep=st.floats(0.3, 3.0), left=st.booleans(), tail=st.floats(0.0, 0.19))
def test_an_arc_ends_on_its_tangent_and_the_end_counts_one_over_its_radius(radius, step, psi0, sweep, left, tail):
    """The end test mirrors the start: an arc of radius ``R`` sampled every ``step`` metres, with a
    last point ``tail`` metres of arc beyond the last full step (nearer than ``ds_min``: kept in place
    of the last kept point), ending on its tangent: every value is ``1/R``; ending on the road's
    heading after turning away from it, the end counts the turn."""
    n = max(3, int(sweep * radius / step))
    s = np.concatenate((np.arange(n + 1) * step, [n * step + tail] if tail > 0 else []))
    sign = 1.0 if left else -1.0
    ang = sign * s / radius
    cx, cy = -sign * radius * math.sin(psi0), sign * radius * math.cos(psi0)
    x = cx + sign * radius * np.sin(psi0 + ang)
    y = cy - sign * radius * np.cos(psi0 + ang)
    end = psi0 + float(ang[-1])
    k = turning(x, y, psi0, psi_end=end)
    assert k.size == n + 1
    np.testing.assert_allclose(k[:-2], 1.0 / radius, rtol=1e-6, atol=1e-9)
    # the last vertex and the end: chords of unequal arcs (step, step + tail), exact to second order
    np.testing.assert_allclose(k[-2:], 1.0 / radius, rtol=(step / radius) ** 2 / 4 + 1e-6, atol=1e-9)
    # ending on a heading turned 0.5 rad further away from the last chord: it counts at least that
    assert turning(x, y, psi0, psi_end=end + sign * 0.5)[-1] >= 2.0 * math.sin(0.5) / (step + tail) * (1 - 1e-9)


def test_a_plan_that_ends_rolling_straightens_before_its_end():
    """Slow-leader light 44: a lane change at a crawl that ends rolling along the road (``v_y = 0``)
    after decelerating on a heading of 22°: its path turns by 22° in its last centimetres, which the
    chords of at least 0.2 m do not see; the end test does (``kinematics``), while the same plan at
    highway speed straightens on a radius of hundreds of metres and passes."""
    slow = EgoBoundary(tf=1.5, x0=0.0, y0=0.0, vx0=2.2, vy0=0.9, xf=1.7, yf=0.7, vxf=0.07, vyf=0.0)
    plan = free_plan(slow, "free")
    X = plan.require_trajectory().states(np.linspace(0.0, 1.5, 151))
    assert float(turning(X[:, 0], X[:, 2], start_heading(2.2, 0.9)).max()) <= KAPPA_MAX  # the chords alone
    assert judge(plan, None, DecisionConfig(), heading=start_heading(2.2, 0.9)) == "kinematics"
    fast = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.5, xf=125.0, yf=2.0, vxf=25.0, vyf=0.0)
    assert judge(free_plan(fast, "free"), None, DecisionConfig(), heading=start_heading(25.0, 0.5)) == "accepted"


@settings(max_examples=60, deadline=None)
@given(psi=st.floats(-1.5, 1.5), length=st.floats(0.25, 20.0), moving=st.booleans())
def test_the_stop_heading_is_the_last_chord_s_angle_to_the_road(psi, length, moving):
    """A straight path of ``length`` metres on heading ``ψ`` ending at a standstill leaves the car at
    ``|ψ|`` to the road; ending in motion, 0 (its end heading is the end test's)."""
    from iamp.simulation.kinematics import stop_heading

    s = np.linspace(0.0, length, 50)
    X = np.zeros((s.size, 4))
    X[:, 0], X[:, 2] = s * math.cos(psi), s * math.sin(psi)
    X[:-1, 1], X[:-1, 3] = math.cos(psi), math.sin(psi)
    if moving:
        X[-1, 1], X[-1, 3] = math.cos(psi), math.sin(psi)
    assert stop_heading(X) == (0.0 if moving else pytest.approx(abs(psi), abs=1e-9))
    # a standstill reached after less than ds_min of motion: the heading the car had, not tested
    short = X.copy()
    short[:, 0], short[:, 2] = X[:, 0] * 0.19 / length, X[:, 2] * 0.19 / length
    short[-1, 1] = short[-1, 3] = 0.0
    assert stop_heading(short) == 0.0


def test_judge_refuses_a_plan_that_leaves_the_ego_standing_across_the_road():
    """Merge medium 74: a plan stopped the ego at 43° to the road in its new lane, and a car drives on
    along its heading (the lane keeping could only straighten it 1.3 m further across).  A plan that
    stops the ego after a lane change at a crawl is refused beyond ``stop_heading_max``; the same
    stop straight along the road is accepted."""
    from dataclasses import replace

    from iamp.simulation.kinematics import STOP_HEADING_MAX, stop_heading

    cfg = DecisionConfig()
    across = EgoBoundary(tf=2.0, x0=0.0, y0=0.0, vx0=1.2, vy0=1.0, xf=1.2, yf=1.0, vxf=0.0, vyf=0.0)
    plan = free_plan(across, "free")
    X = plan.require_trajectory().states(np.linspace(0.0, 2.0, 201))
    assert stop_heading(X) > STOP_HEADING_MAX
    assert judge(plan, None, cfg, heading=start_heading(1.2, 1.0)) == "kinematics"
    assert judge(plan, None, replace(cfg, stop_heading_max=math.pi / 2),
                 heading=start_heading(1.2, 1.0)) == "accepted"
    along = EgoBoundary(tf=2.0, x0=0.0, y0=0.0, vx0=1.2, vy0=0.0, xf=1.2, yf=0.0, vxf=0.0, vyf=0.0)
    assert judge(free_plan(along, "free"), None, cfg) == "accepted"


@settings(max_examples=150, deadline=None)
@given(speed=st.floats(0.06, 6.0), psi=st.floats(-0.75, 0.75), ax=st.floats(-3.0, 3.0), cut=st.floats(0.0, 1.0))
def test_a_lateral_cut_the_heading_cannot_follow_is_met_by_braking_along_the_heading(speed, psi, ax, cut):
    """:meth:`Controller._heading_brake`: RSS's lateral response cuts the lateral speed (by the share
    ``cut``, never past zero); where the velocity would then turn faster than ``TURN_SHARE κ_max``
    per metre, the car brakes along its heading instead: after the period its velocity is on a
    heading within the bound of its own (smaller) distance, or it stands, or it brakes at the car's
    limit; it never accelerates more than asked, and a velocity within the bound is left alone.
    (Merge medium 74 and merge dense 13: the ego, at 38° and 15° to the road at a crawl, turned on
    radii of 1-4 m under a lateral cap.)"""
    from iamp.core.physical import PASSENGER_CAR
    from iamp.simulation.controller import TURN_SHARE
    from iamp.simulation.simulator import EgoState

    ctl = _controller(psi)
    vx, vy = speed * math.cos(psi), speed * math.sin(psi)
    ay = -cut * vy / 0.1
    ego = EgoState(x=0.0, vx=vx, y=0.0, vy=vy, ax=0.0, ay=0.0)
    out = ctl._heading_brake(ego, ax, ay)
    assert out <= ax
    vx1, vy1 = vx + out * 0.1, vy + ay * 0.1
    vx_asked = vx + ax * 0.1
    bound = TURN_SHARE * KAPPA_MAX * 0.5 * 0.1
    asked = math.atan2(vy1, vx_asked) if vx_asked > 0.0 else psi
    if vx_asked <= 0.0 or abs(asked - psi) <= bound * (speed + math.hypot(vx_asked, vy1)) or abs(asked) > abs(psi):
        # standing, within the bound, or turned away from the road (by braking harder along the road
        # than the cut: :meth:`_turn_bound`'s case, before the caps; braking more would turn it further)
        assert out == ax
        return
    lo = PASSENGER_CAR.ax[0] if PASSENGER_CAR.ax is not None else -6.0
    within = abs(math.atan2(vy1, vx1) - psi) <= bound * (speed + math.hypot(vx1, vy1)) + 1e-9
    assert out < ax and (within or vx1 <= 1e-12 or out == pytest.approx(lo))


def test_the_stop_heading_is_read_on_the_last_chord_and_a_sideways_roll_is_motion():
    """On an arc of radius 10 m from the road's heading, stopping after 3 m: the car stands on the
    heading of its last chord of 0.2 m (about 0.29 rad), not of its first; a path whose last velocity
    is sideways (``v_x = 0``, ``v_y`` above :data:`MOVING_MPS`) still moves: no stop heading."""
    from iamp.simulation.kinematics import MOVING_MPS, stop_heading

    s = np.linspace(0.0, 3.0, 301)
    X = np.zeros((s.size, 4))
    X[:, 0], X[:, 2] = 10.0 * np.sin(s / 10.0), 10.0 * (1.0 - np.cos(s / 10.0))
    X[:-1, 1], X[:-1, 3] = np.cos(s[:-1] / 10.0), np.sin(s[:-1] / 10.0)
    # the chord of the last 0.21 m of arc (the nearest sample at least 0.2 m away) leaves the end's
    # tangent (0.3 rad) by half its turn, 0.0105 rad
    assert stop_heading(X) == pytest.approx(0.3 - 0.0105, abs=1e-4)
    side = X.copy()
    side[-1, 1], side[-1, 3] = 0.0, 2 * MOVING_MPS
    assert stop_heading(side) == 0.0
    rolling = X.copy()  # still rolling along the road at the end: its heading is the end test's
    rolling[-1, 1], rolling[-1, 3] = 2 * MOVING_MPS, 0.0
    assert stop_heading(rolling) == 0.0


@settings(max_examples=60, deadline=None)
@given(dy=st.floats(-4.0, 4.0).filter(lambda d: abs(d) > 0.05), vy0=st.floats(-1.0, 1.0),
       T=st.floats(3.0, 15.0))
def test_the_end_speed_keeps_a_lane_change_s_last_turn_within_a_car_s_radius(dy, vy0, T):
    """:func:`~iamp.simulation.tactical.turn_end_speed` against the planner's own optimum: the free
    plan that drives at that speed along the road (``x`` uniform) while its lateral motion goes from
    ``v_{y,0}`` to ``Δy`` ends on a radius of exactly ``1 / κ_max`` (``|u_y(T)| / v²``); 10 % slower
    it ends tighter than a car can turn, 10 % faster within its radius."""
    from iamp.simulation.tactical import turn_end_speed

    v = turn_end_speed(dy, vy0, T, KAPPA_MAX)
    assert v >= 0.0 and turn_end_speed(dy, vy0, T, None) == 0.0
    # no turning bound, or no time: no floor (and no division by zero)
    assert turn_end_speed(dy, vy0, T, 0.0) == 0.0 and turn_end_speed(dy, vy0, T, -KAPPA_MAX) == 0.0
    assert turn_end_speed(dy, vy0, 0.0, KAPPA_MAX) == 0.0 and turn_end_speed(dy, vy0, -T, KAPPA_MAX) == 0.0
    assert turn_end_speed(dy, vy0, 1e-3, 1e-6) > 0.0

    def end_curvature(speed: float) -> float:
        b = EgoBoundary(tf=T, x0=0.0, y0=0.0, vx0=speed, vy0=vy0, xf=speed * T, yf=dy, vxf=speed, vyf=0.0)
        u = np.asarray(free_plan(b, "free").require_trajectory().inputs(np.array([T])))[0]
        assert abs(u[0]) <= 1e-9  # uniform along the road
        return float(abs(u[1]) / speed**2)

    if v > 1e-3:
        assert end_curvature(v) == pytest.approx(KAPPA_MAX, rel=1e-6)
        assert end_curvature(0.9 * v) > KAPPA_MAX and end_curvature(1.1 * v) < KAPPA_MAX


def test_a_plan_into_a_crawling_gap_ends_no_slower_than_its_last_turn_allows():
    """Merge LOS E 31003: beside a gap of a jammed target lane whose cars were predicted to slow to
    0.3 m/s, every plan ended at that speed while still turning (radius 2 m at its end) and was
    refused (``kinematics``) for 35 s.  The end speed of :func:`~iamp.simulation.tactical.gap_end`
    is now at least the last turn's speed ``turn_end_speed(dy, ...)`` where it is reachable (and the end
    point in the gap at that speed); ``horizons_for`` passes ``dy`` for each horizon."""
    from iamp.simulation.decision import EgoNow, Gap, Neighbour
    from iamp.simulation.tactical import TacticalConfig, gap_end, horizons_for, safe_interval, turn_end_speed

    cfg, dcfg = TacticalConfig(), DecisionConfig()
    ego = EgoNow(0.0, 1.3, 0.0, 0.0)
    # both cars of the gap slow from 1.2 m/s at 0.066 m/s²
    slow = lambda name, x: Neighbour(name, (x, 1.2, -0.033, 0.0), 3.75, 4.6, 1.8, 1)  # noqa: E731
    gap = Gap(slow("f", -20.0), slow("l", 25.0))
    T = 15.0
    plain = gap_end(ego, gap, T, dcfg, cfg)
    assert plain is not None and plain[1] < 0.5  # the gap's speed at T
    v_min = turn_end_speed(3.75, 0.0, T, dcfg.kappa_max)
    raised = gap_end(ego, gap, T, dcfg, cfg, dy=3.75)
    assert raised is not None and raised[1] >= v_min - 1e-12
    lo, hi = safe_interval(ego, gap, raised[1], T, cfg)
    assert lo <= raised[0] <= hi
    # out of reach (the turn's speed above every reachable speed): the highest reachable speed
    assert turn_end_speed(100.0, 0.0, 1.0, dcfg.kappa_max) > 1.3 + dcfg.limits.ax[1] * 1.0
    capped = gap_end(ego, gap, 1.0, dcfg, cfg, dy=100.0)
    assert capped is None or capped[1] <= 1.3 + dcfg.limits.ax[1] * 1.0 + 1e-9
    planned = horizons_for(ego, gap, dcfg, cfg, dy=3.75)
    assert planned
    for Tk, (_, vf) in planned:
        assert vf >= turn_end_speed(3.75, 0.0, Tk, dcfg.kappa_max) - 1e-12


@settings(max_examples=60, deadline=None)
@given(v0=st.floats(0.0, 33.0), lane=st.floats(5.0, 40.0), T=st.sampled_from([3.0, 4.0, 5.0, 6.0, 7.0, 9.0]),
       a0=st.one_of(st.none(), st.floats(-2.0, 2.0)))
def test_a_plan_into_an_empty_lane_ends_as_near_the_lane_s_speed_as_it_reaches(v0: float, lane: float, T: float,
                                                                               a0: float | None) -> None:
    """On-ramp light 19: every plan into the empty target lane ended at the ramp's 19.4 m/s, and a
    car arriving at 32 m/s 149 m behind aborted the change (RSS's distance to a follower shrinks as
    the ego's end speed grows).  A gap with neither follower nor leader now carries the lane's speed
    (:class:`~iamp.simulation.decision.Gap`), and :func:`~iamp.simulation.tactical.gap_end` ends at
    the reachable speed nearest it whose cubic keeps the ``a_x`` bounds' reach: never farther from the
    lane's speed than the ego is, nearer whenever a speed step toward it is within reach; without a
    lane speed, at the ego's own speed (as before)."""
    from iamp.simulation.decision import EgoNow, Gap
    from iamp.simulation.rss import safe_longitudinal_float
    from iamp.simulation.tactical import TacticalConfig, gap_end, within_reach

    cfg, dcfg = TacticalConfig(), DecisionConfig()
    ego = EgoNow(0.0, v0, 0.0, 0.0)
    own = gap_end(ego, Gap(None, None), T, dcfg, cfg, a0)
    assert own is not None and own[1] == pytest.approx(v0, abs=1e-12)
    end = gap_end(ego, Gap(None, None, lane), T, dcfg, cfg, a0)
    assert end is not None
    assert abs(end[1] - lane) <= abs(v0 - lane) + 1e-9
    if within_reach(ego, own, T, dcfg, cfg):
        assert within_reach(ego, end, T, dcfg, cfg)
    # a follower at the lane's speed needs no more room behind the ego's end than at its own speed
    p = cfg.safe.rss
    if lane >= v0:
        assert safe_longitudinal_float(lane, end[1], p) <= safe_longitudinal_float(lane, v0, p) + 1e-9
    from iamp.simulation.decision import REACH
    from iamp.simulation.tactical import continuing_end

    ax = dcfg.limits.ax
    v_lo, v_hi = max(0.0, v0 + REACH * ax[0] * T), min(dcfg.speed_cap, v0 + REACH * ax[1] * T)
    if a0 is None:  # the constant-acceleration end keeps the reach: the lane's speed, clipped to what REACH reaches
        assert end[1] == pytest.approx(float(np.clip(lane, v_lo, v_hi)), abs=1e-9)
    else:  # no speed of the grid whose continuing end keeps the reach is nearer the lane's
        for v in np.linspace(v_lo, v_hi, max(2, int(np.ceil((v_hi - v_lo) / cfg.speed_step)) + 1)):
            other = (continuing_end(ego, a0, T, float(v)), float(v))
            if within_reach(ego, other, T, dcfg, cfg):
                assert abs(end[1] - lane) <= abs(v - lane) + 1e-9


def test_a_gap_with_a_vehicle_keeps_the_least_peak_end_where_its_speed_is_out_of_reach() -> None:
    """The empty lane's rule (the reachable end speed nearest the lane's) is for a gap with neither
    follower nor leader; a gap with one, whose speed is out of reach, keeps the end that needs the
    least peak acceleration (:func:`~iamp.simulation.tactical.gap_end`).  A re-plan braking at 2 m/s²
    with a follower 400 m behind at 30 m/s (its safe interval binds no end): the two rules differ."""
    from iamp.simulation.decision import EgoNow, Gap, Neighbour
    from iamp.simulation.tactical import TacticalConfig, gap_end, peak_accel

    cfg, dcfg = TacticalConfig(), DecisionConfig()
    ego = EgoNow(0.0, 10.0, 0.0, 0.0)
    far = Neighbour("f", (-400.0, 30.0, 0.0, 0.0), 3.75, 4.6, 1.8, 1)
    T, a0 = 4.0, -2.0
    one = gap_end(ego, Gap(far, None), T, dcfg, cfg, a0)
    empty = gap_end(ego, Gap(None, None, 30.0), T, dcfg, cfg, a0)
    assert one is not None and empty is not None
    assert peak_accel(ego, one, T) < peak_accel(ego, empty, T) - 1e-6
    assert empty[1] > one[1] + cfg.speed_step / 2
