"""The bounded PMP with several vehicles beside an edge of the feasible contact times (issue 32 item 4).

Found by tests/test_bounded_random.py: ``random_problem(864097, m=3)`` with the box at 0.744 of
its unbounded plan's peaks ended ``inaccurate`` (Hamiltonian-jump check 0.016 against 1e-7):
L-BFGS-B and the Newton polish stopped ``7e-7 t_f`` below the upper edge of ``t_0``'s feasible
times (their central differences, ``1e-6 t_f`` wide, cross it) with ``J_b`` still falling
along ``t_2``.  :func:`~iamp.planners.pmp.bounded._edge_polish` holds ``t_0`` at the edge (here
``J_b`` turns ``5e-8 t_f`` inside it: Brent's root of ``r_0``) while the Newton polish moves
the others; the plan is a stationary local minimum, checked against the bounded FOH QP through
its contact times and against ``J_b`` at feasible contact times around it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from test_bounded_property import at_the_edge_problem
from test_bounded_random import boxed, check

from iamp.core import status as stc
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import TOLERANCES
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp import bounded as B

SEED, SCALE = 864097, 0.7439556619624459


def test_three_vehicles_beside_an_edge_are_a_verified_local_minimum() -> None:
    """``local`` (was ``inaccurate``), stationary in every contact time, ``t_0`` held at the upper
    edge of its feasible times (``t_0 + EDGE_PROBE t_f`` admits no plan), the FOH QP through the
    contact times at or above the cost and within 2e-3 (:func:`check`), and no feasible contact
    times within ``1e-7 .. 1e-3 t_f`` of the plan's have a lower ``J_b``."""
    assert check(SEED, 3, SCALE).startswith("local/")
    problem = boxed(SEED, 3, SCALE)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None
    checks = pmp.diagnostics.checks
    assert checks is not None and checks["hamiltonian_jump"]["ok"]
    search = pmp.info["search"]
    assert search["edge_polish"]["held"] == [{"vehicle": 0, "side": "upper"}]
    assert "feasibility_edges" not in search  # stationary: the jump condition applied to all three
    T = float(problem.tf)
    t = np.array(pmp.contact_times, dtype=float)
    ev = B._Evaluator(problem)
    J0 = ev(t)[0]
    assert abs(J0 - pmp.cost) <= 1e-9 * pmp.cost
    beyond = t.copy()
    beyond[0] += B.EDGE_PROBE * T
    assert not math.isfinite(ev(beyond)[0])
    rng = np.random.default_rng(0)
    feasible = 0
    for h in (1e-7, 1e-5, 1e-3):
        for _ in range(12):
            d = rng.normal(size=3)
            J = ev(t + h * T * d / np.linalg.norm(d))[0]
            if math.isfinite(J):
                feasible += 1
                assert J >= J0 - 1e-9 * J0, (h, J, J0)
    assert feasible >= 12


def test_the_edge_is_skipped_only_where_the_slope_points_out() -> None:
    """The jump condition is dropped only for a time at an edge whose slope points out of the
    feasible set: on 864097, ``t_0`` moved to its edge has ``r_0 > 0`` (``J_b`` rises towards the
    upper edge), so :func:`_kkt_at_edges` refuses it; and dropping ``t_0`` does not hide the
    other times' residual at the point where the search used to stop (``r_2 = -1.1``)."""
    problem = boxed(SEED, 3, SCALE)
    assert problem is not None
    T = float(problem.tf)
    ev = B._Evaluator(problem)
    stopped = np.array([5.93277429, 0.93588727, 3.14842788])  # the search's end before the edge polish
    assert math.isfinite(ev(stopped)[0])
    seated = B._seat_at_edge(ev, stopped, 0, 1.0, T)
    assert seated is not None
    sol = B.solve_bounded_fixed(problem, seated, ev.warm_for(seated))
    assert sol.hamiltonian_jump_residual()[0] > 0
    assert not B._kkt_at_edges(ev, sol, {0: 1.0}, T)
    at_stop = B.solve_bounded_fixed(problem, stopped, ev.warm_for(stopped))
    tol = TOLERANCES["pmp_hjump_rel"]
    assert B.check_values(at_stop, at_edge=[0])["hamiltonian_jump"] > tol
    assert B.check_values(at_stop, at_edge=[0, 1, 2])["hamiltonian_jump"] == 0.0


def test_a_minimum_at_an_edge_meets_the_kkt_sign() -> None:
    """A minimum *at* an edge (tests/test_bounded_property.py: ``J_b`` rises from the lower edge of
    the feasible contact times, ``r = +0.81``): :func:`_kkt_at_edges` accepts it as a lower edge and
    refuses it as an upper one."""
    problem = at_the_edge_problem()
    pmp = PMPPlanner(certify_bounded=False).plan(problem)
    assert pmp.info["search"]["feasibility_edge"] == "lower"
    ev = B._Evaluator(problem)
    sol = B.solve_bounded_fixed(problem, np.array(pmp.contact_times), None)
    T = float(problem.tf)
    assert B._kkt_at_edges(ev, sol, {0: -1.0}, T)
    assert not B._kkt_at_edges(ev, sol, {0: 1.0}, T)


