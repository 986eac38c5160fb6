"""``iamp scenarios``: the built-in scenarios."""

from __future__ import annotations

import argparse

from iamp.cli.types import EXIT_OK


def cmd_scenarios(args) -> int:
    from iamp.core.scenario import builtin_names, load_scenario

    for name in builtin_names():
        sc = load_scenario(name)
        kind = "history" if sc.needs_prediction else "x_poly"
        print(f"{name:16s} {len(sc.vehicles)} vehicle(s), {kind:7s} {sc.description}")
    return EXIT_OK


def add_parsers(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``iamp scenarios``."""
    s = sub.add_parser("scenarios", help="list the built-in scenarios")
    s.set_defaults(func=cmd_scenarios)
