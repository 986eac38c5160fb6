r"""``iamp bench``: the project's speed numbers against their targets, in one run.

All numbers are medians of individual :func:`time.perf_counter` samples after a warm-up
(:mod:`iamp.comparison.timing`), on whatever machine runs the command (the targets were set
for a 2-core machine).  Targets:

==================================================  ==================
PMP plan with the global contact time, one vehicle  ≤ 100 µs
PMP plan, two vehicles                              ≤ 2 ms
batch PMP planning, one-vehicle scenarios           ≥ 10,000 plans/s
native QP solve (one candidate), N = 100            ≤ 1 ms (per solver)
FOH grid sweep, one vehicle, N = 100                ≤ 0.5 s (cvxpy and native, per solver)
==================================================  ==================

Problems: ``paper-1-poly`` (one vehicle) and ``two-vehicle`` (two), both built in; the batch
uses seeded :func:`~iamp.planners.examples.random_problem` scenarios (built before the clock
starts).  The native solve time is the wall time of
:meth:`~iamp.planners.native._NativeQP.solve_nodes` (data update + solve + unpacking) over
the candidates of a full sweep in sweep order (so OSQP's warm start comes from the
neighbouring node, as in a sweep); the solver-reported time is given beside it.  The grid
sweep is a complete :meth:`QPPlanner.plan` (cvxpy: model build and compile included, since a
user's plan pays for it) and a complete native sweep (set-up included).
"""

from __future__ import annotations

import time

import numpy as np

from iamp.comparison.timing import measure, qp_breakdown, solver_settings, summarize, versions

TARGETS = {
    "pmp_plan_one_vehicle_s": ("<=", 100e-6),
    "pmp_plan_two_vehicles_s": ("<=", 2e-3),
    "pmp_batch_plans_per_s": (">=", 10_000.0),
    "qp_native_solve_osqp_s": ("<=", 1e-3),
    "qp_native_solve_clarabel_s": ("<=", 1e-3),
    "qp_grid_sweep_osqp_s": ("<=", 0.5),
    "qp_grid_sweep_clarabel_s": ("<=", 0.5),
    "qp_grid_sweep_native_osqp_s": ("<=", 0.5),
    "qp_grid_sweep_native_clarabel_s": ("<=", 0.5),
}


def _pmp_fn(problem):
    import inspect

    from iamp.planners.pmp import PMPPlanner

    planner = PMPPlanner()
    if "diagnostics" in inspect.signature(planner.plan).parameters:
        return lambda: planner.plan(problem, diagnostics=False)
    return lambda: planner.plan(problem)


def _batch(quick: bool, notes: list) -> tuple[float, dict, dict]:
    """Plans per second of the batch API over one-vehicle scenarios."""
    from iamp.planners import pmp as pmp_mod
    from iamp.planners.examples import random_problem

    K = 2_000 if quick else 10_000
    problems = [random_problem(seed, m=1) for seed in range(K)]
    batch = getattr(pmp_mod, "plan_batch", None)
    if batch is not None:
        stats, res = measure(lambda: batch(problems), repeats=2 if quick else 5, warmup=1)
        ok = int(np.sum(np.asarray(res.status) == "optimal"))
        api = "iamp.planners.pmp.plan_batch"
    else:  # honest fallback: the per-problem planner in a loop
        planner = pmp_mod.PMPPlanner()
        sub = problems[: 500 if quick else 2_000]
        stats, _ = measure(lambda: [planner.plan(p) for p in sub], repeats=1, warmup=0)
        K = len(sub)
        ok = K
        api = "PMPPlanner().plan in a Python loop (plan_batch not available)"
        notes.append("plan_batch does not exist: the batch number is a loop over PMPPlanner.plan")
    rate = K / stats.median
    return rate, stats.to_dict(), {"api": api, "problems": K, "optimal": ok}


def _native_sweep_times(problem, solver: str, steps: int, repeats: int):
    """Per-candidate solve times of native sweeps, and the sweep totals."""
    from iamp.planners.native import native_sweep

    per_solve, per_solver_time, per_call, totals, failures = [], [], [], [], 0
    for _ in range(repeats + 1):  # the first sweep is the warm-up
        from iamp.planners.native import build_native

        t0 = time.perf_counter()
        qp = build_native(problem, steps, "foh", solver)
        walls, own, calls = [], [], []
        orig = qp.solve_nodes

        def timed(nodes, _orig=orig, _walls=walls, _own=own, _calls=calls):
            r = _orig(nodes)
            _walls.append(r["wall_time_s"])
            _own.append(r["solver_time_s"])
            _calls.append(r["solve_call_s"])
            return r

        qp.solve_nodes = timed
        s = native_sweep(problem, steps, "foh", solver, qp=qp)
        totals.append(time.perf_counter() - t0)
        per_solve.append(walls)
        per_solver_time.append(own)
        per_call.append(calls)
        failures = len(s["failures"])
    info = dict(qp.info)
    info["solve_call_s"] = summarize(np.concatenate(per_call[1:])).to_dict()
    return (summarize(np.concatenate(per_solve[1:])), summarize(np.concatenate(per_solver_time[1:])),
            summarize(totals[1:], warmup=1), failures, info)


