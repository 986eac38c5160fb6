"""Argument types shared by the ``iamp`` sub-commands (argparse ``type=`` callables)."""

from __future__ import annotations

import argparse
import math

#: Exit statuses (SPEC §5, §6, §9): success, bad input, solver failure, unsafe plan with
#: ``--require-safe``; ``EXIT_INTERNAL`` (1) is an unexpected error (a bug: one line, the
#: traceback with ``--debug``), ``EXIT_INTERRUPTED`` (130) a run stopped by Ctrl-C / SIGTERM.
EXIT_OK, EXIT_BAD_INPUT, EXIT_SOLVER, EXIT_UNSAFE = 0, 2, 3, 4
EXIT_INTERNAL, EXIT_INTERRUPTED = 1, 130


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


def steps_int(text: str) -> int:
    """Grid intervals / output samples ``N``: an integer in ``[1, steps_max]`` (:mod:`iamp.core.limits`)."""
    from iamp.core.limits import LIMITS

    value = positive_int(text)
    cap = int(LIMITS["steps_max"])
    if value > cap:
        raise argparse.ArgumentTypeError(f"must be at most {cap} (got {value})")
    return value


#: Largest predictor model file read.
MODEL_FILE_MAX_BYTES = 64 * 1024 * 1024


def model_file(text: str) -> str:
    """A predictor model file that loads and whose time step is within the documented bounds.

    Loads the model once to check it (any failure, whatever its type, becomes one line naming
    the file: the file is the user's input); returns the path unchanged.
    """
    from pathlib import Path

    from iamp.core.limits import LIMITS, bound_message

    path = Path(text)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: cannot be read ({exc.strerror or exc})") from None
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text}: is not a file")
    if size > MODEL_FILE_MAX_BYTES:
        raise argparse.ArgumentTypeError(f"{text}: is {size} bytes; a model file may have at most "
                                         f"{MODEL_FILE_MAX_BYTES} bytes")
    try:
        from iamp.prediction.predictor import Predictor

        predictor = Predictor.from_file(text)
        dt = float(predictor.dt)
    except Exception as exc:  # the file is user input: every way it can be malformed is a refusal
        detail = exc.one_line() if hasattr(exc, "one_line") else f"{exc.__class__.__name__}: {exc}"
        detail = " ".join(str(detail).split())[:300]
        raise argparse.ArgumentTypeError(f"{text}: not a usable predictor model ({detail})") from None
    msg = bound_message(dt, LIMITS["model_dt_min_s"], LIMITS["model_dt_max_s"], "s")
    if msg is not None:
        raise argparse.ArgumentTypeError(f"{text}: field 'dt' {msg}")
    return text


def leader_model_file(text: str) -> str:
    """A leader model file (``kind: "leader"``) that loads, with a usable fallback; returns the path."""
    from pathlib import Path

    path = Path(text)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: cannot be read ({exc.strerror or exc})") from None
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text}: is not a file")
    if size > MODEL_FILE_MAX_BYTES:
        raise argparse.ArgumentTypeError(f"{text}: is {size} bytes; a model file may have at most "
                                         f"{MODEL_FILE_MAX_BYTES} bytes")
    try:
        from iamp.prediction.leader.model import LeaderPredictor

        LeaderPredictor.from_file(text)
    except Exception as exc:  # the file is user input: every way it can be malformed is a refusal
        detail = exc.one_line() if hasattr(exc, "one_line") else f"{exc.__class__.__name__}: {exc}"
        detail = " ".join(str(detail).split())[:300]
        raise argparse.ArgumentTypeError(f"{text}: not a usable leader model ({detail})") from None
    return text
