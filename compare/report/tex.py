r"""The text and numbers of the reproduction report's LaTeX.

* :func:`tex_escape` — plain text into LaTeX (special characters escaped, common non-ASCII
  symbols as math, anything else ``?`` so that pdflatex never stops);
* the number formats of the tables: :func:`tex_sci` (``$m\times10^{e}$``), :func:`tex_time`
  (seconds in µs, ms or s), :func:`poly_tex` (a polynomial
  :math:`\sum_k c_k t^k`), :func:`intervals_tex` (time intervals);
* run labels: :func:`short_label` and :func:`pretty_label`.

:mod:`iamp.comparison.report.latex` has the generic pieces (escaping, scientific notation) these
formats build on; the tables are :mod:`iamp.comparison.report.tables`, the document
:mod:`iamp.comparison.report.document`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .latex import ESCAPES, is_missing, mantissa_exponent

__all__ = [
    "SOLVER_NAMES",
    "intervals_tex",
    "poly_tex",
    "pretty_label",
    "short_label",
    "tex_escape",
    "tex_sci",
    "tex_time",
]

SOLVER_NAMES = {"clarabel": "Clarabel", "osqp": "OSQP"}

_UNICODE_TEX = {"≤": "$\\le$", "≥": "$\\ge$", "Φ": "$\\Phi$", "ν": "$\\nu$", "Δ": "$\\Delta$", "·": "$\\cdot$",
                "²": "$^2$", "³": "$^3$", "∞": "$\\infty$", "−": "-", "–": "--", "—": "---", "×": "$\\times$",
                "→": "$\\to$", "≈": "$\\approx$", "∂": "$\\partial$", "λ": "$\\lambda$", "Ω": "$\\Omega$",
                "µ": "\\textmu{}", "μ": "\\textmu{}", "‖": "$\\|$", "±": "$\\pm$", "’": "'", "“": "``", "”": "''"}


#: :data:`iamp.comparison.report.latex.ESCAPES`, and ``< > |`` as text commands.
_TEX_ESCAPES = {**ESCAPES, "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}"}


def tex_escape(text: str) -> str:
    """Escape LaTeX special characters in plain text (common non-ASCII symbols become math;
    any other non-ASCII character becomes ``?`` so that pdflatex never stops on it)."""
    out = []
    for c in str(text):
        if c in _TEX_ESCAPES:
            out.append(_TEX_ESCAPES[c])
        elif ord(c) < 128:
            out.append(c)
        else:
            out.append(_UNICODE_TEX.get(c, "?"))
    return "".join(out).replace("--", "-{}-")  # no en/em dashes from option names


def tex_sci(x: float | None, digits: int = 1, floor: float | None = None) -> str:
    """A number for a table cell: ``$1.2\\times10^{-9}$``, ``0.0312``, ``0`` or ``--``.

    With ``floor`` (a power of ten), a magnitude below it is shown as ``$<10^{k}$``: round-off
    (a gap of ``1e-15`` between two solvers' optima) changes with the machine, the bound does not.
    """
    if x is None or is_missing(x):
        return "--"
    x = float(x)
    if x == 0:
        return "0"
    if floor is not None and abs(x) < floor:
        return f"$<10^{{{round(math.log10(floor))}}}$"
    if 1e-2 <= abs(x) < 1e4:
        return f"{x:.{digits + 2}g}"
    m, e = mantissa_exponent(x, digits)
    return f"${m:.{digits}f}\\times10^{{{e}}}$"


def tex_time(s: float | None) -> str:
    """Seconds → a readable duration for a table."""
    if s is None or not math.isfinite(s):
        return "--"
    if s < 1e-3:
        return f"{s * 1e6:.0f}\\,\\textmu s" if s >= 1e-5 else f"{s * 1e6:.1f}\\,\\textmu s"
    if s < 1.0:
        return f"{s * 1e3:.2f}\\,ms" if s < 1e-2 else f"{s * 1e3:.1f}\\,ms"
    return f"{s:.2f}\\,s"


def short_label(label: str) -> str:
    """A run label without its ``qp-`` prefix (``PMP`` for the PMP)."""
    return "PMP" if label == "pmp" else (label[3:] if label.startswith("qp-") else label)


def pretty_label(label: str) -> str:
    """A run label for a table: ``PMP (jump conditions)``, ``QP Clarabel FOH $N=100$, ...``."""
    if label == "pmp":
        return "PMP (jump conditions)"
    parts = label.split("-")
    if parts[0] != "qp" or len(parts) < 4:
        return tex_escape(label)
    s = f"QP {SOLVER_NAMES.get(parts[1], parts[1])} {parts[2].upper()} $N={parts[3]}$"
    extra = [p for p in parts[4:]]
    return s + "".join(f", {tex_escape(p)}" for p in extra)


def poly_tex(c: Sequence[float]) -> str:
    r"""The polynomial :math:`\sum_k c_k t^k` in math mode (zero terms above the constant left out)."""
    terms: list[str] = []
    for k, a in enumerate(c):
        if a == 0 and k > 0:
            continue
        mag = f"{abs(a):.4g}"
        var = "" if k == 0 else ("t" if k == 1 else f"t^{k}")
        body = f"{mag}\\,{var}" if var else mag
        if not terms:
            terms.append(("-" if a < 0 else "") + body)
        else:
            terms.append(("- " if a < 0 else "+ ") + body)
    return "$" + " ".join(terms) + "$"


def intervals_tex(iv: Sequence[Sequence[float]]) -> str:
    """Time intervals ``a--b`` (two decimals), or ``none``."""
    if not iv:
        return "none"
    return ", ".join(f"{a:.2f}--{b:.2f}" for a, b in iv)
