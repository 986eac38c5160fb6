r"""Kernels of the weak-duality bounds (:mod:`iamp.planners.avoid.dual`), written once.

Plain Python over numpy arrays and scalars (loops, no BLAS or LAPACK calls): every sum runs in one
fixed order and every power as products, so the numbers depend neither on the machine nor on
whether numba is installed.  Each function is marked :func:`~iamp.planners.pmp.jit.compilable`:
where numba is installed the bounds run its twin (the same code compiled, no fastmath: the same
IEEE operations in the same order), else this Python function itself
(``tests/test_avoid_dual_kernel.py`` compares the two bit for bit, and each kernel with the numpy
formulation it replaced).

Notation of :mod:`iamp.planners.avoid.dual`: ``K`` the equality-constrained KKT matrix, whose
inverse's primal block :math:`K^{-1}_{zz}` the node solver keeps column by column (``Kinv[c]``:
column ``c``, a row by symmetry); a solved candidate's binding rows ``nz`` of its imposed rows
(CSR arrays ``indptr, indices, data``) with multipliers ``y``; per half-plane of the polynomial
vehicle's split piece the binding rows ``rows`` among them, their Bernstein indices ``jidx``, the
sign ``σ``, the piece's four node columns ``cols``, the σ-free row values ``M`` (power
coefficients in :math:`\lambda`, shape ``(d + 1, d + 1, 4)``) and bounds ``rhs`` (shape
``(d + 1, d + 1)``).

* :func:`slope` — the envelope theorem's :math:`\partial J/\partial\tau` of a candidate
  (:meth:`~iamp.planners.avoid.dual.DualBounds.gradient`);
* :func:`tangent` — :math:`\dot y` of :meth:`~iamp.planners.avoid.dual.DualBounds.tangent`;
* :func:`tangent_terms` — the right-hand sides ``R`` and ``yᵀh`` of one polynomial vehicle with
  its multipliers on their (cut) tangent (:meth:`~iamp.planners.avoid.dual.DualBounds.polynomial`);
* :func:`primal` — :math:`Z = K^{-1}_{zz} R + z_0 e_0^\top` from the kept columns;
* :func:`coefficients` — the polynomial's coefficients
  :math:`-\mathrm{lin} - \tfrac12 Z^\top P Z` summed per power, and the size of the terms that
  cancel in them (its round-off margin);
* :func:`binding_rows` — a solution's binding rows decoded from their layout numbers, and the
  multipliers' sums per vehicle (:meth:`~iamp.planners.avoid.dual.DualBounds._decode`);
* :func:`select_rows` — the binding Bernstein rows of one half-plane on one piece
  (:meth:`~iamp.planners.avoid.dual._Binding.split_rows`);
* :func:`kept_rows` — the binding rows whose multipliers stay valid over a box
  (:meth:`~iamp.planners.avoid.dual.DualBounds.polynomial`);
* :func:`ratio_limits` — the smallest ratios ``y / |μ|`` of the multipliers falling and rising along
  their tangent (:meth:`~iamp.planners.avoid.dual.DualBounds.tangent_interval`).
"""

from __future__ import annotations

from math import isfinite, sqrt
from typing import Any

import numpy as np

from iamp.planners.avoid.schur_kernel import _solve
from iamp.planners.pmp.jit import compilable


@compilable
def _split_derivatives(lam0: float, rows: Any, jidx: Any, M: Any, rhs: Any, sigma: float, cols: Any,
                       dGv: Any, dGc: Any, dh: Any, has: Any) -> None:
    r"""For each binding row ``r`` of ``rows`` (one half-plane of the split piece): the derivative in
    :math:`\lambda` at ``lam0`` of its values on the node columns ``cols`` (``σ Σ_p p λ^{p-1} M[p, j]``,
    into ``dGv[r]``, ``dGc[r]``) and of its bound (``Σ_p p λ^{p-1} rhs[p, j]``, into ``dh[r]``)."""
    D = M.shape[0] - 1
    for t in range(rows.shape[0]):
        r = rows[t]
        jj = jidx[r]
        for c in range(4):
            acc = 0.0
            pw = 1.0
            for p in range(1, D + 1):
                acc += (p * pw) * M[p, jj, c]
                pw = pw * lam0
            dGv[r, c] = sigma * acc
            dGc[r, c] = cols[c]
        acc = 0.0
        pw = 1.0
        for p in range(1, D + 1):
            acc += (p * pw) * rhs[p, jj]
            pw = pw * lam0
        dh[r] = acc
        has[r] = True


