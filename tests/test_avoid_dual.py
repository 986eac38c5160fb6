"""Issue 32 item 3: the weak-duality bound of the continuous-time avoidance QP over crossing-time
boxes (:mod:`iamp.planners.avoid.dual`).

* It is a lower bound: on generated problems (hypothesis) and boxes, inside one grid piece or
  across several, the polynomial's Bernstein bound never exceeds ``J(τ)`` solved at sampled
  crossing times in the box, nor the polynomial itself there.
* It is tight at the candidate: ``g(y(τ_c); τ_c) = J(τ_c)``, and second order: on a box of
  width ``w`` around the optimum it falls below ``J`` by ``O(w²)`` (halving ``w`` divides the
  loss by about four), far less than the relaxation of the search (rows dropped in the box).
* The branch and bound built on it is global: against a dense scan of fixed crossing times.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st_h

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.tolerances import tol
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, ContinuousAvoidQP
from iamp.planners.avoid.dual import DualBounds, piece_of
from iamp.planners.examples import overtake_problem


def problem(x0v: float, speed: float, xf: float, vxf: float, limits: bool) -> Problem:
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=xf, yf=3.75, vxf=vxf)
    v = SurroundingVehicle(x_poly=(x0v, speed), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding", limits=PASSENGER_CAR if limits else None)


def grid_qp(prob: Problem, steps: int, hold: str) -> ContinuousAvoidQP:
    """The problem's QP on ``steps`` pieces (a generated draw the planner refuses is rejected)."""
    try:
        return ContinuousAvoidQP(prob, steps, hold, "clarabel")
    except ScenarioError:
        assume(False)
        raise


def spec(order: tuple[int, int], t: float) -> tuple[tuple[int, int, float, float], ...]:
    return ((order[0], order[1], float(t), float(t)),)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.floats(100.0, 125.0), st_h.floats(20.0, 26.0),
       st_h.booleans(), st_h.sampled_from(["foh", "zoh"]), st_h.integers(6, 20), st_h.floats(0.05, 0.95),
       st_h.floats(0.0, 1.0), st_h.floats(0.0, 1.0), st_h.floats(0.0, 3.0))
