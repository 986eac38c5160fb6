r"""``iamp plot SCENARIO --out FILE.png|.pdf|.svg``: one plan, drawn; and ``plan --csv``.

With ``--animate`` (``--out F.gif|.mp4``) the plan moves among its predicted vehicles; with
``--episode LOG`` a closed-loop episode moves from its step log, and with ``--commonroad
SCENARIO.xml --solution SOLUTION.xml`` a CommonRoad solution among the recorded vehicles
(:mod:`iamp.comparison.figures.animation`).

The figure (:func:`plan_figure`):

* top, **to scale** (equal aspect): the x–y plane with the lanes, every surrounding
  vehicle's body and safety box :math:`x_{s,i}(t) \pm (L_i/2 + S_{x,i})` by
  :math:`y_{s,i} \pm (W_i/2 + S_{y,i})` at several instants, the ego's path and body at the
  same instants, and each contact point (the named corner at :math:`t_i`);
* below, against time, longitudinal on the left and lateral on the right: the speeds
  :math:`v_x, v_y` [m/s], the accelerations (the inputs) :math:`a_x = u_x, a_y = u_y`
  [m/s²] and the jerks :math:`\dot u_x, \dot u_y` [m/s³], with the contact times marked.

The PMP's and the FOH QP's inputs are piecewise linear, so their jerk is piecewise constant
(it jumps at the contact times, where the co-states :math:`p_1, p_3` jump). A ZOH input is
piecewise constant: its jerk is a train of impulses, drawn as the input step divided by the
step, :math:`(u_k - u_{k-1})/h`, at the nodes and labelled so.

The planner options are the ones ``iamp plan`` has (copied from its parser), so the figure
shows exactly the plan that ``iamp plan`` with the same options prints.

:func:`write_trajectory_csv` (from :mod:`iamp.cli.trajectory_csv`) writes the SPEC §5 sampled
trajectory for ``iamp plan --csv``.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from iamp.cli.types import EXIT_OK, EXIT_SOLVER, float_in, int_in
from iamp.core.errors import ScenarioError
from iamp.core.plan import Plan

from .trajectory_csv import write_trajectory_csv

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FORMATS", "add_parsers", "cmd_plot", "plan_figure", "plan_label", "write_trajectory_csv"]

#: Output formats of ``iamp plot`` (by the suffix of ``--out``).
FORMATS = ("png", "pdf", "svg")
#: Options of ``iamp plan`` that are not planner options (not copied to ``iamp plot``).
_NOT_COPIED = {"help", "scenario", "json", "csv", "require_safe", "safety_tolerance", "quiet", "func"}


def plan_label(result: Plan) -> str:
    """``PMP`` or ``QP clarabel FOH N=100`` (with ``avoid`` for the avoidance QP)."""
    if result.planner == "pmp":
        return "PMP"
    extra = " avoid" if "avoid" in str(result.diagnostics.constraint or "") else ""
    return f"QP{extra} {result.solver} {str(result.hold).upper()} N={result.steps}"


def _jerk(result: Plan, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(t, jerk (n, 2), impulsive)``: the time derivative of the input.

    Piecewise-linear inputs: finite differences on the fine grid ``tt`` (exact between kinks),
    at the midpoints. ZOH: the input steps over the step size at the interior nodes.
    """
    if result.planner == "qp" and result.hold == "zoh" and result.steps:
        h = result.problem.tf / int(result.steps)
        mid = (np.arange(int(result.steps)) + 0.5) * h  # one sample inside each interval
        u = result.inputs(mid)
        return np.arange(1, int(result.steps)) * h, np.diff(u, axis=0) / h, True
    u = result.inputs(tt)
    return 0.5 * (tt[1:] + tt[:-1]), np.diff(u, axis=0) / np.diff(tt)[:, None], False


