"""``iamp scenarios`` (list, or ``--show NAME``), ``iamp template``, and the scenario argument
every command shares (a file, a built-in name, or ``-`` for standard input).

``iamp template > my.toml`` writes a scenario file with every key of SPEC §4 explained in a
comment; it plans as it is (``iamp plan my.toml``), so it is the starting point for a new
scenario. ``iamp scenarios --show paper-2`` prints a built-in scenario's TOML exactly as
shipped (``iamp scenarios --show paper-2 > mine.toml`` and edit).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from iamp.cli.types import EXIT_OK
from iamp.core.errors import ScenarioError
from iamp.core.problem import Problem
from iamp.core.scenario import Scenario

__all__ = ["STDIN", "TEMPLATE", "add_parsers", "cmd_scenarios", "cmd_template", "load_cli_problem",
           "load_cli_scenario"]

#: The scenario argument that means "read the TOML from standard input".
STDIN = "-"
_stdin_cache: tuple[object, str] | None = None  # (the stream read, its text)

#: The commented scenario printed by ``iamp template`` (paper scenario 1, vehicle 1 given by its
#: polynomial; the history alternative is shown commented out). It must plan as it is.
TEMPLATE = '''\
# iamp scenario file (SPEC §4). Units are SI: metres, seconds, m/s.
# Plan it:   iamp plan THIS.toml            (or: iamp plan - < THIS.toml)
# Draw it:   iamp plot THIS.toml --out plan.png
# Unknown keys are errors; every value must be a finite number unless noted.

name = "my-scenario"                 # optional; defaults to the file name
description = "Paper scenario 1: merge ahead of a vehicle at 18 m/s in the target lane."  # optional

[ego]                 # the ego's boundary conditions: the full state is fixed at t = 0 and t = tf
tf = 5.0              # horizon [s], > 0
x0 = 0.0              # longitudinal position s_x(0) [m]
y0 = -2.0             # lateral position s_y(0) [m] (centre of the current lane)
vx0 = 20.0            # longitudinal speed v_x(0) [m/s]
vy0 = 0.0             # lateral speed v_y(0) [m/s]; optional, default 0
xf = 85.0             # s_x(tf) [m]
yf = 3.75             # s_y(tf) [m] (centre of the target lane)
vxf = 20.0            # v_x(tf) [m/s]
vyf = 0.0             # v_y(tf) [m/s]; optional, default 0

# One [[vehicles]] table per surrounding vehicle (at least one). The ego passes through one
# named corner of the vehicle's safety region x_s(t) ± (length/2 + safety_x) by
# y ± (width/2 + safety_y) at a free contact time the planner chooses.
[[vehicles]]
name = "sv1"                  # optional
corner = "front-lower"        # front|rear - lower|upper: merge ahead of a vehicle behind in the
                              # target lane = "front-lower"; clear a vehicle ahead in the current
                              # lane = "rear-upper" (mirror lower/upper for a change towards -y)
y = 3.75                      # its lateral position y_s [m], constant
length = 4.8                  # L > 0 [m]
width = 1.8                   # W > 0 [m]
safety_x = 5.0                # S_x >= 0 [m], added to each end
safety_y = 0.5                # S_y >= 0 [m], added to each side
x_poly = [-15.0, 18.0, 0.0, 0.0]   # x_s(t) = c0 + c1 t + c2 t^2 + c3 t^3 [m], ascending powers,
                                   # any length >= 1; here: from -15 m at a constant 18 m/s
# Instead of x_poly, give the vehicle's observed history before t = 0 and let the predictor
# turn it into the cubic (exactly one of x_poly and history per vehicle):
# [vehicles.history]
# t = [-3.0, -2.5, -2.0, -1.5, -1.0, -0.5, 0.0]            # [s], strictly increasing, ends at 0
# x = [-69.0, -60.0, -51.0, -42.0, -33.0, -24.0, -15.0]    # [m], same length as t

# What the ego can do (SPEC §14): a passenger car. Every key is optional; delete the table for
# the paper's unbounded problem. Every plan reports its peaks against these bounds; the QP
# imposes all of them at every grid node, the PMP the input box (ax, ay) exactly.
[limits]
ax = [-6.0, 3.0]      # longitudinal acceleration range [m/s^2] (braking, accelerating)
ay = [-2.0, 2.0]      # lateral acceleration range [m/s^2]
a_total = 8.0         # |u| <= a_total [m/s^2] (friction circle; the QP uses an inscribed 16-gon)
vx = [0.0, 40.0]      # longitudinal speed range [m/s]
# jerk = 5.0          # |du/dt| per axis [m/s^3]: a comfort bound the FOH QP imposes; the PMP
#                     # only checks it (this scenario's PMP plan peaks at 5.84), so it is off here
# y = [-3.0, 4.75]    # range of the ego's centre s_y [m] (road edges less half its width)
'''


def _read_stdin() -> str:
    """Standard input, read once per stream (a second ``-`` in the same command, or a second
    look at the same scenario, gets the same text)."""
    global _stdin_cache
    stream = sys.stdin
    if _stdin_cache is not None and _stdin_cache[0] is stream:
        return _stdin_cache[1]
    if stream is None or stream.isatty():
        raise ScenarioError("standard input is a terminal: pipe a scenario into it "
                            "(e.g. iamp template | iamp plan -)", None, "<stdin>")
    # bytes when possible: text-mode universal newlines would turn a bare CR (invalid TOML) into LF
    buffer = getattr(stream, "buffer", None)
    try:
        text = buffer.read().decode("utf-8") if buffer is not None else stream.read()
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"cannot be read (not UTF-8 text: {exc.reason} at byte {exc.start})", None,
                            "<stdin>") from None
    _stdin_cache = (stream, text)
    return _stdin_cache[1]


def load_cli_scenario(spec: str) -> Scenario:
    """A scenario argument: a TOML file, a built-in name, or ``-`` (TOML on standard input)."""
    from iamp.core.scenario import load_scenario, loads_scenario

    if spec == STDIN:
        return loads_scenario(_read_stdin(), source="<stdin>", default_name="stdin")
    return load_scenario(spec)


def load_cli_problem(spec: str, model: str | None = None) -> tuple[Scenario, Problem, list[Any]]:
    """:func:`iamp.prediction.resolve.load_problem` that also accepts ``-`` for standard input.

    Vehicles given by a history go through the predictor (the model file ``model``, else the
    shipped model); returns ``(scenario, problem, predictions)``.
    """
    from iamp.prediction.resolve import load_problem, problem_from_scenario

    if spec != STDIN:
        return load_problem(spec, model)
    return problem_from_scenario(load_cli_scenario(spec), model)


def cmd_scenarios(args: argparse.Namespace) -> int:
    """List the built-in scenarios, or print one's TOML with ``--show NAME``."""
    from iamp.core.scenario import builtin_names, builtin_text, load_scenario

    if args.show is not None:
        if args.show not in builtin_names():
            raise ScenarioError(f"is not a built-in scenario (built-ins: {', '.join(builtin_names())})",
                                "--show", args.show)
        sys.stdout.write(builtin_text(args.show))
        return EXIT_OK
    for name in builtin_names():
        sc = load_scenario(name)
        kind = "history" if sc.needs_prediction else "x_poly"
        print(f"{name:16s} {len(sc.vehicles)} vehicle(s), {kind:7s} {sc.description}")
    return EXIT_OK


def cmd_template(args: argparse.Namespace) -> int:
    """Print the commented scenario template."""
    sys.stdout.write(TEMPLATE)
    return EXIT_OK


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp scenarios`` and ``iamp template``."""
    s = sub.add_parser("scenarios", help="list the built-in scenarios (or print one with --show)",
                       description="List the built-in scenarios; with --show NAME print that scenario's TOML "
                                   "(redirect it to a file to start your own).")
    s.add_argument("--show", metavar="NAME", default=None, help="print the TOML of the built-in scenario NAME")
    s.set_defaults(func=cmd_scenarios)

    t = sub.add_parser("template", help="print a commented scenario file that plans as it is",
                       description="Print a scenario file (SPEC §4) with every key explained; "
                                   "`iamp template > my.toml` and edit. It plans unchanged: the QP imposes its "
                                   "passenger car's [limits]; a planner that cannot impose a bound reports "
                                   "limits_violated with the peaks.")
    t.set_defaults(func=cmd_template)