def run_bench(quick: bool = False) -> dict:
    """Measure everything; returns the ``iamp bench --json`` object (SPEC §5b keys and more)."""
    import warnings

    from iamp.planners.examples import builtin_problem, paper_problem
    from iamp.planners.qp import QPPlanner

    notes: list = []
    one, two = paper_problem(1), builtin_problem("two-vehicle")
    r1 = 30 if quick else 300
    r2 = 5 if quick else 30
    s1, _ = measure(_pmp_fn(one), repeats=r1, warmup=5)
    s2, _ = measure(_pmp_fn(two), repeats=r2, warmup=2)
    rate, batch_stats, batch_info = _batch(quick, notes)

    steps = 100
    native_solve, native_solver, native_sweep_s, native_fail, native_info = {}, {}, {}, {}, {}
    for solver in ("osqp", "clarabel"):
        a, b, c, f, info = _native_sweep_times(one, solver, steps, 1 if quick else 3)
        native_solve[solver], native_solver[solver], native_sweep_s[solver] = a, b, c
        native_fail[solver], native_info[solver] = f, info

    cvx_sweep, cvx_fail = {}, {}
    for solver in ("osqp", "clarabel"):
        planner = QPPlanner(steps=steps, hold="foh", solver=solver)

        def plan(planner=planner):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return planner.plan(one)

        stats, res = measure(plan, repeats=1 if quick else 3, warmup=1, budget_s=20.0)
        cvx_sweep[solver] = stats
        cvx_fail[solver] = len(res.info.get("failures", []))

    breakdown = {s: qp_breakdown(one, steps, "foh", s, repeats=10 if quick else 40, native=False)
                 for s in ("osqp", "clarabel")}

    for solver in ("osqp", "clarabel"):
        if native_fail[solver] or cvx_fail[solver]:
            notes.append(f"{solver}: {native_fail[solver]} (native) / {cvx_fail[solver]} (cvxpy) of {steps - 1} "
                         "sweep candidates did not reach 'solved' with the configured settings; they run to "
                         "max_iter and dominate the sweep time")

    values = {
        "pmp_plan_one_vehicle_s": s1.median,
        "pmp_plan_two_vehicles_s": s2.median,
        "pmp_batch_plans_per_s": rate,
        "qp_native_solve_osqp_s": native_solve["osqp"].median,
        "qp_native_solve_clarabel_s": native_solve["clarabel"].median,
        "qp_grid_sweep_osqp_s": cvx_sweep["osqp"].median,
        "qp_grid_sweep_clarabel_s": cvx_sweep["clarabel"].median,
        "qp_grid_sweep_native_osqp_s": native_sweep_s["osqp"].median,
        "qp_grid_sweep_native_clarabel_s": native_sweep_s["clarabel"].median,
    }
    targets = {}
    for k, (op, target) in TARGETS.items():
        v = values[k]
        met = v <= target if op == "<=" else v >= target
        targets[k] = {"value": float(v), "target": target, "op": op, "met": bool(met)}
    ratios = {
        "pmp_two_over_one_vehicle": s2.median / s1.median,
        "native_clarabel_solve_over_pmp_plan": native_solve["clarabel"].median / s1.median,
        "native_osqp_solve_over_pmp_plan": native_solve["osqp"].median / s1.median,
        "cvxpy_clarabel_sweep_over_pmp_plan": cvx_sweep["clarabel"].median / s1.median,
        "cvxpy_osqp_sweep_over_pmp_plan": cvx_sweep["osqp"].median / s1.median,
        "cvxpy_over_native_sweep_clarabel": cvx_sweep["clarabel"].median / native_sweep_s["clarabel"].median,
        "cvxpy_over_native_sweep_osqp": cvx_sweep["osqp"].median / native_sweep_s["osqp"].median,
        "osqp_over_clarabel_native_solve": native_solve["osqp"].median / native_solve["clarabel"].median,
        "pmp_batch_speedup_over_single_plan": rate * s1.median,
    }
    return {
        "pmp_plan_s": {"one_vehicle": s1.median, "two_vehicles": s2.median},
        "pmp_batch_plans_per_s": rate,
        "qp_native_solve_s": {s: native_solve[s].median for s in ("osqp", "clarabel")},
        "qp_grid_sweep_s": {s: cvx_sweep[s].median for s in ("osqp", "clarabel")},
        "qp_grid_sweep_native_s": {s: native_sweep_s[s].median for s in ("osqp", "clarabel")},
        "versions": versions(),
        "solver_settings": solver_settings(),
        "quick": bool(quick),
        "steps": steps,
        "problems": {"one_vehicle": one.name, "two_vehicles": two.name},
        "stats": {
            "pmp_plan_one_vehicle_s": s1.to_dict(), "pmp_plan_two_vehicles_s": s2.to_dict(),
            "pmp_batch_s": batch_stats,
            "qp_native_solve_s": {s: v.to_dict() for s, v in native_solve.items()},
            "qp_native_solver_reported_s": {s: v.to_dict() for s, v in native_solver.items()},
            "qp_grid_sweep_s": {s: v.to_dict() for s, v in cvx_sweep.items()},
            "qp_grid_sweep_native_s": {s: v.to_dict() for s, v in native_sweep_s.items()},
            "cvxpy_breakdown": breakdown,
        },
        "batch": batch_info,
        "native": native_info,
        "failed_sweep_candidates": {"native": native_fail, "cvxpy": cvx_fail},
        "targets": targets,
        "missed": [k for k, t in targets.items() if not t["met"]],
        "ratios": ratios,
        "notes": notes,
    }


