"""The bounded PMP on generated three-vehicle problems: how each ends (issue 32 item 4).

``random_problem(seed, m=3)`` with the input box at ``scale`` of its unbounded plan's peaks
(tests/test_bounded_random.py's ``boxed``), ``seed`` from 0..1e6 and ``scale`` from 0.40..1.20
drawn by ``numpy.random.default_rng(--rng)``, until ``--count`` problems have an unbounded plan to
scale.  Prints one line per problem (status, failed check, the certificate's vehicle or pair, its
axis solves, CPU seconds of the plan with the compiled axis solve where numba is installed) and the
count of each ending; ``--json`` writes the rows.

    python scripts/bounded_three_census.py --rng 1 --count 246

The uncertified ``infeasible`` ones (``box_infeasible_at_contact_times``) are what issue 32 item 4
still has to settle: a certificate or a plan.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_bounded_random import boxed

from iamp.planners.pmp import (
    PMPPlanner,
    compiled,
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rng", type=int, default=1, help="seed of numpy.random.default_rng drawing the problems")
    ap.add_argument("--count", type=int, default=246, help="problems with an unbounded plan to scale")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = ap.parse_args(argv)
    if compiled.numba_available():
        compiled.load_axis()
        compiled.load_search()
    rng = np.random.default_rng(args.rng)
    rows = []
    while len(rows) < args.count:
        seed, scale = int(rng.integers(0, 10**6)), float(rng.uniform(0.4, 1.2))
        problem = boxed(seed, 3, scale)
        if problem is None:
            continue
        c0 = time.process_time()
        plan = PMPPlanner().plan(problem)
        cpu = time.process_time() - c0
        search = plan.info.get("search", {}) or {}
        row = {"seed": seed, "scale": scale, "status": plan.status, "failed_check": plan.info.get("failed_check"),
               "vehicle": search.get("infeasibility_vehicle"), "pair": search.get("infeasibility_vehicles"),
               "solves": search.get("infeasibility_solves"), "cost": plan.cost, "cpu_s": cpu}
        rows.append(row)
        print(f"{seed:7d} {scale:.4f} {plan.status:11s} {row['failed_check']!s:36s} vehicle={row['vehicle']!s:4s} "
              f"pair={row['pair']!s:7s} solves={row['solves']!s:6s} cpu={cpu:.3f}", flush=True)
    counts = Counter(f"{r['status']}/{r['failed_check']}" for r in rows)
    for key, n in sorted(counts.items()):
        print(f"{n:4d} {key}")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
