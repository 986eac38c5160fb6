"""The fail-safe brakes along the ego's lane where the road frame does not follow it (SPEC §16).

A road frame fitted near the ego on a curved road (:func:`iamp.commonroad.convert.road_frame`)
leaves the lanes at an angle to its path; the fail-safe's braking (:class:`~iamp.commonroad.interactive.Braking`)
brought the lateral speed to zero *in the frame*, so it turned the car away from its lane (the
public DEU_Muc-3_1: 47 executed steps off CommonRoad's road while braking).  With ``slope`` (the
lane's ``dd/ds``) it keeps the lane's direction instead.  Pure kinematics: no extra needed.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st


def _braking(slope: float, **kw):  # type: ignore[no-untyped-def]
    from iamp.commonroad.interactive import Braking

    return Braking(kw.pop("x0"), kw.pop("decel"), kw.pop("v_end"), kw.pop("t_lat"), kw.pop("d_end", None), slope=slope)


@settings(max_examples=60, deadline=None)
@given(slope=st.floats(-0.3, 0.3), v0=st.floats(2.0, 35.0), vd_rel=st.floats(-2.0, 2.0), decel=st.floats(1.0, 8.0),
       frac=st.sampled_from([0.0, 0.25, 0.5, 0.75]), d_end=st.one_of(st.none(), st.floats(-2.0, 2.0)))
def test_braking_is_the_same_motion_about_the_lanes_line(slope: float, v0: float, vd_rel: float, decel: float,
                                                         frac: float, d_end: float | None) -> None:
    """The braking with ``slope`` is the braking without it, shifted by the lane's line
    ``d = d0 + m (s - s0)``: its states (offset and lateral speed) and inputs (the lateral one plus
    ``m`` times the longitudinal) differ exactly by the line's, the longitudinal motion unchanged;
    it ends at rest relative to the lane (its lateral speed ``m`` times its speed), and its
    lateral acceleration is the derivative of its lateral speed."""
    x_rel = (10.0, v0, 0.5, vd_rel)
    x0 = (10.0, v0, 0.5, vd_rel + slope * v0)
    kw = {"decel": decel, "v_end": frac * v0, "t_lat": 1.0, "d_end": d_end}
    lane = _braking(slope, x0=x0, **kw)
    flat = _braking(0.0, x0=x_rel, **kw)
    t = np.linspace(0.0, 6.0, 241)
    A, B = lane.states(t), flat.states(t)
    assert np.allclose(A[:, [0, 1]], B[:, [0, 1]], atol=1e-12)
    assert np.allclose(A[:, 2], B[:, 2] + slope * (B[:, 0] - 10.0), atol=1e-9)
    assert np.allclose(A[:, 3], B[:, 3] + slope * B[:, 1], atol=1e-9)
    Ua, Ub = lane.inputs(t), flat.inputs(t)
    assert np.allclose(Ua[:, 0], Ub[:, 0]) and np.allclose(Ua[:, 1], Ub[:, 1] + slope * Ub[:, 0], atol=1e-9)
    late = t > max(lane.t_b, 1.0) + 1e-6
    assert np.allclose(A[late, 3], slope * A[late, 1], atol=1e-9)
    # the lateral acceleration is the lateral speed's derivative (central differences, away from kinks)
    mid = (t > 0.05) & (np.abs(t - 1.0) > 0.05) & (np.abs(t - lane.t_b) > 0.05) & (t < 5.95)
    h = 1e-5
    dv = (lane.states(t[mid] + h)[:, 3] - lane.states(t[mid] - h)[:, 3]) / (2 * h)
    assert np.allclose(dv, Ua[mid, 1], atol=1e-4)


def test_without_a_slope_the_numbers_are_those_of_before() -> None:
    """``slope`` 0 gives the braking of before bit for bit (the shared scenes' fail-safes)."""
    from iamp.commonroad.interactive import Braking

    b = Braking((3.0, 20.0, -0.4, 0.7), 4.0, 5.0, 1.0)
    t = np.linspace(0.0, 5.0, 51)
    tb = np.minimum(t, 15.0 / 4.0)
    s = 3.0 + 20.0 * tb - 2.0 * tb**2 + 5.0 * (t - tb)
    tl = np.minimum(t, 1.0)
    d = -0.4 + 0.7 * tl - 0.35 * tl**2
    X = b.states(t)
    assert np.array_equal(X[:, 0], s) and np.array_equal(X[:, 2], d)


@pytest.mark.parametrize("slope", [0.1, -0.2])
def test_the_failsafe_keeps_the_lanes_direction(slope: float) -> None:
    """In a lane running at ``slope`` across the frame, the car moving along it: the braking stays
    on the lane's line (within 1 cm over 4 s); without the slope it would leave it by metres."""
    from iamp.commonroad.interactive import Braking

    x0 = (0.0, 20.0, 0.0, slope * 20.0)
    t = np.linspace(0.0, 4.0, 41)
    along = Braking(x0, 4.0, 0.0, 1.0, slope=slope).states(t)
    assert np.max(np.abs(along[:, 2] - slope * along[:, 0])) < 1e-9
    frame = Braking(x0, 4.0, 0.0, 1.0).states(t)
    assert np.max(np.abs(frame[:, 2] - slope * frame[:, 0])) > 1.0
