r"""The verdict on a ``pmp`` / QP pair of a problem with physical limits (SPEC §14).

With ``problem.limits`` the PMP is the bounded PMP (:mod:`iamp.planners.pmp.bounded`: the
input box ``ax``/``ay`` imposed exactly, every other bound checked on its plan) and the QP is
the bounded QP (:mod:`iamp.planners.qp.bounded`, every bound at every node).  The rules of
:mod:`iamp.comparison.agreement.pmp_qp` rest on the FOH QP being *exact* and on closed forms that
hold without bounds; here the references are the bounded PMP's:

B0. *Same problem*: the fingerprints (which include the limits) are equal.

B1. *Status*.  Both verified (PMP ``optimal`` or ``local``, QP ``optimal``): rules B2–B6.  Both
    ``infeasible``: **agree** — the PMP certifies that no contact time admits a plan within the
    box and the QP that no grid candidate does (every QP plan is a plan within the box, so the
    first implies the second).  A QP plan where the PMP certifies the box infeasible is a
    contradiction (**disagree**).

    A verified PMP plan (``optimal`` or ``local``) beside a QP ``infeasible`` is decided from the
    data (:func:`grid_plan_from_pmp`).  The QP's grid is a restriction of the continuous problem
    (contact times on nodes, every bound at every node; every QP plan is a continuous plan, B4),
    so it can have no plan where the continuous problem has one: a property of the grid, not a
    contradiction.  Over the contact-node candidates nearest the PMP's contact times (per
    vehicle the interior nodes by distance, the ``2^m`` bracketing ones first, at most
    :data:`B1_MAX_CANDIDATES`: every node of a one-vehicle grid up to ``N = 65``) the bounded
    PMP is re-solved with its contacts at the node times, and :func:`upper_plan` (rule B6's
    construction) builds a plan of the QP from it and checks it against the QP's rows: the
    equalities (boundary, dynamics, corners) to ``cmp_residual_rel_*``, every limit row at every
    node to ``limits_bound_rel``.

    (a) Such a plan exists: the QP's ``infeasible`` is wrong, **disagree**; the reason
        (``qp_infeasible_not_contradicted``) names the QP's claim, the contact nodes and the
        plan's residuals and cost.
    (b) None exists: the pair is **not comparable** — no optimum is compared.  The verdict set is
        ``agree`` / ``disagree`` (SPEC §5b shows no other value and ``iamp compare`` counts every
        verdict but ``agree`` as a disagreement), so the verdict is ``agree`` in the sense of the
        both-``infeasible`` case: the two claims are consistent.  ``verdict_basis`` begins
        ``not comparable (rule B1)``; ``notes`` give the QP's reason, the PMP's plan, and per
        candidate why it holds no plan: the bounded PMP certifies the input box infeasible at its
        node times (Farkas; then no QP plan has its contacts there), two vehicles share a node
        where their corners differ (the ego's position there is one point), or the built plan
        violates a row — the largest violation, its row and node (when the correction in the box
        does not close the equalities, the input bound that the correction without the box leaves
        furthest).  When every candidate of the grid is certified to hold no plan the QP's claim
        is *proved*; otherwise it is *not contradicted* (the construction is sufficient, not
        necessary).  ``grid_feasibility`` in the JSON holds the counts, the worst violation and
        whether it is proved.  Measured (``random_problem`` 12, 40, 53, 73, 84 with the box at
        0.6 of their inputs, feasible contact times in an interval of about 0.3 s;
        ZOH and FOH, ``N`` = 4–32): the Clarabel QP is ``infeasible`` with every node certified
        (Farkas) where the PMP is ``optimal`` (``local`` for 84); e.g. 12 at ZOH ``N = 12``:
        one node (``t = 2.28`` s) admits a plan in the box, whose plan of the grid needs ``ax``
        3.2 % beyond its bound at node 4; at ``N = 16`` the QP is ``optimal``.  Until 2026-11-29
        such pairs were **disagree**.

    Any other status (``limits_violated``: the PMP's plan exceeds a bound it cannot impose; a
    solver failure): **disagree**, with the status as the reason.

B2. *KKT* of the QP, recomputed from the stacked matrices ``[A; A_L]`` and the returned
    ``(z, y)``: primal, dual, gap and the limit rows' complementarity below ``cmp_kkt_rel_*``.

B3. *Constraints*: the QP trajectory's boundary and corner residuals below ``cmp_residual_rel_*``.

B4. *Lower bound at the same contact times* (rigorous): every plan of the QP at its contact
    times ``t_Q`` is a plan with inputs in the box (FOH: linear between nodes that lie in the
    box; ZOH: constant), with cost exactly :math:`\tfrac12\int|u|^2`, so
    :math:`J_{QP} \ge J_b(t_Q)`, the bounded PMP re-solved at ``t_Q`` (unique: a strictly convex
    problem), within ``cmp_cost_rel_*``.  A QP plan where the bounded PMP finds the box
    infeasible at ``t_Q`` fails this rule.  Its premise, that the re-solve's plan lies in the
    box, through the corners at ``t_Q`` and between the boundary states, is checked (exactly:
    the input is linear between its knots, :func:`box_violation`, and the states are
    integrated exactly; ``pmp_at_contact_times_box_violation_rel``,
    ``pmp_at_contact_times_residual_rel``).  With B5' it makes the PMP's claim
    :math:`J_b(t_Q)` the energy of a plan of the continuous problem, hence at least its optimum.

B5. *The PMP's global claim*: an ``optimal`` bounded PMP is certified global over the contact
    times, so :math:`J_b(t_Q) \ge J_b^*` within ``cmp_cost_rel_*`` (a ``local`` PMP: a note).

B5'. *The PMP's cost is its plan's*: :math:`J^*` equals :math:`E(u^*) = \tfrac12\int_0^{t_f}|u^*|^2`
    of its own input (exact: the input is linear between its knots, :func:`input_energy`),
    within ``cmp_cost_rel_*``, and so does the re-solve's :math:`J_b(t_Q)`; the rules compare
    costs, so the cost compared must be the plan's.

B6. *Discretisation excess* :math:`\Delta = J_{QP} - J_b(t_Q) \ge 0` (B4 is its lower side),
    for both holds within an a-posteriori two-sided bracket, derived below, not fitted:

    .. math::  J_b(t_Q) \;\le\; J_{QP} \;\le\; J_b(t_Q) + D,\qquad
               D = J_{up} - E(u_b),

    with :math:`u_b` the bounded PMP's input at ``t_Q`` and :math:`J_{up}` the cost of a
    plan of the QP built from it (:func:`upper_plan`).

    *Lower side.*  On a grid ``t_0 < … < t_N`` the QP's rows are the exact solution of
    :math:`\dot s = v,\ \dot v = u` for the hold's input and its cost is exactly
    :math:`\tfrac12\int|u|^2` of that input:

    * ZOH, :math:`u \equiv u_k` on :math:`[t_k, t_{k+1})`: :math:`v_{k+1} = v_k + h_k u_k`,
      :math:`s_{k+1} = s_k + h_k v_k + \tfrac{h_k^2}{2} u_k`, cost
      :math:`\tfrac12\sum_k h_k|u_k|^2`;
    * FOH, :math:`u` linear from :math:`u_k` to :math:`u_{k+1}` on :math:`[t_k, t_{k+1}]`:
      :math:`v_{k+1} = v_k + \tfrac{h_k}{2}(u_k + u_{k+1})`,
      :math:`s_{k+1} = s_k + h_k v_k + \tfrac{h_k^2}{3} u_k + \tfrac{h_k^2}{6} u_{k+1}`, cost
      :math:`\sum_k \tfrac{h_k}{6}(|u_k|^2 + u_k\cdot u_{k+1} + |u_{k+1}|^2)`
      (:math:`\int_0^h (a + (b-a)\sigma/h)^2 d\sigma = h(a^2 + ab + b^2)/3`; the FOH QP's
      ``P``, :class:`~iamp.planners.qp.data.QPData`).

    The QP's input rows hold at the nodes; the input is constant (ZOH) or a convex
    combination of two nodal values (FOH) between them, so it lies in the box ``ax``/``ay``
    at every time.  Every plan of the QP at its contact nodes ``t_Q`` is therefore a
    continuous plan with the contacts at ``t_Q``, the input in the box, the same boundary
    values and the same cost.  The bounded PMP at ``t_Q`` minimises over exactly those
    continuous plans (box only); the QP's other rows (``a_total``'s polygon, ``vx`` and ``y``
    at the nodes, FOH's ``jerk``) only remove plans from the QP, so they tighten this side and
    relax nothing: :math:`J_{QP} \ge J_b(t_Q) \ge J_b^*` (B4, B5) whatever other limits are set.

    *Upper side.*  The QP's optimum is no higher than the cost of any plan it admits at its
    own contact nodes; one is built from :math:`u_b` (:func:`upper_plan`, one construction for
    both holds; only the basis :math:`\varphi_j` differs, :func:`hold_moments`):

    1. the hold's image :math:`\bar u` of :math:`u_b`, exact (``u_b`` is linear between its
       knots: the contact times, which are nodes, and the switching times :math:`\theta`).
       ZOH: interval averages :math:`\bar u_k = h_k^{-1}\int_{t_k}^{t_{k+1}} u_b`, which keep
       every nodal speed.  FOH: nodal values :math:`\bar u_j = u_b(t_j)`, whose interpolant
       equals :math:`u_b` except on the intervals holding a :math:`\theta`, where the error
       :math:`e = \bar u - u_b` is a tent of height :math:`|\Delta_\theta| h\,\alpha(1-\alpha)`
       (:math:`\Delta_\theta` the slope change, :math:`\theta = t_j + \alpha h`).  Both lie in
       the box (averages, resp. values, of a function in a convex set).  Per axis, the final
       speed and the positions at :math:`t_N` and at the contact nodes ``n`` are linear in the
       nodal inputs, :math:`G u = g` with rows :math:`V_N`, :math:`S_N`, :math:`S_n`,
       :math:`V_{nj} = \int_0^{t_n}\varphi_j`,
       :math:`S_{nj} = \int_0^{t_n}(t_n - \tau)\varphi_j(\tau)d\tau`, and the defect
       :math:`g - G\bar u = -\int G e` is :math:`O(h^2)` (ZOH: first moments of
       :math:`u_b - \bar u`; FOH: :math:`O(|\Delta_\theta| h^2)` per switching time).
    2. The minimum-norm correction in the box,

       .. math::  \min_w \tfrac12\sum_j \omega_j w_j^2 \quad\text{s.t.}\quad G w = g - G\bar u,
                  \quad \ell \le \bar u + w \le h_{\mathrm{box}},\qquad \omega_j = \int\varphi_j

       (ZOH :math:`\omega_k = h_k`, the correction's energy; FOH the lumped mass
       :math:`(h_{j-1} + h_j)/2`, within a factor 3 of it), solved through its dual
       (:math:`w_j(\lambda) = \mathrm{clip}((G^\top\lambda)_j/\omega_j)`, a piecewise-linear
       monotone equation :math:`G w(\lambda) = g - G\bar u` in 2 + m unknowns, semismooth
       Newton with a line search on the concave dual, at most :data:`UPPER_MAX_ITERATIONS`
       steps).  The inputs at a bound are pinned first (``w = 0``: the box's multiplier is
       :math:`O(1)` on a saturated arc, so moving one inward costs to first order); only when
       the free inputs cannot close the equalities may they move inward
       (``bounded.<hold>_upper_pinned`` is false).
    3. The plan :math:`u = \bar u + w` with its exact states (:math:`v_0 + Vu`,
       :math:`s_0 + v_0 t + Su`) is checked against the QP's own rows
       (:class:`~iamp.planners.qp.data.QPData` equalities to ``cmp_residual_rel_*``, every
       :func:`~iamp.planners.qp.limits.limit_rows` row to ``limits_bound_rel``): it is a plan
       of the QP, so :math:`J_{QP} \le J_{up} = \tfrac12 u^\top M u`,
       :math:`M_{ij} = \int\varphi_i\varphi_j` (the hold's exact cost above).

    Writing :math:`J_{up} = E(u_b) + D` and :math:`E(u_b) = J_b(t_Q)` (the PMP's cost is its
    input's energy, B5' at ``t_Q``), the two sides give the bracket; both ends are computed
    numbers, so agreement is a proof (to ``cmp_cost_rel_*``), not an estimate.  Its
    resolution is :math:`D`: a claimed :math:`J_b(t_Q)` too low by more than :math:`D - \Delta`
    or too high by more than :math:`\Delta` is caught.  When no plan of the QP can be built
    this way (a row other than the box is violated, e.g. ``a_total``'s polygon, ``vx`` at a
    node, FOH's ``jerk``, or the dual iteration does not close), the upper side is not applied
    and a note names the row; the lower side still applies.

    *How tight.*  ZOH: :math:`D` is the excess of averaging, :math:`\Delta` and :math:`D` both
    :math:`\approx \tfrac{h^2}{24}\int|\dot u_b|^2 =: \Delta_1`; :math:`D/\Delta` = 1.009
    (N = 24) and 1.047 (N = 48) on ``random_problem(229)`` with limits at 0.609 of its inputs,
    where the former fitted bracket :math:`\Delta \in [0.8, 1.25]\,\Delta_1` failed with
    :math:`\Delta/\Delta_1` = 1.2535 (1.377 on ``random_problem(980978)`` at 0.627).  FOH is
    exact away from the switching times; expanding :math:`J_{up}` about :math:`u_b`, with the
    correction on the free set where :math:`u_b` is the (unclipped) costate
    :math:`p = \lambda^\top G(t)`,

    .. math::  D = \int (u_b - p)\,e + \tfrac12\int e^2 + O(h^4)
               \approx K_h,\qquad
               K_h = \sum_\theta \frac{\Delta_\theta^2 h^3}{6}\,\beta(\alpha),\quad
               \beta = \alpha(1-\alpha)^2 \text{ (saturated after } \theta),\
               \alpha^2(1-\alpha) \text{ (before)}

    (:func:`foh_kink_term`; ``½∫e²`` of the tent plus ``∫(u_b − p)e`` on its saturated side,
    where :math:`u_b - p = O(\Delta_\theta h)`, to leading order for switching times far apart
    compared with ``h``; the correction's own cost is :math:`O(h^4)`); the QP, free to move the nodes beside each
    :math:`\theta`, does better, so :math:`\Delta \le D \approx K_h`, and :math:`\Delta = 0`
    to solver precision when no switching time falls inside an interval.  Measured
    (``random_problem`` with the box at 0.4–1.0 of its inputs, ``N`` in 12, 24, 48; 139 pairs
    of a certified PMP and an optimal FOH QP in 300 draws): :math:`D/\Delta` 1.0006–9.4,
    median 1.32 (1.014 and 1.34 on ``random_problem(229)`` at 0.609, ``N`` = 24, 48);
    :math:`D/K_h` 0.31–1.80, :math:`\Delta/K_h` 0.10–1.80; :math:`D - \Delta \ge 8\times10^{-7} J`.
    Until 2026-11-29 the FOH rule was :math:`\Delta \le 2 K_h` (``cmp_bounded_foh_ratio``): a
    leading-order estimate, not a bound, whose resolution on the low side was
    :math:`2K_h - \Delta` (3.1e-3 of J on ``random_problem(229)``, ``N = 24``, against
    :math:`D - \Delta` = 8e-5 of J now); before 2026-11-28
    it was :math:`\Delta \le 0.25\,\Delta_1`, which failed on ``random_problem(229)`` at 0.609
    (:math:`\Delta/\Delta_1` = 0.35 at ``N = 24``, :math:`\Delta/K_h` = 1.30) with the
    bounded PMP right: the FOH QP at that contact time converges to its :math:`J_b` from
    above, 5.4e-1, 4.4e-3, 1.3e-4, 1.2e-6 at ``N`` = 24, 96, 384, 1536.  :math:`\Delta_1`,
    :math:`K_h` and the ratios to them are still reported (``bounded.ratio_to_leading``,
    ``bounded.foh_kink_term``, ``bounded.ratio_to_kink_term``).

The headline gaps (``cost_rel_gap`` etc.) and ``at_same_contact_times`` are those of
:mod:`iamp.comparison.agreement.gaps`, against the bounded PMP.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from iamp.comparison.trajectories import hold_trajectory
from iamp.core import status as st
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.pmp.bounded import input_box, plan_knots
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.qp.data import QPData
from iamp.planners.qp.limits import limit_rows

from .gaps import at_same_contact_times, run_vs_run_gaps
from .records import GridFeasibilityJSON, PairJSON
from .runs import Run
from .signs import sign_entry
from .verdict import Checks, plan_cost, same_problem, solver_tol

__all__ = ["B1_MAX_CANDIDATES", "UPPER_MAX_ITERATIONS", "GridCandidate", "GridSearch", "UpperPlan", "ZohUpper",
           "box_violation", "candidate_nodes", "compare_bounded_pmp_qp", "foh_kink_term", "foh_upper_plan",
           "grid_plan_from_pmp", "hold_moments", "input_energy", "input_slope_energy", "upper_plan",
           "zoh_upper_plan"]

#: Newton steps of the dual of the box-constrained minimum-norm correction (rule B6), per axis and attempt.
UPPER_MAX_ITERATIONS = 200


def input_slope_energy(plan: Plan) -> float:
    r""":math:`\int_0^{t_f}|\dot u|^2\,dt` of a PMP plan (bounded or not): its input is linear
    between the knots (contact and switching times), so the integral is a finite sum."""
    tf = float(plan.problem.tf)
    knots = np.array(sorted({0.0, tf, *(float(t) for t in plan_knots(plan))}))
    U = plan.require_trajectory().inputs(knots)
    dt = np.diff(knots)
    keep = dt > 0
    return float(np.sum(np.sum(np.diff(U, axis=0) ** 2, axis=1)[keep] / dt[keep]))


def _piecewise_linear_input(plan: Plan, extra: npt.NDArray[np.float64] | None = None
                            ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The times ``0, knots, extra, t_f`` (sorted, unique) and the plan's input there: between
    consecutive ones the input is linear."""
    tf = float(plan.problem.tf)
    pts = {0.0, tf, *(float(t) for t in plan_knots(plan) if 0.0 < float(t) < tf)}
    if extra is not None:
        pts.update(float(t) for t in extra)
    knots = np.array(sorted(pts))
    return knots, np.asarray(plan.require_trajectory().inputs(knots), dtype=float)


