r"""The avoidance QP safe in continuous time (SPEC §14, amending §10): ``--safety continuous``.

For each vehicle ``i`` with half-plane order (first, second) and crossing time
:math:`\tau_i`, the ego must be in the first half-plane for :math:`t \le \tau_i` and in the
second for :math:`t \ge \tau_i` — at :math:`\tau_i` itself in both.  On the uniform grid of
SPEC §3 (same holds, cost, boundary rows), every piece's position is a cubic whose Bernstein
coefficients are linear in the node variables (:mod:`iamp.planners.avoid.bernstein`), so the
constraint is imposed by rows

* first half-plane on every Bernstein coefficient of the pieces (and sub-piece) of
  :math:`[0, \tau_i]`, second on those of :math:`[\tau_i, t_f]` — the piece containing
  :math:`\tau_i` split at :math:`\tau_i` (:meth:`ContinuousAvoidQP.spec_rows`).

A feasible point of these rows is safe for every ``t`` (the polynomial lies in the convex hull
of its coefficients), so the crossing cannot cut the corner between nodes.  The rows are
sufficient, not necessary: the QP's optimum is an upper bound of the continuous-time safe
optimum on this grid's piecewise-polynomial trajectories, and it converges to it as ``N``
grows (the certificate is exact as the pieces shrink).

Crossing-time search: branch and bound over boxes
-------------------------------------------------
For fixed :math:`\tau` the problem is a convex QP with optimal cost :math:`J(\tau)`.  The
search keeps boxes :math:`\tau_i \in [a_i, b_i]` (and an order per vehicle) in a heap by their
lower bound; it pops the lowest, evaluates :math:`J` at one crossing in it (an upper bound
``U``), raises the box's bound, and splits it at the midpoint of one vehicle's interval unless
its bound is within the gap of ``U``.  Two lower bounds:

* the *relaxation* (a box spanning several grid pieces for the split vehicle, or whose
  candidate is infeasible): the first half-plane on :math:`[0, a_i]` and the second on
  :math:`[b_i, t_f]` only; every :math:`\tau` in the box satisfies those rows, so its optimum
  is :math:`R(\text{box}) \le \min_{\text{box}} J`, and it suggests the candidate crossing
  (a max-min of margins);
* the *dual polynomial* of every solved candidate (:mod:`iamp.planners.avoid.dual`): weak
  duality with the candidate's multipliers, as a polynomial in the crossing times of the
  vehicles whose interval lies in one piece, bounded by its Bernstein coefficients; it equals
  :math:`J` at the candidate and falls off quadratically (the relaxation: linearly; with one
  vehicle, whose multipliers follow their tangent, as the fourth power), and it
  holds on every sub-box, so a box inside one piece needs no relaxation solve (its candidate is
  where its polynomials' largest value is lowest).  Every candidate's *piece polynomial* (over
  the grid pieces of its crossing times) is kept in one store for the whole search
  (:class:`~iamp.planners.avoid.dual.DualStore`) and bounds every box inside those pieces —
  for a vehicle without multipliers, any box — not only the candidate's own descendants; where
  those polynomials keep a box above ``U - gap`` at every probe, it is split without a QP
  (their Bernstein bound tightens as the box shrinks).

A box that spans several grid pieces for the split vehicle is cut at the grid node nearest its
midpoint (within one piece: at the midpoint), so that boxes near the optimum soon lie within one
piece, where the polynomials bound them without relaxation solves.  With one vehicle such a box
is cut instead at both ends of its solved candidate's piece (:meth:`ContinuousAvoidPlanner._cuts`):
that piece is bounded by the candidate's polynomial, the boxes beside it by relaxations that the
incumbent cuts off early.

The search stops when every remaining box has bound :math:`\ge U - \text{gap}` (``closed``: the
best :math:`\tau` is the global minimiser over all crossing times, to the gap :data:`GAP_REL`)
or after ``max_solves`` QPs (``local``, with the remaining bound reported); then a secant
search on :math:`\partial J/\partial \tau_i` (each candidate's slope read off its dual
polynomial; with one vehicle the first step a Newton step on the curvature of its second-order
polynomial) polishes the best crossing within one grid step.  No work limit refuses a problem:
the budget only decides between ``optimal`` and ``local``.

Verification
------------
``optimal`` only when the KKT conditions of the final QP, recomputed from the data
(:func:`~iamp.planners.avoid.check.kkt_conditions`), pass ``cmp_kkt_rel_<solver>``, the search
closed, and the plan's own SPEC §9 report (exact roots) is intrusion-free.  Physical limits
(``problem.limits``, :mod:`iamp.planners.qp.limits`) are imposed as two one-sided rows each,
inside the same KKT check, and hold in continuous time (``limits_between="certified"``, the
default): the input bounds (``a_x``, ``a_y``, the friction polygon, jerk) are exact at the nodes
because the input is piecewise linear (FOH) or constant (ZOH); the speed ``v_x`` (quadratic per
FOH piece) and ``s_y`` (cubic) are bounded by their inner Bernstein coefficients per piece, rows
linear in ``z`` built by :func:`~iamp.planners.qp.limits.limit_rows` (the one builder, shared by
the node solver, the dual bound and every backend; independent of the crossing times).  They are
sufficient, not necessary: ``optimal`` is the optimum of this tightened QP, an upper bound of the
optimum with the limits imposed exactly between the nodes (``limits_between="nodes"``, for study
and tests: the bounds at the nodes only).
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from iamp.core import status as st
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.avoid import search_kernel
from iamp.planners.avoid.bernstein import piece_matrix, poly_bernstein
from iamp.planners.avoid.check import AXIS_NAMES, FloatArray, KKTCheck, crossing_orders, leave_time
from iamp.planners.avoid.data import AvoidData, HalfPlane
from iamp.planners.avoid.diagnostics import AvoidDiagnostics
from iamp.planners.avoid.dual import (
    DualBounds,
    DualPolynomial,
    DualStore,
    Packing,
    fit_polynomial,
    fit_polynomials,
    grid_minimum,
    max_lower_bound,
    piece_of,
)
from iamp.planners.avoid.result import ACTIVE_SLACK_M, failed_plan, residual_and_safety_lines
from iamp.planners.avoid.schur import CHECK_TOL, CUTOFF, CsrArrays, SchurActiveSet, _run, csr_arrays
from iamp.planners.avoid.solve import GENERATION_TOL, RowGeneration, RowsSolution
from iamp.planners.qp.backends import BACKENDS
from iamp.planners.qp.backends.base import compressed, csr_to_csc, matvec
from iamp.planners.qp.hold import HoldTrajectory
from iamp.planners.qp.options import check_choice

#: At most this many sub-pieces' values per grid (:attr:`_GridLayout.split_vals`).
SPLIT_LIMIT = 4096

__all__ = ["GAP_REL", "ROW_TOL_M", "ContinuousAvoidPlanner", "ContinuousAvoidQP", "GridShare", "Spec"]

#: The branch and bound closes when no box's bound is below the best cost by more than this
#: (relative to ``max(1, J)``).
GAP_REL = 1e-4
#: Added to every Bernstein row's bound [m]: a start or end on a half-plane's boundary (to
#: round-off) stays feasible; far below the 1 mm intrusion tolerance of SPEC §9.
ROW_TOL_M = 1e-9

#: The solvers of the search's QPs: the exact dual active set on the grid's factored KKT matrix
#: (:class:`~iamp.planners.avoid.schur.SchurActiveSet`; the backend then solves the final QP,
#: whose KKT conditions the plan checks), or the backend for every QP (for study and tests).
NODE_SOLVERS = ("schur", "backend")

#: Per vehicle ``(first, second, a, b)``: first half-plane on ``[0, a]``, second on ``[b, t_f]``.
Spec = tuple[tuple[int, int, float, float], ...]


class GridShare:
    """What the plans of one planner keep for the next (:class:`ContinuousAvoidQP`'s ``shared``):
    per grid, the factored node solver (:class:`~iamp.planners.avoid.schur.SchurActiveSet`, with
    the columns of ``K⁻¹`` solved so far, and ``triu(P, 1)ᵀ`` of the final KKT checks), the QP's
    ``A`` and ``P`` (:class:`~iamp.planners.avoid.data.AvoidData`; they depend on the grid, the
    hold and the half-planes' signs only) and the limit rows with their stack
    ``[A_lim; -A_lim]``, which depend on the grid, the hold and the limits only; the rows' layout
    (:class:`_GridLayout`: grid, hold, degree, half-plane signs) and each half-plane's row bounds
    (full pieces, and the polynomials of split pieces: grid, degree and the half-plane).  The closed
    loop plans the same few horizons every period; its planner factors each grid once.  At most
    :attr:`SIZE` grids per kind, the least recently used dropped.  The node solver's reuse is
    checked against the plan's own ``P`` and ``A_eq`` (bit for bit); the other values are kept
    under everything they are built from (the grid's bytes, the hold, the signs or the limits),
    so a plan is the same with or without it."""

    SIZE = 8

    def __init__(self) -> None:
        self._items: dict[tuple[Any, ...], Any] = {}

    def get(self, key: tuple[Any, ...]) -> Any:
        """The value kept under ``key`` (now the most recent), or None."""
        out = self._items.pop(key, None)
        if out is not None:
            self._items[key] = out
        return out

    def forget(self, kind: str) -> int:
        """Drop every value kept under a key of ``kind`` (its first element, e.g. ``"rhs"``: the
        half-planes' rows, which depend on the vehicles' motion); the number dropped."""
        gone = [k for k in self._items if k[0] == kind]
        for k in gone:
            del self._items[k]
        return len(gone)

    def values(self, kind: str) -> list[Any]:
        """The values kept under keys of ``kind`` (oldest first)."""
        return [v for k, v in self._items.items() if k[0] == kind]

    def put(self, key: tuple[Any, ...], value: Any) -> None:
        """Keep ``value`` under ``key``; beyond :attr:`SIZE` values per kind, drop the oldest."""
        self._items.pop(key, None)
        self._items[key] = value
        same = [k for k in self._items if k[0] == key[0]]
        for k in same[:max(0, len(same) - self.SIZE)]:
            del self._items[k]


class _GridLayout:
    """What :class:`ContinuousAvoidQP` builds from its grid, hold, Bernstein degree and half-plane
    signs only (kept in :class:`GridShare` under all of them, so the plans of one grid build it
    once): the equality rows ``A_eq`` (CSR), ``P``'s diagonal, the full piece's Bernstein matrix
    ``M_full``, the node columns of every Bernstein row of the layout, per vehicle and half-plane
    the row values ``σ M_full`` of every piece, and :meth:`ContinuousAvoidQP.split_polynomials`
    (filled on first use), and the σ-free values of the sub-pieces' rows (:attr:`split_vals`, filled
    on use).  Read-only once built, but for those."""

    def __init__(self, d: AvoidData, h: float, degree: int) -> None:
        self.A_eq = sp.csr_matrix(d.A[: d.n_eq])
        self.P_diag = d.P.diagonal()
        self.M_full = piece_matrix(h, 0.0, 1.0, degree)
        n, N = degree + 1, d.N
        k = np.arange(N)
        blocks = []
        for _ in d.planes:
            for a in (0, 1):
                cs = np.stack([d.idx_s(a, k), d.idx_v(a, k), d.idx_s(a, k + 1), d.idx_v(a, k + 1)], axis=1)
                blocks.append(np.repeat(cs, n, axis=0))  # (N n, 4): piece k's n rows
        self.bern_cols = (np.concatenate(blocks) if blocks else np.zeros((0, 4))).astype(np.int32)
        #: the same, raveled (four per row: a segment's columns are one slice of it)
        self.bern_cols_flat = self.bern_cols.ravel()
        self.full_vals = {(i, a): np.tile(hp.sigma * self.M_full.ravel(), N)
                          for i, pair in enumerate(d.planes) for a, hp in enumerate(pair)}
        self.split_polys: tuple[FloatArray, FloatArray] | None = None
        #: the samples ``λ_j = j / d`` of :meth:`ContinuousAvoidQP.rhs_polynomial`
        self.lam = np.linspace(0.0, 1.0, degree + 1)
        self.lam.flags.writeable = False
        #: the exponents ``0..d`` of the powers ``λ^j`` of :meth:`ContinuousAvoidQP._split`
        self.exponents = np.arange(degree + 1)
        #: per sub-piece ``[0, λ]`` (``pre``) or ``[λ, 1]``: the powers ``λ^j`` and the σ-free row
        #: values ``Σ_j λ^j M_j`` of :meth:`ContinuousAvoidQP._split` (filled on use; functions of
        #: the key and the grid alone, so every plan of the grid reads them: a box's ends recur in
        #: the plans of a closed loop; beyond :data:`SPLIT_LIMIT` entries emptied first)
        self.split_vals: dict[tuple[bool, float], tuple[FloatArray, FloatArray]] = {}


class _PlaneRows:
    """One half-plane's Bernstein rows on one grid (:class:`ContinuousAvoidQP`; kept in
    :class:`GridShare` under the grid, the degree and the half-plane, so the plans of one planner
    compute each once): the bounds on every full piece, the polynomials of split pieces
    (:meth:`~ContinuousAvoidQP.rhs_polynomial`, per ``(k, pre)``; ``H_y``'s one polynomial also
    under ``(-1, True)``), the values and bounds of
    sub-pieces (:meth:`~ContinuousAvoidQP._split`, per ``(k, λ0, λ1)``) and of segments
    (:meth:`~ContinuousAvoidQP._segment_blocks`, per ``(vehicle, t_a, t_b)``: the layout numbers depend on
    the vehicle's index).  Each value is a function of its key alone (read-only once kept); beyond
    :attr:`LIMIT` entries a kind is emptied and computed again (a plan of the bench overtakes adds
    ~16-23 segments per half-plane, each a few small arrays and views of the full pieces' rows)."""

    LIMIT = 512

    def __init__(self, full_rhs: FloatArray) -> None:
        self.full_rhs = full_rhs
        self.polys: dict[tuple[int, bool], FloatArray] = {}
        self.splits: dict[tuple[int, float, float], tuple[FloatArray, FloatArray]] = {}
        self.segments: dict[tuple[int, float, float], _Segment] = {}

    def keep(self, kind: dict[Any, Any], key: Any, value: Any) -> None:
        """``kind[key] = value``, after emptying ``kind`` when it holds :attr:`LIMIT` entries."""
        if len(kind) >= self.LIMIT:
            kind.clear()
        kind[key] = value


class _Segment:
    """One half-plane imposed on one interval (:meth:`ContinuousAvoidQP._segment_blocks`): the
    values (four per row) and bounds of its rows as blocks (a sub-piece, or a run of full pieces: a
    slice of the half-plane's arrays), in layout order, the rows' layout numbers (consecutive) and
    their node columns (a slice of the layout's, four per row).  Read-only once built."""

    __slots__ = ("cols", "ids", "rhs", "vals")

    def __init__(self, vals: list[FloatArray], rhs: list[FloatArray], ids: NDArray[np.int64],
                 cols: NDArray[np.int32]) -> None:
        self.vals, self.rhs, self.ids, self.cols = vals, rhs, ids, cols


def _stacked(top: sp.csr_matrix, below: sp.csr_matrix) -> sp.csc_matrix:
    """``[top; below]`` (both CSR) as CSC, every stored entry kept: ``sp.vstack`` of the two,
    converted, entry for entry, from their CSR arrays without its general checks — the arrays of
    ``compressed(sp.csr_matrix, …).tocsc()`` (:func:`~iamp.planners.qp.backends.base.csr_to_csc`,
    scipy's own conversion without its wrapper) and, as ``tocsc`` marks it, sorted indices."""
    indptr = np.concatenate((top.indptr, top.indptr[-1] + below.indptr[1:]))
    indices, data = np.concatenate((top.indices, below.indices)), np.concatenate((top.data, below.data))
    shape = (top.shape[0] + below.shape[0], top.shape[1])
    if indptr.dtype != np.int32 or indices.dtype != np.int32 or data.dtype != np.float64:
        return compressed(sp.csr_matrix, data, indices, indptr, shape).tocsc()  # scipy's own index types
    ptr_c, ind_c, data_c = csr_to_csc(indptr, indices, data, shape)
    M = compressed(sp.csc_matrix, data_c, ind_c, ptr_c, shape)
    M.has_sorted_indices = True
    return M


@dataclass
class Solved:
    """One solved QP of the search: its solution on the rows of its ``spec``.

    ``y`` holds the multipliers of the rows of :attr:`A` (equality rows, then the spec's imposed
    rows in the order of :meth:`ContinuousAvoidQP.spec_rows`: every vehicle's Bernstein blocks, then
    the limit rows); :attr:`A` and :attr:`u` are built when asked for."""

    spec: Spec
    status: str
    cost: float
    z: FloatArray
    y: FloatArray
    iterations: int
    qp: ContinuousAvoidQP = field(repr=False)
    solves: int = 1
    #: the spec's imposed rows, their bounds and layout numbers (:meth:`ContinuousAvoidQP.spec_rows`)
    rows: tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]] | None = field(default=None, repr=False)
    _traj: HoldTrajectory | None = field(default=None, repr=False)
    _active: NDArray[np.int64] | None = field(default=None, repr=False)

    def trajectory(self) -> HoldTrajectory:
        """The trajectory of :attr:`z` (built once)."""
        if self._traj is None:
            self._traj = self.qp.trajectory(self.z)
        return self._traj

    def spec_rows(self) -> tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]]:
        """:meth:`ContinuousAvoidQP.spec_rows` of :attr:`spec` (kept from the solve)."""
        return self.rows if self.rows is not None else self.qp.spec_rows(self.spec)

    def active(self) -> NDArray[np.int64]:
        """The layout numbers of the rows with a positive multiplier (the warm start of a nearby
        QP's node solve; computed once: the incumbent warm-starts many solves; read-only)."""
        if self._active is None:
            _, _, ids = self.spec_rows()
            self._active = np.asarray(ids[self.y[self.qp.data.n_eq:] > 0], dtype=np.int64)
        return self._active

    @property
    def A(self) -> sp.csc_matrix:
        """``[A_eq; imposed rows]`` of :attr:`spec` (CSC)."""
        A_in, _, _ = self.qp.spec_rows(self.spec)
        return _stacked(self.qp.A_eq, A_in)

    @property
    def u(self) -> FloatArray:
        """``[b_eq; bounds of the imposed rows]``."""
        _, u_in, _ = self.qp.spec_rows(self.spec)
        return np.asarray(np.concatenate((self.qp.data.b_eq, u_in)), dtype=float)


