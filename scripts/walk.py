"""The walk of one plan through the code: which iamp modules a call enters, in order.

Usage::

    PYTHONPATH=TREE python scripts/walk.py [SCENARIO] [--cli [--whole]] [--planner NAME] [--cold] [--json] [--quiet]
    PYTHONPATH=TREE python scripts/walk.py --table [--whole] [--json]   # the five scenarios x pmp, qp (CLI walks)

Traces ``PMPPlanner().plan(problem)`` (or, with ``--cli``, the whole ``iamp plan SCENARIO --json
[--planner NAME]``: the ``plan`` command from its parsed arguments to the printed JSON; with
``--whole`` also the building of every sub-command's parser and the parsing) with ``sys.setprofile``
and measures it twice:

* the *stop* metric (issue 18's first count): a stop at each change of the iamp module that
  executes on a ``call`` event (consecutive calls in one module are one stop); a stop is *back*
  when it enters a module seen before, even if that module is still on the call stack (a callee
  returning to its caller and calling again counts);
* the *stack* metric (the reader's count): a module is *left* when no frame of it remains on the
  call stack; a *return* is a call that enters a module that was left earlier.  A callee returning
  to a caller that is still on the stack is not leaving the caller, so a module called in one
  contiguous stretch is never a return however many calls it makes.  An *upward* call is a call
  from a lower layer into a higher one (``core`` < ``planners`` | ``prediction`` < ``simulation`` <
  ``comparison`` < ``commonroad`` < ``api`` < ``cli`` < ``iamp``), protocol callbacks included;
  the caller is the nearest iamp frame below the callee (calls made for iamp by numpy, scipy or
  the standard library count as made by the iamp frame that called them).  A kernel (a function
  marked ``@compilable``, :mod:`iamp.core.jit`) counts as such a frame: compiled, it runs none.

The CLI is run once untraced before the traced run (``--cold``: not), so that the walk shows the
plan, not the imports (a module body executing at import time is a call too).  Python properties
and methods are calls; reading a plain attribute is not.
"""

from __future__ import annotations

import io
import json
import sys
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager, redirect_stdout
from dataclasses import dataclass, field
from typing import Any

LAYERS = ("core", "planners", "prediction", "simulation", "comparison", "commonroad", "api", "cli")
#: Rank of each layer, lowest first; planners and prediction are one level (independent of each other).
RANKS = {"core": 0, "planners": 1, "prediction": 1, "simulation": 2, "comparison": 3, "commonroad": 4,
         "api": 5, "cli": 6}
SCENARIOS = ("paper-1", "paper-2", "paper-3", "paper-1-poly", "two-vehicle")


def rank(module: str) -> int:
    """Position of the module's layer, lowest first (``iamp`` itself: above every layer)."""
    return RANKS.get(layer(module), len(RANKS))


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else module


@dataclass
class StackWalk:
    """The stack metric, fed one ``call`` / ``ret`` event per Python frame entered / left.

    ``module`` is the frame's module name, ``None`` for a frame outside iamp (numpy, the standard
    library): such frames sit on the stack but are nobody's module.
    """

    entered: list[str] = field(default_factory=list)  # modules in the order first entered
    returns: list[tuple[str, str, str]] = field(default_factory=list)  # (module, function, caller module)
    upward: Counter[tuple[str, str]] = field(default_factory=Counter)  # (caller, callee.function) -> calls
    stretches: Counter[str] = field(default_factory=Counter)  # module -> contiguous stretches on the stack
    plan_made: int | None = None  # len(returns) when the planner handed its Plan up (None: not yet)
    planning_from: int | None = None  # len(returns) at the first call into the planners layer
    _stack: list[str | None] = field(default_factory=list)
    _active: Counter[str] = field(default_factory=Counter)

    def caller(self) -> str | None:
        """The nearest iamp module on the stack."""
        return next((m for m in reversed(self._stack) if m is not None), None)

    def call(self, module: str | None, function: str = "") -> None:
        if module is not None:
            if self.planning_from is None and layer(module) == "planners":
                self.planning_from = len(self.returns)
            caller = self.caller()
            if self._active[module] == 0:
                self.stretches[module] += 1
                if self.stretches[module] == 1:
                    self.entered.append(module)
                else:
                    self.returns.append((module, function, caller or ""))
            if caller is not None and rank(module) > rank(caller):
                self.upward[(caller, f"{module}.{function}")] += 1
            self._active[module] += 1
        self._stack.append(module)

    def ret(self) -> None:
        if not self._stack:  # a frame that was running before the trace began
            return
        module = self._stack.pop()
        if module is not None:
            self._active[module] -= 1

    def summary(self) -> dict[str, Any]:
        made = len(self.returns) if self.plan_made is None else self.plan_made
        loading = made if self.planning_from is None else min(self.planning_from, made)
        return {"modules": len(self.entered), "returns": len(self.returns), "returns_to_plan": made,
                "returns_loading": loading, "returns_planning": made - loading,
                "upward_calls": sum(self.upward.values()),
                "returned_to": dict(Counter(m for m, _, _ in self.returns).most_common()),
                "upward": {f"{a} -> {b}": n for (a, b), n in sorted(self.upward.items())}}


