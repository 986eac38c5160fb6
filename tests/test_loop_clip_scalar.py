"""The loop clips its scalars (the lane keeping's inputs, the tactical layer's speeds and end points)
with :func:`iamp.simulation.decision.clip_scalar` instead of ``float(np.clip(...))``, the former code
and here the oracle: the same float bit for bit, for floats, integers and numpy floats, signed zeros,
``nan`` of any payload in any position, infinities, subnormals and crossed bounds (``lo > hi``)."""

from __future__ import annotations

import itertools
import math
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.decision import clip_scalar


def _nan(bits: int) -> float:
    return struct.unpack("<d", struct.pack("<Q", bits))[0]


NANS = [math.nan, -math.nan, _nan(0x7FF8000000000001), _nan(0xFFF8000000000123), _nan(0x7FF4000000000777)]
SPECIAL = [0.0, -0.0, math.inf, -math.inf, 5e-324, -5e-324, 1.0, -1.0, 0.5, *NANS]


def _bits(v) -> bytes:
    return np.float64(v).tobytes()


def _check(x, lo, hi) -> None:
    got = clip_scalar(x, lo, hi)
    assert type(got) is float
    assert _bits(got) == _bits(float(np.clip(x, lo, hi))), (x, lo, hi)


def test_every_combination_of_special_values():
    for x, lo, hi in itertools.product(SPECIAL, repeat=3):
        _check(x, lo, hi)


number = st.one_of(st.floats(), st.sampled_from(SPECIAL), st.floats(-10.0, 10.0), st.integers(-5, 5),
                   st.floats(-10.0, 10.0).map(np.float64))


@settings(max_examples=1500, deadline=None)
@given(x=number, lo=number, hi=number)
def test_clip_scalar_is_numpys_clip_bit_for_bit(x, lo, hi):
    _check(x, lo, hi)


@settings(max_examples=300, deadline=None)
@given(x=st.floats(-10.0, 10.0), lo=st.floats(-10.0, 10.0))
def test_ties_at_the_bounds(x, lo):
    """``x`` equal to a bound, the bounds equal, and zeros of both signs at the bounds."""
    for a, b, c in ((x, x, lo), (x, lo, x), (lo, x, x), (x, lo, lo), (-0.0, 0.0, lo), (0.0, -0.0, -0.0)):
        _check(a, b, c)
