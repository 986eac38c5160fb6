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
    contradiction (**disagree**).  Any other status (``limits_violated``: the PMP's plan exceeds
    a bound it cannot impose; a solver failure): **disagree**, with the status as the reason.

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

B6. *Discretisation excess* :math:`\Delta = J_{QP} - J_b(t_Q) \ge 0` (B4 is its lower side).
    ZOH: an a-posteriori two-sided bracket, derived below, not fitted:

    .. math::  J_b(t_Q) \;\le\; J_{QP} \;\le\; J_b(t_Q) + D,\qquad
               D = J_{up} - E(u_b),

    with :math:`u_b` the bounded PMP's input at ``t_Q`` and :math:`J_{up}` the cost of a
    plan of the ZOH QP built from it (:func:`zoh_upper_plan`).

    *Lower side.*  On a grid ``t_0 < … < t_N`` the ZOH rows of the QP are the exact
    solution of :math:`\dot s = v,\ \dot v = u` for :math:`u \equiv u_k` on
    :math:`[t_k, t_{k+1})` (:math:`v_{k+1} = v_k + h_k u_k`,
    :math:`s_{k+1} = s_k + h_k v_k + \tfrac{h_k^2}{2} u_k`) and its cost
    :math:`\tfrac12\sum_k h_k|u_k|^2` is exactly :math:`\tfrac12\int|u|^2`.  So every plan of
    the ZOH QP at its contact nodes ``t_Q`` is a continuous plan with the contacts at ``t_Q``,
    inputs in the box ``ax``/``ay`` at every time (constant per interval), the same
    boundary values and cost.  The bounded PMP at ``t_Q`` minimises over exactly those
    continuous plans (box only); the QP's other rows (``a_total``'s polygon, ``vx`` and ``y``
    at the nodes) only remove plans from the QP, so they tighten this side and relax nothing:
    :math:`J_{QP} \ge J_b(t_Q) \ge J_b^*` (B4, B5) whatever other limits are set.

    *Upper side.*  The QP's optimum is no higher than the cost of any plan it admits at its
    own contact nodes; one is built from :math:`u_b`:

    1. interval averages :math:`\bar u_k = h_k^{-1}\int_{t_k}^{t_{k+1}} u_b` (exact: ``u_b`` is
       linear between its knots).  They lie in the box (an average of values in a convex set)
       and keep every nodal speed: :math:`v(t_k)` is the same for :math:`\bar u` and :math:`u_b`.
       Per axis, the positions at the contact nodes ``n`` and at :math:`t_N` (and the final
       speed) are linear in the inputs, :math:`G u = g` with rows
       :math:`G_{v,k} = h_k`, :math:`G_{n,k} = h_k (t_n - m_k)^+` (:math:`m_k` the interval's
       midpoint, :math:`k < n`), and :math:`G\bar u - g = O(h^2)` (the first moments of
       :math:`u_b - \bar u`).
    2. The minimum-norm correction in the box,

       .. math::  \min_w \tfrac12\sum_k h_k w_k^2 \quad\text{s.t.}\quad G w = g - G\bar u,\quad
                  \ell \le \bar u + w \le h_{\mathrm{box}},

       solved through its dual (:math:`w_k(\lambda) = \mathrm{clip}((G^\top\lambda)_k/h_k)`, a
       piecewise-linear monotone equation :math:`G w(\lambda) = g - G\bar u` in 2 + m unknowns,
       semismooth Newton with a line search on the concave dual, at most
       :data:`ZOH_UPPER_MAX_ITERATIONS` steps).  Saturated intervals may move inward only.
    3. The plan :math:`u = \bar u + w` with its exact ZOH states is checked against the QP's
       own rows (:class:`~iamp.planners.qp.data.QPData` equalities to
       ``cmp_residual_rel_*``, every :func:`~iamp.planners.qp.limits.limit_rows` row to
       ``limits_bound_rel``): it is a plan of the QP, so
       :math:`J_{QP} \le J_{up} = \tfrac12\sum_k h_k|u_k|^2`.

    Writing :math:`J_{up} = E(u_b) + D` and :math:`E(u_b) = J_b(t_Q)` (the PMP's cost is its
    input's energy, B5' at ``t_Q``), the two sides give the bracket; both ends are
    computed numbers, so agreement is a proof (to ``cmp_cost_rel_*``), not an estimate.  It
    is as tight as the construction: :math:`D/\Delta` = 1.02 (N = 24) and 1.05 (N = 48) on
    ``random_problem(229)`` with limits at 0.609 of its inputs, where the former bracket
    :math:`\Delta \in [0.8, 1.25]\,\Delta_1`, :math:`\Delta_1 = \tfrac{h^2}{24}\int|\dot u_b|^2`
    (the unbounded leading term), failed with :math:`\Delta/\Delta_1` = 1.2535 (1.377 on
    ``random_problem(980978)`` at 0.627); the unbounded bracket's :math:`1/(1-\rho)` has no
    bounded analogue.  Its resolution is :math:`D`: a claimed :math:`J_b(t_Q)` too low by more
    than :math:`D - \Delta` or too high by more than :math:`\Delta` is caught.  When no plan of
    the QP can be built this way (a row other than the box is violated, e.g. ``a_total``'s
    polygon, or the dual iteration does not close), the upper side is not applied and a note
    says why; :math:`\Delta_1` and :math:`\Delta/\Delta_1` are still reported.

    FOH represents every piecewise-linear input on the grid
    exactly (the contact times are nodes) and misses ``u_b`` only on the intervals holding a
    switching time :math:`\theta` (slope change :math:`\Delta_\theta`, at
    :math:`\theta = t_j + \alpha h`).  The FOH interpolant of ``u_b``, corrected back onto the
    equalities by an FOH input on the free set (cost :math:`O(h^4)`), is an FOH plan in the
    box whose excess is, to leading order (:func:`foh_kink_term`),

    .. math::  K_h = \sum_\theta \frac{\Delta_\theta^2 h^3}{6}\,\beta(\alpha),\qquad
               \beta = \alpha(1-\alpha)^2 \text{ (saturated after } \theta),\
               \alpha^2(1-\alpha) \text{ (before)},

    (``½∫e²`` of the interpolation error plus ``∫(u_b − w)e`` on the saturated side), so
    :math:`\Delta \le` ``cmp_bounded_foh_ratio`` :math:`\cdot K_h` (the QP minimises over all
    FOH plans; :math:`\Delta/K_h` measured 0.25–1.54 at ``N = 24`` on 60 generated problems, at
    most 1 from ``N = 48`` on, as the leading-order argument says), and :math:`\Delta = 0` to
    solver precision when no switching time falls inside an interval.  (Until 2026-11-28 the
    FOH rule was :math:`\Delta \le 0.25\,\Delta_1`; that is not a bound — the FOH excess is set
    by the switching kinks, not by :math:`\int|\dot u_b|^2` — and failed on
    ``random_problem(229)`` with limits at 0.609 of its inputs: :math:`\Delta/\Delta_1` = 0.35
    at ``N = 24``, :math:`\Delta/K_h` = 1.30, with the bounded PMP right: the FOH QP at that
    contact time converges to its :math:`J_b` from above, 5.4e-1, 4.4e-3, 1.3e-4, 1.2e-6 at
    ``N`` = 24, 96, 384, 1536.)

