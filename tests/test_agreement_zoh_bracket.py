r"""Rule B6 for ZOH (issue 32): the bounded PMP / ZOH QP pair is judged by a derived two-sided
bracket, :math:`J_b(t_Q) \le J_{QP} \le J_b(t_Q) + D`, where :math:`D = J_{up} - E(u_b)` and
:math:`J_{up}` is the cost of a plan of the ZOH QP built from the bounded PMP's input
(:func:`iamp.comparison.agreement.bounded_pair.zoh_upper_plan`; the derivation is in that
module's docstring).  The former bracket ``[0.8, 1.25] x (h²/24)∫|u̇_b|²`` was fitted and failed
on ``random_problem(229)`` at 0.609 of its inputs (ratio 1.2535)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.sparse as sp
from bounded_bracket import WrongAtContactTimes, bounded, bracket_property, run_pair, with_cost
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from iamp.comparison.agreement import bounded_pair
from iamp.comparison.agreement.bounded_pair import (
    _box_min_norm,
    box_violation,
    compare_bounded_pmp_qp,
    zoh_upper_plan,
)
from iamp.core.physical import PhysicalLimits
from iamp.planners.pmp import PMPPlanner
from iamp.planners.qp.backends import get_backend
from iamp.planners.qp.bounded import BoundedQP

# --- the construction -----------------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6), st.integers(6, 30), st.integers(1, 4))
def test_box_min_norm_is_the_optimum_of_its_qp(seed: int, n: int, k: int) -> None:
    """The dual semismooth Newton returns the minimiser of ``½Σh w²`` s.t. ``G w = r``, box —
    the same cost as Clarabel on the same QP, feasible to 1e-12."""
    rng = np.random.default_rng(seed)
    G = rng.normal(size=(k, n))
    h = rng.uniform(0.1, 1.0, n)
    a, b = -rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    a[rng.random(n) < 0.2] = 0.0  # saturated entries: inward moves only
    r = G @ rng.uniform(a, b)  # feasible by construction
    w, _, ok = _box_min_norm(G, r, h, a, b, 1e-12)
    assert ok and np.all(w >= a) and np.all(w <= b)
    assert np.max(np.abs(G @ w - r)) <= 1e-12
    A = sp.vstack([sp.csc_matrix(G), sp.identity(n, format="csc")], format="csc")
    ref = get_backend("clarabel")(sp.diags(h, format="csc"), np.zeros(n), A, np.r_[r, a], np.r_[r, b]).solve()
    assert 0.5 * float(h @ w**2) == pytest.approx(0.5 * float(h @ ref.z**2), rel=1e-7, abs=1e-10)


def test_the_built_plan_is_a_plan_of_the_qp_above_its_optimum() -> None:
    """random_problem(229) at 0.609375, ZOH N = 24, contact at the QP's node 7: the plan built
    from the bounded PMP's input meets the QP's equalities (1e-12), its limit rows, and costs
    at least the QP's optimum at that node; the PMP's cost is its input's energy."""
    problem, N = bounded(229, 0.609375), 24
    t = np.linspace(0.0, problem.tf, N + 1)
    qp = BoundedQP(problem, N, "zoh", "clarabel")
    sweep = [qp.solve_nodes([n]) for n in range(1, N)]
    best = min((r for r in sweep if r.cost is not None), key=lambda r: float(r.cost))  # type: ignore[arg-type]
    (n,) = best.nodes
    at = PMPPlanner().plan(problem, contact_times=[t[n]])
    assert at.cost is not None and best.cost is not None
    up = zoh_upper_plan(problem, at, t, [n])
    assert up.reason is None and up.equality_residual_rel < 1e-12 and up.limit_violation_rel == 0.0
    assert up.energy == pytest.approx(at.cost, rel=1e-12)
    # the states: exact ZOH integration reaches the end state and the corner at t_n
    ego = problem.ego
    assert np.allclose(up.X[-1], [ego.xf, ego.vxf, ego.yf, ego.vyf], rtol=0, atol=1e-9)
    v = problem.vehicles[0]
    assert np.allclose(up.X[n, [0, 2]], [float(np.asarray(v.corner_x(t[n]))), float(v.corner_y)], atol=1e-9)
    excess = float(best.cost) - float(at.cost)
    assert 0.0 < excess <= up.excess < 1.03 * excess  # the bracket and its tightness (D / excess = 1.009, pinned)
    assert box_violation(problem, at) <= 1e-12  # rounding of the knots only


# --- the property: the rule never rejects a right pair --------------------------------------------

@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.4, 1.0), st.sampled_from([12, 24, 48]))
@example(229, 0.609375, 24)  # the former bracket's counterexample (ratio 1.2535)
@example(980978, 0.627, 24)  # ratio 1.377 under the former bracket
@example(27559, 0.723, 48)  # ratio 2.08 under the former bracket
def test_a_certified_pmp_and_an_optimal_zoh_qp_agree(seed: int, frac: float, N: int) -> None:
    bracket_property(seed, frac, N, "zoh")


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), st.floats(0.4, 1.0), st.sampled_from([12, 24, 48]))
def test_a_certified_pmp_and_an_optimal_zoh_qp_agree_many(seed: int, frac: float, N: int) -> None:
    bracket_property(seed, frac, N, "zoh")


# --- the rule catches a wrong PMP -----------------------------------------------------------------

