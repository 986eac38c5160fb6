r"""The dual active-set loop of :class:`~iamp.planners.avoid.schur.SchurActiveSet`, written once.

Plain Python over numpy arrays and scalars (loops, no BLAS or LAPACK): every sum runs in one
fixed order, so the numbers do not depend on the machine's BLAS kernel.  :func:`active_set` is
marked :func:`~iamp.planners.pmp.jit.compilable`: where numba is installed the node solver runs
its twin (the same code compiled, no fastmath: the same IEEE operations in the same order, the
same numbers bit for bit; ``tests/test_avoid_schur_kernel.py`` compares the two), else this
Python function itself.

The method (Goldfarb and Idnani, :mod:`iamp.planners.avoid.schur`): the working set's rows
``g_r`` (sparse, from the CSR arrays of the QP's rows ``G z <= u``), their ``w_r`` (the primal
part of ``K⁻¹ [g_r; 0]``, the combination of the grid's columns of ``K⁻¹`` that ``g_r``
touches), ``S = [g_r · w_s]`` and the multipliers ``λ``; the optimum with the working rows held as
equalities is ``z = z0 - Σ λ_r w_r`` with ``S λ = G_W z0 - u_W`` (Gaussian elimination with
partial pivoting; a warm start's ``S`` is first checked by its Cholesky factor).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from iamp.planners.pmp.jit import compilable, inlined

#: Status codes of :func:`active_set`.
OPTIMAL, INFEASIBLE, NUMERICAL_ERROR, MAX_ITER, CUTOFF = 0, 1, 2, 3, 4
#: :func:`active_set` needs a larger ``cap`` (run it again with more: the same steps until then).
CAPACITY = 5


@inlined
def _row_dot(indptr: Any, indices: Any, data: Any, r: int, x: Any) -> float:
    """``g_r · x``."""
    s = 0.0
    for j in range(indptr[r], indptr[r + 1]):
        s += data[j] * x[indices[j]]
    return s


@compilable
def _row_w(indptr: Any, indices: Any, data: Any, r: int, Kinv: Any, out: Any) -> None:
    """``out = w_r = Σ_j g_rj K⁻¹[c_j]`` (entries in the row's stored order)."""
    n = out.shape[0]
    for i in range(n):
        out[i] = 0.0
    for j in range(indptr[r], indptr[r + 1]):
        c = indices[j]
        v = data[j]
        for i in range(n):
            out[i] += v * Kinv[c, i]


@compilable
def _cholesky(S: Any, k: int, L: Any) -> bool:
    """``L Lᵀ = S[:k, :k]`` into ``L``; False when a pivot is not positive."""
    for j in range(k):
        d = S[j, j]
        for p in range(j):
            d -= L[j, p] * L[j, p]
        if not d > 0.0:
            return False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, k):
            s = S[i, j]
            for p in range(j):
                s -= L[i, p] * L[j, p]
            L[i, j] = s / L[j, j]
    return True


@compilable
def _solve(S: Any, k: int, b: Any, x: Any, M: Any) -> bool:
    """``x = S[:k, :k]⁻¹ b`` by Gaussian elimination with partial pivoting (``M``: work space);
    False when a pivot is zero (``S`` singular)."""
    for i in range(k):
        for j in range(k):
            M[i, j] = S[i, j]
        x[i] = b[i]
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(M[r, c]) > abs(M[p, c]):
                p = r
        if M[p, c] == 0.0:
            return False
        if p != c:
            for j in range(k):
                t = M[c, j]
                M[c, j] = M[p, j]
                M[p, j] = t
            t = x[c]
            x[c] = x[p]
            x[p] = t
        for r in range(c + 1, k):
            f = M[r, c] / M[c, c]
            for j in range(c + 1, k):
                M[r, j] -= f * M[c, j]
            x[r] -= f * x[c]
    for i in range(k - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, k):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]
    return True


@compilable
def _set_z(z0: Any, W: Any, lam: Any, k: int, z: Any) -> None:
    """``z = z0 - Σ_r λ_r w_r`` (rows in working-set order)."""
    n = z0.shape[0]
    for i in range(n):
        z[i] = z0[i]
    for r in range(k):
        lr = lam[r]
        for i in range(n):
            z[i] -= lr * W[r, i]