def plan_figure(result: Plan, *, title: str | None = None, snapshots: int = 6, pyplot: bool = False) -> Figure:
    """The ``iamp plot`` figure of one plan (see the module docstring).

    Parameters
    ----------
    result : Plan
        A plan with a trajectory.
    title : str, optional
    snapshots : int
        Number of instants drawn in the x–y plane, evenly spaced over ``[0, t_f]``.
    pyplot : bool
        Make the figure through :mod:`matplotlib.pyplot` (so that ``plt.show()`` and the
        documentation's gallery see it); default: a standalone figure (no GUI state).

    Returns
    -------
    Figure
        The figure.
    """
    from iamp.comparison.figures.style import (
        SAFETY_COLOR,
        is_avoidance,
        legend_below,
        planner_style,
        tidy_axis,
    )
    from iamp.comparison.figures.trajectory import draw_xy, xy_limits

    problem = result.problem
    tf = problem.tf
    label = plan_label(result)
    color = planner_style(label)["color"]
    xmin, xmax, ymin, ymax = xy_limits(result)
    width = 10.0
    xy_height = 0.92 * width * (ymax - ymin) / (xmax - xmin) + 1.3  # to scale, plus the legend
    from matplotlib.figure import Figure

    size = (width, xy_height + 3 * 2.1 + 0.4)
    if pyplot:
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=size, layout="constrained")
    else:
        fig = Figure(figsize=size, layout="constrained")
    gs = fig.add_gridspec(4, 2, height_ratios=[xy_height, 2.1, 2.1, 2.1])
    ax_xy = fig.add_subplot(gs[0, :])
    draw_xy(ax_xy, result, np.linspace(0.0, tf, max(int(snapshots), 2)), time_labels=True, ego_color=color)
    ax_xy.set_title("x–y plane to scale (equal aspect); ego and vehicles at the labelled instants, lighter = "
                    "earlier", fontsize=9)
    legend_below(ax_xy, ncol=3, fontsize=7)

    time_name = "crossing time $\\tau_i$" if is_avoidance(result) else "contact time $t_i$"
    tt = np.linspace(0.0, tf, 2001)
    X = result.states(tt)
    U = result.inputs(tt)
    tj, J, impulsive = _jerk(result, tt)
    rows: list[tuple[str, Any, Any, str]] = [
        ("speed", (tt, X[:, 1]), (tt, X[:, 3]), "m/s"),
        ("acceleration", (tt, U[:, 0]), (tt, U[:, 1]), "m/s$^2$"),
        ("jerk", (tj, J[:, 0]), (tj, J[:, 1]), "m/s$^3$"),
    ]
    names = {"speed": ("$v_x$", "$v_y$"), "acceleration": ("$a_x = u_x$", "$a_y = u_y$"),
             "jerk": ("$\\dot u_x$", "$\\dot u_y$")}
    for r, (kind, left, right, unit) in enumerate(rows):
        for c, (tv, yv) in enumerate((left, right)):
            ax = fig.add_subplot(gs[r + 1, c])
            sym = names[kind][c]
            if kind == "jerk" and impulsive:
                ax.plot(tv, yv, "o", ms=2.5, color=color, label=f"{sym}: ZOH input step / $h$ (impulses)")
            else:
                ax.plot(tv, yv, color=color, lw=1.5, label=f"{sym}, {label}")
            tidy_axis(ax, yv)
            for i, ti in enumerate(result.contact_times):
                if np.isfinite(ti):
                    ax.axvline(float(ti), color=SAFETY_COLOR, ls=":", lw=1.0,
                               label=(time_name if i == 0 else None))
            ax.set_xlim(0.0, tf)
            ax.set_ylabel(f"{sym} [{unit}]")
            ax.set_xlabel("$t$ [s]")
            ax.grid(True, lw=0.3, alpha=0.5)
            ax.legend(fontsize=7, loc="best")
    cost = f", $J$ = {result.cost:.6g} m$^2$/s$^3$" if result.cost is not None else ""
    fig.suptitle(title or f"{problem.name}: {label}{cost}", fontsize=11)
    return fig


def _check_out(path: str, formats: tuple[str, ...] = FORMATS) -> Path:
    out = Path(path)
    fmt = out.suffix.lstrip(".").lower()
    if fmt not in formats:
        raise ScenarioError(f"must end in {', '.join('.' + f for f in formats)} (got {out.name!r})", "--out")
    if out.is_dir():
        raise ScenarioError("is a folder; give a file name", "--out", str(out))
    return out


def cmd_plot(args: argparse.Namespace) -> int:
    """Plan the scenario with the given options and draw the plan into ``--out``."""
    from iamp.cli import plan as plan_cli
    from iamp.cli.progress import call_with_progress
    from iamp.cli.scenarios import load_cli_problem
    from iamp.comparison.figures.animation import ANIMATION_FORMATS, check_animation_path
    from iamp.comparison.figures.style import save_one
    from iamp.core.outputs import check_output  # fail fast: not the scenario, existing only with --force, writable

    sources = [name for name, value in (("SCENARIO", args.scenario), ("--episode", args.episode),
                                        ("--commonroad", args.commonroad)) if value is not None]
    if len(sources) != 1:
        raise ScenarioError("give exactly one of SCENARIO, --episode LOG and --commonroad SCENARIO.xml"
                            + (f" (got {' and '.join(sources)})" if sources else ""), sources[-1] if sources
                            else "SCENARIO")
    if (args.commonroad is None) != (args.solution is None):
        raise ScenarioError("--commonroad and --solution go together", "--solution")
    moving = args.animate or args.episode is not None or args.commonroad is not None
    out = _check_out(args.out, ANIMATION_FORMATS if moving else FORMATS)
    if moving:
        check_animation_path(out)  # an .mp4 without ffmpeg: refused before the work
    inputs = [p for p in (args.scenario, args.episode, args.commonroad, args.solution) if p not in (None, "-")]
    check_output(out, inputs, getattr(args, "force", False))
    if args.episode is not None or args.commonroad is not None:
        return _animate_file(args, out)
    if hasattr(plan_cli, "check_options"):
        plan_cli.check_options(args)
    if getattr(args, "constraint", "equality") == "avoid" and not getattr(args, "_constraint_from_plan", False):
        raise ScenarioError("the avoidance QP (SPEC §10) is not available in this version of iamp plan",
                            "--constraint")
    _, problem, _ = load_cli_problem(args.scenario, args.model)
    # the planner `iamp plan` builds from the same options
    result = call_with_progress(plan_cli.prepared_plan(args), problem, desc="planning", enabled=args)
    if not result.ok or result.trajectory is None:
        sys.stderr.write(f"iamp: the plan failed (status {result.status}); nothing to draw, {out} not written\n")
        return EXIT_SOLVER
    if args.animate:
        from iamp.comparison.figures.animation import animate_plan

        animate_plan(result, out, fps=args.fps, speed=args.speed)
    else:
        save_one(plan_figure(result, title=args.title, snapshots=args.snapshots), out)
    print(f"wrote {out} ({plan_label(result)}, status {result.status}, J = {result.cost:.9g} m²/s³)")
    return EXIT_OK


