"""highD recordings (``XX_tracks.csv`` with ``XX_tracksMeta.csv`` and ``XX_recordingMeta.csv``)."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from iamp.prediction.tracks.table import TrackDataError, Tracks

from . import plausibility
from .csv import _integers, _path, _segments, duplicate_rows, read_csv
from .report import LoadReport

__all__ = ["HIGHD_DEFAULT_FRAME_RATE", "load_highd"]

HIGHD_DEFAULT_FRAME_RATE = 25.0


_HIGHD_TRACKS = (
    ("frame", ("frame",), True),
    ("id", ("id",), True),
    ("x", ("x",), True),
    ("width", ("width",), True),
    ("xVelocity", ("xVelocity",), True),
    ("xAcceleration", ("xAcceleration",), True),
    ("laneId", ("laneId",), True),
    ("y", ("y",), False),
    ("height", ("height",), False),
)
_HIGHD_TRACKS_META = (
    ("id", ("id",), True),
    ("drivingDirection", ("drivingDirection",), True),
    ("class", ("class",), False),
)
_HIGHD_RECORDING_META = (
    ("id", ("id",), False),
    ("frameRate", ("frameRate",), True),
    ("locationId", ("locationId",), False),
    ("speedLimit", ("speedLimit",), False),
)


def _highd_sibling(tracks_csv: Path, suffix: str) -> Path | None:
    m = re.match(r"^(.*)tracks\.csv(\.gz)?$", tracks_csv.name)
    if not m:
        return None
    cand = tracks_csv.with_name(f"{m.group(1)}{suffix}.csv{m.group(2) or ''}")
    return cand if cand.is_file() else None


def load_highd(tracks_csv: str | os.PathLike[str], tracks_meta_csv: str | os.PathLike[str] | None = None,
               recording_meta_csv: str | os.PathLike[str] | None = None) -> Tracks:
    """Load one highD recording.

    Parameters
    ----------
    tracks_csv : path
        ``XX_tracks.csv`` (one row per vehicle and frame).
    tracks_meta_csv : path, optional
        ``XX_tracksMeta.csv``, for each vehicle's ``drivingDirection``.  When not given, the
        file of that name beside ``tracks_csv`` is used if it exists; otherwise the direction
        is inferred from the sign of the vehicle's mean ``xVelocity`` (noted in the meta).
    recording_meta_csv : path, optional
        ``XX_recordingMeta.csv``, for the ``frameRate``; found beside ``tracks_csv`` likewise.
        Without it the frame rate defaults to 25 Hz (noted in the meta).

    Conversions: highD's ``x`` is the upper-left corner of the bounding box, so the centre
    is ``x + width/2``.  Vehicles of driving direction 1 (upper lanes, moving towards −x)
    are mirrored: position ``−(x + width/2)``, speed ``−xVelocity``, acceleration
    ``−xAcceleration``, so that positions increase in the driving direction for every
    track.  Time is ``frame / frameRate``.  highD vehicle ids are kept as track ids (they are
    unique within a recording) unless a vehicle's frames have gaps, in which case tracks are
    split and renumbered (the original ids are then listed in ``meta["source_ids"]``).
    """
    path = _path(tracks_csv)
    cols = read_csv(path, _HIGHD_TRACKS)
    meta: dict[str, Any] = {"format": "highd", "source": str(path), "reference_point": "centre (x + width/2)",
                  "units": "SI (as recorded)"}
    n = cols["frame"].size
    report = LoadReport(sources=[str(path)], rows_read=int(n))
    if n == 0:
        raise TrackDataError("no data rows", source=path)
    frame = _integers(cols["frame"], "frame", path)
    vid = _integers(cols["id"], "id", path)
    lane = _integers(cols["laneId"], "laneId", path)
    width = cols["width"]
    if np.any(width <= 0):
        k = int(np.flatnonzero(width <= 0)[0])
        raise TrackDataError(f"row {k + 1}: the bounding-box length must be positive, got {width[k]}",
                             column="width", source=path)

    # frame rate
    rec_path = _path(recording_meta_csv) if recording_meta_csv is not None else _highd_sibling(path, "recordingMeta")
    frame_rate = HIGHD_DEFAULT_FRAME_RATE
    if rec_path is not None:
        rec = read_csv(rec_path, _HIGHD_RECORDING_META)
        if rec["frameRate"].size != 1:
            raise TrackDataError(f"expected one recording row, found {rec['frameRate'].size}",
                                 column="frameRate", source=rec_path)
        frame_rate = float(rec["frameRate"][0])
        if frame_rate <= 0:
            raise TrackDataError(f"must be positive, got {frame_rate}", column="frameRate", source=rec_path)
        meta["recording_meta"] = str(rec_path)
        meta["frame_rate_source"] = "recordingMeta"
        for key in ("id", "locationId", "speedLimit"):
            if key in rec:
                val = float(rec[key][0])
                meta[{"id": "recording_id"}.get(key, key)] = int(val) if val == int(val) else val
    else:
        meta["frame_rate_source"] = f"default ({HIGHD_DEFAULT_FRAME_RATE:g} Hz, no recordingMeta)"
        report.note(f"no XX_recordingMeta.csv beside the tracks file: the frame rate {HIGHD_DEFAULT_FRAME_RATE:g} Hz "
                    "(highD's) was assumed")
    meta["frame_rate"] = frame_rate

    # driving direction per vehicle
    ids_unique = np.unique(vid)
    tm_path = _path(tracks_meta_csv) if tracks_meta_csv is not None else _highd_sibling(path, "tracksMeta")
    if tm_path is not None:
        tm = read_csv(tm_path, _HIGHD_TRACKS_META, text=("class",))
        tm_id = _integers(tm["id"], "id", tm_path)
        tm_dir = _integers(tm["drivingDirection"], "drivingDirection", tm_path)
        if np.any((tm_dir != 1) & (tm_dir != 2)):
            k = int(np.flatnonzero((tm_dir != 1) & (tm_dir != 2))[0])
            raise TrackDataError(f"row {k + 1}: must be 1 or 2, got {tm_dir[k]}", column="drivingDirection",
                                 source=tm_path)
        if tm_id.size == 0:
            raise TrackDataError("no data rows", column="id", source=tm_path)
        order = np.argsort(tm_id)
        tm_id, tm_dir = tm_id[order], tm_dir[order]
        pos = np.searchsorted(tm_id, vid)
        pos_c = np.clip(pos, 0, tm_id.size - 1)
        missing = tm_id[pos_c] != vid
        if np.any(missing):
            raise TrackDataError(f"vehicle {vid[np.flatnonzero(missing)[0]]} of the tracks file is not listed",
                                 column="id", source=tm_path)
        direction = tm_dir[pos_c]
        meta["tracks_meta"] = str(tm_path)
        if "class" in tm:
            listed = np.isin(tm["id"], vid)
            names, counts = np.unique(tm["class"][listed], return_counts=True)
            meta["classes"] = {str(k): int(c) for k, c in zip(names, counts)}
        meta["driving_direction_source"] = "tracksMeta"
    else:
        sums = np.zeros(ids_unique.size)
        np.add.at(sums, np.searchsorted(ids_unique, vid), cols["xVelocity"])
        direction = np.where(sums[np.searchsorted(ids_unique, vid)] < 0, 1, 2)
        meta["driving_direction_source"] = "inferred from the sign of xVelocity (no tracksMeta)"

    sign = np.where(direction == 1, -1.0, 1.0)
    x = sign * (cols["x"] + 0.5 * width) + 0.0  # + 0.0 turns -0.0 into 0.0
    v = sign * cols["xVelocity"] + 0.0
    a = sign * cols["xAcceleration"] + 0.0
    t = frame / frame_rate

    y = sign * (cols["y"] + 0.5 * cols["height"]) + 0.0 if "y" in cols and "height" in cols else None
    order = np.lexsort((np.arange(n), frame, vid))
    vid, frame, t, x, v, a, lane, direction = (c[order] for c in (vid, frame, t, x, v, a, lane, direction))
    if y is not None:
        y = y[order]
    keep = duplicate_rows((np.diff(vid) == 0) & (np.diff(frame) == 0), [x, v, a, lane], report)
    vid, frame, t, x, v, a, lane, direction = (c[keep] for c in (vid, frame, t, x, v, a, lane, direction))
    if y is not None:
        y = y[keep]
    report.rows_kept = int(vid.size)
    seg = _segments(np.diff(vid) != 0, frame)
    starts = np.concatenate(([0], np.flatnonzero(np.diff(seg)) + 1))
    if starts.size == np.unique(vid).size:
        track_id = vid
    else:
        track_id = seg
        meta["source_ids"] = [int(s) for s in vid[starts]]
        meta["split_at_frame_gaps"] = True
    dir_per_track = direction[starts]
    meta["n_tracks_direction_1_mirrored"] = int(np.sum(dir_per_track == 1))
    meta["n_tracks_direction_2"] = int(np.sum(dir_per_track == 2))
    meta["mirrored"] = "driving direction 1: x -> -(x + width/2), xVelocity and xAcceleration negated"
    if starts.size > np.unique(vid).size:
        report.note(f"{starts.size - np.unique(vid).size} track split(s) at frame gaps (no row dropped)")
    meta["lateral"] = "y + height/2 (centre), mirrored like x" if y is not None else "no y/height columns"
    meta["load_report"] = report.to_dict()
    report.check()
    tracks = Tracks(track_id, t, x, v, a, lane, 1.0 / frame_rate, meta, y)
    return plausibility.apply(tracks, path, "metres (highD)", report)
