"""The vehicles at their contact times (:mod:`iamp.core.contact`): corners and speeds against the
polynomial written out term by term, over generated vehicles (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core import contact
from iamp.core.problem import CORNERS, EgoBoundary, Problem, SurroundingVehicle

EGO = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=85.0, yf=3.75, vxf=20.0)
coef = st.floats(-2.0, 2.0, allow_nan=False)  # |x_s| and |ẋ_s| within the bounds over [0, 5] s


@st.composite
def problems(draw):
    m = draw(st.integers(0, 4))
    vehicles = []
    for i in range(m):
        poly = tuple(draw(st.lists(coef, min_size=1, max_size=4)))
        vehicles.append(SurroundingVehicle(
            x_poly=poly, corner=draw(st.sampled_from(CORNERS)), y=draw(st.floats(-5, 5)),
            length=draw(st.floats(1, 20)), width=draw(st.floats(1, 3)), safety_x=draw(st.floats(0, 10)),
            safety_y=draw(st.floats(0, 1)), name=f"v{i}"))
    times = draw(st.lists(st.floats(0.01, 4.99), min_size=m, max_size=m))
    return Problem(EGO, tuple(vehicles)), np.array(times)


@settings(max_examples=200, deadline=None)
@given(problems())
def test_corners_and_speeds_are_the_polynomials_written_out(case):
    problem, t = case
    C, v = contact.corners_and_speeds(problem, t)
    assert v.shape == (problem.m,)
    assert C.shape == (problem.m, 2) if problem.m else C.size == 0  # no vehicle: an empty array
    for i, (veh, ti) in enumerate(zip(problem.vehicles, t)):
        x = sum(c * ti ** k for k, c in enumerate(veh.x_poly))
        xdot = sum(k * c * ti ** (k - 1) for k, c in enumerate(veh.x_poly) if k > 0)
        front = 1.0 if veh.corner.startswith("front") else -1.0
        upper = 1.0 if veh.corner.endswith("upper") else -1.0
        assert np.isclose(C[i, 0], x + front * (veh.length / 2 + veh.safety_x), rtol=1e-12, atol=1e-9)
        assert C[i, 1] == veh.y + upper * (veh.width / 2 + veh.safety_y)
        assert np.isclose(v[i], xdot, rtol=1e-12, atol=1e-9)
    # the Problem's methods are these functions (the same numbers, not a second formula)
    np.testing.assert_array_equal(problem.corners(t), C)
    Cp, vp = problem.corners_and_speeds(t)
    np.testing.assert_array_equal(Cp, C)
    np.testing.assert_array_equal(vp, v)
