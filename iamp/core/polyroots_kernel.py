r"""Kernels of :func:`iamp.core.polyroots.roots_in_unit_interval`, written once.

Plain Python over numpy arrays and scalars (loops, no BLAS or SIMD library calls), run compiled by
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

from iamp.core.jit import compilable

#: Bound on the coefficient backward error of the companion-matrix eigenvalues, relative to the
#: monic polynomial's :math:`(1 + \max_k |a_k|)^2` (the unbalanced worst case): about 45,000 times
#: the unit round-off 2.2e-16; the largest seen over 10^5 eigenvalues of stress polynomials
#: (``tests/test_safety_exact_speed.py``'s, degrees 3-7, leading coefficients down to 1e-21 of the
#: largest) was 2.7 times the unit round-off.
BACKWARD_REL = 1e-11


@compilable
def horner(C: Any, r: int, n: int, x: float) -> float:
    r""":math:`\sum_{k < n} C_{r,k} x^k` by Horner's rule from the highest power, starting at 0
    (:func:`iamp.core.polyroots.polyval_rows`' operations)."""
    out = 0.0
    for k in range(n - 1, -1, -1):
        out = out * x + C[r, k]
    return out


@compilable
def horner_deriv(C: Any, r: int, n: int, x: float) -> float:
    r"""The derivative of row ``r`` (``n`` coefficients) at ``x``: Horner's rule on
    :math:`(k + 1) C_{r,k+1}`, as :func:`iamp.core.polyroots.poly_deriv` then ``polyval_rows``."""
    out = 0.0
    for k in range(n - 2, -1, -1):
        out = out * x + C[r, k + 1] * (k + 1.0)
    return out


@compilable
def root_degrees(C: Any, M: Any, imag_tol: float, skip_far: bool, deg: Any) -> None:
    r"""``deg[r]``: the degree of row ``r`` of the ascending coefficients ``C`` (the highest
    ``k`` with :math:`|c_k| > 10^{-12} \max_j |c_j|`, 0 when none), or, with ``skip_far``, 0 when the
    row provably has no eigenvalue in the window: every Bernstein coefficient on :math:`[0, 1]` (``C[r] @ M``, ``M`` the
    matrix of :func:`iamp.core.polyroots._bernstein_matrix`) beyond :math:`T` with one sign, the
    bound on :math:`|p|` at any eigenvalue the solver could return in the accepted window
    (:func:`iamp.core.polyroots.roots_in_unit_interval`: :math:`|\mathrm{Im}\,z| \le` ``imag_tol``,
    :math:`\mathrm{Re}\,z \in [-10^{-9}, 1 + 10^{-9}]`).

    The computed eigenvalues of row :math:`p` (degree :math:`d`, leading coefficient :math:`\ell`)
    are exact roots of :math:`p/\ell + \delta a` with :math:`|\delta a_k| \le \epsilon_b (1 + \max_k
    |a_k|)^2` (:data:`BACKWARD_REL`), and of :math:`p` without its coefficients below
    :math:`10^{-12} \max_k |c_k|`; at such a root :math:`z` in the window, :math:`|p(z)| \le T`, with
    :math:`T` the sum of these perturbations on :math:`|z| \le 1.01` plus :math:`|z - x| \sum_k k |c_k|`
    (:math:`x` the nearest point of :math:`[0, 1]`) and the round-off of the Bernstein
    coefficients (in any order of summation).  When every Bernstein coefficient on :math:`[0, 1]`
    exceeds :math:`T` (or every one is below :math:`-T`), :math:`|p| > T` on the whole window, so
    the row has no root there; a row whose :math:`T` is not finite is kept."""
    K, D1 = C.shape
    for r in range(K):
        scale = abs(C[r, 0])
        for k in range(1, D1):
            a = abs(C[r, k])
            if a > scale or a != a:  # the largest, NaN when one is (numpy's max)
                scale = a
        d = 0
        for k in range(D1 - 1, -1, -1):
            if abs(C[r, k]) > 1e-12 * scale:
                d = k
                break
        lead = abs(C[r, d])
        if skip_far and D1 >= 2 and d > 0 and lead > 0:
            amax = scale / lead  # >= max_k |a_k| of the monic polynomial
            s0 = 0.0
            s1 = 0.0
            for k in range(D1):
                s0 += abs(C[r, k])
                s1 += k * abs(C[r, k])
            T = (BACKWARD_REL * 1.01 * (d + 1) * lead * ((1.0 + amax) * (1.0 + amax))
                 + 1.01 * (imag_tol + 1e-9) * s1 + 1e-12 * s0 + 1.1e-12 * D1 * scale)
            if T - T == 0.0:  # finite
                above = True
                below = True
                for j in range(D1):
                    b = 0.0
                    for k in range(j + 1):
                        b += C[r, k] * M[k, j]
                    if not b > T:
                        above = False
                    if not b < -T:
                        below = False
                if above or below:
                    d = 0
        deg[r] = d


@compilable
def polish_roots(C: Any, rows: Any, re: Any, im: Any, imag_tol: float, out_rows: Any, out_x: Any) -> int:
    r"""The eigenvalues ``re + i im`` of rows ``rows`` of ``C`` with :math:`|\mathrm{Im}| \le`
    ``imag_tol`` and :math:`\mathrm{Re} \in [-10^{-9}, 1 + 10^{-9}]`, in order: their real parts
    clipped to :math:`[0, 1]`, then three Newton steps :math:`x \leftarrow \mathrm{clip}(x - p/p')`
    (no step where :math:`p' = 0`), each kept only where it is not NaN and lowers :math:`|p|`.
    Writes ``out_rows[:n]``, ``out_x[:n]`` and returns ``n``."""
    D1 = C.shape[1]
    n = 0
    for j in range(rows.size):
        if abs(im[j]) <= imag_tol and re[j] >= -1e-9 and re[j] <= 1 + 1e-9:
            r = rows[j]
            x = re[j]
            if x < 0.0:  # numpy's clip: -0.0 stays, NaN stays
                x = 0.0
            elif x > 1.0:
                x = 1.0
            for _ in range(3):
                f = horner(C, r, D1, x)
                fp = horner_deriv(C, r, D1, x)
                step = f / fp if fp != 0 else 0.0
                xn = x - step
                if xn < 0.0:
                    xn = 0.0
                elif xn > 1.0:
                    xn = 1.0
                if xn == xn and abs(horner(C, r, D1, xn)) < abs(f):
                    x = xn
            out_rows[n] = r
            out_x[n] = x
            n += 1
    return n