def _animate_file(args: argparse.Namespace, out: Path) -> int:
    """``--episode LOG`` or ``--commonroad SCENARIO.xml --solution SOLUTION.xml``: animate a file."""
    from iamp.comparison.figures.animation import animate_commonroad, animate_episode

    for option, value in (("--episode", args.episode), ("--commonroad", args.commonroad),
                          ("--solution", args.solution)):
        if value is not None and not Path(value).is_file():
            raise ScenarioError("no such file", option, str(value))
    if args.episode is not None:
        animate_episode(args.episode, out, fps=args.fps, speed=args.speed)
        print(f"wrote {out} (the episode of {args.episode})")
    else:
        animate_commonroad(args.commonroad, args.solution, out, fps=args.fps)
        print(f"wrote {out} (the solution {args.solution} in {args.commonroad})")
    return EXIT_OK


def _copy_plan_options(target: argparse.ArgumentParser) -> set[str]:
    """Give ``target`` the planner options of ``iamp plan`` (same names, types, defaults);
    returns their destinations."""
    from iamp.cli import plan as plan_cli

    scratch = argparse.ArgumentParser(add_help=False).add_subparsers()
    plan_cli.add_parsers(scratch)
    plan_parser = scratch.choices["plan"]
    copied = set()
    for action in plan_parser._actions:
        if action.dest in _NOT_COPIED or not action.option_strings:
            continue
        if action.dest == "force":  # plan's says "the --csv file"; plot writes --out
            action = copy.copy(action)
            action.help = "replace the --out file if it exists"
        target._add_action(action)
        copied.add(action.dest)
    return copied


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp plot``."""
    from iamp.cli.progress import add_quiet_flag

    p = sub.add_parser("plot", help="plan a scenario and draw the plan (x-y to scale, speeds, accelerations, "
                                    "jerks) into a PNG, PDF or SVG",
                       description="Plan a scenario (same planner options as `iamp plan`) and draw it: the x-y "
                                   "plane to scale with every vehicle's safety box at several instants and the "
                                   "contact points, and the speeds, accelerations and jerks against time. "
                                   "SCENARIO is a TOML file, a built-in name, or - for standard input.")
    p.add_argument("scenario", nargs="?", default=None,
                   help="scenario TOML file, built-in name, or - (standard input); omit it with --episode or "
                        "--commonroad")
    p.add_argument("--out", required=True, metavar="FILE",
                   help="output file: .png, .pdf or .svg; with --animate, --episode or --commonroad a .gif or .mp4 "
                        "(mp4 needs ffmpeg); written atomically")
    p.add_argument("--animate", action="store_true",
                   help="an animation of the plan among its predicted vehicles instead of the still figure")
    p.add_argument("--episode", default=None, metavar="LOG",
                   help="animate a closed-loop episode from its step log (iamp simulate --log LOG)")
    p.add_argument("--commonroad", default=None, metavar="SCENARIO.xml",
                   help="animate a CommonRoad solution (with --solution) among the recorded vehicles, drawn by "
                        "CommonRoad's renderer (needs the [commonroad] extra)")
    p.add_argument("--solution", default=None, metavar="SOLUTION.xml",
                   help="the CommonRoad solution file to animate (iamp commonroad plan --out)")
    p.add_argument("--fps", type=float_in("fps"), default=12.0,
                   help="animation frames per second, in [1, 60] (default 12)")
    p.add_argument("--speed", type=float_in("animation_speed"), default=1.0,
                   help="animation: simulated seconds per second shown, in [0.1, 20] (default 1)")
    copied = _copy_plan_options(p)
    if "constraint" not in copied:
        p.add_argument("--constraint", choices=("equality", "avoid"), default="equality",
                       help="QP only: the paper's equality at a contact time, or the avoidance QP (SPEC §10)")
    p.set_defaults(_constraint_from_plan="constraint" in copied)
    p.add_argument("--snapshots", type=int_in("snapshots"), default=6, metavar="K",
                   help="instants drawn in the x-y plane, evenly spaced over [0, tf] (default 6)")
    p.add_argument("--title", default=None, help="figure title (default: scenario, planner and cost)")
    add_quiet_flag(p)
    p.set_defaults(func=cmd_plot)
