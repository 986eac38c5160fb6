r"""Optional numba path of the saturated axis solve (``pip install iamp[fast]``).

:func:`load` compiles the functions of :mod:`~iamp.planners.pmp.saturated_kernel` from their
own code objects with ``numba.njit`` (no fastmath), as :mod:`~iamp.planners.pmp.compiled`
does for the one-vehicle kernel: the same source, the same arithmetic, so the pure and the
compiled path return the same numbers (tested bit for bit on generated problems).

Nothing is compiled on import, and the bounded PMP never triggers it: :func:`core` returns
the compiled function only once :func:`load` has run in the process (``iamp bench`` loads
it before its clock starts; a user opts in with ``load()``).  The first :func:`load` in a
process compiles (a few seconds; the rebuilt twins cannot use numba's on-disk cache, see
:mod:`~iamp.planners.pmp.compiled`), which pays for itself only over many bounded plans
(one plan is then about 10× faster, ``iamp bench``).
"""

from __future__ import annotations

import importlib.util
import types
from collections.abc import Callable
from typing import Any

import numpy as np

_STATE: dict[str, Any] = {}


def available() -> bool:
    """Whether numba can be imported (without importing it)."""
    return importlib.util.find_spec("numba") is not None


def ready() -> bool:
    """Whether the compiled axis solve is loaded in this process."""
    return "core" in _STATE


def core() -> Callable[..., Any] | None:
    """The compiled :func:`~iamp.planners.pmp.saturated_kernel.axis_core` wrapped for the
    arguments of :func:`~iamp.planners.pmp.saturated.solve_axis` (``lam0`` ``None`` for a
    cold start), or ``None`` when :func:`load` has not run."""
    return _STATE.get("core")


def unload() -> None:
    """Back to the pure path in this process (tests compare both; a later :func:`load`
    reuses the compiled code)."""
    _STATE.pop("core", None)


def load() -> bool:
    """Import numba and compile the kernel; ``False`` if numba is missing or fails (the
    reason in ``_STATE["error"]``).  Idempotent."""
    if ready():
        return True
    if not available():
        return False
    if "built" in _STATE:  # compiled earlier in this process (then unloaded)
        _STATE["core"] = _STATE["built"]
        return True
    try:
        _STATE["core"] = _build()
        _STATE["core"]([0.5], [0.0, 0.5, 1.0], [0.1, 0.2, 0.0], -1.0, 1.0, None, 1e-12, 60)
        _STATE["built"] = _STATE["core"]
    except Exception as exc:  # a broken numba install: the pure path stays
        _STATE.pop("core", None)
        _STATE["error"] = f"{type(exc).__name__}: {exc}"
        return False
    return True


def _build() -> Callable[..., Any]:
    import math

    import numba

    from . import saturated_kernel as kern

    env: dict[str, Any] = {"math": math, "abs": abs, "len": len, "range": range,
                           "CONVERGED": kern.CONVERGED, "NOT_CONVERGED": kern.NOT_CONVERGED,
                           "SINGULAR_GRAM": kern.SINGULAR_GRAM}
    jit = numba.njit(cache=False)

    def rebuild(fn: Any) -> Any:
        return jit(types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__))

    for name in ("gauss", "pieces", "evaluate", "max_abs"):
        env[name] = rebuild(getattr(kern, name))
    compiled = rebuild(kern.axis_core)
    empty = np.empty(0)

    def run(sig: list[float], base: list[float], d: list[float], lo: float, hi: float, lam0: list[float] | None,
            tol_residual: float, max_newton: int) -> Any:
        warm = lam0 is not None
        return compiled(np.asarray(sig, dtype=float), np.asarray(base, dtype=float), np.asarray(d, dtype=float),
                        float(lo), float(hi), np.asarray(lam0, dtype=float) if warm else empty, warm,
                        float(tol_residual), int(max_newton))

    return run
