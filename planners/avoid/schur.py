r"""The avoidance QP's own exact node solver: a dual active-set method on one factored KKT matrix.

Every QP of the crossing-time search (:mod:`iamp.planners.avoid.continuous`) has the same
cost and equality rows — the dynamics and boundary rows of one grid — and differs only in a
few hundred one-sided rows ``G z <= u`` (Bernstein rows of the half-planes, the limit rows), of
which a handful bind.  With

.. math::  K = \begin{pmatrix} P & E^\top \\ E & 0 \end{pmatrix}, \qquad
           K \begin{pmatrix} z_0 \\ \nu_0 \end{pmatrix} = \begin{pmatrix} 0 \\ b \end{pmatrix},
           \qquad K \begin{pmatrix} w_r \\ \cdot \end{pmatrix} = \begin{pmatrix} g_r \\ 0 \end{pmatrix},

factored once per grid (sparse LU; ``K`` is nonsingular: the inputs determine the states and
:math:`P` is positive definite on the inputs), the optimum with the rows ``W`` held as
equalities is :math:`z = z_0 - \sum_{r \in W} \lambda_r w_r` with
:math:`S \lambda = G_W z_0 - u_W`, :math:`S = G_W [w_r]` (a small dense Schur complement).

:class:`SchurActiveSet` is the dual active-set method of Goldfarb and Idnani on these
quantities: it starts from a dual-feasible point (the equality optimum ``z_0``, or a warm start
from a nearby solution's binding rows held as equalities, every negative multiplier dropped), adds the most
violated row, steps along the primal-dual direction until that row binds or a multiplier of
the working set reaches zero (that row leaves), and stops when no row is violated by more than
:data:`~iamp.planners.avoid.solve.GENERATION_TOL`.  Each step keeps the multipliers
nonnegative, so the result satisfies the KKT conditions of the whole QP: stationarity and the
equality rows to the LU's round-off, every row feasible to the tolerance, complementarity
exactly (a row outside ``W`` has zero multiplier, a row in ``W`` holds with equality).  A row
that is linearly dependent on the working set takes a pure dual step; if no multiplier blocks
it, the QP is infeasible (the step is a dual ray; declared only for a clearly dependent row,
:data:`INFEASIBLE_REL`).  The sparse solves are one column of ``K⁻¹`` per node variable a row
touches, once per grid (``w_r`` is their combination), and one final ``K`` solve per QP for the
equality multipliers.

Every returned optimum is checked against its KKT residuals recomputed from the data
(:meth:`SchurActiveSet.residual`, :data:`CHECK_TOL`); a solve that fails the check, meets an
ill-conditioned step or exhausts its step budget (``max_iter``, a count of work) reports so, and
the search solves that QP by the backend instead.  With a ``cutoff`` the solve may stop early:
the cost of every working set's optimum is a lower bound of the QP's optimum and only grows.

The loop and the residual are written once, in :mod:`~iamp.planners.avoid.schur_kernel` (plain
loops over the rows' CSR arrays, no BLAS), and run compiled by numba where it is installed, as
Python otherwise: the same numbers either way.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from iamp.core import status as st
from iamp.planners.pmp import jit

from . import schur_kernel as kernel
from .solve import GENERATION_TOL, RowsSolution

FloatArray = NDArray[np.float64]

__all__ = ["CHECK_TOL", "CUTOFF", "DEPENDENT_REL", "INFEASIBLE_REL", "SchurActiveSet", "full_hessian", "kkt_matrix"]

#: A row whose Schur complement on the working set is below this times ``g_r·w_r`` is treated as
#: linearly dependent on the working set (a pure dual step).
DEPENDENT_REL = 1e-9
#: ... and is declared to prove the QP infeasible (no multiplier of the working set blocks the
#: dual step) only when its Schur complement is below this; between the two the solve stops
#: with ``numerical_error`` (and the search solves that QP by the backend).
INFEASIBLE_REL = 1e-13


#: The status of a solve stopped at its cutoff (:meth:`SchurActiveSet.solve`): the QP's optimum
#: is at least the reported ``bound`` (internal to the search, never a plan's status).
CUTOFF = "cutoff"

#: A warm start whose working rows' Schur complement is not positive definite, or whose squared
#: Cholesky pivots spread by more than this factor (a lower bound of its condition number), is
#: dropped (the solve starts from the equality optimum).
WARM_COND = 1e10

#: The largest KKT residual (:meth:`SchurActiveSet.residual`) of a solution reported ``optimal``;
#: beyond it the solve reports ``numerical_error`` (and the search solves that QP by the backend).
CHECK_TOL = 1e-7


#: The node solver's statuses by :mod:`~iamp.planners.avoid.schur_kernel`'s codes.
_STATUS = {kernel.OPTIMAL: st.OPTIMAL, kernel.INFEASIBLE: st.INFEASIBLE, kernel.NUMERICAL_ERROR: st.NUMERICAL_ERROR,
           kernel.MAX_ITER: st.MAX_ITER, kernel.CUTOFF: CUTOFF}
#: Run the kernel as Python (numba absent): the same numbers, bit for bit, more slowly.
_PYTHON = not jit.available()
_TWINS: dict[tuple[str, str], Any] = {}


def _run(name: str, module: Any = kernel) -> Any:
    """The kernel ``name`` of ``module`` (:mod:`~iamp.planners.avoid.schur_kernel`, or
    :mod:`~iamp.planners.avoid.search_kernel`: modules whose compilable functions call none outside
    their own file), compiled by numba when available (else the Python function itself: the same
    numbers)."""
    fn = getattr(module, name)
    if _PYTHON:
        return fn
    key = (module.__name__, name)
    if key not in _TWINS:
        _TWINS[key] = jit.twin(fn, cache=True)
    return _TWINS[key]


#: A CSR matrix's ``indptr`` and ``indices`` (int64) and ``data`` (float), as the kernels take them.
CsrArrays = tuple[NDArray[np.int64], NDArray[np.int64], FloatArray]


def csr_arrays(A: sp.spmatrix) -> CsrArrays:
    """``A``'s CSR arrays as the kernels take them (:data:`CsrArrays`)."""
    A = A if isinstance(A, sp.csr_matrix) else sp.csr_matrix(A)
    return (np.asarray(A.indptr, dtype=np.int64), np.asarray(A.indices, dtype=np.int64),
            np.asarray(A.data, dtype=float))


