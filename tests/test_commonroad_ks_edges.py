"""The steered car at the road's edge (issue 33): a plan whose ``KS`` solution leaves CommonRoad's
road is repaired laterally with the margin the steered body lacks
(:func:`iamp.commonroad.planning.steer_at_edges`), judged by CommonRoad's own road check.

Every test needs the ``[commonroad]`` extra and the shared US-101 data; each skips with the reason
where either is absent.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from conftest import data_path, needs_commonroad_data
from hypothesis import given, settings
from hypothesis import strategies as st

DATA = data_path("commonroad", "US101")
needs_data = needs_commonroad_data("commonroad", "US101")


def _ks_verdict(cr, rp):  # type: ignore[no-untyped-def]
    from iamp.commonroad.check import check
    from iamp.commonroad.solution import build_solution

    solution, dev = build_solution(cr, rp.trajectory, rp.candidate.steps, vehicle_model="KS")
    return check(cr.scenario, cr.planning_problem_set, solution, cost=False), dev


@needs_data
def test_the_steered_car_on_us101_5_stays_on_the_road() -> None:
    """US101-5 (the shared set's one ``KS`` failure): the ego starts 5 mm from a left edge that
    narrows.  The point-mass plan clears CommonRoad's road; the steered car follows it 5 mm off,
    its body turned to the rear axle's heading (6 mrad behind the plan's direction of travel), and
    leaves the road at 0.5-0.7 s.  Without the vehicle type (a plain engine tuple, as before) the
    ``KS`` solution is off road; with it the plan is repaired at the steered body's margins and
    the ``KS`` solution is valid by CommonRoad's checker."""
    from iamp.commonroad.convert import load
    from iamp.commonroad.ks import track
    from iamp.commonroad.planning import ks_engine, off_road_poses, plan

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cr = load(DATA / "USA_US101-5_1_T-1.xml")
    engine = ks_engine(2)
    before = plan(cr, engine=tuple(engine[:5]))
    assert before.safe
    verdict, _ = _ks_verdict(cr, before)
    assert not verdict.valid and not verdict.checks["road_boundary"]["ok"]
    after = plan(cr, engine=engine)
    assert after.safe and after.iamp_status == "steered-edge-repair", after.iamp_status
    ks = track(cr, after.trajectory, after.candidate.steps, 2)
    assert not off_road_poses(cr, ks.centre, ks.states[:, 4]).any()
    verdict, dev = _ks_verdict(cr, after)
    assert verdict.valid, verdict.checks
    assert dev < 0.02
    # the point-mass solution of the repaired plan is valid too (the repair keeps every vehicle's side)
    pm = plan(cr)
    assert pm.iamp_status != "steered-edge-repair"


@needs_data
@settings(max_examples=15, deadline=None)
@given(x=st.floats(-3.0, 3.0), y=st.floats(-3.0, 3.0), th=st.floats(-0.3, 0.3))
def test_road_clearance_is_the_growth_at_which_the_body_leaves_the_road(x: float, y: float, th: float) -> None:
    """:func:`~iamp.commonroad.planning.road_clearance` near US101-5's narrowing left edge (the
    ego's start moved by up to 3 m, turned by up to 0.3 rad): the body grown by the returned value
    is on CommonRoad's road and grown by the bisection's resolution more it is off (or the value
    is an end of the interval searched, with the same meaning there)."""
    from iamp.commonroad.planning import CLEARANCE_ITERATIONS, off_road_poses, road_clearance

    cr = _us101_5()
    init = cr.planning_problem.initial_state
    c = np.asarray(init.position, dtype=float)[None, :] + np.array([[x, y]])
    h = np.array([float(init.orientation) + th])
    lo, hi = -0.2, 0.05
    g = float(road_clearance(cr, c, h, lo, hi)[0])
    step = (hi - lo) / 2**CLEARANCE_ITERATIONS
    if g > lo:
        assert not off_road_poses(cr, c, h, g)[0]
    else:
        assert off_road_poses(cr, c, h, lo)[0]
    if g < hi:
        assert off_road_poses(cr, c, h, g + step + 1e-9)[0]
    else:
        assert not off_road_poses(cr, c, h, hi)[0]
    assert math.isfinite(g)


