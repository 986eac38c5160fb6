"""The one minimum-energy cubic (iamp.core.free) and a Problem with zero vehicles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import iamp
from iamp.core.free import FreeTrajectory, free_plan, min_energy_cubic, transfer_cost
from iamp.core.problem import EgoBoundary, Problem
from iamp.planners.pmp.fixed import hermite_cubic
from iamp.planners.pmp.scale import _hermites, hermite_sigma

finite = st.floats(-50, 50, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(s0=finite, v0=finite, sf=finite, vf=finite, tf=st.floats(0.5, 10))
def test_the_cubic_meets_its_end_states_and_its_energy_is_the_transfer_cost(s0, v0, sf, vf, tf):
    c = np.array(min_energy_cubic(s0, v0, sf, vf, tf))
    P = np.polynomial.polynomial
    scale = max(1.0, abs(s0), abs(sf), abs(v0) * tf, abs(vf) * tf)
    assert P.polyval(tf, c) == pytest.approx(sf, abs=1e-9 * scale)
    assert P.polyval(tf, P.polyder(c)) * tf == pytest.approx(vf * tf, abs=1e-9 * scale)
    # J = ½∫u², u = 2c2 + 6c3 t linear: Simpson is exact; an independent evaluation of the closed form
    u = P.polyval(np.array([0, tf / 2, tf]), P.polyder(c, 2))
    J = 0.5 * tf / 6 * (u[0] ** 2 + 4 * u[1] ** 2 + u[2] ** 2)
    assert J == pytest.approx(transfer_cost(s0, v0, sf, vf, tf), rel=1e-7, abs=1e-7 * scale**2 / tf**3)


@settings(max_examples=30, deadline=None)
@given(s0=finite, v0=finite, sf=finite, vf=finite)
def test_every_planner_copy_is_the_shared_cubic_bit_for_bit(s0, v0, sf, vf):
    ref = np.array(min_energy_cubic(s0, v0, sf, vf))
    assert np.array_equal(hermite_sigma(s0, v0, sf, vf), ref)
    hx, hy = _hermites([s0, v0, sf, vf, vf, sf, v0, s0])  # both axes in one call, each the shared cubic
    assert np.array_equal(np.array(hx), ref)
    assert np.array_equal(np.array(hy), np.array(min_energy_cubic(vf, sf, v0, s0)))
    assert np.array_equal(hermite_cubic(s0, v0, sf, vf, 1.0), ref)


def test_a_problem_with_zero_vehicles_is_the_free_cubic():
    ego = iamp.load_scenario("paper-1-poly").ego
    prob = Problem(ego, ())
    assert prob.m == 0
    plan = iamp.plan(prob)
    assert plan.status == "optimal" and plan.contact_times.size == 0
    J = (transfer_cost(ego.x0, ego.vx0, ego.xf, ego.vxf, ego.tf)
         + transfer_cost(ego.y0, ego.vy0, ego.yf, ego.vyf, ego.tf))
    assert plan.cost == pytest.approx(J, rel=1e-12)
    assert plan.residuals["boundary"] < 1e-9 * max(abs(ego.xf), 1.0)
    # the constrained optimum costs at least as much (a lower bound attained only without contact)
    assert iamp.plan(iamp.load_scenario("paper-1-poly")).cost >= plan.cost
    with pytest.raises(iamp.IampError, match="at least one vehicle"):
        iamp.plan(prob, "qp")
    assert plan.to_json()["cost"] == pytest.approx(J, rel=1e-12)


def test_free_plan_of_a_boundary_is_a_real_problem():
    ego = EgoBoundary(tf=4.0, x0=0.0, y0=0.0, vx0=20.0, vy0=0.0, xf=85.0, yf=3.5, vxf=22.0, vyf=0.0)
    plan = free_plan(ego, "qp")
    assert isinstance(plan.problem, Problem) and plan.problem.m == 0 and plan.planner == "qp"
    assert isinstance(plan.trajectory, FreeTrajectory)