def test_the_dual_bound_is_below_every_crossing_in_its_box(x0v, speed, xf, vxf, limits, hold, steps, where, a, b,
                                                           pieces):
    prob = problem(x0v, speed, xf, vxf, limits)
    qp = grid_qp(prob, steps, hold)
    h = qp.h
    k = min(int(where * steps), steps - 1)
    lo = (k + min(a, b) * pieces) * h if pieces >= 1 else (k + min(a, b)) * h
    hi = (k + max(a, b) * pieces) * h if pieces >= 1 else (k + max(a, b)) * h
    lo, hi = max(0.0, lo), min(prob.tf, max(hi, lo))
    assume(hi - lo > 1e-6)
    bounds = DualBounds(qp)
    order = (1, 0)  # the ego starts below the vehicle's lane (H_y) and ends ahead of it (H_x)
    taus = np.linspace(lo, hi, 7)
    solved = [qp.solve(spec(order, t)) for t in taus]
    feasible = [s for s in solved if s.status == st.OPTIMAL]
    assume(feasible)
    box_lo, box_hi = np.array([lo]), np.array([hi])
    for cand in feasible[:: max(1, len(feasible) // 3)]:
        dp = bounds.polynomial(cand, box_lo, box_hi)
        if piece_of(lo, hi, h, steps) is not None:
            assert dp.vehicles == (0,)
            c_tau = cand.spec[0][2]
            # tight at the candidate (its own dual value), to the backend's accuracy
            assert float(dp.evaluate(np.array([[c_tau]]))[0]) == pytest.approx(cand.cost, rel=1e-6, abs=1e-6)
        lb = dp.lower_bound(box_lo, box_hi)
        for t, s in zip(taus, solved):
            if s.status == st.OPTIMAL:
                assert lb <= s.cost + 1e-9 * max(1.0, s.cost), (t, lb, s.cost)
                assert float(dp.evaluate(np.array([[t]]))[0]) - dp.roundoff <= s.cost + 1e-7 * max(1.0, s.cost)


def test_the_bound_is_second_order_in_the_box_width():
    prob = overtake_problem()
    qp = ContinuousAvoidQP(prob, 50, "foh", "clarabel")
    plan = ContinuousAvoidPlanner(steps=50).plan(prob)
    tau = float(plan.info["avoidance"]["vehicles"][0]["crossing_time"])
    best = qp.solve(spec((1, 0), tau))
    bounds = DualBounds(qp)
    loss = []
    widths = (0.08, 0.04, 0.02)
    for w in widths:  # boxes around the optimum inside its piece [3.7, 3.8]
        lo, hi = np.array([tau - 0.1 * w]), np.array([tau + 0.9 * w])
        assert piece_of(lo[0], hi[0], qp.h, qp.N) is not None
        loss.append(best.cost - bounds.polynomial(best, lo, hi).lower_bound(lo, hi))
    assert all(x > 0 for x in loss)
    assert 3.0 < loss[0] / loss[1] < 5.0 and 3.0 < loss[1] / loss[2] < 5.0, loss
    # the relaxation (rows dropped inside the box) loses far more on the same boxes
    rel = [best.cost - qp.solve(((1, 0, tau - 0.1 * w, tau + 0.9 * w),)).cost for w in widths]
    assert all(r > 10 * x for r, x in zip(rel, loss)), (rel, loss)


@pytest.mark.parametrize("hold, limits", [("foh", True), ("zoh", False)])
def test_the_search_is_global_against_a_dense_scan(hold, limits):
    prob = problem(5.0, 20.0, 118.0, 24.0, limits)
    planner = ContinuousAvoidPlanner(steps=20, hold=hold)
    plan = planner.plan(prob)
    assert plan.status == st.OPTIMAL
    scan_planner = ContinuousAvoidPlanner(steps=20, hold=hold, node_solver="backend")  # independent of the search
    scan = [scan_planner.plan_at_times(prob, [t]) for t in np.linspace(0.025, 4.975, 199)]
    costs = [p.cost for p in scan if p.cost is not None]
    assert plan.cost <= min(costs) * (1 + 1e-9)
    s = plan.info["search"]
    assert s["closed"] and s["lower_bound"] <= plan.cost and plan.cost - s["lower_bound"] <= 1e-4 * plan.cost


def fine_reference(prob: Problem, steps: int) -> float:
    """An independent minimum of ``J(τ)`` over every crossing time: the fixed-crossing-time QP
    (no branch and bound, no dual bound) on 120 scanned crossing times, then a bounded Brent
    search within one scan step on each side of the best scanned time; every QP solved by Clarabel
    (not the search's node solver)."""
    from scipy.optimize import minimize_scalar

    planner = ContinuousAvoidPlanner(steps=steps, solver="clarabel", node_solver="backend")

    def J(t: float) -> float:
        p = planner.plan_at_times(prob, [t])
        return p.cost if p.cost is not None else np.inf

    ts = np.linspace(0.02, 4.98, 120)
    costs = np.array([J(float(t)) for t in ts])
    if not np.isfinite(costs).any():
        return np.inf
    k = int(np.argmin(costs))
    lo, hi = float(ts[max(k - 1, 0)]), float(ts[min(k + 1, ts.size - 1)])
    res = minimize_scalar(J, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
    return float(min(costs[k], res.fun))


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.floats(100.0, 125.0), st_h.floats(20.0, 26.0),
       st_h.booleans())
def test_generated_problems_the_certified_optimum_is_no_worse_than_any_scanned_crossing(x0v, speed, xf, vxf, limits):
    """Generated one-vehicle problems: OSQP, Clarabel and PIQP reach the same status, and an
    ``optimal`` plan of the branch and bound costs no more than an independent fine reference
    (:func:`fine_reference`: a scan of fixed crossing times refined by Brent), the same cost on
    every backend (to OSQP's comparison tolerance), its reported bounds bracketing it within the
    gap."""
    prob = problem(x0v, speed, xf, vxf, limits)
    plans = {}
    for solver in ("osqp", "clarabel", "piqp"):
        try:
            plans[solver] = ContinuousAvoidPlanner(steps=12, solver=solver).plan(prob)
        except ScenarioError:
            assume(False)
    assert len({p.status for p in plans.values()}) == 1, {k: p.status for k, p in plans.items()}
    assume(plans["piqp"].status == st.OPTIMAL)
    ref = fine_reference(prob, 12)
    costs = [p.cost for p in plans.values()]
    assert max(costs) - min(costs) <= tol("cmp_cost_rel_osqp") * max(costs)
    for plan in plans.values():
        assert plan.cost <= ref * (1 + 1e-9) + 1e-12
        s = plan.info["search"]
        assert s["lower_bound"] <= plan.cost * (1 + 1e-12)
        assert plan.cost - s["lower_bound"] <= 1e-4 * max(1.0, plan.cost)


@pytest.mark.parametrize("solver", ["piqp", "clarabel"])
def test_every_stored_polynomial_bounds_j_on_its_whole_region(solver):
    """The search's store (:class:`~iamp.planners.avoid.dual.DualStore`) bounds a box by every
    candidate's polynomial whose region holds it, not only its ancestors'; a vehicle with no
    multiplier counts as valid for any crossing time.  Three vehicles: at crossing times drawn
    in each stored polynomial's region, ``J(τ)`` is never below it."""
    from iamp.planners.avoid.continuous import _spec
    from iamp.planners.avoid.dual import DualStore
    from iamp.planners.examples import overtake_three_problem

    prob = overtake_three_problem()
    qp = ContinuousAvoidQP(prob, 20, "foh", solver)
    store = DualStore(DualBounds(qp))
    orders = [(1, 0), (0, 1), (0, 1)]
    rng = np.random.default_rng(3)
    centres = [(3.71, 1.86, 3.6), (3.66, 1.9, 4.4)]
    for c in centres:
        sol = qp.solve(_spec(orders, c, c))
        assert sol.status == st.OPTIMAL
        store.piece(sol)
    checked = 0
    for o, lo, hi, dp in zip(store._orders, store._LO, store._HI, store._polys):
        a, b = np.maximum(lo, 1e-3), np.minimum(hi, qp.tf - 1e-3)
        for _ in range(4):
            t = a + (b - a) * rng.random(3)
            assert store.valid(tuple(o), t, t)
            sol = qp.solve(_spec(o, t, t))
            if sol.status != st.OPTIMAL:
                continue
            assert float(dp.evaluate(t[None, :])[0]) - dp.roundoff <= sol.cost * (1 + 1e-9) + 1e-9, (t, sol.cost)
            assert dp.lower_bound(t, t) <= sol.cost * (1 + 1e-9) + 1e-9
            checked += 1
    assert checked >= 4


@pytest.mark.parametrize("three", [False, True])
def test_the_stores_polynomials_are_built_when_asked_for_and_are_the_eager_ones(three):
    """The search stores every optimal candidate with its region (:meth:`DualStore.add`, from its
    multipliers' sums per vehicle) and builds its piece polynomial only when a box or the search
    asks for it: each one built is, bit for bit, :meth:`DualBounds.polynomial` of the same
    candidate on its pieces built at once in a fresh store, the regions are those of the
    polynomials' own ``mass``, and three vehicles leave some never built."""
    from iamp.planners.avoid.check import crossing_orders
    from iamp.planners.avoid.dual import DualStore
    from iamp.planners.examples import overtake_three_problem

    prob = overtake_three_problem() if three else overtake_problem()
    qp = ContinuousAvoidQP(prob, 50, "foh", "clarabel")
    planner = ContinuousAvoidPlanner(steps=50)
    stores: list[DualStore] = []
    init = DualStore.__init__

    def keep(self, dual):  # type: ignore[no-untyped-def]
        init(self, dual)
        stores.append(self)

    DualStore.__init__ = keep  # type: ignore[method-assign]
    try:
        planner.search(qp, crossing_orders(prob)[0])
    finally:
        DualStore.__init__ = init  # type: ignore[method-assign]
    store = stores[0]
    assert len(store._polys) >= 4
    unbuilt = sum(p is None for p in store._polys)
    assert unbuilt >= (1 if three else 0)
    fresh = DualStore(DualBounds(qp))
    near = {v: a for a, v in store._near.items()}  # a candidate's second entry: its tangent interval
    assert bool(near) == (not three)
    for at, (sol, lo, hi) in enumerate(store._sources):
        ref = fresh.near(sol) if at in near else fresh.piece(sol)
        assert np.array_equal(store.dual.mass(sol), ref.mass)
        assert np.array_equal(store._B[at], ref.mass > 0)
        k = np.array([piece_of(float(a), float(a), qp.h, qp.N) for _, _, a, _ in sol.spec], dtype=float)
        if at in near:
            assert store._sources[near[at]][0] is sol and ref.second_order
            la, lb = store.dual.tangent_interval(sol, 0, int(k[0]))
            assert np.array_equal(lo, k * qp.h + la * qp.h) and np.array_equal(hi, k * qp.h + lb * qp.h)
        else:
            assert np.array_equal(lo, k * qp.h) and np.array_equal(hi, (k + 1) * qp.h)
        built = store._polys[at]
        if built is not None:
            assert built.vehicles == ref.vehicles and built.pieces == ref.pieces
            assert np.array_equal(built.coef, ref.coef) and np.array_equal(built.mass, ref.mass)
        assert np.array_equal(store._poly(at).coef, ref.coef)  # built now if it was not


@pytest.mark.parametrize("three", [False, True])
def test_the_envelope_gradient_is_the_piece_polynomials_slope(three):
    """:meth:`DualBounds.gradient` (the envelope theorem on the split piece's rows, used by the
    final secant search) equals the slope of the candidate's piece polynomial at its crossing
    times, and a central difference of ``J`` where ``J`` is smooth."""
    from iamp.planners.avoid.continuous import _spec
    from iamp.planners.avoid.dual import DualStore
    from iamp.planners.examples import overtake_three_problem

    prob = overtake_three_problem() if three else overtake_problem()
    qp = ContinuousAvoidQP(prob, 30, "foh", "clarabel")
    store = DualStore(DualBounds(qp))
    orders = [(1, 0), (0, 1), (0, 1)][:prob.m]
    centres = ([3.71, 1.86, 3.6], [3.66, 1.9, 4.4]) if three else ([3.71], [3.55])
    for c in centres:
        tau = np.array(c)
        sol = qp.solve(_spec(orders, tau, tau))
        assert sol.status == st.OPTIMAL
        grad = store.dual.gradient(sol)
        dp = store.piece(sol)
        slope = np.array([dp.slope(tau, i) for i in range(prob.m)])
        np.testing.assert_allclose(grad, slope, rtol=1e-9, atol=1e-9)
        for i in np.flatnonzero(np.abs(grad) > 1e-6):
            e = np.zeros(prob.m)
            e[i] = 1e-5
            up, down = qp.solve(_spec(orders, tau + e, tau + e)), qp.solve(_spec(orders, tau - e, tau - e))
            assert grad[i] == pytest.approx((up.cost - down.cost) / 2e-5, rel=1e-3, abs=1e-6)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.booleans(), st_h.sampled_from(["foh", "zoh"]),
       st_h.integers(6, 30), st_h.floats(0.05, 0.95), st_h.floats(0.0, 3.0))
def test_the_polynomial_from_the_node_solvers_columns_is_the_direct_solves(x0v, speed, limits, hold, steps, where,
                                                                           pieces):
    # K^-1 R from the columns of K^-1 the node solver keeps (and the equality optimum) is the
    # sparse LU solve of the same system (the backend node solver's route): same coefficients
    # to round-off
    prob = problem(x0v, speed, 118.0, 24.0, limits and hold == "foh")
    try:
        qp = ContinuousAvoidQP(prob, steps, hold, "clarabel")
    except ScenarioError:
        assume(False)
    assert qp.schur is not None
    h = qp.h
    t = min(max(where * prob.tf, 1e-3), prob.tf - 1e-3)
    sol = qp.solve(spec((1, 0), t))
    assume(sol.status == st.OPTIMAL)
    k = piece_of(t, t, h, steps)
    assert k is not None
    lo, hi = np.array([max(0.0, (k - pieces) * h)]), np.array([min(prob.tf, (k + 1 + pieces) * h)])
    for box in ((np.array([k * h]), np.array([(k + 1) * h])), (lo, hi)):
        kept = DualBounds(qp).polynomial(sol, *box)
        schur, qp.schur = qp.schur, None
        try:
            direct = DualBounds(qp).polynomial(sol, *box)
        finally:
            qp.schur = schur
        assert kept.vehicles == direct.vehicles and kept.pieces == direct.pieces
        scale = max(1.0, float(np.abs(direct.coef).max()))
        assert np.abs(kept.coef - direct.coef).max() <= 1e-11 * scale


def _fixed(qp: ContinuousAvoidQP) -> DualBounds:
    """The dual bounds with every multiplier held at the candidate's (no tangent)."""
    out = DualBounds(qp)
    out.tangent = lambda sol, i, k: np.zeros(out._binding(sol).nz.size)  # type: ignore[method-assign]
    return out


def _multipliers(qp: ContinuousAvoidQP, sol) -> dict[int, float]:  # type: ignore[no-untyped-def]
    """A solution's positive multipliers by layout number."""
    _, _, ids = sol.spec_rows()
    return {int(i): float(v) for i, v in zip(ids, sol.y[qp.data.n_eq:]) if v > 0}


def test_the_tangent_is_the_multipliers_derivative_and_makes_the_bound_fourth_order():
    """At the overtake's optimum (one vehicle, N = 50): :meth:`DualBounds.tangent` equals the
    central difference of the multipliers of two solves ``±1e-5 h`` away (same binding rows); on
    the interval where no multiplier on its tangent turns negative, ``J - g`` falls off as the
    fourth power of the distance (halving it divides the loss by about 16) and the polynomial's
    curvature is ``J``'s (central difference), where the multipliers held fixed lose the second
    power (ratios about 4); every value is below ``J`` (weak duality)."""
    prob = overtake_problem()
    qp = ContinuousAvoidQP(prob, 50, "foh", "clarabel")
    plan = ContinuousAvoidPlanner(steps=50).plan(prob)
    tau = float(plan.info["avoidance"]["vehicles"][0]["crossing_time"])
    h = qp.h
    best = qp.solve(spec((1, 0), tau))
    k = piece_of(tau, tau, h, qp.N)
    assert k is not None
    bounds = DualBounds(qp)
    mu = bounds.tangent(best, 0, k)
    e = 1e-5 * h
    up, down = _multipliers(qp, qp.solve(spec((1, 0), tau + e))), _multipliers(qp, qp.solve(spec((1, 0), tau - e)))
    _, _, ids = best.spec_rows()
    rows = ids[bounds._binding(best).nz]
    assert set(up) == set(down) == {int(r) for r in rows}
    fd = np.array([(up[int(r)] - down[int(r)]) / (2 * e / h) for r in rows])
    assert np.allclose(mu, fd, rtol=1e-6, atol=1e-8), (mu, fd)
    la, lb = bounds.tangent_interval(best, 0, k)
    lam = (tau - k * h) / h
    assert la < lam < lb and (la, lb) != (0.0, 1.0)
    near = bounds.polynomial(best, np.array([(k + la) * h]), np.array([(k + lb) * h]))
    fixed = _fixed(qp).polynomial(best, np.array([(k + la) * h]), np.array([(k + lb) * h]))
    assert near.second_order
    steps = (0.16, 0.08, 0.04, 0.02)
    assert lam + steps[0] < lb
    loss_near, loss_fixed = [], []
    for d in steps:
        t = tau + d * h
        J = qp.solve(spec((1, 0), t)).cost
        loss_near.append(J - float(near.evaluate(np.array([[t]]))[0]))
        loss_fixed.append(J - float(fixed.evaluate(np.array([[t]]))[0]))
    assert all(x >= -1e-9 for x in loss_near + loss_fixed)
    for a, b in zip(loss_near, loss_near[1:]):
        assert 12.0 < a / b < 20.0, loss_near
    for a, b in zip(loss_fixed, loss_fixed[1:]):
        assert 3.0 < a / b < 5.0, loss_fixed
    E = 1e-4 * h
    curv = (qp.solve(spec((1, 0), tau + E)).cost - 2 * best.cost + qp.solve(spec((1, 0), tau - E)).cost) / E ** 2
    assert near.curvature(np.array([tau]), 0) == pytest.approx(curv, rel=1e-3)
    assert near.slope(np.array([tau]), 0) == pytest.approx(float(bounds.gradient(best)[0]), rel=1e-6, abs=1e-9)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@example(-4.0, 15.0, 100.0, 20.0, False, "foh", 6, 0.125, 0.0)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.floats(100.0, 125.0), st_h.floats(20.0, 26.0),
       st_h.booleans(), st_h.sampled_from(["foh", "zoh"]), st_h.integers(6, 30), st_h.floats(0.02, 0.98),
       st_h.floats(0.0, 1.0))
