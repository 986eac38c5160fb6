r"""Clarabel (interior point, homogeneous embedding; no warm start).

Set up once and re-used through its data-update API (``solver.update(P=…, A=(idx, v),
b=…)``, checked with ``is_data_update_allowed()``; if a version refuses, the backend
rebuilds the solver and says so in :attr:`ClarabelBackend.data_update`).  The general form
``l ≤ Az ≤ u`` becomes Clarabel's cones: equality rows (``l = u``) a zero cone on
``Az = l``; the other rows ``Az ≤ u`` and ``−Az ≤ −l`` (finite sides only) nonnegative
cones.  The row split is fixed at set-up (a change of which rows are equalities rebuilds
the solver); the multipliers are mapped back to OSQP's sign convention
(``y_i = z_upper − z_lower``).

Settings (:func:`default`): gap and feasibility tolerances 1e-12, ``max_iter = 200``.  When
every row is an equality, :func:`equality_settings` are added (unless given explicitly):
``static_regularization_enable = False``.  The equality QP is solved at Clarabel's initial
point or after one iteration (its initial point, computed from one factorisation of the KKT
matrix, already meets the tolerances); what a candidate costs is that factorisation and its
iterative refinement.
With the static regularisation (1e-8 on the diagonal) the refinement needs several solves
to remove it; without it the factorisation is of the exact quasi-definite KKT matrix (the
dynamic regularisation still guards tiny pivots).  Measured on ``paper-1-poly``, FOH,
``N = 100``, all 99 candidates per row, rows interleaved over three rounds on the shared
2-core machine, Clarabel 0.11.1 (update + solve per candidate; verified = recomputed KKT
within ``cmp_kkt_rel_clarabel`` = 1e-9):

=============================================  ========  ==========  =========  =======
settings (besides :func:`default`)             verified  iterations  max KKT    time
=============================================  ========  ==========  =========  =======
static regularisation on (before)              99        1           5.0e-13    346 µs
**static regularisation off (default now)**    99        0 (≤ 1)     1.7e-13    237 µs
… and ``equilibrate_enable`` off               99        0 (≤ 1)     1.7e-13    233 µs
… and ``presolve_enable`` off                  99        0 (≤ 1)     1.7e-13    267 µs
… and ``direct_solve_method`` qdldl / faer     99        0 (≤ 1)     1.7e-13    278 / ~400 µs
``static_regularization_constant`` 1e-12       99        0 (≤ 7)     4.7e-13    429 µs
``iterative_refinement_enable`` off            99        4 (≤ 5)     4.9e-13    739 µs
=============================================  ========  ==========  =========  =======

(Equilibration off gains nothing measurable and is kept on.)  Over 600 random candidates
(``random_problem``, FOH and ZOH, ``N`` 10–100, one and two vehicles, on and off the grid)
both settings verify every one (worst 4.9e-13).  Problems with inequalities keep
:func:`default` alone.

Status mapping: ``Solved`` → OPTIMAL; ``AlmostSolved`` → INACCURATE;
``(Almost)PrimalInfeasible`` → INFEASIBLE; ``MaxIterations`` → MAX_ITER; ``MaxTime`` →
TIME_LIMIT; ``NumericalError``, ``InsufficientProgress`` → NUMERICAL_ERROR; anything else
→ SOLVER_ERROR.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp

from iamp.core import status as st

from .base import IntArray, QPBackend, QPSolution

CLARABEL_STATUS: dict[str, str] = {
    "Solved": st.OPTIMAL,
    "AlmostSolved": st.INACCURATE,
    "PrimalInfeasible": st.INFEASIBLE,
    "AlmostPrimalInfeasible": st.INFEASIBLE,
    "DualInfeasible": st.SOLVER_ERROR,
    "AlmostDualInfeasible": st.SOLVER_ERROR,
    "MaxIterations": st.MAX_ITER,
    "MaxTime": st.TIME_LIMIT,
    "NumericalError": st.NUMERICAL_ERROR,
    "InsufficientProgress": st.NUMERICAL_ERROR,
    "CallbackTerminated": st.SOLVER_ERROR,
    "Unsolved": st.SOLVER_ERROR,
}


def map_status(raw: str) -> str:
    """Clarabel's status name → the iamp vocabulary (unknown names → SOLVER_ERROR)."""
    return CLARABEL_STATUS.get(raw.strip(), st.SOLVER_ERROR)


def default(tol: float = 1e-12) -> dict[str, Any]:
    """Clarabel: gap and feasibility tolerances tightened to ``tol``."""
    return {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol, "tol_ktratio": 1e-10,
            "max_iter": 200, "verbose": False}


def equality_settings() -> dict[str, Any]:
    """Added to :func:`default` when every row is an equality (module docstring)."""
    return {"static_regularization_enable": False}


