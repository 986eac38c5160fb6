"""The bounded PMP (SPEC §14) against an independent bounded FOH QP written here in cvxpy.

The QP (SPEC §3's FOH, exact double-integrator discretisation) restricts ``u`` to piecewise
linear functions on the grid and imposes the box at the nodes, which for FOH is the box
everywhere: it is a *restriction* of the continuous bounded problem, so at the same contact
times (grid nodes) ``J_PMP_bounded <= J_QP_bounded(N)`` (up to solver tolerance), and the gap
closes as N grows (the saturated law kinks at switching times that are not nodes).
"""

from __future__ import annotations

import math
import os

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from iamp.api import load_scenario
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.status import INFEASIBLE, LIMITS_VIOLATED, LOCAL, OPTIMAL
from iamp.core.tolerances import TOLERANCES
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import (
    boundary_feasible,
    certify_global_one,
    check_values,
    exact_peaks,
    interval_bound,
    judge,
    solve_bounded_fixed,
)
from iamp.planners.pmp.saturated import AxisInfeasible, AxisNoConvergence

EXAMPLES = {"ci": 15, "dev": 200, "long": 2000}.get(os.environ.get("HYPOTHESIS_PROFILE", "ci"), 15)
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=os.environ.get("HYPOTHESIS_PROFILE") is None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
BOX = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay)


# ------------------------------------------------------------------------------------------
# the independent reference: bounded FOH QP in cvxpy (Clarabel)
# ------------------------------------------------------------------------------------------
def bounded_foh_qp(problem: Problem, nodes: list[int], steps: int) -> tuple[str, float | None]:
    """``(status, cost)`` of the FOH QP with corners at grid nodes ``nodes`` and the box of
    ``problem.limits`` (ax, ay) on every nodal input."""
    ego, T = problem.ego, problem.tf
    h = T / steps
    t_nodes = np.array(nodes) * h
    C = problem.corners(t_nodes)
    cost = 0
    cons = []
    lim = problem.limits
    for k, (s0, v0, sf, vf, box) in enumerate(((ego.x0, ego.vx0, ego.xf, ego.vxf, lim.ax if lim else None),
                                                (ego.y0, ego.vy0, ego.yf, ego.vyf, lim.ay if lim else None))):
        s = cp.Variable(steps + 1)
        v = cp.Variable(steps + 1)
        u = cp.Variable(steps + 1)
        cons += [s[0] == s0, v[0] == v0, s[steps] == sf, v[steps] == vf,
                 s[1:] == s[:-1] + h * v[:-1] + h * h * (u[:-1] / 3 + u[1:] / 6),
                 v[1:] == v[:-1] + h / 2 * (u[:-1] + u[1:])]
        cons += [s[n] == C[i, k] for i, n in enumerate(nodes)]
        if box is not None:
            cons += [u >= box[0], u <= box[1]]
        # (h/6)(a² + ab + b²) = (h/12)((a + b)² + a² + b²), written DCP
        cost = cost + h / 12 * (cp.sum_squares(u[:-1] + u[1:]) + cp.sum_squares(u[:-1]) + cp.sum_squares(u[1:]))
    prob = cp.Problem(cp.Minimize(cost), cons)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-11, tol_gap_rel=1e-11, tol_feas=1e-11)
    return prob.status, (float(prob.value) if prob.status == cp.OPTIMAL else None)


def one_vehicle_problem(tf: float, vx0: float, dx: float, dvx: float, y0: float, dy: float, c0: float,
                        c1: float, sx: float, box: PhysicalLimits | None) -> Problem:
    ego = EgoBoundary(tf=tf, x0=0.0, y0=y0, vx0=vx0, xf=vx0 * tf + dx, yf=y0 + dy, vxf=vx0 + dvx)
    veh = SurroundingVehicle(x_poly=(c0, vx0 + c1), corner="front-lower", y=y0 + dy, length=4.8, width=1.8,
                             safety_x=sx, safety_y=0.5)
    return Problem(ego, (veh,), "gen", box)


def box_from_unbounded(problem: Problem, t: float, factors: tuple[float, float, float, float]) -> PhysicalLimits:
    """A box that cuts the unbounded fixed-time optimum's peaks at ``t`` by ``factors`` (so it
    is active and, for factors near 1, feasible); always contains 0."""
    sol = solve_bounded_fixed(problem.with_limits(None), [t])
    U = sol.inputs(np.asarray(sol.knots()))
    lims = []
    for k in range(2):
        lo, hi = float(U[:, k].min()), float(U[:, k].max())
        lims.append((min(-0.05, lo * factors[2 * k]), max(0.05, hi * factors[2 * k + 1])))
    return PhysicalLimits(ax=lims[0], ay=lims[1])