def full_hessian(P: sp.spmatrix) -> sp.csc_matrix:
    """The symmetric ``P`` from its upper triangle."""
    P = sp.csc_matrix(P)
    return sp.csc_matrix(P + sp.triu(P, 1).T)


def kkt_matrix(P: sp.spmatrix, A_eq: sp.spmatrix, full: sp.spmatrix | None = None) -> sp.csc_matrix:
    """``[[P, E^T], [E, 0]]`` with ``P`` given as its upper triangle (``full``: the symmetric
    ``P`` when already built)."""
    full = full_hessian(P) if full is None else full
    return sp.csc_matrix(sp.bmat([[full, sp.csr_matrix(A_eq).T], [A_eq, None]], format="csc"))


class SchurActiveSet:
    r"""``min ½zᵀPz`` s.t. ``E z = b``, ``G z <= u`` by the dual active-set method (module docstring).

    Parameters
    ----------
    P : scipy.sparse matrix
        Upper triangle of the cost Hessian.
    A_eq : scipy.sparse matrix
        The equality rows ``E``.
    b_eq : ndarray
        Their right-hand side ``b``.
    max_iter : int
        Active-set steps per solve before it stops with ``max_iter_reached`` (a count of work).

    Attributes
    ----------
    lu : scipy.sparse.linalg.SuperLU
        The factored KKT matrix (shared with :class:`~iamp.planners.avoid.dual.DualBounds`).
    columns : int
        Columns of ``K⁻¹`` computed so far (one sparse triangular solve each).
    """

    def __init__(self, P: sp.spmatrix, A_eq: sp.spmatrix, b_eq: FloatArray, max_iter: int = 200) -> None:
        self.P = sp.csc_matrix(P)
        self.n = self.P.shape[0]
        self.b_eq = np.asarray(b_eq, dtype=float)
        self.n_eq = self.b_eq.size
        self.A_eq = sp.csr_matrix(A_eq)
        self.A_eq_T = sp.csr_matrix(self.A_eq.T)
        full = full_hessian(self.P)
        self.P_full = sp.csr_matrix(full)
        #: the symmetric ``P`` as CSC (:class:`~iamp.planners.avoid.dual.DualBounds`' products)
        self.P_full_csc = sp.csc_matrix(full)
        self._Pp = np.asarray(self.P_full.indptr, dtype=np.int64)
        self._Pi = np.asarray(self.P_full.indices, dtype=np.int64)
        self._Px = np.asarray(self.P_full.data, dtype=float)
        #: CSR arrays of ``E`` and ``Eᵀ`` (:meth:`residual`)
        self._csr = (np.asarray(self.A_eq.indptr, dtype=np.int64), np.asarray(self.A_eq.indices, dtype=np.int64),
                     np.asarray(self.A_eq.data, dtype=float))
        self._csr_T = (np.asarray(self.A_eq_T.indptr, dtype=np.int64),
                       np.asarray(self.A_eq_T.indices, dtype=np.int64), np.asarray(self.A_eq_T.data, dtype=float))
        #: ``triu(P, 1)ᵀ``, the strict lower part of ``P`` the final KKT checks use
        #: (:func:`~iamp.planners.avoid.check.kkt_conditions`; shared by the plans of one grid)
        self.P_lower = sp.triu(self.P, 1).T
        self.lu = spla.splu(kkt_matrix(self.P, A_eq, full))
        self.max_iter = int(max_iter)
        x0 = np.asarray(self.lu.solve(np.r_[np.zeros(self.n), self.b_eq]), dtype=float)
        #: the equality optimum and its multipliers (the final solve of a QP whose working set
        #: stays empty: the same solve with the same right-hand side)
        self._x0 = x0
        self.z0 = x0[:self.n].copy()
        #: row ``c``: the primal part of column ``c`` of ``K⁻¹`` once solved (:attr:`_have`)
        self._Kinv = np.zeros((self.n, self.n))
        self._have = np.zeros(self.n, dtype=bool)
        self.columns = 0

    def same_matrix(self, P: sp.spmatrix, A_eq: sp.spmatrix) -> bool:
        """Whether ``P`` (upper triangle) and ``A_eq`` are, bit for bit, the matrices this solver
        factored (then :meth:`with_rhs` may serve them)."""
        def same(a: sp.spmatrix, b: sp.spmatrix) -> bool:
            return (a.shape == b.shape and np.array_equal(a.indptr, b.indptr)
                    and np.array_equal(a.indices, b.indices) and np.array_equal(a.data, b.data))

        return same(self.P, sp.csc_matrix(P)) and same(self.A_eq, sp.csr_matrix(A_eq))

    def with_rhs(self, b_eq: FloatArray) -> SchurActiveSet:
        """The solver of the same ``P`` and ``E`` with the right-hand side ``b_eq``: it shares this
        one's factored KKT matrix and its solved columns of ``K⁻¹`` (which depend on ``P`` and
        ``E`` only; a column is the same bit for bit whichever batch solved it), so the plans of
        one grid factor it once (the closed loop plans the same horizon many times)."""
        out = copy.copy(self)
        out.b_eq = np.asarray(b_eq, dtype=float)
        if out.b_eq.shape != self.b_eq.shape:
            raise ValueError(f"b_eq has {out.b_eq.size} rows, the factored matrix {self.n_eq}")
        out._x0 = np.asarray(self.lu.solve(np.r_[np.zeros(self.n), out.b_eq]), dtype=float)
        out.z0 = out._x0[:self.n].copy()
        out.columns = 0
        return out

    def solve(self, A_in: sp.csr_matrix, u_in: FloatArray, start: NDArray[np.int64] | None = None,
              cutoff: float | None = None, arrays: CsrArrays | None = None) -> RowsSolution:
        """Solve with the inequality rows ``A_in z <= u_in``.

        Parameters
        ----------
        A_in : scipy.sparse.csr_matrix
            The inequality rows ``G``.
        u_in : ndarray
            Their bounds ``u``.
        start : ndarray of int, optional
            Rows of ``A_in`` that start the working set (warm start: a nearby solution's binding
            rows); without them the method starts from the equality optimum.
        cutoff : float, optional
            Stop with status :data:`CUTOFF` once the cost of the working set's optimum — a lower
            bound of the QP's optimum: it minimises the cost over the working rows alone, with
            nonnegative multipliers — reaches ``cutoff`` (an infeasible QP's bound grows without
            limit, so it stops there too).
        arrays : tuple, optional
            ``A_in``'s CSR arrays as the kernels take them (:func:`csr_arrays`), when the caller
            keeps them.

        Returns
        -------
        RowsSolution
            ``status`` ``optimal``, ``infeasible``, ``max_iter_reached`` or ``numerical_error``
            (a solution whose KKT residual exceeds :data:`CHECK_TOL`); ``y`` holds the
            equality rows' multipliers, then one per row of ``A_in`` (OSQP's convention
            ``Pz + Aᵀy = 0``); ``solves`` is 1.
        """
        u = np.asarray(u_in, dtype=float)
        n_in = u.size
        indptr, indices, data = csr_arrays(A_in) if arrays is None else arrays
        self._columns(indices)
        seed = np.zeros(0, dtype=np.int64) if start is None else np.asarray(start, dtype=np.int64)
        z = np.empty(self.n)
        out = np.zeros(1)
        cap = min(max(32, 2 * seed.size), n_in, self.n) + 1
        while True:
            lam = np.zeros(cap)
            rows = np.zeros(cap, dtype=np.int64)
            code, k, iterations = _run("active_set")(
                self.z0, self._Kinv, indptr, indices, data, u, seed, cutoff is not None,
                float(cutoff) if cutoff is not None else 0.0, self._Pp, self._Pi, self._Px, self.max_iter,
                GENERATION_TOL, DEPENDENT_REL, INFEASIBLE_REL, WARM_COND, cap, z, lam, rows, out)
            if code != kernel.CAPACITY:
                break
            cap = min(2 * cap, n_in + 1)  # the same steps again, with room for more rows
        status = _STATUS[code]
        rows, lam = rows[:k], lam[:k]
        if status == CUTOFF:
            return RowsSolution(CUTOFF, z, np.zeros(self.n_eq + n_in), iterations, 1, rows, True, float(out[0]))
        if status != st.OPTIMAL:
            return RowsSolution(status, z, np.zeros(self.n_eq + n_in), iterations, 1, rows,
                                bool(np.isfinite(z).all()))
        # the equality multipliers (and z) from one K solve: P z + Eᵀν = -G_Wᵀλ, E z = b
        Gt_lam = np.zeros(self.n)
        if k:
            _run("row_transpose_dot")(indptr, indices, data, rows, lam, k, Gt_lam)
        x = self.lu.solve(np.concatenate([-Gt_lam, self.b_eq])) if k else self._x0
        z = np.array(x[:self.n], dtype=float)  # a copy: x may be the stored equality optimum
        y = np.zeros(self.n_eq + n_in)
        y[:self.n_eq] = x[self.n:]
        if k:
            y[self.n_eq + rows] = lam
        finite = bool(np.isfinite(z).all() and np.isfinite(y).all())
        if not finite or self.residual(A_in, u, z, y, Gt_lam, (indptr, indices, data)) > CHECK_TOL:
            status = st.NUMERICAL_ERROR  # e.g. a nearly dependent row of an infeasible QP
        return RowsSolution(status, z, y, iterations, 1, np.sort(rows), finite)

    def _columns(self, cols: NDArray[np.int64]) -> None:
        """Solve the columns of ``K⁻¹`` among ``cols`` not solved yet (one batch; each column is
        the same bit for bit whichever batch solved it)."""
        if self._have[cols].all():
            return
        missing = np.unique(cols[~self._have[cols]])
        if missing.size:
            R = np.zeros((self.n + self.n_eq, missing.size))
            R[missing, np.arange(missing.size)] = 1.0
            X = np.asarray(self.lu.solve(R), dtype=float).reshape(self.n + self.n_eq, missing.size)
            self._Kinv[missing] = X[:self.n].T
            self._have[missing] = True
            self.columns += int(missing.size)

    def residual(self, A_in: sp.csr_matrix, u: FloatArray, z: FloatArray, y: FloatArray,
                 Gt: FloatArray | None = None, arrays: CsrArrays | None = None) -> float:
        """The largest KKT residual of ``(z, y)``, recomputed from the data: the equality rows'
        and the inequality rows' violations (absolute, metres or the limit's unit), a negative
        multiplier, and stationarity ``Pz + Eᵀν + Gᵀλ`` relative to its largest term (``Gt``:
        ``Gᵀλ`` when known; ``arrays``: ``A_in``'s :func:`csr_arrays` when known)."""
        Gp, Gi, Gx = csr_arrays(A_in) if arrays is None else arrays
        y = np.asarray(y, dtype=float)
        if Gt is None:
            Gt = np.zeros(self.n)
            lam = y[self.n_eq:]
            rows = np.arange(lam.size, dtype=np.int64)
            _run("row_transpose_dot")(Gp, Gi, Gx, rows, lam, lam.size, Gt)
        return float(_run("kkt_residual")(*self._csr, self.b_eq, *self._csr_T, self._Pp, self._Pi, self._Px,
                                          Gp, Gi, Gx, np.asarray(u, dtype=float), np.asarray(z, dtype=float), y,
                                          np.asarray(Gt, dtype=float), self.n_eq, np.empty(self.n)))
