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
import inspect
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Protocol

__all__ = ["ProgressCallback", "ProgressTick", "accepts_progress", "add_quiet_flag", "call_with_progress",
           "progress_bar", "progress_enabled"]

ProgressCallback = Callable[[int, int], None]
"""Signature of every progress callback: ``callback(done, total)``."""


class ProgressTick(Protocol):
    """What :func:`progress_bar` yields: a ``(done, total)`` callback that can also relabel the bar."""

    def __call__(self, done: int, total: int) -> None: ...

    def describe(self, text: str) -> None:
        """Show ``text`` as the bar's label (the step under way)."""


class _Noop:
    """The disabled bar: accepts every report and writes nothing."""

    def __call__(self, done: int, total: int) -> None:
        return None

    def describe(self, text: str) -> None:
        return None


class _Tick:
    """Drives one :mod:`tqdm` bar from absolute ``(done, total)`` reports."""

    def __init__(self, bar: Any) -> None:
        self._bar = bar

    def __call__(self, done: int, total: int) -> None:
        bar = self._bar
        if total and total != bar.total:
            bar.total = total
        step = int(done) - int(bar.n)
        if step > 0:
            bar.update(step)
        elif step < 0:  # a restarted count (e.g. a new sub-task): show it as it is
            bar.n = int(done)
            bar.refresh()

    def describe(self, text: str) -> None:
        self._bar.set_description_str(text, refresh=True)


def accepts_progress(fn: Callable[..., Any]) -> bool:
    """Whether ``fn`` takes a ``progress`` keyword argument (so the CLI can pass its bar's
    callback to library functions that grew the parameter, and nothing to those that did not)."""
    try:
        params = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return "progress" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


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
def progress_bar(total: int | None, desc: str, *, enabled: bool) -> Iterator[ProgressTick]:
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
    ProgressTick
        ``callback(done, total)``, a ``Callable[[int, int], None]``; ``done`` is the number of
        steps finished so far (absolute, not an increment). ``callback.describe(text)``
        relabels the bar.
    """
    if not enabled or not _stderr_is_tty():
        yield _Noop()
        return
    from tqdm import tqdm  # imported lazily: only interactive runs pay for it

    # tqdm's default layout ends with "[elapsed<remaining, rate]": the time left is shown.
    bar: Any = tqdm(total=total, desc=desc, file=sys.stderr, leave=False, dynamic_ncols=True, unit="step")
    try:
        yield _Tick(bar)
    finally:
        bar.close()


def call_with_progress(fn: Callable[..., Any], /, *args: Any, desc: str, enabled: bool | argparse.Namespace,
                       total: int | None = None, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)``, with ``progress=`` a bar's callback if ``fn`` accepts one.

    For library calls that may or may not have grown a ``progress`` parameter yet (the bar
    appears as soon as they do; until then the call is made unchanged).  ``enabled`` may be the
    parsed arguments themselves (:func:`progress_enabled` of them).
    """
    if isinstance(enabled, argparse.Namespace):
        enabled = progress_enabled(enabled)
    if not accepts_progress(fn) or not enabled or not _stderr_is_tty():
        # no bar: no callback either, so the library never calls back into the CLI
        return fn(*args, **kwargs)
    with progress_bar(total, desc, enabled=enabled) as tick:
        return fn(*args, progress=tick, **kwargs)
