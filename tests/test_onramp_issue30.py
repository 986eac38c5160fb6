"""Issue 30, the on-ramp in medium traffic (31/40 before): the lane's end as a braking bound, end
speeds searched when the gap's mean is out of reach, and courteous followers asked as far back as
RSS makes them keep their distance (SPEC §17; docs/closed-loop.md)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.controller import ControllerConfig
from iamp.simulation.decision import REACH, EgoNow, Gap, Neighbour
from iamp.simulation.rss import DEFAULT, safe_longitudinal_distance
from iamp.simulation.simulator import Courtesy
from iamp.simulation.tactical import (
    TacticalConfig,
    gap_end,
    horizons_for,
    lane_end_accel,
    peak_accel,
    rss_follow_gap,
    safe_interval,
    seek_accel,
    within_reach,
)

W_LANE = 3.75


def _drive(v: float, s: float, cfg: TacticalConfig, dt: float = 0.05) -> tuple[float, float, float, float]:
    """The ego under the lane-end term alone: (stop position, the largest deceleration, the largest
    change of acceleration per second, the speed when ``r`` first reached 1)."""
    x, a_prev, peak, jerk = 0.0, None, 0.0, 0.0
    for _ in range(20000):
        a = min(lane_end_accel(v, s - x, cfg), cfg.idm.a_max)
        if a_prev is not None:
            jerk = max(jerk, abs(a - a_prev) / dt)
        a_prev = a
        peak = min(peak, a)
        if v + a * dt <= 0.0:
            x += v * v / (2 * max(-a, 1e-9)) if a < 0 else 0.0
            return x, -peak, jerk, v
        x, v = x + v * dt + a * dt * dt / 2, v + a * dt
    raise AssertionError("did not stop")


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.floats(1.0, 35.0), st.floats(0.0, 1.0))
def test_the_lane_end_bound_stops_the_ego_at_the_point_braking_at_most_b_end(v, extra):
    """From any speed with room to stop at ``b_end`` (``s ≥ v²/(2 b_end)``, up to 3x that) the ego
    stops before the point, never braking harder than ``b_end`` (up to the step's round-off); from
    6 m/s up, starting before the onset, its acceleration changes by less than the car's jerk bound
    (5 m/s³; the term is continuous in the state: only crawling up to a point a few metres ahead
    asks for more)."""
    cfg = TacticalConfig()
    s = v * v / (2 * cfg.b_end) * (1.0 + 2.0 * extra) + 0.05
    x, brake, _, _ = _drive(v, s, cfg)
    assert x <= s + 0.05
    assert brake <= cfg.b_end * 1.02
    if v >= 6.0:
        _, _, jerk, _ = _drive(v, v * v / (2 * cfg.b_end * cfg.end_onset) * (1.0 + 2.0 * extra), cfg)
        assert jerk <= 5.0


def test_the_lane_end_bound_is_continuous_at_its_onset_and_at_b_end():
    cfg = TacticalConfig()
    v = 25.0
    for r in (cfg.end_onset, 1.0):
        s = v * v / (2 * cfg.b_end * r)
        below, above = lane_end_accel(v, s * (1 + 1e-7), cfg), lane_end_accel(v, s * (1 - 1e-7), cfg)
        assert abs(below - above) < 1e-5
    assert lane_end_accel(v, v * v / (2 * cfg.b_end), cfg) == pytest.approx(-cfg.b_end)
    assert lane_end_accel(v, 1e5, cfg) == pytest.approx(cfg.idm.a_max, rel=1e-2)  # far away: no brake


def test_the_ego_is_faster_on_a_250_m_ramp_than_behind_idms_standing_obstacle():
    """Why the bound replaced IDM's standing obstacle: from 17.6 m/s, 230 m before the stopping
    point (the on-ramp's first seek, seed 30), with the free-road IDM term alone besides it, the
    ego passes 100 m before the point 2.5 m/s faster and stops at the point itself; behind IDM's
    obstacle (``s*`` ≈ 300 m at 30 m/s) it never exceeds 20.1 m/s."""
    cfg = TacticalConfig()

    def run(term):  # type: ignore[no-untyped-def]
        x, v, top, at100 = 0.0, 17.6, 0.0, None
        for _ in range(600):
            a = min(term(v, 230.0 - x), cfg.idm.accel(v))
            x, v = x + v * 0.1 + a * 0.005, max(v + a * 0.1, 0.0)
            top = max(top, v)
            if at100 is None and x >= 130.0:
                at100 = v
        return top, at100, x

    top, at100, x = run(lambda v, s: lane_end_accel(v, s, cfg))
    idm_top, idm_at100, _ = run(lambda v, s: cfg.idm.accel(v, s, 0.0))
    assert idm_top < 20.1 and top > idm_top + 1.0
    assert at100 > idm_at100 + 2.5
    assert x == pytest.approx(230.0, abs=0.5)


def _nb(name: str, x: float, v: float) -> Neighbour:
    return Neighbour(name, (x, v, 0.0, 0.0), W_LANE, 4.6, 1.8, 1)


def test_an_end_behind_a_fast_leader_ahead_of_a_yielding_follower_is_found():
    """The on-ramp (seed 30 at 8 s): the ego at 17.7 m/s between a follower 86 m behind at its
    speed and a leader 57 m ahead at 31.3 m/s. The gap's mean speed (24.5 m/s) is not reachable
    within the bounds in 4-7 s; an end at a lower speed is, inside the safe interval."""
    ego = EgoNow(0.0, 17.7, 0.0, 0.0)
    gap = Gap(_nb("f", -86.0, 17.6), _nb("l", 57.0, 31.3))
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    ends = horizons_for(ego, gap, dcfg, tac)
    assert ends, "no end state although the ego is inside the gap's safe interval"
    ax = dcfg.limits.ax
    assert ax is not None
    for T, end in ends:
        lo, hi = safe_interval(ego, gap, end[1], T, tac)
        assert lo <= end[0] <= hi
        assert peak_accel(ego, end, T) <= max(-ax[0], ax[1]) + 1e-9


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(5.0, 30.0), st.floats(-120.0, -20.0), st.floats(0.0, 15.0), st.floats(20.0, 120.0),
       st.floats(0.0, 15.0), st.sampled_from([4.0, 5.0, 6.0, 7.0]))
def test_gap_end_returns_the_mean_speed_end_when_reachable_else_the_least_peak(v, xf, dvf, xl, dvl, T):
    """Property: ``gap_end`` keeps the gap's mean speed whenever its end is reachable (the behaviour
    the rest of the campaign relies on), and otherwise no speed of its grid gives a smaller peak."""
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb("f", xf, v + dvf), _nb("l", xl, v + dvl))
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    end = gap_end(ego, gap, T, dcfg, tac)
    if end is None:
        return
    lo, hi = safe_interval(ego, gap, end[1], T, tac)
    assert lo < end[0] < hi
    ax = dcfg.limits.ax
    assert ax is not None
    peak = peak_accel(ego, end, T)
    for w in np.arange(0.0, 40.0, 0.25):
        lo_w, hi_w = safe_interval(ego, gap, float(w), T, tac)
        if lo_w < hi_w and abs(w - end[1]) > 1e-9:
            s = min(2.0, (hi_w - lo_w) / 2)
            x = float(np.clip(ego.x + (v + w) * T / 2, lo_w + s, hi_w - s))
            if peak > max(-ax[0], ax[1]) and v + 0.8 * ax[0] * T <= w <= v + 0.8 * ax[1] * T:
                assert peak_accel(ego, (x, float(w)), T) >= peak - 0.6 * T  # the grid's resolution


def test_a_courteous_follower_is_asked_as_far_back_as_rss_makes_it_keep_its_distance():
    """The on-ramp (seed 30, 1 s): a follower 117 m behind at 31.8 m/s, the ego at 18.9 m/s. RSS
    asks it to stay 130 m behind the ego once the ego is in its lane: it is asked (60 m was the
    limit before, so it yielded only 60 m behind, too late for any RSS-safe slot)."""
    c = Courtesy()
    d = float(safe_longitudinal_distance(31.8, 18.9, DEFAULT))
    assert c.reach(31.8, 18.9) >= d + c.margin_m
    assert c.reach(31.8, 18.9) >= 117.0
    assert c.reach(0.0, 30.0) == pytest.approx(c.margin_m + c.range_m)  # a standing car: no RSS distance
    assert c.reach(10.0, 10.0) == pytest.approx(float(safe_longitudinal_distance(10.0, 10.0, DEFAULT)) + 60.5)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(5.0, 35.0), st.floats(0.0, 35.0), st.floats(0.05, 0.95))
def test_closer_than_rss_behind_its_leader_the_ego_brakes_at_brake_min(v, v_l, frac):
    """RSS's proper response of the rear car (the judge blames an ego that does not brake at
    ``brake_min`` once the longitudinal distance is unsafe, e.g. a situation handed over by SUMO:
    slow-leader, medium, seed 33 had 4.3 s at fault): closer than the RSS distance the tactical
    layer brakes at least at ``brake_min``; at the distance itself it follows IDM."""
    cfg = TacticalConfig()
    d = float(safe_longitudinal_distance(v, v_l, cfg.safe.rss))
    ego = EgoNow(0.0, v, 0.0, 0.0)
    half = (4.6 + ego.length) / 2
    if d <= 0.0:
        return
    near = Neighbour("l", (half + frac * d, v_l, 0.0, 0.0), 0.0, 4.6, 1.8, 0)
    assert seek_accel(ego, near, None, None, 33.0, cfg) <= -cfg.safe.rss.brake_min
    far = Neighbour("l", (half + d + 1e-6, v_l, 0.0, 0.0), 0.0, 4.6, 1.8, 0)
    g = far.x(0.0) - ego.x - half  # the gap as the tactical layer computes it (round-off included)
    idm = replace(cfg.idm, v0=33.0)
    idm_only = idm.accel(v, rss_follow_gap(g, v, v_l, cfg), v_l)
    assert seek_accel(ego, far, None, None, 33.0, cfg) == pytest.approx(min(idm_only, idm.accel(v)), rel=1e-9)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(-6.0, 3.0), st.floats(-6.0, 3.0), st.floats(2.0, 30.0), st.floats(-2.0, 2.0), st.booleans())
def test_executed_inputs_change_within_the_jerk_bound_except_an_urgent_brake(a_prev, a_cmd, v, ay_prev, urgent):
    """Issue 30 item 4: the tactical layer's input changes by at most ``JERK_SHARE · jerk · dt`` per
    period on both axes; an urgent brake (fail-safe, RSS's proper response) is applied at once, and
    releasing it is rate-limited like any change."""
    from types import SimpleNamespace

    from iamp.simulation.controller import JERK_SHARE, Controller
    from iamp.simulation.simulator import EgoState

    ctl = Controller.__new__(Controller)
    ctl.cfg = ControllerConfig()
    ctl.sim = SimpleNamespace(step=0.1)  # type: ignore[assignment]
    ctl.heading = 0.0
    jerk = ctl.cfg.decision.limits.jerk
    assert jerk is not None
    step = JERK_SHARE * jerk * 0.1
    ego = EgoState(0.0, v, -1.0, 0.0, ax=a_prev, ay=ay_prev)
    nxt = ctl._move(ego, a_cmd, 0.0, urgent)
    if urgent and a_cmd < a_prev:
        assert nxt.ax == pytest.approx(a_cmd)
    else:
        assert abs(nxt.ax - a_prev) <= step + 1e-12
    assert abs(nxt.ay - ay_prev) <= step + 1e-12 or abs(nxt.vy) <= ctl.cfg.max_slip * (v + nxt.ax * 0.1) + 1e-12


def test_rss_regions_are_the_rss_distance_capped_by_the_room_the_boundary_leaves() -> None:
    """Exact values (mutation testing found them untested): a follower's region is
    ``L_e/2 + m_x + d(v_f(T), v_xf)``, capped at ``x_f - x_f(T) - L_f/2 - 0.5``; a target-lane
    leader's ``L_e/2 + m_x + d(v_xf, v_l(T))``, capped at ``x_l(T) - L_l/2 - x_f - 0.5``; never negative."""
    from iamp.core.problem import EgoBoundary
    from iamp.simulation.tactical import rss_regions

    cfg = TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    region = rss_regions(ego, cfg)
    b = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=20.0, vy0=0.0, xf=100.0, yf=W_LANE, vxf=20.0, vyf=0.0)
    half = ego.length / 2 + cfg.safe.margin_x
    far_f, far_l = _nb("f", -500.0, 20.0), _nb("l", 700.0, 20.0)  # x(5) = -400, 800: room is ample
    assert region(far_f, "follower", b) == pytest.approx(half + float(safe_longitudinal_distance(20.0, 20.0, DEFAULT)))
    assert region(far_l, "leader", b) == pytest.approx(half + float(safe_longitudinal_distance(20.0, 20.0, DEFAULT)))
    near_f, near_l = _nb("f", -30.0, 20.0), _nb("l", 30.0, 20.0)  # x(5) = 70, 130
    assert region(near_f, "follower", b) == pytest.approx(100.0 - 70.0 - 4.6 / 2 - 0.5)
    assert region(near_l, "leader", b) == pytest.approx(130.0 - 4.6 / 2 - 100.0 - 0.5)
    inside = _nb("l", 0.0, 20.0)  # x(5) = 100: the end state inside its body: no room at all
    assert region(inside, "leader", b) == 0.0