The headline gaps (``cost_rel_gap`` etc.) and ``at_same_contact_times`` are those of
:mod:`iamp.comparison.agreement.gaps`, against the bounded PMP.
"""

from __future__ import annotations

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
from .records import PairJSON
from .runs import Run
from .signs import sign_entry
from .verdict import Checks, plan_cost, same_problem, solver_tol

__all__ = ["ZOH_UPPER_MAX_ITERATIONS", "ZohUpper", "box_violation", "compare_bounded_pmp_qp", "foh_kink_term",
           "input_energy", "input_slope_energy", "zoh_upper_plan"]

#: Newton steps of the dual of the box-constrained minimum-norm correction (rule B6, ZOH), per axis.
ZOH_UPPER_MAX_ITERATIONS = 200


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
class ZohUpper:
    """A plan of the ZOH QP built from a PMP plan (rule B6's upper side, :func:`zoh_upper_plan`).

    Attributes
    ----------
    cost : float
        :math:`J_{up} = \\tfrac12\\sum_k h_k|u_k|^2` of the built plan.
    energy : float
        :math:`E(u_b)` of the PMP plan it was built from (:func:`input_energy`).
    X, U : numpy.ndarray
        Nodal states ``(N+1, 4)`` ``(s_x, v_x, s_y, v_y)`` and inputs ``(N, 2)``.
    equality_residual_rel : float
        ``max|A z − b| / max(1, max|b|)`` on the QP's own equality rows at the contact nodes.
    limit_violation_rel : float
        The largest violation of a limit row of the QP, relative to ``max(1, |bound|)``.
    iterations : int
        Dual Newton steps (both axes).
    reason : str or None
        Why the plan is not a plan of the QP (None when it is).
    """

    cost: float
    energy: float
    X: npt.NDArray[np.float64]
    U: npt.NDArray[np.float64]
    equality_residual_rel: float
    limit_violation_rel: float
    iterations: int
    reason: str | None

    @property
    def excess(self) -> float:
        """:math:`D = J_{up} - E(u_b)`."""
        return self.cost - self.energy


def _box_min_norm(G: npt.NDArray[np.float64], r: npt.NDArray[np.float64], h: npt.NDArray[np.float64],
                  a: npt.NDArray[np.float64], b: npt.NDArray[np.float64], tol_abs: float
                  ) -> tuple[npt.NDArray[np.float64], int, bool]:
    r"""``argmin ½ Σ h_k w_k²`` s.t. ``G w = r``, ``a <= w <= b`` (``a <= 0 <= b``) through the
    dual: :math:`w(\lambda) = \mathrm{clip}(G^\top\lambda / h, a, b)` minimises the Lagrangian
    :math:`\tfrac12\sum h w^2 - \lambda^\top(Gw - r)` over the box (it is separable), so the
    dual :math:`\varphi(\lambda)` is that Lagrangian at :math:`w(\lambda)`, concave, with
    gradient :math:`r - Gw(\lambda)`; semismooth Newton (the Jacobian
    :math:`G_F\,\mathrm{diag}(1/h_F)\,G_F^\top` on the unclipped set ``F``) with an Armijo line
    search.  Returns ``(w, iterations, converged)``; ``w`` is in the box in every case."""
    lam = np.zeros(G.shape[0])

    def w_of(x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return np.asarray(np.clip(G.T @ x / h, a, b), dtype=float)

    def phi(x: npt.NDArray[np.float64], w: npt.NDArray[np.float64]) -> float:
        return float(0.5 * np.sum(h * w * w) - x @ (G @ w - r))

    w = w_of(lam)
    for it in range(ZOH_UPPER_MAX_ITERATIONS):
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
    return w, ZOH_UPPER_MAX_ITERATIONS, bool(float(np.max(np.abs(grad), initial=0.0)) <= tol_abs)


def zoh_upper_plan(problem: Problem, plan: Plan, t_nodes: npt.NDArray[np.float64], nodes: Sequence[int]
                   ) -> ZohUpper:
    r"""A plan of the bounded ZOH QP at the contact nodes ``nodes`` built from a PMP plan whose
    contacts are at those nodes (rule B6's upper side, module docstring): the interval
    averages of its input, corrected onto the equalities by the minimum-norm correction in the
    input box, with exact ZOH states, checked against the QP's own rows.

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

    Returns
    -------
    ZohUpper
        The plan, its cost :math:`J_{up}`, the PMP plan's energy, and ``reason`` (None when it
        satisfies every row of the QP: then the QP's optimum at ``nodes`` is at most ``cost``).

    Raises
    ------
    ValueError
        ``t_nodes`` not increasing from 0 to ``t_f``, or ``nodes`` not one interior node per
        vehicle.
    """
    t = np.asarray(t_nodes, dtype=float)
    N = t.size - 1
    if N < 1 or np.any(np.diff(t) <= 0) or t[0] != 0.0 or not np.isclose(t[-1], problem.tf, rtol=1e-12, atol=0.0):
        raise ValueError("t_nodes must increase from 0 to the problem's t_f")
    data = QPData(problem, N, "zoh")
    data.set_grid(t)
    data.selector_update(nodes)  # checks one interior node per vehicle
    nd = np.asarray(list(nodes), dtype=np.int64)
    h = np.diff(t)
    mid = 0.5 * (t[1:] + t[:-1])
    # 1. interval averages, exact (the input is linear between the plan's knots and the nodes)
    knots, Uk = _piecewise_linear_input(plan, t)
    if not np.isclose(float(plan.problem.tf), float(problem.tf), rtol=1e-12, atol=0.0):
        raise ValueError("the plan is of another horizon than the problem")
    cum = np.vstack([np.zeros((1, 2)), np.cumsum(0.5 * (Uk[1:] + Uk[:-1]) * np.diff(knots)[:, None], axis=0)])
    ubar = np.diff(cum[np.searchsorted(knots, t)], axis=0) / h[:, None]
    ego = problem.ego
    ends = ((ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf))
    corners = (np.array([float(np.asarray(v.corner_x(t[n]))) for v, n in zip(problem.vehicles, nd)]),
               np.array([float(v.corner_y) for v in problem.vehicles]))
    k = np.arange(N)
    G = np.vstack([h, h * (t[-1] - mid)] + [np.where(k < n, h * (t[n] - mid), 0.0) for n in nd])
    U = np.empty((N, 2))
    X = np.empty((N + 1, 4))
    iterations, converged = 0, True
    for ax, (lo, hi) in enumerate(input_box(problem)):
        s0, v0, sf, vf = ends[ax]
        g = np.r_[vf - v0, sf - s0 - v0 * t[-1], corners[ax] - s0 - v0 * t[nd]]
        u0 = np.clip(ubar[:, ax], lo, hi)  # an average of values in the box (rounding only)
        scale = max(1.0, float(np.max(np.abs(np.r_[s0, v0, sf, vf, corners[ax]]))))
        w, its, ok = _box_min_norm(G, g - G @ u0, h, lo - u0, hi - u0, 1e-12 * scale)
        iterations += its
        converged &= ok
        u = np.clip(u0 + w, lo, hi)
        U[:, ax] = u
        v = v0 + np.r_[0.0, np.cumsum(h * u)]
        X[:, 2 * ax], X[:, 2 * ax + 1] = s0 + np.r_[0.0, np.cumsum(h * v[:-1] + 0.5 * h * h * u)], v
    z = data.pack(X, U)
    eq = float(np.max(np.abs(data.A @ z - data.b))) / max(1.0, float(np.max(np.abs(data.b))))
    viol = 0.0
    reason: str | None = None
    if problem.limits is not None and not problem.limits.empty:
        rows = limit_rows(data, t, "zoh", problem.limits)
        if rows.n_rows:
            rel = rows.violation(z) / np.maximum(1.0, np.maximum(np.abs(rows.lo), np.abs(rows.hi)))
            viol = float(np.max(rel))
            if viol > tol("limits_bound_rel"):
                worst = int(np.argmax(rel))
                reason = (f"the plan built from the PMP's input violates the QP's {rows.kind[worst]} row at node "
                          f"{int(rows.node[worst])} by {viol:.3g} (relative)")
    if not converged:
        reason = (f"the minimum-norm correction in the box did not close the equalities in "
                  f"{ZOH_UPPER_MAX_ITERATIONS} dual steps per axis")
    return ZohUpper(cost=float(0.5 * np.sum(h[:, None] * U * U)), energy=input_energy(plan), X=X, U=U,
                    equality_residual_rel=eq, limit_violation_rel=viol, iterations=iterations, reason=reason)


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
        ``bounded`` (the excess and its leading term), ``verdict_basis``, ``verdict``,
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
    # B6: the discretisation excess, ZOH within its two-sided bracket, FOH against the switching kinks' term
    h = float(np.max(np.diff(t_nodes)))
    lead = h * h / 24.0 * input_slope_energy(at)
    excess = J_qp - J_at
    ratio = excess / lead if lead > 0 else None
    bounded: dict[str, float | str | None] = {}
    if hold == "zoh":
        up = zoh_upper_plan(problem, at, t_nodes, nodes)
        bounded.update({"zoh_upper_cost": up.cost, "zoh_upper_excess": up.excess,
                        "ratio_to_upper_excess": float(excess / up.excess) if up.excess > 0 else None,
                        "zoh_upper_equality_residual_rel": up.equality_residual_rel,
                        "zoh_upper_limit_violation_rel": up.limit_violation_rel, "zoh_upper_reason": up.reason})
        if up.reason is None:
            checks.check("bounded_zoh_upper_residual_rel", up.equality_residual_rel, solver_tol("residual_rel", solver))
            checks.check("bounded_zoh_excess_rel", (excess - up.excess) / abs(J_at), ctol,
                         why=f"the QP's cost {J_qp:.9g} is above the bounded PMP's {J_at:.9g} plus the excess "
                             f"{up.excess:.6g} of a plan of the QP built from the PMP's input: the QP is not optimal, "
                             f"or the PMP's cost is below its plan's")
        else:
            checks.notes.append(f"rule B6's upper side is not applied: {up.reason}")
    kink = foh_kink_term(at, t_nodes)
    if hold != "zoh":
        factor = tol("cmp_bounded_foh_ratio")
        checks.check("bounded_foh_excess_rel", (excess - factor * kink) / abs(J_at), ctol,
                     why=f"excess {excess:.6g} above {factor:g} x the FOH kink term {kink:.6g}")
    out["bounded"] = {"pmp_at_contact_times_status": at.status, "pmp_at_contact_times_cost": J_at,
                      "excess": float(excess), "leading_h2_term": float(lead),
                      "ratio_to_leading": None if ratio is None else float(ratio), "h": h,
                      "foh_kink_term": float(kink), **bounded}
    out["reference"] = "bounded PMP at the QP's contact times"
    out["verdict_basis"] = ("bounded problem: KKT with complementarity, constraint residuals, the QP's cost above the "
                            "bounded PMP's at the same contact times, the PMP's global claim and its cost, and the "
                            "discretisation excess: ZOH within the bracket [0, D] of a plan of the QP built from the "
                            "PMP's input, FOH against the switching kinks' term (rules B1-B6)")
    return checks.finish(out)
