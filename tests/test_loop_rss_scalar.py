"""RSS's scalar distances (the loop's thousands of questions per episode) are the former functions' floats.

* :func:`iamp.simulation.rss.safe_longitudinal_float` with the parameters' terms computed once per
  parameter set (:attr:`RssParameters.scalar_terms`) and the ``max`` calls written out;
* :func:`iamp.simulation.rss.safe_lateral_float`, the float of two floats without the 0-d arrays, and
  :func:`~iamp.simulation.rss.lateral_reach` / :func:`~iamp.simulation.rss.safe_lateral_distance` on
  arrays, all from one expression.

Each is compared bit for bit with the implementation it replaced, kept here as the oracle, over
speeds with signed zeros, ties at the positive part's kink, ``nan`` and ``inf``, and parameter sets
of floats and of integers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.rss import (
    RssParameters,
    lateral_reach,
    safe_lateral_distance,
    safe_lateral_float,
    safe_longitudinal_distance,
    safe_longitudinal_float,
)


def _old_rss_scalar(v_r, v_f, rho, a_acc, b_min, b_max):
    vr, vf = max(v_r, 0.0), max(v_f, 0.0)
    v_rho = max(vr + rho * a_acc, 0.0)
    d = vr * rho + 0.5 * a_acc * (rho * rho) + v_rho**2 / (2.0 * b_min) - vf**2 / (2.0 * b_max)
    return max(d, 0.0)


def _old_rss_distance(v_r, v_f, rho, a_acc, b_min, b_max):
    if all(isinstance(z, float) for z in (v_r, v_f, rho, a_acc, b_min, b_max)):
        return np.asarray(_old_rss_scalar(float(v_r), float(v_f), float(rho), float(a_acc), float(b_min),
                                          float(b_max)), dtype=float)
    vr = np.maximum(np.asarray(v_r, dtype=float), 0.0)
    vf = np.maximum(np.asarray(v_f, dtype=float), 0.0)
    rho_, a = np.asarray(rho, dtype=float), np.asarray(a_acc, dtype=float)
    v_rho = np.maximum(vr + rho_ * a, 0.0)
    d = vr * rho_ + 0.5 * a * rho_**2 + v_rho**2 / (2.0 * np.asarray(b_min, dtype=float)) \
        - vf**2 / (2.0 * np.asarray(b_max, dtype=float))
    return np.asarray(np.maximum(d, 0.0), dtype=float)


def _old_safe_longitudinal_float(v_rear, v_front, p):
    rho, a_acc, b_min, b_max = p.response_time_s, p.accel_max, p.brake_min, p.brake_max
    if isinstance(v_rear, float) and isinstance(v_front, float) and isinstance(rho, float) \
            and isinstance(a_acc, float) and isinstance(b_min, float) and isinstance(b_max, float):
        return _old_rss_scalar(float(v_rear), float(v_front), float(rho), float(a_acc), float(b_min), float(b_max))
    return float(_old_rss_distance(v_rear, v_front, rho, a_acc, b_min, b_max))


def _old_lateral_reach(u_toward, p):
    u = np.asarray(u_toward, dtype=float)
    rho, a = p.response_time_s, p.lat_accel_max
    after = np.maximum(u + rho * a, 0.0)
    return np.asarray(u * rho + 0.5 * a * rho**2 + after**2 / (2 * p.lat_brake_min), dtype=float)


def _old_safe_lateral_distance(u1, u2, p):
    return np.asarray(p.lat_margin_m + np.maximum(_old_lateral_reach(u1, p) + _old_lateral_reach(u2, p), 0.0),
                      dtype=float)


def _bits(x) -> bytes:
    return np.float64(x).tobytes()


SPECIAL = [0.0, -0.0, math.nan, math.inf, -math.inf, 5e-324, -5e-324, 1e300]
speed = st.one_of(st.floats(-50.0, 50.0), st.sampled_from(SPECIAL), st.floats(allow_nan=True, allow_infinity=True))
#: A lateral speed at the kink of ``max(u + ρ α, 0)``: ``-ρ α`` and its neighbouring floats.
lat_speed = st.one_of(speed, st.sampled_from([-0.1, float(np.nextafter(-0.1, 0.0)), float(np.nextafter(-0.1, -1.0)),
                                              -0.5, -0.25]))
params = st.one_of(
    st.just(RssParameters()),
    st.builds(RssParameters, response_time_s=st.sampled_from([0.5, 1.0, 0.37, 1]),
              accel_max=st.sampled_from([3.5, 2.0, 3]), brake_min=st.sampled_from([4.0, 4, 3.3]),
              brake_max=st.sampled_from([8.0, 8, 9.5]), lat_accel_max=st.sampled_from([0.2, 0.5, 1]),
              lat_brake_min=st.sampled_from([0.8, 1, 1.7]), lat_margin_m=st.sampled_from([0.1, 0.0, 0, 0.35])))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=600, deadline=None)
@given(v_r=st.one_of(speed, st.integers(-5, 40), st.sampled_from([np.float64(3.5), np.float64(-0.0)])),
       v_f=st.one_of(speed, st.integers(-5, 40)), p=params)
def test_safe_longitudinal_float_is_the_former_float(v_r, v_f, p):
    try:
        old = _old_safe_longitudinal_float(v_r, v_f, p)
    except OverflowError:  # a Python float's square out of range: raised before as now
        with pytest.raises(OverflowError):
            safe_longitudinal_float(v_r, v_f, p)
        return
    got = safe_longitudinal_float(v_r, v_f, p)
    assert type(got) is float
    assert _bits(got) == _bits(old)
    if isinstance(v_r, float) and isinstance(v_f, float):  # and the array function's float
        assert _bits(got) == _bits(float(safe_longitudinal_distance(v_r, v_f, p)))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=200, deadline=None)
@given(v_r=st.lists(speed, min_size=0, max_size=6), v_f=speed, p=params)
def test_the_longitudinal_array_function_is_unchanged(v_r, v_f, p):
    got = safe_longitudinal_distance(np.array(v_r, dtype=float), v_f, p)
    old = _old_rss_distance(np.array(v_r, dtype=float), v_f, p.response_time_s, p.accel_max, p.brake_min, p.brake_max)
    assert got.shape == old.shape and got.tobytes() == old.tobytes()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=600, deadline=None)
@given(u1=st.one_of(lat_speed, st.integers(-3, 3), st.just(np.float64(0.3))),
       u2=st.one_of(lat_speed, st.integers(-3, 3)), p=params)
def test_safe_lateral_float_is_the_float_of_the_former_array_function(u1, u2, p):
    got = safe_lateral_float(u1, u2, p)
    assert type(got) is float
    assert _bits(got) == _bits(float(_old_safe_lateral_distance(u1, u2, p)))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=300, deadline=None)
@given(u1=st.one_of(lat_speed, st.lists(lat_speed, min_size=0, max_size=6)), u2=lat_speed, p=params)
def test_lateral_array_functions_are_unchanged(u1, u2, p):
    for got, old in ((lateral_reach(u1, p), _old_lateral_reach(u1, p)),
                     (safe_lateral_distance(u1, u2, p), _old_safe_lateral_distance(u1, u2, p))):
        assert type(got) is np.ndarray and got.dtype == np.float64
        assert got.shape == old.shape and got.tobytes() == old.tobytes()


def test_scalar_terms_are_kept_only_for_float_parameters():
    assert RssParameters().scalar_terms is not None
    assert RssParameters(brake_min=4).scalar_terms is None  # integers: the array path, as before
    p = RssParameters(response_time_s=0.37, accel_max=2.9, brake_min=3.3, brake_max=9.1)
    rho, rho_a, half, two_bmin, two_bmax = p.scalar_terms
    assert (rho, rho_a, half, two_bmin, two_bmax) == (0.37, 0.37 * 2.9, 0.5 * 2.9 * (0.37 * 0.37), 6.6, 18.2)