_CACHE: dict[str, object] = {}


def _us101_5():  # type: ignore[no-untyped-def]
    from iamp.commonroad.convert import load

    if "cr" not in _CACHE:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _CACHE["cr"] = load(DATA / "USA_US101-5_1_T-1.xml")
    return _CACHE["cr"]


#: USA_US101-6_204_T-1 (seed 1, ``lanes3``): three lanes over at 18-24 m/s, heading in [-0.759, -0.585]
#: (the generated problem's); the test below narrows the heading to [-0.750, -0.585].
GOAL_6_204 = [{"time_step": [70, 80], "velocity": [18.2385, 24.2385], "orientation": [-0.7594, -0.5849],
               "position": {"center": [101.9631, -98.245], "length": 2.2446, "width": 1.7266,
                            "orientation": -0.65965}}]


@needs_data
def test_a_plan_whose_steered_car_misses_the_goal_heading_is_not_taken(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """6_204 as ``KS``, its goal heading narrowed to [-0.750, -0.585]: the plan ends turning with its
    direction of travel inside the goal's heading interval, but the steered car's heading (the rear
    axle's) lags it by the slip angle and ends outside: goal missed.  A plan whose tracked
    solution misses the goal by CommonRoad's own test is not taken while another final state or
    the corridor planner (whose goal rows hold for the rear axle's heading) gives one that
    reaches it: valid by CommonRoad's checker.  (With the generated problem's interval,
    [-0.759, -0.585], the plan missed it by 4 mrad until the avoidance's search changed with the
    multipliers' tangent; its plan under the budget of ``AVOID_MAX_SOLVES`` now ends at -0.7535,
    inside.)"""
    import copy

    from test_commonroad_unseen import with_goal

    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import ks_engine, plan

    goal = copy.deepcopy(GOAL_6_204)
    goal[0]["orientation"] = [-0.7500, -0.5849]
    cr = load(with_goal(tmp_path, "USA_US101-6_1_T-1.xml", "USA_US101-6_204_T-1", goal))
    engine = ks_engine(2)
    before = plan(cr, engine=tuple(engine[:5]))
    assert before.safe and before.steered_goal is None
    verdict, _ = _ks_verdict(cr, before)
    assert not verdict.valid and not verdict.checks["goal_reached"]["ok"]
    after = plan(cr, engine=engine)
    assert after.safe and after.steered_goal is True
    verdict, _ = _ks_verdict(cr, after)
    assert verdict.valid, verdict.checks


@needs_data
@settings(max_examples=40, deadline=None)
@given(along=st.floats(-40.0, 40.0), across=st.floats(-12.0, 12.0), th=st.floats(-0.4, 0.4))
def test_every_body_off_the_road_is_near_an_edge(along: float, across: float, th: float) -> None:
    """:func:`~iamp.commonroad.planning.near_road_edges` decides which steered bodies need
    CommonRoad's road check; a body it calls far from every edge must be on the road by that
    check (bodies placed along and across US101-5's road, which narrows, turned by up to 0.4 rad)."""
    from iamp.commonroad.planning import near_road_edges, off_road_poses

    cr = _us101_5()
    init = cr.planning_problem.initial_state
    psi = float(init.orientation)
    u = np.array([math.cos(psi), math.sin(psi)])
    n = np.array([-u[1], u[0]])
    c = (np.asarray(init.position, dtype=float) + along * u + across * n)[None, :]
    h = np.array([psi + th])
    if off_road_poses(cr, c, h)[0]:
        assert near_road_edges(cr, c, h)[0]