def _mirrored(indptr: NDArray[np.int32], indices: NDArray[np.int32], data: FloatArray) -> int:
    """``h`` when the ``2h`` CSR rows ``(indptr, indices, data)`` are ``[B; -B]`` entry for entry
    (the second half's rows the first half's columns in the same order, every value negated bit for
    bit), else 0."""
    m = indptr.size - 1
    h = m // 2
    if m % 2 or not h:
        return 0
    mid = int(indptr[h])
    same = (np.array_equal(indptr[h:] - mid, indptr[:h + 1]) and np.array_equal(indices[mid:], indices[:mid])
            and (-data[:mid]).tobytes() == data[mid:].tobytes())
    return h if same else 0


class ContinuousAvoidQP:
    """The data of the continuous-time avoidance QP on the uniform grid of ``steps`` pieces.

    Its inequality rows have one fixed layout (:meth:`spec_rows`): for every vehicle ``i``, half-plane
    ``a`` and piece ``k`` a block of ``d + 1`` Bernstein rows on the piece's four node columns
    (row ``((2i + a) N + k)(d + 1) + j``), then the limit rows ``[A_lim; -A_lim] z <= [hi; -lo]``.
    A crossing-time spec sets the values and bounds of the blocks it imposes (a full piece, or
    the sub-piece of a piece split at a box's end) and leaves the others out; the QP is solved by
    row generation on those rows (:class:`~iamp.planners.avoid.solve.RowGeneration`)."""

    def __init__(self, problem: Problem, steps: int, hold: str, solver: str,
                 settings: dict[str, Any] | None = None, row_generation: bool = True,
                 node_solver: str = "schur", limits_between: str = "certified",
                 shared: GridShare | None = None) -> None:
        self.problem, self.hold, self.solver, self.settings = problem, hold, solver, settings
        self.N = int(steps)
        self.tf = problem.tf
        self.h = self.tf / self.N
        self.data = AvoidData(problem, np.linspace(0.0, self.tf, self.N + 1), hold, shared=shared)
        d = self.data
        self.degree = max([3] + [len(v.x_poly) - 1 for v in problem.vehicles])
        # what depends on the grid, the hold, the degree and the half-planes' signs only: kept
        # for the next plans (:class:`_GridLayout`)
        layout_key = ("layout", self.N, hold, d.t_nodes.tobytes(), self.degree,
                      tuple(hp.sigma for pair in d.planes for hp in pair))
        grid = shared.get(layout_key) if shared is not None else None
        if grid is None:
            grid = _GridLayout(d, self.h, self.degree)
            if shared is not None:
                shared.put(layout_key, grid)
        self._grid: _GridLayout = grid
        self._shared = shared
        self._t_nodes: list[float] = d.t_nodes.tolist()
        self.A_eq, self._P_diag, self.M_full = grid.A_eq, grid.P_diag, grid.M_full
        self.limit_rows: Any = None
        A_lim: sp.csr_matrix | None = None
        u_lim = np.zeros(0)
        if problem.limits is not None:
            from iamp.planners.qp.limits import check_hold, limit_rows

            check_hold(problem.limits, hold)
            key = ("limits", self.N, hold, d.t_nodes.tobytes(), repr(problem.limits), limits_between)
            kept = shared.get(key) if shared is not None else None
            if kept is None:
                lr = limit_rows(d, d.t_nodes, hold, problem.limits, between=limits_between)
                # the stacked rows depend on the limit rows only: kept with them
                A_lim = sp.csr_matrix(sp.vstack([lr.A, -lr.A]))
                A_lim.sort_indices()
                # and so does the number of its rows that negate the others (:func:`_mirrored`)
                kept = (lr, A_lim, np.r_[lr.hi, -lr.lo],
                        _mirrored(np.asarray(A_lim.indptr, dtype=np.int32), np.asarray(A_lim.indices, dtype=np.int32),
                                  np.asarray(A_lim.data, dtype=float)))
                if shared is not None:
                    shared.put(key, kept)
            self.limit_rows, A_lim, u_lim, mirrored = kept
        if A_lim is None:  # no limit rows
            A_lim = sp.csr_matrix((0, d.n))
            mirrored = 0
        A_lim.sort_indices()
        #: the number of limit rows that negate the first half (``-A_lim``, entry for entry: the
        #: node solver forms each pair's product once), else 0
        self._lim_mirrored: int = mirrored
        self.A_lim, self.u_lim = A_lim, u_lim
        self.n_solves = 0
        #: the search's solved specs (:meth:`ContinuousAvoidPlanner._qp_solve`)
        self.solved: dict[Spec, Solved] = {}
        self._layout()
        self._rows_solver = RowGeneration(solver, self.data.P, self.A_eq, self.data.b_eq, settings,
                                          every_row=not row_generation)
        check_choice(node_solver, NODE_SOLVERS, "node_solver", "node solver")
        self.node_solver = node_solver
        #: the exact node solver of the search (``node_solver="schur"``; its factored KKT matrix
        #: is shared with :class:`~iamp.planners.avoid.dual.DualBounds`)
        self.schur = self._schur(shared) if node_solver == "schur" else None
        #: backend solves among :attr:`n_solves`
        self.n_backend_solves = 0
        #: relaxations whose optimum was their parent's, proved without a solve (:meth:`inherit`;
        #: not in :attr:`n_solves`)
        self.n_inherited = 0

    def _schur(self, shared: GridShare | None) -> SchurActiveSet:
        """The node solver of this grid: from ``shared`` when a plan before factored the same
        ``P`` and ``A_eq`` (bit for bit, :meth:`~iamp.planners.avoid.schur.SchurActiveSet.same_matrix`),
        with this problem's right-hand side; else factored here (and kept in ``shared``)."""
        d = self.data
        key = ("schur", self.N, self.hold, d.t_nodes.tobytes())
        known = shared.get(key) if shared is not None else None
        if isinstance(known, SchurActiveSet) and known.same_matrix(d.P, self.A_eq):
            return known.with_rhs(d.b_eq)
        out = SchurActiveSet(d.P, self.A_eq, d.b_eq)
        if shared is not None:
            shared.put(key, out)
        return out

    # --- rows ----------------------------------------------------------------------------
    def _layout(self) -> None:
        """The fixed CSR structure of every inequality row (class docstring) and the values of
        the full pieces' blocks."""
        d = self.data
        n = self.degree + 1
        m = len(self.problem.vehicles)
        self.n_b = m * 2 * self.N * n
        #: the four node columns of every Bernstein row of the layout, shape ``(n_b, 4)``
        #: (int32 like scipy's own index arrays: no conversion when a spec's CSR matrix is built)
        self._bern_cols = self._grid.bern_cols
        self._lim_data = np.asarray(self.A_lim.data, dtype=float)
        self._lim_indices = np.asarray(self.A_lim.indices, dtype=np.int32)
        self._lim_indptr = np.asarray(self.A_lim.indptr, dtype=np.int32)
        #: whether the node solver has solved the columns of ``K⁻¹`` of the limit rows' entries
        #: (after this QP's first node solve, :meth:`solve`)
        self._lim_columns = False
        #: whether a layout row is in a set (:meth:`solve`'s warm start), reset after each use
        self._mark = np.zeros(self.n_b + self.u_lim.size, dtype=bool)
        self._lim_ids = self.n_b + np.arange(self.u_lim.size, dtype=np.int64)
        #: per vehicle and half-plane: σ M (row values of a full piece) of every piece, every full
        #: piece's bounds
        self._full_vals: dict[tuple[int, int], FloatArray] = self._grid.full_vals
        self._spec_rows: dict[Spec, tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]]] = {}
        self._csr64: dict[int, tuple[sp.csr_matrix, CsrArrays]] = {}
        #: per number of Bernstein rows, the row pointers of a spec's CSR rows (:meth:`_build_spec_rows`;
        #: read-only, shared by the specs' matrices), as int32 (scipy's) and int64 (the kernels')
        self._ptrs: dict[int, tuple[NDArray[np.int32], NDArray[np.int64]]] = {}
        #: per vehicle and half-plane, its rows' values and bounds (:class:`_PlaneRows`): they depend
        #: on the grid, the degree and the half-plane (its vehicle's motion, size and corner) only,
        #: so the plans of one planner keep them (``shared``, under all of these; the same arrays as
        #: computed here)
        self._planes: dict[tuple[int, int], _PlaneRows] = {}
        self._plane_arrays: tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.int64]] | None = None
        self._full_rhs: dict[tuple[int, int], FloatArray] = {}
        for i in range(m):
            for a in (0, 1):
                hp = self.data.planes[i][a]
                v = hp.vehicle
                plane_key = ("rhs", self.N, d.t_nodes.tobytes(), self.degree, hp.axis,
                             repr((tuple(v.x_poly), v.y, v.length, v.width, v.safety_x, v.safety_y, v.corner)))
                kept = self._shared.get(plane_key) if self._shared is not None else None
                if not isinstance(kept, _PlaneRows):
                    t0 = d.t_nodes[:-1]
                    kept = _PlaneRows(self._rhs(hp, t0, t0 + self.h).ravel())
                    if self._shared is not None:
                        self._shared.put(plane_key, kept)
                self._planes[(i, a)] = kept
                self._full_rhs[(i, a)] = kept.full_rhs

    def plane_arrays(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.int64]]:
        """The half-planes as :func:`~iamp.planners.avoid.search_kernel.plane_margin` takes them:
        per vehicle and half-plane ``σ`` and the half size plus safety margin (``L/2 + S_x``,
        ``W/2 + S_y``), per vehicle its ``y`` and its ``x_s`` coefficients (rows padded with zeros;
        their number), built once."""
        if self._plane_arrays is None:
            vs = self.problem.vehicles
            m = len(vs)
            sigma = np.array([[hp.sigma for hp in pair] for pair in self.data.planes], dtype=float).reshape(m, 2)
            half = np.array([[v.length / 2 + v.safety_x, v.width / 2 + v.safety_y] for v in vs],
                            dtype=float).reshape(m, 2)
            lateral = np.array([float(v.y) for v in vs], dtype=float)
            plen = np.array([len(v.x_poly) for v in vs], dtype=np.int64)
            polys = np.zeros((m, int(plen.max(initial=1))))
            for i, v in enumerate(vs):
                polys[i, :len(v.x_poly)] = np.asarray(v.x_poly, dtype=float)
            self._plane_arrays = (sigma, half, lateral, polys, plen)
        return self._plane_arrays

    def _rhs(self, hp: HalfPlane, ta: float | FloatArray, tb: float | FloatArray) -> FloatArray:
        """The bounds of half-plane ``hp``'s Bernstein rows on ``[ta, tb]`` (arrays: on every
        interval, shape ``(..., d + 1)``)."""
        v = hp.vehicle
        if hp.axis == "x":
            beta = poly_bernstein(np.asarray(v.x_poly, dtype=float), ta, tb, self.degree)
            half = v.length / 2 + v.safety_x
        else:
            beta = np.full(np.shape(ta) + (self.degree + 1,), float(v.y))
            half = v.width / 2 + v.safety_y
        return np.asarray(hp.sigma * beta - half + ROW_TOL_M, dtype=float)

    def split_polynomials(self) -> tuple[FloatArray, FloatArray]:
        """Power coefficients in ``λ`` (axis 0, shape ``(d + 1, d + 1, 4)``) of the σ-free row
        values of a piece's sub-pieces ``[0, λ]`` and ``[λ, 1]`` (:func:`~iamp.planners.avoid.bernstein.piece_matrix`
        is a polynomial of degree ``d`` in either end: fitted exactly on ``d + 1`` points, once)."""
        grid = self._grid
        if grid.split_polys is None:
            D = self.degree
            lam = np.linspace(0.0, 1.0, D + 1)
            grid.split_polys = (fit_polynomial(np.array([piece_matrix(self.h, 0.0, float(x), D) for x in lam]), D),
                                fit_polynomial(np.array([piece_matrix(self.h, float(x), 1.0, D) for x in lam]), D))
        return grid.split_polys

    def rhs_polynomial(self, i: int, plane: int, k: int, pre: bool) -> FloatArray:
        """Power coefficients in ``λ`` (shape ``(d + 1, d + 1)``) of the bounds of vehicle ``i``'s
        half-plane ``plane`` on ``[t_k, t_k + λh]`` (``pre``) or ``[t_k + λh, t_{k+1}]`` (a
        polynomial of degree ``d`` in ``λ``; fitted once per piece, with the pieces beside it not
        yet fitted: the search's boxes move between neighbouring pieces, and one pass computes the
        same numbers per piece as one piece at a time (:func:`~iamp.planners.avoid.dual.fit_polynomials`);
        for ``H_y``, whose bound is the same number on every interval, once for all pieces)."""
        kept = self._planes[(i, plane)].polys
        out = kept.get((k, pre))
        if out is not None:
            return out
        hp = self.data.planes[i][plane]
        if hp.axis == "y":
            out = kept.get((-1, True))  # the same samples on every piece and at either end
            if out is not None:
                kept[(k, pre)] = out
                return out
            ks = [k]
        else:
            ks = [j for j in (k - 1, k, k + 1) if 0 <= j < self.N and (j, pre) not in kept]
        # every sample interval of every piece in one call (the same operations per interval as
        # one at a time): ends t_k + λ_j h
        tk = np.array([self._t_nodes[j] for j in ks])[:, None]
        ends = tk + self._grid.lam * self.h
        fixed = np.empty_like(ends)  # the other end of every sample interval
        fixed[...] = tk if pre else tk + self.h
        vals = self._rhs(hp, fixed, ends) if pre else self._rhs(hp, ends, fixed)
        for j, fit in zip(ks, fit_polynomials(vals, self.degree)):
            kept[(j, pre)] = fit
        out = kept[(k, pre)]
        if hp.axis == "y":
            kept[(-1, True)] = out
        return out

    def _split_values(self, pre: bool, x: float) -> tuple[FloatArray, FloatArray]:
        r"""The powers :math:`p = (1, \lambda, .., \lambda^d)` of ``λ = x`` and the σ-free row values
        :math:`p\,M` (raveled) of the sub-piece ``[0, λ]`` (``pre``) or ``[λ, 1]`` of any piece, ``M``
        of :meth:`split_polynomials`; kept with the grid (:attr:`_GridLayout.split_vals`: they depend
        on nothing else, and every plan of a closed loop on the grid splits pieces at the same box
        ends; read-only)."""
        split_vals = self._grid.split_vals
        # (not at zero: its key is also -0.0's, whose powers differ in sign)
        kept = split_vals.get((pre, x)) if x != 0.0 else None
        if kept is not None:
            return kept
        pw: FloatArray = np.asarray(x ** self._grid.exponents, dtype=float)
        M = self.split_polynomials()[0 if pre else 1]
        out = (pw, np.asarray(pw @ M.reshape(M.shape[0], -1), dtype=float))
        if x != 0.0:
            if len(split_vals) >= SPLIT_LIMIT:
                split_vals.clear()
            split_vals[(pre, x)] = out
        return out

    def _split(self, i: int, plane: int, k: int, l0: float, l1: float) -> tuple[FloatArray, FloatArray]:
        """The row values (``σ M``, raveled) and bounds of vehicle ``i``'s half-plane ``plane`` on
        the sub-piece ``[λ0, λ1]`` of piece ``k``: from :meth:`split_polynomials` and
        :meth:`rhs_polynomial` for ``[0, λ]`` and ``[λ, 1]`` (the only sub-pieces a spec imposes),
        directly otherwise; kept with the half-plane (:class:`_PlaneRows`: a box's ends recur in
        its children, candidates and relaxations)."""
        kept = self._planes[(i, plane)]
        key = (k, l0, l1)
        out = kept.splits.get(key)
        if out is None:
            hp = self.data.planes[i][plane]
            if l0 == 0.0 or l1 == 1.0:
                pre = l0 == 0.0
                x = l1 if pre else l0
                pw, vals = self._split_values(pre, x)
                out = (hp.sigma * vals, pw @ self.rhs_polynomial(i, plane, k, pre))
            else:
                t0 = float(self.data.t_nodes[k])
                out = (hp.sigma * piece_matrix(self.h, l0, l1, self.degree).ravel(),
                       self._rhs(hp, t0 + l0 * self.h, t0 + l1 * self.h))
            kept.keep(kept.splits, key, out)
        return out

    def segment_pieces(self, ta: float, tb: float) -> list[tuple[int, float, float]]:
        """The pieces ``(k, λ0, λ1)`` of ``[ta, tb]`` (local coordinates ``λ ∈ [0, 1]`` of piece
        ``k``; at most one sub-interval per piece); a point ``ta = tb`` inside ``(0, t_f)`` gives
        its piece's point (the state's own row)."""
        parts = self._segment_parts(ta, tb)
        if parts is None:
            return []
        head, full_lo, full_hi, tail = parts
        return ([head] if head is not None else []) + [(k, 0.0, 1.0) for k in range(full_lo, full_hi + 1)] \
            + ([tail] if tail is not None else [])

    def _segment_parts(self, ta: float, tb: float) -> tuple[tuple[int, float, float] | None, int, int,
                                                            tuple[int, float, float] | None] | None:
        """:meth:`segment_pieces` as its first sub-piece (or None), the range ``full_lo..full_hi``
        of its full pieces and its last sub-piece (or None); None for an empty interval."""
        if tb < ta or tb <= 0.0 or ta >= self.tf:
            return None
        # Python floats: the same IEEE operations as on numpy's scalars, without their overhead
        t_nodes = self._t_nodes
        ka = min(math.floor(ta / self.h), self.N - 1)
        kb = min(math.ceil(tb / self.h) - 1, self.N - 1)
        kb = max(kb, ka)
        lam = [(ta - t_nodes[ka]) / self.h, (tb - t_nodes[kb]) / self.h]
        full_lo = ka + (1 if lam[0] > 1e-12 else 0)
        full_hi = kb - (1 if lam[1] < 1 - 1e-12 else 0)
        if ka == kb and full_lo > full_hi:
            return (ka, lam[0], lam[1]), 0, -1, None
        return ((ka, lam[0], 1.0) if full_lo > ka else None, full_lo, full_hi,
                (kb, 0.0, lam[1]) if full_hi < kb else None)

    def _segment_blocks(self, i: int, plane: int, ta: float, tb: float) -> _Segment:
        """Vehicle ``i``'s half-plane ``plane`` imposed on ``[ta, tb]`` as the blocks of its
        Bernstein rows, in layout order (:class:`_Segment`: the first sub-piece, the full pieces as
        one slice of the half-plane's arrays, the last sub-piece; the layout numbers and the node
        columns of its rows); kept with the half-plane (:class:`_PlaneRows`: a box's ends recur in
        its children, candidates and relaxations).  :meth:`_build_spec_rows` concatenates the
        blocks of every segment of a spec at once."""
        kept = self._planes[(i, plane)]
        key = (i, ta, tb)
        out = kept.segments.get(key)
        if out is None:
            n = self.degree + 1
            base = (i * 2 + plane) * self.N * n
            vals: list[FloatArray] = []
            rhs: list[FloatArray] = []
            start = 0
            parts = self._segment_parts(ta, tb)
            if parts is not None:
                head, full_lo, full_hi, tail = parts
                start = base + (head[0] if head is not None else full_lo) * n
                # the first sub-piece, the full pieces (contiguous: one block), the last sub-piece
                if head is not None:
                    v, c = self._split(i, plane, *head)
                    vals.append(v)
                    rhs.append(c)
                if full_lo <= full_hi:
                    vals.append(self._full_vals[(i, plane)][4 * full_lo * n:4 * (full_hi + 1) * n])
                    rhs.append(self._full_rhs[(i, plane)][full_lo * n:(full_hi + 1) * n])
                if tail is not None:
                    v, c = self._split(i, plane, *tail)
                    vals.append(v)
                    rhs.append(c)
            rows = sum(c.size for c in rhs)
            # the sub-pieces and full pieces are consecutive pieces: consecutive layout rows
            out = _Segment(vals, rhs, np.arange(start, start + rows, dtype=np.int64),
                           self._grid.bern_cols_flat[4 * start:4 * (start + rows)])
            kept.keep(kept.segments, key, out)
        return out

    def _segment(self, i: int, plane: int, ta: float, tb: float) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """Vehicle ``i``'s half-plane ``plane`` imposed on ``[ta, tb]``: the values (four per row),
        bounds and layout numbers of its Bernstein rows, in layout order (:meth:`_segment_blocks`
        concatenated)."""
        seg = self._segment_blocks(i, plane, ta, tb)
        return (np.concatenate(seg.vals) if seg.vals else np.zeros(0),
                np.concatenate(seg.rhs) if seg.rhs else np.zeros(0), seg.ids)

    def _spec_segments(self, spec: Spec) -> list[_Segment]:
        """The segments that ``spec`` imposes (per vehicle ``(first, second, a, b)``: ``first`` on
        ``[0, a]``, ``second`` on ``[b, t_f]``), in layout order (class docstring)."""
        out = []
        for i, (first, second, a, b) in enumerate(spec):
            segs = [(first, 0.0, a)] if a > 0.0 else []
            if b < self.tf:
                segs.append((second, b, self.tf))
            for plane, ta, tb in sorted(segs):  # layout order: half-plane 0, then 1
                out.append(self._segment_blocks(i, plane, ta, tb))
        return out

    def bernstein_rows(self, spec: Spec) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """The Bernstein rows that ``spec`` imposes (per vehicle ``(first, second, a, b)``:
        ``first`` on ``[0, a]``, ``second`` on ``[b, t_f]``), in layout order (class docstring):
        their values (four per row, on the columns of the layout), bounds and layout numbers."""
        segs = self._spec_segments(spec)
        vals = [v for s in segs for v in s.vals]
        rhs = [c for s in segs for c in s.rhs]
        return (np.concatenate(vals) if vals else np.zeros(0), np.concatenate(rhs) if rhs else np.zeros(0),
                np.concatenate([s.ids for s in segs]) if segs else np.zeros(0, dtype=np.int64))

    def spec_rows(self, spec: Spec) -> tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]]:
        """The imposed rows of ``spec`` (CSR, in layout order): its Bernstein rows
        (:meth:`bernstein_rows`), then every limit row; their bounds and their layout row
        numbers (built once per spec and plan: a relaxation that :meth:`inherit` cannot prove is
        then solved on the same rows; read-only)."""
        out = self._spec_rows.get(spec)
        if out is None:
            out = self._spec_rows[spec] = self._build_spec_rows(spec)
        return out

    def csr_arrays(self, A: sp.csr_matrix) -> CsrArrays:
        """:func:`~iamp.planners.avoid.schur.csr_arrays` of a spec's rows (:meth:`spec_rows`; kept
        per plan with the matrix: its node solve, KKT residuals and dual bounds read them)."""
        kept = self._csr64.get(id(A))
        if kept is None or kept[0] is not A:
            kept = self._csr64[id(A)] = (A, csr_arrays(A))
        return kept[1]

    def _build_spec_rows(self, spec: Spec) -> tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]]:
        """:meth:`spec_rows` built: the blocks of the spec's segments (:meth:`_spec_segments`) and
        the limit rows, each of the matrix's values, column indices, the bounds and the layout
        numbers concatenated once (the same arrays as :meth:`bernstein_rows` followed by the limit
        rows)."""
        segs = self._spec_segments(spec)
        vals: list[FloatArray] = []
        rhs: list[FloatArray] = []
        for seg in segs:
            vals += seg.vals
            rhs += seg.rhs
        nb = sum(seg.ids.size for seg in segs)
        ptrs = self._ptrs.get(nb)
        if ptrs is None:  # the row pointers of nb Bernstein rows (four entries each), then the limit rows
            ptr = np.concatenate((np.arange(0, 4 * nb + 1, 4, dtype=np.int32), 4 * nb + self._lim_indptr[1:]))
            ptr.flags.writeable = False
            ptrs = self._ptrs[nb] = (ptr, ptr.astype(np.int64))  # (numba: a writeable int64 array)
        vals.append(self._lim_data)
        rhs.append(self.u_lim)
        data = np.concatenate(vals)
        indices = np.concatenate([seg.cols for seg in segs] + [self._lim_indices])
        A = compressed(sp.csr_matrix, data, indices, ptrs[0], (nb + self.u_lim.size, self.data.n))
        # the kernels' arrays (:meth:`csr_arrays`: what csr_arrays(A) returns, the row pointers
        # converted once per number of Bernstein rows)
        self._csr64[id(A)] = (A, (ptrs[1], indices.astype(np.int64), data))
        return A, np.concatenate(rhs), np.concatenate([seg.ids for seg in segs] + [self._lim_ids])

    # --- solving ---------------------------------------------------------------------------
    def solve(self, spec: Spec, reference: FloatArray | None = None, active: NDArray[np.int64] | None = None,
              cutoff: float | None = None) -> Solved:
        """The QP with the rows of ``spec`` (plus the limit rows).

        With the node solver (:attr:`schur`): the exact dual active set, warm-started from the rows
        ``active`` (layout numbers: a nearby solution's binding rows); a solve it does not finish
        (``numerical_error`` or its step budget) and every solve without it goes to the backend,
        by row generation from the rows that ``reference`` (a nearby solution) nearly binds
        (:class:`~iamp.planners.avoid.solve.RowGeneration`).  Every solve counts in
        :attr:`n_solves` (the backend's also in :attr:`n_backend_solves`).  With ``cutoff``, the
        node solver may stop as soon as its lower bound of the QP's optimum reaches it: status
        :data:`CUTOFF`, ``cost`` that bound (no solution)."""
        A_in, u_in, ids = self.spec_rows(spec)
        sol = None
        if self.schur is not None:
            start = None
            if active is not None:  # the positions of the rows ``active`` among ``ids``
                self._mark[active] = True
                start = np.flatnonzero(self._mark[ids])
                self._mark[active] = False
            arrays = self.csr_arrays(A_in)
            # the columns of K⁻¹ the limit rows touch are solved by this QP's first solve (every
            # spec imposes them): the later solves test the Bernstein rows' columns only
            cols = arrays[1][:int(arrays[0][ids.size - self.u_lim.size])] if self._lim_columns else None
            sol = self.schur.solve(A_in, u_in, start, cutoff, arrays, self._lim_mirrored, cols)
            self._lim_columns = True
            self.n_solves += 1
            if sol.status == CUTOFF:
                return Solved(spec, CUTOFF, float(sol.bound), sol.z, sol.y, sol.iterations, self, 1,
                              (A_in, u_in, ids))
            if sol.status not in (st.OPTIMAL, st.INFEASIBLE):
                sol = None  # not solved (ill-conditioned or its step budget): the backend solves it
        if sol is None:
            sol = self._rows_solver.solve(A_in, u_in, ids, reference)
            self.n_solves += sol.solves
            self.n_backend_solves += sol.solves
        return self._solved(spec, sol, (A_in, u_in, ids))

    def inherit(self, spec: Spec, parent: Solved) -> Solved | None:
        r"""The optimum of ``spec`` without a solve, when it is ``parent``'s: ``parent`` is the
        optimum of a relaxation of ``spec`` (every row it imposes is one of ``spec``'s, e.g. the
        relaxation of a box that contains ``spec``'s box); if its ``z`` keeps every row of
        ``spec`` (to :data:`~iamp.planners.avoid.solve.GENERATION_TOL`, the node solver's own
        stopping test) and each row with a positive multiplier is also a row of ``spec`` with the
        same values and bound, then ``(z, y)`` (those multipliers, zero on the other rows) satisfies
        ``spec``'s KKT conditions — checked again from the data
        (:meth:`~iamp.planners.avoid.schur.SchurActiveSet.residual`,
        :data:`~iamp.planners.avoid.schur.CHECK_TOL`) — so it is ``spec``'s unique optimum (strictly
        convex in the inputs), the cost a lower bound attained.  Returns None otherwise (then solve
        it).  Counted in :attr:`n_inherited`, not in :attr:`n_solves`."""
        if self.schur is None or parent.status != st.OPTIMAL:
            return None
        A_in, u_in, ids = self.spec_rows(spec)
        z = parent.z
        arrays = self.csr_arrays(A_in)
        if A_in.shape[0] and self.schur.violation(arrays, z, u_in, self._lim_mirrored) > GENERATION_TOL:
            return None
        n_eq = self.data.n_eq
        pA, pu, pids = parent.spec_rows()
        y_p = parent.y[n_eq:]
        y = np.zeros(n_eq + ids.size)
        y[:n_eq] = parent.y[:n_eq]
        bind = np.flatnonzero(y_p > 0)
        if bind.size:
            at = np.searchsorted(ids, pids[bind])  # the layout numbers ascend in both
            if np.any(at >= ids.size) or np.any(ids[np.minimum(at, ids.size - 1)] != pids[bind]):
                return None
            for r, c in zip(bind, at):
                a, b = pA.indptr[r], pA.indptr[r + 1]
                e, f = A_in.indptr[c], A_in.indptr[c + 1]
                if (pu[r] != u_in[c] or not np.array_equal(pA.indices[a:b], A_in.indices[e:f])
                        or not np.array_equal(pA.data[a:b], A_in.data[e:f])):
                    return None
            y[n_eq + at] = y_p[bind]
        if self.schur.residual(A_in, u_in, z, y, None, arrays, self._lim_mirrored) > CHECK_TOL:
            return None
        self.n_inherited += 1
        return Solved(spec, st.OPTIMAL, parent.cost, z, y, 0, self, 0, (A_in, u_in, ids))

    def backend_solve(self, sol: Solved) -> Solved:
        """The QP of ``sol`` solved again by the plan's backend (OSQP, Clarabel or PIQP), by row
        generation from the rows with a positive multiplier in ``sol`` (the independent check of
        a node solver's optimum, :meth:`ContinuousAvoidPlanner._verified`)."""
        A_in, u_in, ids = sol.spec_rows()
        d = self.data
        binding = np.flatnonzero(sol.y[d.n_eq:] > 0)
        # OSQP starts from the node solver's point (the interior-point backends from their own):
        # where ADMM starts, not what it accepts — the KKT check below is on the backend's answer
        r = self._rows_solver.solve(A_in, u_in, ids, None, binding, (sol.z, sol.y))
        self.n_solves += r.solves
        self.n_backend_solves += r.solves
        return self._solved(sol.spec, r, (A_in, u_in, ids))

    def polish(self, sol: Solved) -> Solved | None:
        """``sol`` (the backend's answer of :meth:`backend_solve`) refined on the rows it holds
        active: the exact optimum with those rows held at their bounds
        (:func:`~iamp.planners.qp.backends.polish.polish`, one LU of that KKT matrix), or None
        when that matrix is singular.  Not checked here: :meth:`ContinuousAvoidPlanner._verified`
        checks its KKT conditions and keeps the backend's own answer when they fail."""
        from iamp.planners.qp.backends.polish import polish

        A_in, u_in, ids = sol.spec_rows()
        d = self.data
        l = np.concatenate((d.b_eq, np.full(u_in.size, -np.inf)))
        r = polish(d.P, d.q, _stacked(self.A_eq, A_in), l, np.concatenate((d.b_eq, u_in)), sol.z, sol.y)
        if r is None:
            return None
        rows = RowsSolution(st.OPTIMAL, r.z, r.y, sol.iterations, sol.solves,
                            np.flatnonzero(r.y[d.n_eq:] != 0.0), True)
        return self._solved(sol.spec, rows, (A_in, u_in, ids))

    def _solved(self, spec: Spec, sol: RowsSolution,
                rows: tuple[sp.csr_matrix, FloatArray, NDArray[np.int64]]) -> Solved:
        """:class:`Solved` of a solver's answer; cost :math:`J = \\tfrac12 z^\\top P z`."""
        d = self.data
        ok = sol.status == st.OPTIMAL and sol.finite
        cost = float(sol.z @ matvec(d.P, sol.z) - 0.5 * sol.z @ (self._P_diag * sol.z)) if ok else np.inf
        status = sol.status if (ok or sol.status != st.OPTIMAL) else st.NUMERICAL_ERROR
        return Solved(spec, status, cost, sol.z, sol.y, sol.iterations, self, sol.solves, rows)

    def trajectory(self, z: FloatArray) -> HoldTrajectory:
        X, U = self.data.unpack(z)
        return HoldTrajectory(self.data.t_nodes.copy(), X, U, self.hold)


