"""Loaders of recorded vehicle trajectories (CSV, highD, NGSIM, SUMO FCD) into the common
:class:`~iamp.prediction.tracks.Tracks` table, each with its :class:`LoadReport`.
"""

from __future__ import annotations

from .formats import (
    FEET,
    FORMATS,
    HIGHD_DEFAULT_FRAME_RATE,
    NGSIM_FRAME_PERIOD,
    NGSIM_TXT_COLUMNS,
    SUMO_DEFAULT_LENGTH,
    LoadReport,
    TrackDataError,
    load,
    load_highd,
    load_ngsim,
    load_sumo_fcd,
    load_with_report,
)

__all__ = [
    "FEET",
    "FORMATS",
    "HIGHD_DEFAULT_FRAME_RATE",
    "NGSIM_FRAME_PERIOD",
    "NGSIM_TXT_COLUMNS",
    "SUMO_DEFAULT_LENGTH",
    "LoadReport",
    "TrackDataError",
    "load",
    "load_highd",
    "load_ngsim",
    "load_sumo_fcd",
    "load_with_report",
]
