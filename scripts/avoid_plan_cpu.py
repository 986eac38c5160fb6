"""CPU time per continuous-time avoidance plan, as ``iamp bench`` times its ``avoid_limits_*`` rows.

The overtake (``one``: :func:`iamp.planners.examples.overtake_problem`; ``three``:
:func:`~iamp.planners.examples.overtake_three_problem`) under the passenger car's limits, FOH,
``N = 50``, ``--safety continuous``, planned ``--plans`` times by one planner with its vehicles
forgotten (untimed) before each plan; the compiled kernels are made ready first.  Prints the median
process CPU time [ms], the status, the cost and the number of QP solves.  For before/after
comparisons run it alternately on two checkouts (``PYTHONPATH=CHECKOUT``, from another folder)::

    python scripts/avoid_plan_cpu.py one piqp
    python scripts/avoid_plan_cpu.py three clarabel --plans 30
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any


def case_arguments(description: str, plans: int) -> argparse.Namespace:
    """The command line of this script and ``avoid_plan_instructions.py``: case, solver, ``--plans``."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("case", choices=("one", "three"))
    ap.add_argument("solver", choices=("osqp", "clarabel", "piqp"))
    ap.add_argument("--plans", type=int, default=plans)
    return ap.parse_args()


def planner_and_problem(case: str, solver: str) -> tuple[Any, Any]:
    """The timed planner and problem (module docstring), the compiled kernels made ready."""
    from iamp.planners import registry
    from iamp.planners.examples import overtake_problem, overtake_three_problem
    from iamp.planners.kernels import warm_kernels

    warm_kernels()
    problem = overtake_problem() if case == "one" else overtake_three_problem()
    return registry.make_planner("qp-avoid", steps=50, hold="foh", solver=solver, safety="continuous"), problem


def main() -> None:
    args = case_arguments(__doc__.splitlines()[0], 30)
    planner, problem = planner_and_problem(args.case, args.solver)
    planner.plan(problem)  # warm-up
    times = []
    for _ in range(max(1, args.plans)):
        planner.forget_vehicles()
        t0 = time.process_time()
        plan = planner.plan(problem)
        times.append(time.process_time() - t0)
    print(f"median {1e3 * statistics.median(times):.3f} ms CPU over {len(times)} plans; {plan.status}, cost "
          f"{plan.cost}, {plan.diagnostics.n_solves} QP solves")


if __name__ == "__main__":
    main()