@dataclass
class StopWalk:
    """The stop metric of issue 18 (every change of the executing module on a ``call`` event)."""

    stops: list[str] = field(default_factory=list)

    def call(self, module: str | None) -> None:
        if module is not None and (not self.stops or self.stops[-1] != module):
            self.stops.append(module)

    def summary(self) -> dict[str, Any]:
        seen: set[str] = set()
        back = 0
        for s in self.stops:
            back += s in seen
            seen.add(s)
        return {"stops": len(self.stops), "modules": len(seen), "back": back}


def _hands_up_plan(frame: Any, value: Any) -> bool:
    """Whether ``frame`` (a planners-layer frame) returns a ``Plan`` to a caller outside the planners
    layer: the moment the walk reaches its Plan (what follows is the output of it)."""
    from iamp.core.plan import Plan

    if not isinstance(value, Plan) or not frame.f_globals.get("__name__", "").startswith("iamp.planners."):
        return False
    back = frame.f_back
    while back is not None and not back.f_globals.get("__name__", "").startswith("iamp."):
        back = back.f_back
    return back is None or not back.f_globals.get("__name__", "").startswith("iamp.planners.")


def _kernel_codes() -> frozenset[Any]:
    """The code objects of every function marked ``@compilable`` (:mod:`iamp.core.jit`) so far."""
    from iamp.core import jit

    return frozenset(fn.__code__ for fn in jit._SOURCE)


@contextmanager
def traced(stack: StackWalk, stops: StopWalk) -> Iterator[None]:
    """Feed both metrics from ``sys.setprofile`` while the block runs."""

    kernels = _kernel_codes()

    def prof(frame: Any, event: str, arg: Any) -> None:
        if event == "call":
            name = frame.f_globals.get("__name__", "")
            # a compilable kernel is a leaf like numpy's: compiled by numba it runs no Python
            # frame, so the walk is the same whether or not the compiled path is loaded
            module = name if name.startswith("iamp.") and frame.f_code not in kernels else None
            stack.call(module, frame.f_code.co_name)
            stops.call(module)
        elif event == "return":
            stack.ret()
            if stack.plan_made is None and _hands_up_plan(frame, arg):
                stack.plan_made = len(stack.returns)

    sys.setprofile(prof)
    try:
        yield
    finally:
        sys.setprofile(None)


def walk_cli(scenario: str, planner: str = "pmp", cold: bool = False,
             whole: bool = False) -> tuple[StackWalk, StopWalk]:
    """Both metrics of ``iamp plan SCENARIO --json --planner PLANNER``: the command (``cmd_plan``
    with the parsed arguments, to the printed JSON), or with ``whole`` all of ``iamp.cli.main.main``
    (building the parser of every sub-command and parsing the arguments too)."""
    from iamp.cli.main import build_parser
    from iamp.cli.main import main as cli_main

    argv = ["plan", scenario, "--json", "--planner", planner]
    if not cold:
        with redirect_stdout(io.StringIO()):
            cli_main(argv)
    stack, stops = StackWalk(), StopWalk()
    if whole:
        with redirect_stdout(io.StringIO()), traced(stack, stops):
            cli_main(argv)
        return stack, stops
    args = build_parser().parse_args(argv)
    with redirect_stdout(io.StringIO()), traced(stack, stops):
        args.func(args)
    return stack, stops