@compilable
def _both_derivatives(S: int, lam0: float, rows_f: Any, M_f: Any, rhs_f: Any, sigma_f: float, cols_f: Any,
                      rows_s: Any, M_s: Any, rhs_s: Any, sigma_s: float, cols_s: Any, jidx: Any) -> Any:
    """:func:`_split_derivatives` of both half-planes of the split piece, into new arrays
    ``(dGv, dGc, dh, has)`` over the ``S`` binding rows (zero where a row is not split)."""
    dGv = np.zeros((S, 4))
    dGc = np.zeros((S, 4), dtype=np.int64)
    dh = np.zeros(S)
    has = np.zeros(S, dtype=np.bool_)
    _split_derivatives(lam0, rows_f, jidx, M_f, rhs_f, sigma_f, cols_f, dGv, dGc, dh, has)
    _split_derivatives(lam0, rows_s, jidx, M_s, rhs_s, sigma_s, cols_s, dGv, dGc, dh, has)
    return dGv, dGc, dh, has


@compilable
def tangent(indptr: Any, indices: Any, data: Any, nz: Any, y: Any, jidx: Any, z: Any, Kinv: Any, lam0: float,
            rows_f: Any, M_f: Any, rhs_f: Any, sigma_f: float, cols_f: Any,
            rows_s: Any, M_s: Any, rhs_s: Any, sigma_s: float, cols_s: Any, out: Any) -> bool:
    r"""``out`` :math:`= \dot y_S`, the solution of
    :math:`(G_S K^{-1}_{zz} G_S^\top)\,\dot y_S = G_S K^{-1}_{zz}(-\dot G_S^\top y_S) - (\dot h_S - \dot G_S z)`
    (:meth:`~iamp.planners.avoid.dual.DualBounds.tangent`; ``f``: the first half-plane's split
    rows, ``s``: the second's), by the node solver's Gaussian elimination
    (:func:`~iamp.planners.avoid.schur_kernel._solve`).

    Returns False, ``out`` zero, where no split row binds, where a pivot is zero, or where the
    solution is not finite or leaves a residual above :math:`10^{-8}(1 + \|rhs\|)` (binding rows
    that depend on each other: no tangent)."""
    S = nz.shape[0]
    for r in range(S):
        out[r] = 0.0
    if rows_f.shape[0] + rows_s.shape[0] == 0:
        return False
    dGv, dGc, dh, has = _both_derivatives(S, lam0, rows_f, M_f, rhs_f, sigma_f, cols_f, rows_s, M_s, rhs_s, sigma_s,
                                          cols_s, jidx)
    W = np.zeros((S, S))
    for r1 in range(S):
        a0 = indptr[nz[r1]]
        a1 = indptr[nz[r1] + 1]
        for r2 in range(r1, S):
            b0 = indptr[nz[r2]]
            b1 = indptr[nz[r2] + 1]
            acc = 0.0
            for a in range(a0, a1):
                ca = indices[a]
                inner = 0.0
                for b in range(b0, b1):
                    inner += Kinv[ca, indices[b]] * data[b]
                acc += data[a] * inner
            W[r1, r2] = acc
            W[r2, r1] = acc
    rhs = np.zeros(S)
    for r in range(S):
        acc = 0.0
        for a in range(indptr[nz[r]], indptr[nz[r] + 1]):
            ca = indices[a]
            inner = 0.0
            for r2 in range(S):
                if has[r2]:
                    for c in range(4):
                        inner += Kinv[ca, dGc[r2, c]] * (dGv[r2, c] * y[r2])
            acc += data[a] * inner
        dgz = 0.0
        if has[r]:
            for c in range(4):
                dgz += dGv[r, c] * z[dGc[r, c]]
        rhs[r] = -acc - (dh[r] - dgz)
    # the node solver's Gaussian elimination (schur_kernel._solve, partial pivoting)
    x = np.zeros(S)
    if not _solve(W, S, rhs, x, np.empty((S, S))):
        return False
    res = 0.0
    size = 0.0
    for i in range(S):
        if not isfinite(x[i]):
            return False
        acc = 0.0
        for j in range(S):
            acc += W[i, j] * x[j]
        d = acc - rhs[i]
        res += d * d
        size += rhs[i] * rhs[i]
    if sqrt(res) > 1e-8 * (1.0 + sqrt(size)):
        return False
    for r in range(S):
        out[r] = x[r]
    return True


