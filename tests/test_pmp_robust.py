"""PMP self-verification (issue 9.1) and scaling (issue 9): large but legitimate numbers,
long polynomials, negligible trailing coefficients; failures become statuses, never
exceptions, and name the check that failed."""

import dataclasses
import math

import numpy as np
import pytest
from scipy import interpolate, optimize

from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.status import INACCURATE, NUMERICAL_ERROR, OPTIMAL
from iamp.core.tolerances import tol
from iamp.planners.examples import DEFAULT_GEOMETRY, paper_problem, random_problem
from iamp.planners.pmp.planner import PMPPlanner, solve_fixed_times
from iamp.planners.pmp.scale import scale_problem, strip_negligible
from iamp.planners.pmp.verify import check_values, judge

CHECKS = {"linear_system", "boundary", "corner", "h_minimisation", "costate_jump", "hamiltonian_jump",
          "cost_consistency"}


def independent_one_vehicle(problem: Problem, corner_x, n: int = 3000) -> tuple[float, float]:
    """min over t of the clamped-spline cost through the corner ``(corner_x(t), corner_y)``:
    dense grid + bounded Brent; ``corner_x`` is any callable (e.g. the exact exp motion)."""
    ego, v = problem.ego, problem.vehicles[0]
    xg, wg = np.polynomial.legendre.leggauss(4)

    def cost(t: float) -> float:
        total = 0.0
        knots = np.array([0.0, t, ego.tf])
        for y, (v0, vf) in (([ego.x0, corner_x(t), ego.xf], (ego.vx0, ego.vxf)),
                            ([ego.y0, v.corner_y, ego.yf], (ego.vy0, ego.vyf))):
            cs = interpolate.CubicSpline(knots, y, bc_type=((1, v0), (1, vf)))
            for a, b in zip(knots[:-1], knots[1:]):
                tt = (b - a) / 2 * xg + (a + b) / 2
                total += 0.5 * (b - a) / 2 * np.sum(wg * cs(tt, 2) ** 2)
        return total

    grid = np.linspace(0, ego.tf, n)[1:-1]
    vals = np.array([cost(t) for t in grid])
    k = int(np.argmin(vals))
    res = optimize.minimize_scalar(cost, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
                                   method="bounded", options={"xatol": 1e-11})
    return float(res.fun), float(res.x)


def _with_poly(problem: Problem, poly) -> Problem:
    return problem.with_vehicles([dataclasses.replace(problem.vehicles[0], x_poly=tuple(poly))])


# ------------------------------------------------------------------------------------------
# self-verification
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("problem", [paper_problem(1), random_problem(3, m=2)], ids=["paper-1", "random-3-m2"])
def test_optimal_plan_reports_every_check_inside_its_tolerance(problem):
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL and plan.info["failed_check"] is None
    assert set(plan.info["checks"]) == CHECKS
    for name, c in plan.info["checks"].items():
        assert c["ok"] and 0 <= c["value"] <= c["tol"], name


def test_corrupted_solution_fails_the_named_check():
    problem = random_problem(4, m=2)
    sol = PMPPlanner().solve(problem)
    good = check_values(sol)
    assert all(c["ok"] for c in judge(good)[0].values())
    bad = dataclasses.replace(sol, jumps=sol.jumps * (1 + 1e-6), z_scaled=None)
    checks, failed, status = judge(check_values(bad))
    assert status == INACCURATE and failed is not None and not checks[failed]["ok"]
    assert checks["corner"]["value"] > tol("pmp_scaled_residual")  # the corners are missed
    # a wrong initial input breaks the final state and the linear system, not the corners' formula
    bad_a = dataclasses.replace(sol, a=sol.a + 1e-5, z_scaled=None)
    checks, failed, _ = judge(check_values(bad_a))
    assert not checks["boundary"]["ok"] and not checks["linear_system"]["ok"]


def test_non_finite_value_is_a_numerical_error():
    checks, failed, status = judge({"corner": float("nan"), "boundary": 0.0})
    assert status == NUMERICAL_ERROR and failed == "corner" and not checks["corner"]["ok"]


def test_singular_contact_times_return_a_failed_plan_not_an_exception():
    problem = random_problem(1, m=2)
    plan = PMPPlanner().plan(problem, contact_times=[2.0, 2.0])
    assert plan.status == NUMERICAL_ERROR and plan.cost is None
    assert plan.info["failed_check"] == "linear_system"
    assert plan.to_json("x", 10)["cost"] is None


def test_given_contact_times_outside_the_horizon_are_a_caller_error():
    with pytest.raises(ValueError):
        PMPPlanner().plan(paper_problem(1), contact_times=[-1.0])


# ------------------------------------------------------------------------------------------
# scaling
# ------------------------------------------------------------------------------------------

