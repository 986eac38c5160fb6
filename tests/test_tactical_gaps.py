"""The tactical layer's gap choice and end-state search, value by value (SPEC §17, issue 30 item 3).

Mutation testing of ``simulation/tactical.py`` left these untested: which gap ``choose_gap``
returns and how it weighs distance against speed matching (``b_match``), where it aims in an
open gap (``open_m``) and how far it looks (``reach_m``), the end-speed grid of ``gap_end``,
the cubic's end accelerations and the reach test on both bounds, and the plan window's
``|v_g - v|``.  Each test states the formula of the module docstring it checks.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.controller import ControllerConfig
from iamp.simulation.decision import REACH, EgoNow, Gap, Neighbour
from iamp.simulation.rss import safe_longitudinal_distance
from iamp.simulation.tactical import (
    TacticalConfig,
    aim_point,
    choose_gap,
    end_accels,
    gap_end,
    horizons_for,
    peak_accel,
    safe_interval,
    within_reach,
)

W_LANE = 3.75


def _nb(name: str, x: float, v: float) -> Neighbour:
    return Neighbour(name, (x, v, 0.0, 0.0), W_LANE, 4.6, 1.8, 1)


def test_an_open_gap_is_aimed_open_m_past_its_one_end_and_only_within_reach_m() -> None:
    """A gap with a follower only: the aim point is ``lo + open_m`` (10 m past the end of the
    follower's safe distance); with a leader only ``hi - open_m``; a gap whose near end lies more
    than ``reach_m`` (60 m) ahead or behind is no target."""
    cfg = TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    behind = Gap(_nb("f", -40.0, 20.0), None)
    lo, hi = safe_interval(ego, behind, 20.0, 0.0, cfg)
    assert np.isfinite(lo) and hi == np.inf
    assert aim_point(ego, behind, cfg) == (pytest.approx(lo + 10.0), pytest.approx(20.0))
    ahead = Gap(None, _nb("l", 40.0, 20.0))
    lo, hi = safe_interval(ego, ahead, 20.0, 0.0, cfg)
    assert aim_point(ego, ahead, cfg) == (pytest.approx(hi - 10.0), pytest.approx(20.0))
    # the follower placed so that lo is 59 m / 61 m ahead of the ego
    lo0 = safe_interval(ego, Gap(_nb("f", 0.0, 20.0), None), 20.0, 0.0, cfg)[0]
    assert aim_point(ego, Gap(_nb("f", 59.0 - lo0, 20.0), None), cfg) is not None
    assert aim_point(ego, Gap(_nb("f", 61.0 - lo0, 20.0), None), cfg) is None
    hi0 = safe_interval(ego, Gap(None, _nb("l", 0.0, 20.0)), 20.0, 0.0, cfg)[1]
    assert aim_point(ego, Gap(None, _nb("l", -59.0 - hi0, 20.0)), cfg) is not None
    assert aim_point(ego, Gap(None, _nb("l", -61.0 - hi0, 20.0)), cfg) is None
    # no vehicle at all: the ego's own position
    assert aim_point(ego, Gap(None, None), cfg) == (0.0, 20.0)


def test_choose_gap_returns_the_gap_nearest_after_matching_its_speed_at_b_match() -> None:
    """The cost of a gap is ``|x_m - x + w|w|/(2 b_match)|`` with ``w = v_g - v``: a gap 30 m
    ahead moving 8 m/s slower than the ego is met after ``8·8/(2·2) = 16`` m of braking, at
    14 m; one 20 m behind at the ego's speed costs 20 m — the slower gap ahead is chosen although
    it is farther.  With ``b_match = 8`` the braking costs 4 m (26 m) and the gap behind wins."""
    cfg = TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)

    def gap_aimed_at(x_m: float, v: float, tag: str) -> Gap:
        # a gap of two cars 160 m apart around x_m, both at v: its aim point is the middle of its safe interval
        g = Gap(_nb(tag + "f", x_m - 80.0, v), _nb(tag + "l", x_m + 80.0, v))
        aim = aim_point(ego, g, cfg)
        assert aim is not None
        return Gap(_nb(tag + "f", 2 * x_m - aim[0] - 80.0, v), _nb(tag + "l", 2 * x_m - aim[0] + 80.0, v))

    slow_ahead = gap_aimed_at(30.0, 12.0, "a")
    same_behind = gap_aimed_at(-20.0, 20.0, "b")
    assert aim_point(ego, slow_ahead, cfg)[0] == pytest.approx(30.0)  # type: ignore[index]
    assert aim_point(ego, same_behind, cfg)[0] == pytest.approx(-20.0)  # type: ignore[index]
    assert choose_gap(ego, [same_behind, slow_ahead], None, cfg) is slow_ahead
    assert choose_gap(ego, [slow_ahead, same_behind], None, cfg) is slow_ahead
    assert choose_gap(ego, [slow_ahead, same_behind], None, replace(cfg, b_match=8.0)) is same_behind
    # hysteresis: the previous target is kept unless another is better by more than switch_m (10 m)
    assert choose_gap(ego, [slow_ahead, same_behind], ("bf", "bl"), cfg) is same_behind
    assert choose_gap(ego, [slow_ahead, same_behind], ("bf", "bl"), replace(cfg, switch_m=5.0)) is slow_ahead
    assert choose_gap(ego, [], None, cfg) is None


def test_choose_gap_skips_a_gap_whose_aim_lies_past_the_limit() -> None:
    """With ``x_limit`` (the lane's end) a gap is a target only if ``x_m + v_g·aim_s`` stays before it."""
    cfg = TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    g = Gap(_nb("f", -80.0, 20.0), _nb("l", 80.0, 20.0))
    x_m = aim_point(ego, g, cfg)[0]  # type: ignore[index]
    reach = x_m + 20.0 * cfg.aim_s
    assert choose_gap(ego, [g], None, cfg, x_limit=reach + 0.01) is g
    assert choose_gap(ego, [g], None, cfg, x_limit=reach - 0.01) is None


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(0.0, 35.0), st.floats(-60.0, 60.0), st.floats(-15.0, 15.0), st.sampled_from([4.0, 5.0, 6.0, 7.0]))
def test_end_accels_are_the_cubics_accelerations_at_both_ends(v0, dx, dv, T):
    """``end_accels`` = ``(a(0), a(T))`` of the cubic ``x(t)`` with ``x(0) = x_0``, ``ẋ(0) = v_0``,
    ``x(T) = x_f``, ``ẋ(T) = v_f`` (solved here as a 4×4 linear system), and ``peak_accel`` the
    larger magnitude."""
    ego = EgoNow(3.0, v0, 0.0, 0.0)
    xf, vf = 3.0 + v0 * T + dx, max(v0 + dv, 0.0)
    A = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, T, T**2, T**3], [0, 1, 2 * T, 3 * T**2]], dtype=float)
    c = np.linalg.solve(A, [3.0, v0, xf, vf])
    a0, aT = 2 * c[2], 2 * c[2] + 6 * c[3] * T
    got = end_accels(ego, (xf, vf), T)
    assert got == (pytest.approx(a0, abs=1e-9), pytest.approx(aT, abs=1e-9))
    assert peak_accel(ego, (xf, vf), T) == pytest.approx(max(abs(a0), abs(aT)), abs=1e-9)