def _fmt_s(x: float) -> str:
    if x < 1e-3:
        return f"{x * 1e6:8.1f} µs"
    if x < 1:
        return f"{x * 1e3:8.3f} ms"
    return f"{x:8.3f} s "


def _fmt_target(x: float) -> str:
    if x < 1e-3:
        return f"{x * 1e6:g} µs"
    if x < 1:
        return f"{x * 1e3:g} ms"
    return f"{x:g} s"


def format_bench(out: dict) -> str:
    """The human-readable report of :func:`run_bench`'s result."""
    lines = ["iamp bench — medians" + (" (quick)" if out.get("quick") else ""), ""]
    names = {
        "pmp_plan_one_vehicle_s": "PMP plan, one vehicle (global t*)",
        "pmp_plan_two_vehicles_s": "PMP plan, two vehicles",
        "pmp_batch_plans_per_s": "PMP batch planning, one vehicle",
        "qp_native_solve_osqp_s": "native QP solve N=100, OSQP (warm)",
        "qp_native_solve_clarabel_s": "native QP solve N=100, Clarabel",
        "qp_grid_sweep_osqp_s": "FOH grid sweep N=100, cvxpy+OSQP",
        "qp_grid_sweep_clarabel_s": "FOH grid sweep N=100, cvxpy+Clarabel",
        "qp_grid_sweep_native_osqp_s": "FOH grid sweep N=100, native OSQP",
        "qp_grid_sweep_native_clarabel_s": "FOH grid sweep N=100, native Clarabel",
    }
    for k, t in out["targets"].items():
        if k == "pmp_batch_plans_per_s":
            val, tgt = f"{t['value']:8.0f} /s", f"{t['op']} {t['target']:.0f} /s"
        else:
            val, tgt = _fmt_s(t["value"]), f"{t['op']} {_fmt_target(t['target'])}"
        lines.append(f"  {names[k]:40s} {val}   target {tgt:12s} {'met' if t['met'] else 'MISSED'}")
    st = out["stats"]
    lines += ["", "  native solve, bare solve() call: "
              + ", ".join(f"{s} {_fmt_s(out['native'][s]['solve_call_s']['median']).strip()}" for s in out["native"])
              + "; solver-reported: "
              + ", ".join(f"{s} {_fmt_s(v['median']).strip()}" for s, v in st["qp_native_solver_reported_s"].items())]
    for s, b in st["cvxpy_breakdown"].items():
        lines.append(f"  cvxpy+{s}: compile (build + first solve) {_fmt_s(b['cvxpy_compile_s']).strip()}, "
                     f"re-solve {_fmt_s(b['cvxpy_resolve_s']['median']).strip()} (solver-reported "
                     f"{_fmt_s(b['cvxpy_solver_s']['median']).strip()}, overhead total-solver "
                     f"{_fmt_s(b['cvxpy_overhead_s']['median']).strip()})")
    lines += ["", "ratios (same run):"]
    for k, v in out["ratios"].items():
        lines.append(f"  {k:42s} {v:10.3g}")
    lines += ["", f"batch API: {out['batch']['api']} ({out['batch']['problems']} problems)"]
    missed = out["missed"]
    lines.append("targets missed: " + (", ".join(missed) if missed else "none"))
    for n in out["notes"]:
        lines.append(f"note: {n}")
    v = out["versions"]
    lines.append("versions: " + ", ".join(f"{k} {v[k]}" for k in ("python", "numpy", "scipy", "cvxpy", "osqp",
                                                                    "clarabel")) + f"; {v['cpu_count']} CPU(s)")
    return "\n".join(lines)
