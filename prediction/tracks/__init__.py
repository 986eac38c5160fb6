"""The common table of recorded vehicle trajectories (:class:`Tracks`) and its files."""

from __future__ import annotations

from .io import load_tracks, save_tracks
from .table import SHIPPED_DATASET, TrackDataError, Tracks, load_shipped_dataset

__all__ = ["SHIPPED_DATASET", "TrackDataError", "Tracks", "load_shipped_dataset", "load_tracks", "save_tracks"]