@compilable
def _exact(z0: Any, u: Any, indptr: Any, indices: Any, data: Any, rows: Any, W: Any, S: Any, L: Any, lam: Any,
           k: int, rhs: Any, z: Any) -> bool:
    """``λ`` and ``z`` of the optimum with the working rows as equalities; False when ``S`` is
    singular."""
    if k == 0:
        for i in range(z0.shape[0]):
            z[i] = z0[i]
        return True
    for r in range(k):
        rhs[r] = _row_dot(indptr, indices, data, rows[r], z0) - u[rows[r]]
    if not _solve(S, k, rhs, lam, L):
        return False
    _set_z(z0, W, lam, k, z)
    return True


@compilable
def _pop(rows: Any, W: Any, S: Any, lam: Any, k: int, j: int) -> int:
    """Drop the working set's ``j``-th row (the others keep their order); the new size."""
    n = W.shape[1]
    for r in range(j, k - 1):
        rows[r] = rows[r + 1]
        lam[r] = lam[r + 1]
        for i in range(n):
            W[r, i] = W[r + 1, i]
        for c in range(k):
            S[r, c] = S[r + 1, c]
    for c in range(j, k - 1):
        for r in range(k - 1):
            S[r, c] = S[r, c + 1]
    return k - 1


@compilable
def _push(indptr: Any, indices: Any, data: Any, rows: Any, W: Any, S: Any, lam: Any, k: int, r: int, w: Any,
          lam_r: float) -> int:
    """Append row ``r`` with ``w_r = w`` and multiplier ``lam_r``; the new size."""
    n = W.shape[1]
    for i in range(n):
        W[k, i] = w[i]
    for c in range(k):
        s = _row_dot(indptr, indices, data, rows[c], w)
        S[c, k] = s
        S[k, c] = s
    S[k, k] = _row_dot(indptr, indices, data, r, w)
    rows[k] = r
    lam[k] = lam_r
    return k + 1


@compilable
def _dual_feasible(z0: Any, u: Any, indptr: Any, indices: Any, data: Any, rows: Any, W: Any, S: Any, L: Any,
                   lam: Any, k: int, rhs: Any, z: Any) -> int:
    """Drop the most negative multiplier until ``λ >= 0``; the new size, or -1 when ``S`` is
    singular."""
    if not _exact(z0, u, indptr, indices, data, rows, W, S, L, lam, k, rhs, z):
        return -1
    while k > 0:
        j = 0
        for r in range(1, k):
            if lam[r] < lam[j]:
                j = r
        if not lam[j] < 0.0:
            break
        k = _pop(rows, W, S, lam, k, j)
        if not _exact(z0, u, indptr, indices, data, rows, W, S, L, lam, k, rhs, z):
            return -1
    return k


@compilable
def _most_violated(indptr: Any, indices: Any, data: Any, u: Any, mirror: int, z: Any, inw: Any,
                   prod: Any) -> tuple[int, float]:
    """The first row ``r`` not in the working set (``inw[r]`` False) of the largest violation
    ``g_r · z - u_r``, and that violation (``(-1, 0.0)`` when every row is working); a NaN
    violation is never larger, so a NaN in the first row keeps it.

    Rows ``r >= mirror`` are the negations of rows ``r - h`` (``h = m - mirror``, ``m`` the number
    of rows; :func:`active_set`): their products are the negated products of their twins, kept in
    ``prod`` (``h`` numbers) as the scan passes the twins — the former scan's sum of the negated
    terms in the same order is the same number (negation is exact and rounding symmetric) but for
    the sign of a zero sum; ``±0 - u_r`` is then the same number unless ``u_r`` is a zero, and then
    a zero again, and the violations are only compared (``>`` here, ``best`` with the caller's
    tolerance), which no zero's sign changes: the same row, and ``best`` the same number.
    """
    m = u.shape[0]
    lo = 2 * mirror - m
    p = -1
    best = 0.0
    for r in range(lo):
        if inw[r]:
            continue
        v = _row_dot(indptr, indices, data, r, z) - u[r]
        if p < 0 or v > best:
            p = r
            best = v
    for r in range(lo, mirror):
        s = _row_dot(indptr, indices, data, r, z)
        prod[r - lo] = s
        if inw[r]:
            continue
        v = s - u[r]
        if p < 0 or v > best:
            p = r
            best = v
    for r in range(mirror, m):
        if inw[r]:
            continue
        v = -prod[r - mirror] - u[r]
        if p < 0 or v > best:
            p = r
            best = v
    return p, best


