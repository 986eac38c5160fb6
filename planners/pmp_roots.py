r"""Real-root isolation on the unit interval, without eigenvalues (scalar and batched).

The one-vehicle contact time is a root of the stationarity polynomial
:math:`P(\sigma) = N'(\sigma)\,\sigma(1-\sigma) - 3N(\sigma)(1-2\sigma)` on
:math:`\sigma = t/t_f \in (0, 1)` (see :mod:`iamp.planners.pmp_search`).  Its roots are
isolated in the Bernstein basis of :math:`[0, 1]`,

.. math::  P(\sigma) = \sum_{j=0}^{n} \beta_j \binom{n}{j}\sigma^j(1-\sigma)^{n-j},\qquad
           \beta_j = \sum_{i \le j} \frac{\binom{j}{i}}{\binom{n}{i}}\, a_i ,

where :math:`a_i` are the monomial coefficients.  By Descartes' rule in Bernstein form, the
number of roots in the open interval is at most the number of sign variations
:math:`V(\beta)` and has the same parity: ``V = 0`` means no root, ``V = 1`` exactly one.
Intervals with ``V ≥ 2`` are halved by de Casteljau's algorithm until every piece has
``V ≤ 1`` (or is narrower than :data:`MIN_WIDTH`, a multiple root); each isolated root is
then found by Newton's method safeguarded by bisection inside its bracket.  Every root in
``(0, 1)`` is found; no companion matrix, no ``np.roots``.

The scalar functions use plain Python lists and loops on purpose: they are also compiled
unchanged by numba (:mod:`iamp.planners.pmp_compiled`), so both paths run the same
arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Narrowest interval subdivided; below it a cluster of roots counts as one (multiple) root.
MIN_WIDTH = 1e-13
#: Newton/bisection stops when the bracket is this narrow (relative to 1 = the horizon).
ROOT_XTOL = 4e-16


def bernstein_weights(n: int) -> list[list[float]]:
    """Row ``j``: the weights ``C(j,i)/C(n,i)``, ``i ≤ j``, of monomial → Bernstein."""
    return [[math.comb(j, i) / math.comb(n, i) for i in range(j + 1)] for j in range(n + 1)]


_WEIGHTS: dict[int, list[list[float]]] = {}


def to_bernstein(a: Sequence[float]) -> list[float]:
    """Bernstein coefficients on ``[0, 1]`` of the polynomial with ascending coefficients ``a``."""
    n = len(a) - 1
    w = _WEIGHTS.get(n)
    if w is None:
        w = _WEIGHTS[n] = bernstein_weights(n)
    out = [0.0] * (n + 1)
    for j in range(n + 1):
        wj = w[j]
        acc = 0.0
        for i in range(j + 1):
            acc += wj[i] * a[i]
        out[j] = acc
    return out


def sign_variations(b: Sequence[float]) -> int:
    """Sign changes of the sequence ``b``, zeros skipped."""
    v = 0
    last = 0.0
    for x in b:
        if x != 0.0:
            if last != 0.0 and (x > 0.0) != (last > 0.0):
                v += 1
            last = x
    return v


def casteljau_halves(b: Sequence[float]) -> tuple[list[float], list[float]]:
    """Bernstein coefficients of the left and right halves of the interval (de Casteljau)."""
    work = list(b)
    n = len(work) - 1
    left = [work[0]]
    right = [work[n]]
    for r in range(1, n + 1):
        for i in range(n - r + 1):
            work[i] = 0.5 * (work[i] + work[i + 1])
        left.append(work[0])
        right.append(work[n - r])
    right.reverse()
    return left, right


def horner2(a: Sequence[float], x: float) -> tuple[float, float]:
    """``(p(x), p'(x))`` for ascending coefficients ``a``."""
    p = 0.0
    dp = 0.0
    for k in range(len(a) - 1, -1, -1):
        dp = dp * x + p
        p = p * x + a[k]
    return p, dp


def newton_in_bracket(a: Sequence[float], lo: float, hi: float) -> float:
    """The single root of ``a`` in ``(lo, hi)`` (``p(lo)``, ``p(hi)`` of opposite signs):
    Newton's method from the midpoint, falling back to bisection whenever a step leaves
    the bracket; the bracket shrinks every iteration."""
    plo, _ = horner2(a, lo)
    if plo == 0.0:  # the bracket's end is an exact root
        return lo
    x = 0.5 * (lo + hi)
    for _ in range(200):
        p, dp = horner2(a, x)
        if p == 0.0:
            return x
        if (p > 0.0) == (plo > 0.0):
            lo = x
            plo = p
        else:
            hi = x
        if hi - lo <= ROOT_XTOL:
            break
        nx = x - p / dp if dp != 0.0 else lo - 1.0
        if not lo < nx < hi:
            nx = 0.5 * (lo + hi)
        if abs(nx - x) <= ROOT_XTOL:
            x = nx
            break
        x = nx
    return x


def unit_roots(a: Sequence[float]) -> list[float]:
    """Every real root in ``(0, 1)`` of the polynomial with ascending coefficients ``a``,
    sorted (a multiple root is returned once, to about ``MIN_WIDTH``)."""
    n = len(a) - 1
    while n > 0 and a[n] == 0.0:
        n -= 1
    if n < 1:
        return [0.0] * 0  # a typed empty list (numba)
    coeffs = [float(a[i]) for i in range(n + 1)]
    out = [0.0] * 0
    # the stack holds (lo, hi) and the Bernstein coefficients of each pending interval
    los = [0.0]
    his = [1.0]
    bs = [to_bernstein(coeffs)]
    while len(los) > 0:
        lo = los.pop()
        hi = his.pop()
        b = bs.pop()
        v = sign_variations(b)
        if v == 0:
            continue
        if v == 1 and b[0] != 0.0 and b[n] != 0.0:
            out.append(newton_in_bracket(coeffs, lo, hi))
            continue
        mid = 0.5 * (lo + hi)
        if hi - lo < MIN_WIDTH:
            out.append(mid)
            continue
        left, right = casteljau_halves(b)
        if horner2(coeffs, mid)[0] == 0.0:  # an exact root on the split point
            out.append(mid)
        los.append(mid)
        his.append(hi)
        bs.append(right)
        los.append(lo)
        his.append(mid)
        bs.append(left)
    out.sort()
    dedup = [0.0] * 0
    for r in out:
        if 0.0 < r < 1.0 and (len(dedup) == 0 or r - dedup[-1] > 4 * MIN_WIDTH):
            dedup.append(r)
    return dedup


# ------------------------------------------------------------------------------------------
# Batched version (one polynomial per row)
# ------------------------------------------------------------------------------------------


def bernstein_matrix(n: int) -> FloatArray:
    """``B`` with ``β = a @ B`` for rows of ascending coefficients of degree ``n``."""
    W = np.zeros((n + 1, n + 1))
    for j, row in enumerate(bernstein_weights(n)):
        W[: j + 1, j] = row
    return W


def _variations_rows(beta: FloatArray) -> npt.NDArray[np.int64]:
    """:func:`sign_variations` of every row (zeros skipped)."""
    s = np.sign(beta)
    nz = s != 0
    idx = np.where(nz, np.arange(beta.shape[1]), 0)
    prev = np.maximum.accumulate(idx, axis=1)
    last = np.take_along_axis(s, prev, axis=1)
    out: npt.NDArray[np.int64] = np.sum(nz[:, 1:] & (s[:, 1:] != last[:, :-1]) & (last[:, :-1] != 0), axis=1)
    return out


def _casteljau_rows(B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`casteljau_halves` of every row."""
    work = B.copy()
    n = B.shape[1] - 1
    left = np.empty_like(B)
    right = np.empty_like(B)
    left[:, 0] = work[:, 0]
    right[:, n] = work[:, n]
    for r in range(1, n + 1):
        work[:, : n - r + 1] = 0.5 * (work[:, : n - r + 1] + work[:, 1: n - r + 2])
        left[:, r] = work[:, 0]
        right[:, n - r] = work[:, n - r]
    return left, right


def batch_unit_roots(Pc: FloatArray) -> FloatArray:
    """All roots in ``(0, 1)`` of every row of ``Pc`` (ascending coefficients, ``(K, n+1)``).

    The same isolation as :func:`unit_roots`, vectorised over rows and pending intervals
    (Bernstein variations, de Casteljau halving), then :func:`newton_in_bracket` on every
    isolating interval at once; rows whose own leading coefficient is zero go through
    :func:`unit_roots`.  Returns ``(K, n)`` sorted per row, NaN padded.
    """
    while Pc.shape[1] > 2 and not np.any(Pc[:, -1]):  # leading zeros shared by every row
        Pc = Pc[:, :-1]
    K, n1 = Pc.shape
    n = n1 - 1
    out = np.full((K, max(n, 1)), np.nan)
    full = Pc[:, -1] != 0
    rows = np.flatnonzero(full)
    owner = rows.copy()
    lo = np.zeros(rows.size)
    hi = np.ones(rows.size)
    B = Pc[rows] @ bernstein_matrix(n)
    found_owner, found_lo, found_hi, found_mid = [], [], [], []
    while owner.size:
        v = _variations_rows(B)
        iso = (v == 1) & (B[:, 0] != 0) & (B[:, -1] != 0)
        found_owner.append(owner[iso])
        found_lo.append(lo[iso])
        found_hi.append(hi[iso])
        found_mid.append(np.zeros(int(iso.sum()), dtype=bool))
        split = (v >= 1) & ~iso
        mid = 0.5 * (lo + hi)
        tiny = split & (hi - lo < MIN_WIDTH)
        found_owner.append(owner[tiny])
        found_lo.append(mid[tiny])
        found_hi.append(mid[tiny])
        found_mid.append(np.ones(int(tiny.sum()), dtype=bool))
        split &= ~tiny
        L, R = _casteljau_rows(B[split])
        msp = mid[split]
        pm = np.zeros(msp.size)
        for k in range(n, -1, -1):
            pm = pm * msp + Pc[owner[split], k]
        at_mid = pm == 0.0  # an exact root on the split point
        found_owner.append(owner[split][at_mid])
        found_lo.append(mid[split][at_mid])
        found_hi.append(mid[split][at_mid])
        found_mid.append(np.ones(int(at_mid.sum()), dtype=bool))
        owner = np.concatenate([owner[split], owner[split]])
        lo, hi = np.concatenate([lo[split], mid[split]]), np.concatenate([mid[split], hi[split]])
        B = np.vstack([L, R])
    fo = np.concatenate(found_owner)
    flo, fhi, fmid = np.concatenate(found_lo), np.concatenate(found_hi), np.concatenate(found_mid)
    roots = np.where(fmid, flo, 0.0)
    need = ~fmid
    if np.any(need):
        roots[need] = _batch_newton(Pc[fo[need]], flo[need], fhi[need])
    order = np.lexsort((roots, fo))
    fo, roots = fo[order], roots[order]
    keep = (roots > 0.0) & (roots < 1.0)
    same = np.r_[False, (fo[1:] == fo[:-1]) & (roots[1:] - roots[:-1] <= 4 * MIN_WIDTH)]
    fo, roots = fo[keep & ~same], roots[keep & ~same]
    start = np.searchsorted(fo, fo, side="left")
    out[fo, np.arange(fo.size) - start] = roots
    for r in np.flatnonzero(~full):
        rr = unit_roots(Pc[r].tolist())
        out[r, : len(rr)] = rr
    return out


def _batch_newton(A: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """Vectorised :func:`newton_in_bracket` (one bracket and polynomial per row)."""
    K, n1 = A.shape
    lo = lo.copy()
    hi = hi.copy()
    plo = np.zeros(K)
    for k in range(n1 - 1, -1, -1):
        plo = plo * lo + A[:, k]
    x = np.where(plo == 0.0, lo, 0.5 * (lo + hi))  # an exact root at the bracket's end
    done = plo == 0.0
    for _ in range(200):
        p = np.zeros(K)
        dp = np.zeros(K)
        for k in range(n1 - 1, -1, -1):
            dp = dp * x + p
            p = p * x + A[:, k]
        exact = p == 0.0
        same = (p > 0.0) == (plo > 0.0)
        act = ~done & ~exact
        lo = np.where(act & same, x, lo)
        plo = np.where(act & same, p, plo)
        hi = np.where(act & ~same, x, hi)
        done |= exact | (hi - lo <= ROOT_XTOL)
        with np.errstate(divide="ignore", invalid="ignore"):
            nx = np.where(dp != 0.0, x - p / dp, lo - 1.0)
        nx = np.where((lo < nx) & (nx < hi), nx, 0.5 * (lo + hi))
        small = np.abs(nx - x) <= ROOT_XTOL
        x = np.where(done, x, nx)
        done |= small
        if done.all():
            break
    return x
