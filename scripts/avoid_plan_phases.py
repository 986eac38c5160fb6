"""Where a continuous-time avoidance plan's time goes: its phases, timed inside the plan.

The same planner and problem as ``scripts/avoid_plan_cpu.py`` (the overtake, ``one`` or ``three``
vehicles, the passenger car's limits, FOH, ``N = 50``, ``--safety continuous``, the planner's
vehicles forgotten before each plan).  Each phase's method is wrapped by a timer
(``time.perf_counter``) for the run; prints the mean wall time per plan of the whole plan and of
each phase (inclusive: ``verified`` holds ``backend``, ``safety`` and ``leave_time``; ``search``
holds ``node_solve`` and ``polish_tau``), in milliseconds and as a share of the plan.  The timers
add a few microseconds per call; the shares, not the absolute times, are the point on a shared
machine::

    python scripts/avoid_plan_phases.py one piqp
    python scripts/avoid_plan_phases.py one clarabel --plans 300
"""

from __future__ import annotations

import functools
import time
from typing import Any

from avoid_plan_cpu import case_arguments, planner_and_problem

#: (owner path, attribute, label): the phases timed.
PHASES = (("iamp.planners.avoid.continuous:ContinuousAvoidPlanner", "search", "search"),
          ("iamp.planners.avoid.continuous:ContinuousAvoidQP", "solve", "node_solve"),
          ("iamp.planners.avoid.continuous:ContinuousAvoidPlanner", "_polish", "polish_tau"),
          ("iamp.planners.avoid.continuous:ContinuousAvoidPlanner", "_verified", "verified"),
          ("iamp.planners.avoid.continuous:ContinuousAvoidQP", "backend_solve", "backend"),
          ("iamp.core.plan", "safety_report", "safety"),
          ("iamp.planners.avoid.continuous", "leave_time", "leave_time"),
          ("iamp.planners.avoid.continuous:ContinuousAvoidQP", "__init__", "qp_init"))


def _owner(path: str) -> Any:
    import importlib

    module, _, cls = path.partition(":")
    mod = importlib.import_module(module)
    return getattr(mod, cls) if cls else mod


def _wrap(owner: Any, name: str, label: str, acc: dict[str, float]) -> None:
    fn = getattr(owner, name)

    @functools.wraps(fn)
    def timed(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] = acc.get(label, 0.0) + time.perf_counter() - t

    setattr(owner, name, timed)


def main() -> None:
    args = case_arguments(__doc__.splitlines()[0], 200)
    acc: dict[str, float] = {}
    for path, name, label in PHASES:
        _wrap(_owner(path), name, label, acc)
    planner, problem = planner_and_problem(args.case, args.solver)
    for _ in range(5):  # warm-up
        planner.forget_vehicles()
        planner.plan(problem)
    acc.clear()
    n, total = max(1, args.plans), 0.0
    for _ in range(n):
        planner.forget_vehicles()
        t = time.perf_counter()
        plan = planner.plan(problem)
        total += time.perf_counter() - t
    print(f"{args.case} {args.solver}: {1e3 * total / n:.3f} ms per plan (wall, mean of {n}); {plan.status}, "
          f"{plan.diagnostics.n_solves} QP solves")
    for label, v in sorted(acc.items(), key=lambda kv: -kv[1]):
        print(f"  {label:12s} {1e3 * v / n:7.3f} ms  {100 * v / total:5.1f} %")


if __name__ == "__main__":
    main()
