"""Three vehicles the bounded PMP used to call ``infeasible`` without a certificate (issue 32 item 4).

Drawn as ``random_problem(seed, m=3)`` with the box at 0.40-1.20 of the unbounded plan's peaks
(``numpy.random.default_rng(1)``: 246 problems, 23 of them ``infeasible`` uncertified, the FOH QP
at ``N = 8`` without a plan on every one).  Now:

* the cover's Lipschitz rate is read on each box (:func:`~iamp.planners.pmp.bounded._box_rate`:
  ``max |ċ_i − v_0 − q τ|``, ``q ∈ {ℓ, h}``, over the box's times, instead of
  ``max|ċ_i| + |v_0| + max(|ℓ|, |h|) t_f`` over all of them), so boxes close sooner: two of the
  23 are certified by a single vehicle;
* the pairs' covers go on past feasible centres and prune the full cover
  (:func:`~iamp.planners.pmp.bounded.pair_projection`; a pair whose cover met no feasible
  centre resumed once): 9 certified by a pair, and the pruned full cover meets feasible contact
  times on 9 — those problems have plans (the FOH QP at ``N = 240`` through the plan's contact
  times agrees), the PMP was wrong to say ``infeasible``;
* 3 stay uncertified (a budget of 34 000 solves; 758025 at 0.595 has a plan too).

References: the rate is checked against the Farkas margin recomputed by quadrature at moved
contact times with the same multipliers; certified boxes against solves at points inside them;
found plans against the FOH QP (a restriction of the continuous problem).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from test_bounded_random import boxed, check
from test_pmp_bounded_multi_edge import _a_verified_local_minimum, stationary_by_sign_at_the_edge

from iamp.api import plan
from iamp.comparison.bench.limits import bounded_pmp_problems
from iamp.core import status as stc
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp import bounded as B
from iamp.planners.qp.bounded import BoundedQP


def _margin(lam: list[float], t: list[float], T: float, axis: tuple[float, ...], corners: list[float]) -> float:
    """The Farkas margin ``λᵀd(t) − ∫ max(h w, ℓ w)`` in physical units, by quadrature
    (``w = Σ λ_i (t_i − τ)_+ + λ_v (T − τ) + λ_s T``)."""
    s0, v0, sf, vf, lo, hi = axis
    m = len(t)
    d = [corners[i] - s0 - v0 * t[i] for i in range(m)] + [sf - s0 - v0 * T, (vf - v0) * T]

    def w(tau: float) -> float:
        return sum(lam[i] * max(t[i] - tau, 0.0) for i in range(m)) + lam[m] * (T - tau) + lam[m + 1] * T

    cuts = sorted({0.0, T, *t})
    sigma = sum(quad(lambda tau: max(hi * w(tau), lo * w(tau)), a, b, limit=200, epsabs=1e-12)[0]
                for a, b in zip(cuts, cuts[1:]))
    return sum(x * y for x, y in zip(lam, d)) - sigma


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), scale=st.floats(0.4, 0.9), m=st.sampled_from([1, 2, 3]),
       u=st.lists(st.floats(0.02, 0.98), min_size=6, max_size=6), width=st.floats(1e-3, 0.2))
def test_the_box_rate_bounds_the_margin_at_moved_contact_times(seed: int, scale: float, m: int, u: list[float],
                                                                width: float) -> None:
    """``|M(t') − M(t)| ≤ Σ |t'_i − t_i| |λ_i| L_i`` for ``t'`` in the box ``[a, b]`` around the
    centre ``t`` (``L_i`` of :func:`_box_rate` on ``[a_i, b_i]``), with ``M`` by quadrature and the
    multipliers of the cover's Farkas certificate at ``t``; and ``L_i`` is the largest
    ``|ċ_i − v_0 − q τ|`` on a fine sampling of the box."""
    problem = boxed(seed, m, scale)
    if problem is None:
        return
    T = float(problem.tf)
    ego = problem.ego
    (lx, hx), (ly, hy) = B.input_box(problem)
    axes = ((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx), (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))
    t = [T * x for x in u[:m]]
    if len(set(t)) < m:
        return
    a = [max(0.0, x - width * T) for x in t]
    b = [min(T, x + width * T) for x in t]
    t = [0.5 * (p + q) for p, q in zip(a, b)]
    pos = [[float(c) for c in np.asarray(v.x_poly, dtype=float)] for v in problem.vehicles]
    ders = [B._derivative(c) for c in pos]
    off = [(float(v.offset_x), float(v.corner_y)) for v in problem.vehicles]

    def corners(times: list[float], k: int) -> list[float]:
        return [B._polyval(pos[i], times[i]) + off[i][0] if k == 0 else off[i][1] for i in range(m)]

    rng = np.random.default_rng(seed)
    for k in range(2):
        # the axis solve's Farkas certificate (the cover's kernel repeats it operation for
        # operation and keeps the ramps' multipliers): all its multipliers, for M by quadrature
        try:
            B.solve_axis(t, T, *axes[k][:4], corners(t, k), axes[k][4], axes[k][5])
            continue
        except B.AxisInfeasible as exc:
            if exc.lam_phys is None or exc.margin_phys is None:
                continue
            lam = list(exc.lam_phys[:m]) + [exc.lam_phys[m], exc.lam_phys[m + 1] / T]
            margin = exc.margin_phys
        except B.AxisNoConvergence:
            continue
        M0 = _margin(lam, t, T, axes[k], corners(t, k))
        assert abs(M0 - margin) <= 1e-6 * max(1.0, abs(margin)), (M0, margin)
        L = [B._box_rate(ders[i] if k == 0 else [0.0], axes[k], a[i], b[i]) for i in range(m)]
        for i in range(m):  # L_i against a sampling of its definition
            c = ders[i] if k == 0 else [0.0]
            grid = np.linspace(a[i], b[i], 2001)
            cdot = np.polynomial.polynomial.polyval(grid, c)
            sampled = max(float(np.max(np.abs(cdot - axes[k][1] - q * grid))) for q in (axes[k][4], axes[k][5]))
            assert sampled <= L[i] <= sampled * (1 + 1e-6) + 1e-9
        for _ in range(4):
            moved = [p + (q - p) * float(x) for p, q, x in zip(a, b, rng.uniform(size=m))]
            if len(set(moved)) < m:
                continue
            M1 = _margin(lam, moved, T, axes[k], corners(moved, k))
            bound = sum(abs(x - y) * abs(lam[i]) * L[i] for i, (x, y) in enumerate(zip(moved, t)))
            assert abs(M1 - M0) <= bound * (1 + 1e-6) + 1e-7 * max(1.0, abs(M0)), (M1, M0, bound)


def test_three_vehicles_said_infeasible_have_a_plan() -> None:
    """random_problem(493571, m=3) at 0.628 was ``infeasible`` (not certified; the FOH QP's sweep
    at ``N = 8`` has no plan either): the feasible contact times are slivers that neither the
    cover's centres nor the product of each vehicle's feasible times met.  The full cover pruned
    by the pairs' certified boxes meets one; the search from it plans ``local`` at 3192.0155.
    The FOH QP at ``N = 240`` through the plan's contact times has a plan at or above the cost
    and within 2e-3 (:func:`check`), so a plan exists."""
    seed, scale = 493571, 0.6283721830284628
    assert check(seed, 3, scale) == f"{stc.LOCAL}/{stc.INFEASIBLE}"
    problem = boxed(seed, 3, scale)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.LOCAL and pmp.cost is not None
    at = BoundedQP(problem, 240, "foh", "clarabel").solve_times(np.array(pmp.contact_times, dtype=float))
    assert at.status == stc.OPTIMAL and at.cost is not None
    assert pmp.cost * (1 - 1e-9) <= at.cost <= pmp.cost * (1 + 2e-3)
    # the pair projection cannot certify a problem with a plan, and it found the start
    proof = B.pair_projection(problem, B.PAIR_SOLVES)
    assert not proof.certified and proof.feasible_t is not None
    assert math.isfinite(B._Evaluator(problem)(proof.feasible_t)[0])


def test_a_plan_found_in_a_sliver_is_stationary_by_the_sign_of_r() -> None:
    """random_problem(58781, m=3) at 0.659 (drawn by ``default_rng(2)``) was ``infeasible``
    uncertified; the pruned cover meets feasible contact times, and the edge polish holds ``t_0``
    at its upper edge (``J_b`` falls out of the set) while ``t_1`` is polished to ``|r_1|`` 2e-5,
    the rounding of ``r_1`` there (its terms 3.96): stationary by the sign of ``r_1`` (negative
    ``1e-11 t_f`` before, positive after, both beyond that rounding).  ``local`` at 1977.2755;
    the FOH QP through its contact times +1.5e-7 at ``N = 480``, +3.3e-8 at ``N = 960`` (Clarabel
    ``inaccurate`` at 240), no lower ``J_b`` at feasible neighbours along the axes."""
    seed, scale = 58781, 0.6585968705314464
    problem, pmp, _, _ = stationary_by_sign_at_the_edge(seed, scale)
    gaps = _a_verified_local_minimum(problem, pmp, (-1e-3, -1e-5, -1e-7, 1e-7, 1e-5, 1e-3), 10,
                                     qp_steps=(480, 960), qp_within=2e-4)
    assert gaps[1] < gaps[0]


def test_a_pair_cover_certifies_only_infeasible_boxes() -> None:
    """random_problem(311071, m=3) at 0.606 (was ``infeasible`` uncertified) is now certified by
    vehicles 0 and 2.  Every box the pair's cover certified admits no plan at sampled contact
    times inside it (solved directly), the pair's FOH QP sweep finds no plan, and neither does
    the QP through sampled pair contact times."""
    seed, scale = 311071, 0.6062424951973893
    problem = boxed(seed, 3, scale)
    assert problem is not None
    pmp = PMPPlanner().plan(problem)
    assert pmp.status == stc.INFEASIBLE and pmp.info["failed_check"] == "box_infeasible_at_every_contact_time"
    assert pmp.info["search"]["infeasibility_vehicles"] == [0, 2]
    pair = problem.with_vehicles([problem.vehicles[0], problem.vehicles[2]])
    tree: dict[tuple[float, ...], tuple[object, ...]] = {}
    cert = B._cover_infeasible(pair, B.PAIR_TREE_SOLVES, tree)
    assert cert.certified
    rng = np.random.default_rng(0)
    boxes = [k for k, v in tree.items() if v[0] == "c"]
    T = float(problem.tf)
    edges = [T * j / 8 for j in range(9)]
    for key in [boxes[int(i)] for i in rng.choice(len(boxes), size=40, replace=False)]:
        a, b = np.array(key[:2]), np.array(key[2:])
        assert B._tree_covers(tree, edges, (a[0], a[1]), (b[0], b[1]))
        for x in rng.uniform(size=(3, 2)):
            t = a + (b - a) * x
            if abs(t[0] - t[1]) < 1e-9 * T:
                continue
            try:
                B.solve_bounded_fixed(pair, t)
            except B.AxisInfeasible:
                continue
            raise AssertionError(f"a plan at {t} in the certified box {key}")
    assert plan(pair, "qp", solver="clarabel", steps=16).status not in (stc.OPTIMAL, stc.LOCAL)
    qp = BoundedQP(pair, 60, "foh", "clarabel")
    for t in rng.uniform(0.02 * T, 0.98 * T, size=(8, 2)):
        assert qp.solve_times(t).status not in (stc.OPTIMAL, stc.LOCAL)


def test_the_tree_lookup_needs_every_piece_certified() -> None:
    """:func:`_tree_covers` on a hand-made tree: a rectangle across a halving is covered only when
    both halves are certified, and an open or unreached box covers nothing."""
    edges = [0.0, 1.0, 2.0]
    tree: dict[tuple[float, ...], tuple[object, ...]] = {
        (0.0, 0.0, 1.0, 1.0): ("s", 0, 0.5), (0.0, 0.0, 0.5, 1.0): ("c",), (0.5, 0.0, 1.0, 1.0): ("o",),
        (1.0, 0.0, 2.0, 1.0): ("c",), (0.0, 1.0, 1.0, 2.0): ("c",)}
    assert B._tree_covers(tree, edges, (0.1, 0.1), (0.4, 0.9))
    assert not B._tree_covers(tree, edges, (0.4, 0.1), (0.6, 0.9))  # into the open half
    assert B._tree_covers(tree, edges, (1.2, 0.2), (1.8, 0.8))
    assert B._tree_covers(tree, edges, (0.2, 0.5), (0.5, 1.5))  # across two first-grid cells
    assert not B._tree_covers(tree, edges, (1.5, 0.5), (1.8, 1.5))  # (1, 1)-(2, 2) never reached
    tree[(0.5, 0.0, 1.0, 1.0)] = ("c",)
    assert B._tree_covers(tree, edges, (0.0, 0.0), (1.0, 1.0))


def test_the_pairs_certify_nothing_where_the_bench_has_a_plan() -> None:
    problem = bounded_pmp_problems()["bounded_pmp_three_vehicles_feasible"]
    proof = B.pair_projection(problem, B.PAIR_SOLVES)
    assert not proof.certified


def test_a_stopped_cover_resumes_where_it_stopped() -> None:
    """A pair's cover stopped by its budget leaves boxes undecided (:func:`_frontier`); they and
    the boxes it decided (certified or open) tile ``(0, t_f)²`` without overlap (areas sum to
    ``t_f²``, no undecided box meets a decided one's interior), and covering them finishes the
    cover: random_problem(903871, m=3) at 0.610, vehicles 0 and 2, certified in two runs of 6000
    solves (one of 6000 does not close), while every certified box admits no plan at sampled
    contact times inside it."""
    problem = boxed(903871, 3, 0.6098506723534796)
    assert problem is not None
    pair = problem.with_vehicles([problem.vehicles[0], problem.vehicles[2]])
    T = float(problem.tf)
    tree: dict[tuple[float, ...], tuple[object, ...]] = {}
    first = B._cover_infeasible(pair, 6000, tree)
    assert not first.certified and first.feasible_t is None
    edges = [T * j / 8 for j in range(9)]
    grid = [(np.array([edges[i], edges[j]]), np.array([edges[i + 1], edges[j + 1]]))
            for i in range(8) for j in range(8)]
    undecided = B._frontier(tree, grid)
    decided = [(np.array(k[:2]), np.array(k[2:])) for k, v in tree.items() if v[0] in ("c", "o")]
    area = sum(float(np.prod(b - a)) for a, b in undecided + decided)
    assert abs(area - T * T) <= 1e-12 * T * T
    rng = np.random.default_rng(2)
    for a, b in [undecided[int(i)] for i in rng.choice(len(undecided), size=30, replace=False)]:
        centre = 0.5 * (a + b)
        assert not any(np.all(p < centre) and np.all(centre < q) for p, q in decided)
    second = B._cover_infeasible(pair, 6000, tree)
    assert second.certified
    for key in [k for k, v in tree.items() if v[0] == "c"][::97]:
        a, b = np.array(key[:2]), np.array(key[2:])
        t = a + (b - a) * rng.uniform(size=2)
        if abs(t[0] - t[1]) > 1e-9 * T:
            try:
                B.solve_bounded_fixed(pair, t)
                raise AssertionError(f"a plan at {t} in the certified box {key}")
            except B.AxisInfeasible:
                pass
