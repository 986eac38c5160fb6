"""Issue 19's closing table for branch avoid: the paper's scenarios under a passenger car's limits,
``--constraint active`` (PMP and equality QP) and the avoidance QP (``--safety continuous``, and
``nodes`` for study).

    PYTHONPATH=. python scripts/avoid_table.py [--steps 50] [--out FILE]

Per plan: status, cost, whether its own SPEC §9 report is intrusion-free, and the peaks of the
trajectory (``|a_x|``, ``|a_y|``, ``|a|``, speed range, ``|jerk|``) from a dense evaluation on
20,001 samples of the planner's own trajectory (jerk: finite differences of the dense
acceleration), judged against ``PASSENGER_CAR``.  On this branch only the avoidance QP imposes
the limits; the PMP and equality QP of the active set plan the unbounded problem (the bounded
PMP and bounded equality QP are on branches bpmp and limits), so their "within" column says
whether the unbounded plan happens to satisfy the bounds.  Markdown on standard output (or
``--out``, written atomically).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

from iamp.core.atomic import write_text
from iamp.core.errors import IampError
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.scenario import builtin_names
from iamp.planners import registry
from iamp.prediction.resolve import load_problem


def dense_peaks(plan: Any, n: int = 20001) -> dict[str, float]:
    tf = plan.problem.tf
    t = np.linspace(0.0, tf, n)
    X = plan.trajectory.states(t)
    U = np.asarray(plan.trajectory.inputs(t))
    jerk = np.abs(np.diff(U, axis=0)) / np.diff(t)[:, None]
    return {"ax_min": float(U[:, 0].min()), "ax_max": float(U[:, 0].max()), "ay_abs": float(np.abs(U[:, 1]).max()),
            "a_total": float(np.hypot(U[:, 0], U[:, 1]).max()), "vx_min": float(X[:, 1].min()),
            "vx_max": float(X[:, 1].max()), "jerk": float(jerk.max())}


def within(p: dict[str, float], lim: PhysicalLimits, tol: float = 1e-6) -> bool:
    ok = True
    if lim.ax is not None:
        ok &= lim.ax[0] - tol <= p["ax_min"] and p["ax_max"] <= lim.ax[1] + tol
    if lim.ay is not None:
        ok &= p["ay_abs"] <= max(-lim.ay[0], lim.ay[1]) + tol
    if lim.a_total is not None:
        ok &= p["a_total"] <= lim.a_total + tol
    if lim.vx is not None:
        ok &= lim.vx[0] - tol <= p["vx_min"] and p["vx_max"] <= lim.vx[1] + tol
    if lim.jerk is not None:
        ok &= p["jerk"] <= lim.jerk + 1e-3  # finite differences of a piecewise-linear input
    return bool(ok)


CONFIGS = (("pmp-active", "PMP, --constraint active", {}),
           ("qp-active", "QP, --constraint active", {"steps": None}),
           ("qp-avoid", "avoid, continuous", {"steps": None}),
           ("qp-avoid", "avoid, nodes (study)", {"steps": None, "safety": "nodes"}))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--scenarios", nargs="*", default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    lines = ["| scenario | planner | status | cost J | intrusion-free | within limits | a_x [min, max] | "
             "max abs a_y | max abs a | v_x [min, max] | max abs jerk | time |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    start = time.perf_counter()
    for name in args.scenarios or list(builtin_names()):
        _, problem, _ = load_problem(name)
        problem = problem.with_limits(PASSENGER_CAR)
        for entry, label, opts in CONFIGS:
            o = {k: (args.steps if v is None else v) for k, v in opts.items()}
            sys.stderr.write(f"{name}: {label} ...\n")
            t0 = time.perf_counter()
            try:
                plan = registry.make_planner(entry, **o).plan(problem)
            except IampError as exc:  # a scenario the planner refuses (exit 2 in the CLI)
                lines.append(f"| {name} | {label} | refused: {str(exc)[:120]} | — | — | — | — | — | — | — | — | — |")
                continue
            dt = time.perf_counter() - t0
            cost = "—" if plan.cost is None else f"{plan.cost:.6g}"
            if plan.trajectory is None or plan.cost is None:
                why = plan.diagnostics.reason or plan.diagnostics.why or ""
                lines.append(f"| {name} | {label} | {plan.status}{': ' + why[:90] if why else ''} | — | — | — | — | "
                             f"— | — | — | — | {dt:.2f} s |")
                continue
            p = dense_peaks(plan)
            safe = plan.safety.intrusion_free if plan.safety is not None else None
            lines.append(f"| {name} | {label} | {plan.status} | {cost} | {'yes' if safe else 'no'} | "
                         f"{'yes' if within(p, PASSENGER_CAR) else 'no'} | [{p['ax_min']:.2f}, {p['ax_max']:.2f}] | "
                         f"{p['ay_abs']:.2f} | {p['a_total']:.2f} | [{p['vx_min']:.1f}, {p['vx_max']:.1f}] | "
                         f"{p['jerk']:.2f} | {dt:.2f} s |")
    lim = ", ".join(f"{k} {list(v) if isinstance(v, tuple) else v}" for k, v in PASSENGER_CAR.given().items())
    text = (f"PASSENGER_CAR: {lim}; N = {args.steps}, FOH, Clarabel; {time.perf_counter() - start:.0f} s\n\n"
            + "\n".join(lines) + "\n")
    if args.out:
        write_text(args.out, text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
