"""SPEC §2: the PMP planner's conditions and identities, on the paper's scenarios and on
seeded random ones it was never tuned for, against independent formulations."""

import numpy as np
import pytest
from scipy import interpolate, optimize

from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp.planner import PMPPlanner, ValueFunction, solve_fixed_times

PAPER = [paper_problem(k) for k in (1, 2, 3)]
RANDOM_1 = [random_problem(seed, m=1) for seed in range(8)]
RANDOM_2 = [random_problem(seed, m=2, side=(1 if seed % 2 else -1)) for seed in range(6)]
ONE_VEHICLE = PAPER + RANDOM_1 + [two_minima_problem()]
ALL = ONE_VEHICLE + RANDOM_2


def ids(problems):
    return [p.name for p in problems]


def spline_cost(problem: Problem, times) -> float:
    """Independent fixed-time optimum: per axis, the minimum of ½∫s''² through the
    interior points is the clamped cubic spline (scipy), integrated by Gauss-Legendre."""
    times = np.asarray(times, float)
    order = np.argsort(times)
    corners = problem.corners(times)[order]
    t = np.r_[0.0, times[order], problem.tf]
    ego = problem.ego
    total = 0.0
    for axis, (s0, v0, sf, vf) in enumerate([(ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf)]):
        y = np.r_[s0, corners[:, axis], sf]
        cs = interpolate.CubicSpline(t, y, bc_type=((1, v0), (1, vf)))
        xg, wg = np.polynomial.legendre.leggauss(4)
        for a, b in zip(t[:-1], t[1:]):
            tt = (b - a) / 2 * xg + (a + b) / 2
            total += 0.5 * (b - a) / 2 * np.sum(wg * cs(tt, 2) ** 2)
    return total


@pytest.mark.parametrize("problem", ALL, ids=ids(ALL))
def test_conditions_solved_at_optimum(problem):
    res = PMPPlanner().plan(problem)
    scale = max(1.0, abs(res.cost), float(np.max(np.abs(problem.ego.final))))
    for name in ("linear_system", "boundary", "interior_constraint", "h_minimisation", "costate_jump"):
        assert res.residuals[name] <= tol("pmp_condition_residual") * scale, (name, res.residuals)
    # the free-time condition: Hamiltonian jump residual vanishes at t*
    assert res.residuals["hamiltonian_jump"] <= tol("pmp_hjump_at_optimum") * max(1.0, res.cost)
    assert np.all((res.contact_times > 0) & (res.contact_times < problem.tf))
    # the cost is J of the trajectory: compare with quadrature of |u|^2
    t = np.linspace(0, problem.tf, 20001)
    u = res.trajectory.inputs(t)
    assert res.cost == pytest.approx(0.5 * np.trapezoid(np.sum(u**2, axis=1), t), rel=1e-6)


@pytest.mark.parametrize("problem", ALL, ids=ids(ALL))
def test_fixed_time_cost_matches_clamped_spline(problem):
    rng = np.random.default_rng(1)
    for _ in range(3):
        times = np.sort(rng.uniform(0.1, 0.9, problem.m)) * problem.tf
        sol = solve_fixed_times(problem, times)
        ref = spline_cost(problem, times)
        assert sol.cost() == pytest.approx(ref, rel=1e-9)
        assert float(ValueFunction(problem)(times[None, :])[0]) == pytest.approx(ref, rel=1e-9)


@pytest.mark.parametrize("problem", ALL, ids=ids(ALL))
def test_identity1_hamiltonian_jump_is_gradient(problem):
    """r_i = H⁻ − H⁺ − ẋ_s Φ_x equals ∂J/∂t_i (central differences away from the optimum)."""
    rng = np.random.default_rng(2)
    h = 1e-5 * problem.tf
    checked = 0
    while checked < 3:
        times = rng.uniform(0.15, 0.85, problem.m) * problem.tf
        if problem.m > 1 and abs(times[0] - times[1]) < 0.1 * problem.tf:
            continue
        r = solve_fixed_times(problem, times).hamiltonian_jump_residual()
        for i in range(problem.m):
            d = np.zeros(problem.m)
            d[i] = h
            fd = (solve_fixed_times(problem, times + d).cost() - solve_fixed_times(problem, times - d).cost()) / (2 * h)
            assert r[i] == pytest.approx(fd, rel=tol("fd_gradient_rel"), abs=1e-6 * max(1, abs(fd)))
        checked += 1


