r"""Optional numba path of the global contact-time search (``pip install iamp[fast]``).

The same algorithm as :func:`iamp.planners.pmp.search.global_search` — starts, damped Newton
(:func:`newton`), basin boxes (:mod:`iamp.planners.pmp.basin`) and the certified branch and
bound (:mod:`iamp.planners.pmp.bound`) with its three lower bounds — as scalar loops compiled
by numba (kernels in :mod:`iamp.planners.pmp.compiled_kernels`), for any number of vehicles.
Both paths certify the same tolerance (``pmp_global_certificate_rel``), so they return the
same contact times to that tolerance and the same status (tested over generated scenarios).

Incumbents pass the same check as on the pure path
(:func:`~iamp.planners.pmp.search.trusted_q`: distinct times, closed form against the exact
integral of the solved trajectory), compiled too.

Compilation.  Nothing is compiled on import, and ``PMPPlanner()`` never triggers it: the
default ``compiled=None`` uses this path only once :func:`load` has run in the process
(``PMPPlanner(compiled=True)`` calls it).  :func:`load` imports numba and compiles with
``cache=True``: the first time on a machine takes seconds (the machine code is then cached
next to the module, or in numba's user cache directory if that is read-only); later
processes load it in a fraction of a second.  A one-plan CLI run therefore never pays JIT
unless asked to.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

_STATE: dict[str, Any] = {}


def available() -> bool:
    """Whether numba can be imported (without importing it)."""
    return importlib.util.find_spec("numba") is not None


def ready() -> bool:
    """Whether the compiled search is loaded in this process (:func:`load`)."""
    return "run" in _STATE


def use(flag: bool | None) -> bool:
    """Whether to take the compiled path: ``None`` → only if already loaded, ``True`` →
    load it now (``False`` if numba is missing), ``False`` → never."""
    if flag is None:
        return ready()
    return load() if flag else False


def load() -> bool:
    """Import numba and compile (or load from its cache) the search; ``False`` if numba is
    missing or fails (the reason is kept in ``_STATE["error"]``).  Idempotent."""
    if ready():
        return True
    if not available():
        return False
    try:
        from .compiled_kernels import search

        _STATE["run"] = search
        _warm_up()
    except Exception as exc:  # a broken numba install: the pure path stays
        _STATE.pop("run", None)
        _STATE["error"] = f"{type(exc).__name__}: {exc}"
        return False
    return True


def _warm_up() -> None:
    """Compile for the array types the planner passes (a two-vehicle example)."""
    from iamp.planners.examples import random_problem

    from .scale import scale_problem

    run(scale_problem(random_problem(0, m=2)))


def padded(S: Any) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(EX, EY, DEX, DEY)``: the error polynomials padded to one width and their
    derivatives (as :class:`~iamp.planners.pmp.fixed.ValueFunction` holds them)."""
    m = S.EX.shape[0]
    d = max(S.EX.shape[1], S.EY.shape[1])
    E = np.zeros((2, m, d))
    E[0, :, :S.EX.shape[1]] = S.EX
    E[1, :, :S.EY.shape[1]] = S.EY
    DE = np.zeros((2, m, d))
    DE[:, :, :-1] = E[:, :, 1:] * np.arange(1, d)
    return E[0], E[1], DE[0], DE[1]


def run(S: Any, max_starts: int = 32, max_boxes: int = 200_000,
        progress: Callable[[int, int], None] | None = None) -> Any:
    """:func:`~iamp.planners.pmp.search.global_search` on the compiled path for the scaled
    problem ``S`` (call :func:`load` first); returns a
    :class:`~iamp.planners.pmp.search.SearchResult`."""
    from iamp.core.tolerances import TOLERANCES

    from .basin import MAX_M
    from .compiled_kernels import make_starts
    from .search import SearchResult, start_points

    EX, EY, DEX, DEY = padded(S)
    jbar = float(S.jbar)
    starts = make_starts(EX, EY, jbar, max_starts)
    if not starts.shape[0]:  # many vehicles: the pure path's sampled starts
        pts = np.array(start_points(S, max_starts))
        starts = np.ascontiguousarray(pts[np.argsort(_quad_rows(EX, EY, pts, jbar))[:max_starts]])
    P = (S.ego, np.ascontiguousarray(S.CX, dtype=float), np.asarray(S.CY, dtype=float), jbar,
         TOLERANCES["pmp_cost_consistency_rel"])
    s, q, cert, boxes = _STATE["run"](EX, EY, DEX, DEY, P, starts, TOLERANCES["pmp_global_certificate_rel"],
                                      int(max_boxes), MAX_M)
    if progress is not None:
        progress(min(int(boxes), max_boxes), max_boxes)
    return SearchResult(np.asarray(s, dtype=float), float(q), bool(cert), int(boxes), int(starts.shape[0]))


def _quad_rows(EX: FloatArray, EY: FloatArray, pts: FloatArray, jbar: float) -> FloatArray:
    from .compiled_kernels import quad

    return np.array([quad(EX, EY, np.ascontiguousarray(p), jbar) for p in pts])
