"""``iamp compare`` and ``iamp bench`` (registered by :func:`iamp.cli.build_parser`).

``iamp compare SCENARIO... [--json] [--latex FILE] [--steps N ...] [--repeats K]``
    Runs the PMP and every QP configuration (OSQP and Clarabel × FOH and ZOH × each ``N``;
    ``--native`` adds the native-solver path) on each scenario (a file or a built-in name;
    history scenarios go through the predictor once, so every planner gets the identical
    polynomial), and prints the runs, their timing and a verdict per pair (rules in
    :mod:`iamp.comparison.agreement.judge`).  Default ``N``: 100 for one vehicle, 20 for two or more
    (a two-vehicle sweep solves ``(N−1)(N−2)`` QPs per configuration).

``iamp bench [--json] [--quick] [-q]``
    The speed numbers against their targets (:mod:`iamp.comparison.bench.run`).

Exit status: 0 when every run finished (verdicts are printed, ``disagree`` included); 3 if
any planner or solver failed (a run whose status is not ``optimal``); 2 for bad input (one
line on standard error, from :func:`iamp.cli.main`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from typing import Any

from iamp.cli.types import float_in, int_in, model_file
from iamp.cli.types import positive_int as _positive_int
from iamp.comparison.durations import format_seconds as _fmt_time
from iamp.core.errors import ScenarioError
from iamp.core.jsonable import to_jsonable
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import Problem

EXIT_OK, EXIT_SOLVER = 0, 3
MAX_CANDIDATES = 20_000


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``compare`` and ``bench`` to the ``iamp`` sub-command parsers."""
    c = sub.add_parser("compare", help="PMP vs QP (OSQP/Clarabel, FOH/ZOH): agreement and timing",
                       description="Run the PMP and the QP baselines on the same problem and judge whether "
                                   "they agree (cost, contact times, states, jumps vs multipliers, KKT "
                                   "residuals), with timing. Exit 0 when every run finished (verdicts printed), "
                                   "3 if a planner or solver failed, 2 for bad input.")
    c.add_argument("scenarios", nargs="+", metavar="SCENARIO",
                   help="scenario TOML files, built-in names, or - (standard input)")
    c.add_argument("--steps", type=_positive_int, nargs="+", default=None, metavar="N",
                   help="QP grid intervals (several allowed; default 100 for one vehicle, 20 for more)")
    c.add_argument("--solvers", nargs="+", choices=("osqp", "clarabel"), default=["osqp", "clarabel"],
                   help="QP solvers compared with the PMP (default: osqp clarabel)")
    c.add_argument("--holds", nargs="+", choices=("foh", "zoh"), default=["foh", "zoh"],
                   help="input holds of the QP: foh (exact for the continuous optimum) and/or zoh (default: both)")
    c.add_argument("--native", action="store_true", help="also run the native OSQP/Clarabel path")
    c.add_argument("--avoid", action="store_true",
                   help="also run the avoidance QP (SPEC §10) per solver, hold and N, with every run's intrusion "
                        "and overlap (SPEC §9) and the cost of safety J_avoid - J_eq; an infeasible avoidance run "
                        "(start or end inside a safety region) is reported with its reason, not counted as a failure")
    c.add_argument("--bounded", action="store_true",
                   help="also plan the bounded problem (SPEC §14): each scenario under a passenger car's limits "
                        "(or its own [limits]) with the PMP, the equality QP, the active set and the avoidance QP: "
                        "status (infeasible with the reason), cost, what the bounds cost, exact peaks, and the "
                        "bounded PMP vs bounded QP gap where the bounded PMP exists")
    c.add_argument("--repeats", type=int_in("repeats"), default=3, metavar="K",
                   help="timed full plans per QP configuration (the PMP gets max(20, 10K)); default 3")
    c.add_argument("--budget", type=float_in("budget_s"), default=5.0, metavar="S",
                   help="stop repeating a configuration once its timed plans exceed S seconds (default 5)")
    c.add_argument("--no-breakdown", action="store_true",
                   help="skip the per-solve timing breakdown (cvxpy compile / re-solve / solver / native)")
    c.add_argument("--model", type=model_file, default=None, help="predictor model file for history scenarios")
    c.add_argument("--force", action="store_true", help="replace an existing --latex file")
    c.add_argument("--json", action="store_true", help="print exactly one JSON object (SPEC §5b)")
    c.add_argument("--latex", default=None, metavar="FILE", help="write a booktabs table (atomically)")
    from iamp.cli.progress import add_quiet_flag

    add_quiet_flag(c)
    c.set_defaults(func=cmd_compare)

    b = sub.add_parser("bench", help="speed numbers against the project's targets",
                       description="One run: medians of the PMP plan and batch API, every QP backend per "
                                   "candidate (osqp, clarabel, piqp, the exact kkt), FOH grid sweeps (native and "
                                   "through cvxpy), the avoidance-QP sweep, OSQP settings, planning with the car's "
                                   "limits (bounded PMP, avoidance with limits at N = 50, one and three vehicles; CPU "
                                   "and wall time) and, without --quick, 60 s closed-loop episodes per iamp "
                                   "planner (medians of 3; --loop: only those); targets, ratios, machine, library "
                                   "versions, and a warning when the spread says the machine was busy. python "
                                   "scripts/bench_table.py writes "
                                   "docs/bench.md and the README's table from the JSON.")
    b.add_argument("--json", action="store_true", help="print exactly one JSON object (SPEC §5b)")
    b.add_argument("--quick", action="store_true", help="fewer repeats")
    b.add_argument("--loop", action="store_true",
                   help="only the closed-loop episodes (needs iamp[sim]); with --json the loop object alone")
    b.add_argument("--planner", action="append", metavar="PLANNER",
                   help="with --loop: this iamp planner's episodes only (repeatable; default every one)")
    b.add_argument("--repeats", type=_positive_int, default=None,
                   help="with --loop: timed episodes per planner (default 3; medians reported)")
    add_quiet_flag(b)
    b.set_defaults(func=cmd_bench)


