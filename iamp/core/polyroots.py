r"""Many polynomials at once: real roots on ``[0, 1]`` and row-wise coefficient algebra.

Every array holds one polynomial per row in **ascending** powers,
:math:`p_r(\sigma) = \sum_{k=0}^{D} C_{r,k}\,\sigma^k`.  Roots come from the eigenvalues of
the companion matrix of each row (rows grouped by their true degree, so one batched
``eigvals`` per degree), polished by Newton steps :math:`\sigma \leftarrow \sigma -
p(\sigma)/p'(\sigma)` that are kept only where they lower :math:`|p|`.  A row whose Bernstein
coefficients on ``[0, 1]`` all exceed (in absolute value, with one sign) a bound on what the
eigenvalue solver's backward error, the complex tolerance and the round-off could make of it has no
root in the accepted window and is not sent to ``eigvals`` (:func:`_no_root_near_unit_interval`):
the roots returned are those of the full computation, bit for bit, since each row's eigenvalues
and Newton steps do not depend on the other rows.
"""

from __future__ import annotations

from math import comb

import numpy as np
from numpy.typing import NDArray

__all__ = ["pad_coeffs", "poly_deriv", "poly_mul", "polyval_rows", "roots_in_unit_interval"]

FloatArray = NDArray[np.float64]


def polyval_rows(C: FloatArray, x: FloatArray) -> FloatArray:
    """:math:`p_r(x_r)` for every row ``r`` (Horner)."""
    out = np.zeros_like(x)
    for k in range(C.shape[1] - 1, -1, -1):
        out = out * x + C[:, k]
    return out


def roots_in_unit_interval(C: FloatArray, imag_tol: float = 1e-6) -> tuple[NDArray[np.intp], FloatArray]:
    """Real roots in ``[0, 1]`` of many polynomials at once.

    Parameters
    ----------
    C : ndarray, shape (K, D + 1)
        Ascending coefficients, one polynomial per row.
    imag_tol : float
        Eigenvalues with ``|Im| <= imag_tol`` count as real (near-double roots; an extra cut
        point is harmless to every caller).

    Returns
    -------
    rows, sigma : ndarray
        Row index and root of every root found, polished by Newton steps.
    """
    C = np.asarray(C, dtype=float)
    D1 = C.shape[1]
    absC = np.abs(C)
    scale = np.max(absC, axis=1) if D1 else np.zeros(C.shape[0])
    big = absC > 1e-12 * scale[:, None]
    deg = np.where(big.any(axis=1), D1 - 1 - np.argmax(big[:, ::-1], axis=1), 0)
    # rows that provably have no eigenvalue in the accepted window are not sent to eigvals
    deg = np.where(_no_root_near_unit_interval(C, absC, scale, deg, imag_tol), 0, deg)
    rows_out: list[NDArray[np.intp]] = []
    roots_out: list[FloatArray] = []
    for d in np.unique(deg):
        d = int(d)
        if d == 0:
            continue
        idx = np.flatnonzero(deg == d)
        lead = C[idx, d]
        if d == 1:
            r = (-C[idx, 0] / lead)[:, None].astype(complex)
        else:
            comp = np.zeros((idx.size, d, d))
            comp[:, 1:, :-1] = np.eye(d - 1)
            comp[:, :, -1] = -C[idx, :d] / lead[:, None]
            r = np.linalg.eigvals(comp)
        ok = (np.abs(r.imag) <= imag_tol) & (r.real >= -1e-9) & (r.real <= 1 + 1e-9)
        ii, jj = np.nonzero(ok)
        rows_out.append(idx[ii])
        roots_out.append(np.clip(r.real[ii, jj], 0.0, 1.0))
    if not rows_out:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    rows, x = np.concatenate(rows_out), np.concatenate(roots_out)
    if rows.size:
        Cr = C[rows]
        dC = Cr[:, 1:] * np.arange(1, D1)
        for _ in range(3):
            f = polyval_rows(Cr, x)
            fp = polyval_rows(dC, x)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(fp != 0, f / fp, 0.0)
            xn = np.clip(x - step, 0.0, 1.0)
            better = np.abs(polyval_rows(Cr, xn)) < np.abs(f)
            x = np.where(better & np.isfinite(xn), xn, x)
    return rows, x


