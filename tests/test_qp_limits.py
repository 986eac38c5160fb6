"""The limit rows of planners/qp/limits.py: each row is the bound it names, on every layout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.planners.examples import random_problem
from iamp.planners.qp.data import QPData
from iamp.planners.qp.limits import limit_rows, polygon_normals

ALL = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.5), a_total=8.0, vx=(1.0, 40.0), y=(-1.0, 4.75), jerk=5.0)


def _random_z(d: QPData, rng: np.random.Generator) -> np.ndarray:
    return rng.normal(scale=5.0, size=d.n)


@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_rows_are_the_bounds_they_name(hold: str) -> None:
    p = random_problem(3)
    lim = ALL if hold == "foh" else PhysicalLimits(ax=ALL.ax, ay=ALL.ay, a_total=8.0, vx=ALL.vx, y=ALL.y)
    d = QPData(p, 20, hold)
    rows = limit_rows(d, d.t_nodes, hold, lim)
    rng = np.random.default_rng(0)
    z = _random_z(d, rng)
    X, U = d.unpack(z)
    Az = rows.A @ z
    for kind, quantity, rng_ in (("ax", U[:, 0], lim.ax), ("ay", U[:, 1], lim.ay), ("vx", X[:, 1], lim.vx),
                                 ("y", X[:, 2], lim.y)):
        sel = rows.kind == kind
        assert np.array_equal(rows.node[sel], np.arange(quantity.size))
        np.testing.assert_array_equal(Az[sel], quantity)
        assert np.all(rows.lo[sel] == rng_[0]) and np.all(rows.hi[sel] == rng_[1])
    if hold == "foh":
        for a, kind in enumerate(("jerk_x", "jerk_y")):
            sel = rows.kind == kind
            np.testing.assert_allclose(Az[sel], np.diff(U[:, a]), rtol=0, atol=1e-12)
            np.testing.assert_allclose(rows.hi[sel], 5.0 * d.h, rtol=1e-15)
            np.testing.assert_allclose(rows.lo[sel], -5.0 * d.h, rtol=1e-15)
    sel = rows.kind == "a_total"
    assert rows.polygon_sides == 16 and sel.sum() == 8 * U.shape[0]


@settings(max_examples=60, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(0.0, 1.2), st.sampled_from([16, 18, 32, 64]))
def test_polygon_inside_circle_and_close_to_it(angle: float, radius: float, sides: int) -> None:
    """A point is in the polygon iff |n_j·u| <= cos(π/M) for all j; the polygon lies in the unit
    circle and contains the circle of radius cos(π/M)."""
    normals, apothem = polygon_normals(sides)
    u = radius * np.array([math.cos(angle), math.sin(angle)])
    inside = bool(np.all(np.abs(normals @ u) <= apothem + 1e-15))
    if radius > 1.0 + 1e-12:
        assert not inside
    if radius <= apothem - 1e-12:
        assert inside
    # the vertices (angles π/M + 2πk/M) are on the unit circle and on two edges each
    vert = np.array([[math.cos(math.pi / sides * (2 * k + 1)), math.sin(math.pi / sides * (2 * k + 1))]
                     for k in range(sides)])
    g = np.abs(vert @ normals.T)
    assert np.all(g <= apothem + 1e-12)
    assert np.all(np.sum(np.isclose(g, apothem, atol=1e-12), axis=1) >= 1)


def test_polygon_sides_validated() -> None:
    with pytest.raises(ValueError, match="even number >= 16"):
        polygon_normals(12)
    with pytest.raises(ValueError, match="even number >= 16"):
        polygon_normals(17)


def test_jerk_refused_with_zoh() -> None:
    p = random_problem(1)
    d = QPData(p, 10, "zoh")
    with pytest.raises(ScenarioError, match="limits.jerk"):
        limit_rows(d, d.t_nodes, "zoh", PASSENGER_CAR)


def test_layout_mismatch_refused() -> None:
    p = random_problem(1)
    d = QPData(p, 10, "zoh")
    with pytest.raises(ValueError, match="not FOH"):
        limit_rows(d, d.t_nodes, "foh", PhysicalLimits(ax=(-1.0, 1.0)))


def test_no_bounds_no_rows() -> None:
    p = random_problem(1)
    d = QPData(p, 10, "foh")
    rows = limit_rows(d, d.t_nodes, "foh", PhysicalLimits())
    assert rows.n_rows == 0 and rows.A.shape == (0, d.n)


def test_grid_changes_only_jerk_bounds() -> None:
    p = random_problem(2)
    d = QPData(p, 12, "foh")
    rows = limit_rows(d, d.t_nodes, "foh", ALL)
    t2 = np.sort(np.r_[0.0, np.random.default_rng(1).uniform(0, p.tf, 11), p.tf])
    lo, hi = rows.bounds_for(t2)
    jerk = np.isin(rows.kind, ["jerk_x", "jerk_y"])
    np.testing.assert_array_equal(lo[~jerk], rows.lo[~jerk])
    np.testing.assert_allclose(hi[jerk], 5.0 * np.tile(np.diff(t2), 2), rtol=1e-15)
    fresh = limit_rows(d, t2, "foh", ALL)
    np.testing.assert_array_equal(fresh.hi, hi)
    assert (fresh.A != rows.A).nnz == 0
