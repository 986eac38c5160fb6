"""Time the continuous-time avoidance planner with limits (issue 32 item 3): N = 50, FOH, one and
three vehicles, every inequality backend; median CPU time of repeats, QP solves, status, cost.

    python scripts/avoid_speed.py [--repeats 10] [--solvers osqp,clarabel,piqp] [--m 1,3] [--json]

One vehicle: ``iamp.planners.examples.overtake_problem`` (the ``avoid_bounded`` bench plan);
three vehicles: ``overtake_three_problem`` (that overtake plus a slow vehicle ahead in the current
lane, which binds, and a fast one behind in it).  The times are CPU time (``time.process_time``)
and wall time, medians of the repeats; ``inherited``: the search's relaxations proved without a
solve (not in ``solves``); a last line per ``m`` says whether every backend reached the same status
and cost (to the tolerance table's ``cmp_cost_rel_<solver>``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from iamp.core.tolerances import tol
from iamp.planners.avoid import AvoidQPPlanner
from iamp.planners.examples import overtake_problem, overtake_three_problem
from iamp.planners.qp.backends import BACKENDS


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--solvers", default="osqp,clarabel,piqp")
    ap.add_argument("--m", default="1,3")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--max-repeat-s", type=float, default=60.0, help="fewer repeats once a row took this long")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = []
    for m in (int(x) for x in a.m.split(",")):
        prob = overtake_problem() if m == 1 else overtake_three_problem()
        for s in a.solvers.split(","):
            planner = AvoidQPPlanner(steps=a.steps, solver=s)
            cpu, wall, plan = [], [], None
            for _ in range(a.repeats):
                c0, w0 = time.process_time(), time.perf_counter()
                plan = planner.plan(prob)
                cpu.append(time.process_time() - c0)
                wall.append(time.perf_counter() - w0)
                if sum(cpu) > a.max_repeat_s:
                    break
            assert plan is not None
            row = {"m": m, "solver": s, "repeats": len(cpu), "cpu_median_s": statistics.median(cpu),
                   "wall_median_s": statistics.median(wall), "status": str(plan.status), "cost": plan.cost,
                   "n_solves": plan.info.get("n_solves"), "boxes": plan.info.get("search", {}).get("boxes"),
                   "inherited": plan.info.get("search", {}).get("inherited_relaxations"),
                   "tau": [float(t) for t in plan.contact_times]}
            rows.append(row)
            if not a.json:
                print(f"m={m} {s:9s} cpu {row['cpu_median_s'] * 1e3:9.2f} ms  wall {row['wall_median_s'] * 1e3:9.2f} ms"
                      f"  ({len(cpu)} repeats)  {row['status']:8s} J={plan.cost!r}  solves={row['n_solves']}"
                      f"  boxes={row['boxes']}  inherited={row['inherited']}  tau={row['tau']}", file=sys.stderr,
                      flush=True)
    # every backend must reach the same certified optimum: same status, cost to the loosest
    # backend's comparison tolerance (the tolerance table, cmp_cost_rel_<solver>)
    for m in sorted({r["m"] for r in rows}):
        group = [r for r in rows if r["m"] == m]
        cost_tol = max(tol(BACKENDS[r["solver"]].tolerance_key.replace("kkt", "cost")) for r in group)
        costs = [r["cost"] for r in group if r["cost"] is not None]
        same = (len({r["status"] for r in group}) == 1 and len(costs) == len(group)
                and max(costs) - min(costs) <= cost_tol * max(1.0, abs(min(costs))))
        for r in group:
            r["backends_agree"] = same
        if not a.json:
            print(f"m={m} backends agree (status, cost to {cost_tol:g} rel): {same}", file=sys.stderr, flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