def test_within_reach_tests_each_end_against_its_own_bound() -> None:
    """Bounds ``a_x ∈ [-6, 3]``: a cubic that starts at +4 and ends at -2 breaks the upper bound
    (although both magnitudes are below 6); one that starts at -5 and ends at +1 keeps both."""
    dcfg, cfg = ControllerConfig().decision, TacticalConfig()
    assert dcfg.limits.ax == (-6.0, 3.0)
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    T = 5.0

    def end_for(a0: float, aT: float) -> tuple[float, float]:
        # a(0) = 6e/T² - 2g/T, a(T) = -6e/T² + 4g/T  ->  g = (a0 + aT) T / 2, e = (a0 T² + 2 g T) / 6
        g = (a0 + aT) * T / 2
        e = (a0 * T**2 + 2 * g * T) / 6
        return ego.x + ego.vx * T + e, ego.vx + g

    up = end_for(4.0, -2.0)
    assert end_accels(ego, up, T) == (pytest.approx(4.0), pytest.approx(-2.0))
    assert not within_reach(ego, up, T, dcfg, cfg)
    assert not within_reach(ego, end_for(-2.0, 4.0), T, dcfg, cfg)
    assert within_reach(ego, end_for(-5.0, 1.0), T, dcfg, cfg)
    assert within_reach(ego, end_for(2.9, -5.9), T, dcfg, cfg)
    assert not within_reach(ego, end_for(-6.1, 0.0), T, dcfg, cfg)
    # reach_limits scales both bounds
    assert not within_reach(ego, end_for(-5.0, 1.0), T, dcfg, replace(cfg, reach_limits=0.8))