# --------------------------------------------------------------------------------------
# compare
# --------------------------------------------------------------------------------------


def _candidates(m: int, N: int) -> int:
    return math.perm(N - 1, m) if N - 1 >= m else 0


def _steps_for(problem: Problem, args: argparse.Namespace) -> list[int]:
    steps = args.steps or ([100] if problem.m == 1 else [20])
    for N in steps:
        if N < problem.m + 1:
            raise ScenarioError(f"must be at least {problem.m + 1} for {problem.m} vehicle(s) (got {N})", "--steps")
        if _candidates(problem.m, N) > MAX_CANDIDATES:
            raise ScenarioError(f"N = {N} with {problem.m} vehicles means {_candidates(problem.m, N)} QPs per "
                                f"configuration (limit {MAX_CANDIDATES}); choose a smaller N", "--steps")
    return list(dict.fromkeys(steps))


def run_compare(args: argparse.Namespace) -> dict[str, Any]:
    """Everything ``iamp compare`` computes, as the JSON object (no printing)."""
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.cli.scenarios import load_cli_problem  # a file, a built-in, or - (standard input)
    from iamp.comparison.agreement.judge import compare_problem, default_configs
    from iamp.comparison.timing import DEFAULT_SHIFT_S, geomean_table, qp_breakdown, solver_settings, versions
    from iamp.core.tolerances import TOLERANCES

    loaded: list[tuple[Any, Problem, list[int]]] = []
    refused: list[dict[str, str]] = []
    for spec in args.scenarios:  # validate every input before any solve; a bad one does not stop the good ones
        try:
            scenario, problem, _ = load_cli_problem(spec, args.model)
            loaded.append((scenario, problem, _steps_for(problem, args)))
        except ScenarioError as exc:
            if len(args.scenarios) == 1:
                raise
            refused.append({"scenario": spec, "error": " ".join(exc.one_line().split())})
    if not loaded and refused:
        raise ScenarioError("no scenario could be loaded", "scenarios", ", ".join(args.scenarios))
    scenarios: list[dict[str, Any]] = []
    medians: dict[str, dict[str, Any]] = {}
    # progress: 1000 units per scenario, 800 for the planners (finer if compare_problem reports), 200 breakdown
    with progress_bar(1000 * len(loaded), "compare", enabled=progress_enabled(args)) as tick:
        for k, (scenario, problem, steps) in enumerate(loaded):
            tick.describe(f"compare {scenario.name}")
            configs = default_configs(steps=steps, solvers=tuple(args.solvers), holds=tuple(args.holds),
                                      native=args.native)

            def sub(d: int, n: int, k: int = k) -> None:
                tick(1000 * k + (800 * d) // max(n, 1), 1000 * len(loaded))

            comp = compare_problem(problem, configs, name=scenario.name, repeats=args.repeats, budget_s=args.budget,
                                   progress=sub)
            tick(1000 * k + 800, 1000 * len(loaded))
            if not args.no_breakdown:
                comp.timing["breakdown"] = [
                    qp_breakdown(problem, N, h, s, repeats=max(5, 4 * args.repeats), native=True)
                    for N in steps for h in args.holds for s in args.solvers
                    if not (h == "zoh" and problem.limits is not None and problem.limits.jerk is not None)]
            tick(1000 * (k + 1), 1000 * len(loaded))
            data = comp.to_json()
            data["source"] = str(scenario.source) if getattr(scenario, "source", None) else None
            if getattr(args, "bounded", False):
                from iamp.comparison.bounded import bounded_section

                own = problem.limits is not None and not problem.limits.empty
                data["bounded"] = bounded_section(scenario.name, problem, None if own else PASSENGER_CAR,
                                                  steps=max(steps))
            if getattr(args, "avoid", False):
                from iamp.comparison.safety_compare import avoid_section

                data["avoidance"] = avoid_section(problem, {r.label: r.result for r in comp.runs}, steps,
                                                  tuple(args.solvers), tuple(args.holds))
            scenarios.append(data)
            medians[scenario.name] = {_summary_key(r, auto=args.steps is None): (r["time_s"] or {}).get("median")
                                      for r in data["runs"]}
    return {
        "scenarios": scenarios,
        "refused": refused,
        "timing_summary": geomean_table(medians, DEFAULT_SHIFT_S),
        "repeats": args.repeats,
        "budget_s": args.budget,
        "versions": versions(),
        "solver_settings": solver_settings(),
        "tolerances": {k: v for k, v in TOLERANCES.items()
                       if k.startswith(("cmp_", "pmp_", "refine_cost_rel"))},
    }


def _summary_key(run: dict[str, Any], auto: bool) -> str:
    """Label for the cross-scenario summary; with the default (per-scenario) ``N`` the step
    count is replaced by ``N`` so that one configuration is one row."""
    if run["planner"] == "pmp" or not auto:
        return str(run["label"])
    return (str(run["label"]) + "-").replace(f"-{run['steps']}-", "-N-", 1).rstrip("-")


def _fmt_g(x: float | None, spec: str = ".3g") -> str:
    return "-" if x is None else format(x, spec)


def _print_text(out: dict[str, Any], write: Callable[[str], Any]) -> None:
    for sc in out["scenarios"]:
        write(f"scenario {sc['name']} ({sc['m']} vehicle(s)); x_poly sha256 {sc['x_poly_sha256'][:16]}\n")
        if sc.get("limits"):
            write("  limits " + ", ".join(f"{k} {v}" for k, v in sc["limits"].items())
                  + " (the bounded problem: the bounded PMP against the bounded QP, rules B0-B6)\n")
        for skip in sc.get("skipped", []):
            write(f"  skipped {skip}\n")
        write(f"  {'run':28s} {'status':10s} {'cost J':>14s}  {'contact times [s]':22s} {'jumps (x, y)':34s} "
              f"{'time median [IQR]':>24s}\n")
        for r in sc["runs"]:
            ct = ", ".join(f"{t:.4f}" for t in r["contact_times"])
            jp = "; ".join(f"{j[0]:.4g}, {j[1]:.4g}" for j in r["jumps"])
            ts = r["time_s"] or {}
            tm = f"{_fmt_time(ts.get('median'))} [{_fmt_time(ts.get('iqr'))}] n={ts.get('n', 0)}" if ts else "-"
            cost = f"{r['cost']:.9g}" if r["cost"] is not None else "-"
            extra = ""
            if r.get("failed_candidates"):
                extra = f"  ({r['failed_candidates']} of {r['n_solves']} candidates failed)"
            write(f"  {r['label']:28s} {r['status']:10s} {cost:>14s}  {ct:22s} {jp:34s} {tm:>24s}{extra}\n")
        if "pmp" in sc:
            for s in sc["pmp"]["signs"]:
                write(f"  PMP {s['vehicle']} ({s['corner']}): {s['meaning']}\n")
        write(f"  {'pair':52s} {'verdict':9s} {'cost gap':>10s} {'t gap':>9s} {'state gap':>10s} {'jump gap':>10s}\n")
        for a in sc["agreement"]:
            write(f"  {a['a'] + ' / ' + a['b']:52s} {a['verdict']:9s} {_fmt_g(a['cost_rel_gap'], '.2e'):>10s} "
                  f"{_fmt_g(a['contact_time_gap'], '.2e'):>9s} {_fmt_g(a['state_sup_gap'], '.2e'):>10s} "
                  f"{_fmt_g(a['jump_gap'], '.2e'):>10s}\n")
            for reason in a["reasons"]:
                write(f"      reason: {reason}\n")
            for note in a["notes"]:
                write(f"      note: {note}\n")
        for b in sc.get("timing", {}).get("breakdown", []):
            med = {k: _fmt_time(v["median"]) for k, v in b.items() if isinstance(v, dict) and "median" in v}
            write(f"  timing {b['solver']}-{b['hold']}-{b['steps']}: cvxpy compile {_fmt_time(b['cvxpy_compile_s'])}, "
                  f"re-solve {med['cvxpy_resolve_s']} (solver-reported {med['cvxpy_solver_s']}, overhead "
                  f"{med['cvxpy_overhead_s']}); native {med['native_solve_s']} (solve() call "
                  f"{med['native_solve_call_s']}, solver-reported {med['native_solver_s']})\n")
        write("\n")
    ts = out["timing_summary"]
    if ts["means"]:
        write(f"shifted geometric means of the medians across scenarios (shift {ts['shift_s'] * 1e3:g} ms):\n")
        for lab, m in ts["means"].items():
            write(f"  {lab:28s} {_fmt_time(m['shifted_geomean_s']):>12s}  (n = {m['n']})\n")
    v = out["versions"]
    write("versions: " + ", ".join(f"{k} {v[k]}" for k in ("python", "numpy", "scipy", "cvxpy", "osqp", "clarabel"))
          + "\n")
    n_dis = sum(a["verdict"] != "agree" for sc in out["scenarios"] for a in sc["agreement"])
    n_all = sum(len(sc["agreement"]) for sc in out["scenarios"])
    write(f"verdicts: {n_all - n_dis} of {n_all} pairs agree\n")


def latex_table(out: dict[str, Any]) -> str:
    """One booktabs table: every run of every scenario with its verdict against the PMP."""
    from iamp.comparison.report.latex import Raw, booktabs_table, escape, sci

    rows: list[list[Any] | None] = []
    for k, sc in enumerate(out["scenarios"]):
        if k:
            rows.append(None)
        verdicts = {a["b"]: a for a in sc["agreement"] if a["a"] == "pmp"}
        for r in sc["runs"]:
            a = verdicts.get(r["label"])
            ct = ", ".join(f"{t:.3f}" for t in r["contact_times"]) or "--"
            rows.append([
                escape(sc["name"]), Raw(r"\texttt{" + escape(r["label"]) + "}"), escape(r["status"]),
                sci(r["cost"], 6) if r["cost"] is not None else Raw("--"), ct,
                sci((r["time_s"] or {}).get("median")),
                sci(a["cost_rel_gap"]) if a else Raw("--"),
                sci(a["jump_gap"]) if a else Raw("--"),
                escape(a["verdict"]) if a else Raw("--"),
            ])
    header = ["scenario", "run", "status", Raw("$J$"), Raw("$t_i$ [s]"), Raw("time [s]"),
              Raw(r"$\Delta J/J$"), Raw(r"$|\nu-\Phi|$"), "verdict"]
    v = out["versions"]
    notes = (f"Medians of up to {out['repeats']} timed full plans per configuration (contact-time search "
             f"included; fewer once {out['budget_s']:g} s are spent). "
             f"Gaps: each QP run against the PMP run as they came out (SPEC 5b). "
             f"python {v['python']}, cvxpy {v['cvxpy']}, osqp {v['osqp']}, clarabel {v['clarabel']}.")
    return booktabs_table(header, rows, caption="PMP and QP baselines: cost, contact times, timing and agreement",
                          label="tab:compare", align="llllrrrrl", notes=notes)


def cmd_compare(args: argparse.Namespace) -> int:
    from pathlib import Path

    from iamp.core.outputs import check_output

    inputs = [s for s in args.scenarios if Path(s).is_file()]
    for option in ("latex", "json_out"):  # fail fast, before the solves
        if getattr(args, option, None):
            check_output(getattr(args, option), inputs, args.force, option="--" + option.replace("_", "-"))
    out = run_compare(args)
    if args.latex:
        from iamp.core.atomic import write_text

        write_text(args.latex, latex_table(out))
    if args.json:
        sys.stdout.write(json.dumps(to_jsonable(out), allow_nan=False) + "\n")
    else:
        _print_text(out, sys.stdout.write)
        if getattr(args, "bounded", False):
            from iamp.comparison import bounded

            for sc in out["scenarios"]:
                sys.stdout.write("\n".join(bounded.section_lines(sc["name"], sc["bounded"])) + "\n")
        if getattr(args, "avoid", False):
            from iamp.comparison.safety_compare import section_lines

            for sc in out["scenarios"]:
                sys.stdout.write("\n".join(section_lines(sc["name"], sc["avoidance"])) + "\n")
        if args.latex:
            sys.stdout.write(f"wrote {args.latex}\n")
    failed = any(r["status"] != "optimal" for sc in out["scenarios"] for r in sc["runs"])
    if out.get("refused"):
        for r in out["refused"]:
            sys.stderr.write(f"iamp: error: {r['error']} (this scenario was skipped; the others ran)\n")
        return 2
    return EXIT_SOLVER if failed else EXIT_OK


# --------------------------------------------------------------------------------------
# bench
# --------------------------------------------------------------------------------------


def cmd_bench(args: argparse.Namespace) -> int:
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.comparison.bench.run import run_bench
    from iamp.comparison.bench.text import format_bench

    if not args.loop and (args.planner or args.repeats is not None):
        raise ScenarioError("only with --loop", "--planner" if args.planner else "--repeats")
    if args.loop:
        from iamp.comparison.bench.loop import REPEATS, bench_loop, format_loop
        from iamp.simulation.network import require_sumo
        from iamp.simulation.planning import IAMP_PLANNERS

        unknown = [p for p in args.planner or () if p not in IAMP_PLANNERS]
        if unknown:
            raise ScenarioError(f"not an iamp planner of the loop: {', '.join(unknown)} (choose from "
                                f"{', '.join(IAMP_PLANNERS)})", "--planner")
        require_sumo()
        loop = bench_loop(args.repeats or REPEATS, tuple(args.planner) if args.planner else None)
        sys.stdout.write((json.dumps(to_jsonable(loop), allow_nan=False) if args.json else format_loop(loop)) + "\n")
        return EXIT_OK

    with progress_bar(7, "bench", enabled=progress_enabled(args)) as tick:
        out = run_bench(quick=args.quick, progress=tick)
    if args.json:
        sys.stdout.write(json.dumps(to_jsonable(out), allow_nan=False) + "\n")
    else:
        sys.stdout.write(format_bench(out) + "\n")
    return EXIT_OK
