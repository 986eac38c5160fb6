"""Argument types shared by the ``iamp`` sub-commands (argparse ``type=`` callables)."""

from __future__ import annotations

import argparse
import math

#: Exit statuses (SPEC §5, §6, §9): success, bad input, solver failure, unsafe plan with
#: ``--require-safe``.
EXIT_OK, EXIT_BAD_INPUT, EXIT_SOLVER, EXIT_UNSAFE = 0, 2, 3, 4


def positive_int(text: str) -> int:
    """An integer ``>= 1``."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer (got {text!r})") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer (got {text!r})")
    return value


def positive_float(text: str) -> float:
    """A finite number ``> 0``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number (got {text!r})") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number (got {text!r})")
    return value