def test_the_plan_window_grows_with_the_speed_difference_either_way() -> None:
    """The window is ``plan_window_m + window_s·|v_g - v|``: a gap 10 m/s slower than the ego whose
    safe interval begins 20 m ahead is within 5 + 2·10 = 25 m and planned, as is one 10 m/s
    faster; at the ego's speed (5 m) neither position is."""
    dcfg, cfg = ControllerConfig().decision, TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    for v_g in (10.0, 30.0, 20.0):
        lo0 = safe_interval(ego, Gap(_nb("f", 0.0, v_g), None), ego.vx, 0.0, cfg)[0]
        gap = Gap(_nb("f", 20.0 - lo0, v_g), None)
        assert safe_interval(ego, gap, ego.vx, 0.0, cfg)[0] == pytest.approx(20.0)
        planned = horizons_for(ego, gap, dcfg, replace(cfg, reach_limits=10.0)) != []
        assert planned is (v_g != 20.0)


def _assert_the_least_peak_of_the_grid(ego: EgoNow, gap: Gap, T: float, grid: np.ndarray, end: tuple[float, float],
                                       cfg: TacticalConfig) -> None:
    """``end`` is a point of ``grid`` and no speed of the grid ends (at its constant-acceleration point
    clipped ``min(2, (hi - lo)/2)`` inside the safe interval) with a smaller peak acceleration."""
    assert np.min(np.abs(grid - end[1])) < 1e-12, "the end speed is not on the grid"
    best = np.inf
    for w in grid:
        lo, hi = safe_interval(ego, gap, float(w), T, cfg)
        if lo < hi:
            s = min(2.0, (hi - lo) / 2)
            x = float(np.clip(ego.x + (ego.vx + w) * T / 2, lo + s, hi - s))
            best = min(best, peak_accel(ego, (x, float(w)), T))
    assert peak_accel(ego, end, T) == pytest.approx(best, abs=1e-12)


def test_the_end_speed_grid_steps_by_speed_step_across_the_reachable_speeds() -> None:
    """When the gap's mean speed is out of reach, ``gap_end`` tries ``ceil((v_hi - v_lo)/step) + 1``
    speeds evenly from ``v_lo = max(v + REACH·a_min·T, 0)`` to ``v_hi = v + REACH·a_max·T``: with
    ``T = 5``, ``v = 13.6`` that is 53 speeds from 0 to 25.6 m/s, and the end returned is the grid
    point with the least peak acceleration (checked against every grid point here; a leader 79 m
    ahead at 5.7 m/s, a follower 22 m behind at 13.1 m/s)."""
    dcfg, cfg = ControllerConfig().decision, TacticalConfig()
    ego = EgoNow(0.0, 13.6, 0.0, 0.0)
    T = 5.0
    gap = Gap(_nb("f", -22.0, 13.1), _nb("l", 79.0, 5.7))
    v_lo, v_hi = max(13.6 + REACH * -6.0 * T, 0.0), 13.6 + REACH * 3.0 * T
    assert v_hi == pytest.approx(25.6)
    n = int(np.ceil((v_hi - v_lo) / cfg.speed_step)) + 1
    assert n == 53
    grid = np.linspace(v_lo, v_hi, n)
    end = gap_end(ego, gap, T, dcfg, cfg)
    assert end is not None
    mean = float(np.mean([13.1, 5.7]))
    assert abs(end[1] - mean) > 0.1, "the mean speed's end was reachable: the grid was not searched"
    _assert_the_least_peak_of_the_grid(ego, gap, T, grid, end, cfg)
    assert v_lo + 1e-9 < end[1] < v_hi - 1e-9  # an interior grid point (every grid holds both bounds)


def test_choose_gap_measures_from_the_ego_wherever_it_is() -> None:
    """The same two gaps and the same ego shifted 500 m along the road: the same choice (the cost
    is ``|x_m - x + w|w|/(2 b_match)|``, relative to the ego's position)."""
    cfg = TacticalConfig()
    for x0 in (0.0, 500.0):
        ego = EgoNow(x0, 20.0, 0.0, 0.0)
        slow_ahead = Gap(_nb("af", x0 - 50.0, 12.0), _nb("al", x0 + 110.0, 12.0))
        same_behind = Gap(_nb("bf", x0 - 100.0, 20.0), _nb("bl", x0 + 60.0, 20.0))
        aim_a = aim_point(ego, slow_ahead, cfg)
        aim_b = aim_point(ego, same_behind, cfg)
        assert aim_a is not None and aim_b is not None
        cost_a = abs(aim_a[0] - x0 - 8.0 * 8.0 / (2 * cfg.b_match))
        cost_b = abs(aim_b[0] - x0)
        want = slow_ahead if cost_a < cost_b else same_behind
        assert abs(cost_a - cost_b) > 1.0
        assert choose_gap(ego, [slow_ahead, same_behind], None, cfg) is want