def input_energy(plan: Plan) -> float:
    r""":math:`E(u) = \tfrac12\int_0^{t_f}|u|^2\,dt` of a PMP plan (bounded or not), exactly: its
    input is linear between its knots, and :math:`\int_0^d (a + (b-a)s/d)^2 ds = d(a^2+ab+b^2)/3`.

    Parameters
    ----------
    plan : Plan
        A PMP plan with a trajectory.

    Returns
    -------
    float
        The energy of the plan's input (its cost, when the plan is right).
    """
    knots, U = _piecewise_linear_input(plan)
    a, b = U[:-1], U[1:]
    return float(0.5 * np.sum(np.diff(knots)[:, None] * (a * a + a * b + b * b)) / 3.0)


def box_violation(problem: Problem, plan: Plan) -> float:
    """The largest excursion of a PMP plan's input outside ``problem``'s input box ``ax``/``ay``,
    relative to ``max(1, |bound|)`` (exact: the input is linear between its knots, so its
    extremes are at knots).

    Parameters
    ----------
    problem : Problem
        Whose ``limits`` give the box (``0`` without one).
    plan : Plan
        A PMP plan with a trajectory.

    Returns
    -------
    float
        ``0`` when the input stays in the box.
    """
    _, U = _piecewise_linear_input(plan)
    worst = 0.0
    for ax, (lo, hi) in enumerate(input_box(problem)):
        u = U[:, ax]
        for bound, over in ((lo, lo - u), (hi, u - hi)):
            if np.isfinite(bound):
                worst = max(worst, float(np.max(over)) / max(1.0, abs(bound)))
    return worst


