r"""The bounded PMP: the input box ``ax``/``ay`` imposed exactly (SPEC §14).

**Conditions.**  With :math:`H = \tfrac12|u|^2 + p_1v_x + p_2u_x + p_3v_y + p_4u_y` and the
box :math:`u_x\in[\ell_x,h_x]`, :math:`u_y\in[\ell_y,h_y]`, the minimum principle gives, per
axis (``p_v`` = ``p2`` or ``p4``, ``p_s`` = ``p1`` or ``p3``):

1. *co-states*: :math:`\dot p_s = 0,\ \dot p_v = -p_s` between contact times, so ``p_v`` is
   linear there: :math:`-p_v(t) = w(t) = a + bt - \sum_i\Phi_i(t-t_i)_+`;
2. *saturated law* (minimising ``H`` over the box): :math:`u = \operatorname{clip}(-p_v,\ell,h)`;
3. *switching times* :math:`\theta`: the roots of :math:`-p_v(\theta) = \ell` or
   :math:`= h`; ``u`` is continuous, linear between contact and switching times, constant
   (= the bound) where saturated;
4. *boundary conditions*: :math:`s(0)=s_0, v(0)=v_0, s(t_f)=s_f, v(t_f)=v_f`;
5. *interior points*: :math:`s_x(t_i) = x_{s,i}(t_i) \pm (L_i/2+S_{x,i})`,
   :math:`s_y(t_i) = y_{s,i}\pm(W_i/2+S_{y,i})`;
6. *co-state jumps*: :math:`p_s^-(t_i) = p_s^+(t_i) + \Phi_i`, ``p_v`` continuous;
7. *Hamiltonian jump* (free contact times):
   :math:`H^-(t_i) - H^+(t_i) - \dot x_{s,i}(t_i)\Phi_{i,x} = 0`.

For fixed contact times, 1–6 are the optimality conditions of a strictly convex problem per
axis (:mod:`~iamp.planners.pmp.saturated` solves them by a semi-smooth Newton method on the
concave dual).  Condition 7 is still :math:`\partial J/\partial t_i`: by the envelope theorem
on the dual :math:`J(t) = \max_\lambda D(\lambda; t)`,

.. math::  \frac{\partial J}{\partial t_i} = \sum_{\text{axis}} \lambda_i(\dot c_i - \dot s(t_i))
           = \sum_{\text{axis}} \Phi_i\,(v(t_i) - \dot c_i) = H^- - H^+ - \dot x_{s,i}\Phi_{i,x},

because only ``p_s`` jumps (``u``, ``p_v``, ``v`` are continuous), so
:math:`H^- - H^+ = \Phi_{i,x}v_x + \Phi_{i,y}v_y` with or without saturation (tested by finite
differences).  Along an extremal ``H`` is constant between contact times (the law is
autonomous), a further check of the switching structure.

**Contact times.**  The free times minimise :math:`J_b(t) = J_x(t) + J_y(t)`:

* if the unbounded global optimum (:class:`~iamp.planners.pmp.PMPPlanner`) respects the box,
  it is the bounded optimum too (:math:`J_b \ge J_u \ge J_u(t^*) = J_b(t^*)`): the unbounded
  plan is returned unchanged and stays ``optimal`` (certified global);
* otherwise a grid over :math:`(0,t_f)^m` (one vehicle: 16 points; two: 8×8) plus the
  unbounded ``t*`` as starts, then a polish on :math:`\partial J/\partial t = r(t)` (Brent's
  root on ``r`` for one vehicle, L-BFGS-B with the exact gradient ``r`` and a damped Newton
  polish otherwise).  One vehicle: an end of Brent's bracket where the box is infeasible is
  first moved to the edge of the feasible contact times (bisection), since ``J_b`` can fall
  all the way to that edge; a minimum *at* the edge is not stationary (``r ≠ 0``, pointing out
  of the feasible set), so the Hamiltonian-jump check is not applied there
  (``info["search"]["feasibility_edge"]``); if ``r`` turns again just inside the edge, the
  stationary minimum there is found instead (:func:`_edge_candidate`).  Beyond such an edge
  (``info["search"]["edge"]``) the certificate uses :mod:`~iamp.planners.pmp.reach` (a Farkas
  margin maximised over the multipliers, where the dual Newton method stalls).
  One vehicle: :func:`certify_global_one` covers
  ``(0, t_f)`` with intervals on which the closed-form unbounded bound
  :math:`J_b \ge J_u` (vectorised, no solve), a weak-duality Taylor bound or a Farkas margin
  stays above :math:`J^*(1 - 10^{-9})`; certified, the plan is ``optimal``, otherwise
  ``local``.  Several vehicles: ``local`` (no certificate); where the polish ends
  non-stationary next to an edge of the feasible contact times, :func:`_edge_polish` holds the
  time whose descent leaves the set at its edge (or at the stationary point just inside it) and
  polishes the others; a time left at the edge is excused from the Hamiltonian-jump check only
  with the KKT sign (:func:`_kkt_at_edges`; ``info["search"]["feasibility_edges"]``).
  Caller-given contact times give the fixed-time optimum, which is unique (strictly convex
  problem): ``optimal``.

**Self-check** (:func:`check_values`, tolerances ``pmp_bounded_*`` of
:mod:`iamp.core.tolerances`), every value dimensionless (time over ``t_f``, lengths over the
axis' data scale): boundary, corners (states integrated from the knots, independent of the
dual's integrals), saturation law at every knot and piece midpoint (``u`` against
``clip(−p_v)`` with ``p_v`` from ``a, b, Φ``), switching consistency (``−p_v(θ)`` = the bound),
the box, ``H`` constant between contact times, the Hamiltonian jump (free times), and the
duality gap (primal cost = dual value).

**Bounds the PMP cannot impose** (``vx``, ``y``, ``a_total``, ``jerk``) are checked on the
plan with exact peaks (:func:`exact_peaks`): satisfied, the plan is optimal for the bounded
problem too (``info["limits_note"]``); violated, status ``limits_violated`` with the peaks.
"""

from __future__ import annotations

import math
import time as _time
from bisect import bisect_right
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.status import INACCURATE, INFEASIBLE, LIMITS_VIOLATED, LOCAL, NUMERICAL_ERROR, OPTIMAL
from iamp.core.tolerances import TOLERANCES
from iamp.planners.pmp.diagnostics import BoundedPMPDiagnostics
from iamp.planners.pmp.saturated import (
    AxisInfeasible,
    AxisNoConvergence,
    AxisSolution,
    contact_points,
    cover_points,
    interval_terms,
    solve_axis,
    solve_axis_value,
)
from iamp.planners.pmp.saturated_kernel import INTERVAL_WIDTH, POINT_WIDTH, free_measure
from iamp.planners.pmp.verify import HJUMP_FLOOR

FloatArray = npt.NDArray[np.float64]
INF = math.inf

#: Grid points of the one-vehicle contact-time search (the starts of Brent's polish).
GRID_ONE = 16

#: Points per axis of the grid over ``(0, t_f)^m`` whose lower bound prunes the further starts of
#: the search with ``m`` = 2, 3, ≥ 4 vehicles (:func:`_pruned_grid`).  Of 38 generated
#: three-vehicle problems that ended in a costlier basin or ``inaccurate`` (scripts/bounded_sweep.py,
#: default_rng 7, 8, 10), 8, 10, 12 per axis brought 27, 29, 28 to a verified plan at or below the
#: FOH QP's sweep (the order of the contact times leaves many minima under a tight ``a_y`` box, so
#: a finer grid is lower on some and higher on others); two vehicles (default_rng 9): 16, 24, 42
#: per axis moved 0, 3, 2 of 4.  The lower bound costs ~0.1 µs a point (0.1 ms for 10³).
GRID_MANY = (24, 10, 6)
#: Ratio of the distances from ``t_best`` of the ends of the graded intervals that start the
#: one-vehicle certificate around its minimum (:func:`certify_global_one`): of 1.6, 2, 2.4, 3,
#: 2 had the fewest axis solves on paper-1 (66; 72 without grading, in 9 kernel calls
#: instead of 3) and on it with 8 boxed random problems (622 in 43 calls; 644 in 82 without).
CERT_GRADE = 2.0

#: How far inside the edge of the feasible contact times (over ``t_f``) the search reads the
#: slope ``r`` (at the edge the dual multipliers grow without bound).
EDGE_PROBE = 1e-6

#: A minimum at that edge is planned this far inside (over ``t_f``): at the edge itself the
#: multipliers' size turns the residual of F = 0 into a duality gap above its tolerance; the
#: cost this adds, ``|r| EDGE_BACKOFF t_f``, is far below the certificate's ``1e-9``.
EDGE_BACKOFF = 1e-10

#: Half-width (over ``t_f``) of the interval whose Taylor bound :func:`certify_global_one` takes
#: at an edge of the feasible contact times beside a stationary minimum (the bound's radius
#: there is about ``1e-9 t_f``; ``M`` only falls as the interval shrinks).
EDGE_TAYLOR = 1e-8

#: :func:`certify_global_one` tries :mod:`~iamp.planners.pmp.reach` on an interval left open by
#: the axis solve (a stall, or a Farkas margin below its Lipschitz rate) once halving has
#: narrowed it below this (over ``t_f``); wider ones are halved as before (most close so).
REACH_BELOW = 1e-4

#: Distances (over ``t_f``) past a feasibility edge found by bisection at which the one-vehicle
#: search looks for feasible times beyond an axis solve's stall (:func:`_feasible_edge`).
EDGE_BEYOND = (1e-11, 1e-10, 1e-9, 1e-8)

#: :func:`certify_global_one` stops where the dual value at an interval's centre (``J_b`` there)
#: is below ``J_best`` by this much (relative): the search missed a better contact time.
BETTER_REL = 1e-6

#: One vehicle: a root of ``r`` (or an edge candidate) polished in a bracket replaces the best
#: start or grid point also where its ``J_b`` is above that point's by at most this (relative):
#: the rounding of ``J_b``.  random_problem(817765) with the box at 0.9985 of its peaks: the
#: unbounded ``t*`` lies 8.7e-8 s from the root (``J_b`` 1.2e-13 above it in exact arithmetic),
#: but its ``J_b`` came out 7e-13 (relative) below the root's, so the plan stayed at ``t*``
#: (``r`` = -2.7e-6) and ended ``inaccurate`` (Hamiltonian jump 5.4e-7 against 1e-7).
STATIONARY_TIE_REL = 1e-10

#: Axis-pair solves of the thin-valley polish (:func:`_valley_polish`) from one start: several
#: vehicles where the search, the edge polish and the search without the finer grid all end
#: ``inaccurate``.  The 10 such problems of scripts/bounded_sweep.py (default_rng 7-10) verify
#: after 365-8226 solves from the start that verified (the budget is checked once per step, and
#: the judging where the steps end sweeps once more).
VALLEY_SOLVES = 8000

#: Newton iterations of :func:`_valley_polish` from one start.
VALLEY_ITERATIONS = 80

#: Cycles of :func:`_valley_sweep` before a step of :func:`_valley_polish` (its first two, and
#: after a step that did not halve ``max|r|``).
VALLEY_CYCLES = 3

#: The tolerance entry of each check of :func:`check_values`.
BOUNDED_TOLERANCE_OF = {
    "boundary": "pmp_bounded_residual",
    "corner": "pmp_bounded_residual",
    "saturation_law": "pmp_bounded_residual",
    "switching": "pmp_bounded_residual",
    "box": "pmp_bounded_residual",
    "hamiltonian_constant": "pmp_bounded_residual",
    "hamiltonian_jump": "pmp_hjump_rel",
    "duality_gap": "pmp_bounded_gap_rel",
}


