"""Numbers in the CLI's text output: rounded, signed once, and never ``None`` (issue 22 item 13).

The JSON output carries the exact values; the text is for a reader, so every number goes
through one of these: :func:`polynomial` writes ``c0 + c1 t + c2 t^2 ...`` with each sign once
(``18 t - 0.067 t^2``, not ``+ -0.067 t^2``) and :func:`quantity` rounds to a few significant
digits and writes ``n/a`` (with the reason, if given) for a missing value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["polynomial", "quantity"]


def polynomial(coeffs: Sequence[float], var: str = "t", digits: int = 6) -> str:
    """``Σ c_k var^k`` as text, ascending powers, zero terms (after ``c_0``) left out."""
    terms: list[tuple[float, str]] = []
    for k, c in enumerate(coeffs):
        c = float(c)
        if k and c == 0.0:
            continue
        power = "" if k == 0 else f" {var}" if k == 1 else f" {var}^{k}"
        terms.append((c, power))
    if not terms:
        return "0"
    c0, p0 = terms[0]
    out = f"{c0:.{digits}g}{p0}"
    for c, p in terms[1:]:
        out += f" {'-' if c < 0 or (c == 0 and math.copysign(1, c) < 0) else '+'} {abs(c):.{digits}g}{p}"
    return out


def quantity(value: float | None, unit: str = "", digits: int = 3, missing: str = "n/a") -> str:
    """``value`` to ``digits`` significant digits with its unit, or ``missing`` for ``None``/NaN."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return missing
    text = f"{float(value):.{digits}g}"
    if "e" not in text and "." not in text and abs(float(value)) >= 10 ** digits:
        text = f"{float(value):.0f}"  # 12345 m, not 1.23e+04 m
    return f"{text} {unit}" if unit else text