@st.composite
def bounded_problems(draw: st.DrawFn) -> Problem:
    """A one-vehicle lane change whose box cuts the unbounded fixed-time optimum at the
    drawn grid node ``node`` of a 60-interval grid (``problem.name`` carries the node)."""
    f = st.floats
    node = draw(st.integers(8, 52))
    base = one_vehicle_problem(draw(f(3.0, 7.0)), draw(f(10.0, 30.0)), draw(f(-20.0, 15.0)), draw(f(-3.0, 3.0)),
                               draw(f(-3.0, 0.0)), draw(f(3.0, 4.0)), draw(f(-35.0, -5.0)), draw(f(-6.0, 3.0)),
                               draw(f(0.0, 5.0)), None)
    factors = tuple(draw(f(0.7, 1.3)) for _ in range(4))
    box = box_from_unbounded(base, node * base.tf / 60, factors)  # type: ignore[arg-type]
    return Problem(base.ego, base.vehicles, f"node-{node}", box)


# ------------------------------------------------------------------------------------------
# fixed contact times: PMP <= QP (restriction), checks, bounds, dJ/dt
# ------------------------------------------------------------------------------------------
@SETTINGS
@given(bounded_problems())
def test_bounded_pmp_below_bounded_qp_at_grid_contact_times(problem: Problem) -> None:
    steps = 60
    node = int(problem.name.split("-")[1])
    t = node * problem.tf / steps
    qp_status, qp_cost = bounded_foh_qp(problem, [node], steps)
    try:
        sol = solve_bounded_fixed(problem, [t])
    except AxisInfeasible:
        # the continuous problem is infeasible -> its restriction, the QP, too
        assert qp_status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE), qp_status
        return
    except AxisNoConvergence:  # the feasible set is one point (never drawn in practice)
        assume(False)
        return
    checks, failed, _ = judge(check_values(sol, stationary=False))
    assert failed is None, checks
    lim = problem.limits
    assert lim is not None and lim.ax is not None and lim.ay is not None
    U = sol.inputs(np.asarray(sol.knots()))
    assert np.all(U[:, 0] >= lim.ax[0] - 1e-12) and np.all(U[:, 0] <= lim.ax[1] + 1e-12)
    assert np.all(U[:, 1] >= lim.ay[0] - 1e-12) and np.all(U[:, 1] <= lim.ay[1] + 1e-12)
    # a dense evaluation never exceeds the exact peaks (u is linear between knots)
    dense = sol.inputs(np.linspace(0, problem.tf, 2001))
    assert np.all(dense[:, 0] >= lim.ax[0] - 1e-12) and np.all(dense[:, 0] <= lim.ax[1] + 1e-12)
    if qp_cost is not None:
        assert sol.cost <= qp_cost + 1e-7 * max(1.0, qp_cost), (sol.cost, qp_cost)
        # ... and close to it: the FOH restriction only misses the kinks at switching times
        assert qp_cost - sol.cost <= 0.05 * sol.cost + 1e-9, (sol.cost, qp_cost)


@SETTINGS
@given(bounded_problems(), st.floats(-0.05, 0.05))
def test_hamiltonian_jump_is_dJ_dt_with_saturation(problem: Problem, shift: float) -> None:
    """SPEC §2 identity 1 with the saturated law: r = H⁻ − H⁺ − ẋ_sΦ_x = ∂J/∂t (central FD)."""
    t = (int(problem.name.split("-")[1]) / 60 + shift) * problem.tf
    d = 1e-5 * problem.tf
    try:
        sol = solve_bounded_fixed(problem, [t])
        c = {k: (solve_bounded_fixed(problem, [t + k * d]).cost - solve_bounded_fixed(problem, [t - k * d]).cost)
             / (2 * k * d) for k in (1.0, 0.5)}
    except (AxisInfeasible, AxisNoConvergence):
        assume(False)
        return
    # Richardson: the central difference's d² term cancels (J_b is smooth between structure
    # changes, but its third derivative can be large where two switching times nearly meet:
    # tf = 3, t = 1.929 between switching times 1.916 and 1.935 gave a 1.3e-5 error at d alone)
    fd = (4 * c[0.5] - c[1.0]) / 3
    r = float(sol.hamiltonian_jump_residual()[0])
    scale = max(1.0, abs(r), sol.cost / problem.tf)
    assert abs(fd - r) <= 1e-5 * scale, (fd, r)


def test_switching_times_are_where_minus_pv_crosses_the_bound() -> None:
    problem = load_scenario("paper-1").with_limits(BOX)
    sol = solve_bounded_fixed(problem, [3.35])
    sw = sol.axes[0].switching
    assert len(sw) >= 2  # the unbounded plan brakes beyond -6 and accelerates beyond 3
    for theta, value, side, _ in sw:
        w = float(sol.w(0, np.array([theta]))[0])
        assert abs(w - value) <= 1e-10 * max(1.0, abs(value))
        assert value == (3.0 if side == "upper" else -6.0)
    # strictly inside the saturated intervals u equals the bound; elsewhere u = -p_v
    ts = np.linspace(0, problem.tf, 4001)
    U, P = sol.inputs(ts), sol.costates(ts)
    assert np.allclose(U[:, 0], np.clip(-P[:, 1], -6.0, 3.0), atol=1e-10, rtol=0)
    assert np.allclose(U[:, 1], np.clip(-P[:, 3], -2.0, 2.0), atol=1e-10, rtol=0)


