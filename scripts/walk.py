"""The walk of one plan through the code: which iamp modules a call enters, in order.

Usage::

    PYTHONPATH=TREE python scripts/walk.py [SCENARIO] [--cli]

Traces ``PMPPlanner().plan(problem)`` (or, with ``--cli``, the whole ``iamp plan SCENARIO --json``)
with ``sys.setprofile`` and prints the sequence of *stops*: each change of the iamp module that
executes (consecutive calls in one module are one stop), how many stops there are, how many of them
enter a module already left earlier (a *return*), and the layer of every stop.
"""

from __future__ import annotations

import io
import sys
from collections import Counter
from contextlib import redirect_stdout
from typing import Any

LAYERS = ("core", "planners", "prediction", "simulation", "comparison", "api", "cli")


def rank(module: str) -> int:
    """Position of the module's layer, lowest first (``iamp`` itself: above every layer)."""
    order = ("core", "planners", "prediction", "simulation", "comparison", "api", "cli")
    lay = layer(module)
    return order.index(lay) if lay in order else len(order)


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else module


def main() -> int:
    scenario = next((a for a in sys.argv[1:] if not a.startswith("--")), "paper-1-poly")
    cli = "--cli" in sys.argv
    import iamp

    stops: list[str] = []
    upward: Counter[tuple[str, str]] = Counter()

    def prof(frame: Any, event: str, arg: Any) -> None:
        if event != "call":
            return
        name = frame.f_globals.get("__name__", "")
        if name.startswith("iamp.") and (not stops or stops[-1] != name):
            stops.append(name)
            caller = frame.f_back.f_globals.get("__name__", "") if frame.f_back is not None else ""
            if caller.startswith("iamp.") and rank(name) > rank(caller):
                upward[(caller, f"{name}.{frame.f_code.co_name}")] += 1

    if cli:
        from iamp.cli.main import main as cli_main

        sys.setprofile(prof)
        with redirect_stdout(io.StringIO()):
            cli_main(["plan", scenario, "--json"])
        sys.setprofile(None)
    else:
        try:
            from iamp.planners.pmp.planner import PMPPlanner
        except ImportError:  # the flat layout before issue 18
            from iamp.planners.pmp.planner import PMPPlanner  # type: ignore[no-redef]

        problem = iamp.load_scenario(scenario)
        planner = PMPPlanner()
        planner.plan(problem)  # warm (imports, caches) before tracing
        sys.setprofile(prof)
        planner.plan(problem)
        sys.setprofile(None)
    seen: set[str] = set()
    returns = 0
    for k, s in enumerate(stops):
        back = s in seen
        returns += back
        seen.add(s)
        print(f"{k:3d} {'back ' if back else '     '}{layer(s):11s} {s}")
    layer_stops = [layer(s) for k, s in enumerate(stops) if k == 0 or layer(stops[k - 1]) != layer(s)]
    print("layers in order:", " -> ".join(layer_stops))
    for (caller, callee), n in sorted(upward.items()):
        print(f"upward call (a callback, not an import): {caller} -> {callee} x{n}")
    print(f"{len(stops)} stops in {len(seen)} modules, {returns} of them back into a module already left; "
          f"{len(layer_stops)} layer stops; {sum(upward.values())} upward calls")
    return 0


if __name__ == "__main__":
    sys.exit(main())
