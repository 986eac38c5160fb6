"""``iamp plan``: plan one scenario and print the summary or the SPEC §5 JSON."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from iamp.cli.types import EXIT_OK, EXIT_SOLVER, EXIT_UNSAFE, float_in, leader_model_file, model_file, steps_int
from iamp.core.errors import OptionError, ScenarioError, SolverError
from iamp.core.plan import Plan
from iamp.core.problem import Problem, SurroundingVehicle
from iamp.core.safety import SAFETY_TOLERANCE_M, SafetyReport
from iamp.core.scenario import Scenario
from iamp.planners import registry
from iamp.planners.avoid.diagnostics import AvoidDiagnostics
from iamp.planners.avoid.options import inequality_backends
from iamp.planners.diagnostics import ActiveSetDiagnostics
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.qp.hold import HOLDS
from iamp.planners.qp.options import CONTACTS

#: The one rule for exit status 3 and the cost (issue 22 item 8; SPEC §5): exit 3 whenever the
#: status is not ``optimal``; the cost (and the trajectory) is reported exactly when the plan
#: verified itself (``optimal`` or ``local``), so a ``local`` plan exits 3 *with* its cost,
#: labelled by its status, and every other failure exits 3 with ``"cost": null``.
LOCAL_NOTE = ("status local: this plan is verified at its contact times, but the search could not certify "
              "that they are the global minimiser; its cost is reported under that status (exit 3)")

#: Options that only some planners read (the QP's), with their defaults (SPEC §5).  They default
#: to ``None`` in the parser so that "given by the user" can be told from "the default".
QP_ONLY = {"solver": "clarabel", "hold": "foh", "contact": "grid"}


def option_values(args: argparse.Namespace) -> dict[str, Any]:
    """The planner options the parsed arguments carry (``None``: not given, the default)."""
    names = (*QP_ONLY, *extra_options())
    return {"steps": args.steps, **{name: getattr(args, name, None) for name in names}}


@contextmanager
def _naming_the_flag() -> Iterator[None]:
    """An option refused by the registry (:class:`OptionError`) as a refusal of the CLI's flag."""
    try:
        yield
    except OptionError as exc:
        raise ScenarioError(exc.message, f"--{exc.field}" if exc.field else None) from None


def make_planner(args: argparse.Namespace) -> registry.Planner:
    """The planner object the options ask for, from the registry."""
    spec = registry.lookup(args.planner, getattr(args, "constraint", None) or "equality")
    with _naming_the_flag():
        return spec.make(**registry.options_of(spec, option_values(args)))


def prepared_plan(args: argparse.Namespace) -> Callable[..., Plan]:
    """``plan(problem) -> Plan`` of the planner the options ask for: one call into the registry
    (:func:`iamp.planners.registry.prepare`; the options are validated now, the planner is built
    when it plans). ``iamp plan`` and ``iamp plot`` plan through it."""
    with _naming_the_flag():
        return registry.prepare(args.planner, getattr(args, "constraint", None) or "equality", option_values(args))


def extra_options() -> tuple[str, ...]:
    """The registry's CLI options (:data:`iamp.planners.registry.CLI_OPTIONS`) beyond the QP's."""
    return tuple(name for name in registry.CLI_OPTIONS if name not in QP_ONLY and name != "steps")


def _phi_meaning(vehicle: SurroundingVehicle, phi_x: float) -> str:
    """SPEC §2 identity 4, derived from ∂J/∂corner = −Φ (see docs in compare.signs)."""
    from iamp.comparison.agreement.signs import jump_meaning

    return jump_meaning(vehicle, phi_x)