class _SolvedPoints:
    """The crossing times of the optimal candidates a search has solved, per combination of orders
    (:meth:`ContinuousAvoidPlanner._probe`'s ``solved``), read from
    :attr:`ContinuousAvoidQP.solved` as it grows: each entry once (it only gains entries, each
    stored once), so a search of thousands of boxes does not rescan every solve per box."""

    def __init__(self) -> None:
        self._seen = 0
        self._points: dict[tuple[tuple[int, int], ...], list[list[float]]] = {}
        #: :meth:`of` per combination of orders, until it gains a point
        self._arrays: dict[tuple[tuple[int, int], ...], FloatArray] = {}

    def of(self, qp: ContinuousAvoidQP, orders: tuple[tuple[int, int], ...]) -> FloatArray:
        """The rows of crossing times solved so far with ``orders`` (read-only)."""
        for spec, r in itertools.islice(qp.solved.items(), self._seen, None):
            if r.status == st.OPTIMAL and all(a == b for _, _, a, b in spec):
                key = tuple((f, s) for f, s, _, _ in spec)
                self._points.setdefault(key, []).append([a for _, _, a, _ in spec])
                self._arrays.pop(key, None)
        self._seen = len(qp.solved)
        out = self._arrays.get(orders)
        if out is None:
            out = self._arrays[orders] = np.array(self._points.get(orders, []), dtype=float).reshape(-1, len(orders))
            out.flags.writeable = False
        return out