@dataclass
class UpperPlan:
    """A plan of the ZOH or FOH QP built from a PMP plan (rule B6's upper side,
    :func:`upper_plan`).

    Attributes
    ----------
    hold : {"zoh", "foh"}
        The QP's hold.
    cost : float
        :math:`J_{up} = \\tfrac12\\int|u|^2` of the built plan (its hold's exact cost: ZOH
        :math:`\\tfrac12\\sum_k h_k|u_k|^2`, FOH :math:`\\sum_k \\tfrac{h_k}{6}(u_k^2 + u_k u_{k+1} + u_{k+1}^2)`).
    energy : float
        :math:`E(u_b)` of the PMP plan it was built from (:func:`input_energy`).
    X, U : numpy.ndarray
        Nodal states ``(N+1, 4)`` ``(s_x, v_x, s_y, v_y)`` and inputs (``(N, 2)`` ZOH,
        ``(N+1, 2)`` FOH).
    equality_residual_rel : float
        ``max|A z − b| / max(1, max|b|)`` on the QP's own equality rows at the contact nodes.
    limit_violation_rel : float
        The largest violation of a limit row of the QP, relative to ``max(1, |bound|)``.
    iterations : int
        Dual Newton steps (both axes, every attempt).
    pinned : bool
        Whether the correction left the saturated inputs where they are (the first attempt);
        ``False`` when it had to move some of them inward (the fallback).
    reason : str or None
        Why the plan is not a plan of the QP (None when it is).
    worst_row, worst_node : str or None, int or None
        The QP's row the plan violates most and its node (the limit rows; when the correction
        in the box does not close the equalities, the input bound that the correction without
        the box leaves furthest; ZOH: the interval's left node), None when none is violated.
    worst_violation_rel : float
        That violation relative to ``max(1, |bound|)`` (0 when none).
    """

    hold: str
    cost: float
    energy: float
    X: npt.NDArray[np.float64]
    U: npt.NDArray[np.float64]
    equality_residual_rel: float
    limit_violation_rel: float
    iterations: int
    pinned: bool
    reason: str | None
    worst_row: str | None = None
    worst_node: int | None = None
    worst_violation_rel: float = 0.0

    @property
    def excess(self) -> float:
        """:math:`D = J_{up} - E(u_b)`."""
        return self.cost - self.energy


#: The former name of :class:`UpperPlan` (ZOH only until 2026-11-29).
ZohUpper = UpperPlan


