r"""Figures of the reproduction report: the one palette, the styles and the writing.

Every figure of the report (:mod:`iamp.comparison.figures.trajectory`: the paper's Figs. 4–9;
:mod:`iamp.comparison.figures.comparison`: ``J(t)``, co-states against QP multipliers;
:mod:`iamp.comparison.figures.studies`: ZOH convergence, solve times, predictions;
:mod:`iamp.comparison.figures.safety`) and of ``iamp plot`` draws on a fresh
:class:`matplotlib.figure.Figure` (no ``pyplot``, no global state, no display: the Agg canvas
is used for PNG and the PDF backend for PDF) and writes ``<stem>.png`` and ``<stem>.pdf``
atomically (:func:`save_figure`: saved to a temporary name in the same folder, then
:func:`os.replace`).  Each returns the list of the two paths written.

Conventions every figure follows (a reviewer's checklist): every axis is labelled with its
unit (the cost ``J`` in m²/s³, co-states ``p1, p3`` and jumps in m/s³, ``p2, p4`` in m/s²);
x–y plots are drawn **to scale** (equal aspect,
:func:`~iamp.comparison.figures.trajectory.draw_xy`), so a lane change is not exaggerated into
a cliff; one colour per planner everywhere (:data:`PALETTE`, :func:`planner_style`: PMP green,
Clarabel blue, OSQP orange; red marks safety regions, contacts and jumps only); legends sit
where they hide no data (:func:`legend_below`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from numpy.typing import ArrayLike

from iamp.core.atomic import atomic_path

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from iamp.core.plan import Plan


PathLike = str | os.PathLike[str]

__all__ = [
    "DPI",
    "EGO_COLOR",
    "FORMATS",
    "PALETTE",
    "SAFETY_COLOR",
    "SCENARIO_COLORS",
    "SOLVER_MARKERS",
    "VEHICLE_COLORS",
    "PathLike",
    "is_avoidance",
    "legend_below",
    "planner_style",
    "save_figure",
    "save_one",
    "scenario_color",
    "stable_metadata",
    "tidy_axis",
]

FORMATS = ("png", "pdf")
DPI = 150

# --- one palette for every figure ------------------------------------------------------
#: Colour of each planner family, the same in every figure of the report and of ``iamp plot``
#: (a label is matched by :func:`planner_style`). Red is reserved for safety regions, contact
#: points and jumps; grey shades and olive/pink for the surrounding vehicles.
PALETTE: dict[str, str] = {
    "pmp": "tab:green",
    "clarabel": "tab:blue",
    "osqp": "tab:orange",
    "piqp": "tab:purple",
    "kkt": "tab:brown",
    "safety": "tab:red",
    "other": "tab:gray",
}
#: Marker of each QP solver (ZOH runs use the second marker of the pair).
SOLVER_MARKERS: dict[str, tuple[str, str]] = {"clarabel": ("o", "s"), "osqp": ("x", "+"), "piqp": ("^", "v"),
                                              "kkt": ("D", "d")}
EGO_COLOR = PALETTE["pmp"]  # the ego drawn from a PMP plan
SAFETY_COLOR = PALETTE["safety"]
VEHICLE_COLORS = ("0.45", "tab:olive", "tab:pink", "0.7")
#: Colour of each scenario where scenarios (not planners) are compared.
SCENARIO_COLORS: dict[str, str] = {"paper-1": "0.15", "paper-2": "tab:pink", "paper-3": "tab:olive",
                                   "two-vehicle": "tab:cyan"}
_SCENARIO_CYCLE = ("0.15", "tab:pink", "tab:olive", "tab:cyan", "0.55")


def planner_style(label: str) -> dict[str, str]:
    """Colour, marker, fill and line style of a run label (``pmp``, ``qp-osqp-zoh-100``,
    ``QP clarabel solve, native, ...``): the colour follows the planner or QP solver
    (:data:`PALETTE`), the marker the solver and hold, a filled marker the native path, a
    dashed line the avoidance QP."""
    low = label.lower()
    if "pmp" in low:
        return {"color": PALETTE["pmp"], "marker": "*", "mfc": PALETTE["pmp"], "ls": "-"}
    for key in ("clarabel", "osqp", "piqp", "kkt"):
        if key in low:
            color = PALETTE[key]
            marker = SOLVER_MARKERS[key][1 if "zoh" in low else 0]
            filled = "native" in low and marker not in "x+"
            if "refine" in low:
                marker = "D"
            return {"color": color, "marker": marker, "mfc": color if filled else "none",
                    "ls": "--" if "avoid" in low else "-"}
    return {"color": PALETTE["other"], "marker": "^", "mfc": "none", "ls": ":"}


def is_avoidance(result: Plan) -> bool:
    """Whether ``result`` comes from the avoidance QP (SPEC §10), whose times are crossings."""
    return "avoid" in str(result.diagnostics.constraint or "")


def tidy_axis(ax: Axes, values: ArrayLike, *, min_span: float = 0.1) -> None:
    """No offset notation, and a y-range of at least ``min_span`` (relative to the values' size)
    around values that are constant up to rounding, so that 1e-13 noise is not drawn as a signal."""
    ax.ticklabel_format(axis="y", useOffset=False)
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    lo, hi = float(np.min(v)), float(np.max(v))
    span = max(min_span * max(abs(lo), abs(hi)), min_span)
    if hi - lo < 1e-6 * span:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - span, mid + span)


def scenario_color(name: str, k: int = 0) -> str:
    """The colour of a scenario (:data:`SCENARIO_COLORS`, else a fixed cycle by position)."""
    return SCENARIO_COLORS.get(name, _SCENARIO_CYCLE[k % len(_SCENARIO_CYCLE)])


def stable_metadata(fmt: str) -> dict[str, str | None] | None:
    """``savefig``'s metadata for a file that is the same bytes on every run and with every
    matplotlib version: no creation date, no software version (PNG, PDF, SVG); ``None`` for
    other formats (matplotlib's defaults)."""
    if fmt == "pdf":
        return {"CreationDate": None, "Creator": "iamp", "Producer": None}
    if fmt == "png":
        return {"Software": None}
    if fmt == "svg":
        return {"Date": None, "Creator": "iamp"}
    return None


def _savefig(fig: Figure, path: str, fmt: str) -> None:
    """``fig.savefig`` with :func:`stable_metadata` (and, for SVG, a fixed hash salt for its ids)."""
    from matplotlib import rc_context

    with rc_context({"svg.hashsalt": "iamp"}):
        fig.savefig(path, format=fmt, dpi=DPI, bbox_inches="tight", metadata=stable_metadata(fmt))


def save_figure(fig: Figure, stem: PathLike, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Write ``fig`` as ``stem.<fmt>`` for every format, atomically; return the paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for fmt in formats:
        path = stem.with_name(f"{stem.name}.{fmt}")
        with atomic_path(path) as tmp:
            _savefig(fig, tmp, fmt)
        written.append(path)
    return written


def save_one(fig: Figure, path: PathLike) -> Path:
    """Write ``fig`` to ``path`` atomically, in the format its suffix names (``.png``, ``.pdf``,
    ``.svg``, …); returns the path."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    with atomic_path(path) as tmp:
        _savefig(fig, tmp, fmt)
    return path


def legend_below(ax: Axes, *, ncol: int = 3, fontsize: float = 7, below_points: float = 36.0) -> Legend:
    """A legend under ``ax``, ``below_points`` below its lower edge (clear of the tick labels and
    the x label however short the axes are: equal-aspect road strips are)."""
    return ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=ncol, fontsize=fontsize, frameon=False,
                     borderaxespad=below_points / fontsize)
