"""The decision layer's choice of gap and end state (``simulation/decision.py``), on cases worked
by hand and as properties over generated traffic.

The gap's room at the horizon ``T`` is ``[lo, hi]``: behind the leader's rear and ahead of the
follower's front, each less half the ego's length.  Gaps are ranked by the distance from the
ego's constant-speed end point ``x_cs = x + v T`` to that room (0 inside).  The end speed is the
gap's mean speed, clipped to what ``REACH`` of the ``a_x`` bounds reaches in ``T`` and to
``[0, speed_cap]``; the end position is the constant-acceleration one, clipped to keep a headway
``headway_s · v_f`` inside the room (the room's middle when it is shorter than two headways).
These tests were written against survivors of
``python scripts/mutation_score.py simulation/decision.py --sample 24 --seed 3``.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.physical import PhysicalLimits
from iamp.simulation.decision import REACH, DecisionConfig, EgoNow, Gap, Neighbour, candidate_gaps, end_state

EGO_L = 4.8


def car(name: str, x0: float, v: float, length: float = 4.8) -> Neighbour:
    return Neighbour(name, (x0, v), y=3.5, length=length, width=1.8, lane=1)


def cfg(ax: tuple[float, float] | None = (-4.0, 2.0), **kw: float) -> DecisionConfig:
    return DecisionConfig(limits=PhysicalLimits(ax=ax), **kw)  # type: ignore[arg-type]


def test_end_state_worked_by_hand() -> None:
    """Follower at 0 m and leader at 60 m, both 20 m/s; ego at 10 m, 25 m/s; T = 5 s.

    Room: [100 + 2.4 + 2.4, 160 - 2.4 - 2.4] = [104.8, 155.2]; v_f = 20 (inside the reach
    [25 - 0.8*4*5, 25 + 0.8*2*5] = [9, 33]); x = 10 + 45*5/2 = 122.5; headway 20 m, so the end is
    clipped to 104.8 + 20 = 124.8."""
    ego = EgoNow(10.0, 25.0, 0.0, 0.0, length=EGO_L)
    x, v = end_state(ego, Gap(car("f", 0.0, 20.0), car("l", 60.0, 20.0)), cfg(), 5.0)
    assert v == pytest.approx(20.0, abs=1e-12)
    assert x == pytest.approx(124.8, abs=1e-12)


def test_end_speed_is_clipped_to_what_the_ax_bounds_reach() -> None:
    """A gap at 40 m/s from an ego at 25 m/s: a_x <= 2 m/s^2 at REACH 0.8 over 5 s reaches 33 m/s."""
    ego = EgoNow(0.0, 25.0, 0.0, 0.0, length=EGO_L)
    gap = Gap(car("f", -200.0, 40.0), car("l", 300.0, 40.0))
    _, v = end_state(ego, gap, cfg(), 5.0)
    assert v == pytest.approx(25.0 + REACH * 2.0 * 5.0, abs=1e-12)
    _, v_slow = end_state(ego, Gap(car("f", -200.0, 0.0), car("l", 300.0, 0.0)), cfg(), 5.0)
    assert v_slow == pytest.approx(25.0 - REACH * 4.0 * 5.0, abs=1e-12)
    # without a_x bounds only [0, speed_cap] clips
    _, v_free = end_state(ego, gap, cfg(ax=None), 5.0)
    assert v_free == pytest.approx(40.0, abs=1e-12)


def test_a_room_shorter_than_two_headways_ends_in_its_middle() -> None:
    """Follower front at 100 + 2.4, leader rear at 130 - 2.4 at T: room [104.8, 125.2], 20.4 m,
    shorter than two 20 m headways: the middle, 115.0."""
    ego = EgoNow(0.0, 20.0, 0.0, 0.0, length=EGO_L)
    x, _ = end_state(ego, Gap(car("f", 0.0, 20.0), car("l", 30.0, 20.0)), cfg(), 5.0)
    assert x == pytest.approx(115.0, abs=1e-12)


def test_the_gap_holding_the_constant_speed_end_point_comes_first() -> None:
    """x_cs = 10 + 20*5 = 110.  Cars (all 20 m/s) at 0, 20.3 and 65 m, so at T at 100, 120.3 and
    165: the room of [0, 20.3] is [104.8, 115.5] and holds 110; the room behind 0 ends at
    100 - 4.8 = 95.2 (14.8 m away); the room of [20.3, 65] starts at 125.1 (15.1 m away).  A score
    that gave the gap holding x_cs 1 instead of 0, or measured from x - v T, or halved the lengths
    the wrong way, reorders them."""
    ego = EgoNow(10.0, 20.0, 0.0, 0.0, length=EGO_L)
    a, b, c = car("a", 0.0, 20.0), car("b", 20.3, 20.0), car("c", 65.0, 20.0)
    gaps = candidate_gaps(ego, [c, a, b], cfg(max_gaps=4))
    assert [(g.follower.name if g.follower else None, g.leader.name if g.leader else None) for g in gaps] == [
        ("a", "b"), (None, "a"), ("b", "c"), ("c", None)]
    # the room holding x_cs comes before one 0.85 m from it (short cars and ego: rooms 0.8 m apart)
    short = EgoNow(10.0, 20.0, 0.0, 0.0, length=0.4)
    a2, b2 = car("a", 9.55, 20.0, length=0.4), car("b", 60.0, 20.0, length=0.4)
    first = candidate_gaps(short, [a2, b2], cfg(max_gaps=1))[0]
    assert first.follower is a2 and first.leader is b2

@settings(max_examples=150, deadline=None)
@given(xs=st.lists(st.floats(-55.0, 55.0), min_size=0, max_size=6, unique=True),
       vs=st.lists(st.floats(0.0, 35.0), min_size=6, max_size=6),
       ego_v=st.floats(0.0, 35.0), T=st.sampled_from([3.0, 5.0]))
def test_ranking_is_by_distance_to_the_room(xs: list[float], vs: list[float], ego_v: float, T: float) -> None:
    """The gaps come in the order of the distance from x_cs to their room (stable for ties)."""
    ego = EgoNow(0.0, ego_v, 0.0, 0.0, length=EGO_L)
    cars = [car(f"c{k}", x, vs[k]) for k, x in enumerate(xs)]
    c = cfg(max_gaps=10, horizon_s=T)
    x_cs = ego_v * T
    ordered = sorted(cars, key=lambda n: n.x(0.0))
    bounds = [None, *ordered, None]

    def distance(f: Neighbour | None, ld: Neighbour | None) -> float:
        lo = -float("inf") if f is None else f.x(T) + f.length / 2 + EGO_L / 2
        hi = float("inf") if ld is None else ld.x(T) - ld.length / 2 - EGO_L / 2
        return 0.0 if lo <= x_cs <= hi else min(abs(x_cs - lo), abs(x_cs - hi))

    got = [distance(g.follower, g.leader) for g in candidate_gaps(ego, cars, c)]
    assert got == sorted(got)
    assert len(got) == len(bounds) - 1


def test_the_checked_vehicles_are_the_nearest_in_the_lanes_within_reach() -> None:
    """``check_problem``: the neighbours of the given lanes within ``relevant_m`` (60 m) of the
    ego, nearest first; a car ahead in the ego's own lane closer than ``safety_x`` gets the region
    it leaves (its gap less 0.5 m): the ego is already there."""
    from iamp.core.problem import EgoBoundary
    from iamp.simulation.decision import check_problem

    ego = EgoNow(100.0, 20.0, 0.0, 0.0, length=EGO_L)
    boundary = EgoBoundary(tf=5.0, x0=100.0, y0=0.0, vx0=20.0, xf=200.0, yf=0.0, vxf=20.0)

    def at(name: str, x: float, lane: int, y: float) -> Neighbour:
        return Neighbour(name, (x, 20.0), y=y, length=4.8, width=1.8, lane=lane)

    near_ahead = at("ahead", 106.0, 0, 0.0)  # own lane: rear 3.6 m ahead of the ego's centre
    cars = [at("far", 170.0, 0, 0.0), at("back", 50.0, 0, 0.0), at("side", 130.0, 1, 3.5),
            near_ahead, at("other-lane", 101.0, 2, 7.0)]
    problem = check_problem(boundary, ego, cars, [0, 1], cfg())
    assert problem is not None
    assert [v.name for v in problem.vehicles] == ["ahead", "side", "back"]
    assert problem.vehicles[0].safety_x == pytest.approx(106.0 - 2.4 - 100.0 - 0.5, abs=1e-12)
    assert problem.vehicles[1].safety_x == 5.0 and problem.vehicles[2].safety_x == 5.0
    assert check_problem(boundary, ego, [at("far", 170.0, 0, 0.0)], [0, 1], cfg()) is None


def test_a_fast_follower_beyond_relevant_m_bounds_the_gap_while_within_its_rss_distance() -> None:
    """A target-lane car 137 m behind at 34 m/s, the ego at 20 m/s: beyond ``relevant_m`` (60 m), so
    without RSS's parameters the gap behind the nearest car is open-ended; with them (the closed
    loop) that car bounds it (its RSS distance is about 150 m), and a car as far behind at the
    ego's own speed does not."""
    from iamp.simulation.rss import DEFAULT

    ego = EgoNow(0.0, 20.0, 0.0, 0.0, length=EGO_L)
    fast, near = car("fast", -137.0, 34.0), car("near", 30.0, 20.0)
    plain = candidate_gaps(ego, [fast, near], cfg())
    assert all(g.follower is None or g.follower.name != "fast" for g in plain)
    with_rss = candidate_gaps(ego, [fast, near], cfg(rss=DEFAULT))  # type: ignore[arg-type]
    assert any(g.follower is not None and g.follower.name == "fast" for g in with_rss)
    slow = car("slow", -137.0, 20.0)
    assert all(g.follower is None or g.follower.name != "slow"
               for g in candidate_gaps(ego, [slow, near], cfg(rss=DEFAULT)))  # type: ignore[arg-type]