def test_corner_sensitivity_is_minus_the_jump() -> None:
    """SPEC §2 identity 2 for the bounded problem: ∂J/∂corner_y = −Φ_y (corner_y moved by δ)."""
    problem = load_scenario("paper-1").with_limits(BOX)
    sol = solve_bounded_fixed(problem, [3.35])
    veh = problem.vehicles[0]
    d = 1e-4
    moved = [Problem(problem.ego, (SurroundingVehicle(veh.x_poly, veh.corner, veh.y + s, veh.length, veh.width,
                                                      veh.safety_x, veh.safety_y),), "m", problem.limits)
             for s in (d, -d)]
    fd = (solve_bounded_fixed(moved[0], [3.35]).cost - solve_bounded_fixed(moved[1], [3.35]).cost) / (2 * d)
    assert abs(fd + sol.jumps[0, 1]) <= 1e-6 * max(1.0, abs(fd))


# ------------------------------------------------------------------------------------------
# convergence of the bounded QP to the bounded PMP as N grows
# ------------------------------------------------------------------------------------------
def test_bounded_qp_cost_gap_shrinks_with_N() -> None:
    problem = load_scenario("paper-1").with_limits(BOX)
    t = 3.35  # a node of every grid below
    j_pmp = solve_bounded_fixed(problem, [t]).cost
    gaps = []
    for steps in (100, 200, 400):
        status, j_qp = bounded_foh_qp(problem, [round(t / problem.tf * steps)], steps)
        assert status == cp.OPTIMAL and j_qp is not None
        gaps.append((j_qp - j_pmp) / j_pmp)
    assert all(g >= -1e-9 for g in gaps), gaps
    assert gaps[0] > gaps[1] > gaps[2], gaps
    assert gaps[2] < 1e-4, gaps


# ------------------------------------------------------------------------------------------
# the planner: dispatch, statuses, free contact times
# ------------------------------------------------------------------------------------------
def test_no_limits_and_inactive_box_give_the_unbounded_plan_exactly() -> None:
    planner = PMPPlanner()
    for name in ("paper-1", "two-vehicle"):
        base = load_scenario(name)
        ref = planner.plan(base)
        wide = planner.plan(base.with_limits(PhysicalLimits(ax=(-100.0, 100.0), ay=(-100.0, 100.0))))
        assert ref.status == wide.status == OPTIMAL
        assert ref.cost == wide.cost
        assert np.array_equal(ref.contact_times, wide.contact_times)
        assert np.array_equal(ref.jumps, wide.jumps)
        ts = np.linspace(0, base.tf, 301)
        assert np.array_equal(ref.states(ts), wide.states(ts))
        assert wide.info["bounded"]["box_active"] is False
        j_ref, j_wide = ref.to_json(), wide.to_json()
        j_ref.pop("solve_time_s"), j_wide.pop("solve_time_s")
        # the peaks report (JSON "limits", where the plan output has one) lists the given bounds
        # too, so it differs by them; every given bound holds
        lim_ref, lim_wide = j_ref.pop("limits", {}), j_wide.pop("limits", {})
        assert all(r.get("ok") in (True, None) for r in lim_wide.values())
        assert {k: v["peak"] for k, v in lim_ref.items()} == {k: v["peak"] for k, v in lim_wide.items()
                                                           if k in lim_ref}
        assert j_ref == j_wide


def test_free_contact_time_is_stationary_and_below_every_grid_time() -> None:
    problem = load_scenario("paper-1").with_limits(BOX)
    plan = PMPPlanner().plan(problem)
    # box active: the interval certificate over (0, t_f) closes, so the plan is global
    assert plan.status == OPTIMAL, plan.info.get("reason")
    assert plan.info["certified_global"] and plan.info["global_certificate"]["certified"]
    t_star = float(plan.contact_times[0])
    assert plan.info["checks"]["hamiltonian_jump"]["ok"]
    for t in np.linspace(0.05, 0.95, 181) * problem.tf:
        try:
            j = solve_bounded_fixed(problem, [t]).cost
        except AxisInfeasible:
            continue
        assert plan.cost <= j + 1e-9 * j, (t, j, t_star)
    # the bounded optimum costs more than the unbounded one
    assert plan.cost > PMPPlanner().plan(load_scenario("paper-1")).cost