def test_rss_following_leaves_the_gap_when_time_headway_already_covers_rss() -> None:
    """``rss_follow_gap = gap - max(0, d_RSS + m_x - v T)``: behind a much faster leader RSS needs no
    distance (``d_RSS = 0``), ``m_x = 0.5`` m is less than ``v T``, so IDM sees the true gap; behind a
    leader at its own speed it sees the gap shortened by exactly ``d_RSS + m_x - v T``."""
    from iamp.simulation.tactical import rss_follow_gap

    cfg = TacticalConfig()
    assert rss_follow_gap(30.0, 20.0, 40.0, cfg) == 30.0
    d = float(safe_longitudinal_distance(20.0, 20.0, cfg.safe.rss)) + cfg.safe.margin_x
    assert d > 20.0 * cfg.idm.T
    assert rss_follow_gap(30.0, 20.0, 20.0, cfg) == pytest.approx(30.0 - (d - 20.0 * cfg.idm.T))


def test_the_desired_speed_is_at_least_1_m_s() -> None:
    """Free road: ``seek_accel`` is IDM's free term with ``v0 = max(v0, 1)``, ``a_max (1 - (v/v0)^4)``;
    a desired speed of 0.2 m/s at 0.5 m/s gives ``1.5 (1 - 0.5^4)``, not a division by a tiny ``v0``."""
    from iamp.simulation.tactical import seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(0.0, 0.5, 0.0, 0.0)
    assert seek_accel(ego, None, None, None, 0.2, cfg) == pytest.approx(cfg.idm.a_max * (1 - 0.5**4))
    assert seek_accel(ego, None, None, None, 10.0, cfg) == pytest.approx(cfg.idm.a_max * (1 - 0.05**4))


@pytest.mark.parametrize("x0", [0.0, 250.0])
def test_the_lane_end_bound_counts_from_the_ego_s_front_end_room_m_before_the_end(x0: float) -> None:
    """With the lane ending at ``stop_x`` the braking bound is :func:`lane_end_accel` at the distance
    ``stop_x - end_room_m - x - L_e/2`` (from the ego's front to ``end_room_m`` before the end): at
    15 m/s and 40 m of that distance it brakes, and the bound is what ``seek_accel`` returns."""
    from iamp.simulation.tactical import lane_end_accel, seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(x0, 15.0, 0.0, 0.0)
    stop_x = x0 + 40.0 + cfg.end_room_m + ego.length / 2
    want = lane_end_accel(15.0, 40.0, cfg)
    assert want < 0.0
    assert seek_accel(ego, None, stop_x, None, 30.0, cfg) == pytest.approx(want, abs=1e-12)
    assert lane_end_accel(15.0, 39.0, cfg) < want  # the distance matters at this speed


@settings(max_examples=60, deadline=None)
@given(dx=st.floats(-25.0, 25.0), v_car=st.floats(15.0, 33.0), dv=st.floats(-10.0, 10.0))
def test_beside_a_single_car_a_gap_beyond_reach_is_still_the_target(dx: float, v_car: float, dv: float) -> None:
    """Beside one car of the target lane whose RSS distances reach past ``reach_m`` on both sides,
    no gap is within reach; :func:`choose_gap` then takes the best gap beyond it (the same cost
    formula), and :func:`seek_accel` steers toward it.  Before, no gap was chosen, and the ego
    drove level with the car to its lane's end (merge light 30, every planner)."""
    from iamp.simulation.tactical import seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(0.0, v_car + dv, 0.0, 0.0)
    car = _nb("c", dx, v_car)
    ahead_of_car, behind_car = Gap(car, None), Gap(None, car)
    gaps = [ahead_of_car, behind_car]
    within = [g for g in gaps if aim_point(ego, g, cfg) is not None]
    chosen = choose_gap(ego, gaps, None, cfg)
    assert chosen is not None  # a car that leaves a gap on either side always leaves a target

    def cost(g: Gap) -> float:
        xm, v = aim_point(ego, g, cfg, reach=False)  # type: ignore[misc]
        w = v - ego.vx
        return abs(xm - ego.x + w * abs(w) / (2 * cfg.b_match))

    pool = within or gaps  # within reach first, else every gap
    assert chosen in pool
    assert cost(chosen) == min(cost(g) for g in pool)
    # the chosen gap steers the ego: toward its aim point at the gap's speed (the gap term, clipped)
    xm, v = aim_point(ego, chosen, cfg, reach=False)  # type: ignore[misc]
    a_g = float(np.clip(cfg.k_speed * (v + np.clip(cfg.omega * (xm - ego.x), -cfg.closing_max, cfg.closing_max)
                                       - ego.vx), *cfg.gap_accel))
    a = seek_accel(ego, None, None, chosen, 33.33, cfg)
    assert a <= a_g + 1e-12
    free_road = replace(cfg.idm, v0=1.1 * 33.33).accel(ego.vx)
    assert a == pytest.approx(min(a_g, free_road), abs=1e-12)