@pytest.mark.parametrize("problem", ALL, ids=ids(ALL))
def test_identity2_corner_sensitivity_is_minus_jump(problem):
    """∂J/∂corner_i = −Φ_i: move corner i by δ (t fixed) and compare the optimal cost."""
    res = PMPPlanner().plan(problem)
    t = res.contact_times
    delta = 1e-4
    for i, veh in enumerate(problem.vehicles):
        for axis in (0, 1):
            costs = []
            for sgn in (+1, -1):
                import dataclasses

                if axis == 0:
                    moved = dataclasses.replace(veh, x_poly=(veh.x_poly[0] + sgn * delta,) + veh.x_poly[1:])
                else:
                    moved = dataclasses.replace(veh, y=veh.y + sgn * delta)
                vs = list(problem.vehicles)
                vs[i] = moved
                costs.append(solve_fixed_times(problem.with_vehicles(vs), t).cost())
            dJ = (costs[0] - costs[1]) / (2 * delta)
            assert dJ == pytest.approx(-res.jumps[i, axis], rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("problem", ONE_VEHICLE, ids=ids(ONE_VEHICLE))
def test_identity3_global_optimum_one_vehicle(problem):
    res = PMPPlanner().plan(problem)
    grid = np.linspace(0, problem.tf, 20001)[1:-1]
    J = np.array([solve_fixed_times(problem, [t]).cost() for t in grid[::20]])
    assert res.cost <= J.min() + 1e-9 * res.cost
    Jd = ValueFunction(problem)(grid[:, None])
    assert res.cost <= Jd.min() + 1e-9 * res.cost
    # independent: bounded Brent on the clamped-spline cost around the best grid point
    k = int(np.argmin(Jd))
    ind = optimize.minimize_scalar(lambda t: spline_cost(problem, [t]),
                                   bounds=(grid[max(k - 5, 0)], grid[min(k + 5, len(grid) - 1)]),
                                   method="bounded", options={"xatol": 1e-10})
    assert res.cost == pytest.approx(ind.fun, rel=tol("independent_cost_rel"))
    assert res.contact_times[0] == pytest.approx(ind.x, abs=tol("independent_contact_time_abs"))


@pytest.mark.parametrize("problem", RANDOM_2, ids=ids(RANDOM_2))
def test_identity3_global_optimum_two_vehicles(problem):
    res = PMPPlanner().plan(problem)
    g = np.linspace(0, problem.tf, 302)[1:-1]
    A, B = np.meshgrid(g, g, indexing="ij")
    Z = ValueFunction(problem)(np.stack([A, B], axis=-1))
    assert res.cost <= Z.min() + 1e-9 * res.cost
    # independent local polish from the best dense-grid point with scipy (no PMP code)
    i, j = np.unravel_index(np.argmin(Z), Z.shape)
    ind = optimize.minimize(lambda t: spline_cost(problem, t) if abs(t[0] - t[1]) > 1e-6 else np.inf,
                            [g[i], g[j]], method="Nelder-Mead",
                            options={"xatol": 1e-10, "fatol": 1e-13, "maxiter": 4000})
    assert res.cost == pytest.approx(ind.fun, rel=tol("independent_cost_rel"))
    assert np.allclose(res.contact_times, ind.x, atol=tol("independent_contact_time_abs"))


def test_two_minima_global_is_not_the_middle_one():
    problem = two_minima_problem()
    J = ValueFunction(problem)
    grid = np.linspace(0, problem.tf, 60001)[1:-1]
    Z = J(grid[:, None])
    interior = (Z[1:-1] < Z[:-2]) & (Z[1:-1] < Z[2:])
    minima = grid[1:-1][interior]
    assert len(minima) == 2, minima
    res = PMPPlanner().plan(problem)
    nearest_middle = minima[np.argmin(np.abs(minima - problem.tf / 2))]
    assert abs(res.contact_times[0] - nearest_middle) > 0.5
    assert res.contact_times[0] == pytest.approx(grid[np.argmin(Z)], abs=1e-3)
    # and the other local minimum is a genuine stationary point with a larger cost
    other = minima[minima != minima[np.argmin(np.abs(minima - res.contact_times[0]))]][0]
    assert J(np.array([[other]]))[0] > res.cost * 1.05


@pytest.mark.parametrize("problem", ALL, ids=ids(ALL))
def test_jumps_equal_closed_form(problem):
    """Φ from the jump conditions equals −K⁻¹e from the bridge form (two formulations)."""
    res = PMPPlanner().plan(problem)
    from iamp.planners.pmp.planner import bridge_kernel

    t = res.contact_times
    K = bridge_kernel(t[:, None], t[None, :], problem.tf)
    ex, ey = ValueFunction(problem).errors(t[None, :])
    phi = -np.linalg.solve(K, np.stack([ex[0], ey[0]], axis=1))
    assert np.allclose(res.jumps, phi, rtol=1e-8, atol=1e-8)


def test_three_vehicles_still_work():
    base = random_problem(3, m=2, side=1)
    import dataclasses

    v2 = base.vehicles[1]
    third = dataclasses.replace(v2, x_poly=(v2.x_poly[0] + 40,) + v2.x_poly[1:], name="sv3")
    problem = base.with_vehicles(base.vehicles + (third,))
    res = PMPPlanner().plan(problem)
    assert res.residuals["hamiltonian_jump"] <= tol("pmp_hjump_at_optimum") * max(1, res.cost)
    rng = np.random.default_rng(0)
    samples = rng.uniform(0.01, 0.99, size=(20000, 3)) * problem.tf
    assert res.cost <= np.min(ValueFunction(problem)(samples)) + 1e-9 * res.cost


def test_costates_follow_their_equations():
    problem = random_problem(5, m=2, side=-1)
    sol = PMPPlanner().solve(problem)
    t = np.linspace(0.01, problem.tf - 0.01, 997)
    t = t[np.all(np.abs(t[:, None] - sol.contact_times[None, :]) > 1e-3, axis=1)]
    h = 1e-6
    p = sol.costates(t)
    dp = (sol.costates(t + h) - sol.costates(t - h)) / (2 * h)
    assert np.allclose(dp[:, 0], 0, atol=1e-6) and np.allclose(dp[:, 2], 0, atol=1e-6)
    assert np.allclose(dp[:, 1], -p[:, 0], atol=1e-5) and np.allclose(dp[:, 3], -p[:, 2], atol=1e-5)
    X = sol.states(t)
    dX = (sol.states(t + h) - sol.states(t - h)) / (2 * h)
    U = sol.inputs(t)
    assert np.allclose(dX[:, 0], X[:, 1], atol=1e-5) and np.allclose(dX[:, 1], U[:, 0], atol=1e-5)
    assert np.allclose(dX[:, 2], X[:, 3], atol=1e-5) and np.allclose(dX[:, 3], U[:, 1], atol=1e-5)


def test_batch_plan_equals_planner():
    from iamp.planners.pmp.planner import plan_batch

    problems = ONE_VEHICLE + [random_problem(100 + s, m=1) for s in range(40)]
    batch = plan_batch(problems)
    for k, p in enumerate(problems):
        ref = PMPPlanner().plan(p, diagnostics=False)
        assert batch.status[k] == "optimal"
        assert batch.cost[k] == pytest.approx(ref.cost, rel=1e-10)
        assert batch.contact_time[k] == pytest.approx(ref.contact_times[0], abs=1e-9)
        assert np.allclose(batch.jumps[k], ref.jumps[0], rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("problem", RANDOM_2 + PAPER, ids=ids(RANDOM_2 + PAPER))
def test_closed_form_gradient_equals_hamiltonian_jump_residual(problem):
    rng = np.random.default_rng(7)
    J = ValueFunction(problem)
    for _ in range(3):
        t = rng.uniform(0.1, 0.9, problem.m) * problem.tf
        r = solve_fixed_times(problem, t).hamiltonian_jump_residual()
        assert np.allclose(J.gradient(t[None, :])[0], r, rtol=1e-8, atol=1e-8 * max(1, np.max(np.abs(r))))
