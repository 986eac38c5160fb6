r"""The equality QP of SPEC §3 with the scenario's physical limits (SPEC §14) at every node.

The rows of :class:`~iamp.planners.qp.data.QPData` (dynamics, boundary, corner selectors;
all equalities, ``l = u = b``) are stacked over the limit rows of
:func:`iamp.planners.qp.limits.limit_rows` (``lo <= A_L z <= hi``)::

    [ A   ]  z  in  [ b  , b  ]
    [ A_L ]         [ lo , hi ]

and solved on a backend that takes inequalities (``osqp``, ``clarabel``, ``piqp``; the direct
``kkt`` backend solves equalities only and is refused with
:class:`~iamp.planners.qp.backends.base.UnsupportedProblemError` naming them).  A candidate is
still a value update: the selector entries of ``A`` (mapped to their positions in the
stacked matrix) and the corner values of ``b``; a new grid updates ``P``, ``A`` and the jerk
rows' bounds.

Verification of every solve (recomputed here, never the solver's word), with the backend's
relative tolerance (``cmp_kkt_rel_*``):

* the KKT residuals of the general form (:func:`~iamp.planners.qp.backends.base.kkt_residuals`:
  primal feasibility of every row, stationarity, duality gap);
* **dual sign and complementarity** of the limit rows, :math:`y_i > 0` only at the upper
  bound, :math:`y_i < 0` only at the lower one:
  :math:`\max_i \big(y_i^+ (hi_i - a_i^\top z)^+ + y_i^- (a_i^\top z - lo_i)^+\big)` relative to
  :math:`\max(1, \|y\|_\infty)\,\max(1, \|A_L z\|_\infty)` (``kkt_complementarity_rel``).

A candidate the solver calls infeasible counts as infeasible only with a verified Farkas
certificate (:func:`~iamp.planners.qp.backends.base.farkas_residuals`: ``A^T δy = 0`` to
:data:`FARKAS_STATIONARITY` and a support below ``-``:data:`FARKAS_SUPPORT`); such a candidate
cannot beat the sweep's best, so it does not spoil the certificate of the sweep
(:mod:`iamp.planners.qp.sweep`).  When no candidate is feasible, the planner says why
(:func:`infeasibility_reason`); the status is ``infeasible`` when the solver says so for
every candidate, or when the problem without the corners is certified infeasible (then every
candidate is, whatever its own solve said), and the reason says how many were certified (PIQP
gives no certificate).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from iamp.core import status as st
from iamp.core.physical import PhysicalLimits
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.qp.backends import BACKENDS, QPBackend, get_backend
from iamp.planners.qp.backends.base import (
    FloatArray,
    IntArray,
    KKTResiduals,
    QPSolution,
    UnsupportedProblemError,
    farkas_residuals,
    kkt_residuals,
)
from iamp.planners.qp.core import CandidateResult, DiscretisedQP, verify
from iamp.planners.qp.data import QPData
from iamp.planners.qp.hold import HoldTrajectory
from iamp.planners.qp.limits import LimitRows, limit_rows

#: Added to OSQP's settings for the bounded QP: its infeasibility test at the default
#: ``eps_prim_inf = 1e-4`` returns certificates with ``‖Aᵀδy‖ / ‖A‖`` of 1e-5..1e-4 (not
#: verifiable); at 1e-8 they verify (~1e-8; measured on paper-3 with the passenger car's
#: limits, 50-5000 ADMM iterations per infeasible candidate).
OSQP_SETTINGS: dict[str, Any] = {"eps_prim_inf": 1e-8}

#: A Farkas certificate's ``‖Aᵀδy‖∞ / ‖A‖max`` (δy scaled to unit max-norm) must be below this ...
FARKAS_STATIONARITY = 1e-7
#: ... and its support (relative to ``max(1, ‖l, u‖∞)``) below minus this.
FARKAS_SUPPORT = 1e-9


def inequality_backends() -> list[str]:
    """The registered backends that solve inequalities."""
    return [name for name, cls in BACKENDS.items() if cls.supports_inequalities]


def complementarity(Az: FloatArray, y: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[float, float]:
    """``(absolute, relative)`` complementarity of the limit rows (module docstring)."""
    yp, ym = np.maximum(y, 0.0), np.maximum(-y, 0.0)
    slack_hi, slack_lo = np.maximum(hi - Az, 0.0), np.maximum(Az - lo, 0.0)
    val = float(np.max(yp * slack_hi + ym * slack_lo, initial=0.0))
    scale = max(1.0, float(np.max(np.abs(y), initial=0.0))) * max(1.0, float(np.max(np.abs(Az), initial=0.0)))
    return val, val / scale


def stacked(data: QPData, rows: LimitRows) -> tuple[sp.csc_matrix, FloatArray, FloatArray]:
    """``[A; A_L]``, ``l = [b; lo]``, ``u = [b; hi]`` of the bounded QP on ``data``'s current values
    (the module docstring's stacking, in that row order)."""
    A = sp.vstack([data.A, rows.A], format="csc")
    return A, np.r_[data.b, rows.lo], np.r_[data.b, rows.hi]


def bounded_kkt(data: QPData, rows: LimitRows, z: FloatArray, y: FloatArray) -> tuple[KKTResiduals, float]:
    """The KKT residuals of ``(z, y)`` on the stacked bounded QP and the relative
    complementarity of its limit rows (module docstring), recomputed from the matrices.

    Parameters
    ----------
    data : QPData
        The equality rows (with the candidate's selectors set).
    rows : LimitRows
        The limit rows on the same grid.
    z, y : ndarray
        Primal vector and dual vector in the stacked row order (``y > 0`` at an upper bound).

    Returns
    -------
    tuple of (KKTResiduals, float)
    """
    A, l, u = stacked(data, rows)
    k = kkt_residuals(data.P, data.q, A, l, u, z, y)
    _, rel = complementarity(rows.A @ z, np.asarray(y, dtype=float)[data.n_rows:], rows.lo, rows.hi)
    return k, rel


def check_complementarity(checks: dict[str, Any], status: str, failed: str | None, rel: float,
                          tolerance: float) -> tuple[str, str | None]:
    """Add ``kkt_complementarity_rel`` to ``checks``; an ``optimal`` status becomes ``inaccurate``
    when it fails.  Returns the status and the failed check."""
    ok = bool(np.isfinite(rel) and rel <= tolerance)
    checks["kkt_complementarity_rel"] = {"value": float(rel), "tol": tolerance, "ok": ok}
    if not ok and failed is None:
        failed = "kkt_complementarity_rel"
        if status == st.OPTIMAL:
            status = st.INACCURATE
    return status, failed


def certified_infeasible(A: sp.spmatrix, l: FloatArray, u: FloatArray, dy: FloatArray | None
                         ) -> tuple[bool, dict[str, dict[str, Any]]]:
    """Whether ``dy`` (either sign) is a verified Farkas certificate of ``l <= Az <= u``
    (:data:`FARKAS_STATIONARITY`, :data:`FARKAS_SUPPORT`), with the two checks."""
    inf = float("inf")
    pairs = [farkas_residuals(A, l, u, sign * np.asarray(dy, dtype=float)) for sign in (1.0, -1.0)] \
        if dy is not None else [(inf, inf)]
    stat, support = min(pairs, key=lambda p: (not (p[0] <= FARKAS_STATIONARITY and p[1] < -FARKAS_SUPPORT), p[1]))
    ok = stat <= FARKAS_STATIONARITY and support < -FARKAS_SUPPORT
    return ok, {"farkas_stationarity": {"value": stat, "tol": FARKAS_STATIONARITY, "ok": stat <= FARKAS_STATIONARITY},
                "farkas_support": {"value": support, "tol": -FARKAS_SUPPORT, "ok": support < -FARKAS_SUPPORT}}


def boundary_reason(problem: Problem, limits: PhysicalLimits) -> str | None:
    """Why no plan can satisfy the node bounds of ``vx`` and ``y`` at ``t = 0`` or ``t_f``
    (the boundary state is fixed), or None."""
    ego = problem.ego
    checks = (("vx", "v_x(0)", ego.vx0), ("vx", "v_x(tf)", ego.vxf), ("y", "s_y(0)", ego.y0), ("y", "s_y(tf)", ego.yf))
    for name, label, value in checks:
        rng = getattr(limits, name)
        if rng is not None and not rng[0] <= value <= rng[1]:
            return (f"the boundary condition {label} = {value:g} lies outside limits.{name} = "
                    f"[{rng[0]:g}, {rng[1]:g}]")
    return None


class BoundedQP(DiscretisedQP):
    """:class:`~iamp.planners.qp.core.DiscretisedQP` with the limit rows (module docstring).

    Parameters
    ----------
    problem : Problem
        With ``problem.limits`` set.
    steps, hold, solver, settings
        As for :class:`~iamp.planners.qp.core.DiscretisedQP`.
    between : {"nodes", "certified"}
        Speed and ``y`` bounds at the nodes only (SPEC §14) or certified between them too
        (:mod:`iamp.planners.qp.limits`).
    """

    def __init__(self, problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 settings: Mapping[str, Any] | None = None, between: str = "nodes") -> None:
        if problem.limits is None:
            raise ValueError("BoundedQP needs problem.limits")
        cls = get_backend(solver)
        if not cls.supports_inequalities:
            raise UnsupportedProblemError(
                f"QP backend {solver!r} solves equality-constrained QPs only, but the scenario's [limits] are "
                f"inequalities; use {', '.join(inequality_backends())}")
        self.problem = problem
        self.data = QPData(problem, steps, hold)
        self.N, self.hold, self.solver = self.data.N, hold, solver
        d = self.data
        self.rows: LimitRows = limit_rows(d, d.t_nodes, hold, problem.limits, between=between)
        self._stack()
        if solver == "osqp":  # certificates accurate enough to verify (module docstring)
            settings = {**OSQP_SETTINGS, **dict(settings or {})}
        t0 = time.perf_counter()
        l, u = self._bounds()
        self.backend: QPBackend = cls(d.P, d.q, self.A, l, u, settings)
        self.setup_time_s = time.perf_counter() - t0
        self.tolerance = tol(cls.tolerance_key)
        self.n_solves = 0
        self._grid_dirty = False
        self._last: tuple[FloatArray, FloatArray] | None = None

    # --- the stacked matrix -----------------------------------------------------------------
    def _stack(self) -> None:
        """The pattern of ``[A; A_L]`` and where each entry of ``A.data`` and ``A_L.data`` sits."""
        d, rows = self.data, self.rows
        ids_a = sp.csc_matrix((np.arange(1, d.A.nnz + 1, dtype=float), d.A.indices, d.A.indptr), shape=d.A.shape)
        ids_l = sp.csc_matrix((-np.arange(1, rows.A.nnz + 1, dtype=float), rows.A.indices, rows.A.indptr),
                              shape=rows.A.shape)
        st_ = sp.vstack([ids_a, ids_l], format="csc")
        st_.sort_indices()
        src = st_.data.astype(np.int64)
        self._pos_a = np.empty(d.A.nnz, dtype=np.int64)
        self._pos_l = np.empty(rows.A.nnz, dtype=np.int64)
        where = np.arange(src.size, dtype=np.int64)
        self._pos_a[src[src > 0] - 1] = where[src > 0]
        self._pos_l[-src[src < 0] - 1] = where[src < 0]
        self.A = sp.csc_matrix((np.zeros(src.size), st_.indices.copy(), st_.indptr.copy()), shape=st_.shape)
        self._refresh()

    def _refresh(self) -> None:
        self.A.data[self._pos_a] = self.data.A.data
        self.A.data[self._pos_l] = self.rows.A.data

    def _bounds(self) -> tuple[FloatArray, FloatArray]:
        b = self.data.b
        return np.r_[b, self.rows.lo], np.r_[b, self.rows.hi]

    # --- candidates ------------------------------------------------------------------------
    def set_grid(self, t_nodes: Sequence[float] | FloatArray) -> None:
        t = np.asarray(t_nodes, dtype=float)
        if np.array_equal(t, self.data.t_nodes):
            return
        super().set_grid(t)
        self.rows.set_grid(t)

    def solve_nodes(self, nodes: Sequence[int]) -> CandidateResult:
        """Solve with the contacts at the given nodes of the current grid, and verify."""
        t0 = time.perf_counter()
        d, b = self.data, self.backend
        pos, vals = d.selector_update(nodes)
        tb = time.perf_counter()
        l, u = self._bounds()
        if self._grid_dirty:
            self._refresh()
            b.update(Px=d.P.data, Ax=self.A.data, l=l, u=u)
            self._grid_dirty = False
        else:
            p = self._pos_a[pos]
            self.A.data[p] = vals
            b.update(Ax=vals, Ax_idx=p, l=l, u=u)
        if b.warm_starts:  # from the last verified solution, else from zero: never from a diverged
            # iterate (after an infeasible candidate OSQP's own iterates are a divergent ray)
            b.warm_start(*(self._last if self._last is not None else (np.zeros(d.n), np.zeros(l.size))))
        sol = b.solve()
        backend_s = time.perf_counter() - tb
        self.n_solves += 1
        kkt = kkt_residuals(d.P, d.q, self.A, l, u, sol.z, sol.y, lower=self._lower()) if sol.finite else None
        r = self._bounded_result(tuple(int(k) for k in nodes), sol, kkt, backend_s, l, u)
        r.wall_time_s = time.perf_counter() - t0
        return r

    def _lower(self) -> sp.spmatrix:
        """``triu(P, 1)ᵀ`` of the current grid's ``P`` (built again only when ``P``'s values changed)."""
        P = sp.csc_matrix(self.data.P)
        kept = getattr(self, "_lower_of", None)
        if kept is None or kept[0].shape != P.data.shape or not np.array_equal(kept[0], P.data) \
                or not np.array_equal(kept[1], P.indices) or not np.array_equal(kept[2], P.indptr):
            kept = self._lower_of = (P.data.copy(), P.indices.copy(), P.indptr.copy(), sp.triu(P, 1).T)
        return kept[3]

    def solve_many(self, candidates: Sequence[Sequence[int]]) -> list[CandidateResult]:
        return [self.solve_nodes(c) for c in candidates]

    def _bounded_result(self, nd: tuple[int, ...], sol: QPSolution, kkt: KKTResiduals | None, backend_s: float,
                        l: FloatArray, u: FloatArray) -> CandidateResult:
        d = self.data
        times = d.t_nodes[np.asarray(nd, dtype=np.int64)].copy()
        status, checks, failed = verify(kkt, self.tolerance, sol.status)
        if kkt is not None:
            _, rel = complementarity(self.rows.A @ sol.z, sol.y[d.n_rows:], self.rows.lo, self.rows.hi)
            status, failed = check_complementarity(checks, status, failed, rel, self.tolerance)
        r = CandidateResult.of_solve(nd, status, times, sol, backend_s, kkt, checks, failed)
        if status == st.OPTIMAL:
            self._last = (sol.z, sol.y)
            X, U = d.unpack(sol.z)
            r.trajectory = HoldTrajectory(d.t_nodes.copy(), X, U, self.hold)
            r.cost = r.trajectory.cost()
            r.multipliers = d.collision_multipliers(sol.y[:d.n_rows])
        elif sol.status == st.INFEASIBLE and sol.certificate is not None:
            stat, support = farkas_residuals(self.A, l, u, sol.certificate)
            certified = stat <= FARKAS_STATIONARITY and support < -FARKAS_SUPPORT
            r.checks["farkas_stationarity"] = {"value": stat, "tol": FARKAS_STATIONARITY,
                                               "ok": stat <= FARKAS_STATIONARITY}
            r.checks["farkas_support"] = {"value": support, "tol": -FARKAS_SUPPORT, "ok": support < -FARKAS_SUPPORT}
            r.infeasible_certified = certified
        return r

    def limit_multipliers(self, y: FloatArray) -> FloatArray:
        """The multipliers of the limit rows (``> 0`` at ``hi``, ``< 0`` at ``lo``)."""
        return np.asarray(y, dtype=float)[self.data.n_rows:].copy()


def free_problem_feasible(problem: Problem, steps: int, hold: str, solver: str) -> bool | None:
    """Are the bounds reachable at all from the boundary conditions, without any corner?

    Solves the bounded QP with the corner rows relaxed (``l = -inf, u = +inf``); True when
    it solves, False when infeasibility is certified (Farkas), None when undecided.
    """
    limits = problem.limits
    assert limits is not None
    d = QPData(problem, steps, hold)
    rows = limit_rows(d, d.t_nodes, hold, limits)
    A = sp.vstack([d.A[:d.row_collision], rows.A], format="csc")
    bb = d.b[:d.row_collision]
    l, u = np.r_[bb, rows.lo], np.r_[bb, rows.hi]
    cls = get_backend(solver)
    sol = cls(d.P, d.q, A, l, u).solve()
    if sol.status == st.OPTIMAL:
        return True
    if sol.status == st.INFEASIBLE and sol.certificate is not None:
        stat, support = farkas_residuals(A, l, u, sol.certificate)
        if stat <= FARKAS_STATIONARITY and support < -FARKAS_SUPPORT:
            return False
    return None


def box_screen(problem: Problem) -> Callable[[FloatArray], str | None] | None:
    r"""A per-candidate certificate of infeasibility that costs no QP solve, or None without a box.

    The returned ``screen(times)`` solves the bounded PMP's fixed-time problem with only the
    input box ``ax``/``ay`` at the candidate's contact times
    (:func:`iamp.planners.pmp.bounded.solve_bounded_fixed`, per axis a semi-smooth Newton on
    the dual) and returns the reason when an axis is infeasible with a positive Farkas margin,
    else None.  Sound for the QP: every plan of the QP at those (node) times is a plan within
    the box (module docstring of :func:`infeasible_before_sweep`), so the candidate has none.
    """
    limits = problem.limits
    if limits is None or (limits.ax is None and limits.ay is None):
        return None
    from iamp.planners.pmp.bounded import solve_bounded_fixed
    from iamp.planners.pmp.saturated import AxisInfeasible, AxisNoConvergence

    def screen(times: FloatArray) -> str | None:
        try:
            with np.errstate(all="ignore"):
                solve_bounded_fixed(problem, times)
        except AxisInfeasible as exc:
            if exc.margin > 0:  # the Farkas margin (scaled units) of the axis that is infeasible
                return f"input box infeasible at these contact times (bounded PMP, Farkas margin {exc.margin:.3g})"
        except (AxisNoConvergence, FloatingPointError, ZeroDivisionError, np.linalg.LinAlgError):
            pass
        return None

    return screen


def single_vehicle_screen(problem: Problem, steps: int, hold: str, solver: str,
                          settings: Mapping[str, Any] | None = None
                          ) -> tuple[dict[tuple[int, int], bool], int]:
    r"""Which contact nodes each vehicle alone cannot take within the limits (``m >= 2``).

    For each vehicle ``i`` and interior node ``k`` the bounded QP with only that vehicle's corner
    at ``k`` is solved (``m (N - 1)`` solves).  It is a relaxation of every candidate with
    vehicle ``i`` at node ``k`` (the other corners' rows dropped), so a verified Farkas
    certificate for it, padded with zeros, certifies all of them.

    Returns ``({(i, k): True}`` for the certified pairs, the number of QP solves``)``.
    """
    from iamp.core.problem import Problem as _Problem

    out: dict[tuple[int, int], bool] = {}
    solves = 0
    for i, v in enumerate(problem.vehicles):
        one = _Problem(ego=problem.ego, vehicles=(v,), name=problem.name, limits=problem.limits)
        qp = BoundedQP(one, steps, hold, solver, settings)
        for k in range(1, qp.N):
            r = qp.solve_nodes([k])
            solves += 1
            if r.infeasible_certified:
                out[(i, k)] = True
    return out, solves


#: Axis solves the bounded PMP's certificate over every contact time may spend before the sweep
#: (:func:`infeasible_before_sweep`); a work budget, never a time.
PMP_CERTIFICATE_SOLVES = 4000


def infeasible_before_sweep(problem: Problem, steps: int, hold: str, solver: str,
                            max_pmp_solves: int = PMP_CERTIFICATE_SOLVES) -> tuple[str, dict[str, Any]] | None:
    r"""Certify the whole sweep infeasible before solving any candidate, or return None.

    Three certificates, cheapest first, each valid for *every* grid candidate:

    1. a boundary value outside the ``vx`` or ``y`` bound (no solve);
    2. the bounded QP without the corner rows is infeasible (one QP solve with a verified
       Farkas certificate, :func:`free_problem_feasible`): adding rows keeps it infeasible;
    3. the input box ``ax``/``ay`` admits no plan for *any* contact times in :math:`(0, t_f)^m`
       (the bounded PMP's certificate, :func:`iamp.planners.pmp.bounded.certify_infeasible`:
       boxes of contact times, each with a Farkas certificate and a Lipschitz margin, within
       ``max_pmp_solves`` axis solves).  Every QP candidate's plan would be such a plan: its
       input lies in the box everywhere (FOH: linear between nodal values in the box; ZOH:
       constant), and its contact times are grid nodes in :math:`(0, t_f)`.

    Returns ``(reason, certificate)`` with the work spent (``qp_solves``, ``pmp_boxes``), or
    None when none of them applies (the sweep decides).
    """
    limits = problem.limits
    assert limits is not None
    why = boundary_reason(problem, limits)
    if why is not None:
        return why, {"method": "boundary value outside a bound", "qp_solves": 0, "pmp_boxes": 0}
    given = ", ".join(limits.given())
    if free_problem_feasible(problem, steps, hold, solver) is False:
        return (f"the boundary conditions cannot be joined within the limits ({given}) even without the corner "
                f"constraints (Farkas certificate, N = {steps}, {hold.upper()})"), \
            {"method": "the bounded QP without the corners (Farkas)", "qp_solves": 1, "pmp_boxes": 0}
    if limits.ax is None and limits.ay is None:
        return None
    from iamp.planners.pmp.bounded import boundary_feasible, certify_infeasible

    box = boundary_feasible(problem)
    if box is not None:
        return box, {"method": "the input box cannot meet the boundary conditions (Farkas, bounded PMP)",
                     "qp_solves": 1, "pmp_boxes": 0}
    certified, _, boxes = certify_infeasible(problem, max_solves=max_pmp_solves)
    if not certified:
        return None
    m = problem.m
    what = "contact time in (0, t_f)" if m == 1 else f"choice of the {m} contact times in (0, t_f)^{m}"
    n = math.perm(steps - 1, m)
    return (f"no {what} admits a plan through the corner(s) within the input box ax, ay, so {n} of {n} "
            f"candidate contact nodes are certified infeasible (Farkas certificates of the bounded PMP over {boxes} "
            f"{'intervals' if m == 1 else 'boxes'} of contact times, each with a Lipschitz margin) without a "
            "QP solve"), \
        {"method": "the bounded PMP's certificate over every contact time", "qp_solves": 1, "pmp_boxes": int(boxes)}


def infeasibility_reason(problem: Problem, steps: int, hold: str, solver: str, n_candidates: int,
                         n_certified: int) -> tuple[str, bool]:
    """Why the bounded sweep found no plan: a boundary value outside a bound, the bounds
    unreachable even without the corners, or the corners unreachable within the bounds.

    Returns the reason and whether it certifies every candidate at once: a boundary value
    outside a bound, or a Farkas certificate of the problem without the corners (adding the
    corner rows keeps it infeasible), makes the whole sweep infeasible whatever any single
    candidate's solver said.
    """
    limits = problem.limits
    assert limits is not None
    why = boundary_reason(problem, limits)
    if why is not None:
        return why, True
    free = free_problem_feasible(problem, steps, hold, solver)
    given = ", ".join(limits.given())
    if free is False:
        return (f"the boundary conditions cannot be joined within the limits ({given}) even without the corner "
                f"constraints (Farkas certificate, N = {steps}, {hold.upper()})"), True
    cert = f"{n_certified} of {n_candidates} candidate contact nodes certified infeasible (Farkas)"
    if free is True:
        return (f"no contact node admits a plan through the corner(s) within the limits ({given}); the boundary "
                f"conditions alone are reachable; {cert}"), False
    return f"no contact node admits a plan within the limits ({given}); {cert}", False


__all__ = [
    "FARKAS_STATIONARITY",
    "FARKAS_SUPPORT",
    "PMP_CERTIFICATE_SOLVES",
    "BoundedQP",
    "IntArray",
    "boundary_reason",
    "bounded_kkt",
    "box_screen",
    "certified_infeasible",
    "check_complementarity",
    "complementarity",
    "free_problem_feasible",
    "inequality_backends",
    "infeasibility_reason",
    "infeasible_before_sweep",
    "single_vehicle_screen",
    "stacked",
]
