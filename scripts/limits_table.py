"""The closing table of issue 19: the paper's scenarios under a passenger car's limits.

    PYTHONPATH=. python scripts/limits_table.py [--steps N] [--hold foh|zoh] [--solver S] [--out FILE]

For every built-in scenario (paper-1, paper-1-poly, paper-2, paper-3, two-vehicle, ...) under
``PASSENGER_CAR`` (iamp.core.physical: ax [-6, 3], ay [-2, 2], a_total 8, vx [0, 40], jerk 5):
the PMP, the equality QP (every bound at every node), ``--constraint active`` and the avoidance
QP — status (``infeasible`` with the reason; ``limits_violated`` when a planner that does not
impose the bounds returns a plan beyond them), cost, what the bounds cost against the same planner
unbounded, and the exact peaks.  A planner not on this branch is listed as ``not available``
(iamp.comparison.bounded).  Markdown on standard output (or ``--out``, written atomically).
"""

from __future__ import annotations

import argparse
import sys
import time

from iamp.comparison.bounded import BOUNDED_PLANNERS, bounded_rows, markdown_table, pmp_qp_gap
from iamp.core.atomic import write_text
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.scenario import builtin_names
from iamp.prediction.resolve import load_problem


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--hold", choices=("foh", "zoh"), default="foh")
    ap.add_argument("--solver", default="clarabel")
    ap.add_argument("--scenarios", nargs="*", default=None)
    ap.add_argument("--box", action="store_true",
                    help="only the passenger car's input box (ax, ay): the bounds the bounded PMP imposes exactly, "
                         "so PMP = bounded QP can be checked (relative cost gap per scenario)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    names = args.scenarios or list(builtin_names())
    limits = PhysicalLimits(ax=PASSENGER_CAR.ax, ay=PASSENGER_CAR.ay) if args.box else PASSENGER_CAR
    rows = []
    gaps: list[str] = []
    start = time.perf_counter()
    for name in names:
        _, problem, _ = load_problem(name)
        steps = args.steps if problem.m <= 1 else min(args.steps, 30)  # two vehicles: (N-1)(N-2) candidates
        sys.stderr.write(f"{name} (N = {steps}) ...\n")
        new = bounded_rows(name, problem, limits, steps=steps, hold=args.hold, solver=args.solver,
                           planners=tuple(BOUNDED_PLANNERS))
        gap = pmp_qp_gap(new)
        if gap is not None:
            gaps.append(f"- {name}: bounded PMP vs bounded QP (N = {steps}): relative cost gap {gap:.3e}")
        rows += new
    lim = ", ".join(f"{k} {list(v) if isinstance(v, tuple) else v}" for k, v in limits.given().items())
    text = (f"{'PASSENGER_CAR input box' if args.box else 'PASSENGER_CAR'}: {lim}; N = {args.steps} (two or more "
            f"vehicles: N = {min(args.steps, 30)}), {args.hold.upper()}, {args.solver}; "
            f"{time.perf_counter() - start:.0f} s\n\n" + markdown_table(rows) + "\n"
            + ("\n" + "\n".join(gaps) + "\n" if gaps else ""))
    if args.out:
        write_text(args.out, text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
