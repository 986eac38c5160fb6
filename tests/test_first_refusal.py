"""One call validates an object's fields against the bounds table (:func:`iamp.core.limits.first_refusal`):
the first failing check in order, bound checks before magnitude checks, with the per-field texts; and
the objects of :mod:`iamp.core.problem` refuse exactly the first out-of-bounds field (hypothesis)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.errors import ScenarioError
from iamp.core.limits import LIMITS, abs_message, bound_message, first_refusal
from iamp.core.problem import EgoBoundary, SurroundingVehicle

value = st.floats(-1e4, 1e4, allow_nan=False)
side = st.one_of(st.none(), value)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(value, side, side), max_size=5), st.lists(st.tuples(value, st.floats(0, 1e4)), max_size=5))
def test_the_first_refusal_is_the_first_failing_check_in_order(bounds, absolutes):
    b = [(f"b{i}", v, lo, hi, "m") for i, (v, lo, hi) in enumerate(bounds)]
    a = [(f"a{i}", v, bound, "m/s") for i, (v, bound) in enumerate(absolutes)]
    expected = None
    for field, v, lo, hi, unit in b:
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            expected = (field, bound_message(v, lo, hi, unit))
            break
    if expected is None:
        for field, v, bound, unit in a:
            if abs(v) > bound:
                expected = (field, abs_message(v, bound, unit))
                break
    assert first_refusal(b, a) == expected
    if expected is not None:
        assert expected[1] is not None and ("must" in expected[1])


EGO = dict(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=85.0, yf=3.75, vxf=20.0)
EGO_FIELDS = ("x0", "y0", "xf", "yf", "vx0", "vy0", "vxf", "vyf")


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from(EGO_FIELDS), st.floats(-3e6, 3e6, allow_nan=False), max_size=4))
def test_the_ego_refuses_its_first_field_beyond_its_magnitude_bound(changes):
    """The ego's fields are checked in the order of ``_EGO_KIND`` (positions x0, y0, xf, yf
    against ``position_max_m``, speeds against ``speed_max_mps``); the refusal names the first."""
    order = ("x0", "y0", "xf", "yf", "vx0", "vy0", "vxf", "vyf")
    kw = {**EGO, **changes}
    first = next((n for n in order if abs(kw.get(n, 0.0)) > (LIMITS["speed_max_mps"] if n.startswith("v")
                                                             else LIMITS["position_max_m"])), None)
    if first is None:
        EgoBoundary(**kw)
        return
    with pytest.raises(ScenarioError) as err:
        EgoBoundary(**kw)
    assert err.value.field == f"ego.{first}" and "|value| must be <=" in err.value.message


@pytest.mark.parametrize(("field", "bad"), [("length", 1e5), ("width", 1e5), ("safety_x", 1e5), ("safety_y", 1e5),
                                            ("y", 2e6)])
def test_a_vehicle_refuses_its_out_of_bounds_field_by_name(field, bad):
    kw = dict(x_poly=(0.0, 10.0), corner="front-lower", y=3.75, length=4.8, width=1.8, safety_x=5.0, safety_y=0.5)
    with pytest.raises(ScenarioError) as err:
        SurroundingVehicle(**{**kw, field: bad}, field_prefix="vehicles[2]")
    assert err.value.field == f"vehicles[2].{field}"
    bound = LIMITS["position_max_m"] if field == "y" else LIMITS["size_max_m"]
    assert f"{bound:g}" in err.value.message and not math.isnan(bad)
