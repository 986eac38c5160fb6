"""``iamp commonroad plan|check|bench`` (SPEC §16; needs the ``[commonroad]`` extra)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from iamp.cli.types import EXIT_OK, EXIT_SOLVER, positive_float


def cmd_plan(args: argparse.Namespace) -> int:
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import describe, ks_engine, plan
    from iamp.commonroad.solution import build_solution, write_solution
    from iamp.core.outputs import check_output

    if args.out:
        check_output(args.out, inputs=[args.scenario], force=args.force)
    # progress by stage (a plan takes up to tens of seconds): a bar on a terminal, nothing under --json
    with progress_bar(3, "commonroad plan", enabled=progress_enabled(args)) as tick:
        tick.describe("commonroad plan: reading the scenario")
        cr = load(args.scenario, args.vehicle_type)  # the type's body and limits in the plan too
        seen = cr
        if args.predict:
            from iamp.commonroad.predicted import predict_obstacles

            seen = predict_obstacles(cr)
        tick(1, 3)
        tick.describe(f"commonroad plan: planning ({args.planner})")
        rp = plan(seen, args.planner, engine=ks_engine(args.vehicle_type) if args.vehicle_model == "KS" else None)
        tick(2, 3)
        tick.describe("commonroad plan: checking the solution")
        if rp.trajectory is not None and rp.candidate is not None:
            solution, drift = build_solution(cr, rp.trajectory, rp.candidate.steps, args.cost_function,
                                             args.vehicle_type, args.vehicle_model)
            verdict = check(cr.scenario, cr.planning_problem_set, solution, cost=False)
            from iamp.commonroad.costs import REPORTED, evaluate

            named = tuple(dict.fromkeys([args.cost_function, *REPORTED]))
            costs = evaluate(cr, solution, named)
        tick(3, 3)
    out: dict[str, Any] = dict(describe(rp))
    out["scenario"] = cr.name
    out["frame_fit_residual_m"] = cr.frame_fit_residual_m
    out["notes"] = seen.notes
    out["predict"] = bool(args.predict)
    if rp.trajectory is None or rp.candidate is None:
        if args.json:
            sys.stdout.write(json.dumps(out, indent=1) + "\n")
        else:
            sys.stdout.write(f"{cr.name}: {args.planner}: no plan ({rp.reason or rp.status})\n")
        return EXIT_SOLVER
    out["zoh_drift_m" if args.vehicle_model == "PM" else "ks_deviation_m"] = drift
    out["benchmark_id"] = str(solution.benchmark_id)  # type: ignore[attr-defined]  # commonroad: untyped
    if args.out:
        write_solution(solution, args.out, force=args.force)
        out["solution"] = str(args.out)
    verdict.cost = costs[args.cost_function]["total"]
    verdict.cost_function = args.cost_function
    out["commonroad"] = verdict.to_json()
    out["costs"] = costs
    if args.json:
        sys.stdout.write(json.dumps(out, indent=1, default=float) + "\n")
    else:
        c = rp.candidate
        sys.stdout.write(f"{cr.name}: planner {args.planner}, status {rp.status}, J = {rp.cost:.4f}, "
                         f"tf = {c.tf:.1f} s (goal window {cr.goal.steps[0] * cr.dt:.1f}-"
                         f"{cr.goal.steps[1] * cr.dt:.1f} s), solve {rp.solve_time_s:.2f} s\n")
        imposed = ", ".join(f"{i}:{k}" for i, k in rp.imposed) or (
            "none (no vehicle in the way)" if rp.safe else "none")
        sys.stdout.write(f"imposed: {imposed}; peak |u| {rp.peak_accel_mps2:.2f} m/s^2; "
                         f"max heading to road {rp.max_heading_rad:.3f} rad\n")
        entered = [f"{'road edge' if i.obstacle.road_edge else 'vehicle ' + str(i.obstacle.obstacle_id)} "
                   f"{i.depth_m:.2f} m at {i.time_s:.1f} s" for i in rp.intrusions]
        if rp.off_road_s:
            entered.append(f"CommonRoad's road boundary at {rp.off_road_s[0]:.1f}-{rp.off_road_s[-1]:.1f} s")
        if entered:
            sys.stdout.write("enters: " + ", ".join(entered[:5])
                             + (f" (+{len(entered) - 5} more)" if len(entered) > 5 else "") + "\n")
        sys.stdout.write(f"benchmark {solution.benchmark_id}: "  # type: ignore[attr-defined]
                         + ("ZOH drift" if args.vehicle_model == "PM" else "KS tracking deviation")
                         + f" {drift:.3f} m from the plan\n")
        for line in verdict.lines():
            sys.stdout.write(line + "\n")
        sys.stdout.write("costs " + ", ".join(
            f"{cf} {c['total']:.3f}" if c["total"] is not None else f"{cf} - ({c['error']})"
            for cf, c in costs.items()) + "\n")
        if args.out:
            sys.stdout.write(f"wrote {args.out}\n")
    return EXIT_OK if verdict.valid else EXIT_SOLVER


def cmd_check(args: argparse.Namespace) -> int:
    from iamp.commonroad.check import check, read

    scenario, pps, solution = read(args.scenario, args.solution)
    verdict = check(scenario, pps, solution)
    from iamp.commonroad.convert import load
    from iamp.commonroad.costs import evaluate

    if verdict.cost_function is not None:
        cost = evaluate(load(args.scenario), solution, (verdict.cost_function,))[verdict.cost_function]
        verdict.cost = cost["total"]
        if cost["error"] is not None:
            verdict.cost_function += f" (not defined: {cost['error']})"
    if args.json:
        sys.stdout.write(json.dumps(verdict.to_json(), indent=1, default=float) + "\n")
    else:
        for line in verdict.lines():
            sys.stdout.write(line + "\n")
    return EXIT_OK if verdict.valid else EXIT_SOLVER


def cmd_bench(args: argparse.Namespace) -> int:
    from iamp.commonroad.bench import PREDICT_SUFFIX
    from iamp.commonroad.planning import PLANNERS
    from iamp.core.errors import OptionError, ScenarioError

    names = [p.strip() for p in args.planners.split(",")]
    if not any(names) or not all(names):
        why = "names no planner" if not any(names) else "has an empty planner name"
        raise OptionError(f"{args.planners!r} {why}; give one or more of {', '.join(PLANNERS)}, separated by commas",
                          "--planners")
    planners = names
    for p in planners:
        if p.removesuffix(PREDICT_SUFFIX) not in PLANNERS:
            raise OptionError(f"unknown planner {p!r}; choose from {', '.join(PLANNERS)}", "--planners")
    folder = Path(args.folder)
    scenarios = sorted(folder.glob("*.xml")) if folder.is_dir() else []
    if not scenarios:
        raise ScenarioError("not a folder of CommonRoad *.xml scenarios", None, str(folder))
    for peer in args.peer or []:
        if not (Path(peer) / "peer.json").is_file():
            raise OptionError(f"{peer}: holds no peer.json (run scripts/commonroad_peer.py first)", "--peer")
    if args.out is None:
        return _bench_into(args, planners, folder, len(scenarios), None)
    from iamp.core.outputs import guarded_folder  # checked (ours, empty or --force), locked, marked

    with guarded_folder(args.out, "commonroad bench", args.force, inputs=[folder]) as out:
        return _bench_into(args, planners, folder, len(scenarios), out)


def _bench_into(args: argparse.Namespace, planners: list[str], folder: Path, n_scenarios: int,
                out: Path | None) -> int:
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.commonroad.bench import bench, peer_rows, summary, write_reports

    total = len(planners) * n_scenarios
    announced = [0, 0]  # (scenario, planner) pairs begun, of which stored

    # progress as every iamp command shows it: a bar on a terminal, labelled with the scenario and
    # planner under way; nothing under --json or when standard error is not a terminal
    with progress_bar(total, "commonroad bench", enabled=progress_enabled(args)) as tick:
        def progress(text: str) -> None:
            tick(announced[0], total)
            tick.describe(text)
            announced[0] += 1
            announced[1] += text.endswith("(stored)")

        rows = bench(folder, planners, out, args.timeout, progress, cost_function=args.cost_function,
                     vehicle_model=args.vehicle_model, vehicle_type=args.vehicle_type, force=args.force)
        tick(announced[0], total)
    if announced[1] and not args.json:
        # a resumed bench says so (not progress: what the tables are made of)
        sys.stderr.write(f"iamp: {announced[1]} of {announced[0]} (scenario, planner) results taken from {out} "
                         "(stored), not planned again\n")
    for peer in args.peer or []:
        extra = peer_rows(folder, peer)
        rows += extra
        planners += list(dict.fromkeys(r.planner for r in extra))
    command = "iamp commonroad bench " + " ".join(sys.argv[3:]) if len(sys.argv) > 3 else "iamp commonroad bench"
    if out is not None:
        write_reports(rows, planners, out, command)
    s = summary(rows, planners)
    if args.json:
        sys.stdout.write(json.dumps({"summary": s, "rows": [r.__dict__ for r in rows]}, indent=1, default=float)
                         + "\n")
    else:
        for e in s:
            costs = ", ".join(f"{cf} {v:.2f}" for cf, v in e["median_costs"].items() if v is not None)
            sys.stdout.write(f"{e['planner']:8s} {e['vehicle_model']} valid {e['valid']}/{e['scenarios']} (raw "
                             f"{e['valid_raw']}), collision {e['collision']}, infeasible {e['infeasible']}, goal "
                             f"missed {e['goal missed']}, off road {e['off road']}, no plan {e['no plan']}, "
                             f"timeout {e['timeout']}" + (f"; median {costs}" if costs else "") + "\n")
    return EXIT_OK


def _solution_options(p: argparse.ArgumentParser) -> None:
    from iamp.commonroad.costs import COST_FUNCTIONS
    from iamp.commonroad.ks import VEHICLE_TYPES
    from iamp.commonroad.solution import DEFAULT_COST_FUNCTION, VEHICLE_MODELS

    p.add_argument("--cost-function", default=DEFAULT_COST_FUNCTION, choices=tuple(COST_FUNCTIONS),
                   help="CommonRoad cost function named in the solution's benchmark ID and computed as the "
                        f"drivability checker's evaluator defines it (default {DEFAULT_COST_FUNCTION}; WX1, SM1 "
                        "and TR1 are always reported)")
    p.add_argument("--vehicle-model", default="PM", choices=VEHICLE_MODELS,
                   help="PM: point-mass solution; KS: kinematic single-track (steered) solution tracking the "
                        "plan, feasible by the checker's KS test (default PM)")
    p.add_argument("--vehicle-type", type=int, default=2, choices=VEHICLE_TYPES,
                   help="CommonRoad vehicle type: 1 Ford Escort, 2 BMW 320i, 3 VW Vanagon (default 2)")


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp commonroad``."""
    from iamp.commonroad.planning import DEFAULT_PLANNER, PLANNERS

    cr = sub.add_parser("commonroad", help="CommonRoad scenarios: plan, check a solution, benchmark a folder "
                                           "(needs the [commonroad] extra)")
    csub = cr.add_subparsers(dest="commonroad_command", required=True, parser_class=type(cr))
    p = csub.add_parser("plan", help="plan a CommonRoad scenario and judge the plan with CommonRoad's checker")
    p.add_argument("scenario", help="CommonRoad scenario XML with a planning problem")
    p.add_argument("--planner", choices=tuple(PLANNERS), default=DEFAULT_PLANNER,
                   help=f"active set with the avoidance QP (avoid, default), the PMP or the QP equality; all-pmp: "
                        f"the paper's equality on every relevant vehicle; free: no vehicle (default {DEFAULT_PLANNER})")
    p.add_argument("--out", default=None, metavar="SOLUTION.xml", help="write the CommonRoad solution here")
    p.add_argument("--force", action="store_true", help="overwrite --out")
    _solution_options(p)
    p.add_argument("--predict", action="store_true",
                   help="plan with the vehicles predicted by the §7 predictor from their state at t = 0 (the "
                        "checker still judges against the recorded future)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_plan)
    c = csub.add_parser("check", help="CommonRoad's verdict on a solution, every check separately")
    c.add_argument("scenario", help="CommonRoad scenario XML the solution is for")
    c.add_argument("solution", help="CommonRoad solution XML to check (e.g. from iamp commonroad plan --out)")
    c.add_argument("--json", action="store_true", help="machine-readable output")
    c.set_defaults(func=cmd_check)
    b = csub.add_parser("bench", help="plan every scenario of a folder with each planner and check it")
    b.add_argument("folder", help="folder of CommonRoad scenario XML files, each with a planning problem")
    b.add_argument("--planners", default="avoid,pmp,qp,all-pmp,free",
                   help="comma-separated planners; NAME+predict plans with the predicted vehicles "
                        "(default avoid,pmp,qp,all-pmp,free)")
    b.add_argument("--out", default=None, metavar="DIR",
                   help="bench.md/.tex/.json, the solutions and one resumable result per scenario and planner "
                        "(rows/, manifest.json) go here; a folder iamp did not write needs --force")
    b.add_argument("--timeout", type=positive_float, default=120.0, metavar="S",
                   help="per scenario and planner (default 120 s)")
    b.add_argument("--peer", action="append", default=None, metavar="DIR",
                   help="add a peer planner's rows from DIR (written by scripts/commonroad_peer.py or "
                        "scripts/commonroad_peer_idm.py in the peer's own environment); may be repeated")
    _solution_options(b)
    b.add_argument("--force", action="store_true",
                   help="write into an --out folder iamp did not write, or discard its results made with other "
                        "parameters (otherwise a bench resumes: stored results with the same parameters are kept)")
    b.add_argument("--json", action="store_true", help="machine-readable output")
    b.set_defaults(func=cmd_bench)
