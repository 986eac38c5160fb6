"""The ``iamp`` command line.

Exit status: 0 success; 2 bad input (one line on standard error naming the file and the
field, no traceback); 3 a solver failed (the status is reported, never a cost).
"""

from __future__ import annotations

import argparse
import sys

from iamp._version import __version__
from iamp.cli.types import EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVER
from iamp.core.errors import IampError, ScenarioError, SolverError


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2."""

    def error(self, message):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(EXIT_BAD_INPUT)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="iamp", description="Interaction-aware optimal lane-change planning.")
    parser.add_argument("--version", action="version", version=f"iamp {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    for module in ("iamp.cli.plan", "iamp.cli.scenarios", "iamp.cli.prediction", "iamp.cli.compare",
                   "iamp.cli.report"):
        try:
            mod = __import__(module, fromlist=["add_parsers"])
        except ModuleNotFoundError as exc:  # only a missing command module is optional
            if exc.name != module:
                raise
            continue
        mod.add_parsers(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ScenarioError as exc:
        sys.stderr.write(f"iamp: error: {exc.one_line()}\n")
        return EXIT_BAD_INPUT
    except SolverError as exc:
        sys.stderr.write(f"iamp: solver failure ({exc.status}): {exc}\n")
        return EXIT_SOLVER
    except IampError as exc:
        sys.stderr.write(f"iamp: error: {exc}\n")
        return EXIT_BAD_INPUT
    except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
        sys.stderr.write(f"iamp: error: {exc}\n")
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
