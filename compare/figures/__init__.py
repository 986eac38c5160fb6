"""Figures of the reproduction report: the palette and styles, trajectory, comparison, safety and
study figures.
"""

from __future__ import annotations

from .style import (
    DPI,
    EGO_COLOR,
    FORMATS,
    PALETTE,
    SAFETY_COLOR,
    SCENARIO_COLORS,
    SOLVER_MARKERS,
    VEHICLE_COLORS,
    PathLike,
    is_avoidance,
    legend_below,
    planner_style,
    save_figure,
    save_one,
    scenario_color,
    tidy_axis,
)

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
    "tidy_axis",
]