def test_three_vehicles_with_an_infeasible_unbounded_start_find_a_plan() -> None:
    """Found by test_bounded_random (2026-11-29): random_problem(498873, m=3) under a box at 0.833
    of its peaks was ``infeasible`` (not certified: the certificate's 4000 solves closed nothing;
    the search had evaluated only the unbounded ``t*``) while the FOH QP at ``N = 8`` plans at
    654.78.  Now the contact times feasible for each vehicle alone give a product grid with
    feasible points (:func:`_feasible_start`): ``local``, and the FOH QP through its contact
    times agrees (:func:`check`)."""
    assert check(498873, 3, 0.8334472240975609).startswith("local/")
    problem = boxed(498873, 3, 0.8334472240975609)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None and pmp.cost <= 654.7827711418674
    # the product of the times feasible for each vehicle alone holds feasible points (since the
    # sharper Lipschitz rate of the cover, the cover itself meets a feasible centre first)
    found: dict[str, Any] = {}
    start = B._feasible_start(B._Evaluator(problem), found)
    assert start is not None and found["feasible_start"]["feasible"] > 0
    assert math.isfinite(B._Evaluator(problem)(start)[0])


def test_a_time_held_at_an_edge_is_released_once_j_b_falls_away_from_it() -> None:
    """Found by 400 generated three-vehicle problems with the box at 0.55-0.90 of the peaks
    (2026-11-29): random_problem(217970, m=3) at 0.7252 was ``inaccurate`` (Hamiltonian-jump check
    0.99).  At the search's end ``J_b`` fell along ``t_1`` towards its upper edge (``r_1 = -5e3``),
    so the edge polish held ``t_1`` there; once the polish had moved ``t_2`` (3.64 -> 3.19),
    ``J_b`` rose towards that edge instead (``r_1`` from ``+2e3`` at ``1e-3 t_f`` inside to
    ``+1.5e7`` at ``1e-10 t_f``), but ``t_1`` stayed held at 2551.05.  A held time whose slope
    points into the feasible set, at the edge and ``EDGE_PROBE t_f`` inside, is now released
    and the Newton polish moves every time: ``local`` at 2489.03, stationary.  The FOH QP at N = 8
    has no plan (the feasible times are a sliver); at N = 240 through the plan's contact times it
    does, at or above the cost and within 2e-3, and no feasible contact times ``1e-5 .. 1e-3 t_f``
    from the plan's have a lower ``J_b``."""

    seed, scale = 217970, 0.7252116774550526
    assert check(seed, 3, scale).startswith("local/")
    problem = boxed(seed, 3, scale)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None, pmp.info.get("failed_check")
    assert pmp.info["checks"]["hamiltonian_jump"]["ok"]
    assert pmp.cost < 2551.0538401148037 * (1 - 1e-3)  # below the former held stop
    _a_verified_local_minimum(problem, pmp, (-1e-3, -1e-4, -1e-5, 1e-5, 1e-4, 1e-3), 9)


def _a_verified_local_minimum(problem: Problem, pmp: Plan, steps: tuple[float, ...], n_feasible: int,
                              qp_steps: tuple[int, ...] = (240,), qp_within: float = 2e-3) -> list[float]:
    """The FOH QP at ``N`` of ``qp_steps`` through the plan's contact times has a plan at or above
    its cost and within ``qp_within``, and no feasible contact times ``steps`` (times ``t_f``) from
    the plan's along each axis have a lower ``J_b`` (at least ``n_feasible`` of them feasible).
    Returns the QP's relative excess per ``N``."""
    from iamp.planners.qp.bounded import BoundedQP

    assert pmp.cost is not None
    t = np.array(pmp.contact_times, dtype=float)
    gaps = []
    for n in qp_steps:
        at = BoundedQP(problem, n, "foh", "clarabel").solve_times(t)
        assert at.status == stc.OPTIMAL and at.cost is not None, (n, at.status)
        assert pmp.cost * (1 - 1e-9) <= at.cost <= pmp.cost * (1 + qp_within), (n, at.cost, pmp.cost)
        gaps.append((at.cost - pmp.cost) / pmp.cost)
    T = float(problem.tf)
    ev = B._Evaluator(problem)
    feasible = 0
    for i in range(t.size):
        for d in steps:
            z = t.copy()
            z[i] += d * T
            J = ev(z)[0]
            feasible += math.isfinite(J)
            assert not J < pmp.cost * (1 - 1e-9), (i, d, J)
    assert feasible >= n_feasible
    return gaps