def test_state_bounds_it_cannot_impose_are_checked_with_exact_peaks() -> None:
    problem = load_scenario("paper-1").with_limits(PASSENGER_CAR)
    plan = PMPPlanner().plan(problem)
    assert plan.status == LIMITS_VIOLATED  # the saturated law's jerk exceeds 5 m/s³
    rep = plan.info["limits"]
    assert rep["ax"]["ok"] and rep["ay"]["ok"] and not rep["jerk"]["ok"]
    sol = plan.trajectory
    dense_t = np.linspace(0, problem.tf, 200001)
    U, X = sol.inputs(dense_t), sol.states(dense_t)
    peaks = exact_peaks(sol, problem.tf, sol.knots())
    # every exact peak bounds and (to the sampling's resolution) equals the dense evaluation
    assert peaks["vx"][0] <= X[:, 1].min() + 1e-12 and peaks["vx"][1] >= X[:, 1].max() - 1e-12
    assert abs(peaks["vx"][0] - X[:, 1].min()) < 1e-6 and abs(peaks["vx"][1] - X[:, 1].max()) < 1e-6
    assert abs(peaks["y"][1] - X[:, 2].max()) < 1e-6 and abs(peaks["a_total"] - np.hypot(U[:, 0], U[:, 1]).max()) < 1e-4
    jerk = np.max(np.abs(np.diff(U, axis=0)) / np.diff(dense_t)[:, None])
    assert abs(peaks["jerk"] - jerk) < 1e-3 * peaks["jerk"]
    # without the jerk bound the same plan is fine (box imposed, vx and a_total hold)
    no_jerk = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0), a_total=8.0, vx=(0.0, 40.0))
    ok = PMPPlanner().plan(problem.with_limits(no_jerk))
    assert ok.status == OPTIMAL and "optimal for the bounded problem" in ok.info["limits_note"]


def _reach_interval(s0: float, v0: float, vf: float, T: float, lo: float, hi: float) -> tuple[float, float] | None:
    """Independent reachable range of s(T) given v(T) = vf with u in [lo, hi] (bang-bang)."""
    dv = vf - v0
    if not lo * T <= dv <= hi * T:
        return None
    out = []
    for first, second in ((lo, hi), (hi, lo)):  # lowest s(T): brake first; highest: accelerate first
        tau = (dv - second * T) / (first - second) if first != second else T
        # u = first on [0, tau], second on [tau, T]: s(T) = s0 + v0 T + ∫(T-t)u dt
        s = s0 + v0 * T + first * (T * tau - tau**2 / 2) + second * (T - tau) ** 2 / 2
        out.append(s)
    return min(out), max(out)


@SETTINGS
@given(st.floats(2.0, 8.0), st.floats(5.0, 30.0), st.floats(-60.0, 60.0), st.floats(-15.0, 15.0),
       st.floats(1.0, 8.0), st.floats(0.5, 5.0))
def test_boundary_infeasibility_matches_the_bang_bang_reachable_set(tf: float, vx0: float, dx: float, dvx: float,
                                                                    brake: float, acc: float) -> None:
    box = PhysicalLimits(ax=(-brake, acc))
    problem = one_vehicle_problem(tf, vx0, dx, dvx, -2.0, 3.75, -20.0, 0.0, 5.0, box)
    rng = _reach_interval(0.0, vx0, vx0 + dvx, tf, -brake, acc)
    xf = problem.ego.xf
    reason = boundary_feasible(problem)
    if rng is None or not rng[0] - 1e-6 <= xf <= rng[1] + 1e-6:
        if rng is None or xf < rng[0] - 1e-3 or xf > rng[1] + 1e-3:
            assert reason is not None and "x boundary" in reason
    elif rng[0] + 1e-3 < xf < rng[1] - 1e-3:
        assert reason is None


def test_infeasible_box_is_reported_with_the_reason() -> None:
    plan = PMPPlanner().plan(load_scenario("paper-2").with_limits(PASSENGER_CAR))
    assert plan.status == INFEASIBLE and plan.cost is None
    assert "x boundary conditions are out of reach" in plan.info["reason"]
    assert plan.to_json()["reason"] == plan.info["reason"]
    ego = load_scenario("paper-2").ego
    rng = _reach_interval(ego.x0, ego.vx0, ego.vxf, ego.tf, -6.0, 3.0)
    assert rng is None or not rng[0] <= ego.xf <= rng[1]


def test_fixed_contact_times_are_the_unique_fixed_time_optimum() -> None:
    problem = load_scenario("paper-1").with_limits(BOX)
    plan = PMPPlanner().plan(problem, contact_times=[3.35])
    assert plan.status == OPTIMAL
    assert math.isclose(plan.cost, solve_bounded_fixed(problem, [3.35]).cost, rel_tol=1e-14)
    assert "hamiltonian_jump" not in plan.info["checks"]
    assert TOLERANCES["pmp_bounded_residual"] >= max(v["value"] for v in plan.info["checks"].values())


