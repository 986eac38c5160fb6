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
* :func:`bernstein_min` — the smallest tensor Bernstein coefficient of each of several dual
  polynomials on a box (:func:`~iamp.planners.avoid.dual.lower_bounds`).
"""

from __future__ import annotations

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


@compilable
def polys_max(coef: Any, starts: Any, qs: Any, ns: Any, vehicles: Any, pieces: Any, h: float, taus: Any,
              out: Any, lam: Any, work: Any) -> None:
    """``out[t]`` the largest over the polynomials ``p`` of :func:`tensor_polyval` at the crossing
    times ``taus[t]`` (shape ``(T, m)``): polynomial ``p`` has ``qs[p]`` axes of ``ns[p]``
    coefficients each, the vehicles
    ``vehicles[p, :qs[p]]`` in the pieces ``pieces[p, :qs[p]]``, its coefficients from
    ``coef[starts[p]]``, and ``λ_a = (τ_v - k h) / h`` on its axis ``a`` (``lam``, ``work``:
    space)."""
    for t in range(taus.shape[0]):
        best = 0.0
        for p in range(starts.shape[0]):
            q = qs[p]
            for a in range(q):
                lam[a] = (taus[t, vehicles[p, a]] - pieces[p, a] * h) / h
            v = tensor_polyval(coef, starts[p], q, ns[p], lam, work)
            if p == 0 or v > best or not v == v:
                best = v
            if not best == best:
                break
        out[t] = best


@compilable
def bernstein_min(coef: Any, q: int, n: int, B: Any, out: Any, work: Any, spare: Any) -> None:
    """Per polynomial ``p`` (``coef[p]``: its power coefficients, C order, shape ``(n,) * q``),
    ``out[p]`` the smallest of its tensor Bernstein coefficients: along axis ``a`` (first to last)
    ``T'[.., r, ..] = Σ_i B[p, a, r, i] T[.., i, ..]`` (the sum over ``i`` ascending), then the
    minimum over every entry (``work``, ``spare``: space for ``n**q`` numbers each)."""
    size = 1
    for _ in range(q):
        size *= n
    for p in range(coef.shape[0]):
        for t in range(size):
            work[t] = coef[p, t]
        cur = work
        nxt = spare
        pre = 1
        for a in range(q):
            post = size // (pre * n)
            for u in range(pre):
                for w in range(post):
                    for r in range(n):
                        acc = 0.0
                        for i in range(n):
                            acc += B[p, a, r, i] * cur[(u * n + i) * post + w]
                        nxt[(u * n + r) * post + w] = acc
            tmp = cur
            cur = nxt
            nxt = tmp
            pre *= n
        m = cur[0]
        for t in range(1, size):
            if cur[t] < m:
                m = cur[t]
        out[p] = m
