"""CPU time of ``iamp bench``'s bounded PMP cases alone (issue 32 item 3).

The cases are :func:`iamp.comparison.bench.limits.bounded_pmp_problems`, planned by the
registry's ``pmp`` planner exactly as :func:`~iamp.comparison.bench.limits.bench_limits` does,
with the compiled axis solve loaded as ``iamp bench`` has it by then (``load_axis``; the ``m ≥ 2``
search kernels unloaded again).  Prints per case the median process CPU time
(:func:`time.process_time`) over ``--repeats`` plans after one warm-up, the status and the cost
(``repr``, to see that the answers do not change).

Usage::

    python scripts/bounded_speed.py [--repeats 15] [--pure] [--profile CASE] [--case CASE]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time

from iamp.comparison.bench.limits import bounded_pmp_problems
from iamp.planners import registry
from iamp.planners.pmp import compiled


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--pure", action="store_true", help="the Python kernels (no load_axis)")
    ap.add_argument("--case", default=None, help="only the cases whose name contains this")
    ap.add_argument("--profile", default=None, help="cProfile the case whose name contains this (tottime)")
    ap.add_argument("--top", type=int, default=30)
    ap.add_argument("--sort", default="tottime", help="pstats sort key of --profile (tottime, cumulative)")
    args = ap.parse_args()
    if not args.pure and not compiled.load_axis():
        raise SystemExit("numba unavailable: use --pure")
    pmp = registry.make_planner("pmp", diagnostics=False)
    for name, prob in bounded_pmp_problems().items():
        if args.case and args.case not in name:
            continue
        plan = pmp.plan(prob)
        cpus = []
        for _ in range(args.repeats):
            c0 = time.process_time()
            p = pmp.plan(prob)
            cpus.append(time.process_time() - c0)
            assert (p.status, p.cost) == (plan.status, plan.cost), "not deterministic"
        print(f"{name:40s} cpu median {1e3 * statistics.median(cpus):8.2f} ms  min {1e3 * min(cpus):8.2f} ms  "
              f"{plan.status!s:10s} {plan.cost!r}")
        if args.profile and args.profile in name:
            prof = cProfile.Profile(time.process_time)  # CPU time: a loaded machine does not inflate it
            prof.enable()
            for _ in range(args.repeats):
                pmp.plan(prob)
            prof.disable()
            pstats.Stats(prof).sort_stats(args.sort).print_stats(args.top)


if __name__ == "__main__":
    main()
