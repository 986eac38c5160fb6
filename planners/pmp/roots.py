r"""Real-root isolation on the unit interval, without eigenvalues.

The one-vehicle contact time is a root of the stationarity polynomial
:math:`P(\sigma) = N'(\sigma)\,\sigma(1-\sigma) - 3N(\sigma)(1-2\sigma)` on
:math:`\sigma = t/t_f \in (0, 1)` (see :mod:`iamp.planners.pmp.search`).  Its roots are
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
unchanged by numba (:mod:`iamp.planners.pmp.jit`), so both paths run the same arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .jit import compilable, compiled_as

#: Narrowest interval subdivided; below it a cluster of roots counts as one (multiple) root.
MIN_WIDTH = 1e-13
#: Newton/bisection stops when the bracket is this narrow (relative to 1 = the horizon).
ROOT_XTOL = 4e-16


def bernstein_weights(n: int) -> list[list[float]]:
    """Row ``j``: the weights ``C(j,i)/C(n,i)``, ``i ≤ j``, of monomial → Bernstein."""
    return [[math.comb(j, i) / math.comb(n, i) for i in range(j + 1)] for j in range(n + 1)]


_WEIGHTS: dict[int, list[list[float]]] = {}


def _to_bernstein_inline(a: Sequence[float]) -> list[float]:
    """:func:`to_bernstein` as numba compiles it: the weights ``C(j,i)/C(n,i)`` computed in place
    (binomials as exact integer-valued floats, one correctly rounded division: the values
    :func:`bernstein_weights` caches), the same sums in the same order."""
    n = len(a) - 1
    out = [0.0] * (n + 1)
    for j in range(n + 1):
        acc = 0.0
        for i in range(j + 1):
            cj = 1.0
            cn = 1.0
            for k in range(i):
                cj = cj * (j - k) / (k + 1)
                cn = cn * (n - k) / (k + 1)
            acc += (cj / cn) * a[i]
        out[j] = acc
    return out


@compiled_as(_to_bernstein_inline)
def to_bernstein(a: Sequence[float]) -> list[float]:
    """Bernstein coefficients on ``[0, 1]`` of the polynomial with ascending coefficients ``a``
    (``β_j = Σ_{i≤j} w_ji a_i`` summed from ``0.0`` in ascending ``i``)."""
    n = len(a) - 1
    w = _WEIGHTS.get(n)
    if w is None:
        w = _WEIGHTS[n] = bernstein_weights(n)
    out = [0.0] * (n + 1)
    for j in range(n + 1):
        acc = 0.0
        i = 0
        for wji in w[j]:  # i = 0..j, ascending
            acc += wji * a[i]
            i += 1
        out[j] = acc
    return out


@compilable
def sign_variations(b: Sequence[float]) -> int:
    """Sign changes of the sequence ``b``, zeros skipped (a NaN counts as negative)."""
    v = 0
    last = 0  # sign of the last non-zero entry: 1, -1, or 0 before the first
    for x in b:
        if x > 0.0:
            if last < 0:
                v += 1
            last = 1
        elif x != 0.0:
            if last > 0:
                v += 1
            last = -1
    return v


@compilable
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


@compilable
def horner2(a: Sequence[float], x: float) -> tuple[float, float]:
    """``(p(x), p'(x))`` for ascending coefficients ``a``."""
    p = 0.0
    dp = 0.0
    for k in range(len(a) - 1, -1, -1):
        dp = dp * x + p
        p = p * x + a[k]
    return p, dp


@compilable
def newton_in_bracket(a: Sequence[float], lo: float, hi: float) -> float:
    """The single root of ``a`` in ``(lo, hi)`` (``p(lo)``, ``p(hi)`` of opposite signs):
    Newton's method from the midpoint, falling back to bisection whenever a step leaves
    the bracket; the bracket shrinks every iteration.

    This is the planner's innermost loop, so the Horner evaluations of :func:`horner2` are
    written out: for degree ≤ 6 (every cubic ``x_poly``) term by term with zero leading
    coefficients (``0·x + c = c``, so the values are those of the loop), beyond as a loop
    over the descending coefficients; the same operations in the same order either way."""
    n = len(a) - 1
    small = n <= 6
    c0 = a[0]
    c1 = a[1] if n >= 1 else 0.0
    c2 = a[2] if n >= 2 else 0.0
    c3 = a[3] if n >= 3 else 0.0
    c4 = a[4] if n >= 4 else 0.0
    c5 = a[5] if n >= 5 else 0.0
    c6 = a[6] if n >= 6 else 0.0
    rev = [0.0] * 0 if small else [a[n - k] for k in range(n + 1)]  # descending coefficients
    if small:
        plo = (((((c6 * lo + c5) * lo + c4) * lo + c3) * lo + c2) * lo + c1) * lo + c0
    else:
        plo = 0.0
        for c in rev:
            plo = plo * lo + c
    if plo == 0.0:  # the bracket's end is an exact root
        return lo
    lo_pos = plo > 0.0
    x = 0.5 * (lo + hi)
    for _ in range(200):
        if small:
            p = c6 * x + c5
            dp = c6
            dp = dp * x + p
            p = p * x + c4
            dp = dp * x + p
            p = p * x + c3
            dp = dp * x + p
            p = p * x + c2
            dp = dp * x + p
            p = p * x + c1
            dp = dp * x + p
            p = p * x + c0
        else:
            p = 0.0
            dp = 0.0
            for c in rev:
                dp = dp * x + p
                p = p * x + c
        if p == 0.0:
            return x
        if (p > 0.0) == lo_pos:
            lo = x
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


@compilable
def unit_roots(a: Sequence[float]) -> list[float]:
    """Every real root in ``(0, 1)`` of the polynomial with ascending coefficients ``a``,
    sorted (a multiple root is returned once, to about ``MIN_WIDTH``)."""
    n = len(a) - 1
    while n > 0 and a[n] == 0.0:
        n -= 1
    if n < 1:
        return [0.0] * 0  # a typed empty list (numba)
    coeffs = [float(a[i]) for i in range(n + 1)]
    b = to_bernstein(coeffs)
    v = sign_variations(b)
    if v == 0:
        return [0.0] * 0
    if v == 1 and b[0] != 0.0 and b[n] != 0.0:  # one root, isolated by [0, 1] itself
        r = newton_in_bracket(coeffs, 0.0, 1.0)
        return [r] if 0.0 < r < 1.0 else [0.0] * 0
    out = [0.0] * 0
    # the stack holds (lo, hi) and the Bernstein coefficients of each pending interval
    los = [0.0]
    his = [1.0]
    bs = [b]
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