class ClarabelBackend(QPBackend):
    """Clarabel behind :class:`~iamp.planners.qp.backends.base.QPBackend`."""

    name: ClassVar[str] = "clarabel"
    distribution: ClassVar[str] = "clarabel"
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_clarabel"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return default()

    def _make_settings(self) -> Any:
        import clarabel

        settings = self._apply_settings(self._pure_eq, equality_settings())  # no static regularisation
        s = clarabel.DefaultSettings()
        for k, v in settings.items():
            setattr(s, k, v)
        return s

    def _split(self) -> None:
        """Rows of Clarabel's stacked matrix: equalities, then upper sides, then lower."""
        eq = self.l == self.u
        self._eq = np.flatnonzero(eq)
        self._up = np.flatnonzero(~eq & np.isfinite(self.u))
        self._lo = np.flatnonzero(~eq & np.isfinite(self.l))
        self._pure_eq = bool(eq.all())  # a free row (both sides infinite) is no equality

    def _stack(self) -> tuple[sp.csc_matrix, np.ndarray]:
        if self._pure_eq:
            return self.A, self.l.copy()
        A = sp.vstack([self.A[self._eq], self.A[self._up], -self.A[self._lo]], format="csc")
        return A, self._rhs()

    def _rhs(self) -> np.ndarray:
        """Clarabel's ``b`` of the current bounds (the row split of set-up; no re-stacking of ``A``,
        so a bound-only update of a sweep costs a vector, not a matrix)."""
        if self._pure_eq:
            return self.l.copy()
        return np.concatenate([self.l[self._eq], self.u[self._up], -self.l[self._lo]])

    def _split_changed(self) -> bool:
        """Did the bounds change which rows are equalities or which sides are finite?"""
        eq = self.l == self.u
        return not (np.array_equal(np.flatnonzero(eq), self._eq)
                    and np.array_equal(np.flatnonzero(~eq & np.isfinite(self.u)), self._up)
                    and np.array_equal(np.flatnonzero(~eq & np.isfinite(self.l)), self._lo))

    def _stacked(self) -> tuple[sp.csc_matrix, np.ndarray]:
        """Clarabel's ``A`` and ``b`` of the current row split (:meth:`_split`); besides a pure
        equality problem, also where each entry of the stacked matrix comes from in ``A.data``
        and its sign (``_perm``, ``_sign``): a value update gathers them instead of stacking
        slices of ``A`` again.

        When the split keeps every row in place (the equalities first, then upper sides only,
        as the avoidance QP's rows are), the stacked pattern is ``A``'s own: it is taken without
        slicing (the same arrays as the slices' stack, ``tests/test_clarabel_stack.py``)."""
        if self._pure_eq:
            return self._stack()
        A = self.A
        m = A.shape[0]
        if (self._lo.size == 0 and self._eq.size + self._up.size == m and A.has_canonical_format
                and np.array_equal(np.concatenate([self._eq, self._up]), np.arange(m))):
            self._perm = np.arange(A.nnz, dtype=np.int64)
            self._sign = np.ones(A.nnz)
            # A itself, as a pure equality problem passes it (Clarabel copies what it is given):
            # the stack's arrays, A.data[perm] * 1.0 being A.data
            return A, self._rhs()
        tag = sp.csc_matrix((np.arange(1.0, A.nnz + 1.0), A.indices, A.indptr), shape=A.shape)
        T = sp.vstack([tag[self._eq], tag[self._up], -tag[self._lo]], format="csc")
        self._perm = np.abs(T.data).astype(np.int64) - 1
        self._sign = np.sign(T.data)
        out = sp.csc_matrix((A.data[self._perm] * self._sign, T.indices, T.indptr), shape=T.shape)
        return out, self._rhs()

    def _build(self) -> None:
        import clarabel

        self._split()
        A, b = self._stacked()
        cones = []
        if self._eq.size:
            cones.append(clarabel.ZeroConeT(int(self._eq.size)))
        if self._up.size + self._lo.size:
            cones.append(clarabel.NonnegativeConeT(int(self._up.size + self._lo.size)))
        self.solver = clarabel.DefaultSolver(self.P, self.q, A, b, cones, self._make_settings())
        self.data_update = bool(self.solver.is_data_update_allowed())

    def _setup(self) -> None:
        self._build()

    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        if bounds and self._split_changed():
            self._build()  # the row split changed
            return
        if not self.data_update:
            self._build()
            return
        kw: dict[str, Any] = {}
        if P:
            kw["P"] = self.P.data.copy()
        if self._pure_eq:
            if A:
                if A_idx is None:
                    kw["A"] = self.A.data.copy()
                elif A_idx.size:
                    kw["A"] = (A_idx, self.A.data[A_idx].copy())
            if bounds:
                kw["b"] = self.l.copy()
        else:
            if A:
                kw["A"] = self.A.data[self._perm] * self._sign
            if bounds:
                kw["b"] = self._rhs()
        if q:
            kw["q"] = self.q.copy()
        if kw:
            self.solver.update(**kw)

    def solve(self) -> QPSolution:
        t0 = time.perf_counter()
        sol = self.solver.solve()
        call = time.perf_counter() - t0
        raw = str(sol.status)
        z = np.array(sol.x, dtype=float)
        w = np.array(sol.z, dtype=float)
        if self._pure_eq:
            y = w
        else:
            y = np.zeros(self.l.size)
            ne, nu = self._eq.size, self._up.size
            y[self._eq] = w[:ne]
            y[self._up] += w[ne:ne + nu]
            y[self._lo] -= w[ne + nu:]
        status = map_status(raw)
        return QPSolution(z=z, y=y, status=status, raw_status=raw, iterations=int(sol.iterations),
                          solver_time_s=float(sol.solve_time), solve_call_s=call,
                          certificate=y.copy() if status == st.INFEASIBLE else None)
