r"""Solution polish: a backend's answer refined on the active set it identifies (as OSQP polishes).

For :math:`\min \tfrac12 z^\top P z + q^\top z` s.t. :math:`l \le Az \le u` (the registry's form,
:mod:`~iamp.planners.qp.backends.base`) an approximate primal-dual point ``(z, y)`` names its active
set: every equality row, a row at its upper bound when its multiplier exceeds its slack,
:math:`y_i > u_i - a_i^\top z`, one at its lower bound when :math:`-y_i > a_i^\top z - l_i` (an
interior-point iterate has :math:`y_i s_i \approx \mu` on every row, so the larger of the two
factors says which side of complementarity the row is on; an ADMM or active-set answer has
``y_i = 0`` off its active set).  :func:`polish` solves the equality-constrained QP of those rows
held at their bounds exactly, by the direct backend (:class:`~iamp.planners.qp.backends.kkt.KKTBackend`,
one LU of the KKT matrix); rows identical in pattern and values on the same side are held once,
at the tighter bound (else the KKT matrix is singular).

The result is the QP's optimum exactly when the identified set is the optimal one: then it
satisfies the KKT conditions to round-off, complementarity exactly (a row off the set has a zero
multiplier, a row on it holds with equality).  Nothing here says so: the caller checks the KKT
conditions of the polished point from the data, and keeps the unpolished answer when they fail
(a row missed leaves it infeasible, a row wrongly held gives a multiplier of the wrong sign).

Why: an interior-point method stops with :math:`\sum_i y_i s_i` (its duality gap) of about its
gap tolerance — PIQP's ``eps_duality_gap_abs`` is 1e-8 — so its cost is above the optimum by
up to that much although every single product :math:`y_i s_i` passes a per-row complementarity
test (measured on a two-vehicle ZOH avoidance QP: ``Σ y_i s_i`` = 2.0e-8 = the cost excess,
1.55e-9 relative; polished, the cost is the active-set optimum's to 1e-15).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from iamp.core import status as st

from .base import FloatArray, QPSolution, csc_rows


def _csc(A: sp.spmatrix) -> sp.csc_matrix:
    """``A`` as CSC (itself when it is one: the avoidance passes its stacked rows so)."""
    return A if type(A) is sp.csc_matrix else sp.csc_matrix(A)


def active_rows(A: sp.spmatrix, l: FloatArray, u: FloatArray, z: FloatArray, y: FloatArray
                ) -> tuple[np.ndarray, FloatArray]:
    """The rows ``(z, y)`` holds active (module docstring) and the bound each is held at; of rows
    with the same pattern, values and side only the one with the tighter bound.

    Read from ``A``'s CSC arrays (no conversion to CSR): ``Az`` sums each row's products in the
    order of its columns, as a CSR product does; a held inequality row's pattern and values are
    its entries in column order."""
    A = _csc(A)
    Az = A @ z
    eq = l == u
    with np.errstate(invalid="ignore"):
        upper = ~eq & (y > 0) & (y > u - Az)
        lower = ~eq & (y < 0) & (-y > Az - l)
    rows = np.flatnonzero(eq | upper | lower)
    bound = np.where(lower, l, u)[rows]
    held = eq[rows]
    ineq = np.flatnonzero(~held)  # the inequality rows held (the equalities all are)
    keep: dict[tuple[bytes, bytes, int], int] = {}
    if ineq.size:
        R = csc_rows(A, rows[ineq]).tocsr()  # those rows, each row's entries in column order
        for j, pos in enumerate(ineq.tolist()):
            a, b = R.indptr[j], R.indptr[j + 1]
            side = 1 if upper[rows[pos]] else -1
            key = (R.indices[a:b].tobytes(), R.data[a:b].tobytes(), side)
            old = keep.get(key)
            if old is None:
                keep[key] = pos
            elif side * bound[pos] < side * bound[old]:  # the tighter bound of two identical rows
                keep[key] = pos
    chosen = np.sort(np.concatenate((np.flatnonzero(held), np.fromiter(keep.values(), dtype=np.int64,
                                                                        count=len(keep))))).astype(np.int64)
    return rows[chosen], bound[chosen]


def polish(P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray, u: FloatArray, z: FloatArray,
           y: FloatArray) -> QPSolution | None:
    """``(z, y)`` refined on its active set (module docstring): the optimum of the QP with those
    rows held at their bounds, ``y`` zero on the other rows; None when that KKT matrix is singular
    or the solve not finite.  ``P`` is the upper triangle (CSC), as every backend takes it; the
    result is not checked here (the caller checks its KKT conditions from the data)."""
    from .kkt import KKTBackend

    z, y = np.asarray(z, dtype=float), np.asarray(y, dtype=float)
    l, u = np.asarray(l, dtype=float), np.asarray(u, dtype=float)
    if not (np.isfinite(z).all() and np.isfinite(y).all()):
        return None
    A = _csc(A)
    rows, bound = active_rows(A, l, u, z, y)
    A_act = csc_rows(A, rows)
    sol = KKTBackend(P, q, A_act, bound, bound).solve()
    if sol.status != st.OPTIMAL or not sol.finite:
        return None
    y_out = np.zeros(l.size)
    y_out[rows] = sol.y
    return QPSolution(z=sol.z, y=y_out, status=st.OPTIMAL, raw_status="polished", iterations=1,
                      solver_time_s=sol.solver_time_s, solve_call_s=sol.solve_call_s)