@compilable
def slope(y: Any, jidx: Any, z: Any, lam0: float, rows_f: Any, M_f: Any, rhs_f: Any, sigma_f: float, cols_f: Any,
          rows_s: Any, M_s: Any, rhs_s: Any, sigma_s: float, cols_s: Any) -> float:
    r""":math:`\partial J/\partial\lambda = \sum_r y_r\,(\dot g_r z - \dot h_r)` over the split piece's binding
    rows (first half-plane ``f``, then second ``s``; :func:`_split_derivatives`), the envelope
    theorem's derivative of the candidate's optimum in its crossing time's local coordinate
    (:meth:`~iamp.planners.avoid.dual.DualBounds.gradient` divides it by the step ``h``)."""
    dGv, dGc, dh, _ = _both_derivatives(y.shape[0], lam0, rows_f, M_f, rhs_f, sigma_f, cols_f, rows_s, M_s, rhs_s,
                                        sigma_s, cols_s, jidx)
    total = 0.0
    for half in range(2):
        rows = rows_f if half == 0 else rows_s
        acc = 0.0
        for t in range(rows.shape[0]):
            r = rows[t]
            v = 0.0
            for c in range(4):
                v += dGv[r, c] * z[dGc[r, c]]
            acc += y[r] * (v - dh[r])
        total += acc
    return total


@compilable
def _split_terms(rows: Any, jidx: Any, alpha: Any, beta: Any, M: Any, rhs: Any, sigma: float, cols: Any,
                 R: Any, hc: Any) -> None:
    r"""One half-plane of the split piece in :func:`tangent_terms`: with multipliers
    :math:`\alpha_j + \lambda\beta_j` per Bernstein index ``j``, ``R[cols, p] -= σ Σ_j α_j M[p, j]``,
    ``R[cols, p + 1] -= σ Σ_j β_j M[p, j]``, ``hc[p] += Σ_j rhs[p, j] α_j``, ``hc[p + 1] += Σ_j rhs[p, j] β_j``."""
    D1 = M.shape[0]
    nb = M.shape[1]
    aj = np.zeros(nb)
    bj = np.zeros(nb)
    for t in range(rows.shape[0]):
        r = rows[t]
        aj[jidx[r]] = alpha[r]
        bj[jidx[r]] = beta[r]
    for shift in range(2):  # the α terms on powers 0..d, then the β terms on 1..d + 1
        wj = aj if shift == 0 else bj
        for c in range(4):
            for p in range(D1):
                acc = 0.0
                for jj in range(nb):
                    acc += wj[jj] * M[p, jj, c]
                R[cols[c], p + shift] -= sigma * acc
        for p in range(D1):
            acc = 0.0
            for jj in range(nb):
                acc += rhs[p, jj] * wj[jj]
            hc[p + shift] += acc