def _bernstein_matrix(n: int) -> FloatArray:
    """``M`` with ``C @ M`` the Bernstein coefficients on ``[0, 1]`` of ascending ``C`` of degree ``n``:
    :math:`b_j = \\sum_{k \\le j} \\binom{j}{k} / \\binom{n}{k}\\, c_k`."""
    M = _BERNSTEIN.get(n)
    if M is None:
        M = np.zeros((n + 1, n + 1))
        for j in range(n + 1):
            for k in range(j + 1):
                M[k, j] = comb(j, k) / comb(n, k)
        _BERNSTEIN[n] = M
    return M


_BERNSTEIN: dict[int, FloatArray] = {}
#: Bound on the coefficient backward error of the companion-matrix eigenvalues, relative to the
#: monic polynomial's :math:`(1 + \max_k |a_k|)^2` (the unbalanced worst case): about 45,000 times
#: the unit round-off 2.2e-16; the largest seen over 10^5 eigenvalues of stress polynomials
#: (``tests/test_safety_exact_speed.py``'s, degrees 3-7, leading coefficients down to 1e-21 of the
#: largest) was 2.7 times the unit round-off.
_BACKWARD_REL = 1e-11


def _no_root_near_unit_interval(C: FloatArray, absC: FloatArray, scale: FloatArray, deg: NDArray[np.intp],
                                imag_tol: float) -> NDArray[np.bool_]:
    r"""Rows for which no computed eigenvalue can fall in the window :func:`roots_in_unit_interval`
    accepts (:math:`|\mathrm{Im}\,z| \le` ``imag_tol``, :math:`\mathrm{Re}\,z \in [-10^{-9}, 1 + 10^{-9}]`).

    The computed eigenvalues of row :math:`p` (degree :math:`d`, leading coefficient :math:`\ell`)
    are exact roots of :math:`p/\ell + \delta a` with :math:`|\delta a_k| \le \epsilon_b (1 + \max_k
    |a_k|)^2` (:data:`_BACKWARD_REL`), and of :math:`p` without its coefficients below
    :math:`10^{-12} \max_k |c_k|`; at such a root :math:`z` in the window, :math:`|p(z)| \le T`, with
    :math:`T` the sum of these perturbations on :math:`|z| \le 1.01` plus :math:`|z - x| \sum_k k |c_k|`
    (:math:`x` the nearest point of :math:`[0, 1]`) and the round-off of the Bernstein
    coefficients.  When every Bernstein coefficient on :math:`[0, 1]` exceeds :math:`T` (or every one is
    below :math:`-T`), :math:`|p| > T` on the whole window, so the row has no root there.
    """
    K, D1 = C.shape
    if K == 0 or D1 < 2:
        return np.zeros(K, dtype=bool)
    b = C @ _bernstein_matrix(D1 - 1)
    lead = np.abs(C[np.arange(K), deg])
    sent = (deg > 0) & (lead > 0)  # the rows roots_in_unit_interval sends to the eigenvalues
    amax = scale / np.where(sent, lead, 1.0)  # >= max_k |a_k| of the monic polynomial
    with np.errstate(over="ignore", invalid="ignore"):
        T = (_BACKWARD_REL * 1.01 * (deg + 1) * lead * (1.0 + amax) ** 2
             + 1.01 * (imag_tol + 1e-9) * (absC @ np.arange(D1))
             + 1e-12 * absC.sum(axis=1) + 1.1e-12 * D1 * scale)
        out = (b.min(axis=1) > T) | (b.max(axis=1) < -T)
    no_root: NDArray[np.bool_] = out & sent & np.isfinite(T)
    return no_root


def poly_mul(A: FloatArray, B: FloatArray) -> FloatArray:
    """Row-wise product of ascending coefficient arrays."""
    out = np.zeros((A.shape[0], A.shape[1] + B.shape[1] - 1))
    for i in range(A.shape[1]):
        out[:, i:i + B.shape[1]] += A[:, [i]] * B
    return out


def pad_coeffs(A: FloatArray, n: int) -> FloatArray:
    """``A`` with zero coefficients appended up to ``n`` columns (degree ``n − 1``)."""
    if n < A.shape[1]:
        return np.pad(A, ((0, 0), (0, n - A.shape[1])))  # raises, as it always did
    # np.pad's result (its memory order too), without its overhead
    out = np.zeros((A.shape[0], n), dtype=A.dtype, order="F" if A.flags.fnc else "C")
    out[:, :A.shape[1]] = A
    return out


def poly_deriv(A: FloatArray) -> FloatArray:
    """Row-wise derivative: :math:`p'(\\sigma) = \\sum_k k\\,C_k\\,\\sigma^{k-1}`."""
    return A[:, 1:] * np.arange(1, A.shape[1])
