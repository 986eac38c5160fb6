r"""Kernels of the crossing-time search (:mod:`iamp.planners.avoid.continuous`), written once.

Plain Python over numpy arrays and scalars (loops, no BLAS or SIMD library calls): every sum and
power runs in one fixed order (``d * d * d``, never ``pow``), so the numbers depend neither on the
machine nor on whether numba is installed.  Each function is marked
:func:`~iamp.planners.pmp.jit.compilable`: where numba is installed the search runs its twin (the
same code compiled, no fastmath: the same IEEE operations in the same order, the same numbers bit
for bit; ``tests/test_avoid_search_kernel.py`` compares the two), else this Python function itself.

* :func:`candidate_tau` — a box's candidate crossing times (a max-min of the relaxed optimum's
  half-plane margins on samples of the box,
  :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner._candidate_tau`);
* :func:`valid_polys` — the stored dual polynomials that bound a box
  (:meth:`~iamp.planners.avoid.dual.DualStore.valid`);
* :func:`polys_max` — the largest of several dual polynomials at each of several crossing
  times (:meth:`~iamp.planners.avoid.dual.DualPolynomial.evaluate`, the search's probe);
* :func:`poly_bounds` — the lower bound of each of several dual polynomials on a box, its smallest
  tensor Bernstein coefficient there less a round-off margin (:func:`~iamp.planners.avoid.dual.lower_bounds`);
* :func:`max_poly_bound` — the largest of those bounds, bounding only the polynomials that can reach
  it (:func:`~iamp.planners.avoid.dual.max_lower_bound`).
"""

from __future__ import annotations

from math import inf
from typing import Any

from iamp.planners.pmp.jit import compilable, inlined


@inlined
def held_position(z: Any, t_nodes: Any, N: int, block: int, foh: bool, axis: int, t: float) -> float:
    r"""The position ``s_axis(t)`` of the held trajectory of the QP variables ``z`` (layout of
    :class:`~iamp.planners.qp.data.StateIndex`: per axis ``block`` variables, ``s_0..s_N``,
    ``v_0..v_N``, then the inputs) on the grid ``t_nodes``: on the piece ``k`` holding ``t`` (the
    last node ``<= t``, clipped to ``0..N-1``), with :math:`\delta = t - t_k`,
    :math:`s_k + v_k\delta + u_k\delta^2/2 + \dot u\,\delta^3/6` (FOH,
    :math:`\dot u = (u_{k+1} - u_k)/h_k`) or without the last term (ZOH), as
    :class:`~iamp.core.hold_trajectory.HoldTrajectory` (its powers as products)."""
    lo = 0
    hi = N + 1
    while lo < hi:  # the number of nodes <= t
        mid = (lo + hi) // 2
        if t_nodes[mid] <= t:
            lo = mid + 1
        else:
            hi = mid
    k = lo - 1
    if k < 0:
        k = 0
    if k > N - 1:
        k = N - 1
    d: float = t - t_nodes[k]
    base = axis * block
    s0: float = z[base + k]
    v0: float = z[base + N + 1 + k]
    u0: float = z[base + 2 * (N + 1) + k]
    if not foh:
        return s0 + v0 * d + u0 * (d * d) / 2
    h: float = t_nodes[k + 1] - t_nodes[k]
    du: float = (z[base + 2 * (N + 1) + k + 1] - u0) / h
    return s0 + v0 * d + u0 * (d * d) / 2 + du * (d * d * d) / 6


@inlined
def plane_margin(i: int, plane: int, t: float, s: float, sigma: Any, half: Any, lateral: Any, polys: Any,
                 plen: Any) -> float:
    r"""Vehicle ``i``'s half-plane ``plane`` (0 = ``H_x``, 1 = ``H_y``): the margin
    :math:`c(t) - \sigma s` of :class:`~iamp.planners.avoid.data.HalfPlane` (``sigma[i, plane]``,
    ``half[i, plane]`` the half size plus safety margin, ``lateral[i]`` the vehicle's ``y``,
    ``polys[i, :plen[i]]`` its ``x_s`` coefficients, evaluated by Horner's rule from the highest
    as numpy's ``polyval``)."""
    sg: float = sigma[i, plane]
    if plane == 0:
        n = plen[i]
        c0 = polys[i, n - 1] + t * 0.0
        for j in range(2, n + 1):
            c0 = polys[i, n - j] + c0 * t
        bound: float = -(c0 + half[i, 0]) if sg < 0 else c0 - half[i, 0]
    else:
        bound = -(lateral[i] + half[i, 1]) if sg < 0 else lateral[i] - half[i, 1]
    return bound - sg * s


