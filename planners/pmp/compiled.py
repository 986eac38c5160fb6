"""Opt-in numba path of the PMP's kernels (``pip install iamp[fast]``).

Each is compiled from its one source by :func:`iamp.planners.pmp.jit.twin` (the same code
objects, no fastmath), so they return the same numbers as the Python functions the planner
calls by default, bit for bit:

* :func:`compiled_kernel` — the one-vehicle kernel
  :func:`iamp.planners.pmp.one.one_vehicle_kernel`, for ``PMPPlanner(kernel=compiled_kernel())``;
* :func:`load_axis` — the saturated axis solve
  :func:`iamp.planners.pmp.saturated_kernel.axis_core`, which
  :mod:`~iamp.planners.pmp.saturated` then calls in this process (:func:`axis_core`);
* :func:`load_search` — the kernels of the ``m ≥ 2`` contact-time search
  (:mod:`iamp.planners.pmp.search_kernels`: value function, gradient, Newton, box bounds),
  which the search then calls in this process.

Nothing is compiled on import, and no planner triggers it: the first compile in a process
takes seconds (``import numba`` alone 0.2-0.4 s) against tens of microseconds per plan in
Python, so it pays only for many plans in one process (``iamp bench`` loads the compiled
paths before its clock starts; the search kernels are also kept in numba's on-disk cache).
Whether they are loaded changes the time, never a number.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from . import jit

_STATE: dict[str, Any] = {}


def numba_available() -> bool:
    """Whether numba can be imported (without importing it)."""
    return jit.available()


def compiled_kernel() -> Callable[..., list[float]]:
    """The numba-compiled :func:`~iamp.planners.pmp.one.one_vehicle_kernel` (cached)."""
    if "kernel" in _STATE:
        out: Callable[..., list[float]] = _STATE["kernel"]
        return out
    from .one import one_vehicle_kernel

    compiled = jit.twin(one_vehicle_kernel)

    def kernel(ego: Sequence[float], ex: Sequence[float], ey: Sequence[float], cx: Sequence[float],
               cy: float) -> list[float]:
        res: list[float] = compiled(np.asarray(ego, dtype=float), np.asarray(ex, dtype=float),
                                    np.asarray(ey, dtype=float), np.asarray(cx, dtype=float), float(cy))
        return res

    _STATE["kernel"] = kernel
    return kernel


def axis_core() -> Callable[..., Any] | None:
    """The compiled axis solve wrapped for the arguments of
    :func:`~iamp.planners.pmp.saturated.solve_axis` (``lam0`` ``None`` for a cold start), or
    ``None`` unless :func:`load_axis` has run in this process."""
    return _STATE.get("axis")


def unload_axis() -> None:
    """Back to the Python axis solve (and the Python search kernels of
    :data:`BOUNDED_SEARCH_KERNELS`, unless :func:`load_search` has them) in this process (a
    later :func:`load_axis` reuses the compiled code)."""
    from . import search_kernels as sk

    _STATE.pop("axis", None)
    sk.AXIS_TWINS.clear()


#: the kernels of :mod:`~iamp.planners.pmp.search_kernels` the bounded PMP calls, compiled with
#: the axis solve: the certificate's closed-form bound :math:`J_b \ge J_u` over intervals
#: (``quad``, ``lower_bound``) and, for ``m ≥ 2``, the Newton polish of the unbounded starts
#: (``newton``; ``gradient`` for the value function's gradient).  While loaded they are in
#: :data:`~iamp.planners.pmp.search_kernels.AXIS_TWINS` (:func:`~iamp.planners.pmp.search_kernels.kernel`).
BOUNDED_SEARCH_KERNELS = ("quad", "lower_bound", "gradient", "newton")


def bounded_search_kernel(name: str) -> Callable[..., Any] | None:
    """The compiled twin of the search kernel ``name`` (one of :data:`BOUNDED_SEARCH_KERNELS`)
    once :func:`load_axis` has run in this process, else ``None`` (the caller runs the Python
    function or :func:`load_search`'s twin: the same numbers)."""
    from . import search_kernels as sk

    out: Callable[..., Any] | None = sk.AXIS_TWINS.get(name)
    return out


def load_axis() -> bool:
    """Compile the axis solve and use it in this process; ``False`` if numba is missing or
    fails (the reason in ``_STATE["error"]``).  Idempotent."""
    from . import search_kernels as sk

    if "axis" in _STATE:
        return True
    if not jit.available():
        return False
    if "axis_built" in _STATE:
        _STATE["axis"] = _STATE["axis_built"]
        sk.AXIS_TWINS.update(_STATE["bounded_search"])
        return True
    try:
        run = _build_axis()
        run([0.5], [0.0, 0.5, 1.0], [0.1, 0.2, 0.0], -1.0, 1.0, None, 1e-12, 60)
        _STATE["bounded_search"] = _build_bounded_search()
    except Exception as exc:  # a broken numba install: the Python path stays
        _STATE["error"] = f"{type(exc).__name__}: {exc}"
        return False
    _STATE["axis"] = _STATE["axis_built"] = run
    sk.AXIS_TWINS.update(_STATE["bounded_search"])
    return True


def _build_bounded_search() -> dict[str, Callable[..., Any]]:
    """:data:`BOUNDED_SEARCH_KERNELS` compiled (kept in numba's disk cache, as by
    :func:`load_search`) and called once for the one-vehicle argument types."""
    from . import search_kernels as sk

    twins = {name: jit.twin(getattr(sk, name), cache=True) for name in BOUNDED_SEARCH_KERNELS}
    row = np.array([[0.1, 0.2, 0.3, 0.0]])
    pts = np.array([[0.5], [0.25]])
    twins["quad"](row, row, pts)
    twins["lower_bound"](row, row, row, row, pts, np.full((2, 1), 0.05))
    twins["gradient"](row, row, row, row, pts)
    twins["newton"](row, row, row, row, np.array([0.5]), 3)
    return twins


def _build_axis() -> Callable[..., Any]:
    from . import saturated_kernel as sk
    from .saturated_kernel import axis_core as pure

    compiled = jit.twin(pure, cache=True)  # saturated_kernel.py calls nothing outside itself
    empty = np.empty(0)
    # the kernel's other entry points, compiled now rather than inside a first plan
    one = np.array([0.5])
    base = np.array([0.0, 0.5, 1.0])
    jit.twin(sk.farkas_margin, cache=True)(one, base, np.array([0.1, 0.2, 0.0]), -1.0, 1.0,
                                           np.array([1.0, 0.0, 0.0]))
    jit.twin(sk.contact_points, cache=True)(one, 1.0, 1.0, 1.0, np.array([0.0, 1.0]), 0.0, 0.0,
                                            np.array([0.0, 1.0, 1.0, 1.0, -1.0, 1.0] * 2), np.zeros(6),
                                            np.zeros(2), False, 1e-12, 60)
    jit.twin(sk.cover_points, cache=True)(np.array([0.4, 0.6]), np.array([0.0, 0.1, 0.5, 0.5]), 2, 1.0, 1.0, 1.0,
                                          np.array([0.0, 1.0, 1.0, 1.0, -1.0, 1.0] * 2), 1e-12, 60)
    jit.twin(sk.interval_terms, cache=True)(np.array([0.4, 0.6]), 1.0, 1.0, 1.0, np.array([0.0, 1.0]),
                                            np.array([1.0]), 0.0, 0.0, np.array([0.0, 1.0, 1.0, 1.0, -1.0, 1.0] * 2),
                                            np.zeros(6), np.zeros(2), 0.0, 1e-12, 60)

    def run(sig: list[float], base: list[float], d: list[float], lo: float, hi: float, lam0: list[float] | None,
            tol_residual: float, max_newton: int) -> Any:
        warm = lam0 is not None
        return compiled(np.asarray(sig, dtype=float), np.asarray(base, dtype=float), np.asarray(d, dtype=float),
                        float(lo), float(hi), np.asarray(lam0, dtype=float) if warm else empty, warm,
                        float(tol_residual), int(max_newton))

    return run


#: the kernels of :mod:`~iamp.planners.pmp.search_kernels` that the search looks up in
#: :data:`~iamp.planners.pmp.search_kernels.TWINS`
SEARCH_KERNELS = ("quad", "gradient", "newton", "lower_bound", "expansion", "basin_radius", "box_bound",
                  "split")


def load_search() -> bool:
    """Compile the ``m ≥ 2`` search kernels and use them in this process; ``False`` if numba
    is missing or fails (the reason in ``_STATE["error"]``).  Idempotent.  The compiled
    kernels return the same numbers as the Python ones, bit for bit (tested).  The first
    compile on a machine takes about a minute; numba keeps the machine code on disk
    (``cache=True``), so later processes load it in seconds."""
    from . import search_kernels as sk

    if sk.TWINS:
        return True
    if not jit.available():
        return False
    if "search_built" not in _STATE:
        try:
            # cached on disk: every compilable function they call is in search_kernels.py
            twins = {name: jit.twin(getattr(sk, name), cache=True) for name in SEARCH_KERNELS}
            _warm_up_search(twins)
        except Exception as exc:  # a broken numba install: the Python path stays
            _STATE["error"] = f"{type(exc).__name__}: {exc}"
            return False
        _STATE["search_built"] = twins
    sk.TWINS.update(_STATE["search_built"])
    return True


def unload_search() -> None:
    """Back to the Python search kernels in this process (a later :func:`load_search` reuses
    the compiled code)."""
    from . import search_kernels as sk

    sk.TWINS.clear()


def _warm_up_search(twins: dict[str, Any]) -> None:
    """Compile for the argument types the search passes (two and three vehicles)."""
    from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle

    from .basin import degree
    from .fixed import ValueFunction

    # a lane change with two and three vehicles (any will do: only the argument types matter;
    # not iamp.planners.examples, which imports this package)
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=20.0, xf=100.0, yf=3.75, vxf=20.0)
    vehicles = tuple(SurroundingVehicle(x_poly=(x0, v, 0.0, 0.0), corner=corner, y=y, length=4.8, width=1.8,
                                        safety_x=5.0, safety_y=0.5, name=f"sv{k}")
                     for k, (x0, v, corner, y) in enumerate(((-20.0, 19.0, "front-lower", 3.75),
                                                             (35.0, 15.0, "rear-upper", 0.0),
                                                             (60.0, 18.0, "rear-lower", 3.75)), start=1))
    for m in (2, 3):
        vf = ValueFunction(Problem(ego, vehicles[:m], f"warm-up-m{m}"))
        E = (vf._EX, vf._EY, vf._DEX, vf._DEY)
        pts = np.full((3, m), 0.5) + np.arange(m) * 0.1
        twins["quad"](vf._EX, vf._EY, pts)
        twins["gradient"](*E, pts)
        twins["newton"](*E, np.ascontiguousarray(pts[0]), 3)
        twins["lower_bound"](*E, pts, np.full((3, m), 0.05))
        twins["split"](pts, np.full((3, m), 0.05))
        c, _ = twins["expansion"](*E, np.ascontiguousarray(pts[0]), degree(vf))
        twins["basin_radius"](c, m, degree(vf), 0.1, 1e-9)
        if m == 2:
            twins["box_bound"](c, np.ascontiguousarray(pts[0]), pts, np.full((3, m), 0.05), degree(vf))