def walk_planner(scenario: str) -> tuple[StackWalk, StopWalk]:
    """Both metrics of ``PMPPlanner().plan(problem)`` (warmed once)."""
    import iamp
    from iamp.planners.pmp.planner import PMPPlanner

    problem = iamp.load_scenario(scenario)
    planner = PMPPlanner()
    planner.plan(problem)  # warm (imports, caches) before tracing
    stack, stops = StackWalk(), StopWalk()
    with traced(stack, stops):
        planner.plan(problem)
    return stack, stops


def table(as_json: bool, whole: bool = False) -> int:
    rows = []
    for planner in ("pmp", "qp"):
        for scenario in SCENARIOS:
            stack, stops = walk_cli(scenario, planner, whole=whole)
            rows.append({"scenario": scenario, "planner": planner, "stop": stops.summary(), "stack": stack.summary()})
    if as_json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"{'iamp plan S --json':28s} {'stops':>6s} {'back':>5s} {'modules':>8s} {'returns':>8s} {'loading':>8s} "
          f"{'planning':>9s} {'output':>7s} {'upward':>7s}")
    for r in rows:
        print(f"{r['scenario'] + ' --planner ' + r['planner']:28s} {r['stop']['stops']:6d} {r['stop']['back']:5d} "
              f"{r['stack']['modules']:8d} {r['stack']['returns']:8d} {r['stack']['returns_loading']:8d} "
              f"{r['stack']['returns_planning']:9d} {r['stack']['returns'] - r['stack']['returns_to_plan']:7d} "
              f"{r['stack']['upward_calls']:7d}")
    return 0


def main(argv: list[str]) -> int:
    flags = {a for a in argv if a.startswith("--")}
    values = [a for a in argv if not a.startswith("--")]
    planner = "pmp"
    if "--planner" in argv:
        planner = argv[argv.index("--planner") + 1]
        values.remove(planner)
    if "--table" in flags:
        return table("--json" in flags, whole="--whole" in flags)
    scenario = values[0] if values else "paper-1-poly"
    if "--cli" in flags:
        stack, stops = walk_cli(scenario, planner, cold="--cold" in flags, whole="--whole" in flags)
    else:
        stack, stops = walk_planner(scenario)
    if "--json" in flags:
        print(json.dumps({"stop": stops.summary(), "stack": stack.summary()}, indent=1))
        return 0
    if "--quiet" not in flags:
        seen: set[str] = set()
        for k, s in enumerate(stops.stops):
            print(f"{k:3d} {'back ' if s in seen else '     '}{layer(s):11s} {s}")
            seen.add(s)
        for k, (module, function, caller) in enumerate(stack.returns):
            when = ("loading" if stack.planning_from is None or k < stack.planning_from else
                    "planning" if stack.plan_made is None or k < stack.plan_made else "output")
            print(f"return ({when}; entered again after it was left): {module}.{function} from {caller}")
        for (caller, callee), n in sorted(stack.upward.items()):
            print(f"upward call (a callback, not an import): {caller} -> {callee} x{n}")
    s, k = stops.summary(), stack.summary()
    print(f"stop metric: {s['stops']} stops in {s['modules']} modules, {s['back']} of them back into a module "
          "entered before")
    print(f"stack metric: {k['modules']} modules, {k['returns']} returns into a module already left, "
          f"{k['returns_loading']} loading the scenario, {k['returns_planning']} from the planner's selection to the "
          f"Plan, {k['returns'] - k['returns_to_plan']} in the output; {k['upward_calls']} upward calls")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