def check_options(args: argparse.Namespace) -> None:
    """Refuse options that do not apply to the chosen planner; fill in the QP defaults."""
    accepted = {name for spec in registry.REGISTRY.values() if spec.planner == args.planner
                for name in spec.fields}
    for name, default in QP_ONLY.items():
        if getattr(args, name, None) is not None and name not in accepted:
            accept = registry.accepting(name)
            add = " or ".join(f"--planner {a}" for a in accept)
            who = "the QP planner" if accept == ("qp",) else "planner " + " or ".join(accept)
            raise ScenarioError(f"applies to {who} only (add {add} or drop --{name})", f"--{name}")
        if getattr(args, name, None) is None:
            setattr(args, name, default)
    exact = [s for s in registry.REGISTRY.values()
             if s.planner == args.planner and s.constraint == (getattr(args, "constraint", None) or "equality")]
    if exact:  # the options of the one entry --planner/--constraint select
        accepted = set(exact[0].fields)
    for name in extra_options():
        if getattr(args, name, None) is not None and name not in accepted:
            entries = [s for s in registry.REGISTRY.values() if name in s.fields]
            add = " or ".join(f"--planner {s.planner}" + ("" if s.constraint == "equality" else
                                                          f" --constraint {s.constraint}") for s in entries)
            flag = "--" + name.replace("_", "-")
            raise ScenarioError(f"does not apply to this planner (add {add} or drop {flag})", flag)


def failure_json(scenario: str, args: argparse.Namespace, status: str, message: str) -> dict[str, Any]:
    """The SPEC §5 object of a plan that failed before it produced a :class:`Plan`:
    the failure ``status``, ``cost`` null, no contact times, no trajectory."""
    qp = args.planner == "qp"
    return {"scenario": scenario, "planner": args.planner, "solver": args.solver if qp else None,
            "hold": args.hold if qp else None, "steps": int(args.steps), "status": status, "cost": None,
            "contact_times": [], "jumps": [], "solve_time_s": None,
            "trajectory": {k: [] for k in ("t", "x", "y", "vx", "vy", "ax", "ay")}, "safety": None, "error": message}