def test_casadi_bounded_peer_approaches_the_bounded_pmp() -> None:
    """The CasADi + IPOPT peer of ``iamp bench`` (ZOH, box on every u_k: a restriction) costs
    at least the bounded PMP's J*, and approaches it as N grows, at a nearby contact time."""
    pytest.importorskip("casadi")
    from iamp.comparison.bench.casadi import casadi_free_time
    from iamp.planners.examples import paper_problem

    problem = paper_problem(1).with_limits(BOX)
    plan = PMPPlanner().plan(problem)
    assert plan.ok
    gaps = []
    for steps in (40, 160):
        res = casadi_free_time(problem, steps=steps, repeats=1, box=True)
        assert res["return_status"] == "Solve_Succeeded"
        assert res["cost"] >= plan.cost * (1 - 1e-9)
        gaps.append(res["cost"] - plan.cost)
        assert abs(res["contact_time"] - plan.contact_times[0]) < 0.05
    assert gaps[1] < gaps[0]


def _margin_dense(problem: Problem, axis: int, t: float, lam: list[float], n: int = 200001) -> float:
    """``λᵀd(t) − ∫ max(h w, ℓ w)`` by dense trapezoids (physical units), independent of the
    exact piecewise integral in the planner."""
    ego, T = problem.ego, problem.tf
    s0, v0, sf, vf = ((ego.x0, ego.vx0, ego.xf, ego.vxf) if axis == 0 else (ego.y0, ego.vy0, ego.yf, ego.vyf))
    lo, hi = (problem.limits.ax if axis == 0 else problem.limits.ay)  # type: ignore[union-attr]
    c = float(problem.corners(np.array([t]))[0, axis])
    d = np.array([c - s0 - v0 * t, sf - s0 - v0 * T, vf - v0])
    tau = np.linspace(0, T, n)
    w = lam[0] * np.maximum(t - tau, 0) + lam[1] * (T - tau) + lam[2]
    f = np.maximum(hi * w, lo * w)
    return float(lam @ d - np.sum((f[1:] + f[:-1]) / 2 * np.diff(tau)))


def test_farkas_certificates_are_real_and_lipschitz_in_the_contact_time() -> None:
    """paper-3 under the passenger car's box: the planner certifies infeasibility for every
    contact time; each certificate's margin, recomputed by dense quadrature, is positive, and
    the Lipschitz rate the certification uses bounds the margin's change in t."""
    from iamp.planners.pmp.bounded import certify_infeasible
    from iamp.planners.pmp.saturated import solve_axis

    problem = load_scenario("paper-3").with_limits(BOX)
    plan = PMPPlanner().plan(problem)
    assert plan.status == INFEASIBLE and "certified" in plan.info["reason"]
    certified, feasible_t, intervals = certify_infeasible(problem)
    assert certified and feasible_t is None and intervals >= 32
    ego, T = problem.ego, problem.tf
    veh = problem.vehicles[0]
    cdot = max(abs(float(veh.speed(x))) for x in np.linspace(0, T, 2001))
    for t in np.linspace(0.02, 0.98, 25) * T:
        C = problem.corners(np.array([t]))
        infeasible_axes = 0
        for k, (s0, v0, sf, vf, (lo, hi)) in enumerate(((ego.x0, ego.vx0, ego.xf, ego.vxf, BOX.ax),
                                                         (ego.y0, ego.vy0, ego.yf, ego.vyf, BOX.ay))):
            try:
                solve_axis([t], T, s0, v0, sf, vf, [float(C[0, k])], lo, hi)
                continue
            except AxisInfeasible as exc:
                infeasible_axes += 1
                lam = exc.lam_phys
                assert lam is not None and exc.margin_phys is not None
                dense = _margin_dense(problem, k, t, lam)
                assert dense > 0 and abs(dense - exc.margin_phys) <= 1e-6 * max(1.0, abs(dense))
                rate = abs(lam[0]) * ((cdot if k == 0 else 0.0) + abs(v0) + max(abs(lo), abs(hi)) * T)
                for dt in (1e-3, 1e-2, 5e-2):
                    for t2 in (t - dt, t + dt):
                        if 0 < t2 < T:
                            assert abs(_margin_dense(problem, k, t2, lam) - dense) <= rate * dt * (1 + 1e-6) + 1e-9
        assert infeasible_axes >= 1


@SETTINGS
@given(bounded_problems())
def test_bounded_plan_is_exact_pieces_for_the_safety_report(problem: Problem) -> None:
    """The pieces the safety report and the peaks use (:mod:`iamp.core.trajectory_pieces`)
    end at the bounded plan's knots (contact and switching times): each piece's cubic
    reproduces the states at its end, and the report is ``exact`` (not the 1 ms fallback)."""
    from iamp.core.safety import safety_report
    from iamp.core.trajectory_pieces import breakpoints, taylor_pieces

    plan = PMPPlanner().plan(problem)
    assume(plan.trajectory is not None and plan.info.get("bounded", {}).get("box_active", True))
    sol = plan.trajectory
    br = breakpoints(sol, problem.tf)
    assert br is not None
    kn = np.asarray(sol.knots())
    # every knot is a piece end, up to the merge of knots closer than MERGE_S
    assert np.all(np.min(np.abs(kn[:, None] - br[None, :]), axis=1) < 1e-6)
    _, mismatch = taylor_pieces(sol, br)
    assert mismatch < 1e-9
    assert safety_report(problem, sol).exact


