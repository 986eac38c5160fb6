"""The ``iamp`` command line.

Exit status: 0 success; 2 bad input (one line on standard error naming the file and the
field, no traceback) or an environment that stops the work (a full disk, a read-only
folder, an unreachable ``--scheduler``: one line naming the path or address); 3 a solver
failed (the status is reported, never a cost); 4 an unsafe plan with ``--require-safe``;
1 an unexpected internal error (one line; ``--debug``, anywhere on the command line, or
``IAMP_DEBUG=1`` shows the traceback); 130 interrupted (Ctrl-C or SIGTERM: temporary files
are removed, nothing half-written is left).
"""

from __future__ import annotations

import argparse
import gc
import os
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import NoReturn

from iamp._version import __version__
from iamp.cli.types import EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_OK, EXIT_SOLVER
from iamp.core.errors import IampError, ScenarioError, SolverError


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {' '.join(message.split())}\n")
        raise SystemExit(EXIT_BAD_INPUT)


class Terminated(BaseException):
    """Raised in the main thread by SIGTERM so that ``finally`` blocks (temporary files,
    locks) run, exactly as for Ctrl-C."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signum)


@contextmanager
def _sigterm_unwinds() -> Iterator[None]:
    """Turn SIGTERM into :class:`Terminated` while the command runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def build_parser() -> argparse.ArgumentParser:
    """The ``iamp`` parser with every available sub-command."""
    parser = _Parser(prog="iamp", description="Interaction-aware optimal lane-change planning.")
    parser.add_argument("--version", action="version", version=f"iamp {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an unexpected error (also accepted after the sub-command)")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    for module in ("iamp.cli.plan", "iamp.cli.scenarios", "iamp.cli.prediction", "iamp.cli.compare",
                   "iamp.cli.report", "iamp.cli.plot", "iamp.cli.completion", "iamp.cli.simulate",
                   "iamp.cli.commonroad"):
        try:
            mod = __import__(module, fromlist=["add_parsers"])
        except ModuleNotFoundError as exc:  # only a missing command module is optional
            if exc.name != module:
                raise
            continue
        mod.add_parsers(sub)
    return parser


def _one_line(text: str, limit: int = 300) -> str:
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``iamp`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Never lets a traceback reach the user: an error iamp raises on purpose is one line with
    its exit status; anything else is a bug, reported in one line with exit status 1 (the
    traceback with ``--debug``).
    """
    args_list = list(sys.argv[1:] if argv is None else argv)
    _tolerant_streams()
    debug = os.environ.get("IAMP_DEBUG", "") not in ("", "0")
    if "--debug" in args_list:
        cut = args_list.index("--") if "--" in args_list else len(args_list)
        debug = debug or "--debug" in args_list[:cut]
        args_list = [a for k, a in enumerate(args_list) if not (a == "--debug" and k < cut)]
    with _sigterm_unwinds(), warnings.catch_warnings():
        if not debug:
            # numerical warnings (overflow in a rejected candidate, ...) are not messages for the
            # user: the plan's status and residuals say whether the result is good
            warnings.simplefilter("ignore", RuntimeWarning)
        try:
            code = _run(args_list)
            if code != EXIT_OK:
                # the failed work's objects, held in reference cycles through the caught error's frames,
                # are freed now: at interpreter exit the drivability checker's bindings (nanobind)
                # printed one line per object still alive (431 lines after a one-line error)
                gc.collect()
            return code
        except KeyboardInterrupt:
            sys.stderr.write("iamp: interrupted\n")
            return EXIT_INTERRUPTED
        except Terminated:
            sys.stderr.write("iamp: terminated (SIGTERM)\n")
            return EXIT_INTERRUPTED
        except SystemExit:
            raise
        except RecursionError:
            _report_bug("RecursionError: input nested too deeply", debug)
            return EXIT_INTERNAL
        except MemoryError:
            _report_bug("MemoryError: out of memory", debug)
            return EXIT_INTERNAL
        except Exception as exc:
            _report_bug(f"{exc.__class__.__name__}: {exc}", debug)
            return EXIT_INTERNAL


def _report_bug(what: str, debug: bool) -> None:
    if debug:
        traceback.print_exc()
    sys.stderr.write(f"iamp: internal error ({_one_line(what)}); this is a bug"
                     + ("" if debug else " - run with --debug for the traceback") + "\n")


def _run(args_list: list[str]) -> int:
    parser = build_parser()
    args = parser.parse_args(args_list)
    try:
        return int(args.func(args) or 0)
    except ScenarioError as exc:
        # the file and field in full (a long path must not push the reason off the line); only
        # the reason is shortened
        where = "".join(f"{part}: " for part in (
            exc.source and " ".join(str(exc.source).split()),
            exc.field and f"field '{' '.join(str(exc.field).split())}'") if part)
        sys.stderr.write(f"iamp: error: {where}{_one_line(exc.message)}\n")
        return EXIT_BAD_INPUT
    except SolverError as exc:
        sys.stderr.write(f"iamp: solver failure ({exc.status}): {_one_line(str(exc))}\n")
        return EXIT_SOLVER
    except IampError as exc:
        sys.stderr.write(f"iamp: error: {_one_line(str(exc))}\n")
        return EXIT_BAD_INPUT
    except (FileNotFoundError, PermissionError, IsADirectoryError, NotADirectoryError) as exc:
        if exc.filename is None and isinstance(exc, FileNotFoundError) and not _cwd_exists():
            sys.stderr.write("iamp: error: the current working directory no longer exists (removed while in "
                             "it): change to an existing folder\n")
        else:
            sys.stderr.write(f"iamp: error: {_one_line(str(exc))}\n")
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        # the reader went away (``iamp ... | head``): stop quietly, without a second error at exit
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except OSError as exc:
        # the machine's refusal (a full disk, a read-only file system, a quota) is the user's
        # situation, not a bug: one line naming the path, exit 2
        from iamp.core.atomic import WRITE_REFUSED

        if exc.errno not in WRITE_REFUSED:
            raise
        # a write without a file name is the standard output's (files go through iamp.core.atomic,
        # which names them)
        where = f"{exc.filename}: " if exc.filename else "cannot write the standard output: "
        sys.stderr.write(f"iamp: error: {where}{_one_line(exc.strerror or str(exc))}\n")
        return EXIT_BAD_INPUT


def _cwd_exists() -> bool:
    try:
        os.getcwd()
    except FileNotFoundError:
        return False
    return True


def _tolerant_streams() -> None:
    """Standard output and error that cannot encode a character (``PYTHONIOENCODING=ascii``, a
    C locale) write ``?`` for it instead of failing (the summaries print ``Φ``, ``²``, ``τ``)."""
    for stream in (sys.stdout, sys.stderr):
        enc = (getattr(stream, "encoding", None) or "").lower().replace("-", "").replace("_", "")
        if enc not in ("utf8", "utf8sig") and hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="replace")
            except (ValueError, OSError):  # pragma: no cover - a closed or detached stream
                pass


if __name__ == "__main__":
    sys.exit(main())