@pytest.mark.parametrize("factor", [1 - 1e-2, 1 + 1e-2])
def test_a_wrong_pmp_cost_is_caught(factor: float) -> None:
    """The PMP run's cost 1 % off its plan's energy: B5' fails (the pair compared costs that are
    not its plans')."""
    pmp, qp = run_pair(bounded(229, 0.609375), 24, "zoh")
    assert compare_bounded_pmp_qp(pmp.result.problem, pmp, qp)["verdict"] == "agree"
    wrong = copy.copy(pmp)
    wrong.result = with_cost(pmp.result, factor)
    pair = compare_bounded_pmp_qp(pmp.result.problem, wrong, qp)
    assert pair["verdict"] == "disagree"
    assert pair["checks"]["pmp_cost_is_input_energy"]["ok"] is False


@pytest.mark.parametrize(("factor", "N", "caught_by"), [
    (1 - 1e-2, 24, "bounded_zoh_excess_rel"),  # too low: J_QP > J_b + D (the upper side)
    (1 - 1e-2, 48, "bounded_zoh_excess_rel"),
    (1 + 1e-2, 48, "bounded_lower_bound_rel"),  # too high: J_b > J_QP (excess 0.4 % at N = 48)
])
def test_the_bracket_catches_a_wrong_cost_at_the_contact_times(monkeypatch: pytest.MonkeyPatch, factor: float,
                                                                N: int, caught_by: str) -> None:
    """The bounded PMP re-solved at the QP's contact times reports its cost 1 % off: the bracket
    itself fails (besides B5').  Its resolution is D on the low side (D - excess = 4e-4 of J at
    N = 24) and the excess on the high side (2 % of J at N = 24, 0.4 % at N = 48), so a 1 %
    overstatement is caught from N = 48 on by the bracket (and at every N by B5')."""
    problem = bounded(229, 0.609375)
    pmp, qp = run_pair(problem, N, "zoh")
    wrong = WrongAtContactTimes()
    wrong.factor = factor
    monkeypatch.setattr(bounded_pair, "PMPPlanner", lambda: wrong)
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    assert pair["verdict"] == "disagree"
    assert pair["checks"][caught_by]["ok"] is False
    assert pair["checks"]["pmp_at_contact_times_cost_is_input_energy"]["ok"] is False


def test_a_pmp_plan_outside_the_box_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """A re-solve that did not impose the box (widened 10 %): cheaper, its cost its input's
    energy, so B4, B5' and the bracket's upper side (a plan of the QP exists) all pass; the
    premise check on its input catches it."""
    problem = bounded(229, 0.609375)
    pmp, qp = run_pair(problem, 24, "zoh")
    wrong = WrongAtContactTimes()
    wrong.widen = 1.1
    monkeypatch.setattr(bounded_pair, "PMPPlanner", lambda: wrong)
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    assert pair["verdict"] == "disagree"
    assert pair["checks"]["pmp_at_contact_times_box_violation_rel"]["ok"] is False
    assert pair["checks"]["bounded_lower_bound_rel"]["ok"] and pair["checks"]["bounded_zoh_excess_rel"]["ok"]


def test_a_pmp_plan_missing_the_corner_is_caught(monkeypatch: pytest.MonkeyPatch) -> None:
    """A re-solve whose plan passes the corner a quarter step late (a plan of another problem):
    its miss of the corner at the QP's contact time is caught."""
    problem = bounded(229, 0.609375)
    pmp, qp = run_pair(problem, 24, "zoh")
    wrong = WrongAtContactTimes()
    wrong.shift = 0.25 * problem.tf / 24
    monkeypatch.setattr(bounded_pair, "PMPPlanner", lambda: wrong)
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    assert pair["verdict"] == "disagree"
    assert pair["checks"]["pmp_at_contact_times_residual_rel"]["ok"] is False
    assert pair["checks"]["pmp_at_contact_times_box_violation_rel"]["ok"]


def test_without_a_plan_of_the_qp_the_upper_side_is_a_note() -> None:
    """``a_total`` at the input box's farthest corner: the friction circle holds the whole box,
    so every plan in the box keeps it (the PMP's too), but the QP imposes the inscribed 16-gon
    (apothem 0.981), which the plan built from the PMP's input leaves where it rides the box's
    corner (at 167.6°, 1.2° from a vertex of the 16-gon, by 0.38 %): that plan is no plan of
    the QP, so the upper side is not applied (a note names the row); the lower side is."""
    base = bounded(229, 0.609375)
    lim = base.limits
    assert lim is not None and lim.ax is not None and lim.ay is not None
    radius = max(float(np.hypot(x, y)) for x in lim.ax for y in lim.ay)
    problem = base.with_limits(PhysicalLimits(ax=lim.ax, ay=lim.ay, a_total=radius))
    pmp, qp = run_pair(problem, 24, "zoh")
    assert pmp.result.status == "optimal" and qp.result.status == "optimal"
    pair = compare_bounded_pmp_qp(problem, pmp, qp)
    reason = pair["bounded"]["zoh_upper_reason"]  # type: ignore[typeddict-item]
    assert isinstance(reason, str) and "a_total" in reason
    assert "bounded_zoh_excess_rel" not in pair["checks"]
    assert any("upper side is not applied" in note for note in pair["notes"])
    assert pair["verdict"] == "agree" and pair["checks"]["bounded_lower_bound_rel"]["ok"]