@compilable
def candidate_tau(z: Any, t_nodes: Any, N: int, block: int, foh: bool, lo: Any, hi: Any, orders: Any,
                  sigma: Any, half: Any, lateral: Any, polys: Any, plen: Any, T: Any, mf: Any, ms: Any,
                  out: Any, worst: Any) -> None:
    """Per vehicle ``i`` with orders ``orders[i] = (first, second)``: ``n = T.shape[1]`` samples of
    ``[lo_i, hi_i]`` into ``T[i]`` (as ``numpy.linspace`` of the arrays ``lo, hi``: ``j · step + lo``,
    or ``(j / (n - 1)) · (hi - lo) + lo`` when some vehicle's step is zero, the last sample
    ``hi``); the margins of the first half-plane ``mf`` and of the second ``ms`` of the held
    trajectory of ``z`` (:func:`held_position`, :func:`plane_margin`); the score
    ``min(min(mf[:j+1]), min(ms[j:]))``; ``out[i]`` the first sample of the largest score and
    ``worst[i]`` that score."""
    m = lo.shape[0]
    n = T.shape[1]
    div = n - 1
    any_zero = False
    for i in range(m):
        if (hi[i] - lo[i]) / div == 0.0:
            any_zero = True
    for i in range(m):
        delta = hi[i] - lo[i]
        step = delta / div
        for j in range(n):
            if any_zero:
                T[i, j] = j / div * delta + lo[i]
            else:
                T[i, j] = j * step + lo[i]
        T[i, n - 1] = hi[i]
        f = orders[i, 0]
        s = orders[i, 1]
        for j in range(n):
            t = T[i, j]
            mf[j] = plane_margin(i, f, t, held_position(z, t_nodes, N, block, foh, f, t), sigma, half, lateral,
                                 polys, plen)
            ms[j] = plane_margin(i, s, t, held_position(z, t_nodes, N, block, foh, s, t), sigma, half, lateral,
                                 polys, plen)
        for j in range(1, n):  # running minimum of mf forward, of ms backward
            if mf[j - 1] < mf[j]:
                mf[j] = mf[j - 1]
        for j in range(n - 2, -1, -1):
            if ms[j + 1] < ms[j]:
                ms[j] = ms[j + 1]
        best = 0
        best_score = mf[0] if mf[0] < ms[0] else ms[0]
        for j in range(1, n):
            score = mf[j] if mf[j] < ms[j] else ms[j]
            if score > best_score:
                best = j
                best_score = score
        out[i] = T[i, best]
        worst[i] = best_score


@compilable
def valid_polys(LO: Any, HI: Any, B: Any, O: Any, want: Any, lo: Any, hi: Any, out: Any) -> int:
    """The polynomials ``p`` (their numbers into ``out``, ascending; returns how many) whose region
    holds the box ``[lo, hi]`` with the orders ``want`` (shape ``(m, 2)``): for every vehicle ``i``,
    ``LO[p, i] <= lo[i]`` and ``hi[i] <= HI[p, i]``, and, where the polynomial binds the vehicle
    (``B[p, i]``), the same orders ``O[p, i] == want[i]``."""
    n = 0
    for p in range(LO.shape[0]):
        ok = True
        for i in range(LO.shape[1]):
            if not (lo[i] >= LO[p, i] and hi[i] <= HI[p, i]):
                ok = False
                break
            if B[p, i] and (O[p, i, 0] != want[i, 0] or O[p, i, 1] != want[i, 1]):
                ok = False
                break
        if ok:
            out[n] = p
            n += 1
    return n


@inlined
def tensor_polyval(coef: Any, start: int, q: int, n: int, lam: Any, work: Any) -> float:
    """The tensor polynomial with power coefficients ``coef[start:start + n**q]`` (C order, shape
    ``(n,) * q``) at ``λ = lam[:q]``: Horner's rule along the last axis for every index of the
    others, then along the one before, ... (``work``: space for ``n**q`` numbers)."""
    size = 1
    for _ in range(q):
        size *= n
    for t in range(size):
        work[t] = coef[start + t]
    for a in range(q - 1, -1, -1):
        x = lam[a]
        size = size // n
        for r in range(size):
            acc = work[r * n + n - 1]
            for j in range(n - 2, -1, -1):
                acc = acc * x + work[r * n + j]
            work[r] = acc
    out: float = work[0]
    return out


@inlined
def sizes_to_starts(meta: Any) -> None:
    """The sizes in column 2 of ``meta`` (one row per polynomial, :func:`~iamp.planners.avoid.dual._pack`)
    replaced by the polynomials' starts in the coefficients laid end to end (an exclusive running sum)."""
    acc = 0
    for p in range(meta.shape[0]):
        size = meta[p, 2]
        meta[p, 2] = acc
        acc += size