@compilable
def active_set(z0: Any, Kinv: Any, colnorm: Any, indptr: Any, indices: Any, data: Any, u: Any, mirror: int,
               start: Any, use_cutoff: bool, cutoff: float, Pp: Any, Pi: Any, Px: Any, max_iter: int, gen_tol: float,
               dependent_rel: float, fixed_rel: float, warm_cond: float, cap: int, z: Any, lam: Any, rows: Any,
               out: Any) -> tuple[int, int, int]:
    """The dual active-set method (module docstring) on the rows ``(indptr, indices, data) z <= u``.

    ``mirror``: the rows from ``mirror`` on are the negations of the as many rows before it, row
    ``mirror + i`` of row ``2 mirror - m + i`` (the same columns in the same order, every value
    negated; :func:`_most_violated`), ``m`` the number of rows: ``m`` when none are.
    ``z0``: the equality optimum; ``Kinv[c]``: the primal part of column ``c`` of ``K⁻¹`` (every
    column a row touches); ``start``: rows that start the working set (warm start; dropped when
    their ``S`` is not positive definite or its squared Cholesky pivots spread beyond
    ``warm_cond``); with ``use_cutoff``, stop once the working set's cost ``½ zᵀPz`` (``P`` the
    symmetric CSR ``Pp, Pi, Px``) reaches ``cutoff``.  ``cap``: the working set's largest size.
    Writes ``z``, the working rows ``rows[:k]`` and their multipliers ``lam[:k]``; returns
    ``(status, k, iterations)`` and, in ``out[0]``, the cutoff's bound.

    ``INFEASIBLE`` is a *candidate* Farkas certificate for the caller to verify
    (:meth:`~iamp.planners.avoid.schur.SchurActiveSet.solve`): ``rows[:k]`` and ``lam[:k] >= 0``
    are the weights ``δλ`` of inequality rows whose combination ``Σ δλ_r g_r`` lies in the span of
    the equality rows while ``Σ δλ_r (g_r · z - u_r) > 0``.  Two cases: the violated row ``p``
    alone, when its value is fixed by the equality rows — ``w_p`` is round-off:
    ``g_p · w_p <= fixed_rel |g_p|_1 Σ_j |g_pj| colnorm[c_j]``, ``colnorm[c]`` the largest entry
    of column ``c`` of ``K⁻¹`` (primal and dual parts), the size of the terms that cancel in
    ``w_p`` — where the relative test below is meaningless (``g_p · w_p`` and the curvature are
    both round-off); or ``p`` (weight 1) with the working rows (weights ``-S⁻¹ G_W w_p``, all
    ``>= 0``), when ``p`` is dependent on the working set (curvature ``<= dependent_rel
    g_p · w_p``) and no working multiplier blocks the dual step (Goldfarb and Idnani's
    infeasibility test).
    """
    n = z0.shape[0]
    m = u.shape[0]
    # work space written before it is read (the working rows' ``w_r``, ``S``, its factors, the
    # right-hand sides): not zeroed (``W`` alone is ``cap`` rows of ``n``)
    W = np.empty((cap, n))
    S = np.empty((cap, cap))
    L = np.empty((cap, cap))
    rhs = np.empty(cap)
    dlam = np.empty(cap)
    col = np.empty(cap)
    w = np.empty(n)
    wp = np.empty(n)
    inw = np.zeros(m, dtype=np.bool_)
    prod = np.empty(m - mirror)
    k = 0
    for i in range(n):
        z[i] = z0[i]
    # warm start
    if start.shape[0] > cap:
        return CAPACITY, 0, 0
    for q in range(start.shape[0]):
        r = start[q]
        _row_w(indptr, indices, data, r, Kinv, w)
        k = _push(indptr, indices, data, rows, W, S, lam, k, r, w, 0.0)
    if k > 0:
        ok = _cholesky(S, k, L)
        if ok:
            lo = L[0, 0] * L[0, 0]
            hi = lo
            for r in range(1, k):
                v = L[r, r] * L[r, r]
                if v < lo:
                    lo = v
                if v > hi:
                    hi = v
            ok = lo * warm_cond > hi
        if ok:
            k2 = _dual_feasible(z0, u, indptr, indices, data, rows, W, S, L, lam, k, rhs, z)
            ok = k2 >= 0
            k = k2
        if not ok:
            k = 0
            for i in range(n):
                z[i] = z0[i]
    status = OPTIMAL
    iterations = 0
    while True:
        if use_cutoff:
            bound = 0.0
            for i in range(n):
                acc = 0.0
                for j in range(Pp[i], Pp[i + 1]):
                    acc += Px[j] * z[Pi[j]]
                bound += z[i] * acc
            bound = 0.5 * bound
            if bound >= cutoff:
                out[0] = bound
                return CUTOFF, k, iterations
        for r in range(k):
            inw[rows[r]] = True
        p, best = _most_violated(indptr, indices, data, u, mirror, z, inw, prod)
        for r in range(k):
            inw[rows[r]] = False
        if p < 0 or best <= gen_tol:
            break
        if k == cap:
            return CAPACITY, k, iterations
        # Goldfarb-Idnani steps until row p binds
        _row_w(indptr, indices, data, p, Kinv, wp)
        gwp = _row_dot(indptr, indices, data, p, wp)
        g1 = 0.0
        terms = 0.0
        for j in range(indptr[p], indptr[p + 1]):
            g1 += abs(data[j])
            terms += abs(data[j]) * colnorm[indices[j]]
        if not gwp > fixed_rel * g1 * terms:  # g_p z is fixed by the equality rows, and violated
            rows[0] = p
            lam[0] = 1.0
            return INFEASIBLE, 1, iterations
        lam_p = 0.0
        steps = 0
        done = False
        budget = max_iter - iterations
        while steps < budget:
            steps += 1
            j = -1
            t2 = math.inf
            curv = gwp
            if k > 0:
                for r in range(k):
                    col[r] = _row_dot(indptr, indices, data, rows[r], wp)
                if not _solve(S, k, col, dlam, L):
                    iterations += steps
                    return NUMERICAL_ERROR, k, iterations
                for r in range(k):
                    dlam[r] = -dlam[r]
                for r in range(k):
                    curv += col[r] * dlam[r]
                for r in range(k):
                    if dlam[r] < 0.0:
                        ratio = lam[r] / -dlam[r]
                        if j < 0 or ratio < t2:
                            j = r
                            t2 = ratio
            if not curv > dependent_rel * gwp:  # dependent on the working set: a dual step only
                if j < 0:  # unblocked: the candidate certificate (docstring)
                    iterations += steps
                    for r in range(k):
                        lam[r] = dlam[r]
                    rows[k] = p
                    lam[k] = 1.0
                    return INFEASIBLE, k + 1, iterations
                t = t2
            else:
                t1 = (_row_dot(indptr, indices, data, p, z) - u[p]) / curv
                if t1 <= t2:
                    for r in range(k):
                        lam[r] = lam[r] + t1 * dlam[r]
                    k = _push(indptr, indices, data, rows, W, S, lam, k, p, wp, lam_p + t1)
                    if not _exact(z0, u, indptr, indices, data, rows, W, S, L, lam, k, rhs, z):
                        iterations += steps
                        return NUMERICAL_ERROR, k, iterations
                    neg = False
                    for r in range(k):
                        if lam[r] < 0.0:
                            neg = True
                    if neg:  # round-off only: the steps keep λ >= 0
                        k = _dual_feasible(z0, u, indptr, indices, data, rows, W, S, L, lam, k, rhs, z)
                        if k < 0:
                            iterations += steps
                            return NUMERICAL_ERROR, 0, iterations
                        there = False
                        for r in range(k):
                            if rows[r] == p:
                                there = True
                        if not there:  # the row left again: ill-conditioned, stop
                            iterations += steps
                            return NUMERICAL_ERROR, k, iterations
                    done = True
                    break
                t = t2
            for r in range(k):
                lam[r] = lam[r] + t * dlam[r]
            lam_p += t
            k = _pop(rows, W, S, lam, k, j)
            _set_z(z0, W, lam, k, z)
            for i in range(n):
                z[i] -= lam_p * wp[i]
        iterations += steps
        if not done:
            return MAX_ITER, k, iterations
    return status, k, iterations


