"""Optional numba path: the one-vehicle kernel compiled unchanged (``pip install iamp[fast]``).

:func:`compiled_kernel` rebuilds :func:`iamp.planners.pmp.one.one_vehicle_kernel` and every
function it calls from their own code objects, with the module globals pointing at the
compiled twins, and compiles them with ``numba.njit``: the same source, the same arithmetic
(no fastmath), so both paths give identical numbers (tested).  The one substitution is the
Bernstein weight table: the pure path caches ``C(j,i)/C(n,i)`` in a dict; the compiled path
recomputes the same quotient of exact integers (:func:`_to_bernstein_nb`).

Use it with ``PMPPlanner(kernel=compiled_kernel())``; the first call compiles (about 7 s,
measured with ``import numba`` itself 0.2–0.4 s), then a plan takes about 16 µs against about
25 µs for the pure-Python kernel.  That is why it is not the default (see
:mod:`iamp.planners.pmp.planner`): the compilation pays for itself only after some 10⁵ plans in one
process.  (``numba.njit(cache=True)`` is not used: the twins are rebuilt from the pure
functions' code objects with other globals, and numba's on-disk cache keys on the source
file and the function's name, which the twins share with the pure functions.)
"""

from __future__ import annotations

import types
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

_CACHE: dict[str, Callable[..., Any]] = {}


def numba_available() -> bool:
    """Whether numba can be imported."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def _to_bernstein_nb(a: Sequence[float]) -> list[float]:
    """:func:`iamp.planners.pmp.roots.to_bernstein` with the weights computed in place
    (binomials as exact integer-valued floats, one correctly rounded division)."""
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


def compiled_kernel() -> Callable[..., list[float]]:
    """The numba-compiled :func:`~iamp.planners.pmp.one.one_vehicle_kernel` (cached)."""
    if "kernel" in _CACHE:
        return _CACHE["kernel"]
    import numba

    from . import one as pmp_one
    from . import roots as pmp_roots
    from . import search as pmp_search

    env: dict[str, Any] = {"float": float, "abs": abs, "max": max, "len": len, "range": range}
    jit = numba.njit(cache=False)

    def rebuild(fn: Any) -> Any:
        return jit(types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__))

    env["MIN_WIDTH"] = pmp_roots.MIN_WIDTH
    env["ROOT_XTOL"] = pmp_roots.ROOT_XTOL
    env["to_bernstein"] = jit(_to_bernstein_nb)
    for mod, name in ((pmp_roots, "sign_variations"), (pmp_roots, "casteljau_halves"), (pmp_roots, "horner2"),
                      (pmp_roots, "newton_in_bracket"), (pmp_roots, "unit_roots"),
                      (pmp_search, "stationarity_poly_loops"), (pmp_search, "stationarity_poly"),
                      (pmp_search, "stationary_sigmas"),
                      (pmp_search, "_q_one"), (pmp_search, "one_vehicle_sigma")):
        env[name] = rebuild(getattr(mod, name))
    compiled = rebuild(pmp_one.one_vehicle_kernel)

    def kernel(ego: Sequence[float], ex: Sequence[float], ey: Sequence[float], cx: Sequence[float],
               cy: float) -> list[float]:
        out: list[float] = compiled(np.asarray(ego, dtype=float), np.asarray(ex, dtype=float),
                                    np.asarray(ey, dtype=float), np.asarray(cx, dtype=float), float(cy))
        return out

    _CACHE["kernel"] = kernel
    return kernel