@compilable
def tangent_terms(indptr: Any, indices: Any, data: Any, nz: Any, y: Any, jidx: Any, u_in: Any, keep: Any,
                  mu_in: Any, lam0: float, la: float, lb: float,
                  rows_f: Any, M_f: Any, rhs_f: Any, sigma_f: float, cols_f: Any,
                  rows_s: Any, M_s: Any, rhs_s: Any, sigma_s: float, cols_s: Any, R: Any, hc: Any) -> None:
    r"""``R`` (primal rows, shape ``(n, d + 3)``, zero on entry) and ``hc`` (``d + 3``, zero on entry)
    of :meth:`~iamp.planners.avoid.dual.DualBounds.polynomial` for one polynomial vehicle in its
    piece, the basis :math:`1, \lambda, .., \lambda^{d+2}`: the multipliers move along their tangent
    ``mu_in``, :math:`y(\lambda) = \alpha + \lambda\beta` with :math:`\alpha = y - \lambda_c\beta`,
    each slope cut where its multiplier would turn negative on ``[la, lb]`` (to ``-y/Δλ (1 - 10⁻¹²)``
    at the end it reaches first, zero if it still would), so ``y(λ) >= 0`` on the box.  The kept rows
    (``keep``, independent of :math:`\lambda`) add :math:`-A^\top(\alpha + \lambda\beta)` to columns
    0 and 1 and their bounds to ``hc``; the split piece's rows (``f``, ``s``) their moving values
    (:func:`_split_terms`)."""
    S = nz.shape[0]
    mu = mu_in.copy()
    for e in range(2):
        end = la if e == 0 else lb
        dl = end - lam0
        if dl == 0.0:
            continue
        for r in range(S):
            if y[r] + dl * mu[r] < 0.0:
                mu[r] = -y[r] / dl * (1.0 - 1e-12)
    for r in range(S):
        if not (y[r] + (la - lam0) * mu[r] >= 0.0 and y[r] + (lb - lam0) * mu[r] >= 0.0):
            mu[r] = 0.0
    alpha = np.zeros(S)
    for r in range(S):
        alpha[r] = y[r] - lam0 * mu[r]
    for r in range(S):
        if keep[r]:
            row = nz[r]
            for a in range(indptr[row], indptr[row + 1]):
                R[indices[a], 0] -= alpha[r] * data[a]
                R[indices[a], 1] -= mu[r] * data[a]
            hc[0] += alpha[r] * u_in[row]
            hc[1] += mu[r] * u_in[row]
    _split_terms(rows_f, jidx, alpha, mu, M_f, rhs_f, sigma_f, cols_f, R, hc)
    _split_terms(rows_s, jidx, alpha, mu, M_s, rhs_s, sigma_s, cols_s, R, hc)


@compilable
def primal(R: Any, Kinv: Any, z0: Any, hc: Any, beq_x0: float, beq_x0_abs: float, Z: Any, lin: Any) -> float:
    r"""``Z`` (shape ``(n, C)``) :math:`= K^{-1}_{zz} R + z_0 e_0^\top` from the columns of
    :math:`K^{-1}_{zz}` at the rows where ``R`` has an entry (ascending; they must be solved), and
    ``lin`` :math:`= z_0^\top R + h_c` plus :math:`b^\top \nu_0` (``beq_x0``) on its first entry
    (:math:`(K^{-1}[0; b])_z = z_0` is the equality optimum, :math:`\nu^\top b` by the symmetry of
    ``K``).  Returns the size of ``lin``'s terms, :math:`\sum_c (|z_0|^\top |R_c| + |b|^\top
    |\nu_0|)` (``beq_x0_abs`` the last)."""
    n = Z.shape[0]
    C = Z.shape[1]
    # column by column into a contiguous buffer (each entry the same sum over the rows ``a`` in
    # ascending order, from 0.0), then copied into Z
    ZT = np.zeros((C, n))
    s = np.zeros(C)
    sa = np.zeros(C)
    for c in range(C):
        zc = ZT[c]
        for a in range(n):
            w = R[a, c]
            if w != 0.0:
                ka = Kinv[a]
                for i in range(n):
                    zc[i] += ka[i] * w
                s[c] += z0[a] * w
                sa[c] += abs(z0[a]) * abs(w)
    for i in range(n):
        for c in range(C):
            Z[i, c] = ZT[c, i]
        Z[i, 0] += z0[i]
    size = 0.0
    for c in range(C):
        lin[c] = s[c] + hc[c]
        size += sa[c] + beq_x0_abs
    lin[0] += beq_x0
    return size


