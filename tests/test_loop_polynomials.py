"""The closed loop evaluates its neighbours' predicted cubics by Horner's rule in Python
(:func:`iamp.simulation.decision.poly_value`, :func:`~iamp.simulation.decision.poly_derivative`)
instead of numpy's ``polyval``/``polyder`` (issue 32 item 5: their per-call overhead was about a
sixth of an episode's CPU time).  The episodes must not change: the same floats bit for bit,
signed zeros included."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.decision import Neighbour, poly_derivative, poly_value
from iamp.simulation.failsafe import Obstacle

P = np.polynomial.polynomial
coef = st.floats(-1e4, 1e4, allow_subnormal=True) | st.sampled_from([0.0, -0.0, 1e-300, -2.5])
polys = st.lists(coef, min_size=1, max_size=5).map(tuple)
times = st.floats(-10.0, 10.0) | st.sampled_from([0.0, -0.0, 5.0, 0.3])


def _bits(x: float | np.floating) -> str:
    return float(x).hex()


@settings(max_examples=400, deadline=None)
@given(poly=polys, t=times)
def test_horner_is_numpys_polyval_bit_for_bit(poly: tuple[float, ...], t: float) -> None:
    assert _bits(poly_value(poly, t)) == _bits(P.polyval(t, poly))
    assert [_bits(c) for c in poly_derivative(poly)] == [_bits(c) for c in P.polyder(poly)]
    assert _bits(poly_value(poly_derivative(poly), t)) == _bits(P.polyval(t, P.polyder(poly)))


@settings(max_examples=200, deadline=None)
@given(poly=st.lists(coef, min_size=4, max_size=4).map(tuple), t=times)
def test_neighbour_and_obstacle_equal_numpy(poly: tuple[float, ...], t: float) -> None:
    """A neighbour's position and speed, and an obstacle's speeds on a grid, as numpy computes them."""
    n = Neighbour("v", poly, 0.0, 4.5, 1.8, 1)
    assert _bits(n.x(t)) == _bits(P.polyval(t, poly))
    assert _bits(n.v(t)) == _bits(P.polyval(t, P.polyder(poly)))
    grid = np.linspace(0.0, abs(t) + 0.1, 7)
    x, v = Obstacle("v", poly, 0.0, 4.5, 1.8).xv(grid)
    assert x.tobytes() == np.asarray(P.polyval(grid, poly), dtype=float).tobytes()
    assert v.tobytes() == np.maximum(P.polyval(grid, P.polyder(poly)), 0.0).tobytes()