@compilable
def polys_max(coef: Any, meta: Any, W: int, h: float, taus: Any, out: Any, lam: Any, work: Any) -> None:
    """``out[t]`` the largest over the polynomials ``p`` of :func:`tensor_polyval` at the crossing
    times ``taus[t]`` (shape ``(T, m)``).  Row ``p`` of ``meta`` describes polynomial ``p``
    (:func:`~iamp.planners.avoid.dual._pack`): its number of axes ``q = meta[p, 0]`` of
    ``n = meta[p, 1]`` coefficients each, its size ``meta[p, 2]`` (its coefficients follow the
    previous ones' in ``coef``; replaced by its start, :func:`sizes_to_starts`), its vehicles
    ``meta[p, 3:3 + q]`` and their pieces ``meta[p, 3 + W:3 + W + q]``; on axis ``a``
    ``λ_a = (τ_v - k h) / h`` (``lam``, ``work``: space)."""
    sizes_to_starts(meta)
    for t in range(taus.shape[0]):
        best = 0.0
        for p in range(meta.shape[0]):
            q = meta[p, 0]
            for a in range(q):
                lam[a] = (taus[t, meta[p, 3 + a]] - meta[p, 3 + W + a] * h) / h
            v = tensor_polyval(coef, meta[p, 2], q, meta[p, 1], lam, work)
            if p == 0 or v > best or not v == v:
                best = v
            if not best == best:
                break
        out[t] = best


@inlined
def poly_shape(meta: Any, p: int) -> tuple[int, int, int]:
    """Polynomial ``p``'s number of axes ``q``, coefficients per axis ``n`` and size ``n**q`` (row ``p``
    of ``meta``, as for :func:`polys_max`)."""
    q = meta[p, 0]
    n = meta[p, 1]
    size = 1
    for _ in range(q):
        size *= n
    return q, n, size


@inlined
def local_interval(meta: Any, W: int, p: int, a: int, h: float, lo: Any, hi: Any) -> tuple[float, float]:
    r"""The box ``[lo, hi]``'s interval on axis ``a`` of polynomial ``p`` (row ``p`` of ``meta``, as for
    :func:`polys_max`) in its piece's local coordinate, :math:`[\lambda_a, \lambda_b]`:
    :math:`(\tau - k h)/h` of both ends, clipped to ``[0, 1]``, with :math:`\lambda_b \ge \lambda_a`."""
    v = meta[p, 3 + a]
    k = meta[p, 3 + W + a]
    la = (lo[v] - k * h) / h
    la = 0.0 if la < 0.0 else (1.0 if la > 1.0 else la)
    lb = (hi[v] - k * h) / h
    lb = la if lb < la else (1.0 if lb > 1.0 else lb)
    return la, lb


