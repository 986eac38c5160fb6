"""Durations as text: one formatter for the plain-text outputs (``iamp bench``, ``iamp compare``).

:func:`format_seconds` writes a number of seconds ``x`` in the unit that reads best:

* ``x < 10⁻³`` — microseconds, ``10⁶·x`` with one decimal (``"12.3 µs"``);
* ``10⁻³ ≤ x < 1`` — milliseconds, ``10³·x`` with ``digits`` decimals (``"4.56 ms"``);
* otherwise — seconds with ``digits`` decimals (``"1.23 s"``).

The report's LaTeX tables have their own format (``\\,``-spaced units, fewer digits for
large microsecond counts): :func:`iamp.comparison.report.tex.tex_time`.
"""

from __future__ import annotations

__all__ = ["format_seconds"]


def format_seconds(x: float | None, *, digits: int = 2, width: int = 0, missing: str = "-") -> str:
    """``x`` seconds as ``µs``, ``ms`` or ``s`` text (module docstring).

    Parameters
    ----------
    x : float or None
        Seconds; ``None`` gives ``missing``.
    digits : int
        Decimals of the ``ms`` and ``s`` values (``µs`` always have one).
    width : int
        Right-align the number in this many characters and pad the unit ``s`` to two
        characters, so that a column of durations lines up (``0``: no padding).
    missing : str
        The text for ``None``.
    """
    if x is None:
        return missing
    w = str(width) if width else ""
    if x < 1e-3:
        return f"{x * 1e6:{w}.1f} µs"
    if x < 1:
        return f"{x * 1e3:{w}.{digits}f} ms"
    return f"{x:{w}.{digits}f} s" + (" " if width else "")