@pytest.mark.parametrize("factor", [0.95, 0.8, 0.7])
def test_two_vehicles_bounded_is_stationary_below_a_dense_grid_and_the_bounded_qp(factor: float) -> None:
    """Two vehicles, a box cutting the unbounded plan's peaks by ``factor``: the bounded PMP
    is ``local`` (no certificate between grid points), passes every check (the Hamiltonian
    jump of both vehicles included), costs at most the fixed-time bounded optimum on a dense
    21×21 grid of contact times, at least the unbounded optimum, and at most the independent
    bounded FOH QP (N = 200) at the grid nodes nearest its contact times, within 1e-3."""
    base = load_scenario("two-vehicle")
    ref = PMPPlanner().plan(base)
    U = ref.inputs(np.linspace(0, base.tf, 4001))
    box = PhysicalLimits(ax=(U[:, 0].min() * factor, U[:, 0].max() * factor),
                         ay=(min(-0.05, U[:, 1].min() * factor), max(0.05, U[:, 1].max() * factor)))
    problem = base.with_limits(box)
    plan = PMPPlanner().plan(problem)
    assert plan.status == LOCAL, (plan.info.get("failed_check"), plan.info.get("reason"))
    assert all(c["ok"] for c in plan.info["checks"].values())
    assert plan.cost >= ref.cost - 1e-9 * ref.cost
    dense = np.inf
    for a in np.linspace(0.05, 0.95, 21) * base.tf:
        for b in np.linspace(0.05, 0.95, 21) * base.tf:
            try:
                dense = min(dense, solve_bounded_fixed(problem, [a, b]).cost)
            except (AxisInfeasible, AxisNoConvergence):
                continue
    assert plan.cost <= dense * (1 + 1e-9)
    # the QP at the grid nodes around the contact times (a tight box leaves a narrow set of
    # feasible contact times, so some of the four neighbours may be infeasible): a restriction
    qp_costs = []
    for steps in (200, 400):
        lo = [math.floor(float(t) / base.tf * steps) for t in plan.contact_times]
        for da in (0, 1):
            for db in (0, 1):
                status, j_qp = bounded_foh_qp(problem, [lo[0] + da, lo[1] + db], steps)
                if status == cp.OPTIMAL and j_qp is not None:
                    qp_costs.append(j_qp)
    assert qp_costs, "no neighbouring grid node admits the box"
    assert plan.cost <= min(qp_costs) * (1 + 1e-7)
    assert (min(qp_costs) - plan.cost) / plan.cost < 1e-3, (min(qp_costs), plan.cost)


@SETTINGS
@given(bounded_problems())
def test_global_certificate_is_sound_over_generated_boxes(problem: Problem) -> None:
    """One vehicle, free contact time: a plan called ``optimal`` (certified global) costs at
    most the fixed-time bounded optimum at each of 241 contact times (to 1e-9), and the
    certificate refuses a value 1e-4 above the minimum (it cannot certify what is false);
    without the certificate the same plan is ``local``."""
    plan = PMPPlanner().plan(problem)
    assume(plan.info.get("bounded", {}).get("box_active") and plan.status in (OPTIMAL, LOCAL))
    assert plan.cost is not None
    if plan.status == OPTIMAL:
        assert plan.info["global_certificate"]["certified"]
        for t in np.linspace(0.02, 0.98, 241) * problem.tf:
            try:
                j = solve_bounded_fixed(problem, [t]).cost
            except (AxisInfeasible, AxisNoConvergence):
                continue
            assert plan.cost <= j * (1 + 1e-9), (t, j, plan.cost)
    assert not certify_global_one(problem, plan.cost * (1 + 1e-4))["certified"]
    quick = PMPPlanner(certify_bounded=False).plan(problem)
    assert quick.status == LOCAL and quick.cost == plan.cost


