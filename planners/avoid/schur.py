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
it, the QP is infeasible: the step is a dual ray, a Farkas certificate ``δy`` (the row, the
working rows' weights and, from one ``K`` solve, the equality rows'), which
:meth:`SchurActiveSet.certificate` checks from the data before the solve says ``infeasible``:
an identity to round-off (:data:`FARKAS_ROUNDOFF`) whose rows are violated on every point of
``E z = b`` by more than the node solver's own row tolerance
(:data:`~iamp.planners.avoid.solve.GENERATION_TOL`), so no point the solver would accept exists,
or one that passes a backend's certificate test; else ``numerical_error``.  A row whose value
the equality rows fix (it touches only node variables they determine, e.g. the Bernstein
coefficients of a sub-piece at ``t_f``, which the final position and speed fix) has
``w_r = 0``: its curvature is round-off and the relative dependence test meaningless, so it is
recognised by the size of ``g_r · w_r`` against the terms that cancel in it (:data:`FIXED_REL`)
and, violated, is such a certificate alone.  A solve whose multipliers grew along a dual ray
until the Schur complement was singular tries their direction as a certificate.  The sparse
solves are one column of ``K⁻¹`` per node variable a row touches, once per grid (``w_r`` is
their combination), and one final ``K`` solve per QP for the equality multipliers.

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

from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from iamp.core import status as st
from iamp.planners.pmp import jit

from ..qp.backends.base import farkas_residuals
from ..qp.bounded import certified_infeasible
from . import schur_kernel as kernel
from .solve import GENERATION_TOL, RowsSolution

FloatArray = NDArray[np.float64]

__all__ = ["CHECK_TOL", "CUTOFF", "DEPENDENT_REL", "FIXED_REL", "SchurActiveSet", "full_hessian", "kkt_matrix"]

#: A row whose Schur complement on the working set is below this times ``g_r·w_r`` is treated as
#: linearly dependent on the working set (a pure dual step; when no multiplier of the working set
#: blocks it, the step is a candidate Farkas certificate, verified before ``infeasible`` is said).
DEPENDENT_REL = 1e-9
#: A row whose ``g_r·w_r`` is below this times ``|g_r|_1 Σ_j |g_rj| ‖K⁻¹ e_{c_j}‖_∞`` (the size of
#: the terms that cancel in ``w_r``) has its value fixed by the equality rows (``w_r`` is
#: round-off).  Measured on the narrow window of ``tests/test_avoid_reference.py`` (N = 16, FOH):
#: such rows ~1e-34, every other row of its 63 QPs above 1e-4; on the overtakes (one and three
#: vehicles, with limits, FOH) every other row above 1.2e-3 / 8.8e-5 / 1.2e-5 / 1.5e-6 at
#: N = 20 / 50 / 100 / 200 (about 1/N²).  A misjudged row only yields a certificate that fails its
#: check (then ``numerical_error``, as before).
FIXED_REL = 1e-12


#: The status of a solve stopped at its cutoff (:meth:`SchurActiveSet.solve`): the QP's optimum
#: is at least the reported ``bound`` (internal to the search, never a plan's status).
CUTOFF = "cutoff"

#: A warm start whose working rows' Schur complement is not positive definite, or whose squared
#: Cholesky pivots spread by more than this factor (a lower bound of its condition number), is
#: dropped (the solve starts from the equality optimum).
WARM_COND = 1e10

