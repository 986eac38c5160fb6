"""Progress bars for long CLI work, on standard error, silent when nobody is watching.

Library code never prints; functions that can take more than a couple of seconds accept
``progress: Callable[[int, int], None] | None`` and call it with ``(done, total)``. The CLI
turns that callback into a :mod:`tqdm` bar on standard error showing the elapsed time and
the estimated time left::

    with progress_bar(len(cases), "compare", enabled=progress_enabled(args)) as tick:
        run_everything(cases, progress=tick)

The bar is disabled (the callback is a no-op) under ``--json``, under ``--quiet``, or when
standard error is not a terminal, so piped and scripted use sees no escape sequences.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["ProgressCallback", "add_quiet_flag", "progress_bar", "progress_enabled"]

ProgressCallback = Callable[[int, int], None]
"""Signature of every progress callback: ``callback(done, total)``."""


def _noop(done: int, total: int) -> None:
    """Accept a progress report and do nothing."""


def add_quiet_flag(parser: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet`` (no progress bar) to a sub-command parser.

    Parameters
    ----------
    parser
        The sub-command's parser; the flag lands in ``args.quiet``.
    """
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar on standard error")


def progress_enabled(args: argparse.Namespace) -> bool:
    """Whether a bar should be drawn for these parsed arguments.

    False under ``--json`` or ``--quiet`` (missing attributes count as not given); the
    terminal check is made by :func:`progress_bar` itself.
    """
    return not (bool(getattr(args, "json", False)) or bool(getattr(args, "quiet", False)))


def _stderr_is_tty() -> bool:
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # closed or replaced stream
        return False


@contextmanager
def progress_bar(total: int | None, desc: str, *, enabled: bool) -> Iterator[ProgressCallback]:
    """Context manager yielding a ``(done, total)`` callback that drives a progress bar.

    Parameters
    ----------
    total
        Expected number of steps, or ``None`` when unknown (the bar then counts without an
        estimate of the time left). A later callback may revise it: the bar takes the
        ``total`` passed to the callback whenever it differs.
    desc
        Short label shown in front of the bar.
    enabled
        False under ``--json``/``--quiet``; the bar is also off when standard error is not
        a terminal. When off the callback does nothing and nothing is written.

    Yields
    ------
    Callable[[int, int], None]
        ``callback(done, total)``; ``done`` is the number of steps finished so far
        (monotone, absolute, not an increment).
    """
    if not enabled or not _stderr_is_tty():
        yield _noop
        return
    from tqdm import tqdm  # imported lazily: only interactive runs pay for it

    # tqdm's default layout ends with "[elapsed<remaining, rate]": the time left is shown.
    bar: Any = tqdm(total=total, desc=desc, file=sys.stderr, leave=False, dynamic_ncols=True, unit="step")

    def tick(done: int, new_total: int) -> None:
        if new_total and new_total != bar.total:
            bar.total = new_total
        step = int(done) - int(bar.n)
        if step > 0:
            bar.update(step)

    try:
        yield tick
    finally:
        bar.close()
