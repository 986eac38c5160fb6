r"""Booktabs tables for the reports, written atomically.

* :func:`escape` — LaTeX-escape plain text (``\ & % $ # _ { } ~ ^``).
* :class:`Raw` — a cell that is already LaTeX (e.g. ``Raw(r"$1.2\times10^{-9}$")``), not
  escaped.
* :func:`sci` — a number as ``$m\times10^{e}$`` (a :class:`Raw` cell).
* :func:`is_missing`, :func:`mantissa_exponent` — the pieces of :func:`sci`, shared with
  :mod:`iamp.comparison.report.tex`; :data:`ESCAPES` — what :func:`escape` replaces.
* :func:`booktabs_table` — a ``table``/``tabular`` with ``\toprule``, ``\midrule``,
  ``\bottomrule`` (needs ``\usepackage{booktabs}``).
* :func:`write_atomic` — write text to a temporary file in the destination's folder, then
  :func:`os.replace` it over the destination, so a reader never sees a half-written file and
  an existing file is replaced only by a complete one.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TypedDict, Unpack

from iamp.core.atomic import write_text as write_atomic  # re-exported for callers

#: The characters :func:`escape` replaces, and their LaTeX.
ESCAPES = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
}


class Raw(str):
    """A table cell that is already valid LaTeX and must not be escaped."""


def escape(text: object) -> str:
    """Escape LaTeX's special characters in plain text (a :class:`Raw` passes unchanged)."""
    if isinstance(text, Raw):
        return str(text)
    return "".join(ESCAPES.get(ch, ch) for ch in str(text))


def is_missing(x: object) -> bool:
    """``None`` or a non-finite float: a table shows ``--`` for it."""
    return x is None or (isinstance(x, float) and not math.isfinite(x))


def mantissa_exponent(x: float, digits: int) -> tuple[float, int]:
    """``(m, e)`` with ``x = m·10^e`` and ``|m|``, rounded to ``digits`` decimals, in ``[1, 10)``
    (``x`` finite and non-zero)."""
    e = int(math.floor(math.log10(abs(x))))
    m = x / 10**e
    if round(abs(m), digits) >= 10:
        m, e = m / 10, e + 1
    return m, e


def sci(x: float | None, digits: int = 2) -> Raw:
    r"""``x`` as ``$m\times10^{e}$`` with ``digits`` decimals (``--`` for ``None``/NaN)."""
    if x is None or is_missing(x):
        return Raw("--")
    v = float(x)
    if v == 0:
        return Raw("$0$")
    m, e = mantissa_exponent(v, digits)
    if -2 <= e <= 3:
        return Raw(f"${v:.{max(0, digits - e)}f}$")
    return Raw(f"${m:.{digits}f}\\times10^{{{e}}}$")


def fixed(x: float | None, digits: int = 3) -> Raw:
    """``x`` with ``digits`` decimals in math mode (``--`` for ``None``/NaN)."""
    if x is None or is_missing(x):
        return Raw("--")
    return Raw(f"${float(x):.{digits}f}$")


def booktabs_table(header: Sequence[object], rows: Iterable[Sequence[object] | None], caption: str | None = None,
                   label: str | None = None,
                   align: str | None = None, notes: str | None = None, float_env: bool = True) -> str:
    """A booktabs table as LaTeX source.

    Parameters
    ----------
    header : list
        Column headings (escaped unless :class:`Raw`).
    rows : list of list
        Cells (escaped unless :class:`Raw`); a row equal to ``None`` inserts ``\\midrule``.
    caption, label : str, optional
        ``label`` is used verbatim; ``caption`` is escaped unless :class:`Raw`.
    align : str, optional
        Column specification (default: ``l`` then ``r`` for every other column).
    notes : str, optional
        A footnote line below the table (escaped unless :class:`Raw`).
    """
    ncol = len(header)
    align = align or ("l" + "r" * (ncol - 1))
    lines = []
    if float_env:
        lines += [r"\begin{table}[htbp]", r"\centering"]
        if caption:
            lines.append(rf"\caption{{{escape(caption)}}}")
        if label:
            lines.append(rf"\label{{{label}}}")
    lines += [rf"\begin{{tabular}}{{{align}}}", r"\toprule", " & ".join(escape(h) for h in header) + r" \\",
              r"\midrule"]
    for row in rows:
        if row is None:
            lines.append(r"\midrule")
            continue
        if len(row) != ncol:
            raise ValueError(f"row has {len(row)} cells, header has {ncol}")
        lines.append(" & ".join(escape(c) for c in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    if notes:
        lines.append(rf"\par\smallskip{{\footnotesize {escape(notes)}}}")
    if float_env:
        lines.append(r"\end{table}")
    return "\n".join(lines) + "\n"


class TableOptions(TypedDict, total=False):
    """:func:`booktabs_table`'s keyword options."""

    caption: str | None
    label: str | None
    align: str | None
    notes: str | None
    float_env: bool


def write_table(path: str | Path, header: Sequence[object], rows: Iterable[Sequence[object] | None],
                **kwargs: Unpack[TableOptions]) -> Path:
    """:func:`booktabs_table` written with :func:`write_atomic`."""
    return write_atomic(path, booktabs_table(header, rows, **kwargs))