@compilable
def row_transpose_dot(indptr: Any, indices: Any, data: Any, rows: Any, lam: Any, k: int, out: Any) -> None:
    """``out = G_Wᵀ λ`` (rows in working-set order, entries in stored order)."""
    for i in range(out.shape[0]):
        out[i] = 0.0
    for r in range(k):
        lr = lam[r]
        row = rows[r]
        for j in range(indptr[row], indptr[row + 1]):
            out[indices[j]] += lr * data[j]


@compilable
def _abs_max_rows(indptr: Any, indices: Any, data: Any, x: Any, off: Any, sign: float, mirror: int) -> float:
    """``max_r |g_r · x - off_r|`` (``sign`` 1) or ``max(0, max_r (g_r · x - off_r))`` (``sign``
    0); NaN gives ``inf``.  Rows from ``mirror`` on negate the as many rows before it
    (:func:`active_set`): their products are their twins' negated (:func:`_most_violated`: the
    same numbers but for a zero's sign, which neither the absolute value nor a comparison with
    the floor ``0.0`` sees)."""
    m = indptr.shape[0] - 1
    lo = 2 * mirror - m
    prod = np.empty(m - mirror)
    best = 0.0
    for r in range(m):
        if r < lo:
            v = _row_dot(indptr, indices, data, r, x) - off[r]
        elif r < mirror:
            t = _row_dot(indptr, indices, data, r, x)
            prod[r - lo] = t
            v = t - off[r]
        else:
            v = -prod[r - mirror] - off[r]
        if sign > 0.0:
            v = abs(v)
        if not v == v:
            return math.inf
        if v > best:
            best = v
    return best


