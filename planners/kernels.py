"""The planners' compiled kernels made ready before anything is timed.

The PMP's axis solve (:mod:`iamp.planners.pmp.compiled`), the avoidance's node solver and
search (:mod:`iamp.planners.avoid.schur_kernel`, :mod:`iamp.planners.avoid.search_kernel`) and the
safety report's root finder (:mod:`iamp.core.polyroots_kernel`) are each written once and run
either as plain Python or compiled by numba from that one source, with the same numbers
(:mod:`iamp.core.jit`).  numba compiles a kernel on its first call (a
few seconds of CPU, or a load from its on-disk cache), so a bench that times planning calls
first runs :func:`warm_kernels`, untimed; otherwise the first plan that reaches a kernel carries
its compile (the CommonRoad bench's first avoidance plan took 8.9 s against 0.56 s warm).
"""

from __future__ import annotations

__all__ = ["warm_kernels"]


def warm_kernels() -> bool:
    """Compile or load every compiled kernel of the planners in this process.

    Loads the PMP's compiled axis solve (:func:`iamp.planners.pmp.compiled.load_axis`, which
    the closed loop also uses) and plans the avoidance's overtake once
    (:func:`iamp.planners.examples.overtake_problem`, ``N = 50``, FOH, with the passenger car's
    limits), which reaches the node solver's and the search's kernels and, through the plan's safety
    report, the root finder's (:mod:`iamp.core.polyroots_kernel`, switched to its compiled twins by
    :func:`iamp.core.polyroots.load`; without it every plan's safety report runs them as Python).  Nothing is kept that
    changes a later plan: the compiled and the Python path give the same numbers.

    Returns
    -------
    bool
        Whether numba is installed and the kernels are compiled (``False``: they run as plain
        Python; ``pip install 'iamp[fast]'`` brings numba).
    """
    from iamp.core import polyroots
    from iamp.planners.avoid.planner import AvoidQPPlanner
    from iamp.planners.examples import overtake_problem
    from iamp.planners.pmp import compiled, jit

    if not jit.available():
        return False
    ok = compiled.load_axis()
    polyroots.load()
    AvoidQPPlanner(steps=50, hold="foh", solver="clarabel").plan(overtake_problem())
    return ok