def test_horizons_for_respects_t_max_and_the_plan_window() -> None:
    """``t_max`` bounds the horizons (exactly: 5 s allowed at ``t_max = 5``, 6 s not); a gap whose
    safe interval is farther than ``plan_window_m + window_s |v_g - v|`` from the ego now is not
    planned (the tactical layer brings the ego there first)."""
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    wide = Gap(_nb("f", -200.0, 20.0), _nb("l", 200.0, 20.0))
    all_T = {T for T, _ in horizons_for(ego, wide, dcfg, replace(tac, max_horizons=4))}
    assert all_T == set(tac.horizons)
    capped = {T for T, _ in horizons_for(ego, wide, dcfg, replace(tac, max_horizons=4), t_max=5.0)}
    assert capped == {T for T in tac.horizons if T <= 5.0}
    # a gap whose safe interval starts 50 m ahead at the ego's speed: window 5 m -> not planned
    lo_now = safe_interval(ego, wide, 20.0, 0.0, tac)[0]
    ahead = Gap(_nb("f", -200.0 + 50.0 - lo_now, 20.0), None)
    assert horizons_for(ego, ahead, dcfg, tac) == []
    just = Gap(_nb("f", -200.0 + 4.0 - lo_now, 20.0), None)  # 4 m ahead: inside the 5 m window
    assert horizons_for(ego, just, dcfg, tac) != []