@compilable
def poly_bound(coef: Any, meta: Any, W: int, p: int, h: float, lo: Any, hi: Any, binom: Any, p2b: Any, work: Any,
               spare: Any, pw_a: Any, R: Any, kept: Any) -> float:
    r"""The smallest tensor Bernstein coefficient of polynomial ``p`` (row ``p`` of ``meta`` as for
    :func:`polys_max`, its starts in place: power coefficients ``coef[start:start + n**q]``, C order,
    shape ``(n,) * q``; axis ``a`` the local coordinate :math:`\lambda` of its vehicle
    ``meta[p, 3 + a]`` in its piece ``meta[p, 3 + W + a]``) on the box
    ``[lo, hi]``: per axis the box's interval in that coordinate, :math:`[\lambda_a, \lambda_b]`
    (clipped to ``[0, 1]``, :math:`\lambda_b \ge \lambda_a`), and along it (first axis to last)
    the power coefficients of :math:`p(\lambda_a + w\rho)`, :math:`w = \lambda_b - \lambda_a`,
    :math:`c'_r = \sum_{i \ge r} \binom{i}{r} \lambda_a^{i-r} w^r c_i`
    (:func:`~iamp.planners.avoid.bernstein.reparametrise`), then their Bernstein coefficients on
    ``[0, 1]``, :math:`b_r = \sum_{j \le r} \binom{r}{j}/\binom{d}{j}\, c'_j`
    (:func:`~iamp.planners.avoid.bernstein.power_to_bernstein`; ``binom[i, j]`` the binomial
    coefficients as floats, ``p2b[n, r, j]`` the quotients for ``d = n - 1``); the reparametrisation's
    matrix once per axis, its powers as products, every sum in ascending index.  An axis along which
    the polynomial is constant (every coefficient of a positive power zero: a vehicle that does not
    bind in its piece) is dropped first: along it every Bernstein coefficient is ``c_0``, as the
    transform gives it, so the smallest is that of the slice ``i = 0`` (``work``, ``spare``: space for
    ``n**q`` numbers; ``pw_a``: for ``n``, ``R``: for ``n × n``; ``kept``: for ``q`` integers)."""
    q, n, size = poly_shape(meta, p)
    start = meta[p, 2]
    for t in range(size):
        work[t] = coef[start + t]
    cur = work
    nxt = spare
    # the constant axes dropped (kept[a] = 0): the slice i = 0 of each, the others' order kept
    pre = 1
    for a in range(q):
        post = size // (pre * n)
        flat = True
        for u in range(pre):
            for i in range(1, n):
                for s in range(post):
                    if cur[(u * n + i) * post + s] != 0.0:
                        flat = False
                        break
                if not flat:
                    break
            if not flat:
                break
        if flat:
            for u in range(pre):
                for s in range(post):
                    cur[u * post + s] = cur[u * n * post + s]
            size = size // n
            kept[a] = 0
        else:
            kept[a] = 1
            pre *= n
    pre = 1
    for a in range(q):
        if kept[a] == 0:
            continue
        la, lb = local_interval(meta, W, p, a, h, lo, hi)
        w = lb - la
        pw_a[0] = 1.0
        for e in range(1, n):
            pw_a[e] = pw_a[e - 1] * la
        ww = 1.0  # w^r
        for r in range(n):  # R[r, i] = binom(i, r) λ_a^(i-r) w^r, i >= r
            for i in range(r, n):
                R[r, i] = binom[i, r] * pw_a[i - r] * ww
            ww = ww * w
        post = size // (pre * n)
        for u in range(pre):
            for s in range(post):
                for r in range(n):  # reparametrised into nxt
                    acc = 0.0
                    for i in range(r, n):
                        acc += R[r, i] * cur[(u * n + i) * post + s]
                    nxt[(u * n + r) * post + s] = acc
                for r in range(n):  # to Bernstein, back into cur
                    acc = 0.0
                    for j in range(r + 1):
                        acc += p2b[n, r, j] * nxt[(u * n + j) * post + s]
                    cur[(u * n + r) * post + s] = acc
        pre *= n
    m: float = cur[0]
    for t in range(1, size):
        if cur[t] < m or not cur[t] == cur[t]:
            m = cur[t]
        if not m == m:
            break
    return m


@inlined
def margin_bound(m: float, rel: float, roundoff: float) -> float:
    """A smallest Bernstein coefficient ``m`` less the round-off margin ``rel · max(1, |m|) + roundoff``
    (:data:`~iamp.planners.avoid.dual.ROUND_OFF_REL`, :attr:`~iamp.planners.avoid.dual.DualPolynomial.roundoff`)."""
    mag = m if m >= 0.0 else -m
    return m - rel * (mag if mag > 1.0 else 1.0) - roundoff


@compilable
def poly_bounds(coef: Any, meta: Any, W: int, roundoff: Any, h: float, rel: float, lo: Any, hi: Any, binom: Any,
                p2b: Any, out: Any, work: Any, spare: Any, pw_a: Any, R: Any, kept: Any) -> None:
    """``out[p]`` the lower bound of every polynomial ``p`` on the box ``[lo, hi]``: its smallest tensor
    Bernstein coefficient there (:func:`poly_bound`; the polynomials laid out as for :func:`polys_max`)
    less its round-off margin (:func:`margin_bound`)."""
    sizes_to_starts(meta)
    for p in range(meta.shape[0]):
        out[p] = margin_bound(poly_bound(coef, meta, W, p, h, lo, hi, binom, p2b, work, spare, pw_a, R, kept), rel,
                              roundoff[p])