def test_the_tangent_polynomial_bounds_j_on_its_interval_and_the_piece(x0v, speed, xf, vxf, limits, hold, steps,
                                                                       where, frac):
    """Generated one-vehicle problems, a candidate anywhere in a piece: the polynomial with the
    multipliers on their tangent is below ``J`` at crossing times drawn on the interval where none
    turns negative and, with the slopes cut to keep them nonnegative, on the whole piece, less its
    round-off bound (:attr:`DualPolynomial.roundoff`: a nearly infeasible candidate, J = 8.7e7 at
    the start of a 6-piece grid with multipliers of 5e7, gave coefficients of 1e15 and a value
    0.57 above J = 1.59 at the piece's end, where the bound is now -1e13); its Bernstein bound is
    below every sampled ``J``."""
    qp = grid_qp(problem(x0v, speed, xf, vxf, limits), steps, hold)
    h = qp.h
    k = min(int(where * steps), steps - 1)
    tau = (k + 0.02 + 0.96 * frac) * h
    cand = qp.solve(spec((1, 0), tau))
    assume(cand.status == st.OPTIMAL)
    bounds = DualBounds(qp)
    la, lb = bounds.tangent_interval(cand, 0, k)
    assert 0.0 <= la <= (tau - k * h) / h <= lb <= 1.0
    for a, b in ((la, lb), (0.0, 1.0)):
        lo, hi = np.array([(k + a) * h]), np.array([(k + b) * h])
        dp = bounds.polynomial(cand, lo, hi)
        assert float(dp.evaluate(np.array([[tau]]))[0]) == pytest.approx(cand.cost, rel=1e-6, abs=1e-6)
        lb_box = dp.lower_bound(lo, hi)
        for t in np.linspace(lo[0], hi[0], 6):
            s = qp.solve(spec((1, 0), float(t)))
            if s.status == st.OPTIMAL:
                value = float(dp.evaluate(np.array([[t]]))[0]) - dp.roundoff
                assert value <= s.cost + 1e-7 * max(1.0, s.cost), (t, s.cost)
                assert lb_box <= s.cost + 1e-9 * max(1.0, s.cost)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.floats(-5.0, 12.0), st_h.floats(15.0, 24.0), st_h.floats(100.0, 125.0), st_h.floats(20.0, 26.0),
       st_h.booleans(), st_h.sampled_from(["foh", "zoh"]), st_h.integers(6, 20), st_h.floats(0.0, 1.0),
       st_h.floats(0.0, 1.0), st_h.floats(0.0, 1.0))