@compilable
def coefficients(Z: Any, lin: Any, lin_abs: float, hc: Any, Pp: Any, Pi: Any, Px: Any, flat: Any, coef: Any) -> float:
    r"""``coef`` (flat, zero on entry): :math:`g = -\mathrm{lin} - \tfrac12 Z^\top P Z` per power, each
    basis term ``c`` adding ``-lin[c]`` to ``coef[flat[c]]``, then each product ``(c1, c2)`` (row by row)
    adding :math:`-\tfrac12 (Z^\top P Z)_{c_1 c_2}` to ``coef[flat[C + c1 C + c2]]`` (``P`` the full
    symmetric Hessian, CSC ``Pp, Pi, Px``).  Returns the size of the terms that cancel in ``g``:
    :math:`\tfrac12 w^\top |P| w` with :math:`w = |Z| 1`, plus ``lin_abs`` and :math:`\sum |hc|`
    (:attr:`~iamp.planners.avoid.dual.DualPolynomial.roundoff`, times ``ROUND_OFF_TERMS``)."""
    n = Z.shape[0]
    C = Z.shape[1]
    PZ = np.zeros((n, C))
    w = np.zeros(n)
    for j in range(n):
        for c in range(C):
            w[j] += abs(Z[j, c])
    Pw = np.zeros(n)
    for j in range(n):
        for k in range(Pp[j], Pp[j + 1]):
            i = Pi[k]
            v = Px[k]
            for c in range(C):
                PZ[i, c] += v * Z[j, c]
            Pw[i] += abs(v) * w[j]
    quad = 0.0
    for i in range(n):
        quad += w[i] * Pw[i]
    hsum = 0.0
    for c in range(C):
        coef[flat[c]] += -lin[c]
        hsum += abs(hc[c])
    # every product (c1, c2) in one pass over the rows (each the same sum over i ascending, from 0.0)
    ZPZ = np.zeros((C, C))
    for i in range(n):
        for c1 in range(C):
            zi = Z[i, c1]
            for c2 in range(C):
                ZPZ[c1, c2] += zi * PZ[i, c2]
    for c1 in range(C):
        for c2 in range(C):
            coef[flat[C + c1 * C + c2]] += -0.5 * ZPZ[c1, c2]
    return 0.5 * quad + lin_abs + hsum


