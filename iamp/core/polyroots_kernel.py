r"""Kernels of :func:`iamp.core.polyroots.roots_in_unit_interval`, written once.

Python over numpy arrays, column by column over all rows at once (elementwise operations and
comparisons only: no sums of a library, no BLAS), run compiled by
numba where it is installed (:func:`iamp.core.polyroots.kernel`: the same code compiled by
:func:`iamp.core.jit.twin`, no fastmath, so the same IEEE operations in the same order)
and as this Python itself otherwise; ``tests/test_polyroots_kernel.py`` compares the two bit for bit.
The eigenvalues between the two kernels stay numpy's (``numpy.linalg.eigvals``).

* :func:`root_degrees` — each row's degree (its highest coefficient above :math:`10^{-12}` of its
  largest), or 0 for a row that provably has no eigenvalue in the accepted window (the
  Bernstein test of :func:`iamp.core.polyroots.roots_in_unit_interval`'s docstring);
* :func:`polish_roots` — the eigenvalues in the accepted window, clipped to :math:`[0, 1]` and
  polished by three Newton steps, each kept only where it lowers :math:`|p|`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from iamp.core.jit import compilable, inlined

#: Bound on the coefficient backward error of the companion-matrix eigenvalues, relative to the
#: monic polynomial's :math:`(1 + \max_k |a_k|)^2` (the unbalanced worst case): about 45,000 times
#: the unit round-off 2.2e-16; the largest seen over 10^5 eigenvalues of stress polynomials
#: (``tests/test_safety_exact_speed.py``'s, degrees 3-7, leading coefficients down to 1e-21 of the
#: largest) was 2.7 times the unit round-off.
BACKWARD_REL = 1e-11


@inlined
def horner(C: Any, x: Any) -> Any:
    r""":math:`p_r(x_r)` of every row ``r`` of ``C`` by Horner's rule from the highest power, starting at 0
    (:func:`iamp.core.polyroots.polyval_rows`)."""
    out = np.zeros(x.size)
    for k in range(C.shape[1] - 1, -1, -1):
        out = out * x + C[:, k]
    return out


@inlined
def horner_deriv(C: Any, x: Any) -> Any:
    r"""The derivative of every row of ``C`` at ``x``: Horner's rule on :math:`(k + 1) C_{r,k+1}`, the
    numbers of :func:`iamp.core.polyroots.poly_deriv` then :func:`horner`."""
    out = np.zeros(x.size)
    for k in range(C.shape[1] - 2, -1, -1):
        out = out * x + C[:, k + 1] * (k + 1.0)
    return out


@compilable
def root_degrees(C: Any, M: Any, imag_tol: float, skip_far: bool, deg: Any) -> None:
    r"""``deg[r]``: the degree of row ``r`` of the ascending coefficients ``C`` (the highest
    ``k`` with :math:`|c_k| > 10^{-12} \max_j |c_j|`, 0 when none), or, with ``skip_far``, 0 when the
    row provably has no eigenvalue in the window: every Bernstein coefficient on :math:`[0, 1]`
    (``C[r] @ M``, ``M`` the matrix of :func:`iamp.core.polyroots._bernstein_matrix`) beyond :math:`T`
    with one sign, the bound on :math:`|p|` at any eigenvalue the solver could return in the accepted
    window (:func:`iamp.core.polyroots.roots_in_unit_interval`: :math:`|\mathrm{Im}\,z| \le` ``imag_tol``,
    :math:`\mathrm{Re}\,z \in [-10^{-9}, 1 + 10^{-9}]`).

    The computed eigenvalues of row :math:`p` (degree :math:`d`, leading coefficient :math:`\ell`)
    are exact roots of :math:`p/\ell + \delta a` with :math:`|\delta a_k| \le \epsilon_b (1 + \max_k
    |a_k|)^2` (:data:`BACKWARD_REL`), and of :math:`p` without its coefficients below
    :math:`10^{-12} \max_k |c_k|`; at such a root :math:`z` in the window, :math:`|p(z)| \le T`, with
    :math:`T` the sum of these perturbations on :math:`|z| \le 1.01` plus :math:`|z - x| \sum_k k |c_k|`
    (:math:`x` the nearest point of :math:`[0, 1]`) and the round-off of the Bernstein
    coefficients (in any order of summation).  When every Bernstein coefficient on :math:`[0, 1]`
    exceeds :math:`T` (or every one is below :math:`-T`), :math:`|p| > T` on the whole window, so
    the row has no root there; a row whose :math:`T` is not finite is kept.  Column by column over
    all rows at once (array operations, fast as Python too); overflow gives an infinite :math:`T`.

    A row whose constant term dominates, :math:`|c_0| > 2S + T` with :math:`S = \sum_{k \ge 1} |c_k|`
    (as computed; for rows whose largest :math:`|c_k|` lies in :math:`(10^{-200}, 10^{200})`, with at
    most 1,000 coefficients), is skipped without its Bernstein coefficients, as that test would skip
    it: :math:`b_j = c_0 + \sum_{1 \le k \le j} M_{kj} c_k` with :math:`0 \le M_{kj} \le 1`
    (:math:`M_{0j} = 1`), so each :math:`b_j` has :math:`c_0`'s sign and :math:`|b_j| \ge |c_0| - S`,
    which exceeds :math:`T` by about :math:`S`.  The round-off of the computed :math:`b_j` is at most
    :math:`\gamma_{D_1} (|c_0| + S)` (:math:`\gamma_{D_1} \le 1.2 \cdot 10^{-13}`), that of the test
    :math:`(\gamma_{D_1} + 2u)(S + T)`, and underflow adds at most :math:`10^{-320}`; as :math:`S \ge
    |c_d| > 10^{-12} \max_k |c_k| \ge 10^{-12} \max(|c_0|, T)`, together they stay below
    :math:`0.25\,S`: each computed :math:`b_j` is beyond :math:`T` as computed, with :math:`c_0`'s sign.
    The degrees are those of the Bernstein test on every row, bit for bit
    (``tests/test_verify_constant_term_skip.py``); on the 1,200 rows of the one-vehicle overtake's
    safety report 96 % are decided by their constant term, and only the others' Bernstein
    coefficients are computed."""
    K, D1 = C.shape
    # the columns as contiguous rows: each column operation below reads consecutive numbers
    # (the same numbers, operation for operation; 1.6 times faster compiled, 1.5 times as Python)
    Ct = np.ascontiguousarray(C.T)
    absC = np.abs(Ct)
    scale = absC[0].copy()
    for k in range(1, D1):
        scale = np.maximum(scale, absC[k])  # the largest, NaN when one is (no -0.0 after abs)
    thr = 1e-12 * scale
    d = np.zeros(K, dtype=np.int64)
    above_thr = np.empty(K, dtype=np.bool_)
    for k in range(1, D1):  # ascending: the last k set is the highest above the threshold
        np.greater(absC[k], thr, above_thr)
        d[above_thr] = k  # numpy.where(absC[k] > thr, k, d)
    if not skip_far or D1 < 2:
        deg[:] = d
        return
    lead = absC.ravel()[d * K + np.arange(K)]  # |c_d| of each row (0 <= d < D1)
    # the loops below write into arrays made once (ufuncs with an output array: the same
    # elementwise operations in the same order as ``s0 = s0 + absC[k]`` etc., so the same numbers,
    # without a new array per operation: 1.3 times faster compiled on 1,200 rows of degree 6)
    s0 = np.zeros(K)
    s1 = np.zeros(K)
    rest = np.zeros(K)  # sum of |c_k| over k >= 1 (the constant-term test below)
    t = np.empty(K)
    for k in range(D1):
        np.add(s0, absC[k], s0)
        np.multiply(absC[k], float(k), t)  # k * absC[k]: the same product
        np.add(s1, t, s1)
        if k > 0:
            np.add(rest, absC[k], rest)
    sent = (d > 0) & (lead > 0)  # the rows sent to the eigenvalues
    amax = scale / np.where(sent, lead, 1.0)  # >= max_k |a_k| of the monic polynomial
    T = (BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
         + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)
    ok = sent & np.isfinite(T)  # the rows the test may skip
    # a row whose constant term exceeds twice the others' magnitudes plus T is skipped without
    # its Bernstein coefficients: every one of them is beyond T with c_0's sign, so the test
    # below would skip it too (the docstring's argument: the same degrees); only the other rows
    # are tested (most rows of a safety report are decided here)
    if D1 <= 1000:
        by_constant = (absC[0] > 2.0 * rest + T) & (scale > 1e-200) & (scale < 1e200)
        near = np.flatnonzero(ok & ~by_constant)
    else:
        near = np.flatnonzero(ok)
    skip = ok.copy()  # a row of ok outside near is skipped by its constant term
    n = near.size
    if n > 0:
        Cn = np.ascontiguousarray(Ct[:, near])  # the rows tested, column by column
        Tn = T[near]
        nT = -Tn
        above = np.ones(n, dtype=np.bool_)
        below = np.ones(n, dtype=np.bool_)
        b = np.empty(n)
        tn = np.empty(n)
        c = np.empty(n, dtype=np.bool_)
        for j in range(D1):
            # from the first product rather than from 0: a partial sum can differ only in the sign of
            # a zero (x + y is y for y != 0, a zero for y = ±0), which no comparison below sees
            np.multiply(Cn[0], M[0, j], b)  # b = Ct[0] * M[0, j]
            for k in range(1, j + 1):
                np.multiply(Cn[k], M[k, j], tn)  # b = b + Ct[k] * M[k, j]
                np.add(b, tn, b)
            np.greater(b, Tn, c)  # above = above & (b > T)
            np.logical_and(above, c, above)
            np.less(b, nT, c)  # below = below & (b < -T): -T is exact
            np.logical_and(below, c, below)
        skip[near] = above | below
    deg[:] = np.where(skip, 0, d)


@compilable
def polish_roots(C: Any, rows: Any, re: Any, im: Any, imag_tol: float) -> Any:
    r"""The eigenvalues ``re + i im`` of rows ``rows`` of ``C`` with :math:`|\mathrm{Im}| \le`
    ``imag_tol`` and :math:`\mathrm{Re} \in [-10^{-9}, 1 + 10^{-9}]`, in order: their rows and their
    real parts clipped to :math:`[0, 1]`, then three Newton steps :math:`x \leftarrow \mathrm{clip}(x
    - p/p')` (no step where :math:`p' = 0`), each kept only where it is not NaN and lowers :math:`|p|`
    (numpy's clip: NaN and -0.0 stay)."""
    keep = np.flatnonzero((np.abs(im) <= imag_tol) & (re >= -1e-9) & (re <= 1 + 1e-9))
    r = rows[keep]
    Cr = C[r]
    x = re[keep]
    x = np.where(x < 0.0, 0.0, np.where(x > 1.0, 1.0, x))
    for _ in range(3):
        f = horner(Cr, x)
        fp = horner_deriv(Cr, x)
        nz = fp != 0
        step = np.where(nz, f / np.where(nz, fp, 1.0), 0.0)
        xn = x - step
        xn = np.where(xn < 0.0, 0.0, np.where(xn > 1.0, 1.0, xn))
        better = np.abs(horner(Cr, xn)) < np.abs(f)
        x = np.where(better & np.isfinite(xn), xn, x)
    return r, x