def test_a_box_over_several_pieces_gains_nothing_from_its_candidates_polynomial(x0v, speed, xf, vxf, limits, hold,
                                                                                 steps, a, b, c):
    """The search builds no polynomial for a box whose every vehicle spans several pieces
    (``ContinuousAvoidPlanner.search``): it keeps only rows the box's relaxation imposes, so its
    bound is at most the relaxation's optimum, which the box's bound holds. Checked on generated
    boxes and candidates inside them."""
    prob = problem(x0v, speed, xf, vxf, limits)
    qp = grid_qp(prob, steps, hold)
    lo, hi = sorted((a * prob.tf, b * prob.tf))
    assume(piece_of(lo, hi, qp.h, steps) is None)  # spans several pieces
    order = (1, 0)
    relaxed = qp.solve(((order[0], order[1], float(lo), float(hi)),))
    assume(relaxed.status == st.OPTIMAL)
    cand = qp.solve(spec(order, lo + c * (hi - lo)))
    assume(cand.status == st.OPTIMAL)
    dp = DualBounds(qp).polynomial(cand, np.array([lo]), np.array([hi]))
    assert dp.vehicles == ()
    assert dp.lower_bound(np.array([lo]), np.array([hi])) <= relaxed.cost


@pytest.mark.parametrize("tau_c,lo,hi", [(3.78, 3.66, 3.95), (3.63, 3.45, 3.77)])
def test_a_box_over_several_pieces_keeps_no_row_its_crossings_can_drop(tau_c, lo, hi):
    """A vehicle whose box spans several pieces keeps only its first half-plane's rows on pieces
    that end before the box and its second's on pieces that start after it: a candidate whose
    binding rows lie in the box's pieces (here its crossing's own piece, the box's second) gives
    no bound above ``J`` anywhere in the box, also where the crossing is earlier than those rows
    (the overtake's optimum, 3.7127 s, inside the box)."""
    prob = overtake_problem()
    qp = ContinuousAvoidQP(prob, 50, "foh", "clarabel")
    cand = qp.solve(spec((1, 0), tau_c))
    assert cand.status == st.OPTIMAL
    assert piece_of(lo, hi, qp.h, qp.N) is None
    dp = DualBounds(qp).polynomial(cand, np.array([lo]), np.array([hi]))
    bound = dp.lower_bound(np.array([lo]), np.array([hi]))
    costs = [qp.solve(spec((1, 0), float(t))) for t in np.linspace(lo, hi, 25)]
    feasible = [s.cost for s in costs if s.status == st.OPTIMAL]
    assert feasible and bound <= min(feasible) + 1e-9 * max(1.0, min(feasible))
