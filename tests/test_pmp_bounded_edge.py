"""The bounded PMP at an edge of the feasible contact times (issue 32 item 4).

:mod:`iamp.planners.pmp.reach` certifies the contact times beyond such an edge infeasible by a
Farkas margin ``m(λ; t)`` maximised over the multipliers, and steps along them with a bound
of the margin's slope.  Checked here against an independent fine-grid LP (scipy's HiGHS, a
piecewise-constant input on ``N`` pieces: a *restriction* of the continuous problem, so its
reachable positions at ``t`` lie inside the continuous ones):

* ``m(λ; t) <= (c − max s_N(t))/ℓ`` for every ``λ`` with ``λ_1 = +1`` (weak duality), and the
  ``λ`` found is within the grid's error of that (``−1``: the same with ``min s_N``);
* the slope bound ``m(t + s) >= m(t) + ∂m(t) s − |s| D(δ)`` at fixed ``λ``;
* every contact time of a plan's edge cover is infeasible for the grid LP too;
* the seven one-vehicle problems that ended ``local`` at an edge (1400 generated problems,
  2026-11-28) are ``optimal`` now; two of them had a stationary minimum just inside the edge,
  below the edge plan's cost by more than the certificate's ``1e-9``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from iamp.core import status as stc
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp import bounded as B
from iamp.planners.pmp.reach import AxisReach, _terms
from iamp.planners.qp.bounded import BoundedQP

sys.path.insert(0, str(Path(__file__).parent))
from test_bounded_random import boxed, check

N_GRID = 300


def reachable(T: float, s0: float, v0: float, sf: float, vf: float, lo: float, hi: float, t: float
              ) -> tuple[float, float] | None:
    """``(min, max)`` of ``s(t)`` over piecewise-constant inputs on ``N_GRID`` pieces in the box
    meeting the boundary conditions (``None``: no such input)."""
    e = np.linspace(0.0, T, N_GRID + 1)
    a, b = e[:-1], e[1:]
    h = b - a
    # s(x) = s0 + v0 x + sum_k u_k * integral of (x - tau)_+ over piece k
    def ramp(x: float) -> np.ndarray:
        lo_k, hi_k = np.minimum(a, x), np.minimum(b, x)
        return (hi_k - lo_k) * (x - 0.5 * (hi_k + lo_k))
    A_eq = np.vstack([ramp(T), h])
    b_eq = np.array([sf - s0 - v0 * T, vf - v0])
    g = ramp(t)
    out = []
    for sign in (1.0, -1.0):
        res = linprog(sign * g, A_eq=A_eq, b_eq=b_eq, bounds=[(lo, hi)] * N_GRID, method="highs")
        if res.status != 0:
            return None
        out.append(s0 + v0 * t + float(g @ res.x))
    return out[0], out[1]


@st.composite
def axes(draw: st.DrawFn) -> tuple[AxisReach, tuple[float, ...], float]:
    """A y-like axis (fixed corner) whose boundary conditions some input in the box meets."""
    T = draw(st.floats(2.0, 8.0))
    lo, hi = -draw(st.floats(0.5, 6.0)), draw(st.floats(0.5, 6.0))
    v0 = draw(st.floats(-3.0, 3.0))
    us = draw(st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4))
    u = [lo + (hi - lo) * x for x in us]  # a piecewise-constant input: the end state is reachable
    h = T / 4
    s, v = 0.0, v0
    for uk in u:
        s, v = s + v * h + 0.5 * uk * h * h, v + uk * h
    corner = draw(st.floats(-30.0, 30.0))
    data = (0.0, v0, s, v, lo, hi)
    sig = draw(st.floats(0.05, 0.95))
    return AxisReach(T, data, [0.0], [0.0], corner, False, 0.0, sig * T), data, sig


SETTINGS = settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(axes(), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0))
def test_the_margin_is_the_distance_to_the_reachable_positions(case: tuple[AxisReach, tuple[float, ...], float],
                                                                x2: float, x3: float) -> None:
    axis, (s0, v0, sf, vf, lo, hi), sig = case
    T = axis.T
    reach = reachable(T, s0, v0, sf, vf, lo, hi, sig * T)
    assert reach is not None
    lo_s, hi_s = reach
    d = axis.d(sig)
    grid_err = 4 * (axis.hi - axis.lo) / N_GRID  # a switching time off the grid, in scaled units
    for eps, gap in ((1.0, (axis.offset - hi_s) / axis.ell), (-1.0, (lo_s - axis.offset) / axis.ell)):
        # weak duality: any multipliers, and the best ones found (less the floor of their rounding:
        # where the boundary conditions pin u to a bound the best multipliers run off to ~1e15)
        assert _terms(sig, d, axis.lo, axis.hi, eps, x2, x3)[0] <= gap + 1e-9
        m, _, _, floor = axis.margin(sig, eps, [x2, x3])
        assert m - floor <= gap + 1e-9, (eps, m, floor, gap)
        if floor < 1e-9:
            assert gap - grid_err - 1e-9 <= m, (eps, m, gap)


@settings(SETTINGS, max_examples=100)
@given(axes(), st.sampled_from([1.0, -1.0]), st.floats(-2.0, 2.0), st.floats(0.0, 1.0), st.floats(-0.3, 0.3))
def test_the_slope_bound_holds(case: tuple[AxisReach, tuple[float, ...], float], eps: float, beta: float,
                               root: float, frac: float) -> None:
    """At fixed ``λ``: ``m(σ + s) >= m(σ) + ∂m(σ) s − |s| D(|s|)``, with ``w = α + βτ`` on
    ``[0, σ]`` vanishing at ``root·σ`` (fails without ``D``'s term of the sign changes of ``w``,
    :func:`~iamp.planners.pmp.saturated_kernel.free_measure`)."""
    axis, _, sig = case
    x2 = -eps - beta  # β = −(ε + λ2)
    x3 = -beta * root * sig - eps * sig - x2  # α = εσ + λ2 + λ3 = −β·root·σ
    s = frac * min(sig, 1 - sig)
    m0, _, before = _terms(sig, axis.d(sig), axis.lo, axis.hi, eps, x2, x3)
    rate = eps * (axis.d1_rate(sig) - before)
    m1 = _terms(sig + s, axis.d(sig + s), axis.lo, axis.hi, eps, x2, x3)[0]
    assert m1 >= m0 + rate * s - abs(s) * axis.drift(sig, eps, [x2, x3], abs(s)) - 1e-12


EDGE_CASES = [(421188, 0.9802351504609911), (816845, 0.93), (161397, 0.87), (608074, 0.70), (901663, 0.85),
              (985552, 0.84), (520797, 0.7340482993429447)]


@pytest.mark.parametrize(("seed", "scale"), EDGE_CASES)
def test_a_minimum_at_or_beside_an_edge_is_certified(seed: int, scale: float) -> None:
    problem = boxed(seed, 1, scale)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.status == stc.OPTIMAL, (plan.status, plan.info.get("global_certificate"))
    assert plan.info["search"].get("edge") is not None
    assert plan.info["global_certificate"]["solves"] < 200  # was 3000 (the budget) without closing


@pytest.mark.parametrize(("seed", "scale", "edge_cost", "drop"), [(608074, 0.70, 79.66569173676632, 1e-8),
                                                                  (520797, 0.7340482993429447, 195.52763150983003, 0)])
def test_a_stationary_minimum_just_inside_the_edge_is_found(seed: int, scale: float, edge_cost: float,
                                                            drop: float) -> None:
    """``J_b`` falls from ``EDGE_PROBE`` inside towards the edge and turns up again just before
    it: the minimum is stationary and below the edge plan (the plan before, ``local``); for
    608074 by more than the certificate's ``1e-9`` (3.9e-8), so that plan could not have been
    certified (520797: 2.2e-10)."""
    problem = boxed(seed, 1, scale)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.cost is not None and plan.cost < edge_cost * (1 - drop)
    assert "feasibility_edge" not in plan.info["search"]
    assert plan.status == stc.OPTIMAL
    if "hamiltonian_jump_not_applied" not in plan.info["search"]:  # see test_stationary_within_one_ulp
        assert plan.diagnostics.checks["hamiltonian_jump"]["ok"]


def test_stationary_within_one_ulp() -> None:
    """random_problem(161397) at 0.87: ``r`` changes sign between adjacent float contact times
    1.8e-9 t_f inside the edge, so the Hamiltonian-jump residual cannot fall below ~1e-5; the
    plan says so (``hamiltonian_jump_not_applied``) and rests on the certificate."""
    problem = boxed(161397, 1, 0.87)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.info["search"].get("stationary_within_ulp") is True
    assert "hamiltonian_jump_not_applied" in plan.info["search"]
    assert "hamiltonian_jump" not in plan.info["checks"]
    assert plan.status == stc.OPTIMAL
    # the claim near the edge, independently: J_b on a fine scan around the contact time
    t, T = float(plan.contact_times[0]), float(problem.tf)
    ev = B._Evaluator(problem)
    scan = [ev(np.array([t + k * 1e-10 * T]))[0] for k in range(-40, 41)]
    assert plan.cost is not None and plan.cost <= min(scan) * (1 + 1e-9)
    assert sum(np.isfinite(scan)) > 40  # the scan reaches the edge (1.8e-9 t_f away) and beyond


def test_a_failed_solve_is_not_a_root_of_r() -> None:
    """random_problem(186935) under an ``a_x`` box at 0.4568 of its peaks (``bounded_sweep.py --rng
    2501``): the feasible contact times are a window ~0.01 s wide at the end of the horizon (the
    bounded QP, N = 60 to 240, certifies every node infeasible), ``J_b`` falls from its lower edge
    and turns 6.8e-8 s inside it.  Brent's method on ``r`` met a time whose solve failed, where
    ``r = 0`` stands in, and took it for the root (``r = +8.7e3`` on either side; the plan was
    ``inaccurate``, Hamiltonian-jump check 0.024); the bisection on ``r``'s sign finds the
    stationary minimum, certified."""
    problem = boxed(186935, 1, 0.4568230413213062, "ax")
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.status == stc.OPTIMAL, (plan.status, plan.info.get("failed_check"))
    assert plan.cost is not None and plan.cost < 1545.6486  # the plan at the false root: 1545.64864
    t, T = float(plan.contact_times[0]), float(problem.tf)
    edge = plan.info["search"]["edge"]
    assert edge["side"] == "lower" and 0.0 < t - edge["t"] < 1e-6 * T
    # independently: J_b around the contact time (the evaluator's own solves) is nowhere below it
    ev = B._Evaluator(problem)
    scan = [ev(np.array([t + k * 1e-9]))[0] for k in range(-60, 61)]
    assert sum(np.isfinite(scan)) > 100
    assert plan.cost <= min(scan) * (1 + 1e-12)


@pytest.mark.parametrize(("seed", "scale"), [EDGE_CASES[0], EDGE_CASES[5]])
def test_what_the_edge_cover_claims_is_infeasible(seed: int, scale: float) -> None:
    """Sampled contact times of the edge cover admit no input for the fine-grid LP either."""
    problem = boxed(seed, 1, scale)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    cover = plan.info["global_certificate"]["edge_cover"]
    ib = B._IntervalBound(problem)
    k = "xy".index(cover["axis"])
    s0, v0, sf, vf, lo, hi = ib.axes_data[k]
    T = float(problem.tf)
    for t in np.linspace(cover["from"], cover["to"], 9)[1:-1]:
        corner = (B._polyval(ib.pos, float(t)) + ib.off[0]) if k == 0 else ib.off[1]
        reach = reachable(T, s0, v0, sf, vf, lo, hi, float(t))
        assert reach is None or not reach[0] <= corner <= reach[1], (t, reach, corner)


def test_a_feasible_island_the_search_missed_is_found_by_the_certificate() -> None:
    """random_problem(303480) at 0.72: the feasible contact times are [0.50, 0.62] t_f, where the
    search's minimum is (2.10288, ``local``: the certificate did not close), and an island
    [0.6742, 0.6797] t_f between two grid points, where J_b falls to 1.98079 (the bounded QP,
    N = 60 refined, misses it too: 2.1031).  The certificate meets a centre whose dual value is
    below J_best, the search restarts there, and the island's minimum is certified."""
    problem = boxed(303480, 1, 0.7209343105544178)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.status == stc.OPTIMAL
    assert plan.cost is not None and plan.cost < 2.1028790611568575 * 0.95
    assert "restarted_from_certificate" in plan.info["search"]
    # independently: J_b on a scan of the island is nowhere below the plan
    T = float(problem.tf)
    ev = B._Evaluator(problem)
    scan = [ev(np.array([s * T]))[0] for s in np.linspace(0.6740, 0.6800, 61)]
    assert sum(np.isfinite(scan)) > 40 and plan.cost <= min(scan) * (1 + 1e-9)