@compilable
def kkt_residual(Ep: Any, Ei: Any, Ex: Any, b: Any, ETp: Any, ETi: Any, ETx: Any, Pp: Any, Pi: Any, Px: Any,
                 Gp: Any, Gi: Any, Gx: Any, u: Any, mirror: int, z: Any, y: Any, Gt: Any, n_eq: int,
                 work: Any) -> float:
    """:meth:`~iamp.planners.avoid.schur.SchurActiveSet.residual`: the largest of the equality
    rows' violation ``|E z - b|``, the inequality rows' ``G z - u``, a negative multiplier and the
    stationarity ``|P z + Eᵀν + Gᵀλ|`` relative to its largest term (``Gt = Gᵀλ``; ``E``, ``Eᵀ``,
    ``P`` (symmetric) and ``G`` as CSR arrays, ``G``'s rows from ``mirror`` on negating the as many
    before it (:func:`active_set`); ``work``: space for ``n`` numbers); NaN gives ``inf``."""
    primal = _abs_max_rows(Ep, Ei, Ex, z, b, 1.0, b.shape[0])
    v = _abs_max_rows(Gp, Gi, Gx, z, u, 0.0, mirror)
    if v > primal:
        primal = v
    n = z.shape[0]
    scale = 1.0
    for i in range(n):  # P z + Eᵀν, row by row
        pz = _row_dot(Pp, Pi, Px, i, z)
        at = 0.0
        for j in range(ETp[i], ETp[i + 1]):
            at += ETx[j] * y[ETi[j]]
        work[i] = pz + at + Gt[i]
        for t in (abs(pz), abs(at), abs(Gt[i])):
            if not t == t:
                return math.inf
            if t > scale:
                scale = t
    dual = 0.0
    for i in range(n):
        if abs(work[i]) > dual:
            dual = abs(work[i])
    dual = dual / scale
    out = primal if primal > dual else dual
    for r in range(n_eq, y.shape[0]):
        if -y[r] > out:
            out = -y[r]
        if not y[r] == y[r]:
            return math.inf
    return out