@dataclass(order=True)
class _Box:
    bound: float
    serial: int
    orders: tuple[tuple[int, int], ...] = field(compare=False)
    lo: FloatArray = field(compare=False)
    hi: FloatArray = field(compare=False)
    #: the solution nearest the box: its own relaxation (``own_relaxation``) or its parent's
    #: candidate (row generation starts from its nearly binding rows)
    relaxed: Solved = field(compare=False)
    own_relaxation: bool = field(default=True, compare=False)
    #: dual polynomials of the box's ancestors' candidates (each valid on every sub-box; the
    #: piece polynomials of every candidate are in the search's :class:`DualStore`)
    duals: tuple[DualPolynomial, ...] = field(default=(), compare=False)
    #: the stored polynomials valid on the box when it was pushed (:meth:`DualStore.valid` and
    #: ``duals``) and the store's size then (:meth:`DualStore.__len__`; -1: none computed): at
    #: its pop, a store of the same size gives the same polynomials and bound, which ``bound``
    #: already holds
    polys: list[DualPolynomial] = field(default_factory=list, compare=False)
    store_size: int = field(default=-1, compare=False)


def _spec(orders: Sequence[tuple[int, int]], a: Sequence[float] | FloatArray, b: Sequence[float] | FloatArray) -> Spec:
    return tuple((int(f), int(s), float(x), float(y)) for (f, s), x, y in zip(orders, a, b))