def test_long_taylor_series_gives_the_true_optimum():
    """x_s(t) = −15 + 18t + A(e^{t/τ} − 1 − t/τ) as 30 Taylor coefficients; the reference
    uses math.exp (no polynomial at all)."""
    A, tau = 0.5, 3.0
    poly = [-15.0, 18.0] + [A / (math.factorial(k) * tau**k) for k in range(2, 30)]
    base = paper_problem(1)
    problem = _with_poly(base, poly)
    plan = PMPPlanner().plan(problem)
    assert plan.status == OPTIMAL
    off = problem.vehicles[0].offset_x
    ref, t_ref = independent_one_vehicle(problem, lambda t: -15 + 18 * t + A * (math.exp(t / tau) - 1 - t / tau) + off)
    assert plan.cost == pytest.approx(ref, rel=tol("independent_cost_rel"))
    assert plan.contact_times[0] == pytest.approx(t_ref, abs=tol("independent_contact_time_abs"))


def test_negligible_high_terms_equal_the_cubic():
    """A cubic plus 26 terms far below rounding on [0, t_f] solves like the cubic."""
    base = paper_problem(2)
    cubic = list(base.vehicles[0].x_poly) + [0.0] * (4 - len(base.vehicles[0].x_poly))
    long = cubic + [1e-30 / 10**k for k in range(26)]
    a = PMPPlanner().plan(_with_poly(base, cubic))
    b = PMPPlanner().plan(_with_poly(base, long))
    assert b.status == OPTIMAL
    assert b.cost == pytest.approx(a.cost, rel=1e-12)
    assert b.contact_times[0] == pytest.approx(a.contact_times[0], abs=1e-12)


def test_trailing_1e_300_coefficient_is_dropped_exactly():
    base = paper_problem(3)
    poly = list(base.vehicles[0].x_poly)
    a = PMPPlanner().plan(_with_poly(base, poly))
    b = PMPPlanner().plan(_with_poly(base, poly + [0.0, 1e-300]))
    assert b.status == OPTIMAL
    assert b.cost == a.cost and np.array_equal(b.contact_times, a.contact_times) and np.array_equal(b.jumps, a.jumps)
    assert len(strip_negligible(np.array(poly + [0.0, 1e-300]), base.tf)) == len(poly)
    np.testing.assert_array_equal(scale_problem(_with_poly(base, poly + [1e-300])).EX, scale_problem(base).EX)


def test_far_from_the_origin_is_the_same_lane_change():
    """Translating the whole scene by 9.9e4 m (inside the position limit) changes nothing but
    rounding: same cost, contact time and jumps."""
    base = random_problem(11, m=2)
    shift = 9.9e4 - 200.0
    ego = dataclasses.replace(base.ego, x0=base.ego.x0 + shift, xf=base.ego.xf + shift)
    vs = [dataclasses.replace(v, x_poly=(v.x_poly[0] + shift,) + tuple(v.x_poly[1:])) for v in base.vehicles]
    far = Problem(ego, tuple(vs), "far")
    a, b = PMPPlanner().plan(base), PMPPlanner().plan(far)
    assert a.status == b.status == OPTIMAL
    assert b.cost == pytest.approx(a.cost, rel=1e-7)
    assert np.allclose(b.contact_times, a.contact_times, atol=1e-6)
    assert np.allclose(b.jumps, a.jumps, rtol=1e-5, atol=1e-6)


def test_long_horizon_is_time_scale_invariant():
    """Stretching time by λ (speeds / λ) leaves the path and scales J by λ⁻³, t* by λ."""
    base = random_problem(12, m=1)
    lam = 60.0
    e = base.ego
    ego = EgoBoundary(tf=e.tf * lam, x0=e.x0, y0=e.y0, vx0=e.vx0 / lam, xf=e.xf, yf=e.yf, vxf=e.vxf / lam,
                      vy0=e.vy0 / lam, vyf=e.vyf / lam)
    v = base.vehicles[0]
    veh = SurroundingVehicle(x_poly=tuple(c / lam**k for k, c in enumerate(v.x_poly)), corner=v.corner, y=v.y,
                             name="sv1", **DEFAULT_GEOMETRY)
    a, b = PMPPlanner().plan(base), PMPPlanner().plan(Problem(ego, (veh,), "slow"))
    assert b.status == OPTIMAL
    assert b.cost * lam**3 == pytest.approx(a.cost, rel=1e-9)
    assert b.contact_times[0] / lam == pytest.approx(a.contact_times[0], rel=1e-9)


def test_fixed_time_solution_is_unit_free():
    """The scaled solve returns physical a, b, Φ that satisfy the physical jump system."""
    problem = random_problem(13, m=2)
    sol = solve_fixed_times(problem, [1.3, 3.1])
    scale = max(1.0, float(np.max(np.abs(problem.ego.final))))
    assert sol.system_residual() <= 1e-10 * scale * problem.tf**3