def cmd_plan(args: argparse.Namespace) -> int:
    """``iamp plan``: validate, plan, print (text or the SPEC §5 JSON); returns the exit status."""
    from iamp.cli.progress import call_with_progress
    from iamp.cli.scenarios import load_cli_problem
    from iamp.cli.scenarios import load_cli_scenario as load_scenario  # a file, a built-in, or - (stdin)
    from iamp.core.limits import qp_work_message
    from iamp.core.status import NUMERICAL_ERROR

    check_options(args)
    if getattr(args, "csv", None) is not None:  # fail fast: not the scenario, no silent overwrite, writable
        from iamp.core.outputs import check_output

        check_output(args.csv, [args.scenario], args.force, option="--csv")
    if args.constraint is None:
        args.constraint = "equality"
    if not any(x.planner == args.planner and x.constraint == args.constraint for x in registry.REGISTRY.values()):
        offer = " or ".join(f"--planner {x.planner}" for x in registry.REGISTRY.values()
                            if x.constraint == args.constraint)
        raise ScenarioError(f"the {args.constraint} constraint is not implemented by the {args.planner} planner "
                            f"(add {offer})", "--constraint")
    if args.model is not None and not load_scenario(args.scenario).needs_prediction:
        raise ScenarioError("applies only to scenarios with an observed history; this scenario gives every "
                            "vehicle's x_poly", "--model", args.scenario)
    scenario, problem, _ = load_cli_problem(args.scenario, args.model)
    if getattr(args, "leader_model", None) is not None:
        if not scenario.needs_prediction:
            raise ScenarioError("applies only to scenarios with an observed history; this scenario gives every "
                                "vehicle's x_poly", "--leader-model", args.scenario)
        from iamp.prediction.resolve import problem_with_leader_model

        problem, _ = problem_with_leader_model(scenario, args.leader_model)
    if problem.limits is not None and not problem.limits.empty and args.planner == "qp":
        from iamp.planners.qp.options import check_limits_solver

        with _naming_the_flag():  # refused before any planning, whichever constraint (SPEC §14)
            check_limits_solver(args.solver)
    if args.planner == "qp" and args.constraint != "avoid":  # the avoidance search has a budget, no work limit
        msg = qp_work_message(problem.m, args.steps)
        if msg is not None:
            raise ScenarioError(msg, "--steps")
    try:
        with _naming_the_flag():  # an option the problem refuses (--solver kkt with [limits]): exit 2
            result = call_with_progress(prepared_plan(args), problem, desc="QP sweep" if args.planner == "qp"
                                        else "planning", enabled=args)
        result.judge_limits()  # SPEC §14: no verified plan of any planner beyond a given bound
        text = json.dumps(result.to_json(scenario.name, args.steps), allow_nan=False) if args.json else ""
    except SolverError as exc:
        return _report_failure(scenario, args, exc.status, str(exc))
    except (np.linalg.LinAlgError, ArithmeticError, ValueError) as exc:
        if isinstance(exc, ScenarioError):
            raise
        # the numerics broke down on an accepted input: a failed plan, never a traceback
        return _report_failure(scenario, args, NUMERICAL_ERROR, f"{exc.__class__.__name__}: {exc}")
    if args.csv is not None and result.ok:
        from iamp.cli.trajectory_csv import write_trajectory_csv

        write_trajectory_csv(result, args.csv, args.steps)
    tolerance = float(getattr(args, "safety_tolerance", SAFETY_TOLERANCE_M))
    if args.json:
        if tolerance != SAFETY_TOLERANCE_M and result.safety is not None:  # the user's threshold, not the default
            obj = json.loads(text)
            obj["safety"].update(safety_tolerance_m=tolerance, unsafe=result.safety.unsafe_beyond(tolerance))
            text = json.dumps(obj, allow_nan=False)
        print(text)
    else:
        _print_summary(scenario, problem, result, args)
        if args.csv is not None:
            print(f"wrote {args.csv} ({args.steps + 1} rows)" if result.ok else f"{args.csv} not written: no plan")
    if not result.is_optimal():
        return EXIT_SOLVER
    safety = result.safety
    unsafe = safety is not None and safety.unsafe_beyond(tolerance)
    return EXIT_UNSAFE if args.require_safe and unsafe else EXIT_OK


def safety_lines(report: SafetyReport, tolerance_m: float) -> list[str]:
    """The text output's safety lines: one per vehicle the ego enters, a *touch* (depth within
    ``tolerance_m``, no overlap: interval, duration and depth in mm) or ``UNSAFE`` (SPEC §9)."""
    if report.safe:
        return report.lines()
    lines = []
    for v in report.unsafe():
        if v.touch_only(tolerance_m):
            spans = ", ".join(f"[{a:.3f}, {b:.3f}] s ({(b - a) * 1e3:.0f} ms)" for a, b in v.intrusion)
            lines.append(f"touch     {v.name}: touches its safety region {spans}, depth at most "
                         f"{v.max_intrusion_m * 1e3:.1f} mm, within the safety tolerance {tolerance_m * 1e3:g} mm "
                         "(--safety-tolerance); bodies do not overlap")
        else:
            lines.append(f"UNSAFE    {v.describe()}")
    return lines


def _report_failure(scenario: Scenario, args: argparse.Namespace, status: str, message: str) -> int:
    """A plan that failed with an exception: the JSON object or the text summary, exit 3."""
    message = " ".join(message.split())
    if args.json:
        print(json.dumps(failure_json(scenario.name, args, status, message), allow_nan=False))
    else:
        print(f"scenario  {scenario.name}  ({scenario.source})")
        print(f"planner   {args.planner}")
        print(f"status    {status}")
        print(f"reason    {message}")
        print("no cost is reported: the solver did not reach an optimal solution")
    return EXIT_SOLVER