def test_a_time_at_an_edge_j_b_rises_towards_is_held_where_r_turns() -> None:
    """Of the 400 generated three-vehicle problems (box at 0.55-0.90 of the peaks) that ended
    ``inaccurate``: random_problem(148435, m=3) at 0.7157 (Hamiltonian-jump check 0.54; ``r`` =
    (4334, -210, -29) at the search's end).  ``t_0`` sat within ``1e-8 t_f`` of its upper edge with
    ``J_b`` rising towards it, and ``r_0`` turns ``1e-7 .. 1e-6 t_f`` inside; the edge polish
    looked for an edge only along the descent.  It now also holds a time at an edge on the other
    side (Brent's root of ``r_0`` inside it, or the edge itself): ``local`` at 1551.93, checked as
    the three-vehicle plan above."""

    problem = boxed(148435, 3, 0.7157)
    assert problem is not None
    assert check(148435, 3, 0.7157).startswith("local/")
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None, pmp.info.get("failed_check")
    assert pmp.info["checks"]["hamiltonian_jump"]["ok"]
    assert pmp.info["search"]["edge_polish"]["held"][0]["vehicle"] == 0
    _a_verified_local_minimum(problem, pmp, (-1e-3, -1e-4, -1e-5, -1e-6, 1e-6, 1e-5, 1e-4, 1e-3), 12)



def stationary_by_sign_at_the_edge(seed: int, scale: float):  # type: ignore[no-untyped-def]
    """The bounded PMP on ``boxed(seed, 3, scale)``: ``local``, ``t_0`` held at its feasibility
    edge and ``t_1`` stationary by the sign of ``r_1`` (``search.edge_polish.stationary_by_sign``);
    the signs of the plan's own residual ``r_1``, solved cold at the bracket's ends, are checked
    here (negative before, positive after).  Returns the problem, the plan, the bracket and the
    two residuals."""
    problem = boxed(seed, 3, scale)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None, pmp.info.get("failed_check")
    search = pmp.info["search"]
    assert [e["vehicle"] for e in search["feasibility_edges"]] == [0]
    (by_sign,) = search["edge_polish"]["stationary_by_sign"]
    assert by_sign["vehicle"] == 1
    T = float(problem.tf)
    t = np.array(pmp.contact_times, dtype=float)
    signs = []
    for d in (-by_sign["delta"], by_sign["delta"]):  # the plan's own residual, solved cold
        z = t.copy()
        z[1] += d * T
        signs.append(float(B.solve_bounded_fixed(problem, z).hamiltonian_jump_residual()[1]))
    assert signs[0] < 0 < signs[1], signs
    return problem, pmp, by_sign, signs

def test_a_time_held_where_r_turns_is_stationary_by_the_sign_of_r() -> None:
    """random_problem(539214, m=3) at 0.7162, found with 217970 and 148435, ended ``inaccurate``
    (Hamiltonian-jump check 0.99, then 1.5e-3 after the edge polish).  Its feasible contact
    times are a sliver: ``t_0`` admits a plan only within ``1e-7 t_f`` below an upper edge, ``t_1``
    below an edge that moves with ``t_0``.  The edge polish holds ``t_0`` at its edge (``J_b``
    falls out of the set: KKT) and ``t_1`` where ``r_1`` turns ``1e-8 t_f`` inside its edge; there
    ``r_1`` moves ``2.3e11 t_f`` per unit time while its rounding (warm against cold solves) is
    about 2, so no float time meets the check's ``1e-7`` of its terms (21.6).  The claim is now
    made by the sign of ``r_1`` (:func:`_stationary_brackets`): negative ``1e-11 t_f`` before,
    positive after, so a zero lies within that bracket.  ``local`` at 7118.2475.

    Checked independently: ``r_1`` from the plan's own solution (``H⁻ − H⁺ − ẋ_s Φ_x``, not the
    search's ``Σ Φ (v − ċ)``) solved cold at the bracket's ends has the same signs; the FOH QP
    through the contact times (at ``N = 240`` Clarabel does not converge on the sliver) is at or
    above the cost, within 2e-4 at ``N = 480`` and nearer at ``N = 960``; no feasible contact times
    along the axes or in random directions ``1e-8 .. 1e-3 t_f`` away have a lower ``J_b``."""
    seed, scale = 539214, 0.7162
    assert check(seed, 3, scale).startswith("local/")
    problem, pmp, by_sign, signs = stationary_by_sign_at_the_edge(seed, scale)
    assert pmp.info["checks"]["hamiltonian_jump"]["ok"]
    T = float(problem.tf)
    t = np.array(pmp.contact_times, dtype=float)
    assert by_sign["delta"] * T * max(abs(x) for x in signs) <= 1e-9 * pmp.cost
    beyond = t.copy()
    beyond[0] += B.EDGE_PROBE * T
    assert not math.isfinite(B._Evaluator(problem)(beyond)[0])  # t_0 at its edge
    gaps = _a_verified_local_minimum(problem, pmp, (-1e-3, -1e-5, -1e-7, -1e-8, 1e-8, 1e-7, 1e-5, 1e-3), 12,
                                     qp_steps=(480, 960), qp_within=2e-4)
    assert gaps[1] < gaps[0]  # the grid's excess falls as N grows
    ev = B._Evaluator(problem)
    rng = np.random.default_rng(1)
    feasible = 0
    for h in (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3):
        for _ in range(20):
            d = rng.normal(size=3)
            J = ev(t + h * T * d / np.linalg.norm(d))[0]
            if math.isfinite(J):
                feasible += 1
                assert J >= pmp.cost * (1 - 1e-9), (h, J, pmp.cost)
    assert feasible >= 12
