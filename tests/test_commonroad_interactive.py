"""CommonRoad interactive closed loop (``iamp simulate --commonroad``): what the ego does when a
replan finds no safe plan.

The fail-safe tests need the ``[commonroad]`` extra only (the generated scenario
``tests/fixtures/commonroad_goals.xml`` with a vehicle placed in the ego's lane); the closed-loop
test needs SUMO and the shared interactive scenes and skips with the reason where absent.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import data_path
from hypothesis import given, settings
from hypothesis import strategies as st

FIXTURE = Path(__file__).parent / "fixtures" / "commonroad_goals.xml"
HAVE_EXTRA = all(importlib.util.find_spec(m) is not None for m in ("commonroad", "commonroad_dc", "triangle"))
HAVE_SUMO = importlib.util.find_spec("libsumo") is not None or importlib.util.find_spec("traci") is not None
INTERACTIVE = data_path("commonroad", "interactive-US101")
needs_extra = pytest.mark.skipif(not HAVE_EXTRA, reason="the [commonroad] extra is not installed "
                                                        "(pip install 'iamp[commonroad]')")

_CR: Any = None


def _fixture() -> Any:
    global _CR
    if _CR is None:
        from iamp.commonroad.convert import load

        _CR = load(FIXTURE)
    return _CR


def _standing(s: float, d: float, horizon: float = 12.0) -> Any:
    """A vehicle (4.5 m x 1.8 m) standing at ``(s, d)`` in the road frame over ``horizon``."""
    from iamp.commonroad.convert import Obstacle

    t = np.arange(0.0, horizon + 1e-9, 0.1)
    n = t.size
    return Obstacle(7, t, np.full(n, s - 2.25), np.full(n, s + 2.25), np.full(n, d - 0.9), np.full(n, d + 0.9),
                    4.5, 1.8, (s, 0.0, 0.0, 0.0), 2.25, 0.0, 0, False)


def _live(v0: float, gap: float | None) -> Any:
    """The fixture's ego at its start offset driving at ``v0`` along the lane, a standing vehicle
    ``gap`` metres (centre to centre) ahead in its lane (none if ``None``), no road edge."""
    cr = _fixture()
    s0, _, d0, _ = cr.x0
    obstacles = [] if gap is None else [_standing(s0 + gap, d0)]
    return dataclasses.replace(cr, x0=(s0, v0, d0, 0.0), obstacles=obstacles, road_edges=[])


@needs_extra
def test_failsafe_slows_gently_when_nothing_is_ahead() -> None:
    """With the lane free the fail-safe is the least braking: to 3/4 of the speed at 2 m/s^2,
    then on at that speed in the lane (the lateral speed brought to zero over 1 s)."""
    from iamp.commonroad.interactive import FAILSAFE_DECEL, FAILSAFE_SPEEDS, failsafe

    live = _live(20.0, None)
    live = dataclasses.replace(live, x0=(live.x0[0], 20.0, live.x0[2], 0.4))
    traj, T = failsafe(live, live.a_max)
    assert traj.inputs([0.0])[0, 0] == pytest.approx(-FAILSAFE_DECEL[0])
    end = traj.states([T])[0]
    assert end[1] == pytest.approx(FAILSAFE_SPEEDS[0] * 20.0) and end[3] == pytest.approx(0.0, abs=1e-12)
    assert end[2] == pytest.approx(live.x0[2] + 0.2)  # vd0 * 1 s / 2
    # the states integrate the inputs
    t = np.linspace(0.0, T, 2001)
    X, U = traj.states(t), traj.inputs(t)
    assert np.allclose(np.diff(X[:, 1]), 0.5 * (U[1:, 0] + U[:-1, 0]) * np.diff(t), atol=2e-2 * 2e-3 * 20)
    assert np.allclose(np.diff(X[:, 0]), 0.5 * (X[1:, 1] + X[:-1, 1]) * np.diff(t), atol=1e-5)


@needs_extra
def test_failsafe_brakes_as_hard_as_the_standing_vehicle_needs() -> None:
    """20 m/s with a standing vehicle 40 m ahead (its rear at 37.75 m): at 2 and 4 m/s^2 even a
    stop (100 m, 50 m) runs into it; at 6 m/s^2 slowing to 15 or 10 m/s runs into it within 3 s, slowing
    to 5 m/s does not (31.25 m in 2.5 s, then 2.5 m by 3 s: its front at 33.75 + 2.25 = 36.0 m)."""
    from iamp.commonroad.interactive import failsafe
    from iamp.commonroad.planning import intrusions

    live = _live(20.0, 40.0)
    traj, T = failsafe(live, live.a_max)
    assert traj.inputs([0.0])[0, 0] == pytest.approx(-6.0)
    assert traj.states([T])[0, 1] == pytest.approx(5.0)
    assert not intrusions(live, traj, T)


@needs_extra
@settings(max_examples=25, deadline=None)
@given(v0=st.floats(0.0, 35.0), gap=st.floats(5.0, 150.0))
def test_failsafe_keeps_clear_whenever_a_stop_within_the_limit_does(v0: float, gap: float) -> None:
    """Property: whenever braking to a stop at 0.9 a_max ends the body short of a standing
    vehicle, the fail-safe keeps clear of it and never exceeds a_max."""
    from iamp.commonroad.interactive import failsafe
    from iamp.commonroad.planning import intrusions

    live = _live(v0, gap)
    a = live.a_max
    traj, T = failsafe(live, a)
    assert float(np.max(np.abs(traj.inputs(np.linspace(0.0, T, 50))))) <= a + 1e-9
    if v0**2 / (2 * 0.9 * a) + 2.25 < gap - 2.25 - 0.1:
        assert not intrusions(live, traj, T)


@needs_extra
def test_shifted_is_the_plan_from_its_offset() -> None:
    from iamp.commonroad.interactive import Shifted
    from iamp.commonroad.planning import FreeTrajectory

    plan = FreeTrajectory(5.0, (0.0, 10.0, 0.0, 0.5), (60.0, 12.0, 3.0, 0.0))
    t = np.linspace(0.0, 3.0, 7)
    assert np.allclose(Shifted(plan, 2.0).states(t), plan.states(t + 2.0))
    assert np.allclose(Shifted(plan, 2.0).inputs(t), plan.inputs(t + 2.0))


@pytest.mark.slow
@pytest.mark.skipif(not HAVE_EXTRA or not HAVE_SUMO or not (INTERACTIVE / "USA_US101-2_1_I-1-1").is_dir(),
                    reason="needs the [commonroad] and [sim] extras and the shared interactive scenarios "
                           f"({INTERACTIVE})")
def test_braking_traffic_is_not_run_into() -> None:
    """USA_US101-2_1: the traffic ahead brakes from 15 to 3 m/s; keeping the previous plan (19 m/s)
    when no safe replan exists ran into vehicles 518 and 515 (two contacts, the ego at fault).
    The loop now keeps a previous plan only while it stays clear of the predictions, else brakes."""
    from iamp.commonroad.interactive import simulate

    r = simulate(INTERACTIVE / "USA_US101-2_1_I-1-1")
    assert r["collisions"] == 0 and r["contacts_at_fault"] == 0
    assert r["failsafe_brakes"] >= 1


@needs_extra
def test_predicted_box_spreads_along_the_road_with_time() -> None:
    """A vehicle observed at a constant 15 m/s: its predicted box keeps its length at t = 0 and
    grows by SPREAD_MPS * t at both ends (at most SPREAD_MAX_M), so a plan passing close ahead
    of or behind it keeps room for SUMO's drivers wandering about the predicted speed (in
    USA_US101-12_2 the ego cut in 0.3 m ahead of vehicle 300, which ran 0.25 m further than
    predicted over 0.6 s)."""
    from iamp.commonroad.interactive import SPREAD_MAX_M, SPREAD_MPS, _observed_obstacle
    from iamp.prediction.predictor import Predictor

    cr = _fixture()
    hist_t = [0.0, 0.5, 1.0, 1.5]
    hist_s = [100.0 + 15.0 * t for t in hist_t]
    t = np.arange(0.0, 10.01, 0.1)
    ob = _observed_obstacle(cr, 1, hist_t, hist_s, (120.0, 125.0, -1.0, 1.0), 15.0, t, Predictor.default())
    length = ob.s_hi - ob.s_lo
    assert length[0] == pytest.approx(5.0)
    assert np.allclose(length, 5.0 + 2 * np.minimum(SPREAD_MPS * t, SPREAD_MAX_M))
    assert ob.half_length >= 2.5 + float(np.minimum(SPREAD_MPS * t[-1], SPREAD_MAX_M))  # the planner's box too
