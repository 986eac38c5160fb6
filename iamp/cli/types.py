"""Argument types shared by the ``iamp`` sub-commands (argparse ``type=`` callables)."""

from __future__ import annotations

import argparse
import math

#: Exit statuses (SPEC §5, §6, §9): success, bad input, solver failure, unsafe plan with
#: ``--require-safe``; ``EXIT_INTERNAL`` (1) is an unexpected error (a bug: one line, the
#: traceback with ``--debug``), ``EXIT_INTERRUPTED`` (130) a run stopped by Ctrl-C / SIGTERM.
EXIT_OK, EXIT_BAD_INPUT, EXIT_SOLVER, EXIT_UNSAFE = 0, 2, 3, 4
#: ``iamp simulate``: the episode ran but its mission failed (SPEC §17: not in the target lane in
#: time, a contact, or for ``--commonroad`` the goal missed or an executed body off the road).
EXIT_MISSION_FAILED = 5
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
    from iamp.core.limits import LIMITS, bound_message

    _readable_model_file(text)
    try:
        from iamp.prediction.predictor import Predictor

        predictor = Predictor.from_file(text)
        dt = float(predictor.dt)
    except Exception as exc:  # the file is user input: every way it can be malformed is a refusal
        detail = exc.one_line() if hasattr(exc, "one_line") else str(exc) or "malformed"
        detail = " ".join(str(detail).split())[:300]
        raise argparse.ArgumentTypeError(f"{text}: not a usable predictor model ({detail})") from None
    msg = bound_message(dt, LIMITS["model_dt_min_s"], LIMITS["model_dt_max_s"], "s")
    if msg is not None:
        raise argparse.ArgumentTypeError(f"{text}: field 'dt' {msg}")
    return text


def leader_model_file(text: str) -> str:
    """A leader model file (``kind: "leader"``) that loads, with a usable fallback; returns the path."""
    _readable_model_file(text)
    try:
        from iamp.prediction.leader.model import LeaderPredictor

        LeaderPredictor.from_file(text)
    except Exception as exc:  # the file is user input: every way it can be malformed is a refusal
        detail = exc.one_line() if hasattr(exc, "one_line") else f"{exc.__class__.__name__}: {exc}"
        detail = " ".join(str(detail).split())[:300]
        raise argparse.ArgumentTypeError(f"{text}: not a usable leader model ({detail})") from None
    return text


#: Bounds of the numeric options that are not scenario values (issue 22 item 5): every
#: number the command line accepts is checked here, before any work, in one line naming it.
#: ``seed`` is SUMO's and numpy's seed range (a 32-bit signed integer); ``seeds`` bounds a
#: campaign's episode list (planners x densities x seeds); durations and periods keep one
#: episode within an hour of simulated time at SUMO's step range.
OPTION_BOUNDS: dict[str, tuple[float, float]] = {
    "seed": (0, 2**31 - 1),
    "seeds": (1, 10_000),
    "workers": (1, 64),
    "episode_s": (0.1, 3600.0),
    "period_s": (0.01, 1.0),
    "repeats": (1, 10_000),
    "budget_s": (1e-3, 3600.0),
    "snapshots": (1, 50),
    "fps": (1.0, 60.0),
    "animation_speed": (0.1, 20.0),
    "order": (1, 20),
    "accel_mps2": (1e-3, 50.0),
    "jerk_psd": (1e-9, 1e6),
    "safety_tolerance_m": (0.0, 1.0),
}


def _bounds(name: str) -> tuple[float, float]:
    """``OPTION_BOUNDS[name]``; ``model_dt_s`` is :mod:`iamp.core.limits`' model time step."""
    if name == "model_dt_s":
        from iamp.core.limits import LIMITS

        return LIMITS["model_dt_min_s"], LIMITS["model_dt_max_s"]
    return OPTION_BOUNDS[name]


def int_in(name: str):  # type: ignore[no-untyped-def]
    """An argparse type: an integer within ``OPTION_BOUNDS[name]``."""
    lo, hi = (int(b) for b in _bounds(name))

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer in [{lo}, {hi}] (got {text!r})") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer in [{lo}, {hi}] (got {text})")
        return value

    parse.__name__ = f"integer in [{lo}, {hi}]"
    return parse


def float_in(name: str):  # type: ignore[no-untyped-def]
    """An argparse type: a finite number within ``OPTION_BOUNDS[name]``."""
    lo, hi = _bounds(name)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number in [{lo:g}, {hi:g}] (got {text!r})") from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"must be a number in [{lo:g}, {hi:g}] (got {text})")
        return value

    parse.__name__ = f"number in [{lo:g}, {hi:g}]"
    return parse


def _readable_model_file(text: str) -> None:
    """Refuse (one line naming the path) a model file that cannot be read, is not a file or is
    larger than :data:`MODEL_FILE_MAX_BYTES`."""
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