@compilable
def max_poly_bound(coef: Any, meta: Any, W: int, roundoff: Any, h: float, rel: float, lo: Any, hi: Any, binom: Any,
                   p2b: Any, first: int, est: Any, chosen: Any, lam: Any, work: Any, spare: Any, pw_a: Any, R: Any,
                   kept: Any) -> float:
    r"""The largest of :func:`poly_bounds` over the polynomials (``-inf`` without any; a NaN bound counts as
    ``-inf``: it proves nothing), bounding only those that can reach it.  A polynomial's bound is at most
    its value anywhere in the box, e.g. at the centre of its intervals; that value raised by a bound on
    its evaluation's round-off, :math:`10^{-12}\sum|c|`, is its estimate ``est[p]``.  The ``first``
    polynomials of the highest estimates (the lowest number first among equal ones) are bounded first,
    then, in order, each other one whose estimate exceeds the best bound so far: the maximum over all of
    them, since one left out cannot exceed it (``chosen``, ``lam``: space for the count of polynomials and
    for their axes)."""
    P = meta.shape[0]
    best = -inf
    if P == 0:
        return best
    sizes_to_starts(meta)
    for p in range(P):
        q, n, size = poly_shape(meta, p)
        for a in range(q):
            la, lb = local_interval(meta, W, p, a, h, lo, hi)
            lam[a] = 0.5 * (la + lb)
        reach = 0.0
        for t in range(size):
            c = coef[meta[p, 2] + t]
            reach += c if c >= 0.0 else -c
        est[p] = tensor_polyval(coef, meta[p, 2], q, n, lam, work) + 1e-12 * reach
        chosen[p] = False
    picks = first if first < P else P
    for _ in range(picks):  # the highest estimates (the lowest number among equal ones)
        top = -1
        for p in range(P):
            if not chosen[p] and (top < 0 or est[p] > est[top] or (not est[top] == est[top] and est[p] == est[p])):
                top = p
        chosen[top] = True
        b = margin_bound(poly_bound(coef, meta, W, top, h, lo, hi, binom, p2b, work, spare, pw_a, R, kept), rel,
                         roundoff[top])
        if b > best:
            best = b
    for p in range(P):
        if not chosen[p] and not est[p] <= best:  # a NaN estimate is bounded too
            b = margin_bound(poly_bound(coef, meta, W, p, h, lo, hi, binom, p2b, work, spare, pw_a, R, kept), rel,
                             roundoff[p])
            if b > best:
                best = b
    return best


@compilable
def probe_grid(coef: Any, meta: Any, W: int, h: float, tau: Any, vs: Any, lo: Any, hi: Any, n: int, solved: Any,
               tol: float, pts: Any, vals: Any, near: Any, lam: Any, work: Any) -> int:
    r"""The search's probe (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner._probe`): the
    product grid ``pts`` (shape ``(n**k, m)``, ``k`` the vehicles ``vs``), every row ``tau`` but on the
    vehicles ``vs``, where vehicle ``vs[c]`` takes ``n`` samples of ``[lo_v, hi_v]`` (``numpy.linspace``'s
    numbers: ``j · step + lo``, or ``(j / (n - 1)) · (hi - lo) + lo`` where the step is zero, the last
    one ``hi``) in ``numpy.meshgrid``'s ``"ij"`` order (sample ``j = (t // n^(k-1-c)) % n`` at row
    ``t``); ``vals`` the polynomials' largest value there (:func:`polys_max`, the polynomials laid out
    as for it); where ``solved`` (crossing times of solved candidates, shape ``(S, m)``) has rows, a
    point within ``tol`` of one (the largest ``|Δτ|`` over the vehicles, its smallest over the rows,
    NaN-propagating as ``numpy.max`` and ``numpy.min``) is ``near`` and, unless every point is, its
    value is set to ``inf``.  Returns the point of the smallest value (``numpy.argmin``'s: the first
    NaN, else the first smallest; ``lam``, ``work``: space for :func:`polys_max`)."""
    T = pts.shape[0]
    m = pts.shape[1]
    for t in range(T):
        for v in range(m):
            pts[t, v] = tau[v]
    run = T
    for c in range(vs.shape[0]):
        v = vs[c]
        run = run // n
        lo_v = lo[v]
        hi_v = hi[v]
        delta = hi_v - lo_v
        step = delta / (n - 1)
        for t in range(T):
            j = (t // run) % n
            if j == n - 1:
                pts[t, v] = hi_v
            elif step == 0.0:
                pts[t, v] = j / (n - 1) * delta + lo_v
            else:
                pts[t, v] = j * step + lo_v
    polys_max(coef, meta, W, h, pts, vals, lam, work)
    S = solved.shape[0]
    if S > 0:
        every = True
        for t in range(T):
            low = 0.0
            for s in range(S):
                top = 0.0
                for v in range(m):
                    d = abs(pts[t, v] - solved[s, v])
                    if v == 0 or d > top or not d == d:
                        top = d
                    if not top == top:
                        break
                if s == 0 or top < low or not top == top:
                    low = top
                if not low == low:
                    break
            near[t] = low <= tol
            if not near[t]:
                every = False
        if not every:
            for t in range(T):
                if near[t]:
                    vals[t] = inf
    at = 0
    for t in range(T):
        x = vals[t]
        if not x == x:
            return t
        if x < vals[at]:
            at = t
    return at
