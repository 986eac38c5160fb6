"""The fail-safe may bring the ego back to its lane's centre (``iamp simulate --commonroad``).

SUMO inserts vehicles where the recording has them as soon as its insertion gap allows: in
USA_US101-23_1 (seed 1, with the goal's plan tried before an early lane change) vehicle 75 appeared
at 3.3 s 0.24 m ahead of the ego's front bumper and 0.5 m beside its body in the lane the ego was
moving into (1.2 m/s across the road).  Every fail-safe braking let the lateral speed fall to zero
over 1 s, so the body went on 0.6 m toward 75 and met it (a contact at fault at 3.6 s).  The
fail-safe now also tries the same braking returning to rest at the centre of the lane the ego's
centre is in (:class:`iamp.commonroad.interactive.Braking` with ``d_end``, over
:data:`~iamp.commonroad.interactive.FAILSAFE_RETURN_S`), within ``a_max``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_commonroad_interactive import _fixture, _moving, needs_extra


@needs_extra
@settings(deadline=None, max_examples=60, derandomize=True)
@given(d0=st.floats(-3.0, 3.0), vd0=st.floats(-3.0, 3.0), d_end=st.floats(-4.0, 4.0), t_lat=st.floats(0.5, 3.0),
       v0=st.floats(0.0, 30.0), decel=st.floats(1.0, 10.0))
def test_braking_to_a_lateral_target_is_the_cubic_between_its_ends(d0: float, vd0: float, d_end: float, t_lat: float,
                                                                  v0: float, decel: float) -> None:
    """``Braking(..., d_end)``: the lateral offset starts at ``x0``'s offset and lateral speed and
    rests at ``d_end`` from ``t_lat`` on; its lateral input is the derivative of its lateral speed
    and the lateral speed the derivative of the offset (central differences); along the road it
    is the same braking as without ``d_end``."""
    from iamp.commonroad.interactive import Braking

    x0 = (10.0, v0, d0, vd0)
    b = Braking(x0, decel, 0.0, t_lat, d_end)
    plain = Braking(x0, decel, 0.0, t_lat)
    X0, XT, X2 = b.states([0.0, t_lat, t_lat + 2.0])
    assert X0 == pytest.approx([10.0, v0, d0, vd0], abs=1e-9)
    assert XT[2] == pytest.approx(d_end, abs=1e-9) and XT[3] == pytest.approx(0.0, abs=1e-9)
    assert X2[2] == pytest.approx(d_end, abs=1e-9) and X2[3] == 0.0
    h = 1e-4
    t = np.linspace(0.01, t_lat - 0.01, 23)
    Xp, Xm = b.states(t + h), b.states(t - h)
    np.testing.assert_allclose((Xp[:, 2] - Xm[:, 2]) / (2 * h), b.states(t)[:, 3], atol=1e-5)
    np.testing.assert_allclose((Xp[:, 3] - Xm[:, 3]) / (2 * h), b.inputs(t)[:, 1], atol=1e-5)
    tt = np.linspace(0.0, t_lat + 3.0, 40)
    np.testing.assert_allclose(b.states(tt)[:, :2], plain.states(tt)[:, :2])
    np.testing.assert_allclose(b.inputs(tt)[:, 0], plain.inputs(tt)[:, 0])


def _inserted_beside() -> tuple[Any, float]:
    """The 23_1 moment in the fixture: the ego (18 m/s) 1.6 m left of its lane's centre moving
    left at 1.3 m/s; a car (5 m x 1.8 m, 15 m/s) appears in the next lane 2.0 m to the left of
    the ego's centre line (its right side 0.3 m from the ego's left side), its rear 0.24 m ahead
    of the ego's front.  Returns the live problem and the centre of the ego's lane."""
    from iamp.commonroad.tactical import LaneMap

    cr = _fixture()
    s0, _, d_lane, _ = cr.x0
    lanes = LaneMap(cr)
    lid = lanes.at(s0, d_lane)
    assert lid is not None
    centre = lanes.centre(lid, s0)
    assert centre is not None
    x0 = (s0, 18.0, centre + 1.6, 1.3)
    car = _moving(75, s0 + cr.ego_length / 2 + 0.24 + 2.5, x0[2] + cr.ego_width / 2 + 0.3 + 0.9, 15.0)
    return dataclasses.replace(cr, x0=x0, obstacles=[car], road_edges=[]), centre


@needs_extra
def test_the_failsafe_steers_back_to_its_lane_away_from_a_car_inserted_beside_a_lane_change() -> None:
    """No braking of the fail-safe's list that only lets the lateral speed fall to zero keeps
    clear of the inserted car (the ego is faster and its body drifts 0.65 m further left); the
    fail-safe given the lane's centre returns there, keeps its body off the car over the checked
    horizon and stays inside the friction circle.  Without the lane's centre the fail-safe is the
    plain braking, as before."""
    from iamp.commonroad.interactive import (
        FAILSAFE_DECEL,
        FAILSAFE_MIN_S,
        FAILSAFE_SPEEDS,
        Braking,
        failsafe,
        rear_vehicles,
        rss_followers,
    )
    from iamp.commonroad.planning import intrusions

    live, centre = _inserted_beside()
    v0 = live.x0[1]
    for a in (*FAILSAFE_DECEL, 0.9 * live.a_max):
        for f in FAILSAFE_SPEEDS:
            b = Braking(live.x0, a, f * v0, FAILSAFE_MIN_S)
            assert intrusions(live, b, 3.0), (a, f)
    followers, rear = rss_followers(live), rear_vehicles(live)
    old, _ = failsafe(live, live.a_max, followers, rear)
    assert old.d_end is None
    traj, T = failsafe(live, live.a_max, followers, rear, centre)
    assert traj.d_end == pytest.approx(centre)
    assert not intrusions(live, traj, T)
    t = np.arange(0.0, T + 1e-9, live.dt)
    assert float(np.max(np.hypot(*traj.inputs(t).T))) <= live.a_max + 1e-9
    assert traj.states([T])[0][2] == pytest.approx(centre, abs=1e-9)
