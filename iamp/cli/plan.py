"""``iamp plan``: plan one scenario and print the summary or the SPEC §5 JSON."""

from __future__ import annotations

import argparse
import json

import numpy as np

from iamp.cli.types import EXIT_OK, EXIT_SOLVER
from iamp.cli.types import positive_int as _positive_int
from iamp.core.errors import ScenarioError
from iamp.prediction.resolve import load_problem


def make_planner(args):
    if args.planner == "pmp":
        from iamp.planners.pmp import PMPPlanner

        return PMPPlanner()
    from iamp.planners.qp import QPPlanner

    return QPPlanner(steps=args.steps, hold=args.hold, solver=args.solver, contact=args.contact)


def _phi_meaning(vehicle, phi_x: float) -> str:
    """SPEC §2 identity 4, derived from ∂J/∂corner = −Φ (see docs in compare.signs)."""
    from iamp.comparison.signs import jump_meaning

    return jump_meaning(vehicle, phi_x)


def cmd_plan(args) -> int:
    scenario, problem, _ = load_problem(args.scenario, args.model)
    if args.planner == "qp" and args.steps < problem.m + 1:
        raise ScenarioError(f"must be at least {problem.m + 1} for {problem.m} vehicle(s)", "--steps")
    result = make_planner(args).plan(problem)
    if args.json:
        print(json.dumps(result.to_json(scenario.name, args.steps), allow_nan=False))
    else:
        _print_summary(scenario, problem, result, args)
    return EXIT_OK if result.is_optimal() else EXIT_SOLVER


def _print_summary(scenario, problem, result, args) -> None:
    cfg = "PMP (indirect, jump conditions)" if result.planner == "pmp" else (
        f"QP ({result.solver}, {result.hold.upper()}, N = {result.steps}, contact search: {args.contact})")
    print(f"scenario  {scenario.name}  ({scenario.source})")
    print(f"planner   {cfg}")
    print(f"status    {result.status}")
    if not result.is_optimal():
        print("no cost is reported: the solver did not reach an optimal solution")
        return
    print(f"cost J    {result.cost:.9g}   [½∫(u_x² + u_y²) dt, m²/s³]")
    print(f"time      {result.solve_time_s * 1e3:.3f} ms")
    label = "Φ" if result.planner == "pmp" else "ν"
    if result.planner == "qp" and result.info.get("failures"):
        fails = result.info["failures"]
        print(f"warning   {len(fails)} of {len(result.info['sweep'])} sweep candidates did not solve to optimality "
              f"(e.g. nodes {fails[0][0]}: {fails[0][1]}); they are excluded from the search")
    for v, spec, t, j in zip(problem.vehicles, scenario.vehicles, result.contact_times, result.jumps):
        poly = " ".join(f"{c:+.6g}" + (f"·t^{k}" if k > 1 else "·t" if k == 1 else "") for k, c in enumerate(v.x_poly))
        origin = "predicted from its history" if spec.history is not None else "given"
        print(f"vehicle {v.name}: x_s(t) = {poly}  ({origin})")
        X = result.trajectory.states(np.array([t]))[0]
        print(f"    corner {v.corner}: contact t = {t:.6f} s at (x, y) = ({X[0]:.3f}, {X[2]:.3f}) m; "
              f"{label} = ({j[0]:.6g}, {j[1]:.6g})")
        print(f"    {_phi_meaning(v, j[0])}")
    if result.residuals:
        worst = ", ".join(f"{k} {v:.1e}" for k, v in result.residuals.items())
        print(f"residuals {worst}")


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp plan``."""
    p = sub.add_parser("plan", help="plan the optimal lane change of a scenario",
                       description="Plan the optimal lane change of a scenario file or built-in scenario "
                                   "(see `iamp scenarios`).")
    p.add_argument("scenario", help="scenario TOML file or built-in name")
    p.add_argument("--planner", choices=("pmp", "qp"), default="pmp")
    p.add_argument("--solver", choices=("osqp", "clarabel"), default="clarabel", help="QP only")
    p.add_argument("--hold", choices=("foh", "zoh"), default="foh", help="QP only")
    p.add_argument("--steps", type=_positive_int, default=100,
                   help="grid intervals N for the QP, and output samples t_k = k tf/N for every planner")
    p.add_argument("--contact", choices=("grid", "refine"), default="grid", help="QP only")
    p.add_argument("--model", default=None, help="predictor model file for history scenarios "
                   "(default: the shipped model)")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object (SPEC §5)")
    p.set_defaults(func=cmd_plan)
