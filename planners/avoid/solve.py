r"""The avoidance QP's solver: a backend of the one registry (:mod:`iamp.planners.qp.backends`).

The problem is :math:`\min \tfrac12 z^\top P z` s.t. equality rows :math:`A_{eq} z = b` and
one-sided rows :math:`A_{in} z \le u` (:mod:`iamp.planners.avoid.data`), passed to the
registry's general form ``l <= Az <= u`` with ``l = (b, -inf)``, ``u = (b, u_in)``.  A sweep
candidate changes ``u`` only (:meth:`BoundSolver.set_upper`), a crossing-time box of the fixed
pattern the values of ``A`` and ``u`` (:meth:`BoundSolver.set_values`); the backend keeps its
set-up (OSQP and Clarabel update values on the same symbolic factorisation, PIQP too).
Multipliers are the registry's (OSQP's convention: :math:`Pz + A^\top y = 0`, ``y >= 0`` on a
binding upper bound).

Settings are each backend's registry defaults, plus :data:`AVOID_SETTINGS` (then the
caller's ``settings``):

* OSQP: ``eps_abs = 1e-7`` and ``max_iter = 50_000`` (the registry's equality-QP defaults are
  1e-5 and 10,000); ``eps_rel = 0``, polishing with ``polish_refine_iter = 10`` and no
  dual-gap check as in the registry.  The polish solves the KKT system of the guessed active
  set exactly; without it OSQP is accurate to ``eps_abs`` only and the plan's KKT check
  reports it ``inaccurate``.  Warm-started from the previous candidate.
* Clarabel: the registry's tolerances 1e-12, ``max_iter = 200`` (no warm start: interior point).
* PIQP: ``eps_abs = 1e-12`` (the registry's 1e-10 leaves the optimal cost about 6e-9 relative
  off on some avoidance QPs, beyond the 1e-9 comparison tolerance its KKT check shares with
  Clarabel), ``eps_rel = 0`` as in the registry.

A backend that solves equality-constrained QPs only (``kkt``) is refused with
:class:`~iamp.core.errors.OptionError` (:func:`~.options.check_avoid_solver`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from iamp.core import status as st

from ..qp.backends import QPSolution, get_backend
from ..qp.backends.base import compressed, csr_to_csc, matvec
from .options import check_avoid_solver

FloatArray = NDArray[np.float64]

#: What the avoidance QP adds to a backend's registry defaults (module docstring).
AVOID_SETTINGS: dict[str, dict[str, Any]] = {"osqp": {"eps_abs": 1e-7, "max_iter": 50_000},
                                             "piqp": {"eps_abs": 1e-12}}


class BoundSolver:
    """One set-up registry backend for ``½zᵀPz`` s.t. ``A[:n_eq] z = b``, ``A[n_eq:] z <= u_in``.

    Parameters
    ----------
    name : str
        A registered QP backend that accepts inequalities (osqp, clarabel, piqp).
    P : scipy.sparse matrix
        Upper triangle of the cost Hessian.
    A : scipy.sparse matrix
        Equality rows, then inequality rows; its pattern (explicit zeros included) is fixed.
    b_eq : ndarray, shape (n_eq,)
    u_in : ndarray
        Initial upper bounds of the inequality rows.
    settings : dict, optional
        Overrides of the backend's settings (after :data:`AVOID_SETTINGS`).

    Raises
    ------
    OptionError
        For a backend that does not accept inequality rows or an unknown name.
    MissingDependencyError
        When the backend's package is not installed.
    """

    def __init__(self, name: str, P: sp.spmatrix, A: sp.spmatrix, b_eq: FloatArray, u_in: FloatArray,
                 settings: dict[str, Any] | None = None) -> None:
        check_avoid_solver(name)
        self.name = name
        self.b_eq = np.asarray(b_eq, dtype=float)
        self.n_eq = self.b_eq.size
        u_in = np.asarray(u_in, dtype=float)
        n = P.shape[0]
        l = np.concatenate((self.b_eq, np.full(u_in.size, -np.inf)))
        given = {**AVOID_SETTINGS.get(name, {}), **(settings or {})}
        self.backend = get_backend(name)(P, np.zeros(n), A, l, np.concatenate((self.b_eq, u_in)), given)
        self.settings = dict(self.backend.settings)

    def set_upper(self, u_in: FloatArray) -> None:
        """New upper bounds of the inequality rows."""
        self.backend.update(u=np.concatenate((self.b_eq, u_in)))

    def set_values(self, A: sp.spmatrix, u_in: FloatArray) -> None:
        """New values of ``A`` on the pattern it was set up with (CSC, sorted), and new upper bounds."""
        A = sp.csc_matrix(A)
        A.sort_indices()
        self.backend.update(Ax=np.array(A.data, dtype=float), u=np.concatenate((self.b_eq, u_in)))

    def warm_start(self, z: FloatArray, y: FloatArray) -> None:
        """Start the next solve from ``(z, y)`` (OSQP; interior-point backends ignore it)."""
        self.backend.warm_start(z, y)

    def solve(self) -> QPSolution:
        """Solve with the current data (the registry's :class:`~iamp.planners.qp.backends.base.QPSolution`)."""
        return self.backend.solve()


#: A row outside the working set joins it when the solution violates it by more than this (in the
#: row's unit: metres for the Bernstein rows, the limit's unit for a limit row); far below every
#: tolerance of the plan's checks (the Bernstein rows already carry 1e-9 m of slack).
GENERATION_TOL = 1e-9
#: A row joins the first working set when the reference solution keeps it by less than this.
SEED_SLACK = 1e-3
#: Per backend: does a row that bound (slack below :data:`SEED_SLACK`) at any solution join every
#: later working set?  Measured on the ``avoid_bounded`` bench plan (N = 50, 167 boxes; CPU s of
#: the whole plan, pool on / off): PIQP 0.39 / 0.47 s, Clarabel 0.64 / 0.83 s (273 / 322
#: solves: fewer rounds, and the same working set reuses its set-up backend), OSQP 1.48 / 0.79 s
#: (ADMM takes 675 iterations a solve on the pool's ~50 rows, 149 on the ~9 rows of the
#: reference alone).
POOL = {"osqp": False, "clarabel": True, "piqp": True}


@dataclass(frozen=True)
class RowsSolution:
    """What :func:`solve_working_set` returns: the QP's solution on **all** its rows.

    Attributes
    ----------
    status : str
        The backend's status of the last solve (``optimal`` only when that solve's optimum keeps
        every row, so it is the optimum of the whole QP).
    z : ndarray
    y : ndarray
        Multipliers of every row (equality rows, then every inequality row; zero for a row
        outside the final working set), OSQP's sign convention.
    iterations : int
        Backend iterations over every solve.
    solves : int
        Backend solves (one per round of row generation).
    working : ndarray of int
        The inequality rows of the final working set.
    finite : bool
    bound : float
    """

    status: str
    z: FloatArray
    y: FloatArray
    iterations: int
    solves: int
    working: NDArray[np.int64]
    finite: bool
    #: a lower bound of the QP's optimum (the node solver's dual value when it stopped at a
    #: cutoff; otherwise the optimal cost or ``nan``)
    bound: float = float("nan")
    #: with status ``infeasible``: a verified Farkas certificate ``δy`` on the rows of
    #: ``[A_eq; A_in]`` (the node solver's, :meth:`~iamp.planners.avoid.schur.SchurActiveSet.certificate`)
    certificate: FloatArray | None = None


def row_entries(indptr: NDArray[Any], rows: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[Any]]:
    """The positions in a CSR matrix's ``indices``/``data`` of the entries of ``rows``, row after row
    in stored order, and each row's entry count (``indptr`` its row pointers)."""
    start = indptr[rows]
    lens = indptr[rows + 1] - start
    ends = np.cumsum(lens)
    offsets = np.concatenate((np.zeros(1, dtype=ends.dtype), ends[:-1]))
    return np.repeat(start - offsets, lens) + np.arange(int(lens.sum())), lens


def _stack_rows(top: sp.csr_matrix, A: sp.csr_matrix, rows: NDArray[np.int64]) -> sp.csc_matrix:
    """``[top; A[rows]]`` as CSC, every stored entry kept (explicit zeros too, so that the same
    rows always give the same pattern), gathered from the CSR arrays: the arrays of
    ``sp.csr_matrix((data, indices, indptr)).tocsc()``, each column's entries in the order of their
    rows (a stable sort by column of the row-major entries), without building the CSR matrix
    (scipy's compiled conversion, :func:`~iamp.planners.qp.backends.base.csr_to_csc`, on the
    index type of the two matrices), marked sorted as ``tocsc`` marks its result (the backend's
    copy, :func:`~iamp.planners.qp.backends.base.csc_copy`, then skips the scan that would find
    them sorted)."""
    take, lens = row_entries(A.indptr, rows)
    m, n = top.shape[0] + rows.size, top.shape[1]
    idx = np.promote_types(top.indices.dtype, A.indices.dtype)
    cols = np.concatenate((top.indices, A.indices[take])).astype(idx, copy=False)
    data = np.concatenate((top.data, A.data[take]))
    indptr = np.concatenate((top.indptr, top.indptr[-1] + np.cumsum(lens))).astype(idx, copy=False)
    ptr_c, ind_c, data_c = csr_to_csc(indptr, cols, data, (m, n))
    out = compressed(sp.csc_matrix, data_c, ind_c.astype(idx, copy=False), ptr_c.astype(idx, copy=False), (m, n))
    out.has_sorted_indices = True  # each column's rows in increasing order, as tocsc marks its result
    return out


class RowGeneration:
    r"""``min ½zᵀPz`` s.t. ``A_eq z = b_eq``, ``A_in z <= u_in`` by row generation (exact).

    Most inequality rows of the avoidance QP never bind (at the optimum of the ``avoid_bounded``
    bench plan 7 of 1,526 rows have slack below 1e-3).  :meth:`solve` solves the QP on the
    equality rows and a *working set* of inequality rows; every row the solution violates by more
    than :data:`GENERATION_TOL` joins the set and the QP is solved again.  Each round is a
    relaxation of the whole QP, so its optimum is a lower bound; the last one keeps every row, so
    it is feasible, hence the optimum of the whole QP (the same optimum: the QP is strictly
    convex in the inputs, which determine the states).  A relaxation that is infeasible makes
    the whole QP infeasible; one the backend does not solve (neither optimal nor infeasible) is
    followed by one solve on every row.  The set only grows, so the rounds end.

    The first working set of a solve holds the rows (named by their ``ids``, the caller's fixed
    numbering) that joined any earlier working set of this object, and those that a
    ``reference`` solution (a parent box's) keeps by less than :data:`SEED_SLACK` or violates.
    A working set seen before reuses its set-up backend (values and bounds updated on the same
    pattern, :meth:`BoundSolver.set_values`).

    Parameters
    ----------
    name : str
        A registered backend that accepts inequality rows.
    P : scipy.sparse matrix
        Upper triangle of the cost Hessian.
    A_eq, b_eq
        Equality rows.
    settings : dict, optional
        Overrides of the backend's settings (after :data:`AVOID_SETTINGS`).
    every_row : bool
        Solve every QP on all its rows at once (no generation; for study and tests).

    Raises
    ------
    OptionError
        For a backend that does not accept inequality rows or an unknown name.
    """

    #: Set-up backends kept (the most recently used).
    CACHE = 8

    def __init__(self, name: str, P: sp.spmatrix, A_eq: sp.spmatrix, b_eq: FloatArray,
                 settings: dict[str, Any] | None = None, every_row: bool = False) -> None:
        check_avoid_solver(name)
        self.name, self.P, self.settings, self.every_row = name, P, settings, every_row
        self.A_eq = A_eq if type(A_eq) is sp.csr_matrix else sp.csr_matrix(A_eq)  # a CSR matrix kept as it is
        self.b_eq = np.asarray(b_eq, dtype=float)
        self.pool = np.zeros(0, dtype=bool)
        self._solvers: dict[bytes, BoundSolver] = {}

    def _backend(self, key: bytes, A: sp.csc_matrix, u: FloatArray) -> BoundSolver:
        solver = self._solvers.pop(key, None)
        if solver is not None and solver.backend.A.nnz == A.nnz:
            solver.set_values(A, u)
        else:
            solver = BoundSolver(self.name, self.P, A, self.b_eq, u, self.settings)
        self._solvers[key] = solver  # most recent last
        if len(self._solvers) > self.CACHE:
            del self._solvers[next(iter(self._solvers))]
        return solver

    def solve(self, A_in: sp.csr_matrix, u_in: FloatArray, ids: NDArray[np.int64],
              reference: FloatArray | None = None, start: NDArray[np.int64] | None = None,
              warm: tuple[FloatArray, FloatArray] | None = None) -> RowsSolution:
        """Solve with the inequality rows ``A_in z <= u_in`` (their fixed numbers ``ids``); the
        first working set also holds the rows ``start`` (indices into ``A_in``).  ``warm``: a
        point ``(z, y)`` (``y`` on the rows of ``[A_eq; A_in]``) each backend solve starts from
        (its ``y`` on that solve's working rows; OSQP only, the interior-point backends ignore
        it): where to start, not what is accepted (the rounds end as without it).

        Returns
        -------
        RowsSolution
            ``y`` holds a multiplier for every row of ``[A_eq; A_in]``.
        """
        A_in = A_in if type(A_in) is sp.csr_matrix else sp.csr_matrix(A_in)  # the spec's rows: CSR already
        u_in = np.asarray(u_in, dtype=float)
        ids = np.asarray(ids, dtype=np.int64)
        n_eq, n_in, n = self.A_eq.shape[0], A_in.shape[0], self.P.shape[0]
        if ids.size and ids.max() >= self.pool.size:
            self.pool = np.concatenate((self.pool, np.zeros(int(ids.max()) + 1 - self.pool.size, dtype=bool)))
        work = np.ones(n_in, dtype=bool) if self.every_row else self.pool[ids].copy()
        if reference is not None and n_in:
            work |= matvec(A_in, reference) - u_in > -SEED_SLACK
        if start is not None:
            work[start] = True
        solves = iterations = 0
        while True:
            rows = np.flatnonzero(work)
            if rows.size:
                A = _stack_rows(self.A_eq, A_in, rows)
                u = u_in[rows]
            else:  # one always-true row keeps the cone non-empty
                A = sp.csc_matrix(sp.vstack([self.A_eq, sp.csr_matrix((1, n))]))
                u = np.ones(1)
            solver = self._backend(ids[rows].tobytes(), A, u)
            if warm is not None and solver.backend.warm_starts:
                solver.warm_start(warm[0], np.concatenate((warm[1][:n_eq], warm[1][n_eq + rows])) if rows.size
                                  else np.concatenate((warm[1][:n_eq], np.zeros(1))))
            sol = solver.solve()
            solves += 1
            iterations += sol.iterations
            if sol.status not in (st.OPTIMAL, st.INFEASIBLE) and not work.all():
                # a relaxation the backend did not solve (Clarabel's "almost solved" on a nearly
                # infeasible working set): the whole QP at once, as without generation
                work[:] = True
                continue
            if sol.status != st.OPTIMAL or not sol.finite:
                return RowsSolution(sol.status, sol.z, np.zeros(n_eq + n_in), iterations, solves, rows, sol.finite)
            r = matvec(A_in, sol.z) - u_in
            new = (r > GENERATION_TOL) & ~work
            if not new.any():
                break
            work |= new
        if POOL.get(self.name, True):
            self.pool[ids[r > -SEED_SLACK]] = True
        y = np.zeros(n_eq + n_in)
        y[:n_eq] = sol.y[:n_eq]
        y[n_eq + rows] = sol.y[n_eq:n_eq + rows.size]
        return RowsSolution(sol.status, sol.z, y, iterations, solves, rows, True)