def test_a_minimum_at_a_lower_edge_past_a_stalled_solve_is_certified() -> None:
    """Found by test_bounded_random's many-example property with fresh draws (2026-11-29; the same
    at cb0240f): random_problem(166) at 0.8872 was ``local`` at 2.144495982774.  The x-axis solve
    stalls (no plan, no Farkas certificate) at a feasible contact time ``5.6e-13 t_f`` below the
    plan's, where the search's bisection stopped as at the lower edge of the feasible times; the
    edge is ``9.3e-10 t_f`` lower, with ``J_b`` ``2.5e-9`` (relative) lower there, so the
    certificate's dual values rightly stayed below the plan (by less than ``BETTER_REL``) and it
    never closed.  The search now looks past a bisected edge
    (:data:`~iamp.planners.pmp.bounded.EDGE_BEYOND`): ``optimal`` at the true edge.  Checked
    against the bounded FOH QP (N = 60, refined contact time, ``local`` at 2.16495, 0.9 % above;
    N = 240 through the plan's contact time: :func:`test_bounded_random.check`), the FOH QP at
    N = 240 through contact times across
    the feasible ones (a restriction: never below the minimum), and a fine scan of ``J_b`` from
    beyond the edge."""
    scale = 0.8872161667849776
    assert check(166, 1, scale) in (f"{stc.OPTIMAL}/{stc.OPTIMAL}", f"{stc.OPTIMAL}/{stc.LOCAL}")
    problem = boxed(166, 1, scale)
    assert problem is not None
    plan = PMPPlanner().plan(problem)
    assert plan.status == stc.OPTIMAL and plan.cost is not None
    assert plan.info["search"].get("feasibility_edge") == "lower"
    T, t = float(problem.tf), float(plan.contact_times[0])
    qp = BoundedQP(problem, 240, "foh", "clarabel")
    sweep = [qp.solve_times(np.array([x])) for x in [*(np.linspace(0.01, 0.99, 50) * T),
                                                     *(t + np.geomspace(1e-7, 3e-2, 25) * T)]]
    costs = [r.cost for r in sweep if r.status == stc.OPTIMAL and r.cost is not None]
    assert len(costs) >= 15 and min(costs) >= plan.cost * (1 - 1e-9)
    at = qp.solve_times(np.array([t]))
    assert at.status == stc.OPTIMAL and at.cost is not None
    assert plan.cost * (1 - 1e-9) <= at.cost <= plan.cost * (1 + 1e-7)
    ev = B._Evaluator(problem)
    scan = [ev(np.array([t + k * 1e-10 * T]))[0] for k in range(-30, 61)]
    # the scan starts beyond the edge and crosses the former plan's contact time (+9.3e-10 t_f)
    assert not np.isfinite(scan[0]) and sum(np.isfinite(scan)) > 55
    assert plan.cost <= min(scan) * (1 + 1e-9)
    assert plan.cost < 2.144495982773867 * (1 - 1e-9)  # below the former local plan