def test_a_gap_within_reach_is_preferred_to_a_cheaper_one_beyond() -> None:
    """The fallback only applies when no gap is within reach: a gap within ``reach_m`` wins over
    a cheaper one beyond it."""
    cfg = TacticalConfig()
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)
    hi0 = safe_interval(ego, Gap(None, _nb("l", 0.0, 20.0)), 20.0, 0.0, cfg)[1]
    near = Gap(None, _nb("l", -55.0 - hi0, 20.0))  # its far end 55 m behind: within reach, aim 65 m behind
    assert aim_point(ego, near, cfg) is not None
    lo0 = safe_interval(ego, Gap(_nb("f", 0.0, 14.0), None), 14.0, 0.0, cfg)[0]
    far = Gap(_nb("f", 61.0 - lo0, 14.0), None)  # 61 m ahead, slower: beyond reach, aim 71 m ahead
    assert aim_point(ego, far, cfg) is None and aim_point(ego, far, cfg, reach=False) is not None
    # cheaper: |71 - 6·6/(2·2)| = 62 m against 65 m
    assert aim_point(ego, far, cfg, reach=False)[0] - 9.0 < -aim_point(ego, near, cfg)[0]  # type: ignore[index]
    assert choose_gap(ego, [far, near], None, cfg) is near
    assert choose_gap(ego, [far], None, cfg) is far


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 40.0), st.floats(0.0, 35.0), st.floats(-80.0, -5.0), st.floats(0.0, 30.0),
       st.floats(-60.0, 60.0))
def test_past_the_aim_of_a_gap_open_ahead_the_gap_term_neither_drops_back_nor_slows(
        v: float, vf: float, xf: float, v_leader_own: float, dx_own: float) -> None:
    """A gap open ahead (a follower ``f`` at ``x_f`` and ``v_f``, no leader) with the ego past its
    aim point ``lo + open_m``: the gap term's speed is ``max(v_g, v)``, so the gap term asks no
    braking -- no drop back to the aim point and no slowing to the follower's speed.  (A
    courteous follower keeps its RSS distance behind the ego: matching its speed and dropping
    back braked both to a crawl, slow-leader light 4 and 18.)  Behind the aim point the term
    still pulls the ego forward, above the follower's speed."""
    from iamp.simulation.tactical import seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb("f", xf, vf), None)
    aim = aim_point(ego, gap, cfg, reach=False)
    assert aim is not None
    own = _nb("own", dx_own if dx_own > 6.0 else 6.0 + abs(dx_own), v_leader_own)
    with_gap = seek_accel(ego, own, None, gap, 30.0, cfg)
    alone = seek_accel(ego, own, None, None, 30.0, cfg)
    xm, vg = aim
    if ego.x >= xm:
        # the gap term asks no braking: IDM's terms alone, their free road raised to 1.1 v_0, or
        # the gap term's k (max(v_g, v) - v) >= 0
        assert with_gap >= min(alone, 0.0) - 1e-12
    else:
        v_des = vg + min(cfg.omega * (xm - ego.x), cfg.closing_max)
        lo = safe_interval(ego, gap, vg, 0.0, cfg)[0]
        if v_des < cfg.roll_speed and lo <= ego.x:
            v_des = cfg.roll_speed  # rolling into the gap (a car changes lanes only while it moves)
        assert with_gap <= float(np.clip(cfg.k_speed * (v_des - v), *cfg.gap_accel)) + 1e-12