def _box_min_norm(G: npt.NDArray[np.float64], r: npt.NDArray[np.float64], h: npt.NDArray[np.float64],
                  a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], tol_abs: float
                  ) -> tuple[npt.NDArray[np.float64], int, bool]:
    r"""``argmin ½ Σ h_k w_k²`` s.t. ``G w = r``, ``a <= w <= b`` (``a <= 0 <= b``, ``h > 0``)
    through the dual: :math:`w(\lambda) = \mathrm{clip}(G^\top\lambda / h, a, b)` minimises the
    Lagrangian :math:`\tfrac12\sum h w^2 - \lambda^\top(Gw - r)` over the box (it is separable),
    so the dual :math:`\varphi(\lambda)` is that Lagrangian at :math:`w(\lambda)`, concave, with
    gradient :math:`r - Gw(\lambda)`; semismooth Newton (the Jacobian
    :math:`G_F\,\mathrm{diag}(1/h_F)\,G_F^\top` on the unclipped set ``F``) with an Armijo line
    search.  Entries with ``a = b = 0`` are pinned.  Returns ``(w, iterations, converged)``;
    ``w`` is in the box in every case."""
    lam = np.zeros(G.shape[0])

    def w_of(x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return np.asarray(np.clip(G.T @ x / h, a, b), dtype=float)

    def phi(x: npt.NDArray[np.float64], w: npt.NDArray[np.float64]) -> float:
        return float(0.5 * np.sum(h * w * w) - x @ (G @ w - r))

    w = w_of(lam)
    for it in range(UPPER_MAX_ITERATIONS):
        grad = r - G @ w
        if float(np.max(np.abs(grad), initial=0.0)) <= tol_abs:
            return w, it, True
        free = (w > a) & (w < b)
        M = (G[:, free] / h[free]) @ G[:, free].T
        step = np.linalg.lstsq(M, grad, rcond=None)[0]
        if not float(grad @ step) > 1e-14 * float(grad @ grad):
            step = grad  # no Newton ascent on the current set: the gradient
        f0, slope, alpha = phi(lam, w), float(grad @ step), 1.0
        while alpha > 1e-12:
            trial = lam + alpha * step
            wt = w_of(trial)
            if phi(trial, wt) >= f0 + 1e-4 * alpha * slope:
                lam, w = trial, wt
                break
            alpha *= 0.5
        else:
            return w, it + 1, False
    grad = r - G @ w
    return w, UPPER_MAX_ITERATIONS, bool(float(np.max(np.abs(grad), initial=0.0)) <= tol_abs)


def hold_moments(t_nodes: npt.NDArray[np.float64], hold: str
                 ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    r"""The exact response of the double integrator to a hold's nodal inputs on the grid
    ``t_nodes``: with :math:`u(\tau) = \sum_j u_j\varphi_j(\tau)` (ZOH: :math:`\varphi_j` the
    indicator of :math:`[t_j, t_{j+1})`, ``j < N``; FOH: the hat function of node ``j``,
    ``j <= N``),

    .. math::  v(t_n) - v_0 = \sum_j V_{nj} u_j,\quad V_{nj} = \int_0^{t_n}\varphi_j,\qquad
               s(t_n) - s_0 - v_0 t_n = \sum_j S_{nj} u_j,\quad
               S_{nj} = \int_0^{t_n}(t_n - \tau)\varphi_j(\tau)\,d\tau,

    and the Gram matrix :math:`M_{ij} = \int\varphi_i\varphi_j` (so :math:`\tfrac12 u^\top M u
    = \tfrac12\int|u|^2`).  Per interval ``k < n`` (:math:`d = t_n - t_k`): ZOH
    :math:`V_{nk} \mathrel{+}= h_k`, :math:`S_{nk} \mathrel{+}= h_k(d - h_k/2)`, :math:`M_{kk} = h_k`;
    FOH :math:`V_{n,k} \mathrel{+}= h_k/2`, :math:`V_{n,k+1} \mathrel{+}= h_k/2`,
    :math:`S_{n,k} \mathrel{+}= h_k(d/2 - h_k/6)`, :math:`S_{n,k+1} \mathrel{+}= h_k(d/2 - h_k/3)`,
    :math:`M` the tridiagonal :math:`h_k/3` (diagonal, both ends of the interval), :math:`h_k/6`
    (off-diagonal).  For ``n = k + 1`` these are the QP's own rows
    (:class:`~iamp.planners.qp.data.QPData`).

    Parameters
    ----------
    t_nodes : numpy.ndarray
        ``N + 1`` increasing times.
    hold : {"zoh", "foh"}

    Returns
    -------
    V, S : numpy.ndarray
        Shape ``(N + 1, nu)`` (``nu = N`` ZOH, ``N + 1`` FOH).
    M : numpy.ndarray
        Shape ``(nu, nu)``.

    Raises
    ------
    ValueError
        An unknown hold.
    """
    t = np.asarray(t_nodes, dtype=float)
    h = np.diff(t)
    N = h.size
    d = t[:, None] - t[None, :-1]  # d[n, k] = t_n - t_k
    before = np.arange(N + 1)[:, None] > np.arange(N)[None, :]  # interval k lies in [0, t_n]
    if hold == "zoh":
        V = np.where(before, h[None, :], 0.0)
        S = np.where(before, h[None, :] * (d - h[None, :] / 2), 0.0)
        return V, S, np.diag(h)
    if hold != "foh":
        raise ValueError(f"unknown hold {hold!r}")
    V, S = np.zeros((N + 1, N + 1)), np.zeros((N + 1, N + 1))
    half = np.where(before, h[None, :] / 2, 0.0)
    V[:, :-1] += half
    V[:, 1:] += half
    S[:, :-1] += np.where(before, h[None, :] * (d / 2 - h[None, :] / 6), 0.0)
    S[:, 1:] += np.where(before, h[None, :] * (d / 2 - h[None, :] / 3), 0.0)
    M = np.diag(np.r_[h, 0.0] / 3 + np.r_[0.0, h] / 3) + np.diag(h / 6, 1) + np.diag(h / 6, -1)
    return V, S, M


def upper_plan(problem: Problem, plan: Plan, t_nodes: npt.NDArray[np.float64], nodes: Sequence[int],
               hold: str) -> UpperPlan:
    r"""A plan of the bounded ZOH or FOH QP at the contact nodes ``nodes`` built from a PMP plan
    whose contacts are at those nodes (rule B6's upper side, module docstring): the hold's
    image of its input (ZOH: interval averages; FOH: nodal values), corrected onto the
    equalities by the minimum-norm correction in the input box — first with the saturated
    inputs pinned, else letting them move inward — with the hold's exact states, checked
    against the QP's own rows.

    Parameters
    ----------
    problem : Problem
        The problem of the QP (its ``limits`` give the box and the rows checked).
    plan : Plan
        A PMP plan (bounded or not) of ``problem`` with its contact times at ``t_nodes[nodes]``.
    t_nodes : numpy.ndarray
        The QP's grid, ``N + 1`` increasing times from ``0`` to ``t_f``.
    nodes : sequence of int
        The contact node of each vehicle (interior: ``1..N-1``).
    hold : {"zoh", "foh"}
        The QP's hold.

    Returns
    -------
    UpperPlan
        The plan, its cost :math:`J_{up}`, the PMP plan's energy, and ``reason`` (None when it
        satisfies every row of the QP: then the QP's optimum at ``nodes`` is at most ``cost``).

    Raises
    ------
    ValueError
        ``t_nodes`` not increasing from 0 to ``t_f``, ``nodes`` not one interior node per
        vehicle, the plan of another horizon, or an unknown hold.
    """
    t = np.asarray(t_nodes, dtype=float)
    N = t.size - 1
    if N < 1 or np.any(np.diff(t) <= 0) or t[0] != 0.0 or not np.isclose(t[-1], problem.tf, rtol=1e-12, atol=0.0):
        raise ValueError("t_nodes must increase from 0 to the problem's t_f")
    if not np.isclose(float(plan.problem.tf), float(problem.tf), rtol=1e-12, atol=0.0):
        raise ValueError("the plan is of another horizon than the problem")
    V, S, Mass = hold_moments(t, hold)
    data = QPData(problem, N, hold)
    data.set_grid(t)
    data.selector_update(nodes)  # checks one interior node per vehicle
    nd = np.asarray(list(nodes), dtype=np.int64)
    # 1. the hold's image of u_b, exact (the input is linear between the plan's knots and the nodes)
    knots, Uk = _piecewise_linear_input(plan, t)
    at_nodes = np.searchsorted(knots, t)
    if hold == "zoh":  # interval averages
        cum = np.vstack([np.zeros((1, 2)), np.cumsum(0.5 * (Uk[1:] + Uk[:-1]) * np.diff(knots)[:, None], axis=0)])
        ubar = np.diff(cum[at_nodes], axis=0) / np.diff(t)[:, None]
    else:  # nodal values
        ubar = Uk[at_nodes]
    weight = V[-1]  # ∫φ_j > 0: the correction's norm (ZOH: exactly its energy; FOH: the lumped mass)
    G = np.vstack([V[-1], S[-1], S[nd]])
    ego = problem.ego
    ends = ((ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf))
    corners = (np.array([float(np.asarray(v.corner_x(t[n]))) for v, n in zip(problem.vehicles, nd)]),
               np.array([float(v.corner_y) for v in problem.vehicles]))
    U = np.empty_like(ubar)
    X = np.empty((N + 1, 4))
    iterations, converged, pinned = 0, True, True
    unboxed: tuple[float, str, int] | None = None  # (violation, row, node) of the correction without the box
    for ax, (lo, hi) in enumerate(input_box(problem)):
        s0, v0, sf, vf = ends[ax]
        g = np.r_[vf - v0, sf - s0 - v0 * t[-1], corners[ax] - s0 - v0 * t[nd]]
        u0 = np.clip(ubar[:, ax], lo, hi)  # values in the box (rounding only)
        scale = max(1.0, float(np.max(np.abs(np.r_[s0, v0, sf, vf, corners[ax]]))))
        a, b = lo - u0, hi - u0
        sat = (a >= -1e-12 * max(1.0, abs(lo))) | (b <= 1e-12 * max(1.0, abs(hi)))
        # 2. first the saturated inputs pinned (moving one inward costs to first order), else inward allowed
        w, its, ok = _box_min_norm(G, g - G @ u0, weight, np.where(sat, 0.0, a), np.where(sat, 0.0, b),
                                   1e-12 * scale)
        iterations += its
        if not ok and np.any(sat):
            pinned = False
            w, its, ok = _box_min_norm(G, g - G @ u0, weight, a, b, 1e-12 * scale)
            iterations += its
        converged &= ok
        if not ok:  # how far the grid is from holding the plan: the correction without the box leaves it
            inf = np.full_like(a, np.inf)
            wf, its, _ = _box_min_norm(G, g - G @ u0, weight, -inf, inf, 1e-12 * scale)
            iterations += its
            uf = u0 + wf
            over = np.maximum((lo - uf) / max(1.0, abs(lo)), (uf - hi) / max(1.0, abs(hi)))
            k = int(np.argmax(over))
            if unboxed is None or float(over[k]) > unboxed[0]:
                unboxed = (max(0.0, float(over[k])), ("ax", "ay")[ax], k)
        u = np.clip(u0 + w, lo, hi)
        U[:, ax] = u
        X[:, 2 * ax] = s0 + v0 * t + S @ u
        X[:, 2 * ax + 1] = v0 + V @ u
    z = data.pack(X, U)
    eq = float(np.max(np.abs(data.A @ z - data.b))) / max(1.0, float(np.max(np.abs(data.b))))
    viol = 0.0
    reason: str | None = None
    worst_row: str | None = None
    worst_node: int | None = None
    worst_viol = 0.0
    if problem.limits is not None and not problem.limits.empty:
        rows = limit_rows(data, t, hold, problem.limits)
        if rows.n_rows:
            rel = rows.violation(z) / np.maximum(1.0, np.maximum(np.abs(rows.lo), np.abs(rows.hi)))
            viol = float(np.max(rel))
            if viol > tol("limits_bound_rel"):
                worst = int(np.argmax(rel))
                worst_row, worst_node, worst_viol = str(rows.kind[worst]), int(rows.node[worst]), viol
                reason = (f"the plan built from the PMP's input violates the QP's {worst_row} row at node "
                          f"{worst_node} by {viol:.3g} (relative)")
    if not converged:
        reason = (f"the minimum-norm correction in the box did not close the equalities in "
                  f"{UPPER_MAX_ITERATIONS} dual steps per axis (relative residual {eq:.3g})")
        if unboxed is not None and unboxed[0] > worst_viol:
            worst_viol, worst_row, worst_node = unboxed
            reason += (f"; without the box the correction leaves the QP's {worst_row} row at node {worst_node} by "
                       f"{worst_viol:.3g} (relative)")
    cost = float(0.5 * np.einsum("ia,ij,ja->", U, Mass, U))
    return UpperPlan(hold=hold, cost=cost, energy=input_energy(plan), X=X, U=U, equality_residual_rel=eq,
                     limit_violation_rel=viol, iterations=iterations, pinned=pinned, reason=reason,
                     worst_row=worst_row, worst_node=worst_node, worst_violation_rel=worst_viol)


def zoh_upper_plan(problem: Problem, plan: Plan, t_nodes: npt.NDArray[np.float64], nodes: Sequence[int]
                   ) -> UpperPlan:
    """:func:`upper_plan` of the ZOH QP (same parameters, without ``hold``)."""
    return upper_plan(problem, plan, t_nodes, nodes, "zoh")


def foh_upper_plan(problem: Problem, plan: Plan, t_nodes: npt.NDArray[np.float64], nodes: Sequence[int]
                   ) -> UpperPlan:
    """:func:`upper_plan` of the FOH QP (same parameters, without ``hold``)."""
    return upper_plan(problem, plan, t_nodes, nodes, "foh")


def foh_kink_term(plan: Plan, t_nodes: npt.NDArray[np.float64]) -> float:
    r"""The leading term :math:`K_h` of the FOH excess (rule B6): over the switching times
    :math:`\theta` of a bounded PMP plan strictly inside an interval of ``t_nodes``,
    :math:`\sum_\theta \Delta_\theta^2 h^3 \beta(\alpha)/6` with :math:`\Delta_\theta` the
    change of :math:`\dot u` at :math:`\theta`, :math:`\alpha = (\theta - t_j)/h` and
    :math:`\beta = \alpha(1-\alpha)^2` where the input saturates after :math:`\theta`,
    :math:`\alpha^2(1-\alpha)` where it saturates before (module docstring).

    Parameters
    ----------
    plan : Plan
        A PMP plan; an unbounded one (no switching times) gives ``0``.
    t_nodes : numpy.ndarray
        The QP's grid (increasing, from ``0`` to ``t_f``).

    Returns
    -------
    float
        :math:`K_h` (``0`` when no switching time lies strictly inside an interval).
    """
    nodes = np.asarray(t_nodes, dtype=float)
    total = 0.0
    for ax in getattr(plan.trajectory, "axes", ()):
        kn = np.asarray(ax.knots, dtype=float)
        u = np.asarray(ax.u, dtype=float)
        dk = np.diff(kn)
        slope = np.diff(u) / np.where(dk > 0, dk, 1.0)
        for theta, _, _, direction in ax.switching:
            j = int(np.argmin(np.abs(kn - theta)))
            i = int(np.searchsorted(nodes, theta)) - 1
            if j == 0 or j == len(kn) - 1 or i < 0 or i + 1 >= len(nodes):
                continue
            h = float(nodes[i + 1] - nodes[i])
            alpha = (theta - float(nodes[i])) / h
            if not 0.0 < alpha < 1.0:
                continue
            beta = alpha * (1 - alpha) ** 2 if direction > 0 else alpha * alpha * (1 - alpha)
            total += float(slope[j] - slope[j - 1]) ** 2 * h**3 * beta / 6
    return total


#: Contact-node candidates rule B1 examines when the QP says ``infeasible`` beside a verified bounded
#: PMP plan, nearest the PMP's contact times first: a budget of work (per candidate one fixed-time
#: bounded PMP solve and at most one :func:`upper_plan`), never a time.  With one vehicle it covers
#: every interior node of grids up to ``N = 65``.
B1_MAX_CANDIDATES = 64


@dataclass
class GridCandidate:
    """One candidate of rule B1 (:func:`grid_plan_from_pmp`).

    Attributes
    ----------
    nodes : tuple of int
        The contact node of each vehicle.
    status : str
        The bounded PMP's status with its contacts at those nodes' times (``infeasible`` also
        when two vehicles share a node where their corners differ; the PMP is not solved then).
    reason : str or None
        Why no plan of the QP was built here (the bounded PMP's reason, the shared node, or the
        built plan's violated row); None when :attr:`upper` is a plan of the QP.
    upper : UpperPlan or None
        The plan of the QP built from the bounded PMP's plan there (:func:`upper_plan`).
    """

    nodes: tuple[int, ...]
    status: str
    reason: str | None
    upper: UpperPlan | None

    @property
    def is_plan(self) -> bool:
        """The built plan meets every row of the QP (its equalities and its limit rows)."""
        return self.reason is None and self.upper is not None


@dataclass
class GridSearch:
    """Rule B1's search for a plan of the QP's grid built from a bounded PMP plan.

    Attributes
    ----------
    t_nodes : numpy.ndarray
        The QP's grid.
    hold : {"zoh", "foh"}
    total : int
        Contact-node candidates of the grid, ``(N - 1)^m``.
    candidates : list of GridCandidate
        Those examined, in order (nearest the PMP's contact times first; the search stops at
        the first plan of the QP).
    """

    t_nodes: npt.NDArray[np.float64]
    hold: str
    total: int
    candidates: list[GridCandidate]

    @property
    def plan(self) -> GridCandidate | None:
        """The candidate whose built plan is a plan of the QP, if any."""
        return next((c for c in self.candidates if c.is_plan), None)

    @property
    def certified_no_plan(self) -> int:
        """Candidates certified to hold no plan of the QP: the bounded PMP certifies the input box
        infeasible at the node times (Farkas), or two vehicles share a node with distinct corners."""
        return sum(c.status == st.INFEASIBLE for c in self.candidates)

    @property
    def violating(self) -> list[GridCandidate]:
        """Candidates whose built plan violates a row of the QP."""
        return [c for c in self.candidates if c.upper is not None and not c.is_plan]

    @property
    def proved_infeasible(self) -> bool:
        """Every candidate of the grid examined and certified to hold no plan: no plan of the QP
        exists (each is a plan in the box with its contacts at the nodes, rule B4)."""
        return len(self.candidates) == self.total and self.certified_no_plan == self.total

    @property
    def worst(self) -> GridCandidate | None:
        """The violating candidate whose built plan is furthest from a plan of the QP."""
        bad = self.violating
        return max(bad, key=lambda c: (c.upper.worst_violation_rel, c.upper.equality_residual_rel)  # type: ignore[union-attr]
                   ) if bad else None

    def to_json(self) -> GridFeasibilityJSON:
        """The search as the pair's ``grid_feasibility`` (SPEC §14)."""
        w, p = self.worst, self.plan
        wu = w.upper if w is not None else None
        pu = p.upper if p is not None else None
        return {"steps": int(self.t_nodes.size - 1), "hold": self.hold, "candidates": int(self.total),
                "examined": len(self.candidates), "certified_no_plan": int(self.certified_no_plan),
                "violating": len(self.violating),
                "undecided": len(self.candidates) - self.certified_no_plan - len(self.violating) - (p is not None),
                "proved_infeasible": self.proved_infeasible,
                "worst_candidate": None if w is None else list(w.nodes),
                "worst_row": None if wu is None else wu.worst_row,
                "worst_node": None if wu is None else wu.worst_node,
                "worst_violation_rel": None if wu is None else float(wu.worst_violation_rel),
                "worst_equality_residual_rel": None if wu is None else float(wu.equality_residual_rel),
                "plan_nodes": None if p is None else list(p.nodes),
                "plan_cost": None if pu is None else float(pu.cost),
                "plan_equality_residual_rel": None if pu is None else float(pu.equality_residual_rel),
                "plan_limit_violation_rel": None if pu is None else float(pu.limit_violation_rel)}


def candidate_nodes(t_nodes: npt.NDArray[np.float64], times: Sequence[float], limit: int) -> list[tuple[int, ...]]:
    """Up to ``limit`` contact-node candidates of the grid ``t_nodes`` (one interior node per
    vehicle), nearest ``times`` first: per vehicle the interior nodes ranked by their distance to
    its time (ties: the earlier node), the candidates ordered by their largest rank, then the sum
    of the ranks, then the ranks.  The first ``2^m`` are the nodes bracketing ``times``."""
    t = np.asarray(t_nodes, dtype=float)
    interior = np.arange(1, t.size - 1)
    m = len(times)
    if m == 0 or interior.size == 0 or limit < 1:
        return []
    ranked = [interior[np.argsort(np.abs(t[interior] - float(ti)), kind="stable")] for ti in times]
    k = 1
    while k < interior.size and k**m < limit:
        k += 1
    ranks = sorted(itertools.product(range(k), repeat=m), key=lambda r: (max(r), sum(r), r))[:limit]
    return [tuple(int(ranked[i][r]) for i, r in enumerate(rank)) for rank in ranks]


def _shared_node_clash(problem: Problem, t: npt.NDArray[np.float64], nodes: Sequence[int]) -> str | None:
    """Why two vehicles sharing a contact node admit no plan: the ego's position at a node is
    one point, and their corners there differ (None when no node is shared or they coincide)."""
    pts = problem.corners(t[list(nodes)])
    scale = max(1.0, float(np.max(np.abs(pts))))
    for i, j in itertools.combinations(range(len(nodes)), 2):
        gap = float(np.max(np.abs(pts[i] - pts[j])))
        if nodes[i] == nodes[j] and gap > 1e-9 * scale:
            return (f"vehicles {i} and {j} share node {nodes[i]}, where their corners differ by {gap:.3g} m: "
                    "no position meets both")
    return None


def grid_plan_from_pmp(problem: Problem, plan: Plan, steps: int, hold: str, residual_rel: float,
                       max_candidates: int = B1_MAX_CANDIDATES) -> GridSearch:
    r"""Rule B1: look for a plan of the bounded QP's grid built from a bounded PMP plan.

    For each candidate of :func:`candidate_nodes` (nearest the plan's contact times first) the
    bounded PMP is re-solved with its contacts at the node times; where it certifies the input
    box infeasible there, no plan of the QP has its contacts at those nodes (every plan of the
    QP is a plan in the box with its contacts at its nodes, rule B4); where it has a plan,
    :func:`upper_plan` builds a plan of the QP from it and checks it against the QP's equality
    rows (to ``residual_rel``) and limit rows (to ``limits_bound_rel``).  The search stops at the
    first plan of the QP.

    Parameters
    ----------
    problem : Problem
        With ``problem.limits``.
    plan : Plan
        A verified bounded PMP plan of ``problem``.
    steps : int
        The QP's ``N``; its grid is :class:`~iamp.planners.qp.data.QPData`'s (uniform).
    hold : {"zoh", "foh"}
    residual_rel : float
        The QP solver's ``cmp_residual_rel_*`` (its equality rows).
    max_candidates : int
        The budget of candidates (:data:`B1_MAX_CANDIDATES`).

    Returns
    -------
    GridSearch
    """
    t = np.asarray(QPData(problem, steps, hold).t_nodes, dtype=float)
    out = GridSearch(t_nodes=t, hold=hold, total=max(0, steps - 1) ** problem.m, candidates=[])
    for nodes in candidate_nodes(t, [float(x) for x in plan.contact_times], max_candidates):
        clash = _shared_node_clash(problem, t, nodes)
        if clash is not None:
            out.candidates.append(GridCandidate(nodes, st.INFEASIBLE, clash, None))
            continue
        at = PMPPlanner().plan(problem, contact_times=t[list(nodes)])
        if at.trajectory is None or at.cost is None:
            out.candidates.append(GridCandidate(nodes, at.status, f"the bounded PMP at the node times is {at.status}"
                                                f" ({at.diagnostics.reason})", None))
            continue
        up = upper_plan(problem, at, t, nodes, hold)
        reason = up.reason
        if reason is None and not up.equality_residual_rel <= residual_rel:
            reason = (f"the plan built from the PMP's input misses the QP's equality rows by "
                      f"{up.equality_residual_rel:.3g} (relative)")
        out.candidates.append(GridCandidate(nodes, at.status, reason, up))
        if reason is None:
            break
    return out


def _qp_infeasible(problem: Problem, pmp: Run, qp: Run, checks: Checks, out: PairJSON) -> PairJSON:
    """Rule B1 when the bounded PMP has a verified plan and the QP says ``infeasible``."""
    cfg = qp.config
    assert cfg is not None
    p_res, q_res = pmp.result, qp.result
    search = grid_plan_from_pmp(problem, p_res, cfg.steps, cfg.hold, solver_tol("residual_rel", cfg.solver))
    out["grid_feasibility"] = search.to_json()
    t = search.t_nodes
    grid = f"N = {cfg.steps}, {cfg.hold.upper()}"
    claim = f"{qp.label} reports infeasible ({q_res.diagnostics.reason})"
    found = search.plan
    if found is not None and found.upper is not None:
        up = found.upper
        checks.check("qp_infeasible_not_contradicted", None, None, ok=False,
                     why=f"{claim}, but a plan of its grid ({grid}) exists: contact nodes {list(found.nodes)} "
                         f"(t = {[round(float(x), 9) for x in t[list(found.nodes)]]}), built from the bounded "
                         f"PMP's plan re-solved at those times, meets the QP's equality rows to "
                         f"{up.equality_residual_rel:.3g} and its limit rows to {up.limit_violation_rel:.3g} "
                         f"(relative), cost {up.cost:.9g}")
        out["verdict_basis"] = ("the QP's infeasible against a plan of its grid built from the bounded PMP's plan "
                                "(rule B1)")
        return checks.finish(out)
    checks.check("qp_infeasible_not_contradicted", None, None, ok=True)
    times = [round(float(x), 9) for x in p_res.contact_times]
    checks.notes.append(f"{qp.label}: {q_res.diagnostics.reason}")
    checks.notes.append(f"the bounded PMP's plan (status {p_res.status}, cost {plan_cost(p_res):.9g}, contact times "
                        f"{times}) is a plan of the continuous problem; the QP's grid ({grid}) holds no plan built "
                        "from it: a property of the grid, not a contradiction, and no optimum is compared")
    n_box, bad = search.certified_no_plan, search.violating
    examined = f"{len(search.candidates)} of {search.total} contact-node candidates (nearest t* first)"
    if search.proved_infeasible:
        proof = (f"every one of the {search.total} contact-node candidates is certified to hold no plan (the bounded "
                 "PMP's Farkas certificate of the input box at the node times, or two vehicles on one node with "
                 "distinct corners), so the grid has no plan: the QP's infeasible is proved")
    else:
        proof = (f"examined {examined}: {n_box} certified to hold no plan (the input box infeasible at the node "
                 "times by the bounded PMP's Farkas certificate, or two vehicles on one node with distinct corners), "
                 f"{len(bad)} whose plan built from the bounded PMP's plan violates a row of "
                 f"the QP, {len(search.candidates) - n_box - len(bad)} undecided; the QP's infeasible is not "
                 "contradicted (not proved: the construction is sufficient, not necessary"
                 + (", and candidates beyond the budget were not examined)" if len(search.candidates) < search.total
                    else ")"))
    checks.notes.append(proof)
    w = search.worst
    if w is not None and w.upper is not None:
        wu = w.upper
        where = (f"the QP's {wu.worst_row} row at node {wu.worst_node} by {wu.worst_violation_rel:.3g} (relative)"
                 if wu.worst_row is not None else
                 f"the QP's equality rows by {wu.equality_residual_rel:.3g} (relative)")
        checks.notes.append(f"largest violation of a plan built from the bounded PMP's plan: contact nodes "
                            f"{list(w.nodes)} (t = {[round(float(x), 9) for x in t[list(w.nodes)]]}), {where}")
    if cfg.contact != "grid":
        checks.notes.append(f"the grid examined is the uniform grid of N = {cfg.steps} (the {cfg.contact} search "
                            "starts from it)")
    how = "proved" if search.proved_infeasible else "not contradicted"
    out["verdict_basis"] = (f"not comparable (rule B1): the bounded PMP has a plan of the continuous problem and the "
                            f"QP's grid ({grid}) holds no plan built from it ({how}); the verdict says the two claims "
                            "are consistent, not that the optima agree")
    return checks.finish(out)


def _verified(plan: Plan) -> bool:
    return plan.status in (st.OPTIMAL, st.LOCAL) and plan.cost is not None and plan.trajectory is not None


def compare_bounded_pmp_qp(problem: Problem, pmp: Run, qp: Run) -> PairJSON:
    """Judge one ``pmp`` / QP pair of a bounded problem (rules B0–B6 of the module docstring).

    Parameters
    ----------
    problem : Problem
        With ``problem.limits``.
    pmp, qp : Run
        The bounded PMP's run and one QP configuration's run on ``problem``.

    Returns
    -------
    PairJSON
        The ``agreement`` entry: ``a``, ``b``, the gaps, ``at_same_contact_times``,
        ``bounded`` (the excess, the bracket's ``D`` and the leading terms), ``verdict_basis``, ``verdict``,
        ``reasons``, ``notes`` and every check.
    """
    checks = Checks()
    cfg = qp.config
    out: PairJSON = {"a": pmp.label, "b": qp.label, "cost_rel_gap": None, "contact_time_gap": None,
                     "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    same_problem(pmp, qp, checks)
    p_res, q_res = pmp.result, qp.result
    if p_res.status == st.INFEASIBLE and q_res.status == st.INFEASIBLE:
        out["verdict_basis"] = "both certify the bounded problem infeasible (rule B1)"
        checks.notes.append(f"pmp: {p_res.diagnostics.reason}")
        checks.notes.append(f"{qp.label}: {q_res.diagnostics.reason}")
        return checks.finish(out)
    if p_res.status == st.INFEASIBLE and _verified(q_res):
        checks.fail(f"{qp.label} found a plan within the limits where the PMP certifies the input box infeasible "
                    f"({p_res.diagnostics.reason})")
        return checks.finish(out)
    if _verified(p_res) and q_res.status == st.INFEASIBLE and cfg is not None:
        return _qp_infeasible(problem, pmp, qp, checks, out)
    failed_before = len(checks.reasons)  # rule B0's reason does not stop the numeric rules
    if not _verified(p_res):
        checks.fail(f"pmp status {p_res.status}" + (f" ({p_res.diagnostics.reason})" if p_res.diagnostics.reason
                                                    else ""))
    if not qp.ok:
        checks.fail(f"{qp.label} status {q_res.status}" + (f" ({q_res.diagnostics.reason})"
                                                            if q_res.diagnostics.reason else ""))
    if len(checks.reasons) > failed_before or cfg is None:
        return checks.finish(out)
    if p_res.status == st.LOCAL:
        checks.notes.append("the bounded PMP is local (verified at its contact times, not certified global): "
                            "rule B5 is not applied")
    solver, hold = cfg.solver, cfg.hold
    traj = hold_trajectory(q_res)
    t_nodes = np.asarray(traj.t_nodes)
    nodes = [int(np.argmin(np.abs(t_nodes - t))) for t in q_res.contact_times]
    tQ = t_nodes[nodes]
    gaps = run_vs_run_gaps(p_res, q_res, t_nodes)
    out["cost_rel_gap"], out["contact_time_gap"] = gaps["cost_rel_gap"], gaps["contact_time_gap"]
    out["state_sup_gap"], out["input_sup_gap"] = gaps["state_sup_gap"], gaps["input_sup_gap"]
    out["jump_gap"] = gaps["jump_gap"]
    # the bounded PMP at the QP's contact times (fixed times: the unique optimum of a strictly convex problem)
    at = PMPPlanner().plan(problem, contact_times=tQ)
    ctol = solver_tol("cost_rel", solver)
    # B2: KKT with complementarity, recomputed from the stacked matrices
    if qp.kkt is None:
        checks.fail("KKT residuals unavailable")
    else:
        for k in ("primal_rel", "dual_rel", "gap_rel", "complementarity_rel"):
            value = qp.kkt.get(k)
            checks.check(f"kkt_{k}", value if isinstance(value, float) else None, solver_tol("kkt_rel", solver))
    # B3: the QP's own constraints
    bscale = max(1.0, float(np.max(np.abs(np.r_[problem.ego.initial, problem.ego.final]))))
    checks.check("boundary_residual_rel", q_res.boundary_residual() / bscale, solver_tol("residual_rel", solver))
    checks.check("collision_residual_rel", q_res.corner_residual() / bscale, solver_tol("residual_rel", solver))
    out["signs"] = [sign_entry(v, j[0]) for v, j in zip(problem.vehicles, q_res.jumps)]
    if at.trajectory is None or at.cost is None:
        checks.fail(f"the bounded PMP at the QP's contact times {[round(float(t), 9) for t in tQ]} is {at.status} "
                    f"({at.diagnostics.reason}), but the QP found a plan there within the limits (rule B4)")
        return checks.finish(out)
    J_qp, J_at, J_star = plan_cost(q_res), float(at.cost), plan_cost(p_res)
    out["at_same_contact_times"] = at_same_contact_times(q_res, at, tQ, t_nodes)
    # B4's premise: the re-solve's plan is a plan of the continuous problem at t_Q: in the box (exact: its input is
    # linear between its knots), through the corners at t_Q and from x_0 to x_f (its states are exact)
    checks.check("pmp_at_contact_times_box_violation_rel", box_violation(problem, at), tol("limits_bound_rel"),
                 why="the bounded PMP's input at the QP's contact times leaves the input box")
    ends = at.states(np.array([0.0, float(problem.tf)]))
    miss = max(float(np.max(np.abs(at.states(tQ)[:, [0, 2]] - problem.corners(tQ)))),
               float(np.max(np.abs(ends[0] - np.asarray(problem.ego.initial)))),
               float(np.max(np.abs(ends[1] - np.asarray(problem.ego.final)))))
    checks.check("pmp_at_contact_times_residual_rel", miss / bscale, tol("pmp_condition_residual"),
                 why="the bounded PMP's plan at the QP's contact times misses a corner or a boundary state")
    # B4: the QP's plan is a plan within the box at t_Q
    checks.check("bounded_lower_bound_rel", (J_at - J_qp) / abs(J_at), ctol,
                 why="the QP's cost is below the bounded PMP's at the same contact times: the QP did not "
                     "solve the bounded problem")
    # B5': the cost compared is the plan's (the PMP's and the re-solve's)
    for name, plan_ in (("pmp_cost_is_input_energy", p_res), ("pmp_at_contact_times_cost_is_input_energy", at)):
        energy = input_energy(plan_)
        checks.check(name, abs(plan_cost(plan_) - energy) / max(1.0, abs(energy)), ctol,
                     why="the bounded PMP's cost is not the energy 1/2 int |u|^2 of its own input")
    # B5: t* is the global minimiser of the bounded cost
    if p_res.status == st.OPTIMAL:
        checks.check("pmp_global_lower_bound", (J_star - J_at) / abs(J_star), ctol,
                     why="the QP's contact times have a lower bounded cost than t*: the bounded PMP missed the "
                         "global optimum")
    # B6: the discretisation excess within its derived two-sided bracket [0, D] (the lower side is B4)
    h = float(np.max(np.diff(t_nodes)))
    lead = h * h / 24.0 * input_slope_energy(at)
    excess = J_qp - J_at
    ratio = excess / lead if lead > 0 else None
    kink = foh_kink_term(at, t_nodes)
    up = upper_plan(problem, at, t_nodes, nodes, hold)
    bounded: dict[str, float | str | None] = {
        f"{hold}_upper_cost": up.cost, f"{hold}_upper_excess": up.excess,
        "ratio_to_upper_excess": float(excess / up.excess) if up.excess > 0 else None,
        f"{hold}_upper_equality_residual_rel": up.equality_residual_rel,
        f"{hold}_upper_limit_violation_rel": up.limit_violation_rel, f"{hold}_upper_pinned": up.pinned,
        f"{hold}_upper_reason": up.reason}
    if hold != "zoh":
        bounded["ratio_to_kink_term"] = float(excess / kink) if kink > 0 else None
    if up.reason is None:
        checks.check(f"bounded_{hold}_upper_residual_rel", up.equality_residual_rel, solver_tol("residual_rel", solver))
        checks.check(f"bounded_{hold}_excess_rel", (excess - up.excess) / abs(J_at), ctol,
                     why=f"the QP's cost {J_qp:.9g} is above the bounded PMP's {J_at:.9g} plus the excess "
                         f"{up.excess:.6g} of a plan of the QP built from the PMP's input: the QP is not optimal, "
                         f"or the PMP's cost is below its plan's")
    else:
        checks.notes.append(f"rule B6's upper side is not applied: {up.reason}")
    out["bounded"] = {"pmp_at_contact_times_status": at.status, "pmp_at_contact_times_cost": J_at,
                      "excess": float(excess), "leading_h2_term": float(lead),
                      "ratio_to_leading": None if ratio is None else float(ratio), "h": h,
                      "foh_kink_term": float(kink), **bounded}
    out["reference"] = "bounded PMP at the QP's contact times"
    out["verdict_basis"] = ("bounded problem: KKT with complementarity, constraint residuals, the QP's cost above the "
                            "bounded PMP's at the same contact times, the PMP's global claim and its cost, and the "
                            "discretisation excess within the bracket [0, D] of a plan of the QP built from the PMP's "
                            "input (rules B1-B6)")
    return checks.finish(out)