def test_two_vehicles_infeasibility_is_certified_and_true_on_random_contact_times() -> None:
    """two-vehicle under the passenger car's box: certified infeasible over (0, t_f)²; at 300
    random pairs of contact times an axis' fixed-time problem is indeed infeasible (its Farkas
    margin is positive); with a box cut 0.8 from the unbounded peaks the same search finds a
    feasible pair instead (and the plan is verified)."""
    from iamp.planners.pmp.bounded import certify_infeasible

    problem = load_scenario("two-vehicle").with_limits(BOX)
    plan = PMPPlanner().plan(problem)
    assert plan.status == INFEASIBLE and "certified" in plan.info["reason"] and "(0, t_f)^2" in plan.info["reason"]
    rng = np.random.default_rng(0)
    for t in rng.uniform(0.01, 0.99, size=(300, 2)) * problem.tf:
        with pytest.raises(AxisInfeasible) as exc:
            solve_bounded_fixed(problem, t)
        assert exc.value.margin > 0
    ref = PMPPlanner().plan(load_scenario("two-vehicle"))
    U = ref.inputs(np.linspace(0, problem.tf, 4001))
    box = PhysicalLimits(ax=(U[:, 0].min() * 0.8, U[:, 0].max() * 0.8), ay=(U[:, 1].min() * 0.8, U[:, 1].max() * 0.8))
    certified, feasible_t, _ = certify_infeasible(problem.with_limits(box))
    assert not certified and feasible_t is not None
    assert solve_bounded_fixed(problem.with_limits(box), feasible_t).cost > 0


def test_zero_vehicles_bounded_is_the_fixed_time_optimum_and_matches_the_qp() -> None:
    """No vehicle, an active box: the bounded free problem (no contact time, strictly convex)
    is ``optimal``, its inputs stay in the box, it costs more than the free cubic, and the
    independent bounded FOH QP (a restriction) costs at least as much and agrees to 1e-6."""
    base = load_scenario("paper-1").with_vehicles(())
    problem = base.with_limits(BOX)
    plan = PMPPlanner().plan(problem)
    free = PMPPlanner().plan(base)
    assert plan.status == OPTIMAL and plan.info["bounded"]["box_active"]
    U = plan.inputs(np.linspace(0, problem.tf, 2001))
    assert U[:, 0].min() >= BOX.ax[0] - 1e-12 and U[:, 0].max() <= BOX.ax[1] + 1e-12
    assert free.cost is not None and plan.cost is not None and plan.cost > free.cost
    gaps = []
    for steps in (50, 100, 200):
        status, j_qp = bounded_foh_qp(problem, [], steps)
        assert status == cp.OPTIMAL and j_qp is not None
        gaps.append((j_qp - plan.cost) / plan.cost)
    # (here the switching time falls where FOH can follow it: the QP matches to solver accuracy)
    assert all(-1e-9 <= g < 1e-6 for g in gaps), gaps


def test_bounded_pmp_through_the_registry_and_import_iamp() -> None:
    """``import iamp``: ``iamp.plan`` on a problem with ``limits`` reaches the bounded PMP
    through the registry's ``pmp`` entry (certified ``optimal`` on paper-1 with the passenger
    car's box, inputs in the box); ``certify_bounded=False`` is an API option (``local``, the
    same plan); a bad value is an :class:`iamp.OptionError` naming the field."""
    import iamp
    from iamp.core.errors import OptionError

    problem = iamp.load_scenario("paper-1").with_limits(BOX)
    plan = iamp.plan(problem)
    assert plan.status == OPTIMAL and plan.info["bounded"]["box_active"] and plan.info["certified_global"]
    U = plan.inputs(np.linspace(0, problem.tf, 2001))
    assert U[:, 0].max() <= BOX.ax[1] + 1e-12 and U[:, 0].min() >= BOX.ax[0] - 1e-12
    quick = iamp.plan(problem, "pmp", certify_bounded=False)
    assert quick.status == LOCAL and quick.cost == plan.cost
    with pytest.raises(OptionError) as err:
        iamp.plan(problem, "pmp", certify_bounded="yes")
    assert "certify_bounded" in str(err.value) or getattr(err.value, "field", "") == "certify_bounded"


@SETTINGS
@given(bounded_problems(), st.floats(-1.5, 1.5), st.floats(-1.5, 1.5), st.floats(-4.0, 4.0))
def test_exact_peaks_equal_a_dense_evaluation(problem: Problem, vy0: float, vyf: float, vx_shift: float) -> None:
    """Every exact peak (inputs at the knots, v_x where u_x = 0, s_y where v_y = 0, |u|, jerk)
    equals the extreme of a dense evaluation of the same plan (200001 points) and bounds it;
    lateral end speeds make s_y overshoot inside a piece, so the interior roots matter."""
    import dataclasses

    ego = dataclasses.replace(problem.ego, vy0=vy0, vyf=vyf, vxf=problem.ego.vxf + vx_shift)
    prob = Problem(ego, problem.vehicles, problem.name, problem.limits)
    plan = PMPPlanner(certify_bounded=False).plan(prob)
    assume(plan.trajectory is not None)
    sol = plan.trajectory
    t = np.linspace(0, prob.tf, 200001)
    X, U = sol.states(t), sol.inputs(t)
    peaks = exact_peaks(sol, prob.tf, sol.knots() if hasattr(sol, "knots") else list(plan.contact_times))
    for name, col, arr in (("vx", 1, X), ("y", 2, X), ("ax", 0, U), ("ay", 1, U)):
        lo, hi = peaks[name]
        scale = max(1.0, float(np.max(np.abs(arr[:, col]))))
        assert lo <= arr[:, col].min() + 1e-9 * scale and hi >= arr[:, col].max() - 1e-9 * scale, name
        # equal to the sampling's resolution (one step of the dense grid), and to 1e-6 at least
        res = max(1e-6 * scale, float(np.max(np.abs(np.diff(arr[:, col])))))
        assert abs(lo - arr[:, col].min()) <= res and abs(hi - arr[:, col].max()) <= res, name
    norm = np.hypot(U[:, 0], U[:, 1])
    res = max(1e-6 * max(1.0, norm.max()), float(np.max(np.abs(np.diff(norm)))))
    assert peaks["a_total"] >= norm.max() - 1e-9 and peaks["a_total"] - norm.max() <= res