@pytest.mark.parametrize(("traffic", "seed", "before"), [("light", 4, 35.9), ("light", 8002, 35.7)])
def test_slow_leader_episodes_where_ego_and_courteous_follower_braked_to_a_crawl(traffic: str, seed: int,
                                                                                 before: float) -> None:
    """``free`` slow-leader episodes that merged after the deadline (``before`` [s], episode format
    17.7): the ego, past the aim point of the gap open ahead of a courteous follower, dropped
    back toward it at below its speed while the follower kept its RSS distance behind the ego;
    both braked to 1.5 m/s beside an empty lane, where most lane changes are refused.  Now each
    merges within 20 s, without a contact or RSS time at fault."""
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    s = run_episode(EpisodeSpec(mission="slow-leader", traffic=traffic, seed=seed, planner="free")).summary
    assert s["success"] and s["time_to_merge_s"] < min(20.0, before)
    assert s["contacts"] == 0 and s["rss_dangerous_s"] == 0.0


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 40.0), st.floats(0.0, 35.0), st.floats(-80.0, 40.0), st.floats(5.0, 40.0))
def test_the_gap_term_of_a_gap_open_ahead_is_the_docstrings(v: float, vf: float, xf: float, v0: float) -> None:
    """No leader of the ego's own, no lane end: the seek acceleration is the smaller of IDM's
    free-road term toward ``1.1 v_0`` and the gap term ``clip(k (v_des - v), [-3, 1.5])`` with
    ``v_des = v_g + clip(ω (x_m - x), ±w_max)``, ``max(v_g, v)`` past the aim point of a gap open
    ahead, and ``roll_speed`` where that is slower while the ego is inside the gap's safe interval
    with ``roll_room_m`` of it ahead (module docstring), to round-off."""
    from iamp.simulation.tactical import seek_accel

    cfg = TacticalConfig()
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb("f", xf, vf), None)
    aim = aim_point(ego, gap, cfg, reach=False)
    assert aim is not None
    xm, vg = aim
    w = float(np.clip(cfg.omega * (xm - ego.x), -cfg.closing_max, cfg.closing_max))
    v_des = max(vg, v) if w < 0.0 else vg + w
    lo, hi = safe_interval(ego, gap, vg, 0.0, cfg)
    assert hi == np.inf
    if v_des < cfg.roll_speed and lo <= ego.x:
        v_des = cfg.roll_speed
    free = replace(cfg.idm, v0=1.1 * max(v0, 1.0)).accel(v)
    want = min(free, float(np.clip(cfg.k_speed * (v_des - v), *cfg.gap_accel)))
    assert seek_accel(ego, None, None, gap, v0, cfg) == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize(("v", "T", "follower", "leader"),
                         [(27.9, 5.0, ("f", -79.0, 21.5), ("l", 24.0, 27.1)),
                          (28.1, 5.0, ("f", -83.0, 18.5), ("l", 68.0, 6.5))])
def test_the_end_speed_grid_starts_at_v_lo_when_it_is_not_zero(v: float, T: float, follower: tuple[str, float, float],
                                                               leader: tuple[str, float, float]) -> None:
    """The grid of :func:`gap_end` spans ``[v_lo, v_hi]`` with ``ceil((v_hi - v_lo)/step) + 1`` points
    also where ``v_lo = v + REACH·a_min·T`` is above zero (the grid test above has ``v_lo = 0``): the
    end returned is a point of that grid and no point of it needs a smaller peak acceleration."""
    dcfg, tac = ControllerConfig().decision, TacticalConfig()
    ax = dcfg.limits.ax
    assert ax is not None
    ego = EgoNow(0.0, v, 0.0, 0.0)
    gap = Gap(_nb(*follower), _nb(*leader))
    v_lo = float(np.clip(v + REACH * ax[0] * T, 0.0, dcfg.speed_cap))
    v_hi = float(np.clip(v + REACH * ax[1] * T, 0.0, dcfg.speed_cap))
    assert v_lo > 0.5
    grid = np.linspace(v_lo, v_hi, int(np.ceil((v_hi - v_lo) / tac.speed_step)) + 1)
    end = gap_end(ego, gap, T, dcfg, tac)
    assert end is not None
    assert abs(end[1] - (follower[2] + leader[2]) / 2) > 0.1, "the mean speed's end was reachable"
    _assert_the_least_peak_of_the_grid(ego, gap, T, grid, end, tac)