def test_gap_end_keeps_the_gap_speed_when_its_end_is_reachable() -> None:
    """A gap at the ego's speed, the ego in its middle: the end speed is the gap's mean, the end point
    the constant-speed one (no grid search replaces a reachable mean)."""
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    gap = Gap(_nb("f", -150.0, 18.0), _nb("l", 150.0, 22.0))
    end = gap_end(ego, gap, 5.0, dcfg, tac)
    assert end == (pytest.approx(100.0), pytest.approx(20.0))


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.floats(5.0, 30.0), st.floats(-60.0, -15.0), st.floats(15.0, 80.0), st.floats(-2.0, 2.0),
       st.floats(-2.0, 1.5))
def test_every_horizon_continues_the_executed_acceleration(v, xf, xl, dv, a0):
    """Each ``(T, end)`` of :func:`horizons_for` is :func:`gap_end`'s with the executed ``a0`` (the
    loop once overwrote ``a0`` with the previous horizon's cubic start, which differs where that end
    was clipped into the safe interval)."""
    dcfg, tac = ControllerConfig().decision, replace(TacticalConfig(), max_horizons=4)
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb("f", xf, v + dv), _nb("l", xl, v - dv))
    for T, end in horizons_for(ego, gap, dcfg, tac, a0=a0):
        assert end == gap_end(ego, gap, T, dcfg, tac, a0=a0)