@SETTINGS
@given(bounded_problems(), st.floats(0.03, 0.97), st.floats(0.002, 0.15))
def test_interval_bound_is_below_the_bounded_cost_on_its_interval(problem: Problem, centre: float, width: float
                                                                 ) -> None:
    """The certificate's interval bound (weak duality + the second-order Taylor term in the
    contact time) is below the bounded cost at 81 contact times of its interval, and an
    interval it calls infeasible is infeasible at each of them: the bound is a bound, wherever
    :math:`J_b` is convex or not."""
    T = problem.tf
    a, b = max(1e-3 * T, (centre - width / 2) * T), min((1 - 1e-3) * T, (centre + width / 2) * T)
    kind, value = interval_bound(problem, a, b)
    assume(kind != "unknown")
    for t in np.linspace(a, b, 81):
        try:
            j = solve_bounded_fixed(problem, [t]).cost
        except AxisInfeasible:
            continue  # J_b = +inf here: any bound holds
        except AxisNoConvergence:
            continue
        assert kind == "bound", (t, kind)  # a feasible contact time inside an "infeasible" interval
        assert j >= value - 1e-9 * max(1.0, abs(j)), (t, j, value)


@pytest.mark.parametrize("coeffs", [(-15.0, 18.0, 0.6, -0.08), (-30.0, 22.0, -1.2, 0.05), (5.0, 12.0, 0.0, 0.02)])
def test_certificate_rates_bound_the_true_derivatives(coeffs: tuple[float, float, float, float]) -> None:
    """The constants of the interval certificates are bounds: ``max|c̈|`` and the Farkas
    margin's rate ``max|ċ| + |v0| + max(|ℓ|,|h|) t_f`` (x axis) are at least their values on
    a dense grid of (0, t_f), for cubic vehicle predictions."""
    from iamp.planners.pmp.bounded import _IntervalBound

    base = load_scenario("paper-1")
    veh = SurroundingVehicle(x_poly=coeffs, corner="front-lower", y=base.vehicles[0].y, length=4.8, width=1.8,
                             safety_x=5.0, safety_y=0.5)
    problem = Problem(base.ego, (veh,), "cubic", BOX)
    ib = _IntervalBound(problem)
    ego, T = problem.ego, problem.tf
    t = np.linspace(0, T, 20001)
    poly = np.polynomial.Polynomial(coeffs)
    cdot, cddot = np.abs(poly.deriv(1)(t)).max(), np.abs(poly.deriv(2)(t)).max()
    assert ib.cddot_max[0] >= cddot - 1e-12 and ib.cddot_max[1] == 0.0
    assert ib.lip_rate[0] >= cdot + abs(ego.vx0) + max(abs(b) for b in BOX.ax) * T - 1e-9
    assert ib.lip_rate[1] >= abs(ego.vy0) + max(abs(b) for b in BOX.ay) * T - 1e-9


def test_a_box_on_one_axis_only() -> None:
    """``ax`` given, ``ay`` not (and the reverse): the unbounded axis is free, the bounded one
    imposed; an ``ay``-only box the plan respects returns the unbounded plan unchanged."""
    base = load_scenario("paper-1")
    free = PMPPlanner().plan(base)
    only_x = PMPPlanner().plan(base.with_limits(PhysicalLimits(ax=(-6.0, 3.0))))
    assert only_x.status == OPTIMAL and only_x.info["bounded"]["box_active"]
    U = only_x.inputs(np.linspace(0, base.tf, 2001))
    assert U[:, 0].max() <= 3.0 + 1e-12 and only_x.cost is not None and free.cost is not None
    assert only_x.cost > free.cost
    only_y = PMPPlanner().plan(base.with_limits(PhysicalLimits(ay=(-2.0, 2.0))))
    assert only_y.status == OPTIMAL and not only_y.info["bounded"]["box_active"] and only_y.cost == free.cost