#: A Farkas certificate of the node solver (:meth:`SchurActiveSet.certificate`) is an identity up
#: to the round-off of one solve with ``K``: its ``‖Aᵀδy‖∞ / ‖A‖max`` (``δy`` at unit max-norm,
#: :func:`~iamp.planners.qp.backends.base.farkas_residuals`) must be below this (measured: 1e-18 to
#: 1.1e-16 on the 129 certificates of the narrow window of ``tests/test_avoid_reference.py``; a
#: backend's certificate is accepted at 1e-7, :data:`~iamp.planners.qp.bounded.FARKAS_STATIONARITY`).
FARKAS_ROUNDOFF = 1e-12

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
        #: ``‖K⁻¹ e_c‖_∞`` of every solved column ``c`` (primal and dual parts: the size of the
        #: terms that cancel in ``w_r`` of a row the equality rows fix, :data:`FIXED_REL`)
        self._colnorm = np.zeros(self.n)
        self._have = np.zeros(self.n, dtype=bool)
        self.columns = 0

    def same_matrix(self, P: sp.spmatrix, A_eq: sp.spmatrix) -> bool:
        """Whether ``P`` (upper triangle) and ``A_eq`` are, bit for bit, the matrices this solver
        factored (then :meth:`with_rhs` may serve them)."""
        def same(a: sp.spmatrix, b: sp.spmatrix) -> bool:
            # an index array is equal to itself (the plans of one grid share the matrices' arrays);
            # the values are compared always (a NaN is not equal to itself)
            return (a.shape == b.shape and (a.indptr is b.indptr or np.array_equal(a.indptr, b.indptr))
                    and (a.indices is b.indices or np.array_equal(a.indices, b.indices))
                    and np.array_equal(a.data, b.data))

        # a matrix of the kind compared is compared as it is (the constructor would keep its arrays)
        return (same(self.P, P if type(P) is sp.csc_matrix else sp.csc_matrix(P))
                and same(self.A_eq, A_eq if type(A_eq) is sp.csr_matrix else sp.csr_matrix(A_eq)))

    def with_rhs(self, b_eq: FloatArray) -> SchurActiveSet:
        """The solver of the same ``P`` and ``E`` with the right-hand side ``b_eq``: it shares this
        one's factored KKT matrix and its solved columns of ``K⁻¹`` (which depend on ``P`` and
        ``E`` only; a column is the same bit for bit whichever batch solved it), so the plans of
        one grid factor it once (the closed loop plans the same horizon many times).  A shallow copy
        (what ``copy.copy`` builds: a new object of this class sharing this one's attributes,
        without its dispatch) with the equality optimum of ``b_eq``."""
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out.b_eq = np.asarray(b_eq, dtype=float)
        if out.b_eq.shape != self.b_eq.shape:
            raise ValueError(f"b_eq has {out.b_eq.size} rows, the factored matrix {self.n_eq}")
        out._x0 = np.asarray(self.lu.solve(np.concatenate((np.zeros(self.n), out.b_eq))), dtype=float)
        out.z0 = out._x0[:self.n].copy()
        out.columns = 0
        return out

    def solve(self, A_in: sp.csr_matrix, u_in: FloatArray, start: NDArray[np.int64] | None = None,
              cutoff: float | None = None, arrays: CsrArrays | None = None, mirrored: int = 0,
              columns: NDArray[np.int64] | None = None) -> RowsSolution:
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
        mirrored : int, optional
            The last ``mirrored`` rows of ``A_in`` are the negations of the as many rows before
            them (the same columns in the same stored order, every value negated; the limit rows
            ``[A_lim; -A_lim]``): the kernel forms each pair's product once.
        columns : ndarray of int, optional
            The column indices of ``A_in``'s entries whose columns of ``K⁻¹`` may not be solved
            yet (:meth:`_columns`; by default every entry's): a caller that solved the columns of
            some of the rows before (every spec of a search shares the limit rows) passes the others',
            so the test of which are solved reads fewer indices.  The columns solved are the same.

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
        self._columns(indices if columns is None else columns)
        seed = np.zeros(0, dtype=np.int64) if start is None else np.asarray(start, dtype=np.int64)
        z = np.empty(self.n)
        out = np.zeros(1)
        cap = min(max(32, 2 * seed.size), n_in, self.n) + 1
        while True:
            lam = np.zeros(cap)
            rows = np.zeros(cap, dtype=np.int64)
            code, k, iterations = _run("active_set")(
                self.z0, self._Kinv, self._colnorm, indptr, indices, data, u, n_in - mirrored, seed, cutoff is not None,
                float(cutoff) if cutoff is not None else 0.0, self._Pp, self._Pi, self._Px, self.max_iter,
                GENERATION_TOL, DEPENDENT_REL, FIXED_REL, WARM_COND, cap, z, lam, rows, out)
            if code != kernel.CAPACITY:
                break
            cap = min(2 * cap, n_in + 1)  # the same steps again, with room for more rows
        status = _STATUS[code]
        rows, lam = rows[:k], lam[:k]
        if status == CUTOFF:
            return RowsSolution(CUTOFF, z, np.zeros(self.n_eq + n_in), iterations, 1, rows, True, float(out[0]))
        if status == st.INFEASIBLE:  # a candidate certificate: infeasible only once verified
            cert = self.certificate(A_in, u, (indptr, indices, data), rows, lam)
            return RowsSolution(st.INFEASIBLE if cert is not None else st.NUMERICAL_ERROR, z,
                                np.zeros(self.n_eq + n_in), iterations, 1, rows, bool(np.isfinite(z).all()),
                                certificate=cert)
        if status != st.OPTIMAL:
            return self._unsolved(status, A_in, u, (indptr, indices, data), z, rows, lam, iterations)
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
        # z and y are finite exactly when x and λ are (y is x's dual part, zeros and λ): the
        # shorter arrays tested
        finite = bool(np.isfinite(x).all() and np.isfinite(lam).all())
        if not finite or self.residual(A_in, u, z, y, Gt_lam, (indptr, indices, data), mirrored) > CHECK_TOL:
            # e.g. a nearly dependent row of an infeasible QP
            return self._unsolved(st.NUMERICAL_ERROR, A_in, u, (indptr, indices, data), z, rows, lam, iterations)
        return RowsSolution(status, z, y, iterations, 1, np.sort(rows), finite)

    def _unsolved(self, status: str, A_in: sp.csr_matrix, u: FloatArray, arrays: CsrArrays, z: FloatArray,
                  rows: NDArray[np.int64], lam: FloatArray, iterations: int) -> RowsSolution:
        """A solve the kernel did not finish (``status``), or whose optimum failed its residual
        check: ``infeasible`` when the working rows' multipliers, in their direction, are a Farkas
        certificate (:meth:`certificate`) — the dual of an infeasible QP is unbounded, and the
        dual active-set steps grow the multipliers along a dual ray until the Schur complement is
        singular (measured: multipliers ~1e15, ``cond S`` 4.5e16, a certificate at round-off
        proving a violation of 0.24 m) — else ``status``."""
        n_in = u.size
        cert = None
        if rows.size and np.isfinite(lam).all() and lam.min() >= 0.0 and lam.max() > 0.0:
            cert = self.certificate(A_in, u, arrays, rows, lam / lam.max())
        return RowsSolution(st.INFEASIBLE if cert is not None else status, z, np.zeros(self.n_eq + n_in), iterations,
                            1, rows, bool(np.isfinite(z).all()), certificate=cert)

    def certificate(self, A_in: sp.csr_matrix, u: FloatArray, arrays: CsrArrays, rows: NDArray[np.int64],
                    weights: FloatArray) -> FloatArray | None:
        r"""The Farkas certificate of the kernel's infeasibility verdict, verified, or None.

        ``weights >= 0`` of the inequality rows ``rows`` combine into :math:`g = \sum_r \delta\lambda_r
        g_r`, which the kernel found in the span of the equality rows ``E``; one solve with the factored
        ``K`` gives :math:`K (w, \mu) = (g, 0)`, so :math:`E^\top \mu = g - P w` (``w`` round-off),
        and ``δy = (-μ, δλ)`` on ``[E; A_in]`` (the convention of ``y``).  On every ``z`` with
        ``E z = b``, :math:`\sum_r \delta\lambda_r (g_r z - u_r) = b^\top\mu - u^\top\delta\lambda
        + (Pw)^\top z`; accepted when the last term is round-off — :math:`\|A^\top\delta y\|_\infty
        / \|A\|_{\max}` at unit ``‖δy‖∞`` (:func:`~iamp.planners.qp.backends.base.farkas_residuals`)
        at most :data:`FARKAS_ROUNDOFF` — and the rows' least violation there, that sum over
        :math:`\sum_r \delta\lambda_r`, exceeds :data:`~iamp.planners.avoid.solve.GENERATION_TOL`,
        the tolerance to which the node solver (and row generation) accepts a row as kept: no point
        it would accept exists.  Or when it passes the test a backend's certificate passes
        (:func:`~iamp.planners.qp.bounded.certified_infeasible`: the identity to 1e-7 and a support
        below -1e-9 relative to the largest bound): a combination of many working rows (50 on a
        three-vehicle plan) carries more round-off than one solve (its identity to 1e-12..1e-10)
        while proving violations of 0.2-0.4 m."""
        Gp, Gi, Gx = arrays
        n_in = u.size
        Gt = np.zeros(self.n)
        _run("row_transpose_dot")(Gp, Gi, Gx, rows, weights, rows.size, Gt)
        x = np.asarray(self.lu.solve(np.concatenate([Gt, np.zeros(self.n_eq)])), dtype=float)
        dy = np.zeros(self.n_eq + n_in)
        dy[:self.n_eq] = -x[self.n:]
        dy[self.n_eq + rows] = weights
        A = sp.vstack([self.A_eq, sp.csr_matrix(A_in)], format="csc")
        l_all, u_all = np.r_[self.b_eq, np.full(n_in, -np.inf)], np.r_[self.b_eq, u]
        stat, _ = farkas_residuals(A, l_all, u_all, dy)
        # the least violation of the rows on {E z = b}: Σ δλ_r (g_r z - u_r) = bᵀμ - uᵀδλ there
        violation = float(self.b_eq @ x[self.n:] - u[rows] @ weights) / float(np.sum(weights))
        ok = (stat <= FARKAS_ROUNDOFF and violation > GENERATION_TOL) or certified_infeasible(A, l_all, u_all, dy)[0]
        return dy if ok else None

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
            self._colnorm[missing] = np.max(np.abs(X), axis=0)
            self._have[missing] = True
            self.columns += int(missing.size)

    def violation(self, arrays: CsrArrays, z: FloatArray, u: FloatArray, mirrored: int = 0) -> float:
        """The largest violation ``max(0, max_r (g_r · z - u_r))`` of the rows ``G z <= u`` (``arrays``:
        ``G``'s :func:`csr_arrays`; each ``g_r · z`` summed in stored order from zero, as scipy's
        product does), ``inf`` when one is NaN; the last ``mirrored`` rows negate the as many
        before them (:meth:`solve`)."""
        u = np.asarray(u, dtype=float)
        return float(_run("_abs_max_rows")(*arrays, np.asarray(z, dtype=float), u, 0.0, u.size - mirrored))

    def residual(self, A_in: sp.csr_matrix, u: FloatArray, z: FloatArray, y: FloatArray,
                 Gt: FloatArray | None = None, arrays: CsrArrays | None = None, mirrored: int = 0) -> float:
        """The largest KKT residual of ``(z, y)``, recomputed from the data: the equality rows'
        and the inequality rows' violations (absolute, metres or the limit's unit), a negative
        multiplier, and stationarity ``Pz + Eᵀν + Gᵀλ`` relative to its largest term (``Gt``:
        ``Gᵀλ`` when known; ``arrays``: ``A_in``'s :func:`csr_arrays` when known; ``mirrored``: the
        last rows that negate the as many before them, :meth:`solve`)."""
        Gp, Gi, Gx = csr_arrays(A_in) if arrays is None else arrays
        y = np.asarray(y, dtype=float)
        if Gt is None:
            Gt = np.zeros(self.n)
            lam = y[self.n_eq:]
            rows = np.arange(lam.size, dtype=np.int64)
            _run("row_transpose_dot")(Gp, Gi, Gx, rows, lam, lam.size, Gt)
        return float(_run("kkt_residual")(*self._csr, self.b_eq, *self._csr_T, self._Pp, self._Pi, self._Px,
                                          Gp, Gi, Gx, np.asarray(u, dtype=float), len(u) - mirrored,
                                          np.asarray(z, dtype=float), y,
                                          np.asarray(Gt, dtype=float), self.n_eq, np.empty(self.n)))