def input_box(problem: Problem) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((ℓ_x, h_x), (ℓ_y, h_y))`` of ``problem.limits`` (``±inf`` where not given)."""
    lim = problem.limits
    bx = lim.ax if lim is not None and lim.ax is not None else (-INF, INF)
    by = lim.ay if lim is not None and lim.ay is not None else (-INF, INF)
    return (float(bx[0]), float(bx[1])), (float(by[0]), float(by[1]))


@dataclass
class BoundedSolution:
    """The saturated PMP solution at fixed contact times (both axes).

    ``axes[0]`` is x, ``axes[1]`` is y (:class:`~iamp.planners.pmp.saturated.AxisSolution`):
    knots (contact and switching times), ``u`` at the knots, ``a``, ``b`` and the jumps of
    ``w = −p_v``.  States are integrated exactly from the knots.
    """

    problem: Problem
    contact_times: FloatArray
    axes: tuple[AxisSolution, AxisSolution]

    def __post_init__(self) -> None:
        ego = self.problem.ego
        self._sv: list[tuple[list[float], list[float]]] = []
        for k, (s0, v0) in enumerate(((ego.x0, ego.vx0), (ego.y0, ego.vy0))):
            ax = self.axes[k]
            s, v = [s0], [v0]
            for j in range(len(ax.knots) - 1):
                h = ax.knots[j + 1] - ax.knots[j]
                ua, ub = ax.u[j], ax.u[j + 1]
                s.append(s[-1] + h * v[-1] + h * h * (ua / 3 + ub / 6))
                v.append(v[-1] + h / 2 * (ua + ub))
            self._sv.append((s, v))
        # the slope of u on every piece (what _axis_eval divides per point: the same numbers)
        self._slopes_l = [[(ax.u[j + 1] - ax.u[j]) / (h if h > 0 else 1.0)
                           for j, h in enumerate(ax.knots[q + 1] - ax.knots[q] for q in range(len(ax.knots) - 1))]
                          for ax in self.axes]
        self._hjump: tuple[FloatArray, FloatArray] | None = None
        self._ends_contacts: FloatArray | None = None

    @cached_property
    def _arr(self) -> list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
        """The knots, ``u``, ``s``, ``v`` per axis as arrays (made on the first evaluation at many
        times: the plan itself reads the knots on floats)."""
        return [(np.asarray(ax.knots), np.asarray(ax.u), np.asarray(s), np.asarray(v))
                for ax, (s, v) in zip(self.axes, self._sv)]

    @cached_property
    def _slopes(self) -> list[FloatArray]:
        return [np.asarray(sl, dtype=float) for sl in self._slopes_l]

    @cached_property
    def _jumps_arr(self) -> list[FloatArray]:
        return [np.asarray(ax.jumps) for ax in self.axes]

    def ends_and_contacts(self) -> FloatArray:
        """:meth:`states` at ``0``, ``t_f`` and the contact times (rows in that order), evaluated
        once on floats (:meth:`_axis_at`): the self-check and the Hamiltonian-jump terms both read
        them."""
        if self._ends_contacts is None:
            rows = []
            for x in (0.0, float(self.problem.tf), *self.contact_times.tolist()):
                sx, vx, _ = self._axis_at(0, x)
                sy, vy, _ = self._axis_at(1, x)
                rows.append((sx, vx, sy, vy))
            self._ends_contacts = np.array(rows, dtype=float).reshape(-1, 4)
        return self._ends_contacts

    @property
    def jumps(self) -> FloatArray:
        """``(Φ_i,x, Φ_i,y)`` per vehicle."""
        return np.array([[jx, jy] for jx, jy in zip(self.axes[0].jumps, self.axes[1].jumps)],
                        dtype=float).reshape(-1, 2)

    @property
    def cost(self) -> float:
        """``J = ½∫|u|²`` (exact, from the knots)."""
        total = 0.0
        for ax in self.axes:
            for j in range(len(ax.knots) - 1):
                h = ax.knots[j + 1] - ax.knots[j]
                ua, ub = ax.u[j], ax.u[j + 1]
                total += h / 6 * (ua * ua + ua * ub + ub * ub)
        return total

    def _axis_eval(self, k: int, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        kn, U, S, V = self._arr[k]
        j = np.minimum(np.maximum(np.searchsorted(kn, t, side="right") - 1, 0), len(kn) - 2)
        d = t - kn[j]
        slope = self._slopes[k][j]
        ua = U[j]
        u = ua + slope * d
        vv = V[j] + ua * d + slope * d * d / 2
        ss = S[j] + V[j] * d + ua * d * d / 2 + slope * d**3 / 6
        return ss, vv, u

    def _axis_at(self, k: int, t: float) -> tuple[float, float, float]:
        """:meth:`_axis_eval` at one time, on Python floats (the same operations in the same
        order; no array is made: :func:`exact_peaks` asks a few points of a small plan)."""
        ax = self.axes[k]
        kn, U, sl = ax.knots, ax.u, self._slopes_l[k]
        S, V = self._sv[k]
        j = min(max(bisect_right(kn, t) - 1, 0), len(kn) - 2)
        d = t - kn[j]
        slope = sl[j]
        ua = U[j]
        return (S[j] + V[j] * d + ua * d * d / 2 + slope * d**3 / 6, V[j] + ua * d + slope * d * d / 2,
                ua + slope * d)

    def states(self, t: Any) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at ``t`` → ``(len(t), 4)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sx, vx, _ = self._axis_eval(0, t)
        sy, vy, _ = self._axis_eval(1, t)
        return np.stack([sx, vx, sy, vy], axis=1)

    def states_inputs(self, t: Any) -> tuple[FloatArray, FloatArray]:
        """:meth:`states` and :meth:`inputs` at ``t`` from one evaluation per axis (the same numbers)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sx, vx, ux = self._axis_eval(0, t)
        sy, vy, uy = self._axis_eval(1, t)
        return np.stack([sx, vx, sy, vy], axis=1), np.stack([ux, uy], axis=1)

    def inputs(self, t: Any) -> FloatArray:
        """``(u_x, u_y)`` at ``t`` → ``(len(t), 2)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([self._axis_eval(0, t)[2], self._axis_eval(1, t)[2]], axis=1)

    def w(self, k: int, t: FloatArray) -> FloatArray:
        """``w = −p_v`` of axis ``k`` from ``a, b, Φ`` (not from the knots)."""
        ax = self.axes[k]
        ramps = np.maximum(t[:, None] - self.contact_times[None, :], 0.0)
        out: FloatArray = ax.a + ax.b * t - ramps @ self._jumps_arr[k]
        return out

    def costates(self, t: Any, side: str = "right") -> FloatArray:
        """``(p1, p2, p3, p4)`` at ``t`` (``side``: the one-sided limit of ``p1, p3`` at a contact time)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._costates(t, np.full(len(t), side == "left"))

    def _costates(self, t: FloatArray, left: Any) -> FloatArray:
        d = t[:, None] - self.contact_times[None, :]
        step = np.where(np.asarray(left)[:, None], d > 0, d >= 0).astype(float)
        cols = []
        for k in range(2):
            ax = self.axes[k]
            cols += [ax.b - step @ self._jumps_arr[k], -self.w(k, t)]
        return np.stack(cols, axis=1)

    def hamiltonian(self, t: Any, side: str = "right") -> FloatArray:
        """``H = ½|u|² + p1 v_x + p2 u_x + p3 v_y + p4 u_y``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._hamiltonian(t, np.full(len(t), side == "left"))

    def _hamiltonian(self, t: FloatArray, left: Any) -> FloatArray:
        """:meth:`hamiltonian` with the side per point (``left``: a boolean per ``t``)."""
        _, vx, ux = self._axis_eval(0, t)
        _, vy, uy = self._axis_eval(1, t)
        d = t[:, None] - self.contact_times[None, :]
        step = np.where(np.asarray(left)[:, None], d > 0, d >= 0).astype(float)
        # the columns of _costates, without stacking them (the same operations)
        p1 = self.axes[0].b - step @ self._jumps_arr[0]
        p3 = self.axes[1].b - step @ self._jumps_arr[1]
        out: FloatArray = (0.5 * (ux**2 + uy**2) + p1 * vx + (-self.w(0, t)) * ux
                           + p3 * vy + (-self.w(1, t)) * uy)
        return out

    def hamiltonian_jump_terms(self) -> tuple[FloatArray, FloatArray]:
        """``(r, size)``: ``r_i = H⁻ − H⁺ − ẋ_s,i Φ_i,x`` (= ``∂J/∂t_i``) and the size of its terms
        (computed once: the self-check and the plan's annotation both ask)."""
        if self._hjump is None:
            self._hjump = self._hamiltonian_jump_terms()
        return self._hjump[0].copy(), self._hjump[1].copy()

    def _hamiltonian_jump_terms(self, H: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """``(r, size)`` of :meth:`hamiltonian_jump_terms`; ``H``: :meth:`_hamiltonian` at the
        contact times, left then right limits, when the caller evaluated it already."""
        t = self.contact_times
        m = len(t)
        # ẋ_s(t_i) as Vehicle.speed gives it (_polyval repeats numpy's polyval on polyder's j·c_j)
        xdot = np.array([_polyval(_derivative([float(c) for c in np.asarray(v.x_poly, dtype=float)]), float(ti))
                         for v, ti in zip(self.problem.vehicles, t)])
        X = self.ends_and_contacts()[2:]
        J = self.jumps
        if H is None:
            H = self._hamiltonian(np.concatenate((t, t)),
                                  np.concatenate((np.ones(m, dtype=bool), np.zeros(m, dtype=bool))))
        r: FloatArray = H[:m] - H[m:] - xdot * J[:, 0]
        size = np.abs(J[:, 0]) * (np.abs(X[:, 1]) + np.abs(xdot)) + np.abs(J[:, 1]) * np.abs(X[:, 3])
        return r, size

    def hamiltonian_jump_residual(self) -> FloatArray:
        """``r_i`` (= ``∂J/∂t_i``, SPEC §2 identity 1, with the saturated law)."""
        return self.hamiltonian_jump_terms()[0]

    def switching_times(self) -> dict[str, list[float]]:
        """Switching times per axis (``"x"``, ``"y"``)."""
        return {name: [s[0] for s in ax.switching] for name, ax in zip("xy", self.axes)}

    def knots(self) -> list[float]:
        """Every time where ``u_x`` or ``u_y`` may kink (sorted, with ``0`` and ``t_f``)."""
        return sorted(set(self.axes[0].knots) | set(self.axes[1].knots))

    def breakpoints(self) -> list[float]:
        """The piece ends of the exact polynomial pieces (:mod:`iamp.core.trajectory_pieces`):
        the knots, since ``u`` is linear and the position cubic between them."""
        return self.knots()


def solve_bounded_fixed(problem: Problem, contact_times: Any, warm: list[list[float] | None] | None = None
                        ) -> BoundedSolution:
    """The saturated optimum at fixed contact times (both axes; :func:`solve_axis`).

    Raises :class:`~iamp.planners.pmp.saturated.AxisInfeasible` (with the axis in its
    message) or :class:`~iamp.planners.pmp.saturated.AxisNoConvergence`."""
    t = [float(x) for x in np.asarray(contact_times, dtype=float).reshape(-1)]
    ego = problem.ego
    T = float(problem.tf)
    C = problem.corners(np.asarray(t)).reshape(-1, 2)
    (lx, hx), (ly, hy) = input_box(problem)
    warm = warm or [None, None]
    axes = []
    for k, (s0, v0, sf, vf, lo, hi) in enumerate(((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx),
                                                   (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))):
        try:
            axes.append(solve_axis(t, T, s0, v0, sf, vf, [float(c) for c in C[:, k]], lo, hi, warm[k]))
        except AxisInfeasible as exc:
            raise AxisInfeasible(f"{'xy'[k]} axis: {exc}", exc.certificate, exc.margin) from None
    return BoundedSolution(problem, np.asarray(t, dtype=float), (axes[0], axes[1]))


def boundary_feasible(problem: Problem) -> str | None:
    """``None`` if the box can meet the boundary conditions alone, else the reason (a
    Farkas certificate checked exactly, per axis)."""
    ego = problem.ego
    (lx, hx), (ly, hy) = input_box(problem)
    for name, (s0, v0, sf, vf, lo, hi) in (("x", (ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx)),
                                           ("y", (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))):
        if solve_axis_value([], float(problem.tf), s0, v0, sf, vf, [], lo, hi) is not None:
            continue  # converged (the same solve, without building its AxisSolution)
        try:
            solve_axis([], float(problem.tf), s0, v0, sf, vf, [], lo, hi)
        except AxisInfeasible as exc:
            return (f"the {name} boundary conditions are out of reach with u_{name} in [{lo:g}, {hi:g}] "
                    f"m/s² over t_f = {problem.tf:g} s ({exc})")
        except AxisNoConvergence:
            continue
    return None


@dataclass(frozen=True)
class InfeasibilityCertificate:
    """Outcome of :func:`infeasibility_certificate`.

    Attributes
    ----------
    certified : bool
        The box is infeasible for every choice of contact times.
    feasible_t : numpy.ndarray or None
        Contact times [s] where both axes are feasible (the search stops there), else ``None``.
    boxes : int
        Boxes (intervals for one vehicle) covered by a Farkas certificate.
    solves : int
        Axis solves spent (the work budget counts these).
    vehicle : int or None
        Certified by the vehicle of this index alone (the projection argument), ``None`` when
        the certificate is over all the vehicles' contact times.
    pair : tuple of int or None
        Certified by the two vehicles of these indices alone (the projection on pairs, ``m ≥ 3``).
    """

    certified: bool
    feasible_t: FloatArray | None
    boxes: int
    solves: int
    vehicle: int | None = None
    pair: tuple[int, int] | None = None


#: a single vehicle's share of the budget of :func:`infeasibility_certificate` (``m ≥ 2``):
#: ``max_solves // (PROJECTION_SHARE · m)`` each
PROJECTION_SHARE = 4

#: The axis solves of each pair's cover in the projection on pairs (:func:`infeasibility_certificate`
#: with ``pair_solves``, ``m ≥ 3``): one pass per pair, which goes on past centres where both axes
#: are feasible (those boxes stay open) so that its certified boxes can prune the full cover.
PAIR_TREE_SOLVES = 6000

#: :func:`pair_projection` resumes a pair's cover that met no feasible centre (it may close) by
#: another :data:`PAIR_TREE_SOLVES` while this many solves stay for the pruned full cover.
PAIR_KEEP_SOLVES = 6000

#: The axis solves :func:`plan_bounded` gives :func:`pair_projection` (``m ≥ 3``, once the single
#: vehicles, the 4000-solve cover and the product of each vehicle's feasible times have neither
#: certified nor found a plan).  Of 23 generated three-vehicle problems that ended ``infeasible``
#: uncertified (``random_problem(seed, m=3)``, box at 0.40-1.20 of the peaks, 246 drawn by
#: ``numpy.random.default_rng(1)``; the FOH QP at ``N = 8`` without a plan on all): 9 are now
#: certified by a pair, 2 by a single vehicle (the box rate of :func:`_box_rate`), 9 have a plan
#: (the pruned cover meets feasible contact times; the FOH QP at ``N = 240`` through the plan's
#: contact times agrees), 3 stay uncertified (758025 at 0.595 has a plan, which a cover pruned by
#: pairs of 30 000 solves each meets after 97 000 solves; the FOH QP at ``N = 240`` confirms it).
#: Of 24 more (200 drawn by ``default_rng(2)``): 17 certified, 4 plans, 3 uncertified.  With
#: 20 000 instead, of the 47: 2 plans and 5 certificates fewer, the slowest 0.70 s instead of
#: 0.79 s CPU (compiled axis solve).  50 000 (was 30 000): of the 9 uncertified ``infeasible``
#: of scripts/bounded_sweep.py's 1500 draws (default_rng 7-10), random_problem(523914, m=3) under
#: an ``a_x`` box at 0.5556 has a plan (``local`` 2057.56 after 36 613 solves; the FOH QP at
#: ``N = 240`` through its contact times 2057.99, its sweep at ``N = 8`` none) and (621997, m=2)
#: at 0.6034 is certified (47 661 solves); the 446 problems of default_rng 1 and 2 above end
#: as with 30 000 (every status and cost), the slowest uncertified 0.73 -> 1.55 s CPU; of
#: scripts/bounded_three_census.py --rng 7 --count 120, 215004 at 0.6403 has a plan (local
#: 14710.587; the FOH QP at N = 240 through its contact times 14710.672), the rest as before.
PAIR_SOLVES = 50000


def infeasibility_certificate(problem: Problem, max_solves: int = 4000,
                              pair_solves: int = 0) -> InfeasibilityCertificate:
    r"""Is the box infeasible for *every* choice of contact times in ``(0, t_f)^m``?

    **Projection** (``m ≥ 2``, tried first).  A plan for all ``m`` vehicles meets each
    vehicle's corner at that vehicle's contact time with ``u`` in the box, so it is also a plan
    for the problem with that vehicle alone.  If one vehicle alone is certified infeasible at
    every contact time in ``(0, t_f)`` (the one-vehicle cover below, on 32 intervals), the
    whole problem is infeasible.  Each vehicle, in order, gets the budget
    ``max_solves // (PROJECTION_SHARE · m)``; the full cover gets what is left.  (A cover stops
    refining once its budget is spent; its initial boxes are always solved, so a cover may
    end up to two solves per initial box above its budget.)

    **Pairs** (``m ≥ 3`` and ``pair_solves > 0``, after the single vehicles).  The same argument
    for two vehicles: a plan for all ``m`` is a plan for the problem with vehicles ``i`` and
    ``j`` alone, at their contact times.  So the full problem is infeasible on every box of
    contact times whose projection :math:`[a_i, b_i]\times[a_j, b_j]` lies in the union of the
    boxes that pair's cover certified (:func:`_tree_covers`); if a pair's cover certifies all of
    ``(0, t_f)²``, the whole problem is infeasible.  Tried once the full cover below has
    neither certified nor found a feasible centre within ``max_solves``: each pair's cover gets
    :data:`PAIR_TREE_SOLVES` (while ``pair_solves`` last) and goes on past feasible centres
    (those boxes stay open); a pair's cover that met no feasible centre is resumed once with as
    many more while :data:`PAIR_KEEP_SOLVES` remain; then the full cover again, pruned by every
    pair's certified boxes,
    gets the rest of ``pair_solves`` and stops at the first centre where both axes are feasible
    (``feasible_t``: contact times with a plan, where the search starts again).  These solves
    are counted apart from ``max_solves``.  Two vehicles are their own pair: the full cover gets
    ``pair_solves`` more (random_problem(579407, m=2) with a box on ``a_x`` alone at 0.624 of its
    peaks: uncertified at 4000 solves, certified with 17 972).

    **Cover** (:func:`_cover_infeasible`): boxes of contact times, each with a Farkas certificate
    and a Lipschitz margin.
    """
    m = problem.m
    used = 0
    if m >= 2:
        share = max_solves // (PROJECTION_SHARE * m)
        for i, veh in enumerate(problem.vehicles):
            alone = _cover_infeasible(problem.with_vehicles([veh]), share)
            used += alone.solves
            if alone.certified:
                return InfeasibilityCertificate(True, None, alone.boxes, used, i)
    full = _cover_infeasible(problem, max_solves - used + (pair_solves if m == 2 else 0))
    used += full.solves
    if full.certified or full.feasible_t is not None or m < 3 or pair_solves <= 0:
        return InfeasibilityCertificate(full.certified, full.feasible_t, full.boxes, used)
    pairs = pair_projection(problem, pair_solves)
    return InfeasibilityCertificate(pairs.certified, pairs.feasible_t, pairs.boxes, used + pairs.solves,
                                    pair=pairs.pair)


def pair_projection(problem: Problem, pair_solves: int) -> InfeasibilityCertificate:
    """The projection on pairs of vehicles and the full cover it prunes (``m ≥ 3``; the second
    part of :func:`infeasibility_certificate`), within about ``pair_solves`` axis solves."""
    m = problem.m
    T = float(problem.tf)
    trees: list[tuple[int, int, dict[tuple[float, ...], tuple[Any, ...]]]] = []
    closed: list[tuple[int, int, dict[tuple[float, ...], tuple[Any, ...]]]] = []
    spent = 0
    for i in range(m):
        for j in range(i + 1, m):
            if spent >= pair_solves:
                break
            tree: dict[tuple[float, ...], tuple[Any, ...]] = {}
            two = _cover_infeasible(problem.with_vehicles([problem.vehicles[i], problem.vehicles[j]]),
                                    min(PAIR_TREE_SOLVES, pair_solves - spent), tree)
            spent += two.solves
            if two.certified:
                return InfeasibilityCertificate(True, None, two.boxes, spent, pair=(i, j))
            trees.append((i, j, tree))
            if two.feasible_t is None:
                closed.append((i, j, tree))
    for i, j, tree in closed:  # no feasible centre met: the cover goes on where it stopped
        budget = min(PAIR_TREE_SOLVES, pair_solves - spent - PAIR_KEEP_SOLVES)
        if budget <= 0:
            break
        two = _cover_infeasible(problem.with_vehicles([problem.vehicles[i], problem.vehicles[j]]), budget, tree)
        spent += two.solves
        if two.certified:
            return InfeasibilityCertificate(True, None, two.boxes, spent, pair=(i, j))
    edges = [T * k / 8 for k in range(9)]  # the two-vehicle cover's first grid
    seen: dict[tuple[float, ...], bool] = {}

    def prune(a: FloatArray, b: FloatArray) -> bool:
        for i, j, tree in trees:
            key = (i, j, float(a[i]), float(a[j]), float(b[i]), float(b[j]))
            hit = seen.get(key)
            if hit is None:
                hit = seen[key] = _tree_covers(tree, edges, (key[2], key[3]), (key[4], key[5]))
            if hit:
                return True
        return False

    full = _cover_infeasible(problem, pair_solves - spent, prune=prune)
    return InfeasibilityCertificate(full.certified, full.feasible_t, full.boxes, spent + full.solves)


def _tree_covers(tree: dict[tuple[float, ...], tuple[Any, ...]], edges: list[float], pa: tuple[float, float],
                 pb: tuple[float, float]) -> bool:
    """Whether the boxes a two-vehicle cover certified (its ``tree``: each box's corners ``(a, b)``
    to ``("c",)`` certified, ``("s", i, mid)`` halved at ``mid`` along ``i``, ``("o",)`` open;
    absent: not reached) contain the rectangle ``[pa, pb]``: the rectangle is cut along the cover's
    first grid (``edges`` per axis) and its halvings, each piece needing a certified box."""
    stack: list[tuple[tuple[float, float], tuple[float, float], tuple[float, float], tuple[float, float]]] = []
    for k0 in range(len(edges) - 1):
        if not (edges[k0] < pb[0] and edges[k0 + 1] > pa[0]):
            continue
        for k1 in range(len(edges) - 1):
            if not (edges[k1] < pb[1] and edges[k1 + 1] > pa[1]):
                continue
            a, b = (edges[k0], edges[k1]), (edges[k0 + 1], edges[k1 + 1])
            stack.append((a, b, (max(pa[0], a[0]), max(pa[1], a[1])), (min(pb[0], b[0]), min(pb[1], b[1]))))
    while stack:
        a, b, qa, qb = stack.pop()
        node = tree.get((*a, *b))
        if node is None or node[0] == "o":
            return False
        if node[0] == "c":
            continue
        _, k, mid = node
        lo_b = (mid, b[1]) if k == 0 else (b[0], mid)
        hi_a = (mid, a[1]) if k == 0 else (a[0], mid)
        if qb[k] <= mid:
            stack.append((a, lo_b, qa, qb))
        elif qa[k] >= mid:
            stack.append((hi_a, b, qa, qb))
        else:
            stack.append((a, lo_b, qa, (mid, qb[1]) if k == 0 else (qb[0], mid)))
            stack.append((hi_a, b, (mid, qa[1]) if k == 0 else (qa[0], mid), qb))
    return True


def _frontier(tree: dict[tuple[float, ...], tuple[Any, ...]], first: list[tuple[FloatArray, FloatArray]]
              ) -> list[tuple[FloatArray, FloatArray]]:
    """The boxes a cover recorded in ``tree`` left undecided: those of its first grid ``first``
    never reached, then each halved box's halves not recorded, in the cover's order.  They and
    the recorded boxes partition the contact times, so covering them finishes the cover."""
    out = [(a, b) for a, b in first if (*a.tolist(), *b.tolist()) not in tree]
    n = len(first[0][0]) if first else 0
    for key, node in tree.items():
        if node[0] != "s":
            continue
        _, i, mid = node
        a, b = np.array(key[:n]), np.array(key[n:])
        lo_b, hi_a = b.copy(), a.copy()
        lo_b[i] = hi_a[i] = mid
        for child in ((a, lo_b), (hi_a, b)):
            if (*child[0].tolist(), *child[1].tolist()) not in tree:
                out.append(child)
    return out


def certify_infeasible(problem: Problem, max_solves: int = 4000) -> tuple[bool, FloatArray | None, int]:
    """``(certified, feasible_t, boxes)`` of :func:`infeasibility_certificate` (the projection
    on single vehicles first, then the cover of :func:`_cover_infeasible`)."""
    cert = infeasibility_certificate(problem, max_solves)
    return cert.certified, cert.feasible_t, cert.boxes


def _cover_infeasible(problem: Problem, max_solves: int, tree: dict[tuple[float, ...], tuple[Any, ...]] | None = None,
                      prune: Any = None) -> InfeasibilityCertificate:
    r"""Is the box infeasible for *every* choice of contact times in ``(0, t_f)^m``?

    ``(0, t_f)^m`` is covered by boxes (32
    intervals for one vehicle, an 8×8 grid for two, 4 per axis beyond); at the centre ``t`` of
    each, an axis whose fixed-time problem is infeasible gives a Farkas certificate
    :math:`\lambda` with margin :math:`M(t) = \lambda^\top d(t) - \sigma_t(\lambda) > 0`
    (physical units).  Moving contact time ``i`` changes only its ramp :math:`(t_i-\tau)_+`
    and :math:`d_i(t_i) = c_i(t_i) - s_0 - v_0 t_i`, so with the same :math:`\lambda`

    .. math::  |M(t') - M(t)| \le \sum_i |t_i'-t_i|\,|\lambda_i|\,L_i,\qquad
               L_i = \max_{\tau\in[a_i,b_i]}\ \max_{q\in\{\ell,h\}}|\dot c_i(\tau) - v_0 - q\,\tau|

    over the box :math:`\prod_i[a_i, b_i]` (:func:`_box_rate`): moving ``t_i`` alone by ``s``
    changes :math:`\lambda^\top d` by :math:`\lambda_i\int(\dot c_i - v_0)` over the path, and
    :math:`\sigma = \int\max(hw, \ell w)` by :math:`\lambda_i\int q(\tau)\Delta(\tau)\,d\tau`
    with :math:`\Delta = (t_i+s-\tau)_+ - (t_i-\tau)_+` of one sign and the difference quotient
    ``q`` of ``max(h·, ℓ·)`` in :math:`[\ell, h]`; :math:`\int\Delta = \int_{t_i}^{t_i+s}\tau'\,d\tau'`,
    so the change is :math:`\lambda_i\int_{t_i}^{t_i+s}(\dot c_i(\tau') - v_0 - Q\tau')\,d\tau'`
    for some :math:`Q\in[\ell, h]`, whose size the maximum over ``q ∈ {ℓ, h}`` bounds (linear in
    ``q``); the times are moved one after the other.  (It was the larger, box-independent
    :math:`\max|\dot c_i| + |v_0| + \max(|\ell|,|h|)\,t_f`.)  A box of half-widths ``δ_i`` with
    :math:`M(t) > \sum_i δ_i|\lambda_i|L_i` is infeasible throughout, otherwise it is halved
    along its longest side.  A centre where both axes are feasible ends the search
    (``feasible_t``); so does the budget ``max_solves`` (``certified`` False).

    ``m ≥ 2`` only: with ``tree`` (a dict, filled in) every box reached is recorded (see
    :func:`_tree_covers`) and a box with a feasible centre stays open while the others go on
    (``feasible_t`` the first such centre, ``certified`` False); a ``tree`` that is not empty is
    resumed from the boxes it left undecided (:func:`_frontier`; ``boxes`` and ``solves`` then
    count this run only, ``certified`` whether all of them closed); ``prune(a, b)`` True counts a
    box as infeasible without a solve (a projection certified, :func:`infeasibility_certificate`).
    """
    m = problem.m
    ego = problem.ego
    T = float(problem.tf)
    (lx, hx), (ly, hy) = input_box(problem)
    axes_data = ((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx), (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))
    per_axis = 32 if m == 1 else 8 if m == 2 else 4
    edges = [T * j / per_axis for j in range(per_axis + 1)]
    stack: deque[tuple[FloatArray, FloatArray]] = deque()  # breadth first: a feasible region shows early
    for idx in np.ndindex(*([per_axis] * m)):
        stack.append((np.array([edges[j] for j in idx]), np.array([edges[j + 1] for j in idx])))
    if tree:  # resumed: the boxes the earlier run left undecided, in its order
        stack = deque(_frontier(tree, list(stack)))
    if m == 1:
        return _cover_one(problem, max_solves, edges)
    # the corners as problem.corners gives them (_polyval repeats numpy's polyval), without
    # an array per box; both axes of every box of a level solved in one kernel call
    # (:func:`~iamp.planners.pmp.saturated.cover_points`: solve_axis's numbers and Farkas test),
    # the boxes then read in order with the decisions, counters and budget of one box at a time
    pos = [[float(c) for c in np.asarray(v.x_poly, dtype=float)] for v in problem.vehicles]
    ders = [_derivative(c) for c in pos]
    rates: dict[tuple[int, int, float, float], float] = {}
    off = [(float(v.offset_x), float(v.corner_y)) for v in problem.vehicles]
    data = [float(x) for row in axes_data for x in row]
    width = m + 3
    solves = boxes = 0
    level = list(stack)
    feasible_t: FloatArray | None = None
    while level:
        if prune is not None:
            kept = [(a, b) for a, b in level if not prune(a, b)]
            boxes += len(level) - len(kept)
            level = kept
        centres = []
        flat_t: list[float] = []
        flat_c: list[float] = []
        for a, b in level:
            t = 0.5 * (a + b)
            times = [float(x) for x in t]
            distinct = len(set(times)) == m
            centres.append((t, distinct))
            if distinct:
                flat_t += times
                flat_c += [_polyval(pos[i], times[i]) + off[i][0] for i in range(m)]
                flat_c += [off[i][1] for i in range(m)]
        raw = cover_points(flat_t, flat_c, m, T, data) if flat_t else []
        nxt: list[tuple[FloatArray, FloatArray]] = []
        p = 0
        for (a, b), (t, distinct) in zip(level, centres):
            if distinct:
                half = 0.5 * (b - a)
                covered = False
                converged = 0
                for k in range(2):
                    solves += 1
                    o = (2 * p + k) * width
                    if raw[o] == 0.0:
                        converged += 1
                    elif raw[o] == 1.0:  # AxisInfeasible with its certificate
                        rate = 0.0
                        for i in range(m):
                            key = (k, i, float(a[i]), float(b[i]))
                            L = rates.get(key)
                            if L is None:  # boxes share their sides: each side's rate once
                                L = rates[key] = _box_rate(ders[i] if k == 0 else [0.0], axes_data[k], key[2], key[3])
                            rate += half[i] * abs(raw[o + 2 + i]) * L
                        if raw[o + 1] > rate * (1 + 1e-9):
                            covered = True
                            break
                p += 1
                if covered:
                    boxes += 1
                    if tree is not None:
                        tree[(*a.tolist(), *b.tolist())] = ("c",)
                    continue
                # both axes feasible at t?  solve_bounded_fixed solves the same axes from the
                # same start (the same numbers), so it can succeed only where both converged
                if converged == 2:
                    try:
                        solve_bounded_fixed(problem, t)
                        if tree is None:
                            return InfeasibilityCertificate(False, t, boxes, solves)
                        feasible_t = t if feasible_t is None else feasible_t
                        tree[(*a.tolist(), *b.tolist())] = ("o",)
                        continue
                    except (AxisInfeasible, AxisNoConvergence):
                        pass
            if solves > max_solves or float(np.max(b - a)) < 1e-9 * T:
                return InfeasibilityCertificate(False, feasible_t, boxes, solves)
            i_max = int(np.argmax(b - a))
            if tree is not None:
                tree[(*a.tolist(), *b.tolist())] = ("s", i_max, float(t[i_max]))
            mid_b, mid_a = b.copy(), a.copy()
            mid_b[i_max] = mid_a[i_max] = t[i_max]
            nxt += [(a, mid_b), (mid_a, b)]
        level = nxt
    return InfeasibilityCertificate(feasible_t is None, feasible_t, boxes, solves)


def _box_rate(der: list[float], axis: tuple[float, ...], a: float, b: float) -> float:
    r"""``L_i`` of :func:`_cover_infeasible` on the contact times ``[a, b]``: the largest
    :math:`|\dot c(\tau) - v_0 - q\tau|` over ``τ ∈ [a, b]`` and ``q ∈ {ℓ, h}`` (``der``: the
    coefficients of :math:`\dot c`, ascending, at most quadratic; ``[0.0]`` for ``y``, whose corner
    does not move; ``axis``: ``(s0, v0, sf, vf, ℓ, h)``), from the ends and the vertex inside;
    widened by a relative ``1e-12`` (rounding), ``inf`` for an unbounded side.  (A corner of higher
    degree than cubic: the coefficients' bound of ``|ċ|`` on ``[0, b]``, ``b ≥ 0``.)"""
    v0, lo, hi = axis[1], axis[4], axis[5]
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return INF
    if len(der) > 3:  # a corner of higher degree: |ċ| by its coefficients, |q τ| by the box's end
        return (sum(abs(x) * b**k for k, x in enumerate(der)) + abs(v0) + max(abs(lo), abs(hi)) * b) * (1 + 1e-12)
    c = [*der, 0.0, 0.0, 0.0][:3]
    best = 0.0
    for q in (lo, hi):
        f0, f1, f2 = c[0] - v0, c[1] - q, c[2]
        pts = [a, b]
        if f2 != 0.0 and a < -f1 / (2 * f2) < b:
            pts.append(-f1 / (2 * f2))
        for x in pts:
            v = abs(f0 + (f1 + f2 * x) * x)
            if v > best:
                best = v
    return best * (1 + 1e-12)


def _cover_one(problem: Problem, max_solves: int, edges: list[float]) -> InfeasibilityCertificate:
    """:func:`_cover_infeasible` for one vehicle, one breadth-first level of intervals at a
    time: both axes at every centre of a level in one kernel call
    (:func:`~iamp.planners.pmp.saturated.contact_points`, cold starts, with the Farkas test of
    :func:`~iamp.planners.pmp.saturated.solve_axis` where an axis does not converge), then the
    intervals read in order with the decisions, counters and budget of the general loop (an
    axis counts as a solve where that loop solves it: the second axis of an interval the first
    covers is solved in the same call but not counted).  The same numbers as the general loop:
    a feasible interval is one whose two axes converge."""
    veh, ego = problem.vehicles[0], problem.ego
    T = float(problem.tf)
    (lx, hx), (ly, hy) = input_box(problem)
    data = [float(x) for x in (ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx, ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy)]
    pos = [float(c) for c in np.asarray(veh.x_poly, dtype=float)]
    der = _derivative(pos)
    axes = (tuple(data[:6]), tuple(data[6:]))
    off_x, off_y = float(veh.offset_x), float(veh.corner_y)
    level = [(edges[j], edges[j + 1]) for j in range(len(edges) - 1)]
    W = POINT_WIDTH
    solves = boxes = 0
    while level:
        centres = [float(0.5 * (np.float64(a) + np.float64(b))) for a, b in level]
        raw = contact_points(centres, T, pos, off_x, off_y, data, [0.0] * (6 * len(level)), [0.0] * (2 * len(level)),
                             False)
        nxt: list[tuple[float, float]] = []
        for q, (a, b) in enumerate(level):
            t = centres[q]
            half = float(0.5 * (np.float64(b) - np.float64(a)))
            covered = converged = False
            both = True
            for k in range(2):
                solves += 1
                o = (2 * q + k) * W
                converged = raw[o] == 0.0
                both = both and converged
                if not converged and raw[o + 1] == 1.0:  # a Farkas certificate
                    rate = 0 + half * abs(raw[o + 3]) * _box_rate(der if k == 0 else [0.0], axes[k], a, b)
                    if raw[o + 2] > rate * (1 + 1e-9):
                        covered = True
                        break
            if covered:
                boxes += 1
                continue
            if both:  # both axes feasible at t
                return InfeasibilityCertificate(False, np.array([t]), boxes, solves)
            if solves > max_solves or b - a < 1e-9 * T:
                return InfeasibilityCertificate(False, None, boxes, solves)
            nxt += [(a, t), (t, b)]
        level = nxt
    return InfeasibilityCertificate(True, None, boxes, solves)


class _IntervalBound:
    """The data of :func:`interval_bound` for one problem (one vehicle)."""

    def __init__(self, problem: Problem):
        ego, veh = problem.ego, problem.vehicles[0]
        self.problem, self.veh, self.T = problem, veh, float(problem.tf)
        T = self.T
        (lx, hx), (ly, hy) = input_box(problem)
        d1 = [k * c for k, c in enumerate(veh.x_poly)][1:]
        d2 = [k * c for k, c in enumerate(d1)][1:]
        cdot_max = sum(abs(c) * T**k for k, c in enumerate(d1))
        self.cddot_max = (sum(abs(c) * T**k for k, c in enumerate(d2)), 0.0)
        self.axes_data = ((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx), (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))
        self.pos = [float(c) for c in np.asarray(veh.x_poly, dtype=float)]
        self.der = _derivative(self.pos)
        self.off = (float(veh.offset_x), float(veh.corner_y))
        self.flat_data = [float(x) for row in self.axes_data for x in row]
        self.lip_rate = tuple(cd + abs(v0) + max(abs(lo), abs(hi)) * T
                              if math.isfinite(lo) and math.isfinite(hi) else INF
                              for cd, (_, v0, _, _, lo, hi) in zip((cdot_max, 0.0), self.axes_data))

    def __call__(self, a: float, b: float, warm: list[list[float] | None]
                 ) -> tuple[str, float, list[list[float] | None], int]:
        """``(kind, value, multipliers, solves)`` on ``[a, b]``: ``("bound", B)`` with
        :math:`J_b \\ge B` on the interval, ``("infeasible", margin)`` when a Farkas margin
        covers it, ``("unknown", nan)`` when an axis is infeasible without enough margin or
        its solve stalls."""
        kind, value, lams, solves, _ = self.many([(a, b, warm)])[0]
        return kind, value, lams, solves

    def many(self, intervals: list[tuple[float, float, list[list[float] | None]]]
             ) -> list[tuple[str, float, list[list[float] | None], int, tuple[float, float, float]]]:
        """:meth:`__call__` on every interval, both axes at every centre in one kernel call
        (:func:`~iamp.planners.pmp.saturated.contact_points`, warm from each interval's
        multipliers); each with the terms ``(D, |r|, M)`` of its bound
        :math:`D - |r|\\rho - \\tfrac12 M\\rho^2`, valid on every sub-interval ``t ± ρ``
        (``M`` only falls as the interval shrinks)."""
        if not intervals:
            return []
        zeros = [0.0, 0.0, 0.0]
        ab = [x for a, b, _ in intervals for x in (a, b)]
        warm_flat = [x for _, _, warm in intervals for lam in warm for x in (zeros if lam is None else lam)]
        has = [0.0 if lam is None else 1.0 for _, _, warm in intervals for lam in warm]
        raw = interval_terms(ab, self.T, self.pos, self.der, self.off[0], self.off[1], self.flat_data, warm_flat, has,
                             self.cddot_max[0])
        W = INTERVAL_WIDTH
        out: list[tuple[str, float, list[list[float] | None], int, tuple[float, float, float]]] = []
        nan3 = (math.nan, math.nan, math.nan)
        for q, (a, b, warm) in enumerate(intervals):
            o = q * W
            bad = int(raw[o])
            lams: list[list[float] | None] = [raw[o + 5:o + 8] if bad != 0 else None,
                                              raw[o + 8:o + 11] if bad < 0 else None]
            if bad < 0:
                out.append(("bound", raw[o + 1], lams, 2, (raw[o + 2], raw[o + 3], raw[o + 4])))
            else:  # not converged: the axis solve itself looks for a Farkas certificate
                result = self._not_converged(bad, 0.5 * (a + b), 0.5 * (b - a), warm[bad], lams, bad + 1)
                out.append((*result, nan3))
        return out

    def _not_converged(self, k: int, t: float, delta: float, warm: list[float] | None,
                       lams: list[list[float] | None], solves: int
                       ) -> tuple[str, float, list[list[float] | None], int]:
        s0, v0, sf, vf, lo, hi = self.axes_data[k]
        corner = _polyval(self.pos, t) + self.off[0] if k == 0 else self.off[1]
        try:
            solve_axis([t], self.T, s0, v0, sf, vf, [float(corner)], lo, hi, warm)
        except AxisInfeasible as exc:
            if exc.lam_phys is not None and exc.margin_phys is not None:
                rate = delta * abs(exc.lam_phys[0]) * self.lip_rate[k]
                if exc.margin_phys > rate * (1 + 1e-9):
                    return "infeasible", exc.margin_phys - rate, lams, solves
        except AxisNoConvergence:
            pass
        return "unknown", math.nan, lams, solves


#: the free-time term of ``M`` (one implementation, in the kernel); kept under its former name
_free_measure = free_measure


def _certified_radius(dual: float, slope: float, M: float, target: float) -> float:
    """The largest ``ρ`` (less a relative ``1e-6``) with :math:`D - |r|\\rho - \\tfrac12 M\\rho^2 \\ge`
    ``target`` (``0`` if none), checked by evaluating the bound at it."""
    gap = dual - target
    if not (gap > 0 and math.isfinite(gap) and math.isfinite(slope) and math.isfinite(M)):
        return 0.0
    rho = 2 * gap / (slope + math.sqrt(slope * slope + 2 * M * gap)) if slope > 0 or M > 0 else INF
    rho *= 1 - 1e-6
    if not math.isfinite(rho) or dual - slope * rho - 0.5 * M * rho * rho < target:
        return 0.0
    return rho


class _UnboundedBound:
    """``J_b >= J_u`` on intervals of contact times (one vehicle): the unbounded value
    function's rigorous box bound (:func:`iamp.planners.pmp.bound.lower_bound`), closed form
    and vectorised; also ``J_u`` at the centres (where it is above the target, splitting alone
    may close the interval, without an axis solve)."""

    def __init__(self, problem: Problem, vf: Any = None):
        self.vf = _unbounded_value(problem) if vf is None else vf
        self.T = float(problem.tf)

    def __call__(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        from iamp.planners.pmp import search_kernels as sk

        vf, T = self.vf, self.T
        c = np.ascontiguousarray((0.5 * (a + b) / T)[:, None])
        r = np.ascontiguousarray((0.5 * (b - a) / T)[:, None])
        # the kernels of bound.lower_bound and ValueFunction.quad_sigma, compiled with the axis
        # solve when it is (compiled.load_axis), else as those call them: the same numbers
        bound = sk.kernel("lower_bound")
        quad = sk.kernel("quad")
        with np.errstate(all="ignore"):
            lb = (vf.scaled.jbar + 0.5 * bound(vf._EX, vf._EY, vf._DEX, vf._DEY, c, r)) * vf.units.cost
            centre = (vf.scaled.jbar + 0.5 * quad(vf._EX, vf._EY, c)) * vf.units.cost
        return np.where(np.isfinite(lb), lb, -INF), np.where(np.isnan(centre), -INF, centre)


def interval_bound(problem: Problem, a: float, b: float) -> tuple[str, float]:
    """A lower bound of :math:`J_b` on the contact-time interval ``[a, b]`` (one vehicle;
    :func:`certify_global_one`): ``("bound", B)``, ``("infeasible", margin)`` or
    ``("unknown", nan)``."""
    kind, value, _, _ = _IntervalBound(problem)(a, b, [None, None])
    return kind, value


def certify_global_one(problem: Problem, J_best: float, rel: float | None = None, max_solves: int = 3000,
                       value_function: Any = None, t_best: float | None = None,
                       warm_best: list[list[float] | None] | None = None, edge: tuple[str, float] | None = None,
                       warm_edge: list[list[float] | None] | None = None) -> dict[str, Any]:
    r"""One vehicle: is ``J_best`` the global minimum of :math:`J_b(t)` over ``(0, t_f)`` to the
    relative accuracy ``rel`` (default ``pmp_global_certificate_rel``)?

    **Bound.** For one axis at a contact time :math:`t` with dual optimum :math:`\bar\lambda`,
    weak duality gives :math:`J(t') \ge D(\bar\lambda; t')` for *every* :math:`t'`.  At fixed
    :math:`\bar\lambda` only :math:`g_1 = (t'-\tau)_+` and :math:`d_1(t') = c(t') - s_0 - v_0t'`
    move, so (:math:`\psi(w) = \min_{u\in[\ell,h]}\tfrac12u^2 - wu`, :math:`\psi' = -u_\lambda`)

    .. math::

        \partial_{t'}D = -\Phi\big(\dot c(t') - v_0 - \textstyle\int_0^{t'}u_\lambda\big),\qquad
        \partial^2_{t'}D = -\Phi\ddot c(t') + \Phi\,u_\lambda(t';t') - \Phi^2\mu_{free}(t')
        \ge -|\Phi|\max|\ddot c| + \min_{t'}\Phi\,u_\lambda(t';t') - \Phi^2\bar\mu,

    with :math:`\partial_{t'}D = \Phi(v(t) - \dot c(t))` at :math:`t' = t` (the axis' share of
    ``r``), :math:`u_\lambda(t';t') = \operatorname{clip}(a + bt' - \Phi(t'-t))` monotone in
    :math:`t'` (so :math:`\Phi u_\lambda` is least at an end of the interval), and
    :math:`\bar\mu` (:func:`~iamp.planners.pmp.saturated_kernel.free_measure`) a bound of the
    time in :math:`[0, t']` where :math:`u_\lambda` is free.  ``M`` is minus the sum of these
    lower bounds over the axes, or ``0`` where that sum is positive (the term
    :math:`\Phi u_\lambda` counted with its sign; before issue 32 it was :math:`|\Phi|\max|u_\lambda|`:
    116 -> 104 axis solves on the bench's paper-1 problem).  The kernel sharpens this further by
    following a multiplier path :math:`\bar\lambda + (t'-t)\mu_3 e_3` instead of fixed
    multipliers (weak duality holds for any), which splits the free-set term at ``t'``
    (:func:`~iamp.planners.pmp.saturated_kernel.interval_terms`; ``M`` 195 -> 34 at paper-1's
    minimum, 104 -> 72 solves).  Hence on :math:`|t'-t| \le \delta`

    .. math::  J_b(t') \ge \sum_{\text{axis}} D(\bar\lambda; t) - \Big|\sum_{\text{axis}}\partial_{t'}D\Big|\,\delta
               - \tfrac12\sum_{\text{axis}}M\,\delta^2

    (the slopes add up to ``r(t)``, which vanishes at a stationary contact time).

    An axis infeasible at the midpoint covers its interval by the Farkas margin of
    :func:`certify_infeasible` instead.  Before any solve, a whole level of intervals is
    bounded at once by the unbounded value function, :math:`J_b \ge J_u` (the box only
    removes inputs), with the rigorous box bound of :func:`iamp.planners.pmp.bound.lower_bound`;
    where ``J_u`` at the centre is above the target the interval is halved without a solve.
    ``(0, t_f)`` is covered by intervals whose bound is at least :math:`J_{best}(1 - rel)`.
    Given the contact time ``t_best`` of ``J_best`` (and its multipliers ``warm_best``), the
    piece of the first level that holds it is first replaced by the interval centred at
    ``t_best`` (one solve; its certified radius ``ρ``) and intervals graded geometrically away
    from ``t_best ± ρ`` (ratio :data:`CERT_GRADE`): near a stationary minimum the bound closes
    only on intervals about as wide as their distance from it, which halving alone reaches after
    ten levels or so (paper-1: 11 kernel calls -> 3).
    where the Taylor bound fails on an interval, the radius ``ρ`` around its centre on which it
    holds is certified and the two sides stay open (halved when ``ρ`` is negligible), both
    axes of every open interval of a level solved in one kernel call
    (:func:`~iamp.planners.pmp.saturated.contact_points`); the certificate fails (``local``)
    when an axis solve stalls on an interval below ``1e-12 t_f`` or the budget ``max_solves``
    is spent.  Given an ``edge`` ``(side, t)`` of the feasible contact times beside the minimum
    (``t = t_best`` when the minimum is at it; else a Taylor interval at ``t``, half-width
    :data:`EDGE_TAYLOR`, from the multipliers ``warm_edge``), the contact times beyond it are
    certified infeasible from the end of that Taylor interval outward by
    :func:`~iamp.planners.pmp.reach.cover_edge` (``out["edge_cover"]``) and taken out of the
    levels: near the edge the dual Newton method stalls without a Farkas direction.  An interval
    the axis solve leaves open (``"unknown"``) once narrower than :data:`REACH_BELOW` ``t_f`` is
    tried the same way (:func:`~iamp.planners.pmp.reach.cover_interval`; ``out["reach_steps"]``,
    counted in ``solves``).  A centre whose dual value (``J_b`` there) is below ``J_best`` by
    :data:`BETTER_REL` ends the certificate with ``out["better_t"]``: the search missed it
    (:func:`plan_bounded` restarts from it).

    Returns ``{"certified", "intervals", "solves", "lowest_bound", "pruned_by_unbounded"}`` (and
    ``"edge_cover"``: ``from``, ``to``, ``axis``, ``steps``, when one was certified).
    """
    rel = TOLERANCES["pmp_global_certificate_rel"] if rel is None else rel
    out: dict[str, Any] = {"certified": False, "intervals": 0, "solves": 0, "lowest_bound": INF}
    if problem.m != 1 or not math.isfinite(J_best):
        return out
    T = float(problem.tf)
    target = J_best - rel * abs(J_best)
    bound_on = _IntervalBound(problem)
    unbounded = _UnboundedBound(problem, value_function)
    pieces = 64
    level: list[tuple[float, float, list[list[float] | None]]] = [
        (T * k / pieces, T * (k + 1) / pieces, [None, None]) for k in range(pieces)]
    solves = intervals = pruned = 0
    lowest = INF
    if t_best is not None and 0.0 < t_best < T:
        k_best = min(max(int(t_best / T * pieces), 0), pieces - 1)
        while k_best > 0 and t_best < level[k_best][0]:
            k_best -= 1
        while k_best + 1 < pieces and t_best >= level[k_best][1]:
            k_best += 1
        a0, b0 = level[k_best][0], level[k_best][1]
        h = min(t_best - a0, b0 - t_best)
        if h > 0:
            kind, value, lams, used, terms = bound_on.many([(t_best - h, t_best + h, warm_best or [None, None])])[0]
            solves += used
            if kind == "bound":
                lowest = min(lowest, value)
            rho = 0.0
            if kind == "infeasible" or (kind == "bound" and value >= target):
                rho = h
            elif kind == "bound":
                rho = _certified_radius(*terms, target)
            if rho > 0:
                intervals += 1
                graded: list[tuple[float, float, list[list[float] | None]]] = []
                for side in (-1.0, 1.0):
                    end = a0 if side < 0 else b0
                    x = rho
                    span = abs(end - t_best)
                    while x < span:
                        y = min(CERT_GRADE * x, span)
                        if y >= span * (1 - 1e-12):
                            y = span
                        lo_, hi_ = sorted((t_best + side * x, t_best + side * y if y < span else end))
                        graded.append((lo_, hi_, lams))
                        x = y
                level = level[:k_best] + graded + level[k_best + 1:]
            if edge is not None and edge[0] in ("lower", "upper") and 0.0 < edge[1] < T:
                edge_side, t_edge = edge
                rho_e, warm_e = rho, warm_best or [None, None]
                if t_edge != t_best:  # an edge beside a stationary minimum: the Taylor interval there
                    h_e = min(EDGE_TAYLOR * T, t_edge, T - t_edge)
                    warm_e = warm_edge or [None, None]
                    kind, value, warm_e, used, terms = bound_on.many([(t_edge - h_e, t_edge + h_e, warm_e)])[0]
                    solves += used
                    rho_e = min(_certified_radius(*terms, target), h_e) if kind == "bound" else 0.0
                if rho_e > 0:
                    covered = _cover_beyond_edge(bound_on, t_edge, rho_e, edge_side, warm_e)
                    if covered is not None:
                        out["edge_cover"] = covered
                        lo_e, hi_e = min(covered["from"], t_edge - rho_e), max(covered["to"], t_edge + rho_e)
                        intervals += 1
                        level = [piece for a, b, w in level for piece in (
                            [(a, b, w)] if b <= lo_e or a >= hi_e else
                            [(a, lo_e, w)] * (a < lo_e) + [(hi_e, b, w)] * (b > hi_e))]
    use_unbounded = True
    reach_steps = 0
    while level:  # breadth first, one level of halved intervals at a time
        if use_unbounded:  # the closed-form bound J_b >= J_u on the whole level at once
            ends = np.array([(a, b) for a, b, _ in level])
            lb_arr, centre_arr = unbounded(ends[:, 0], ends[:, 1])
            lb_u, at_centre = lb_arr.tolist(), centre_arr.tolist()
        else:
            lb_u = at_centre = [-INF] * len(level)
        use_unbounded = False
        nxt: list[tuple[float, float, list[list[float] | None]]] = []
        todo: list[tuple[float, float, list[list[float] | None]]] = []
        for k, (a, b, warm) in enumerate(level):
            if lb_u[k] >= target:
                pruned += 1
                continue
            if at_centre[k] >= target and b - a > 1e-6 * T:
                # J_u is above the target at the centre: halving may close it without a solve
                use_unbounded = True
                t = 0.5 * (a + b)
                nxt += [(a, t, warm), (t, b, warm)]
                continue
            todo.append((a, b, warm))
        results = bound_on.many(todo)
        for (a, b, _), (kind, value, lams, used, terms) in zip(todo, results):
            solves += used
            if kind == "bound":
                lowest = min(lowest, value)
                if terms[0] < J_best - BETTER_REL * abs(J_best):
                    # the dual value at the centre is J_b there (converged): a contact time
                    # better than J_best, which the search missed (a feasible island narrower
                    # than its grid, random_problem(303480) at 0.72): not global; plan from it
                    out.update(intervals=intervals, solves=solves, lowest_bound=lowest, pruned_by_unbounded=pruned,
                               better_t=0.5 * (a + b), better_J=terms[0])
                    return out
            if kind == "infeasible" or (kind == "bound" and value >= target):
                intervals += 1
                continue
            if kind == "unknown" and REACH_BELOW * T > b - a > 1e-9 * T:
                # the centre's axis solve stalled or its Farkas margin was too small on an
                # interval that halving has narrowed (near an edge of the feasible contact
                # times): the margin maximised over the multipliers
                lo_r, hi_r, used = _reach_part(bound_on, a, b)
                reach_steps += used
                solves += used
                if lo_r <= hi_r:
                    intervals += 1
                    nxt += [(a, lo_r, lams)] * (lo_r > a) + [(hi_r, b, lams)] * (hi_r < b)
                    continue
            if solves > max_solves or b - a < 1e-12 * T:
                out.update(intervals=intervals, solves=solves, lowest_bound=lowest, pruned_by_unbounded=pruned)
                return out
            t = 0.5 * (a + b)
            rho = _certified_radius(*terms, target) if kind == "bound" else 0.0
            if rho > 1e-3 * (b - a):  # t ± ρ is certified: only the two sides stay open
                intervals += 1
                nxt += [(a, t - rho, lams), (t + rho, b, lams)]
            else:
                nxt += [(a, t, lams), (t, b, lams)]
        level = nxt
    out.update(certified=True, intervals=intervals, solves=solves, lowest_bound=lowest, pruned_by_unbounded=pruned)
    if reach_steps:
        out["reach_steps"] = reach_steps
    return out


def _stationary(search: dict[str, Any], fixed: bool) -> bool:
    """Whether the self-check applies the Hamiltonian-jump condition ``r = 0``: not at given
    contact times, not at an edge of the feasible ones (the minimum is not stationary there)."""
    return not fixed and "feasibility_edge" not in search


def _reach_part(bound_on: _IntervalBound, a: float, b: float) -> tuple[float, float, int]:
    """:func:`~iamp.planners.pmp.reach.cover_interval` on ``[a, b]`` (physical times):
    ``(lo, hi, steps)`` with ``[lo, hi]`` certified infeasible (``lo > hi``: nothing)."""
    from iamp.planners.pmp.reach import AxisReach, cover_interval

    T = bound_on.T
    c = 0.5 * (a + b)
    axes = [AxisReach(T, bound_on.axes_data[k], bound_on.pos, bound_on.der, bound_on.off[k], k == 0,
                      bound_on.cddot_max[0], c) for k in range(2)]
    lo, hi, steps = cover_interval(axes, a / T, b / T)
    if lo > hi:
        return INF, -INF, steps
    lo_t, hi_t = _inside(lo * T, hi * T, T)
    return (a if lo <= a / T else lo_t), (b if hi >= b / T else hi_t), steps


def _edge_of(search: dict[str, Any], t_best: float) -> tuple[str, float] | None:
    """``(side, time)`` of the certificate's edge cover: the plan's own contact time when the
    minimum is at the edge (``feasibility_edge``), the last feasible time when it is beside it."""
    edge = search.get("edge")
    if edge is None:
        return None
    return (edge["side"], t_best if search.get("feasibility_edge") else float(edge["t"]))


def _cover_beyond_edge(bound_on: _IntervalBound, t_best: float, rho: float, edge: str,
                       warm: list[list[float] | None]) -> dict[str, Any] | None:
    """The contact times beyond an edge of the feasible ones, from ``t_best ± ρ`` (the end of
    the Taylor interval around a minimum at the edge) outward, certified infeasible by
    :func:`~iamp.planners.pmp.reach.cover_edge` (a Farkas margin maximised over the
    multipliers, with a bound of its slope on each step); ``None`` when nothing is."""
    from iamp.planners.pmp.reach import AxisReach, edge_cover

    T = bound_on.T
    side = 1.0 if edge == "upper" else -1.0
    axes = [AxisReach(T, bound_on.axes_data[k], bound_on.pos, bound_on.der, bound_on.off[k], k == 0,
                      bound_on.cddot_max[0], t_best) for k in range(2)]
    # start 1e-13 t_f inside the Taylor interval (the two meet whatever σ·T rounds to)
    start = (t_best + side * max(rho - 1e-13 * T, 0.0)) / T
    reached, axis, steps = edge_cover(axes, start, side, warm)
    if axis < 0:
        return None
    lo_e, hi_e = _inside(start * T, reached * T, T)
    return {"from": lo_e, "to": hi_e, "axis": "xy"[axis], "steps": steps}


def _inside(p: float, q: float, T: float) -> tuple[float, float]:
    """``[min, max]`` of two times of a cover, shrunk by ``1e-14 t_f`` at an end inside
    ``(0, t_f)`` (the cover certifies ``σ·T`` as rounded; the rest stays to bisect)."""
    lo, hi = min(p, q), max(p, q)
    return (lo + 1e-14 * T if 0.0 < lo else lo), (hi - 1e-14 * T if hi < T else hi)


# ------------------------------------------------------------------------------------------
# self-check
# ------------------------------------------------------------------------------------------
def check_values(sol: BoundedSolution, stationary: bool = True, at_edge: Any = ()) -> dict[str, float]:
    """The dimensionless value of every condition (module docstring); with ``stationary`` the
    Hamiltonian jump over the contact times not listed in ``at_edge`` (indices of times at an
    edge of the feasible ones, where the minimum is not stationary).

    Evaluated point by point on Python floats (a plan has a few knots): ``u``, ``v`` from the
    knots (:meth:`BoundedSolution._axis_at`), ``w = −p_v`` and ``p_s`` from ``a, b, Φ`` and the
    contact times (independent of the knots), so the checks compare the two representations."""
    prob = sol.problem
    T = float(prob.tf)
    t = sol.contact_times
    tl = t.tolist()
    ego = prob.ego
    (lx, hx), (ly, hy) = input_box(prob)
    C = prob.corners(t).reshape(-1, 2).tolist()
    ends_and_t = sol.ends_and_contacts().tolist()
    ends, X = ends_and_t[:2], ends_and_t[2:]
    vals: dict[str, float] = {}
    bnd = cor = sat = sw = box = 0.0
    coef = [(ax.a, ax.b, list(zip(tl, ax.jumps))) for ax in sol.axes]

    def w_at(k: int, x: float) -> float:
        a, b, tj = coef[k]
        ramps = 0.0
        for ti, jump in tj:
            if x > ti:
                ramps += jump * (x - ti)
        return a + b * x - ramps

    for k, (lo, hi) in enumerate(((lx, hx), (ly, hy))):
        ax = sol.axes[k]
        init = (ego.x0, ego.vx0) if k == 0 else (ego.y0, ego.vy0)
        fin = (ego.xf, ego.vxf) if k == 0 else (ego.yf, ego.vyf)
        L = max([1e-300, abs(fin[0] - init[0]), abs(fin[1] - init[1]) * T, abs(init[1]) * T]
                + [abs(c[k] - init[0]) for c in C] + [abs(b) * T * T for b in (lo, hi) if math.isfinite(b)])
        ua = L / (T * T)
        for e, ref in ((ends[0][2 * k], init[0]), (ends[0][2 * k + 1] * T, init[1] * T),
                       (ends[1][2 * k], fin[0]), (ends[1][2 * k + 1] * T, fin[1] * T)):
            bnd = max(bnd, abs(e - ref) / L)
        for x, c in zip(X, C):
            cor = max(cor, abs(x[2 * k] - c[k]) / L)
        # u at the knots (the knots' values) and at the piece midpoints (linear between them)
        kn, U, slopes = ax.knots, ax.u, sol._slopes_l[k]
        for x, u in [*zip(kn, U), *((0.5 * (kn[q + 1] + kn[q]), U[q] + slopes[q] * (0.5 * (kn[q + 1] + kn[q]) - kn[q]))
                                    for q in range(len(kn) - 1))]:
            w = w_at(k, x)
            e = abs(u - (lo if w < lo else (hi if w > hi else w))) / ua
            if e > sat or e != e:
                sat = e
        for theta, value, _, _ in ax.switching:
            e = abs(w_at(k, theta) - value) / ua
            if e > sw or e != e:
                sw = e
        box = max(box, max((max(u - hi, lo - u) for u in ax.u), default=0.0) / ua)

    def p_at(k: int, x: float, left: bool) -> float:
        _, b, tj = coef[k]
        steps = 0.0
        for ti, jump in tj:
            if (x - ti > 0) if left else (x - ti >= 0):
                steps += jump
        return b - steps

    def H_at(x: float, left: bool) -> float:
        _, vx, ux = sol._axis_at(0, x)
        _, vy, uy = sol._axis_at(1, x)
        return (0.5 * (ux**2 + uy**2) + p_at(0, x, left) * vx + (-w_at(0, x)) * ux + p_at(1, x, left) * vy
                + (-w_at(1, x)) * uy)

    # H constant between contact times (one-sided values at every knot of the interval)
    bp = [0.0, *sorted(tl), T]
    allk = sol.knots()
    Hs = [[H_at(bp[j], False), *(H_at(x, False) for x in allk if bp[j] < x < bp[j + 1]), H_at(bp[j + 1], True)]
          for j in range(len(bp) - 1)]
    if stationary and len(tl) == 1 and sol._hjump is None:
        # one vehicle: the Hamiltonian-jump terms from the two one-sided values at the contact
        # time (the end of the first interval and the start of the second: the same evaluations)
        sol._hjump = sol._hamiltonian_jump_terms(np.array([Hs[0][-1], Hs[1][0]]))
    hscale = max(1e-300, max(abs(h) for hs in Hs for h in hs), sol.cost / T)
    hcon = max(max(hs) - min(hs) for hs in Hs) / hscale
    vals.update(boundary=bnd, corner=cor, saturation_law=sat, switching=sw, box=box, hamiltonian_constant=hcon)
    if stationary and len(tl):
        r, size = sol.hamiltonian_jump_terms()
        edge = {int(i) % len(tl) for i in at_edge}
        floor = HJUMP_FLOOR * hscale
        hj = 0.0
        for i, (ri, si) in enumerate(zip(r.tolist(), size.tolist())):
            if i not in edge:
                e = abs(ri) / (si if si > floor or si != si else floor)
                if e > hj or e != e:
                    hj = e
        vals["hamiltonian_jump"] = hj
    cost = sol.cost
    dual = sum(ax.dual for ax in sol.axes)
    vals["duality_gap"] = abs(cost - dual) / max(cost, 1e-300)
    return vals


def judge(values: dict[str, float]) -> tuple[dict[str, dict[str, float | bool]], str | None, str | None]:
    """``(checks, failed_check, status)`` against :data:`BOUNDED_TOLERANCE_OF`."""
    checks: dict[str, dict[str, float | bool]] = {}
    failed: str | None = None
    status: str | None = None
    for name, value in values.items():
        limit = TOLERANCES[BOUNDED_TOLERANCE_OF[name]]
        ok = -INF < value <= limit
        checks[name] = {"value": float(value), "tol": limit, "ok": bool(ok)}
        if not ok and failed is None:
            failed = name
            status = INACCURATE if math.isfinite(value) else NUMERICAL_ERROR
    return checks, failed, status


# ------------------------------------------------------------------------------------------
# exact peaks and the bounds the PMP cannot impose
# ------------------------------------------------------------------------------------------
def exact_peaks(trajectory: Any, tf: float, knots: list[float]) -> dict[str, Any]:
    """Exact extrema of a trajectory whose inputs are linear between ``knots``.

    ``u`` (per axis) and ``|u|`` peak at knots (``|u|²`` is convex on each piece); ``v_x``
    at knots or where ``u_x = 0`` inside a piece; ``s_y`` at knots or where ``v_y = 0``
    (a quadratic per piece, its real roots in closed form: :func:`_quadratic_roots`); jerk is
    ``|Δu/Δt|`` per piece.  A :class:`BoundedSolution` is evaluated point by point on Python
    floats (:meth:`BoundedSolution._axis_at`: a plan has a few knots, and arrays of a few
    entries cost more than the arithmetic); any other trajectory through its ``states`` and
    ``inputs``.
    """
    kn_l = sorted({min(max(float(x), 0.0), tf) for x in (0.0, *knots, tf)})
    if isinstance(trajectory, BoundedSolution):
        def at(t: float) -> tuple[list[float], list[float]]:
            sx, vx, ux = trajectory._axis_at(0, t)
            sy, vy, uy = trajectory._axis_at(1, t)
            return [sx, vx, sy, vy], [ux, uy]

        rows = [at(t) for t in kn_l]
        X_l, U_l = [r[0] for r in rows], [r[1] for r in rows]
    else:
        U_l = np.asarray(trajectory.inputs(np.asarray(kn_l))).tolist()
        X_l = np.asarray(trajectory.states(np.asarray(kn_l))).tolist()
    jerk = 0.0
    extra_vx: list[float] = []
    extra_y: list[float] = []
    for j in range(len(kn_l) - 1):
        a, b = kn_l[j], kn_l[j + 1]
        h = b - a
        if not h > 0:
            continue
        ux0, ux1 = U_l[j][0], U_l[j + 1][0]
        jerk = max(jerk, abs((ux1 - ux0) / h), abs((U_l[j + 1][1] - U_l[j][1]) / h))
        if ux0 * ux1 < 0:
            extra_vx.append(a + (b - a) * ux0 / (ux0 - ux1))
        # v_y(a + d) = vy + uy d + c d²/2 with c the slope of u_y
        vy, uy = X_l[j][3], U_l[j][1]
        c = (U_l[j + 1][1] - uy) / (b - a)
        if _keeps_sign(vy, uy, c, b - a):
            continue  # v_y has no root in the piece: s_y is monotone there
        extra_y += [a + r for r in _quadratic_roots(c / 2, uy, vy) if 0 < r < b - a]
    VX = [x[1] for x in X_l]
    Y = [x[2] for x in X_l]
    if isinstance(trajectory, BoundedSolution):
        VX += [trajectory._axis_at(0, t)[1] for t in extra_vx]
        Y += [trajectory._axis_at(1, t)[0] for t in extra_y]
    else:
        if extra_vx:
            VX += np.asarray(trajectory.states(np.asarray(extra_vx)))[:, 1].tolist()
        if extra_y:
            Y += np.asarray(trajectory.states(np.asarray(extra_y)))[:, 2].tolist()
    UX = [u[0] for u in U_l]
    UY = [u[1] for u in U_l]
    return {
        "ax": [min(UX), max(UX)],
        "ay": [min(UY), max(UY)],
        "a_total": max(math.hypot(ux, uy) for ux, uy in zip(UX, UY)),
        "vx": [min(VX), max(VX)],
        "y": [min(Y), max(Y)],
        "jerk": jerk,
    }


def _quadratic_roots(A: float, B: float, C: float) -> list[float]:
    """The real roots of ``A d² + B d + C`` (``A = 0``: of ``B d + C``; none when constant), by
    the cancellation-free formula ``q = −(B + sign(B)√(B² − 4AC))/2``, ``d = q/A, C/q``."""
    if A == 0.0:
        return [-C / B] if B != 0.0 else []
    disc = B * B - 4.0 * A * C
    if not disc >= 0.0:
        return []
    q = -0.5 * (B + math.copysign(math.sqrt(disc), B))
    return [q / A] + ([C / q] if q != 0.0 else [])


def _keeps_sign(v0: float, u0: float, c: float, h: float) -> bool:
    """Whether ``q(d) = v0 + u0 d + c d²/2`` keeps one strict sign on ``[0, h]`` with a margin
    of ``1e-9`` of its terms' size (so that no root-finder can place a root inside): at both
    ends and, if inside, at the vertex."""
    margin = 1e-9 * (abs(v0) + abs(u0) * h + abs(c) * h * h)
    ends = (v0, v0 + u0 * h + c * h * h / 2)
    if not (all(q > margin for q in ends) or all(q < -margin for q in ends)):
        return False
    if c != 0.0:
        dv = -u0 / c
        if 0.0 < dv < h:
            qv = v0 + u0 * dv + c * dv * dv / 2
            return bool(qv > margin if v0 > 0 else qv < -margin)
    return True


def limits_report(problem: Problem, peaks: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """``{name: {"peak", "bound", "ok"}}`` for every bound given (SPEC §14's JSON shape);
    ``ok`` allows ``limits_bound_rel`` of the bound's size."""
    lim = problem.limits
    out: dict[str, dict[str, Any]] = {}
    if lim is None:
        return out
    rel = TOLERANCES["limits_bound_rel"]
    for name, bound in lim.given().items():
        peak = peaks[name]
        if isinstance(bound, tuple):
            slack = rel * max(1.0, abs(bound[0]), abs(bound[1]))
            ok = peak[0] >= bound[0] - slack and peak[1] <= bound[1] + slack
            out[name] = {"peak": list(peak), "bound": list(bound), "ok": bool(ok)}
        else:
            ok = peak <= bound + rel * max(1.0, bound)
            out[name] = {"peak": peak, "bound": bound, "ok": bool(ok)}
    return out


def plan_knots(plan: Plan) -> list[float]:
    """Where the plan's inputs may kink: contact times, and switching times of a bounded plan."""
    traj = plan.trajectory
    if isinstance(traj, BoundedSolution):
        return traj.knots()
    return [float(x) for x in plan.contact_times]


# ------------------------------------------------------------------------------------------
# the contact-time search and the plan
# ------------------------------------------------------------------------------------------
class _Evaluator:
    """``J_b(t)`` and ``r(t) = ∇J_b(t)`` with warm starts from the nearest evaluated point.

    Lean: the two axis solves only, ``r_i = Σ_axis Φ_i (v(t_i) − ċ_i)`` (= the Hamiltonian-
    jump residual, module docstring) from the axes' contact speeds; the full
    :class:`BoundedSolution` is built once, for the final contact times.
    """

    def __init__(self, problem: Problem):
        self.problem = problem
        self.memory: list[tuple[list[float], list[list[float]]]] = []
        self.evaluations = 0
        ego = problem.ego
        self.T = float(problem.tf)
        (lx, hx), (ly, hy) = input_box(problem)
        self.data = ((ego.x0, ego.vx0, ego.xf, ego.vxf, lx, hx), (ego.y0, ego.vy0, ego.yf, ego.vyf, ly, hy))
        # x_s, ẋ_s as float coefficients: :func:`_polyval` repeats numpy's polyval, so the
        # corners and speeds are those of ``problem.corners`` and ``vehicle.speed`` exactly
        self.pos = [[float(c) for c in np.asarray(v.x_poly, dtype=float)] for v in problem.vehicles]
        self.der = [_derivative(pos) for pos in self.pos]
        self.off = [(float(v.offset_x), float(v.corner_y)) for v in problem.vehicles]
        self.flat_data = [float(x) for row in self.data for x in row]
        self._vf: Any = None
        # contact times evaluated with a finite J_b: asked again (the search's brackets and
        # Brent's ends repeat its grid points), the result is returned without a solve.  The
        # same numbers: a warm start from the converged multipliers takes no Newton step
        self._done: dict[tuple[float, ...], tuple[float, FloatArray, list[list[float]]]] = {}

    def value_function(self) -> Any:
        """The unbounded value function (made once; the search and the certificate share it)."""
        if self._vf is None:
            self._vf = _unbounded_value(self.problem)
        return self._vf

    def _nearest(self, times: list[float]) -> list[list[float]] | None:
        best, found = INF, None
        if len(times) == 1:  # the same distances, without a generator per entry
            x = times[0]
            for tm, lams in self.memory:
                d = abs(tm[0] - x)
                if d < best:
                    best, found = d, lams
            return found
        for tm, lams in self.memory:
            d = max(abs(a - b) for a, b in zip(tm, times))
            if d < best:
                best, found = d, lams
        return found

    def warm_for(self, t: FloatArray) -> list[list[float] | None] | None:
        """The multipliers of the nearest evaluated contact times (or ``None``)."""
        found = self._nearest([float(x) for x in np.asarray(t).reshape(-1)])
        return None if found is None else list(found)

    def __call__(self, t: FloatArray) -> tuple[float, FloatArray, list[list[float]] | None]:
        t = np.asarray(t, dtype=float)
        times = t.tolist()
        done = self._done.get(tuple(times))
        if done is not None:
            self._remember(times, done[2])  # the memory of warm starts as if solved again
            return done[0], done[1].copy(), done[2]
        J, r, lams = self._solve(t, times)
        if lams is not None and math.isfinite(J):
            self._done[tuple(times)] = (J, r.copy(), lams)
        return J, r, lams

    def r_one(self, x: float) -> float:
        """One vehicle: ``r`` at the contact time ``x`` (a float), as :meth:`__call__` gives it
        (the same cache and warm starts), without the arrays of a call."""
        done = self._done.get((x,))
        if done is not None:
            self._remember([x], done[2])
            return float(done[1][0])
        J, r, lams = self._solve(np.empty(0), [x])
        if lams is not None and math.isfinite(J):
            self._done[(x,)] = (J, r.copy(), lams)
        return float(r[0])

    def known_r(self, x: float) -> float:
        """One vehicle: :meth:`r_one` without touching the warm starts' memory when ``x`` was
        evaluated already (a bisected edge; its multipliers are the latest remembered)."""
        done = self._done.get((x,))
        return float(done[1][0]) if done is not None else self.r_one(x)

    def _solve(self, t: FloatArray, times: list[float]) -> tuple[float, FloatArray, list[list[float]] | None]:
        T = self.T
        m = len(times)
        if m == 1:  # both axes in one kernel call (the same numbers as solve_axis_value)
            if times[0] <= 0 or times[0] >= T:
                return INF, np.full(1, np.nan), None
            warm1 = self._nearest(times)
            self.evaluations += 1
            raw = contact_points(times, T, self.pos[0], self.off[0][0], self.off[0][1], self.flat_data,
                                 warm1[0] + warm1[1] if warm1 is not None else [0.0] * 6,
                                 [1.0, 1.0] if warm1 is not None else [0.0, 0.0], True)
            W = POINT_WIDTH
            if raw[0] != 0.0 or raw[W] != 0.0:
                return INF, np.full(1, np.nan), None
            r = np.array([raw[3] * (raw[6] - _polyval(self.der[0], times[0])) + raw[W + 3] * raw[W + 6]])
            lams1 = [raw[7:10], raw[W + 7:W + 10]]
            self._remember(times, lams1)
            return raw[2] + raw[W + 2], r, lams1
        if np.any(t <= 0) or np.any(t >= T) or np.min(np.diff(np.sort(t))) <= 1e-9 * T:
            return INF, np.full(len(t), np.nan), None
        warm = self._nearest(times)
        self.evaluations += 1
        cdot = [_polyval(self.der[i], times[i]) for i in range(m)]
        corners = ([_polyval(self.pos[i], times[i]) + self.off[i][0] for i in range(m)],
                   [self.off[i][1] for i in range(m)])
        axes: list[tuple[float, list[float], list[float], list[float]]] = []
        for k, (s0, v0, sf, vf, lo, hi) in enumerate(self.data):
            sol = None
            for start in ([warm[k], None] if warm is not None else [None]):
                sol = solve_axis_value(times, T, s0, v0, sf, vf, corners[k], lo, hi, start)
                if sol is not None:
                    break
            if sol is None:
                return INF, np.full(len(t), np.nan), None
            axes.append(sol)
        (cx, jx, vx, lx), (cy, jy, vy, ly) = axes
        r = np.array([jx[i] * (vx[i] - cdot[i]) + jy[i] * vy[i] for i in range(m)])
        lams = [lx, ly]
        self._remember(times, lams)
        return cx + cy, r, lams

    def _remember(self, times: list[float], lams: list[list[float]]) -> None:
        self.memory.append((times, lams))
        if len(self.memory) > 64:
            self.memory.pop(0)


def _derivative(c: list[float]) -> list[float]:
    """The coefficients of the derivative of the polynomial ``c`` (ascending), as
    ``numpy.polynomial.polynomial.polyder`` computes them (``j·c_j``); ``[0.0]`` for a constant."""
    return [j * c[j] for j in range(1, len(c))] if len(c) > 1 else [0.0]


def _polyval(c: list[float], x: float) -> float:
    """``numpy.polynomial.polynomial.polyval(x, c)`` for a float ``x``, operation for operation."""
    acc = c[-1] + x * 0
    for i in range(2, len(c) + 1):
        acc = c[-i] + acc * x
    return acc


def _unbounded_value(problem: Problem) -> Any:
    """The unbounded problem's closed-form value function
    (:class:`~iamp.planners.pmp.fixed.ValueFunction`)."""
    from iamp.planners.pmp.fixed import ValueFunction

    return ValueFunction(problem.with_limits(None))


def _lower_bound(problem: Problem, t: FloatArray, vf: Any = None) -> FloatArray:
    """``J_u(t)`` (the unbounded fixed-time cost, closed form): a lower bound of ``J_b(t)``,
    since the box only removes inputs.  ``t`` has shape ``(..., m)``; ``vf`` the value
    function if made already."""
    with np.errstate(all="ignore"):
        out: FloatArray = (_unbounded_value(problem) if vf is None else vf)(t)
    return out


def _r_at(ev: _Evaluator, x: float) -> float:
    """``r(x)`` for Brent's method (``0`` where no plan: the bracket's ends are feasible)."""
    rr = ev.r_one(float(x))
    return rr if math.isfinite(rr) else 0.0


def _sign_root(ev: _Evaluator, x0: float, x1: float, tol: float) -> float:
    """One vehicle: where ``r`` changes sign between ``x0`` and ``x1`` (whose ``r`` have opposite
    signs), by bisection to ``tol``; a midpoint whose solve fails is replaced by the points a
    quarter of the way to either end, and NaN is returned when all three fail (or the ends do
    not have opposite signs)."""
    r0, r1 = ev.r_one(float(x0)), ev.r_one(float(x1))
    if not (math.isfinite(r0) and math.isfinite(r1) and r0 * r1 < 0):
        return math.nan
    a, ra, b = float(x0), r0, float(x1)
    while abs(b - a) > tol:
        for f in (0.5, 0.25, 0.75):
            mid = a + f * (b - a)
            rm = ev.r_one(mid)
            if math.isfinite(rm):
                break
        else:
            return math.nan
        if rm == 0.0:
            return mid
        if (rm < 0) == (ra < 0):
            a, ra = mid, rm
        else:
            b = mid
    return 0.5 * (a + b)


def _edge_candidate(ev: _Evaluator, T: float, edge_t: float, probe: float, side: str
                    ) -> tuple[float, str | None, tuple[str, float] | None, bool]:
    """The candidate of :func:`_search_one` where ``J_b`` falls from ``probe`` towards the edge
    ``edge_t`` (the last feasible time) on ``side``: ``(t, feasibility_edge, (side, edge_t),
    stationary_within_ulp)``.  The minimum is at the edge (planned :data:`EDGE_BACKOFF` inside),
    unless ``r`` turns again just inside it: then a stationary minimum lies between the probe and
    the edge (random_problem(608074) at 0.70: ``1.5e-7 t_f`` inside, ``4e-8`` below the edge's
    ``J_b``), found by Brent's method on ``r``.  So close to the edge ``r`` can be steep enough to
    change sign between adjacent floats (random_problem(161397) at 0.87: ``r t_f/J_b`` from
    ``-5e-4`` to ``5e-4`` within four ulps of ``t``): bisection on its sign down to adjacent
    floats, the one with the smaller ``|r|``; ``r``'s zero is then within one ulp of it."""
    from scipy.optimize import brentq

    sign = 1.0 if side == "upper" else -1.0
    at = edge_t - sign * EDGE_BACKOFF * T
    r_at = ev(np.array([at]))[1][0]
    if np.isfinite(r_at) and sign * r_at > 0:
        try:
            root = float(brentq(lambda x: _r_at(ev, x), min(probe, at), max(probe, at), xtol=1e-11 * T,
                                maxiter=200))
        except (ValueError, RuntimeError):
            root = math.nan
        if math.isfinite(root):
            a, b = root - 4e-11 * T, root + 4e-11 * T
            ra, rb = _r_at(ev, a), _r_at(ev, b)
            if ra * rb > 0:
                # r keeps its sign beside Brent's root: a solve there failed, and its stand-in
                # r = 0 ended Brent's method (random_problem(186935) under an a_x box at 0.4568:
                # 1.2e-7 s inside the lower edge, r = +8.7e3 on either side); bisection on r's
                # sign instead, a failed solve retried a quarter of the way to either end
                root = _sign_root(ev, probe, at, 4e-11 * T)
                if not math.isfinite(root):
                    return at, side, (side, edge_t), False
                a, b = root - 4e-11 * T, root + 4e-11 * T
                ra, rb = _r_at(ev, a), _r_at(ev, b)
            ulp = ra * rb < 0
            while ulp:
                mid = 0.5 * (a + b)
                if not a < mid < b:
                    break
                rm = _r_at(ev, mid)
                if rm == 0.0:
                    a = b = mid
                    break
                if (rm < 0) == (ra < 0):
                    a, ra = mid, rm
                else:
                    b, rb = mid, rm
            if ulp:
                root = a if abs(ra) <= abs(rb) else b
            return root, None, (side, edge_t), ulp
    return at, side, (side, edge_t), False


def _search_one(ev: _Evaluator, T: float, starts: list[float], grid: int) -> tuple[FloatArray, dict[str, Any]]:
    """One vehicle: ``J_b`` at the unbounded ``t*``, then at the grid points whose lower bound
    ``J_u(t)`` is below the best ``J_b`` so far (the others cannot win), then Brent's root of
    ``r = dJ_b/dt`` in the best point's bracket (and in any other within 5 %)."""
    from scipy.optimize import brentq

    grid_pts = [T * (k + 0.5) / grid for k in range(grid)]
    pts = sorted(set(grid_pts + [s for s in starts if 0 < s < T]))
    lower = _lower_bound(ev.problem, np.array(pts)[:, None], ev.value_function())
    vals = [INF] * len(pts)
    best_J = INF
    for s in starts:
        if 0 < s < T:
            vals[pts.index(s)] = best_J = ev(np.array([s]))[0]
    pruned = 0
    for i in np.argsort(lower):
        i = int(i)
        if vals[i] < INF:
            continue
        if lower[i] >= best_J:
            pruned += 1
            continue
        vals[i] = ev(np.array([pts[i]]))[0]
        best_J = min(best_J, vals[i])
    info: dict[str, Any] = {"grid": grid, "pruned_by_unbounded_bound": pruned}
    if not any(math.isfinite(v) for v in vals):
        info["evaluations"] = ev.evaluations
        return np.array([np.nan]), info
    order = np.argsort(vals)
    best_t, best_J = pts[int(order[0])], vals[int(order[0])]
    edge: str | None = None
    edge_at: tuple[str, float] | None = None  # (side, the last feasible time) of an edge beside the minimum
    within_ulp = False
    polished = False  # best_t a root of r or an edge candidate, not a start or grid point
    for rank, idx in enumerate(order[: min(3, len(order))]):
        i = int(idx)
        # polish the best grid basin, and others only when their grid value is within 5 %
        if not math.isfinite(vals[i]) or (rank > 0 and (vals[i] > vals[int(order[0])] * 1.05
                                                         or abs(i - int(order[0])) <= 1)):
            continue  # (a neighbour of the best point lies in the bracket already polished)
        lo_t = pts[i - 1] if i > 0 else 1e-6 * T
        hi_t = pts[i + 1] if i + 1 < len(pts) else T * (1 - 1e-6)
        r_lo, r_hi = ev(np.array([lo_t]))[1][0], ev(np.array([hi_t]))[1][0]
        # an infeasible end of the bracket moves to the edge of the feasible contact times
        # (bisection): J_b may fall all the way to that edge, where the minimum is not
        # stationary.  At the edge itself the dual multipliers grow without bound and r loses
        # its digits, so the slope there is read EDGE_PROBE t_f inside, where the bracket starts.
        cands: list[tuple[float, str | None, tuple[str, float] | None, bool]] = []

        def r_of(x: float) -> float:
            return _r_at(ev, x)

        if not np.isfinite(r_lo) and math.isfinite(vals[i]):
            edge_t = _feasible_edge(ev, pts[i], lo_t, T)
            lo_t = min(edge_t + EDGE_PROBE * T, 0.5 * (edge_t + pts[i]))
            r_lo = ev(np.array([lo_t]))[1][0]
            if r_lo > 0:  # J_b rises from the lower edge: a minimum at the edge
                cands.append(_edge_candidate(ev, T, edge_t, lo_t, "lower"))
        if not np.isfinite(r_hi) and math.isfinite(vals[i]):
            edge_t = _feasible_edge(ev, pts[i], hi_t, T)
            hi_t = max(edge_t - EDGE_PROBE * T, 0.5 * (edge_t + pts[i]))
            r_hi = ev(np.array([hi_t]))[1][0]
            if r_hi < 0:  # J_b falls to the upper edge
                cands.append(_edge_candidate(ev, T, edge_t, hi_t, "upper"))
        if not (np.isfinite(r_lo) and np.isfinite(r_hi)):
            continue
        if r_lo < 0 < r_hi:
            try:
                cands.append((float(brentq(r_of, lo_t, hi_t, xtol=1e-11 * T, maxiter=200)), None, None, False))
            except (ValueError, RuntimeError):
                pass
        for cand, side, near, ulp in cands:
            J_c = ev(np.array([cand]))[0]
            if J_c < best_J or (not polished and J_c <= best_J + STATIONARY_TIE_REL * abs(best_J)):
                best_t, best_J, edge, edge_at, within_ulp = cand, J_c, side, near, ulp
                polished = True
    if edge is not None:
        info["feasibility_edge"] = edge
    if edge_at is not None:
        info["edge"] = {"side": edge_at[0], "t": edge_at[1]}
    if within_ulp:
        info["stationary_within_ulp"] = True
    info["evaluations"] = ev.evaluations
    return np.array([best_t]), info


def _feasible_edge(ev: _Evaluator, inside: float, outside: float, T: float, point: FloatArray | None = None,
                   i: int = 0) -> float:
    """The feasible contact time nearest the edge of the feasible set between a feasible
    ``inside`` and an infeasible ``outside`` (bisection to ``1e-12 t_f``); with ``point`` (several
    vehicles), of contact time ``i`` with the others at ``point``'s.

    One vehicle: an axis solve can stall (no plan, no Farkas certificate) at a feasible time
    next to the edge, and bisection then stops at a false edge.  Where ``J_b`` falls towards the
    edge found (a minimum may be at it; ``r`` read at that time, which beside a false edge keeps
    its digits; at a true one it may not, and the tries are wasted), the times
    :data:`EDGE_BEYOND` ``t_f`` past it are tried (an infeasible try leaves no warm start
    behind); a feasible one restarts the bisection from it, at most 8 times (random_problem(166) at
    0.8872: a stall ``5.6e-13 t_f`` past the plan's contact time, the edge ``9.3e-10 t_f``
    further, ``J_b`` there ``2.5e-9`` (relative) lower)."""
    if point is None:
        far = outside
        for _ in range(8):
            edge = _bisect_edge(ev, inside, far, T, None, 0)
            step = math.copysign(1.0, far - edge)
            if not ev.known_r(edge) * step < 0:  # J_b does not fall towards the edge: no minimum there
                return edge
            beyond = [edge + step * d * T for d in EDGE_BEYOND if abs(d * T) < abs(far - edge)]
            inside = next((x for x in beyond if math.isfinite(ev(np.array([x]))[0])), edge)
            if inside == edge:
                return edge
        return inside
    return _bisect_edge(ev, inside, outside, T, point, i)


def _bisect_edge(ev: _Evaluator, inside: float, outside: float, T: float, point: FloatArray | None,
                 i: int) -> float:
    """The bisection of :func:`_feasible_edge` (a stalled solve counts as infeasible)."""
    while abs(outside - inside) > 1e-12 * T:
        mid = 0.5 * (inside + outside)
        if mid in (inside, outside):
            break
        if point is None:
            at = np.array([mid])
        else:
            at = np.array(point, dtype=float)
            at[i] = mid
        if math.isfinite(ev(at)[0]):
            inside = mid
        else:
            outside = mid
    return inside


def _search_many(ev: _Evaluator, T: float, m: int, starts: list[FloatArray], grid: int, finer: bool = True
                 ) -> tuple[FloatArray, dict[str, Any]]:
    from scipy.optimize import minimize

    cands = [np.asarray(s, dtype=float) for s in starts]
    if m <= 2:
        cands += list(_mesh(T, grid, m))
    vals = [ev(c)[0] for c in cands]
    info: dict[str, Any] = {"grid": grid}
    if finer and any(math.isfinite(v) for v in vals):
        info["grid_points"] = _pruned_grid(ev, _mesh(T, GRID_MANY[min(m, 4) - 2], m), cands, vals)
    if not any(math.isfinite(v) for v in vals):
        return np.full(m, np.nan), {**info, "evaluations": ev.evaluations}
    order = np.argsort(vals)
    best, best_J = cands[int(order[0])], vals[int(order[0])]
    eps = 1e-6 * T

    def fun(x: FloatArray) -> tuple[float, FloatArray]:
        J, r, _ = ev(x)
        if not math.isfinite(J):
            return 1e300, np.zeros(m)
        return J, np.nan_to_num(r)

    for idx in order[: min(3, len(order))]:
        x0 = cands[int(idx)]
        if not math.isfinite(vals[int(idx)]):
            continue
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=[(eps, T - eps)] * m,
                       options={"ftol": 1e-15, "gtol": 1e-12 * max(1.0, abs(best_J)), "maxiter": 200})
        if res.fun < best_J:
            best, best_J = np.asarray(res.x, dtype=float), float(res.fun)
    # L-BFGS-B stops where its line search leaves the feasible set of contact times (a narrow
    # one under a tight box); a damped Newton method on r finishes the polish of the best
    best, best_J = _newton_polish(ev, best, best_J, T)
    return best, {**info, "evaluations": ev.evaluations}


def _mesh(T: float, per: int, m: int) -> FloatArray:
    """The midpoints of ``per`` equal cells per axis of ``(0, T)^m``, one row per point."""
    g = T * (np.arange(per) + 0.5) / per
    return np.stack(np.meshgrid(*([g] * m), indexing="ij"), axis=-1).reshape(-1, m)


def _pruned_grid(ev: _Evaluator, mesh: FloatArray, cands: list[FloatArray], vals: list[float]) -> int:
    """Several vehicles, once a start has a plan: the grid's points whose lower bound
    ``J_u`` (the unbounded fixed-time cost, closed form) is below the best ``J_b`` found, in
    ascending ``J_u`` until it reaches that best (the rest cannot start cheaper), appended to
    ``cands``/``vals``; returns how many were evaluated.

    Found by scripts/bounded_sweep.py (2026-11-29): under a tight box on ``a_y`` alone the search
    from the unbounded ``t*`` (or the feasible contact times the infeasibility cover met) ended
    ``local`` in a basin of another order of the contact times, up to 6x the cost of the FOH QP's
    sweep at ``N = 8`` (random_problem(979596, m=3) at 0.531: 15318.5 against 2539.8), or
    ``inaccurate`` there; with two vehicles the 8 × 8 grid's best three missed it too
    (random_problem(735598, m=2) at 0.542: 124.73 against the FOH QP's 43.02 at ``N = 16``).
    ``J_b`` costs ~50 µs a point compiled; with an incumbent few of the :data:`GRID_MANY` points
    have ``J_u`` below it (none on ``iamp bench``'s feasible case)."""
    finite = [v for v in vals if math.isfinite(v)]
    best = min(finite) if finite else INF
    lower = _lower_bound(ev.problem, mesh, ev.value_function())
    count = 0
    for k in np.argsort(lower, kind="stable"):
        if not lower[k] < best:
            break
        J = ev(mesh[k])[0]
        count += 1
        cands.append(mesh[k])
        vals.append(J)
        if J < best:
            best = J
    return count


def _newton_polish(ev: _Evaluator, x: FloatArray, J: float, T: float, iterations: int = 25,
                   free: FloatArray | None = None) -> tuple[FloatArray, float]:
    r"""Damped Newton on :math:`r(t) = \nabla J_b(t) = 0` (several contact times): the Hessian
    by central differences of the exact gradient ``r`` (symmetrised; steepest descent where it
    is not positive definite), an Armijo backtracking on ``J_b`` that also backs off from
    infeasible contact times; stops when ``r`` vanishes to the ``pmp_hjump_rel`` scale or no
    step decreases ``J_b``.  ``free`` (boolean per contact time): only those move, the others
    stay where they are (at an edge of the feasible contact times, :func:`_edge_polish`)."""
    m = len(x)
    idx = np.arange(m) if free is None else np.flatnonzero(free)
    k = len(idx)
    Jx, r, _ = ev(x)
    if not math.isfinite(Jx):
        return x, J
    h = 1e-6 * T
    if k == 0:
        return x, Jx
    for _ in range(iterations):
        rf = r[idx]
        if float(np.max(np.abs(rf))) * T <= 1e-12 * max(1.0, abs(Jx)):
            break
        H = np.empty((k, k))
        ok = True
        for j, i in enumerate(idx):
            e = np.zeros(m)
            e[i] = h
            rp, rm = ev(x + e)[1][idx], ev(x - e)[1][idx]
            if not (np.all(np.isfinite(rp)) and np.all(np.isfinite(rm))):
                ok = False
                break
            H[:, j] = (rp - rm) / (2 * h)
        df = -rf
        if ok:
            H = 0.5 * (H + H.T)
            try:
                if np.all(np.linalg.eigvalsh(H) > 0):
                    df = np.asarray(-np.linalg.solve(H, rf), dtype=np.float64)
            except np.linalg.LinAlgError:
                pass
        slope = float(rf @ df)
        if slope >= 0:
            df, slope = -rf, -float(rf @ rf)
        d = np.zeros(m)
        d[idx] = df
        # near the minimum the decrease Newton predicts falls below the noise of J_b (its dual
        # value, converged to |F| <= 1e-12 in scaled units: the same t from two warm starts
        # differs by ~2e-12 relative): there a step that halves r without raising J_b beyond
        # 1e-10 relative is taken (random_problem(815853, m=3) under a box at 0.98 of its peaks
        # ended inaccurate at |r| 1e-3, the full step gives 3e-9 and +1.7e-9 of J_b = 9776;
        # (589819, m=3) at 0.82: |r| 3e-3 -> 1e-8, +3.1e-9 of J_b = 2520)
        x, Jx, r, moved = _backtrack(ev, x, d, Jx, r, slope, idx, 30, 1e-12 * T)
        if not moved:
            break
    return x, Jx


def _backtrack(ev: _Evaluator, x: FloatArray, d: FloatArray, J: float, r: FloatArray, slope: float,
               idx: Sequence[int] | npt.NDArray[np.integer[Any]], tries: int, min_step: float = 0.0
               ) -> tuple[FloatArray, float, FloatArray, bool]:
    """A backtracking step along ``d`` from ``x`` (``J``, ``r`` its values, ``slope`` the
    derivative of ``J`` along ``d``): halving the step from 1 at most ``tries`` times (or until
    ``alpha max|d| < min_step``), the first ``x + alpha d`` whose ``J_b`` decreases by Armijo's
    rule (1e-4 of the slope), or rises by at most ``J_b``'s noise (1e-10 relative) while the
    largest ``|r_i|`` over ``idx`` halves.  Returns the point, ``J_b``, ``r`` and whether it moved
    (else ``x``, ``J``, ``r`` as given)."""
    noise = 1e-10 * max(1.0, abs(J))
    ix = list(idx)
    r_ref = float(np.max(np.abs(r[ix])))
    alpha = 1.0
    for _ in range(tries):
        if alpha * float(np.max(np.abs(d))) < min_step:
            break
        xn = x + alpha * d
        Jn, rn, _ = ev(xn)
        if math.isfinite(Jn) and (Jn <= J + 1e-4 * alpha * slope or (
                Jn <= J + noise and float(np.max(np.abs(rn[ix]))) <= 0.5 * r_ref)):
            return xn, Jn, rn, True
        alpha *= 0.5
    return x, J, r, False


def _fd_width(ev: _Evaluator, x: FloatArray, i: int, T: float) -> float | None:
    """The central-difference width for ``r`` along contact time ``i`` at ``x``: ``1e-6 t_f``,
    quartered until ``x ± width`` both admit a plan (``None`` below ``1e-23 t_f``)."""
    h = 1e-6 * T
    for _ in range(30):
        e = np.zeros(len(x))
        e[i] = h
        if math.isfinite(ev(x + e)[0]) and math.isfinite(ev(x - e)[0]):
            return h
        h *= 0.25
    return None


def _root_along(ev: _Evaluator, x: FloatArray, i: int, T: float) -> FloatArray | None:
    """``x`` with contact time ``i`` at a zero of ``r_i`` (the others fixed), bracketed inside the
    feasible contact times: steps from ``x`` down ``J_b`` (``1e-9 t_f``, growing 4×) until ``r_i``
    changes sign, bisecting towards the last feasible time where a step leaves the feasible set,
    then Brent's method; ``None`` when ``r_i`` keeps its sign up to the edge (``J_b`` falls out of
    the set along ``t_i``: no zero to seat it at) or the bracket fails."""
    from scipy.optimize import brentq

    ri = float(ev(x)[1][i])
    if ri == 0.0:
        return x
    side = -math.copysign(1.0, ri)
    step, a = 1e-9 * T, float(x[i])
    b: float | None = None
    while b is None:
        y = np.array(x, dtype=float)
        y[i] = a + side * step
        if not 0.0 < y[i] < T:
            return None
        Jy, ry, _ = ev(y)
        if math.isfinite(Jy):
            if float(ry[i]) * ri <= 0.0:
                b = float(y[i])
            else:
                a, step = float(y[i]), 4.0 * step
            continue
        lo, hi = a, float(y[i])
        while b is None:
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                return None
            y[i] = mid
            Jm, rm, _ = ev(y)
            if not math.isfinite(Jm):
                hi = mid
            elif float(rm[i]) * ri > 0.0:
                lo = mid
            else:
                a, b = lo, mid

    def r_i(v: float) -> float:
        z = np.array(x, dtype=float)
        z[i] = v
        return float(ev(z)[1][i])

    try:
        root = float(brentq(r_i, min(a, b), max(a, b), xtol=1e-15 * T, maxiter=200))
    except (ValueError, RuntimeError):
        return None
    out = np.array(x, dtype=float)
    out[i] = root
    return out


def _valley_sweep(ev: _Evaluator, x: FloatArray, T: float, held: dict[int, float], keep: Any = ()
                  ) -> FloatArray:
    """One cycle of :func:`_valley_polish`'s sweeps: each contact time in turn (the others fixed) at
    the zero of its ``r_i`` inside the feasible set (:func:`_root_along`), or, where ``r_i`` keeps
    its sign up to the edge (``J_b`` falls out of the set), seated at that edge
    (:func:`_seat_at_edge`; recorded in ``held`` with its side); then a line search along the
    cycle's displacement (doubling while ``J_b`` falls: the valley's direction).  The times in
    ``keep`` stay where they are."""
    J = ev(x)[0]
    before = x.copy()
    for i in range(len(x)):
        if i in keep:
            continue
        z = _root_along(ev, x, i, T)
        if z is None:
            ri = float(ev(x)[1][i])
            side = -math.copysign(1.0, ri)
            z = _seat_at_edge(ev, x, i, side, T) if ri != 0.0 else None
            if z is not None and float(ev(z)[1][i]) * side < 0:
                held[i] = side
            else:
                z = None
        else:
            held.pop(i, None)
        Jz = ev(z)[0] if z is not None else math.inf
        if z is not None and Jz <= J + 1e-10 * abs(J):
            x, J = z, Jz
    step = x - before
    if held or not np.any(step):
        return x
    beta = 1.0
    for _ in range(30):
        y = x + beta * step
        Jy = ev(y)[0]
        if not (math.isfinite(Jy) and Jy < J):
            break
        x, J = y, Jy
        beta *= 2.0
    return x


def _valley_polish(ev: _Evaluator, x: FloatArray, T: float, verified: Any,
                   solves: int = VALLEY_SOLVES, iterations: int = VALLEY_ITERATIONS
                   ) -> tuple[FloatArray, dict[int, float], Any] | None:
    r"""Several vehicles: a stationary point of ``J_b`` in a thin curved valley of the feasible
    contact times, where :func:`_newton_polish` and :func:`_edge_polish` stall.
    ``verified(t, held)`` judges a candidate (the full self-check at ``t``, the times of ``held``
    at an edge: a result, or ``None`` when a check fails); returns ``(t, held, result)`` for the
    first candidate it accepts, ``None`` when none within ``solves`` axis-pair solves or
    ``iterations`` steps.

    Under a tight box on one input the feasible contact times can be a band ``1e-6 .. 1e-4 t_f``
    wide along some times, whose edges move with the other times, with ``J_b`` rising steeply
    towards them (``r_i`` from ``-10^5`` to ``+10^5`` across the band: a slice through it has a
    zero of ``r_i``).  The curvatures across and along the band differ by up to ``10^7``: central
    differences ``1e-6 t_f`` wide cross its edges (:func:`_newton_polish` then falls back to
    steepest descent and stops), and the Hessian's errors across the band swamp the curvature
    along it.  Here each step (1) on the first two steps and after a step that did not halve
    ``max|r|``: :data:`VALLEY_CYCLES` cycles of :func:`_valley_sweep` (every time at the zero of
    its own ``r_i`` inside the band, the valley's floor, or held at an edge ``J_b`` falls out
    through; a line search along each cycle's displacement), (2) a Newton step on the times not
    held, with the Hessian by central differences of ``r`` ``1e-6 t_f`` wide, or 1/100 of the
    width the feasible set allows across the band (:func:`_fd_width`), its eigenvalues replaced
    by their moduli (floored at ``1e-10`` of the largest), backtracking as :func:`_newton_polish`
    does.  The self-check judges the point once ``max|r| t_f`` over the times not held is below
    ``1e-6 J_b``, and where the steps end (a stall, the budget: that point, then the one the sweeps
    reach from it, then that one with the time of the largest ``|r_i|`` held at an edge ``J_b``
    falls out through, the others swept again); nothing is claimed from the iteration itself.

    Found by scripts/bounded_sweep.py (2026-11-29): 10 problems ``inaccurate`` (Hamiltonian jump
    0.26 .. 1.0), e.g. random_problem(320117, m=3) under an ``a_y`` box at 0.5535 (the FOH QP's
    sweep at ``N = 8`` plans at 17226.0): ``local`` at 12538.09 with every check passing."""
    m = len(x)
    start = ev.evaluations
    x = np.array(x, dtype=float)
    J, r, _ = ev(x)
    if not (math.isfinite(J) and np.all(np.isfinite(r))):
        return None
    held: dict[int, float] = {}

    def last_try() -> tuple[FloatArray, dict[int, float], Any] | None:
        # where the steps end (a stall, the budget): the self-check judges the point reached,
        # then the point the sweeps reach from it (a time whose r_i turns within 1e-11 t_f of its
        # edge, where a Newton step's differences cannot follow it, seated at its zero)
        y = x
        for _ in range(2):
            result = verified(y, dict(held))
            if result is not None:
                return y, dict(held), result
            for _ in range(VALLEY_CYCLES):
                y = _valley_sweep(ev, y, T, held)
        # the time with the largest |r_i| held at an edge J_b falls out through (EDGE_BACKOFF
        # inside it; its zero, if any, within the rounding of r_i there), the others swept again
        ry = ev(y)[1]
        free = [i for i in range(m) if i not in held and math.isfinite(ry[i])]
        if not free:
            return None
        i = max(free, key=lambda k: abs(float(ry[k])))
        for side in (1.0, -1.0):
            z = _seat_at_edge(ev, y, i, side, T)
            if z is None or not float(ev(z)[1][i]) * side < 0:
                continue
            held_z = {**held, i: side}
            for _ in range(VALLEY_CYCLES):
                z = _valley_sweep(ev, z, T, held_z, keep=(i,))
            result = verified(z, dict(held_z))
            if result is not None:
                return z, held_z, result
        return None

    poor = True
    for it in range(iterations):
        if it < 2 or poor:
            for _ in range(VALLEY_CYCLES):
                x = _valley_sweep(ev, x, T, held)
            J, r, _ = ev(x)
        free = [i for i in range(m) if i not in held]
        if not free or ev.evaluations - start > solves:
            return last_try()
        rf = r[free]
        r_before = float(np.max(np.abs(rf)))
        k = len(free)
        H = np.empty((k, k))
        for j, i in enumerate(free):
            h = _fd_width(ev, x, i, T)
            if h is None:
                return last_try()
            if h < 1e-6 * T:  # across the band: well inside its edges
                h *= 0.01
            e = np.zeros(m)
            e[i] = h
            H[:, j] = (ev(x + e)[1][free] - ev(x - e)[1][free]) / (2 * h)
        H = 0.5 * (H + H.T)
        if not np.all(np.isfinite(H)):
            return last_try()
        w, V = np.linalg.eigh(H)
        w = np.maximum(np.abs(w), 1e-10 * float(np.max(np.abs(w))))
        if not np.all(w > 0):
            return last_try()
        d = np.zeros(m)
        d[free] = -(V @ ((V.T @ rf) / w))
        slope = float(rf @ d[free])
        x, J, r, moved = _backtrack(ev, x, d, J, r, slope, free, 50)
        if not moved:
            return last_try()
        poor = float(np.max(np.abs(r[free]))) > 0.5 * r_before
        if float(np.max(np.abs(r[free]))) * T <= 1e-6 * max(1.0, abs(J)):
            result = verified(x, dict(held))
            if result is not None:
                return x, dict(held), result
        if ev.evaluations - start > solves:
            break
    return last_try()


def _seat_at_edge(ev: _Evaluator, x: FloatArray, i: int, side: float, T: float) -> FloatArray | None:
    """``x`` with contact time ``i`` moved to the edge of the feasible contact times on ``side``
    (``+1`` later, ``-1`` earlier; the others fixed), planned :data:`EDGE_BACKOFF` ``t_f`` inside
    it as one vehicle's; ``None`` when ``x_i + side·EDGE_PROBE·t_f`` is feasible (no edge there)."""
    out = np.array(x, dtype=float)
    out[i] = x[i] + side * EDGE_PROBE * T
    if math.isfinite(ev(out)[0]):
        return None
    edge_t = _feasible_edge(ev, float(x[i]), float(out[i]), T, x, i)
    out[i] = edge_t - side * EDGE_BACKOFF * T
    if not math.isfinite(ev(out)[0]):
        out[i] = edge_t
    return out


def _edge_polish(ev: _Evaluator, x: FloatArray, T: float, rounds: int = 10
                 ) -> tuple[FloatArray, dict[int, float], dict[int, float]] | None:
    """Several vehicles: the minimum of ``J_b`` beside or at an edge of the feasible contact
    times.  Each round, a contact time whose descent ``−r_i`` leaves the feasible set within
    ``EDGE_PROBE t_f`` is moved to its edge (:func:`_seat_at_edge`, the others fixed): if ``r_i``
    still points out there, the time stays at the edge (an active bound); if ``r_i`` has turned
    (``J_b`` rises again just inside the edge), Brent's method finds its root between the edge
    and the probe, as :func:`_edge_candidate` for one vehicle.  Either way the time is held
    while :func:`_newton_polish` moves the others (its central differences, ``1e-6 t_f`` wide,
    would cross the edge).  A time not held whose descent meets no edge is tried at an edge on
    the other side too (``J_b`` rising towards it; ``r_i`` may turn just inside:
    random_problem(148435, m=3) at 0.7157, ``t_0`` within ``1e-8 t_f`` of its upper edge, ``r_0``
    turning ``1e-7 .. 1e-6 t_f`` inside; ``local`` at 1551.93, was ``inaccurate``).  A held time
    whose ``r_i`` points into the feasible set at the edge
    and ``EDGE_PROBE t_f`` inside, once the polish has moved anything, is released (``J_b`` now
    falls away from that edge: random_problem(217970, m=3) at 0.7252, ``t_1`` held at its upper
    edge at 2551.05 with ``r_1 = +1.5e7``, ``local`` at 2489.03 when released); when none is held
    any more, the Newton polish moves every time and the result is returned with no edge.
    Ends when a round changes nothing, after ``rounds`` at most.
    Returns ``(x, at_edge, held)``, each ``{i: side}`` (``side`` ``+1`` upper, ``-1`` lower):
    the times at an edge and all those held near one; ``None`` when no contact time is near an edge.

    Found by test_bounded_random: random_problem(864097, m=3) with its box at 0.744 of its peaks,
    where L-BFGS-B and the Newton polish stop ``7e-7 t_f`` below the upper edge of ``t_0``'s
    feasible times (``J_b`` falls to within ``5e-8 t_f`` of the edge, then rises) with ``J_b``
    still falling along ``t_2`` (Hamiltonian-jump check 0.016)."""
    from scipy.optimize import brentq

    m = len(x)
    x = np.array(x, dtype=float)
    held: dict[int, float] = {}
    at_edge: dict[int, float] = {}
    start = x.copy()
    for _ in range(rounds):
        before = x.copy()
        J, r, _ = ev(x)
        if not (math.isfinite(J) and np.all(np.isfinite(r))):
            return None
        for i in range(m):
            if r[i] == 0.0:
                continue
            side = held.get(i, -math.copysign(1.0, float(r[i])))
            seated = _seat_at_edge(ev, x, i, side, T)
            if seated is None and i not in held:  # at an edge J_b rises towards: r_i may turn inside
                side = -side
                seated = _seat_at_edge(ev, x, i, side, T)
            if seated is None:
                held.pop(i, None)
                at_edge.pop(i, None)
                continue
            held[i] = side
            r_edge = ev(seated)[1][i]
            if r_edge * side < 0:  # J_b falls out of the feasible set: the edge is the minimum
                x, at_edge[i] = seated, side
                continue
            at_edge.pop(i, None)
            inner = seated.copy()
            inner[i] = seated[i] - side * EDGE_PROBE * T
            if not ev(inner)[1][i] * side < 0:
                if ev(seated)[0] < ev(x)[0]:
                    x = seated
                elif not np.array_equal(x, start):
                    held.pop(i, None)  # J_b falls away from the edge now: the time is free again
                continue

            def r_i(y: float, i: int = i, base: FloatArray = seated) -> float:
                z = base.copy()
                z[i] = y
                rr = ev(z)[1][i]
                return float(rr) if np.isfinite(rr) else 0.0

            try:
                x = seated.copy()
                x[i] = float(brentq(r_i, min(inner[i], seated[i]), max(inner[i], seated[i]), xtol=1e-14 * T,
                                    maxiter=200))
            except (ValueError, RuntimeError):
                x = seated
        if not held:
            if np.array_equal(x, start):
                return None
            x, _ = _newton_polish(ev, x, ev(x)[0], T)
            return x, at_edge, held
        free = np.array([i not in held for i in range(m)])
        x, _ = _newton_polish(ev, x, ev(x)[0], T, free=free)
        if np.array_equal(x, before):
            break
    return x, at_edge, held


#: Half-widths (over ``t_f``) of the brackets in which :func:`_stationary_brackets` looks for the
#: sign change of ``r_i`` at a time beside an edge; the smallest is above the reach of
#: the noise of ``r_i`` there (random_problem(539214, m=3) at 0.7162: ``r_1`` differs by 2 between
#: warm and cold solves at one time, while it moves ``2.3e11 t_f`` per unit of time).
STATIONARY_BRACKET = (1e-11, 1e-10, 1e-9)


def _stationary_brackets(ev: _Evaluator, sol: BoundedSolution, times: list[int], T: float
                         ) -> dict[int, dict[str, float]] | None:
    r"""Times whose Hamiltonian-jump residual fails its check only by the precision of ``r``:
    ``{i: {"delta": δ, "r_minus": r_i(t_i − δ t_f), "r_plus": r_i(t_i + δ t_f), "cost_bound": …}}``
    for each ``i`` of ``times`` whose own residual exceeds ``pmp_hjump_rel``, or ``None`` when one
    of them has no such bracket.

    Just inside an edge of the feasible contact times the multipliers are large and
    :math:`r_i = H^- - H^+ - \dot x_{s,i}\Phi_{i,x}` is a difference of large terms: its
    rounding (warm against cold solves of the same times) can exceed the check's tolerance at
    every float time near its zero.  Then the claim is made by the sign of ``r_i`` instead: with
    the other times fixed, :math:`r_i(t_i-\delta) < 0 < r_i(t_i+\delta)`, both larger than
    :math:`|r_i(t_i)|` (the size of ``r_i``'s rounding there: the signs are read beyond it), for
    the first ``δ`` of :data:`STATIONARY_BRACKET` (``t_f`` units) where it holds, so by continuity of
    :math:`r_i = \partial J_b/\partial t_i` (the fixed-time problem is strictly convex, its
    solution and ``J_b`` smooth in ``t`` where feasible) a zero ``t_i^*`` of ``r_i`` lies within
    ``δ t_f`` of ``t_i``, and ``J_b`` rises through it (a minimum along ``t_i``).  With ``r_i``
    monotone across the bracket, :math:`|J_b(t) - J_b(t^*)| \le \delta t_f\max|r_i(t_i\pm\delta)|`
    (``cost_bound``), which must be within ``pmp_bounded_gap_rel`` of ``J_b``: the plan is then
    the stationary one to the precision its cost is checked to."""
    r, size = sol.hamiltonian_jump_terms()
    t = np.array(sol.contact_times, dtype=float)
    hscale = max(1e-300, sol.cost / T)
    tol = TOLERANCES["pmp_hjump_rel"]
    out: dict[int, dict[str, float]] = {}
    for i in times:
        si = float(size[i])
        if abs(float(r[i])) <= tol * (si if si > HJUMP_FLOOR * hscale else HJUMP_FLOOR * hscale):
            continue
        for delta in STATIONARY_BRACKET:
            lo, hi = t.copy(), t.copy()
            lo[i] -= delta * T
            hi[i] += delta * T
            r_lo, r_hi = float(ev(lo)[1][i]), float(ev(hi)[1][i])
            if r_lo < 0 < r_hi and min(-r_lo, r_hi) > abs(float(r[i])):
                bound = delta * T * max(-r_lo, r_hi)
                if bound <= TOLERANCES["pmp_bounded_gap_rel"] * sol.cost:
                    out[i] = {"delta": delta, "r_minus": r_lo, "r_plus": r_hi, "cost_bound": bound}
                break
        if i not in out:
            return None
    return out


def _kkt_at_edges(ev: _Evaluator, sol: BoundedSolution, edges: dict[int, float], T: float) -> bool:
    """Whether each contact time ``i`` of ``edges`` is at an edge of the feasible contact times
    with ``J_b`` falling out of the set (KKT with the edge an active bound): the slope
    ``r_i = ∂J/∂t_i`` of the plan's own solution has the sign that points out (``r_i < 0`` at an
    upper edge, ``> 0`` at a lower), and ``t_i ± EDGE_PROBE t_f`` beyond it admits no plan."""
    r = sol.hamiltonian_jump_residual()
    t = np.array(sol.contact_times, dtype=float)
    for i, side in edges.items():
        if not r[i] * side < 0:
            return False
        out = t.copy()
        out[i] += side * EDGE_PROBE * T
        if math.isfinite(ev(out)[0]):
            return False
    return True


def _feasible_start(ev: _Evaluator, search: dict[str, Any], grid: int = 64, per_axis: int = 8
                    ) -> FloatArray | None:
    """Three or more vehicles, where the unbounded ``t*`` admits no plan and infeasibility is not
    certified: the contact times that admit a plan with each vehicle alone (a necessary
    condition: every vehicle only removes plans) among ``grid`` points of ``(0, t_f)``, then
    ``J_b`` on the product of ``per_axis`` of each vehicle's, evenly spread; the cheapest feasible
    point (``None``: none).  Recorded in ``search["feasible_start"]`` (``alone``: each vehicle's
    count of feasible grid points; ``points``, ``feasible``: the product's).

    Found by test_bounded_random: random_problem(498873, m=3) under a box at 0.833 of its peaks
    was ``infeasible`` (not certified: 4000 solves closed nothing) while the FOH QP at ``N = 8``
    plans at 654.78; 6 of the 512 product points admit a plan (a uniform grid of 8 per axis: none)."""
    problem = ev.problem
    T = ev.T
    g = T * (np.arange(grid) + 0.5) / grid
    picks: list[FloatArray] = []
    alone_counts: list[int] = []
    for v in problem.vehicles:
        alone = _Evaluator(Problem(problem.ego, (v,), problem.name, problem.limits))
        ok = np.array([x for x in g if math.isfinite(alone(np.array([x]))[0])])
        alone_counts.append(len(ok))
        if len(ok) == 0:
            search["feasible_start"] = {"alone": alone_counts, "points": 0, "feasible": 0}
            return None
        picks.append(ok[np.unique(np.linspace(0, len(ok) - 1, min(per_axis, len(ok))).round().astype(int))])
    mesh = np.stack(np.meshgrid(*picks, indexing="ij"), axis=-1).reshape(-1, len(picks))
    found = [(J, k) for k, J in enumerate(ev(c)[0] for c in mesh) if math.isfinite(J)]
    search["feasible_start"] = {"alone": alone_counts, "points": len(mesh), "feasible": len(found)}
    return mesh[min(found)[1]] if found else None


def plan_bounded(problem: Problem, start_times: FloatArray | None, contact_times: Any = None,
                 start: float | None = None, certify: bool = True, retries: int = 2, finer: bool = True,
                 valley: bool = True) -> Plan:
    """The bounded PMP plan (module docstring): fixed ``contact_times`` or a search from
    ``start_times`` (the unbounded ``t*``).  With ``certify`` (one vehicle, free contact time)
    :func:`certify_global_one` decides ``optimal`` (certified global) or ``local``.  Never
    raises for numerical trouble."""
    t0 = _time.perf_counter() if start is None else start
    m = problem.m
    T = float(problem.tf)
    info: dict[str, Any] = {"bounded": {"method": "saturated co-state law, semi-smooth Newton on the dual"}}
    # the boundary conditions alone out of reach (a Farkas certificate per axis): asked only
    # once no contact time has given a plan (a plan at any contact time meets them too)
    boundary_info = {"bounded": dict(info["bounded"])}

    def out_of_reach() -> Plan | None:
        reason = boundary_feasible(problem)
        if reason is None:
            return None
        return _failed(problem, INFEASIBLE, "boundary_out_of_reach", boundary_info, t0, reason)

    ev = _Evaluator(problem)
    fixed = contact_times is not None
    if fixed:
        t = np.asarray(contact_times, dtype=float).reshape(-1)
        search: dict[str, Any] = {"method": "given contact times"}
    elif m == 1:
        starts = [float(start_times[0])] if start_times is not None and np.all(np.isfinite(start_times)) else []
        t, search = _search_one(ev, T, starts, GRID_ONE)
        search["method"] = f"grid of {GRID_ONE} + unbounded t* + Brent on dJ/dt = H⁻−H⁺−ẋ_sΦ_x"
    else:
        starts_m = [np.asarray(start_times, dtype=float)] if start_times is not None and np.all(
            np.isfinite(start_times)) else []
        t, search = _search_many(ev, T, m, starts_m, 8, finer)
        search["method"] = ("grid (8 per axis for m <= 2) + unbounded t* + a finer grid pruned by J_u "
                            "+ L-BFGS-B with the exact gradient r")
    info["search"] = search
    if not fixed and not np.all(np.isfinite(t)):
        unreachable = out_of_reach()
        if unreachable is not None:
            return unreachable
        proof = infeasibility_certificate(problem, pair_solves=PAIR_SOLVES if m == 2 else 0)
        solves = proof.solves
        if not proof.certified and proof.feasible_t is None and m > 2:
            # the contact times feasible for each vehicle alone first (cheap), then the pairs
            t_start = _feasible_start(ev, search)
            if t_start is not None:
                proof = InfeasibilityCertificate(False, t_start, proof.boxes, solves)
            else:
                proof = pair_projection(problem, PAIR_SOLVES)
                solves += proof.solves
        certified, t_feasible, intervals = proof.certified, proof.feasible_t, proof.boxes
        search["infeasibility_intervals"] = intervals
        search["infeasibility_solves"] = solves
        if proof.vehicle is not None:
            search["infeasibility_vehicle"] = proof.vehicle
        if proof.pair is not None:
            search["infeasibility_vehicles"] = list(proof.pair)
        if certified:
            what = "contact time in (0, t_f)" if m == 1 else f"choice of the {m} contact times in (0, t_f)^{m}"
            how = (f"{intervals} {'intervals' if m == 1 or proof.vehicle is not None else 'boxes'}"
                   + ("" if proof.vehicle is None else f" of vehicle {proof.vehicle}'s contact time, which alone "
                      "admits no plan")
                   + ("" if proof.pair is None else f" of the contact times of vehicles {proof.pair[0]} and "
                      f"{proof.pair[1]}, which alone admit no plan"))
            return _failed(problem, INFEASIBLE, "box_infeasible_at_every_contact_time", info, t0,
                           f"no {what} admits a plan within the input box (certified: {how}, each with a "
                           "Farkas certificate and a Lipschitz margin)")
        if t_feasible is not None:
            if m == 1:
                t, more = _search_one(ev, T, [float(t_feasible[0])], GRID_ONE)
            else:
                t, more = _search_many(ev, T, m, [t_feasible], 8, finer)
            search.update(more)
    if not np.all(np.isfinite(t)):
        msg = ("no contact time admits a plan within the input box" +
               ("" if fixed else f" (all {search.get('evaluations', 0)} evaluated times infeasible; "
                "not certified between grid points)"))
        return _failed(problem, INFEASIBLE, "box_infeasible_at_contact_times", info, t0, msg)
    try:
        with np.errstate(all="ignore"):
            sol = solve_bounded_fixed(problem, t, ev.warm_for(t))
            values = check_values(sol, stationary=_stationary(search, fixed))
    except AxisInfeasible as exc:
        return out_of_reach() or _failed(problem, INFEASIBLE, "box_infeasible_at_contact_times", info, t0, str(exc))
    except (AxisNoConvergence, np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError, OverflowError) as exc:
        info["error"] = f"{type(exc).__name__}: {exc}"
        return out_of_reach() or _failed(problem, NUMERICAL_ERROR, "dual_newton", info, t0, str(exc))
    checks, failed, bad = judge(values)
    if bad is not None:
        # the warm start can end on multipliers that meet F = 0 less well than a cold start
        # (near the edge of the feasible contact times they are large): one cold solve
        try:
            with np.errstate(all="ignore"):
                cold = solve_bounded_fixed(problem, t)
                cold_values = check_values(cold, stationary=_stationary(search, fixed))
            cold_judged = judge(cold_values)
            if cold_judged[2] is None:
                sol, values, (checks, failed, bad) = cold, cold_values, cold_judged
        except (AxisInfeasible, AxisNoConvergence, np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError,
                OverflowError):
            pass
    valley_starts = [t]

    def judged_at(sol_x: BoundedSolution, held: Any) -> tuple[dict[str, float], Any, dict[int, dict[str, float]]]:
        """The checks of ``sol_x`` with the times ``held`` at their edges (no jump condition there);
        where the jump condition fails, a time beside an edge whose ``r_i`` has too few digits for
        it is stationary by its sign (:func:`_stationary_brackets`, those times added to the held
        ones): the values, their verdict and those brackets."""
        with np.errstate(all="ignore"):
            v_x = check_values(sol_x, stationary=True, at_edge=sorted(held))
        j_x = judge(v_x)
        brackets: dict[int, dict[str, float]] = {}
        if j_x[1] == "hamiltonian_jump":
            brackets = _stationary_brackets(ev, sol_x, [i for i in range(m) if i not in held], T) or {}
            if brackets:
                with np.errstate(all="ignore"):
                    v_x = check_values(sol_x, stationary=True, at_edge=sorted({*held, *brackets}))
                j_x = judge(v_x)
        return v_x, j_x, brackets

    if failed == "hamiltonian_jump" and m > 1 and not fixed:
        # several vehicles: the minimum may sit at an edge of the feasible contact times, where
        # r_i ≠ 0 for the times at the edge: the polish keeps those at their edge and moves the
        # others; the jump condition then applies to the free times only, once the slope of
        # each time at an edge is seen to point out of the feasible set (_kkt_at_edges)
        polished = _edge_polish(ev, t, T)
        if polished is not None and not np.array_equal(polished[0], t):
            t_e, edges, held = polished
            valley_starts.insert(0, t_e)
            try:
                with np.errstate(all="ignore"):
                    sol_e = solve_bounded_fixed(problem, t_e, ev.warm_for(t_e))
                # beside an edge r_i may have too few digits for the check (held where it turns
                # just inside its edge, or polished next to a time held there): stationary by r_i's sign
                values_e, judged_e, brackets = judged_at(sol_e, edges)
                if judged_e[2] is None and _kkt_at_edges(ev, sol_e, edges, T):
                    t, sol, values, (checks, failed, bad) = t_e, sol_e, values_e, judged_e
                    r_e = sol_e.hamiltonian_jump_residual()
                    search["edge_polish"] = {"held": [{"vehicle": i, "side": "upper" if side > 0 else "lower"}
                                                      for i, side in sorted(held.items())]}
                    if brackets:
                        search["edge_polish"]["stationary_by_sign"] = [
                            {"vehicle": i, "t": float(sol_e.contact_times[i]), **b}
                            for i, b in sorted(brackets.items())]
                    if edges:
                        search["feasibility_edges"] = [
                            {"vehicle": i, "side": "upper" if edges[i] > 0 else "lower",
                             "t": float(sol_e.contact_times[i]), "slope": float(r_e[i])} for i in sorted(edges)]
                    search["evaluations"] = ev.evaluations
            except (AxisInfeasible, AxisNoConvergence, np.linalg.LinAlgError, FloatingPointError,
                    ZeroDivisionError, OverflowError):
                pass
    if failed == "hamiltonian_jump" and search.get("stationary_within_ulp"):
        # r changes sign between adjacent float contact times (beside an edge, _edge_candidate):
        # no float time is nearer r = 0, so the condition is not applied; the claim rests on
        # the global certificate (``local`` without it)
        values = {k: v for k, v in values.items() if k != "hamiltonian_jump"}
        checks, failed, bad = judge(values)
        search["hamiltonian_jump_not_applied"] = "r changes sign within one ulp of the contact time"
    # the finer grid's start led to a minimum the checks do not verify (on a curved edge of the
    # feasible contact times): the valley polish below, and the search without the finer grid,
    # whose plan may pass them (random_problem(369004, m=2) under an a_y box at 0.373: `local`
    # 2579.171 without it); the cheaper verified plan of the two is taken
    # (random_problem(732887, m=3) under an a_y box at 0.3179: the search without the finer grid
    # ends `local` at 25342.5, the valley polish from the finer grid's times at 12614.6)
    finer_unverified = bad is not None and m > 1 and finer and not fixed and bool(search.get("grid_points"))
    t_finer, failed_finer = t, failed
    if failed == "hamiltonian_jump" and m > 1 and not fixed and valley:
        # still unverified: a thin curved valley of feasible contact times (_valley_polish), from
        # the edge polish's times, then the search's; the plan is taken only if every check passes

        by_sign: list[dict[str, float]] = []

        def verified(x: FloatArray, held: dict[int, float]
                     ) -> tuple[BoundedSolution, dict[str, float], Any] | None:
            for warm in (ev.warm_for(x), None):
                try:
                    with np.errstate(all="ignore"):
                        s_v = solve_bounded_fixed(problem, x, warm)
                    # a time whose r_i has too few digits beside an edge: stationary by its sign
                    v_v, j_v, brackets = judged_at(s_v, held)
                except (AxisInfeasible, AxisNoConvergence, np.linalg.LinAlgError, FloatingPointError,
                        ZeroDivisionError, OverflowError):
                    continue
                if j_v[2] is None and _kkt_at_edges(ev, s_v, held, T):
                    by_sign[:] = [{"vehicle": i, "t": float(s_v.contact_times[i]), **b}
                                  for i, b in sorted(brackets.items())]
                    return s_v, v_v, j_v
            return None

        for k, x0 in enumerate(valley_starts):
            before = ev.evaluations
            found = _valley_polish(ev, x0, T, verified)
            if found is not None:
                t, edges_v, (sol, values, (checks, failed, bad)) = found
                search["valley_polish"] = {"start": "edge polish" if k < len(valley_starts) - 1 else "search",
                                           "from": [float(v) for v in x0], "solves": ev.evaluations - before}
                search.pop("edge_polish", None)
                search.pop("feasibility_edges", None)
                if edges_v:
                    r_v = sol.hamiltonian_jump_residual()
                    search["feasibility_edges"] = [
                        {"vehicle": i, "side": "upper" if edges_v[i] > 0 else "lower",
                         "t": float(sol.contact_times[i]), "slope": float(r_v[i])} for i in sorted(edges_v)]
                if by_sign:
                    search["valley_polish"]["stationary_by_sign"] = by_sign
                search["evaluations"] = ev.evaluations
                break
    if finer_unverified:
        again = plan_bounded(problem, start_times, None, t0, certify, retries, finer=False, valley=False)
        if again.status in (OPTIMAL, LOCAL) and (bad is not None or (again.cost is not None
                                                                       and again.cost < sol.cost)):
            again.annotate(search={**(getattr(again.diagnostics, "search", None) or {}),
                                   "finer_grid_unverified": {"t": [float(x) for x in t_finer],
                                                             "failed_check": failed_finer}})
            return again
    certified = bool(fixed)
    if bad is None and not fixed:
        if m == 1 and certify:
            cert = certify_global_one(problem, sol.cost, value_function=ev.value_function(),
                                      t_best=float(sol.contact_times[0]), warm_best=[sol.axes[0].lam, sol.axes[1].lam],
                                      edge=_edge_of(search, float(sol.contact_times[0])),
                                      warm_edge=ev.warm_for(np.array([search["edge"]["t"]])) if "edge" in search
                                      else None)
            if "better_t" in cert and retries > 0:
                # the certificate found a better contact time: the search again, started there
                again = plan_bounded(problem, np.array([cert["better_t"]]), None, t0, certify, retries - 1)
                again.annotate(search={**(getattr(again.diagnostics, "search", None) or {}),
                                       "restarted_from_certificate": {"t": cert["better_t"], "J": cert["better_J"],
                                                                      "J_before": sol.cost}})
                return again
            certified = bool(cert["certified"])
            info["global_certificate"] = {**cert, "rel": TOLERANCES["pmp_global_certificate_rel"],
                                          "method": "dual Taylor bound per interval of contact times, "
                                                    "Farkas margin where the box is infeasible"}
            if not certified:
                info["global_note"] = ("the interval certificate did not close (budget or a stalled solve): "
                                       "the minimum is verified at its contact time, not shown global")
        else:
            info["global_note"] = ("no certificate over the contact times for several vehicles" if m > 1 else
                                   "certificate not requested (certify=False)")
    info.update(checks=checks, failed_check=failed, certified_global=certified)
    info["bounded"].update(switching_times=sol.switching_times(),
                           newton_iterations=[ax.iterations for ax in sol.axes])
    status = bad if bad is not None else (OPTIMAL if certified else LOCAL)
    info["hamiltonian_jump_residuals"] = sol.hamiltonian_jump_residual()
    plan = Plan(problem=problem, planner="pmp", status=status, cost=sol.cost if bad is None else None,
                contact_times=sol.contact_times.copy(), jumps=sol.jumps, trajectory=sol,
                solve_time_s=_time.perf_counter() - t0, diagnostics=BoundedPMPDiagnostics.from_info(info))
    plan.residuals = {k: float(v) for k, v in values.items()}
    return plan


def apply_state_limits(plan: Plan, **before: Any) -> Plan:
    """Check every given bound on the plan with exact peaks (``info["limits"]``); a verified
    plan that violates one becomes ``limits_violated`` (the input box of the PMP is imposed,
    so only ``vx``, ``y``, ``a_total``, ``jerk`` can fail on a bounded plan).  ``before``:
    diagnostics the caller adds first (the same fields, in the same order, as its own
    :meth:`~iamp.core.plan.Plan.annotate` call before this one; one copy of the diagnostics
    instead of two)."""
    if plan.trajectory is None or plan.status not in (OPTIMAL, LOCAL):
        if before:
            plan.annotate(**before)
        return plan
    peaks = exact_peaks(plan.trajectory, float(plan.problem.tf), plan_knots(plan))
    report = limits_report(plan.problem, peaks)
    bad = [name for name, r in report.items() if not r["ok"]]
    if bad:
        plan.annotate(**before, limits=report, peaks=peaks)
        plan.annotate(limits_violated=bad)
        # the project's one verdict (Plan.judge_limits: core peaks, the same exact pieces via
        # BoundedSolution.breakpoints) names the bound; this report is the PMP's own check
        plan.judge_limits("the PMP imposes only the input box ax, ay exactly")
        if plan.status != LIMITS_VIOLATED:
            plan.annotate(reason="the plan exceeds " + ", ".join(
                f"{n} (peak {_fmt_bound(report[n]['peak'])}, bound {_fmt_bound(report[n]['bound'])})" for n in bad))
            plan.status = LIMITS_VIOLATED
        return plan
    # one copy of the diagnostics (the same fields, in the same order, as two annotate calls)
    plan.annotate(**before, limits=report, peaks=peaks, limits_note=("every given bound holds on this plan, so it is "
                                                           f"{plan.status} for the bounded problem too"))
    return plan


def _failed(problem: Problem, status: str, check: str, info: dict[str, Any], start: float, reason: str) -> Plan:
    info["failed_check"] = check
    info["reason"] = reason
    info.setdefault("checks", {})
    return Plan(problem=problem, planner="pmp", status=status, cost=None,
                contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                trajectory=None, solve_time_s=_time.perf_counter() - start,
                diagnostics=BoundedPMPDiagnostics.from_info(info))


def _fmt_bound(value: Any) -> str:
    """A peak or bound for a message: 4 significant digits, a range as ``[lo, hi]``."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt_bound(v) for v in value) + "]"
    if isinstance(value, (int, float)):
        return f"{float(value):.4g}"
    return str(value)


def box_respected(plan: Plan) -> bool:
    """Whether an (unbounded) plan's inputs stay in the problem's ``ax``/``ay`` box (exact
    peaks at the knots, ``limits_bound_rel`` slack)."""
    (lx, hx), (ly, hy) = input_box(plan.problem)
    kn = np.asarray(sorted(set([0.0, float(plan.problem.tf)] + plan_knots(plan))))
    U = plan.inputs(kn)
    rel = TOLERANCES["limits_bound_rel"]
    for k, (lo, hi) in enumerate(((lx, hx), (ly, hy))):
        slack = rel * max([1.0, *(abs(b) for b in (lo, hi) if math.isfinite(b))])
        if U[:, k].min() < lo - slack or U[:, k].max() > hi + slack:
            return False
    return True


__all__ = ["BoundedSolution", "apply_state_limits", "boundary_feasible", "box_respected", "certify_global_one",
           "check_values", "exact_peaks", "input_box", "interval_bound", "judge", "limits_report", "plan_bounded",
           "solve_bounded_fixed"]