def _print_summary(scenario: Scenario, problem: Problem, result: Plan, args: argparse.Namespace) -> None:
    from iamp.cli.text import polynomial

    cfg = "PMP (indirect, jump conditions)" if result.planner == "pmp" else (
        f"QP ({result.solver}, {str(result.hold).upper()}, N = {result.steps}, contact search: {args.contact})")
    print(f"scenario  {scenario.name}  ({scenario.source})")
    print(f"planner   {cfg}")
    print(f"status    {result.status}")
    diag = result.diagnostics
    if isinstance(diag, ActiveSetDiagnostics):
        _print_active(result, diag)
        return
    if result.status == "unsafe" and diag.constraint == "avoid":
        print(f"reason    {diag.unsafe_reason}")
        from iamp.planners.avoid.result import summary_lines as nodes_lines

        for line in nodes_lines(result):
            print(line)
        return
    if not result.ok:
        if diag.reason:
            print(f"reason    {diag.reason}")
        print("no cost is reported: the solver did not reach an optimal solution")
        return
    if not result.is_optimal():  # `local`: verified at its contact times, not certified global (exit 3)
        print(f"note      {LOCAL_NOTE}")
    if diag.constraint == "avoid":
        if isinstance(diag, AvoidDiagnostics) and diag.safety_mode == "continuous":
            from iamp.planners.avoid.continuous import summary_lines
        else:
            from iamp.planners.avoid.result import summary_lines

        for line in summary_lines(result):
            print(line)
        _print_limits(result)
        return
    print(f"cost J    {result.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]")
    print(f"time      {result.solve_time_s * 1e3:.3f} ms")
    label = "Φ" if result.planner == "pmp" else "ν"
    qp = diag.find(QPDiagnostics)
    if result.planner == "qp" and qp is not None and qp.failures:
        fails = qp.failures
        print(f"warning   {len(fails)} of {len(qp.sweep or ())} sweep candidates did not solve to optimality "
              f"(e.g. nodes {fails[0][0]}: {fails[0][1]}); they are excluded from the search")
    for v, spec, t, j in zip(problem.vehicles, scenario.vehicles, result.contact_times, result.jumps):
        poly = polynomial(v.x_poly)
        origin = "predicted from its history" if spec.history is not None else "given"
        print(f"vehicle {v.name}: x_s(t) = {poly}  ({origin})")
        X = result.require_trajectory().states(np.array([t]))[0]
        print(f"    corner {v.corner}: contact t = {t:.6f} s at (x, y) = ({X[0]:.3f}, {X[2]:.3f}) m; "
              f"{label} = ({j[0]:.6g}, {j[1]:.6g})")
        print(f"    {_phi_meaning(v, j[0])}")
    if result.residuals:
        worst = ", ".join(f"{k} {v:.1e}" for k, v in result.residuals.items())
        print(f"residuals {worst}")
    if result.safety is not None:
        for line in safety_lines(result.safety, float(getattr(args, "safety_tolerance", SAFETY_TOLERANCE_M))):
            print(line)
    _print_limits(result)


def _print_limits(result: Plan) -> None:
    """SPEC §14: one line of peaks against the bounds, and a warning beyond any car."""
    peaks = result.peaks
    if peaks is None:
        return
    sides = result.diagnostics.polygon_sides
    poly = f" (QP: |u| <= a_total imposed as an inscribed {sides}-gon)" if sides else ""
    print(f"limits    {peaks.line()}{poly}")
    for w in peaks.warnings:
        print(f"warning   {w}")


def _planner_help() -> str:
    """The ``--planner`` help, one clause per registry entry."""
    parts = []
    for spec in registry.REGISTRY.values():
        flag = "" if spec.constraint == "equality" else f" --constraint {spec.constraint}"
        parts.append(f"{spec.planner}{flag}: {spec.summary}")
    return "; ".join(parts) + " (default pmp)"