@dataclass
class ContinuousAvoidPlanner:
    """The continuous-time avoidance QP (module docstring).

    Parameters
    ----------
    steps : int
        Grid intervals ``N``.
    hold : {"foh", "zoh"}
    solver : {"osqp", "clarabel"}
    max_solves : int
        QPs the branch and bound may solve before it stops with ``local`` (a count of work, so
        the same problem gives the same status and plan on any machine, SPEC §17; the budget
        decides between ``optimal`` and ``local``, it never refuses a problem).
    max_boxes : int
        Boxes the branch and bound may create before it stops with ``local`` (a count of work
        too: boxes bounded by the dual polynomials alone are split without a QP, so ``max_solves``
        does not bound them; a three-vehicle ZOH problem created 446,689 boxes for 212 QPs, about
        a minute of CPU, where the plans of the bench create 17-73).
    gap_rel : float
        Relative gap at which a box is closed.
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    solver_settings: dict[str, Any] | None = None
    max_solves: int = 2000
    max_boxes: int = 20000
    gap_rel: float = GAP_REL
    #: Solve each QP by row generation (:class:`~iamp.planners.avoid.solve.RowGeneration`, exact);
    #: ``False``: every QP on all its rows at once (for study and tests).
    row_generation: bool = True
    #: The solver of the search's QPs (:data:`NODE_SOLVERS`): ``"schur"``, the exact dual active
    #: set on the grid's factored KKT matrix, then the final QP by the backend (``solver``);
    #: ``"backend"``: every QP by the backend.
    node_solver: str = "schur"
    #: Where the speed and ``y`` limits hold (:data:`iamp.planners.qp.limits.BETWEEN`):
    #: ``"certified"`` (default) for every ``t`` by the Bernstein rows of each piece (module
    #: docstring); ``"nodes"`` at the grid nodes only (for study and tests).
    limits_between: str = "certified"
    #: What the plans of this planner share per grid (:class:`GridShare`; None: each plan builds
    #: its own).  The same plans with or without it.
    shared: GridShare | None = field(default=None, repr=False, compare=False)
    #: Dual polynomials a box keeps from its ancestors' candidates (the most recent).
    DUALS_KEPT = 4
    #: Solves of the final secant search per vehicle (:meth:`_polish`).
    POLISH_STEPS = 8
    #: With several vehicles, the coordinate secant's steps per vehicle before the joint BFGS
    #: search (enough for its curvature).
    POLISH_PROBES = 3
    #: A secant step whose predicted decrease ``½|∂J/∂τ · Δτ|`` is below this (relative to
    #: ``max(1, J)``) is not taken (the backends solve each QP to about 1e-10).
    POLISH_TOL_REL = 1e-11
    #: Starts of the final secant search (:meth:`_polish_starts`).
    POLISH_STARTS = 3

    def _qp_solve(self, qp: ContinuousAvoidQP, spec: Spec, reference: Solved | None = None,
                  cutoff: float | None = None) -> Solved:
        """``qp.solve(spec)``, each spec solved once per plan (a box's candidate is often its
        parent's); ``cutoff``: see :meth:`ContinuousAvoidQP.solve` (a stored :data:`CUTOFF`
        result holds for any lower cutoff: the search's ``U`` only decreases)."""
        if spec not in qp.solved:
            qp.solved[spec] = qp.solve(spec, None if reference is None else reference.z,
                                       None if reference is None else reference.active(), cutoff)
        return qp.solved[spec]

    def _candidate_tau(self, qp: ContinuousAvoidQP, box: _Box) -> tuple[FloatArray, FloatArray]:
        """Per vehicle, the ``τ`` in its box where the relaxed optimum best keeps the first
        half-plane before and the second after (a max-min of margins on 33 samples), and that
        margin (negative: the relaxed optimum breaks vehicle ``i``'s constraint in the box):
        :func:`~iamp.planners.avoid.search_kernel.candidate_tau` on the relaxed optimum's ``z``."""
        m = len(box.orders)
        out = np.empty(m)
        worst = np.empty(m)
        sigma, half, lateral, polys, plen = qp.plane_arrays()
        d = qp.data
        _run("candidate_tau", search_kernel)(
            np.asarray(box.relaxed.z, dtype=float), d.t_nodes, d.N, d.block, qp.hold == "foh",
            np.asarray(box.lo, dtype=float), np.asarray(box.hi, dtype=float),
            np.asarray(box.orders, dtype=np.int64).reshape(m, 2), sigma, half, lateral, polys, plen,
            np.empty((m, 33)), np.empty(33), np.empty(33), out, worst)
        return out, worst

    #: A probe point within this many steps ``h`` of a solved candidate (every vehicle) is passed
    #: over (:meth:`_probe`).
    PROBE_SKIP_STEPS = 1e-4

    def _probe(self, box: _Box, tau: FloatArray, polys: Sequence[DualPolynomial],
               solved: FloatArray | None, h: float, packing: Packing | None = None) -> tuple[FloatArray, float]:
        """``tau`` with each vehicle that a polynomial of ``polys`` (valid on the box) depends on
        moved to where their largest value, the box's dual bound, is lowest on a product grid,
        and that value (``-inf`` without such a polynomial).  A grid point within
        :attr:`PROBE_SKIP_STEPS` steps ``h`` of a point of ``solved`` (crossing times of solved
        candidates, :class:`_SolvedPoints`) is passed over unless every point is: its cost
        is known to the QPs' accuracy, and a candidate there (a box's end, beside the candidate
        moved inside the box below it, :meth:`_inside`) would only repeat it.  One vehicle (the
        search passes ``solved`` only then: with three, the overtakes' searches took more QPs).
        ``packing``: the search's :class:`~iamp.planners.avoid.dual.Packing`."""
        polys = [dp for dp in polys if dp.vehicles]
        if not polys:
            return tau, -np.inf
        # a vehicle without multipliers in a polynomial leaves it constant: only the others move
        lo, hi = box.lo.tolist(), box.hi.tolist()
        vs = sorted({v for dp in polys for v in dp.vehicles if hi[v] > lo[v] and dp.binds[v]})
        # the product grid in meshgrid's "ij" order; a point a solved candidate (in a piece beside
        # the box's) all but shares: its cost is known to the QPs' accuracy, so the probe takes
        # the next lowest point instead
        return grid_minimum(polys, tau, vs, box.lo, box.hi, {1: 9, 2: 5}.get(len(vs), 3),
                            solved if solved is not None and len(solved) else None, self.PROBE_SKIP_STEPS * h,
                            packing)

    def _cut(self, qp: ContinuousAvoidQP, lo: float, hi: float) -> float:
        """Where a box's interval ``[lo, hi]`` of one vehicle is split: at the midpoint within one
        grid piece, else at the grid node nearest the midpoint (so that boxes soon lie within one
        piece, where the candidates' dual polynomials bound them without a QP)."""
        mid = 0.5 * (lo + hi)
        if piece_of(lo, hi, qp.h, qp.N) is not None:
            return mid
        k_lo, k_hi = int(np.ceil(lo / qp.h + 1e-9)), int(np.floor(hi / qp.h - 1e-9))
        if k_lo > k_hi:  # pragma: no cover - a box over two pieces has an interior node
            return mid
        return float(min(max(int(round(mid / qp.h)), k_lo), k_hi) * qp.h)

    #: A candidate at its box's upper end on a grid node moves this far (in steps ``h``) into the
    #: box (:meth:`_inside`).
    INSIDE_STEPS = 1e-6

    def _inside(self, qp: ContinuousAvoidQP, box: _Box, tau: FloatArray) -> FloatArray:
        """``tau`` with each crossing at its box's upper end, where that end is a grid node, moved
        :attr:`INSIDE_STEPS` of a step into the box: a crossing on node ``k`` belongs to piece
        ``k`` (:func:`~iamp.planners.avoid.dual.piece_of`), outside the box, so its piece
        polynomial would not bound the box's last piece; inside, it bounds that piece (and its
        cost differs from the node's by the slope times ``1e-6 h``).  One vehicle (with several,
        the overtakes' searches took more QPs)."""
        out = np.asarray(tau, dtype=float).copy()
        if qp.problem.m != 1:
            return out
        for i in range(out.size):
            hi, lo = float(box.hi[i]), float(box.lo[i])
            node = round(hi / qp.h)
            if (hi - lo > 2 * self.INSIDE_STEPS * qp.h and out[i] >= hi - 1e-9 * qp.h
                    and abs(hi - node * qp.h) <= 1e-9 * qp.h):
                out[i] = hi - self.INSIDE_STEPS * qp.h
        return out

    def _cuts(self, qp: ContinuousAvoidQP, lo: float, hi: float, at: float | None,
              improved: bool = False) -> list[float]:
        """Where a box's interval ``[lo, hi]`` of one vehicle is split: around the grid piece of a
        solved candidate's crossing ``at`` when the interval spans several pieces (that piece
        becomes a child, which the candidate's piece polynomial bounds without a relaxation, and
        the children beside it are bounded by their relaxations, cut off early by the incumbent;
        where that piece lies at an end of the interval, only when the candidate ``improved`` the
        incumbent, else the rest would be nearly the whole box; one vehicle: with several, the
        third child of every split multiplies the boxes); else :meth:`_cut`."""
        if at is not None and qp.problem.m == 1 and piece_of(lo, hi, qp.h, qp.N) is None:
            # the piece of ``at`` inside the interval (a crossing at its upper end: the piece below)
            k = piece_of(at, at, qp.h, qp.N) if at < hi - 1e-9 * qp.h else piece_of(hi - qp.h, hi - qp.h, qp.h, qp.N)
            if k is not None:
                cuts = [float(c * qp.h) for c in (k, k + 1) if lo + 1e-9 * qp.h < c * qp.h < hi - 1e-9 * qp.h]
                if cuts:
                    if len(cuts) == 2 or improved:
                        return cuts
                    # the piece at an end of the interval and the candidate no better than the
                    # incumbent: the rest would be nearly the whole box, and where J is flat the
                    # search walked the pieces one by one; bisect
        return [self._cut(qp, lo, hi)]

    def search(self, qp: ContinuousAvoidQP, orders: list[list[tuple[int, int]]]) -> dict[str, Any]:
        """Branch and bound over crossing-time boxes (module docstring)."""
        tf = qp.tf
        m = len(orders)
        serial = itertools.count()
        heap: list[_Box] = []
        best: Solved | None = None
        best_tau = np.full(m, np.nan)
        n_boxes = 0
        closed_bound = np.inf  # the smallest bound of a box closed to the gap
        free = self._qp_solve(qp, _spec([o[0] for o in orders], np.zeros(m), np.full(m, tf)))
        for combo in itertools.product(*orders):
            if free.status == st.OPTIMAL:
                heapq.heappush(heap, _Box(free.cost, next(serial), tuple(combo), np.zeros(m), np.full(m, tf), free))
                n_boxes += 1
        failures: list[str] = [] if free.status in (st.OPTIMAL, st.INFEASIBLE) else [free.status]
        shortcut = self._free_certified(qp, heap[0]) if heap else None
        if shortcut is not None:
            return {"best": shortcut[0], "tau": shortcut[1], "lower_bound": float(min(free.cost, shortcut[0].cost)),
                    "upper_bound": float(shortcut[0].cost), "closed": True, "n_boxes": n_boxes,
                    "open_boxes": len(heap) - 1, "failures": failures, "free": free, "free_certified": True}
        dual = DualBounds(qp)
        store = DualStore(dual)
        points = _SolvedPoints()

        def gap(u: float) -> float:
            # no incumbent (u = inf): no gap, so that U - gap(U) is inf, not inf - inf = nan (a
            # relaxation compared with nan closed every box of a search whose first candidates
            # were infeasible: "infeasible" where a crossing time was feasible)
            return self.gap_rel * max(1.0, abs(u)) if math.isfinite(u) else 0.0

        def bound_of(orders_: tuple[tuple[int, int], ...], lo: FloatArray, hi: FloatArray,
                     duals: Sequence[DualPolynomial]) -> tuple[float, list[DualPolynomial]]:
            polys = store.valid(orders_, lo, hi) + list(duals)
            return max_lower_bound(polys, lo, hi, store.packing), polys

        while heap:
            box = heap[0]
            U = best.cost if best is not None else np.inf
            if box.bound >= U - gap(U):
                break
            if qp.n_solves >= self.max_solves or n_boxes >= self.max_boxes:
                break
            heapq.heappop(heap)
            if box.store_size == len(store):
                # no candidate stored since the box was pushed: its polynomials and their bound
                # (which ``box.bound`` includes) are those of its push
                bound, polys = box.bound, box.polys
            else:
                # the candidates solved since the box was pushed may bound it now
                poly_bound, polys = bound_of(box.orders, box.lo, box.hi, box.duals)
                bound = max(box.bound, poly_bound)
            if bound >= U - gap(U):
                closed_bound = min(closed_bound, bound)
                continue
            # the box's ends as floats (finite: the root's 0 and tf, then cuts between them)
            box_lo, box_hi = box.lo.tolist(), box.hi.tolist()
            widths = [b - a for a, b in zip(box_lo, box_hi)]
            wide = [w > 1e-9 * tf for w in widths]
            covered = {v for dp in polys for v in dp.vehicles if dp.binds[v]}
            if box.own_relaxation or not all(v in covered for v, w in enumerate(wide) if w):
                tau, margin = self._candidate_tau(qp, box)
            else:  # the probe of the box's polynomials moves every vehicle: no relaxed margin needed
                tau, margin = 0.5 * (box.lo + box.hi), np.zeros(m)
            # per vehicle, whether the candidate's multipliers on its rows sum to a positive number
            # (those of the box's polynomials without a candidate)
            binds = [False] * m
            cand: Solved | None = None
            tau_c: list[float] = []  # the candidate's crossing times
            probe, low = self._probe(box, tau, polys, points.of(qp, box.orders) if m == 1 else None, qp.h,
                                     store.packing)
            if low >= U - gap(U) and any(wide) and max(widths) > 1e-6 * qp.h:
                # the polynomials keep the box above U - gap at every probe: only their Bernstein
                # bound is loose, and splitting tightens it without a QP (the multipliers' sums are
                # never NaN: sums of positive multipliers)
                binds = [any(dp.binds[v] for dp in polys) for v in range(m)]
            else:
                if not box.own_relaxation or low > -np.inf:
                    tau = probe
                tau = self._inside(qp, box, tau)  # a new array
                tau_c = tau.tolist()
                # warm-started from the incumbent's binding rows (a candidate's active set is
                # nearer the incumbent's than the box's relaxation's: 62 -> 39 active-set steps
                # per one-vehicle overtake plan, 173 -> 136 with three vehicles)
                cand = self._qp_solve(qp, _spec(box.orders, tau_c, tau_c), best if best is not None else box.relaxed)
                if cand.status == st.OPTIMAL:
                    if best is None or cand.cost < best.cost:
                        best, best_tau = cand, tau
                    pieces = [piece_of(a, b, qp.h, qp.N) for a, b in zip(box_lo, box_hi)]
                    same = all(k == piece_of(t, t, qp.h, qp.N) for k, t in zip(pieces, tau_c))
                    # the candidate's piece polynomial joins the store (built when first needed)
                    store.add(cand)
                    if same:
                        dp: DualPolynomial | None = store.piece(cand)
                    elif box.own_relaxation and all(k is None for k in pieces):
                        # no vehicle's interval lies in one piece: the box's polynomial would keep only
                        # rows that the box's own relaxation imposes (each half-plane's full pieces
                        # outside the box, the limit rows), so by weak duality its bound cannot
                        # exceed that relaxation's optimum, which the box's bound already holds
                        dp = None
                    else:
                        dp = dual.polynomial(cand, box.lo, box.hi)
                    if dp is None:
                        binds = list(dual.binds(cand))
                    else:
                        binds = list(dp.binds)
                        if dp.vehicles:
                            # dp joins the box's polynomials, whose largest bound on the box
                            # (bound_of, below) counts dp's own, the same number as dp.lower_bound
                            # (a NaN counts in neither): one Bernstein bound of dp on the box, not two
                            box.duals = (box.duals + (dp,))[-self.DUALS_KEPT:]
                        else:
                            bound = max(bound, dp.lower_bound(box.lo, box.hi))
                    poly_bound, polys = bound_of(box.orders, box.lo, box.hi, box.duals)
                    bound = max(bound, poly_bound)
                elif cand.status != st.INFEASIBLE:
                    failures.append(cand.status)
            U = best.cost if best is not None else np.inf
            if bound >= U - gap(U):
                closed_bound = min(closed_bound, bound)
                continue  # the box is closed: no crossing in it is cheaper than U by more than the gap
            # branch on the vehicle whose constraint the relaxed optimum breaks most (a vehicle it
            # keeps gains nothing from a split); else the widest vehicle that binds at the candidate;
            # else the widest box (numpy.argmin's and argmax's first index of the extreme)
            i = -1
            if box.own_relaxation:
                margins = margin.tolist()
                for j in range(m):
                    if margins[j] < 0 and wide[j] and (i < 0 or margins[j] < margins[i]):
                        i = j
            if i < 0:
                for j in range(m):
                    if binds[j] and wide[j] and (i < 0 or widths[j] > widths[i]):
                        i = j
            if i < 0:
                i = widths.index(max(widths))
            if not wide[i]:
                continue  # a point: its bound is J(τ) itself
            solved = cand is not None and cand.status == st.OPTIMAL
            cuts = self._cuts(qp, box_lo[i], box_hi[i], tau_c[i] if solved else None, solved and cand is best)
            ref = cand if cand is not None and solved else box.relaxed
            edges = [box_lo[i]] + cuts + [box_hi[i]]
            for lo_i, hi_i in zip(edges[:-1], edges[1:]):
                lo_c, hi_c = box_lo.copy(), box_hi.copy()
                lo_c[i], hi_c[i] = lo_i, hi_i
                lo, hi = np.array(lo_c), np.array(hi_c)
                child_poly, child_polys = bound_of(box.orders, lo, hi, box.duals)
                child = max(bound, child_poly)
                stored = len(store)
                n_boxes += 1
                if child >= U - gap(U):
                    closed_bound = min(closed_bound, child)
                    continue
                if (cand is None or solved) and piece_of(lo_i, hi_i, qp.h, qp.N) is not None:
                    # within one piece: its candidate's dual polynomial will bound it (no
                    # relaxation; a box whose candidate is infeasible is bounded, or pruned, by
                    # its relaxation)
                    heapq.heappush(heap, _Box(child, next(serial), box.orders, lo, hi, ref, False, box.duals,
                                              child_polys, stored))
                    continue
                rel_spec = _spec(box.orders, lo_c, hi_c)
                # the parent's relaxed optimum, when it keeps the child's rows, is the child's
                inherited = qp.inherit(rel_spec, box.relaxed) \
                    if box.own_relaxation and rel_spec not in qp.solved else None
                if inherited is not None:
                    qp.solved[rel_spec] = inherited
                rel = self._qp_solve(qp, rel_spec, box.relaxed, cutoff=U - gap(U) if math.isfinite(U) else None)
                if rel.status == CUTOFF:  # its bound passed U - gap before its optimum: closed
                    closed_bound = min(closed_bound, max(child, rel.cost))
                elif rel.status == st.OPTIMAL:
                    child = max(child, rel.cost)
                    if child < U - gap(U):
                        heapq.heappush(heap, _Box(child, next(serial), box.orders, lo, hi, rel, True, box.duals,
                                                  child_polys, stored))
                    else:
                        closed_bound = min(closed_bound, child)
                elif rel.status != st.INFEASIBLE:
                    failures.append(rel.status)
                    # an unsolved relaxation cannot prune: keep the box with its parent's bound
                    heapq.heappush(heap, _Box(child, next(serial), box.orders, lo, hi, ref, False, box.duals,
                                              child_polys, stored))
        if best is not None and best.cost > min(closed_bound, heap[0].bound if heap else np.inf) + 1e-12 * max(
                1.0, best.cost):
            best, best_tau = self._polish_starts(qp, store, best, best_tau, gap(best.cost))
        U = best.cost if best is not None else np.inf
        open_bound = heap[0].bound if heap else np.inf
        lower = min(U, open_bound, closed_bound)
        closed = not heap or open_bound >= U - gap(U)
        return {"best": best, "tau": best_tau, "lower_bound": float(lower), "upper_bound": float(U),
                "closed": bool(closed and best is not None), "n_boxes": n_boxes, "open_boxes": len(heap),
                "failures": failures, "free": free, "free_certified": False}

    def _free_certified(self, qp: ContinuousAvoidQP, box: _Box) -> tuple[Solved, FloatArray] | None:
        """The search's first step, when it certifies the relaxed optimum (``box``: the first root
        box, the relaxation of every crossing time): the candidate at the crossing times where the
        relaxed optimum best keeps its half-planes (:meth:`_candidate_tau`), solved warm from the
        relaxation as the search solves it; if it costs no more than the relaxation (to round-off,
        ``1e-12`` relative), the relaxation's optimum keeps every Bernstein and limit row of that
        candidate, so it is the global optimum over every crossing time (lower bound attained: the
        search would close every box at once and not polish).  Returns that candidate and its
        crossing times, else None (the search goes on; the candidate stays solved in
        :attr:`ContinuousAvoidQP.solved`)."""
        free = box.relaxed
        tau, margin = self._candidate_tau(qp, box)
        if free.status != st.OPTIMAL or np.any(margin < 0):
            return None  # the relaxed optimum breaks a vehicle's half-planes at every crossing time
        cand = self._qp_solve(qp, _spec(box.orders, tau, tau), free)
        if cand.status == st.OPTIMAL and cand.cost <= free.cost + 1e-12 * max(1.0, abs(free.cost)):
            return cand, tau
        return None

    @staticmethod
    def _clip(x: float, lo: float, hi: float) -> float:
        """``numpy.clip(x, lo, hi)`` of floats, its numbers without its array set-up: a NaN of any of
        them propagated, else ``lo`` where ``lo > x``, then ``hi`` where ``hi`` is below that (of equal
        numbers, e.g. ``-0.0`` and ``0.0``, ``x`` kept; ``hi`` where ``lo > hi``)."""
        for v in (x, lo, hi):
            if v != v:
                return v
        y = lo if lo > x else x
        return hi if hi < y else y

    def _polish(self, qp: ContinuousAvoidQP, store: DualStore, best: Solved, tau: FloatArray
                ) -> tuple[Solved, FloatArray]:
        """Per vehicle, a secant search for a zero of ``∂J/∂τ_i`` within one grid step of the
        best ``τ`` (the others fixed), the slope of each solved candidate read off its dual
        polynomial (:meth:`~iamp.planners.avoid.dual.DualPolynomial.slope`); at most
        :attr:`POLISH_STEPS` solves per vehicle, none for a vehicle whose rows do not bind.  With
        several vehicles (:attr:`POLISH_PROBES` secant steps each), then a quasi-Newton (BFGS)
        search on the joint gradient from those curvatures (the crossings of binding vehicles
        move together).  It only lowers the upper bound, so the search's certificate stands."""
        orders = [(f, s) for f, s, _, _ in best.spec]
        tau = tau.copy()
        start = tau.copy()
        lo_all, hi_all = np.maximum(0.0, start - qp.h), np.minimum(qp.tf, start + qp.h)
        curvature = np.zeros(tau.size)
        for i in range(len(tau)):
            t, sol = tau.copy(), best
            prev: tuple[float, float] | None = None
            for _ in range(self.POLISH_STEPS if len(tau) == 1 else self.POLISH_PROBES):
                slope = self._gradient(store, sol, t)[i]
                if prev is None:
                    # a Newton step on the curvature of the candidate's piece polynomial where it
                    # is J's (multipliers on their tangent), else a first probe; then secant steps
                    dp = store.near(sol) if len(tau) == 1 else None
                    c = dp.curvature(t, i) if dp is not None and dp.second_order else 0.0
                    step = -slope / c if c > 0 else -np.sign(slope) * 1e-3 * qp.h
                else:
                    ds = slope - prev[1]
                    step = -slope * (t[i] - prev[0]) / ds if ds != 0.0 else 0.0
                    if t[i] != prev[0]:
                        curvature[i] = ds / (t[i] - prev[0])
                    if curvature[i] > 0 and 0.5 * abs(slope * step) <= self.POLISH_TOL_REL * max(1.0, abs(best.cost)):
                        break  # the secant model's decrease is below the QPs' own accuracy
                prev = (float(t[i]), slope)
                x = self._clip(float(t[i] + step), float(lo_all[i]), float(hi_all[i]))
                if not abs(x - t[i]) > 1e-9 * qp.tf:
                    break
                nxt = t.copy()
                nxt[i] = x
                r = self._qp_solve(qp, _spec(orders, nxt, nxt), sol)
                if r.status != st.OPTIMAL:
                    break
                t, sol = nxt, r
                if r.cost < best.cost:
                    best, tau = r, nxt.copy()
        active = curvature > 0
        if active.sum() < 2:
            return best, tau
        H = np.diag(np.where(active, 1.0 / np.where(active, curvature, 1.0), 0.0))  # inverse Hessian
        g = self._gradient(store, best, tau) * active
        for _ in range(self.POLISH_STEPS):
            trial = np.clip(tau - H @ g, lo_all, hi_all)
            if not np.max(np.abs(trial - tau)) > 1e-9 * qp.tf:
                break
            r = self._qp_solve(qp, _spec(orders, trial, trial), best)
            if r.status != st.OPTIMAL:
                break
            g_new = self._gradient(store, r, trial) * active
            sv, yv = trial - tau, g_new - g
            if sv @ yv > 0:  # BFGS update of the inverse Hessian
                rho = 1.0 / float(sv @ yv)
                V = np.eye(tau.size) - rho * np.outer(sv, yv)
                H = V @ H @ V.T + rho * np.outer(sv, sv)
            if r.cost < best.cost:
                best, tau, g = r, trial, g_new
        return best, tau

    def _polish_starts(self, qp: ContinuousAvoidQP, store: DualStore, best: Solved, tau: FloatArray,
                       within: float) -> tuple[Solved, FloatArray]:
        """:meth:`_polish` from the best candidate and from the best candidate of each other
        combination of grid pieces (and orders) whose cost is within ``within`` of it (at most
        :attr:`POLISH_STARTS` starts): the search closes to its gap, and a crossing within the
        gap may lie in another piece than the incumbent's, where the secant search from the
        incumbent cannot reach; the lowest result is kept."""
        starts: dict[tuple[object, ...], Solved] = {}
        for spec, sol in qp.solved.items():
            if sol.status != st.OPTIMAL or sol.cost > best.cost + within or any(a != b for _, _, a, b in spec):
                continue
            key = tuple((f, s, piece_of(a, a, qp.h, qp.N)) for f, s, a, _ in spec)
            if key not in starts or sol.cost < starts[key].cost:
                starts[key] = sol
        ranked = sorted(starts.values(), key=lambda r: r.cost)[:self.POLISH_STARTS]
        out, out_tau = self._polish(qp, store, best, tau)
        for sol in ranked:
            if sol.spec == best.spec:
                continue
            r, t = self._polish(qp, store, sol, np.array([a for _, _, a, _ in sol.spec], dtype=float))
            if r.cost < out.cost:
                out, out_tau = r, t
        return out, out_tau

    def _gradient(self, store: DualStore, sol: Solved, tau: FloatArray) -> FloatArray:
        """``∂J/∂τ`` at the candidate ``sol`` (crossing times ``tau``): the slope of its piece
        polynomial at ``tau``, by the envelope theorem (:meth:`~iamp.planners.avoid.dual.DualBounds.gradient`;
        ``tests/test_avoid_dual.py`` checks it against :meth:`~iamp.planners.avoid.dual.DualPolynomial.slope`)."""
        return store.dual.gradient(sol)

    def plan(self, problem: Problem) -> Plan:
        """Search the crossing times, solve, verify (module docstring)."""
        start = time.perf_counter()
        N = int(self.steps)
        if N < 2:
            from iamp.core.errors import ScenarioError

            raise ScenarioError(f"must be at least 2 (got {N})", "--steps")
        orders, reason = crossing_orders(problem)
        common: dict[str, Any] = {"solver": self.solver, "hold": self.hold, "steps": N}
        if reason is not None:
            return failed_plan(problem, st.INFEASIBLE, reason, start, **common,
                               info={"safety_mode": "continuous"})
        qp = ContinuousAvoidQP(problem, N, self.hold, self.solver, self.solver_settings, self.row_generation,
                               self.node_solver, self.limits_between, self.shared)
        try:
            return self._searched(problem, qp, orders, common, start)
        finally:
            # each QP the search kept (``qp.solved``) refers back to ``qp`` (:attr:`Solved.qp`):
            # without this cycle the plan's QPs, their rows and the backend are freed by reference
            # counting when the plan returns, not by the cyclic garbage collector (some 120
            # objects a plan, sparse matrices among them: its passes took a few per cent of a
            # one-vehicle plan's CPU time, tests/test_avoid_no_cycles.py)
            qp.solved.clear()

    def _searched(self, problem: Problem, qp: ContinuousAvoidQP, orders: list[list[tuple[int, int]]],
                  common: dict[str, Any], start: float) -> Plan:
        """:meth:`plan` from its QP ``qp`` on: search the crossing times (``orders``: each vehicle's
        possible orders), then verify the best candidate (:meth:`_verified`) or say why there is none
        (``common``: the failed plan's solver, hold and steps; ``start``: the plan's start time)."""
        out = self.search(qp, orders)
        info: dict[str, Any] = {"constraint": "avoid", "safety_mode": "continuous", "n_solves": qp.n_solves}
        search = {"method": "branch and bound over crossing-time boxes (bounds: each box's half-planes outside "
                            "the box only; weak duality with each candidate's multipliers)",
                  "n_solves": qp.n_solves, "boxes": out["n_boxes"],
                  "open_boxes": out["open_boxes"], "lower_bound": out["lower_bound"],
                  "upper_bound": out["upper_bound"], "gap_rel_tol": self.gap_rel, "closed": out["closed"],
                  "max_solves": self.max_solves, "max_boxes": self.max_boxes, "failures": len(out["failures"]),
                  "free_certified": bool(out["free_certified"]),
                  "inherited_relaxations": qp.n_inherited}
        info["search"] = search
        best: Solved | None = out["best"]
        if best is None:
            free: Solved = out["free"]
            if free.status != st.INFEASIBLE and not out["failures"] and out["open_boxes"]:
                # no candidate solved, but boxes left open at the budget: infeasibility is not proved
                # (a box leaves the search without an incumbent only when its relaxation is infeasible)
                return failed_plan(problem, st.MAX_ITER,
                                   f"the crossing-time search stopped at its budget (max_solves {self.max_solves}, "
                                   f"max_boxes {self.max_boxes}) with {out['open_boxes']} boxes open before any "
                                   f"crossing time gave a feasible QP: infeasibility not proved", start, **common,
                                   info=info)
            if free.status == st.INFEASIBLE or not out["failures"]:
                why = ("no trajectory satisfies the boundary conditions and the bounds" if free.status == st.INFEASIBLE
                       else "no crossing time gives a feasible QP")
                certified = [k for k in ("vx_between", "y_between")
                             if qp.limit_rows is not None and k in qp.limit_rows.describe()]
                if certified and free.status == st.INFEASIBLE:
                    # the Bernstein rows are sufficient, not necessary: say what was proved
                    why += (f" on this grid of {qp.N} pieces, the {' and '.join(k.split('_')[0] for k in certified)} "
                            f"bound certified between the nodes (Bernstein rows: sufficient, not necessary)")
                return failed_plan(problem, st.INFEASIBLE, why, start, **common, info=info)
            return failed_plan(problem, out["failures"][0], "no crossing-time candidate solved", start, **common,
                               info=info)
        return self._verified(problem, qp, best, out["tau"], orders, out["closed"], info, start)

    def plan_at_times(self, problem: Problem, taus: Sequence[float]) -> Plan:
        """One QP with the crossing times ``taus`` (each vehicle's first order; no search)."""
        start = time.perf_counter()
        orders, reason = crossing_orders(problem)
        common: dict[str, Any] = {"solver": self.solver, "hold": self.hold, "steps": int(self.steps)}
        if reason is not None:
            return failed_plan(problem, st.INFEASIBLE, reason, start, **common)
        qp = ContinuousAvoidQP(problem, int(self.steps), self.hold, self.solver, self.solver_settings,
                               self.row_generation, self.node_solver, self.limits_between, self.shared)
        tau = np.asarray(taus, dtype=float)
        sol = qp.solve(_spec([o[0] for o in orders], tau, tau))
        info: dict[str, Any] = {"constraint": "avoid", "safety_mode": "continuous", "n_solves": 1,
                                "search": {"method": "fixed crossing times", "closed": False}}
        if sol.status != st.OPTIMAL:
            return failed_plan(problem, sol.status, "the QP did not solve", start, **common, info=info)
        return self._verified(problem, qp, sol, tau, [[o] for o in (s[:2] for s in sol.spec)], False, info, start)

    def _verified(self, problem: Problem, qp: ContinuousAvoidQP, sol: Solved, tau: FloatArray,
                  orders: list[list[tuple[int, int]]], closed: bool, info: dict[str, Any], start: float) -> Plan:
        d = qp.data
        n_eq = d.n_eq
        A_in, u_in, layout = sol.spec_rows()
        A = _stacked(qp.A_eq, A_in)
        u = np.concatenate((d.b_eq, u_in))
        l = np.concatenate((d.b_eq, np.full(A_in.shape[0], -np.inf)))
        # both KKT checks below; the node solver's copy was built from this P (or checked
        # against it bit for bit, :meth:`ContinuousAvoidQP._schur`)
        lower = qp.schur.P_lower if qp.schur is not None else sp.triu(sp.csc_matrix(d.P), 1).T
        check_kkt = KKTCheck(d.P, d.q, A, l, u, n_eq, lower)  # the node solver's point, then the backend's
        kkt = check_kkt(sol.z, sol.y)
        key = BACKENDS[self.solver].tolerance_key
        limit = tol(key)
        failed = [k for k, v in kkt.items() if v > limit]
        if qp.schur is not None:
            # the backend solves the final QP independently: its optimum must pass the same KKT
            # check and cost what the node solver's does, to the backend's comparison tolerance.
            # Where its own answer does not, it is refined on the rows it holds active (as OSQP
            # polishes) and the refined point is judged when it passes the KKT check: an interior
            # point's cost exceeds the optimum by its gap Σ y_i s_i (PIQP: up to 1e-8 absolute)
            # though each y_i s_i passes the check.  (An answer that passes is not refined: the
            # refinement, one LU of the KKT matrix, would only confirm it.)
            other = qp.backend_solve(sol)
            check: dict[str, Any] = {"status": other.status,
                                     "cost": float(other.cost) if np.isfinite(other.cost) else None}
            ok = other.status == st.OPTIMAL
            if ok:
                cost_tol = tol(key.replace("kkt", "cost"))

                def passes(r: Solved, r_kkt: dict[str, float]) -> bool:
                    return bool(max(r_kkt.values()) <= limit
                                and abs(r.cost - sol.cost) <= cost_tol * max(1.0, abs(sol.cost)))

                other_kkt = check_kkt(other.z, other.y)
                ok = passes(other, other_kkt)
                check["polished"] = False
                if not ok:
                    polished = qp.polish(other)
                    polished_kkt = check_kkt(polished.z, polished.y) if polished is not None else None
                    if polished is not None and polished_kkt is not None and max(polished_kkt.values()) <= limit:
                        check.update(polished=True, backend_cost=check["cost"], backend_kkt=other_kkt,
                                     cost=float(polished.cost))
                        other, other_kkt = polished, polished_kkt
                        ok = passes(other, other_kkt)
                check.update(kkt=other_kkt, cost_tol_rel=cost_tol)
            check["agrees"] = bool(ok)
            info["backend_check"] = check
            if not ok:
                failed.append("backend_check")
        info["n_solves"] = qp.n_solves
        if isinstance(info.get("search"), dict) and "n_solves" in info["search"]:
            info["search"]["n_solves"] = qp.n_solves
        info["node_solver"] = {"name": qp.node_solver, "backend_solves": qp.n_backend_solves}
        traj = qp.trajectory(sol.z)
        cost = traj.cost()
        slack = u_in - matvec(A_in, sol.z)
        y_in = sol.y[n_eq:]
        jumps = np.zeros((problem.m, 2))
        vehicles: list[dict[str, Any]] = []
        binding: dict[tuple[int, int], int] = {}
        block = layout // (qp.N * (qp.degree + 1))  # 2 i + a of a Bernstein row; limit rows beyond
        for i in range(problem.m):
            for plane in (0, 1):
                rows = block == 2 * i + plane
                jumps[i, plane] = float(d.planes[i][plane].sigma * np.sum(y_in[rows]))
                binding[(i, plane)] = int(np.sum(slack[rows] <= ACTIVE_SLACK_M))
        for i, (v, (f, s, _, _)) in enumerate(zip(problem.vehicles, sol.spec)):
            planes = d.planes[i]
            vehicles.append({"name": v.name, "first": AXIS_NAMES[f], "second": AXIS_NAMES[s],
                             "first_half_plane": planes[f].describe(), "second_half_plane": planes[s].describe(),
                             "crossing_time": float(tau[i]),
                             "leave_time": float(leave_time(traj, planes[f], problem.tf)),
                             "binding_rows": {AXIS_NAMES[a]: binding.get((i, a), 0) for a in (0, 1)},
                             "multiplier_sums": [float(jumps[i, 0]), float(jumps[i, 1])]})
        if qp.limit_rows is not None:
            info["limit_rows"] = qp.limit_rows.describe()
            info["limits_between"] = qp.limit_rows.between
        if failed:
            status = st.INACCURATE
        else:
            status = st.OPTIMAL if closed else st.LOCAL
        plan = Plan(problem=problem, planner="qp", status=status, cost=cost if status in st.SUCCESS else None,
                    contact_times=np.asarray(tau, dtype=float), jumps=jumps, trajectory=traj,
                    solve_time_s=0.0, solver=self.solver, hold=self.hold, steps=int(self.steps))
        safety = plan.safety
        intrusion = max((vs.max_intrusion_m for vs in safety.vehicles), default=0.0) if safety is not None else 0.0
        if safety is not None and not safety.intrusion_free:
            failed.append("intrusion")
            plan.status, plan.cost = st.INACCURATE, None
        for entry, vs in zip(vehicles, safety.vehicles if safety is not None else ()):
            entry["max_intrusion_m"] = vs.max_intrusion_m
        plan.residuals = {"boundary": plan.boundary_residual(), **kkt}
        info.update(kkt=kkt, kkt_tol=limit, failed_checks=failed, solver_iterations=sol.iterations)
        if failed:
            info["failed_check"] = failed[0]
        info["avoidance"] = {"constraint": "avoid", "safety": "continuous", "search": info["search"],
                             "complete_sweep": bool(closed), "n_solves": info["n_solves"], "vehicles": vehicles,
                             "max_intrusion_m": float(intrusion), "kkt": kkt, "kkt_tol": limit,
                             "failed_checks": failed, "node_solver": info["node_solver"]}
        if "backend_check" in info:
            info["avoidance"]["backend_check"] = info["backend_check"]
        plan.diagnostics = AvoidDiagnostics.from_info(info)
        plan.solve_time_s = time.perf_counter() - start
        return plan


def summary_lines(plan: Plan) -> list[str]:
    """The text summary of a continuous-time avoidance plan."""
    diag = plan.diagnostics
    av: Any = (diag.avoidance if isinstance(diag, AvoidDiagnostics) else None) or {}
    sr = av.get("search", {})
    out = [f"cost J    {plan.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]",
           f"time      {plan.solve_time_s * 1e3:.3f} ms ({av.get('n_solves')} QPs; branch and bound over crossing "
           f"times, {'closed: global' if sr.get('closed') else 'stopped at its budget: local'}, "
           f"lower bound {sr.get('lower_bound', float('nan')):.9g})",
           "safety    continuous: every FOH/ZOH piece certified by its Bernstein coefficients"]
    for v in av.get("vehicles", []):
        out.append(f"vehicle {v['name']}: in {v['first']} until t = {v['crossing_time']:.6f} s, then in "
                   f"{v['second']} (binding rows {v['binding_rows']}, multiplier sums "
                   f"({v['multiplier_sums'][0]:.6g}, {v['multiplier_sums'][1]:.6g}))")
    return out + residual_and_safety_lines(plan, av)
