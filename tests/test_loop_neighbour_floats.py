"""A neighbour converts its cubic's coefficients to Python floats once and evaluates it by
:func:`iamp.simulation.decision.horner`: positions and speeds are the floats of the former
:func:`~iamp.simulation.decision.poly_value` (which converted every coefficient on every call), kept
here as the oracle, bit for bit: coefficients as floats, numpy floats or integers, times as floats,
numpy floats or integers, signed zeros, ``nan`` and ``inf`` included."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.decision import Neighbour, float_coefficients, horner, poly_derivative, poly_value


def _old_poly_value(poly, t):
    if len(poly) == 4:
        c0, c1, c2, c3 = poly
        return float(float(c0) + (float(c1) + (float(c2) + (float(c3) + t * 0) * t) * t) * t)
    if len(poly) == 3:
        c0, c1, c2 = poly
        return float(float(c0) + (float(c1) + (float(c2) + t * 0) * t) * t)
    acc = float(poly[-1]) + t * 0
    for k in range(len(poly) - 2, -1, -1):
        acc = float(poly[k]) + acc * t
    return float(acc)


def _bits(x) -> bytes:
    return np.float64(x).tobytes()


def _same(f, g) -> None:
    """``f()`` and ``g()`` give the same float bits, or raise the same exception type."""
    try:
        expect = g()
    except (OverflowError, ZeroDivisionError) as e:
        with pytest.raises(type(e)):
            f()
        return
    got = f()
    assert type(got) is float
    assert _bits(got) == _bits(expect)


SPECIAL = [0.0, -0.0, math.nan, math.inf, -math.inf, 5e-324, 1e300]
number = st.one_of(st.floats(-1e4, 1e4), st.sampled_from(SPECIAL), st.floats())
coef = st.one_of(number, number.map(np.float64), st.integers(-50, 50))
times = st.one_of(st.floats(-10.0, 10.0), st.sampled_from([0.0, -0.0, 0.5, 5.0, math.inf, math.nan]),
                  st.floats(-10.0, 10.0).map(np.float64), st.integers(-3, 7))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=600, deadline=None)
@given(poly=st.lists(coef, min_size=1, max_size=6).map(tuple), t=times)
def test_poly_value_and_horner_are_the_former_poly_value(poly, t):
    _same(lambda: poly_value(poly, t), lambda: _old_poly_value(poly, t))
    _same(lambda: horner(float_coefficients(poly), t), lambda: _old_poly_value(poly, t))
    assert all(type(c) is float for c in float_coefficients(poly))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=400, deadline=None)
@given(poly=st.lists(coef, min_size=1, max_size=5).map(tuple), t=times, other=st.lists(coef, min_size=4, max_size=4))
def test_a_neighbours_position_and_speed_are_the_former_floats(poly, t, other):
    n = Neighbour("v", poly, -1.875, 4.5, 1.8, 1)
    for _ in range(2):  # computed, then from the kept coefficients
        _same(lambda: n.x(t), lambda: _old_poly_value(poly, t))
        _same(lambda: n.v(t), lambda: _old_poly_value(poly_derivative(poly), t))
    m = dataclasses.replace(n, poly=tuple(other))  # another cubic: its own coefficients, never the kept ones
    _same(lambda: m.x(t), lambda: _old_poly_value(tuple(other), t))
    _same(lambda: m.v(t), lambda: _old_poly_value(poly_derivative(tuple(other)), t))