def _print_active(result: Plan, diag: ActiveSetDiagnostics) -> None:
    """The text summary of ``--constraint active``: what was imposed, dropped and why."""
    act = diag.active_set or {}
    if diag.reason:
        print(f"reason    {diag.reason}")
    if result.cost is not None:
        print(f"cost J    {result.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]")
    print(f"time      {result.solve_time_s * 1e3:.3f} ms ({act['iterations']} iteration(s))")
    for v in act["imposed"]:
        print(f"imposed   {v['name']}: contact t = {v['contact_time']:.6f} s, Φ = ({v['phi'][0]:.6g}, "
              f"{v['phi'][1]:.6g}); {v['reason']}")
    if not act["imposed"]:
        print("imposed   none: the unconstrained plan")
    for v in act["dropped"]:
        print(f"dropped   {v['name']}: {v['reason']}")
    if result.safety is not None:
        for line in result.safety.lines():
            print(line)
    _print_limits(result)


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp plan``."""
    p = sub.add_parser("plan", help="plan the optimal lane change of a scenario",
                       description="Plan the optimal lane change of a scenario file or built-in scenario "
                                   "(see `iamp scenarios`).")
    p.add_argument("scenario", help="scenario TOML file, built-in name, or - (standard input)")
    p.add_argument("--planner", choices=registry.planners(), default="pmp", help=_planner_help())
    p.add_argument("--solver", choices=registry.solvers(), default=None,
                   help=f"QP backend, QP only (default clarabel): {', '.join(registry.solvers())}; "
                        f"the avoidance QP needs one that accepts inequalities ({', '.join(inequality_backends())})")
    p.add_argument("--hold", choices=HOLDS, default=None, help="QP only (default foh)")
    p.add_argument("--steps", type=steps_int, default=100,
                   help="grid intervals N for the QP, and output samples t_k = k tf/N for every planner "
                        "(at most 20000; the QP's sweep is limited to perm(N-1, m)·N <= 1e6)")
    p.add_argument("--contact", choices=CONTACTS, default=None, help="QP only (default grid)")
    p.add_argument("--constraint", choices=registry.constraints(), default=None,
                   help="the paper's corner equality on every vehicle (default), the avoidance inequalities "
                        "(QP only, SPEC §10/§14), or the equality only on the vehicles in the way, chosen by the "
                        "jump's sign (active, SPEC §14)")
    for name, f in registry.cli_options().items():  # the options other planners register
        if name not in QP_ONLY and name != "steps":
            who = " or ".join(registry.accepting(name))
            p.add_argument("--" + name.replace("_", "-"), dest=name, choices=f.metadata["choices"], default=None,
                           help=f"{f.metadata['cli']} ({who} only; default {f.default})")
    p.add_argument("--require-safe", action="store_true",
                   help="exit with status 4 when the plan is unsafe: it overlaps a vehicle or enters a safety region "
                        "deeper than --safety-tolerance (SPEC §9); the plan is still printed")
    p.add_argument("--safety-tolerance", type=float_in("safety_tolerance_m"), default=SAFETY_TOLERANCE_M,
                   metavar="M", help="depth [m] up to which entering a safety region without body overlap is "
                   f"reported as a touch, not UNSAFE (default {SAFETY_TOLERANCE_M:g} m; 0: any entry is unsafe)")
    p.add_argument("--model", type=model_file, default=None, help="predictor model file for history scenarios "
                   "(default: the shipped model)")
    p.add_argument("--leader-model", type=leader_model_file, default=None,
                   help="leader model (iamp train --model-kind leader): a history vehicle with another history "
                        "vehicle ahead in its lane (|dy| < 1.75 m) is predicted following it")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object (SPEC §5)")
    p.add_argument("--force", action="store_true", help="replace the --csv file if it exists")
    p.add_argument("--csv", metavar="FILE", default=None,
                   help="also write the trajectory sampled at t_k = k tf/N, k = 0..N, as CSV with the columns "
                        "t,x,y,vx,vy,ax,ay (SI units; written atomically)")
    from iamp.cli.progress import add_quiet_flag

    add_quiet_flag(p)
    p.set_defaults(func=cmd_plan)