def test_from_a_roll_a_plan_ahead_of_a_stopped_follower_does_not_end_stopped() -> None:
    """A gap with a follower and no leader: every speed above the follower's keeps the gap, so the
    end speed is at least ``min(v, roll_speed)`` (clipped to the reachable speeds): a plan from the
    ego's roll (1.5 m/s) does not end at a stopped follower's standstill.  The on-ramp (light, seed
    25004): a courteous follower 40 m behind braked with the ego, both came to a stop near the ramp's
    end, and every plan from the ego's roll into the gap ended stopped (refused: ``kinematics``,
    ``rss:lane-end``).  At speed the follower's speed stays the end speed (a plan ending faster runs
    further toward the lane's end); a gap with a leader keeps its mean."""
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    for v, vf, want in ((1.5, 0.0, 1.5), (1.0, 0.0, 1.0), (0.0, 0.0, 0.0), (6.0, 0.0, tac.roll_speed),
                        (6.0, 1.0, tac.roll_speed), (6.0, 2.0, 2.0), (20.0, 12.0, 12.0), (20.0, 24.0, 24.0)):
        end = gap_end(EgoNow(0.0, v, 0.0, 0.0), Gap(_nb("f", -150.0, vf), None), 9.0, dcfg, tac)
        assert end is not None and end[1] == pytest.approx(want), (v, vf, end)
    ego = EgoNow(0.0, 1.5, 0.0, 0.0)
    both = gap_end(ego, Gap(_nb("f", -150.0, 0.0), _nb("l", 150.0, 0.0)), 9.0, dcfg, tac)
    assert both is not None and both[1] == pytest.approx(0.0)  # the leader's standstill is the gap's
    ahead_only = gap_end(ego, Gap(None, _nb("l", 150.0, 0.0)), 9.0, dcfg, tac)
    assert ahead_only is not None and ahead_only[1] == pytest.approx(0.0)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.floats(0.0, 35.0), st.floats(0.0, 35.0), st.floats(-150.0, -8.0), st.sampled_from([4.0, 5.0, 6.0, 7.0, 9.0]))
