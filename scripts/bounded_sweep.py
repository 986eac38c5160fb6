"""The bounded PMP against the bounded FOH QP on new draws: every disagreement classified (issue 32 item 4).

``random_problem(seed, m)`` (m = 1, 2, 3) with the input box at ``scale`` of its unbounded plan's
peaks per side (at least 0.5 m/s², tests/test_bounded_random.py's ``boxed``) on both inputs, on
``ax`` only or on ``ay`` only; ``seed``, ``m``, ``scale`` ∈ [--lo, --hi] and the box's axes drawn by
``numpy.random.default_rng(--rng)``.  The reference is the bounded QP (Clarabel, FOH): ``N = 60``
with the contact time refined off the grid (one vehicle), the sweep over the grid's nodes at
``N = 16`` (two vehicles) or ``N = 8`` (three); where the QP has a plan and the PMP does not, or
their costs differ beyond the grid's error, the FOH QP at ``N = 240`` through the other's contact
times settles which cost is right.  Classes (one line per problem, then the counts):

* ``ok``: the PMP ``optimal`` (one vehicle) / not ``infeasible`` where the QP plans, at or below
  its cost (1e-6), and the FOH QP at N = 240 through the PMP's contact times within 2e-3 above it;
  or both without a plan, the PMP's ``infeasible`` certified;
* ``uncertified``: the PMP ``infeasible`` without a certificate, the QP without a plan;
* ``missed``: the QP plans, the PMP ``infeasible`` (``missed-certified`` if it was certified);
* ``status``: the QP plans, the PMP ``inaccurate`` / other / ``local`` for one vehicle;
* ``above``: the PMP's cost above the N = 240 QP through the QP's contact times (beyond 1e-7);
* ``below``: the N = 240 QP through the PMP's contact times below the PMP's cost (beyond 1e-7):
  the PMP's plan is not the fixed-time optimum;
* ``fine-far``: that QP more than 2e-3 above the PMP at N = 240 and still at N = 960;
* ``raised``: the PMP raised.

    python scripts/bounded_sweep.py --rng 7 --count 300 --json /tmp/sweep7.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from collections import Counter
from pathlib import Path
from typing import Any

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_bounded_random import boxed

from iamp.api import plan
from iamp.core import status as stc
from iamp.core.problem import Problem
from iamp.planners.pmp import PMPPlanner, compiled
from iamp.planners.qp.bounded import BoundedQP

SOLVED = (stc.OPTIMAL, stc.LOCAL)
QP_STEPS = {1: 60, 2: 16, 3: 8}


def fine(problem: Problem, times: Any, steps: int = 240) -> float | None:
    """The FOH QP (Clarabel) at ``steps`` through the given contact times: its cost, or ``None``."""
    r = BoundedQP(problem, steps, "foh", "clarabel").solve_times(np.asarray(times, dtype=float))
    return float(r.cost) if r.status == stc.OPTIMAL and r.cost is not None else None


def classify(problem: Problem, m: int) -> dict[str, Any]:
    c0 = time.process_time()
    try:
        pmp = PMPPlanner().plan(problem)
    except Exception as exc:  # the sweep records what raised
        return {"cls": "raised", "error": f"{type(exc).__name__}: {exc}", "tb": traceback.format_exc()}
    cpu = time.process_time() - c0
    kw: dict[str, Any] = {"contact": "refine"} if m == 1 else {}
    qp = plan(problem, "qp", solver="clarabel", steps=QP_STEPS[m], **kw)
    row: dict[str, Any] = {"pmp": pmp.status, "pmp_cost": pmp.cost, "failed": pmp.info.get("failed_check"),
                           "qp": qp.status, "qp_cost": qp.cost, "cpu_s": cpu,
                           "pmp_t": [float(t) for t in pmp.contact_times] if pmp.status in SOLVED else None,
                           "qp_t": [float(t) for t in qp.contact_times] if qp.status in SOLVED else None}
    qp_ok = qp.status in SOLVED
    if pmp.status == stc.INFEASIBLE:
        certified = row["failed"] != "box_infeasible_at_contact_times"
        if qp_ok:
            row["cls"] = "missed-certified" if certified else "missed"
            row["qp_fine"] = fine(problem, row["qp_t"])
        else:
            row["cls"] = "ok" if certified else "uncertified"
        return row
    if pmp.status not in SOLVED or (m == 1 and pmp.status == stc.LOCAL and qp_ok):
        row["cls"] = "status"
        if qp_ok:
            row["qp_fine"] = fine(problem, row["qp_t"])
        return row
    assert pmp.cost is not None
    row["pmp_fine"] = at_pmp = fine(problem, row["pmp_t"])
    if at_pmp is not None and at_pmp < pmp.cost * (1 - 1e-7):
        row["cls"] = "below"
        return row
    if qp_ok and qp.cost is not None and pmp.cost > qp.cost * (1 + 1e-6) + 1e-6:
        row["qp_fine"] = at_qp = fine(problem, row["qp_t"])
        if at_qp is not None and pmp.cost > at_qp * (1 + 1e-7):
            row["cls"] = "above"
            return row
    if at_pmp is not None and at_pmp > pmp.cost * (1 + 2e-3):
        # switching times close together cost the grid more: refined, the FOH QP must approach the PMP
        row["pmp_fine_960"] = at_960 = fine(problem, row["pmp_t"], 960)
        if at_960 is None or at_960 > pmp.cost * (1 + 2e-3) or at_960 >= at_pmp:
            row["cls"] = "fine-far"
            return row
    row["cls"] = "ok"
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rng", type=int, default=7)
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--m", type=int, nargs="+", default=[1, 1, 2, 3])
    ap.add_argument("--lo", type=float, default=0.3)
    ap.add_argument("--hi", type=float, default=1.3)
    ap.add_argument("--axes", nargs="+", default=["both", "both", "ax", "ay"])
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    if compiled.numba_available():
        compiled.load_axis()
        compiled.load_search()
    rng = np.random.default_rng(args.rng)
    rows: list[dict[str, Any]] = []
    while len(rows) < args.count:
        seed = int(rng.integers(0, 10**6))
        m = int(rng.choice(args.m))
        scale = float(rng.uniform(args.lo, args.hi))
        axes = str(rng.choice(args.axes))
        problem = boxed(seed, m, scale, axes)
        if problem is None:
            continue
        row = {"seed": seed, "m": m, "scale": scale, "axes": axes, **classify(problem, m)}
        rows.append(row)
        print(f"{seed:7d} m={m} {scale:.4f} {axes:4s} {row['cls']:16s} pmp={row.get('pmp')!s:11s} "
              f"{row.get('pmp_cost')!s:22s} qp={row.get('qp')!s:10s} {row.get('qp_cost')!s:22s} "
              f"fine(pmp)={row.get('pmp_fine')!s:22s} fine(qp)={row.get('qp_fine')!s:22s} "
              f"failed={row.get('failed')} cpu={row.get('cpu_s', 0):.2f}", flush=True)
        if args.json is not None:
            args.json.write_text(json.dumps(rows, indent=1, default=str))
    counts = Counter(f"m={r['m']} {r['cls']}" for r in rows)
    for key, n in sorted(counts.items()):
        print(f"{n:4d} {key}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