@compilable
def binding_rows(y_all: Any, ids_all: Any, n_b: int, N: int, nb: int, m: int, indptr: Any, indices: Any) -> Any:
    """The rows of a solution with a positive multiplier, decoded from their layout numbers
    (:meth:`~iamp.planners.avoid.dual.DualBounds._decode`): from the multipliers ``y_all`` of the
    imposed rows and their layout numbers ``ids_all`` (``n_b`` Bernstein rows, ``N`` pieces, ``nb``
    Bernstein indices per piece; ``m`` vehicles; ``indptr, indices`` the rows' CSR arrays).

    Parameters
    ----------
    y_all, ids_all : ndarray
        The imposed rows' multipliers and layout numbers.
    n_b, N, nb, m : int
        The layout's sizes.
    indptr, indices : ndarray
        The imposed rows' CSR row pointers and column indices.

    Returns
    -------
    tuple of ndarray
        ``(nz, y, bern, veh, plane, piece, j, cols, mass)``: ``numpy.flatnonzero(y_all > 0)``, the
        multipliers there, per binding row whether it is a Bernstein row (``id < n_b``), its vehicle
        and half-plane axis (``blk // 2``, ``blk % 2`` of ``blk = id // (N nb)``, ``-1`` for a limit
        row), piece ``(id // nb) % N`` and Bernstein index ``id % nb`` (Python's floor division and
        remainder, as numpy's), the columns of the binding rows' entries (row after row, in stored
        order) and per vehicle the sum of the multipliers on its Bernstein rows (in row order from
        0.0: ``numpy.bincount``'s sums).
    """
    S = 0
    for r in range(y_all.shape[0]):
        if y_all[r] > 0.0:
            S += 1
    nz = np.empty(S, dtype=np.int64)
    y = np.empty(S)
    bern = np.empty(S, dtype=np.bool_)
    veh = np.empty(S, dtype=np.int64)
    plane = np.empty(S, dtype=np.int64)
    piece = np.empty(S, dtype=np.int64)
    j = np.empty(S, dtype=np.int64)
    mass = np.zeros(m)
    t = 0
    E = 0
    for r in range(y_all.shape[0]):
        if y_all[r] > 0.0:
            ident = ids_all[r]
            nz[t] = r
            y[t] = y_all[r]
            b = ident < n_b
            bern[t] = b
            blk = ident // (N * nb) if b else -1
            veh[t] = blk // 2
            plane[t] = blk % 2
            piece[t] = (ident // nb) % N
            j[t] = ident % nb
            if b:
                mass[blk // 2] += y_all[r]
            E += indptr[r + 1] - indptr[r]
            t += 1
    cols = np.empty(E, dtype=np.int64)
    e = 0
    for t in range(S):
        for a in range(indptr[nz[t]], indptr[nz[t] + 1]):
            cols[e] = indices[a]
            e += 1
    return nz, y, bern, veh, plane, piece, j, cols, mass


@compilable
def select_rows(bern: Any, veh: Any, plane: Any, piece: Any, i: int, pl: int, k: int) -> Any:
    """The positions (ascending) of the Bernstein rows of vehicle ``i``'s half-plane axis ``pl`` on
    piece ``k`` (:meth:`~iamp.planners.avoid.dual._Binding.split_rows`).

    Parameters
    ----------
    bern, veh, plane, piece : ndarray
        Per binding row, whether it is a Bernstein row, its vehicle, half-plane axis and piece.
    i, pl, k : int
        The vehicle, half-plane axis and piece.

    Returns
    -------
    ndarray of int64
        ``numpy.flatnonzero(bern & (veh == i) & (plane == pl) & (piece == k))``.
    """
    S = bern.shape[0]
    count = 0
    for r in range(S):
        if bern[r] and veh[r] == i and plane[r] == pl and piece[r] == k:
            count += 1
    out = np.empty(count, dtype=np.int64)
    t = 0
    for r in range(S):
        if bern[r] and veh[r] == i and plane[r] == pl and piece[r] == k:
            out[t] = r
            t += 1
    return out


@compilable
def kept_rows(bern: Any, veh: Any, plane: Any, piece: Any, first: Any, second: Any, split: Any, lo: Any, hi: Any,
              h: float, tol: float, keep: Any) -> None:
    """``keep`` (per binding row): the rows whose multipliers stay valid over the box ``[lo, hi]``
    (:meth:`~iamp.planners.avoid.dual.DualBounds.polynomial`): the limit rows, and of vehicle
    ``i``'s Bernstein rows (``first[i]``, ``second[i]`` its half-plane axes), where its box lies in
    piece ``split[i] >= 0``, the first half-plane's rows on the pieces before it and the second's
    after it, else (``split[i] < 0``) the first's on pieces that end by ``lo[i] + tol`` and the
    second's on pieces that start from ``hi[i] - tol``.

    Parameters
    ----------
    bern, veh, plane, piece : ndarray
        Per binding row, whether it is a Bernstein row, its vehicle, half-plane axis and piece.
    first, second, split : ndarray of int64
        Per vehicle, its half-plane axes and its box's piece (``-1``: none).
    lo, hi : ndarray
        The box.
    h, tol : float
        The grid step and the tolerance of a piece's end.
    keep : ndarray of bool
        Output.
    """
    for r in range(bern.shape[0]):
        if not bern[r]:
            keep[r] = True
            continue
        i = veh[r]
        k = split[i]
        p = piece[r]
        if k >= 0:
            keep[r] = (plane[r] == first[i] and p < k) or (plane[r] == second[i] and p > k)
        else:
            keep[r] = ((plane[r] == first[i] and (p + 1) * h <= lo[i] + tol)
                       or (plane[r] == second[i] and p * h >= hi[i] - tol))


@compilable
def ratio_limits(y: Any, mu: Any) -> Any:
    """The smallest ratio ``y / -μ`` over the multipliers falling along their tangent (``μ < 0``) and
    the smallest ``y / μ`` over those rising (``μ > 0``), each NaN where there is none or where a
    ratio is NaN (``numpy.min``'s)
    (:meth:`~iamp.planners.avoid.dual.DualBounds.tangent_interval`).

    Parameters
    ----------
    y, mu : ndarray
        The multipliers and their slopes.

    Returns
    -------
    tuple
        ``(down, has_down, up, has_up)``.
    """
    down = np.nan
    up = np.nan
    has_down = False
    has_up = False
    for r in range(y.shape[0]):
        if mu[r] < 0.0:
            v = y[r] / -mu[r]
            if not has_down:
                down = v
                has_down = True
            elif down == down and (v < down or v != v):
                down = v
        elif mu[r] > 0.0:
            v = y[r] / mu[r]
            if not has_up:
                up = v
                has_up = True
            elif up == up and (v < up or v != v):
                up = v
    return down, has_down, up, has_up