def test_a_follower_only_gap_ends_at_least_at_the_ego_s_roll(v, vf, xf, T):
    """Property: in a gap with a follower and no leader, the end ``gap_end`` returns lies in the gap's
    safe interval at its speed, and where the speed ``max(v_f, min(v, roll_speed))`` clipped to the
    reachable speeds ends within reach that is the end speed."""
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    ax = dcfg.limits.ax
    assert ax is not None
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb("f", xf, vf), None)
    end = gap_end(ego, gap, T, dcfg, tac)
    want = float(np.clip(max(vf, min(v, tac.roll_speed)), np.clip(v + REACH * ax[0] * T, 0.0, dcfg.speed_cap),
                         np.clip(v + REACH * ax[1] * T, 0.0, dcfg.speed_cap)))
    lo, _ = safe_interval(ego, gap, want, T, tac)
    x = float(max(v * T + (want - v) * T / 2, lo + 2.0))
    if within_reach(ego, (x, want), T, dcfg, tac):
        assert end is not None and end[1] == pytest.approx(want, abs=1e-12) and end[0] == pytest.approx(x)
    if end is not None:
        assert safe_interval(ego, gap, end[1], T, tac)[0] < end[0]


@pytest.mark.parametrize(("seed", "planner"), [(25004, "pmp-active"), (11, "qp-avoid"), (32, "free")])
def test_a_courteous_follower_and_the_ego_no_longer_stop_together_at_the_ramp_s_end(seed: int, planner: str) -> None:
    """The on-ramp in light traffic (25004: a seed no campaign uses; 11 of ``reports/campaign-safe``):
    the target lane's follower, courteous, kept its RSS distance behind the ego and braked with it,
    both came to a stop near the ramp's end, and every plan from the ego's roll ended at the
    follower's standstill (a failure of every iamp planner).  Now the ego merges, safely.  Seed 32
    merges as before (ending every plan at least at the ego's speed, not only its roll's, lost it:
    the plans ran further and met the ramp's end)."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission="onramp", traffic="light", seed=seed, planner=planner)).summary
    assert s["success"] and not s["stopped_at_end"]
    assert s["contacts"] == 0 and s["rss_dangerous_s"] == 0.0 and s["limit_violations"] == 0
