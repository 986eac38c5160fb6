"""Loaders of recorded vehicle trajectories into the common :class:`~iamp.prediction.tracks.Tracks` table.

Supported sources
-----------------
``highd``
    The highD dataset (``XX_tracks.csv`` with, optionally, ``XX_tracksMeta.csv`` and
    ``XX_recordingMeta.csv``; found beside the tracks file when not given).
``ngsim``
    The NGSIM US-101 / I-80 trajectory CSV (the combined "Vehicle Trajectories" table).
``sumo``
    Eclipse SUMO floating-car-data output (``--fcd-output``), XML (optionally gzipped) or
    the ``;``-separated CSV written by SUMO itself or by ``xml2csv.py``.

Every loader returns positions of the vehicle *centre*, increasing in the driving direction,
in metres, speeds in m/s and accelerations in m/s², and records what it converted in
``Tracks.meta``.  Problems with a file raise :class:`~iamp.prediction.tracks.TrackDataError`
naming the file and the column.
"""

from __future__ import annotations

import csv
import gzip
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from array import array
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from .tracks import Tracks, TrackDataError

__all__ = ["load_highd", "load_ngsim", "load_sumo_fcd", "load", "FORMATS", "FEET", "TrackDataError"]

#: One foot in metres (NGSIM units).
FEET = 0.3048

#: Formats understood by :func:`load` (the CLI's ``--format``).
FORMATS = ("highd", "ngsim", "sumo")

HIGHD_DEFAULT_FRAME_RATE = 25.0
NGSIM_FRAME_PERIOD = 0.1
SUMO_DEFAULT_LENGTH = 5.0

_CHUNK_ROWS = 200_000  # CSV rows converted to arrays at a time


# ------------------------------------------------------------------------------------------
# CSV reading
# ------------------------------------------------------------------------------------------

def _open_text(path: Path):
    if path.suffix == ".gz":
        return gzip.open(path, "rt", newline="", encoding="utf-8-sig")
    return open(path, "r", newline="", encoding="utf-8-sig")


def _norm(name: str) -> str:
    return name.strip().strip('"').strip().lower()


def _read_header(path: Path, delimiter: str | None) -> tuple[list[str], str]:
    try:
        with _open_text(path) as fh:
            first = fh.readline()
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    if not first.strip():
        raise TrackDataError("the file is empty (no header line)", source=path)
    if delimiter is None:
        delimiter = ";" if first.count(";") > first.count(",") else ","
    header = next(csv.reader([first], delimiter=delimiter))
    return header, delimiter


def _resolve(header: list[str], spec: Sequence[tuple[str, tuple[str, ...], bool]], path: Path) -> dict[str, int]:
    """Map logical column names to header indices; a missing required column is an error."""
    index = {}
    for i, name in enumerate(header):
        index.setdefault(_norm(name), i)
    found = {}
    for logical, candidates, required in spec:
        for cand in candidates:
            if cand.lower() in index:
                found[logical] = index[cand.lower()]
                break
        else:
            if required:
                shown = ", ".join(h.strip() for h in header[:6]) + (", ..." if len(header) > 6 else "")
                raise TrackDataError(f"missing (the header has: {shown})", column=candidates[0], source=path)
    return found


def _to_float(strings: Sequence[str], column: str, path: Path, lines=None) -> np.ndarray:
    try:
        out = np.asarray(strings, dtype=str).astype(np.float64)
    except ValueError:
        out = None
    if out is None:
        vals = []
        for k, s in enumerate(strings):
            try:
                vals.append(float(s))
            except ValueError:
                try:  # thousands separators, as in some NGSIM exports
                    vals.append(float(s.replace(",", "")))
                except ValueError:
                    line = lines[k] if lines is not None else k + 2
                    raise TrackDataError(f"line {line}: cannot read {s!r} as a number",
                                         column=column, source=path) from None
        out = np.asarray(vals, dtype=np.float64)
    bad = ~np.isfinite(out)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        line = lines[k] if lines is not None else k + 2
        raise TrackDataError(f"line {line}: value {strings[k]!r} is not finite", column=column, source=path)
    return out


def _read_csv(path: Path, spec: Sequence[tuple[str, tuple[str, ...], bool]], *, text: Iterable[str] = (),
              delimiter: str | None = None, skip_empty: str | None = None, row_hash: bool = False) -> dict:
    """Read the columns of ``spec`` (logical name, accepted header names, required).

    Numeric columns come back as float64 arrays, the ``text`` ones as str arrays; with
    ``row_hash`` the key ``"__hash__"`` holds a hash of each full row (for exact-duplicate
    detection) and ``"__line__"`` the line numbers.  Rows where the ``skip_empty`` column is
    blank are dropped (SUMO CSV has such rows for empty time steps).
    """
    header, delimiter = _read_header(path, delimiter)
    where = _resolve(header, spec, path)
    text = set(text)
    numeric_only = not (text & set(where)) and skip_empty is None and not row_hash

    if numeric_only:  # fast path for big purely numeric files (highD)
        names = list(where)
        try:
            with _open_text(path) as fh, warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "input contained no data": reported below
                data = np.loadtxt(fh, delimiter=delimiter, skiprows=1, usecols=[where[n] for n in names],
                                  dtype=np.float64, ndmin=2)
        except ValueError:
            data = None  # fall through to the slow path, which names the bad column and line
        if data is not None:
            cols = {n: data[:, k] for k, n in enumerate(names)}
            for n in names:
                if not np.all(np.isfinite(cols[n])):
                    k = int(np.flatnonzero(~np.isfinite(cols[n]))[0])
                    raise TrackDataError(f"line {k + 2}: value is not finite", column=header[where[n]].strip(),
                                         source=path)
            return cols

    names = list(where)
    idx = [where[n] for n in names]
    width = max(idx) + 1
    store: list[list[str]] = [[] for _ in names]
    lines = array("q")
    hashes = array("q")
    skip_k = names.index(skip_empty) if skip_empty in where else None
    parts: dict[str, list[np.ndarray]] = {n: [] for n in names}

    def flush():  # convert the strings read so far (bounded memory for big files)
        line_arr = np.frombuffer(lines, dtype=np.int64)[len(lines) - len(store[0]):]
        for n, lst in zip(names, store):
            if not lst:
                continue
            if n in text:
                parts[n].append(np.asarray([s.strip() for s in lst], dtype=str))
            else:
                parts[n].append(_to_float(lst, header[where[n]].strip(), path, line_arr))
            lst.clear()

    try:
        with _open_text(path) as fh:
            reader = csv.reader(fh, delimiter=delimiter)
            next(reader)
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue
                if len(row) < width:
                    short = next(n for n, i in zip(names, idx) if i >= len(row))
                    raise TrackDataError(f"line {reader.line_num}: row has only {len(row)} fields",
                                         column=header[where[short]].strip(), source=path)
                if skip_k is not None and not row[idx[skip_k]].strip():
                    continue
                for lst, i in zip(store, idx):
                    lst.append(row[i])
                lines.append(reader.line_num)
                if row_hash:
                    hashes.append(hash(tuple(row)))
                if len(store[0]) >= _CHUNK_ROWS:
                    flush()
            flush()
    except csv.Error as exc:
        raise TrackDataError(f"malformed CSV ({exc})", source=path) from None
    except UnicodeDecodeError as exc:
        raise TrackDataError(f"not a UTF-8 text file ({exc})", source=path) from None
    line_arr = np.frombuffer(lines, dtype=np.int64) if len(lines) else np.empty(0, np.int64)
    cols = {}
    for n in names:
        if parts[n]:
            cols[n] = np.concatenate(parts[n])
        else:
            cols[n] = np.empty(0, dtype=str) if n in text else np.empty(0)
    if row_hash:
        cols["__hash__"] = np.frombuffer(hashes, dtype=np.int64) if len(hashes) else np.empty(0, np.int64)
    cols["__line__"] = line_arr
    return cols


def _integers(col: np.ndarray, column: str, path: Path) -> np.ndarray:
    r = np.round(col)
    if np.any(np.abs(r - col) > 1e-9):
        k = int(np.flatnonzero(np.abs(r - col) > 1e-9)[0])
        raise TrackDataError(f"row {k + 1}: {col[k]!r} is not an integer", column=column, source=path)
    return r.astype(np.int64)


def _segments(key_change: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Segment number per row (rows sorted by key then frame): new segment where the key
    changes or the frame does not advance by exactly one."""
    n = frame.size
    if n == 0:
        return np.empty(0, dtype=np.int64)
    new = np.ones(n, dtype=bool)
    new[1:] = key_change | (np.diff(frame) != 1)
    return np.cumsum(new) - 1


def _path(p) -> Path:
    return Path(os.fspath(p))


# ------------------------------------------------------------------------------------------
# highD
# ------------------------------------------------------------------------------------------

_HIGHD_TRACKS = (
    ("frame", ("frame",), True),
    ("id", ("id",), True),
    ("x", ("x",), True),
    ("width", ("width",), True),
    ("xVelocity", ("xVelocity",), True),
    ("xAcceleration", ("xAcceleration",), True),
    ("laneId", ("laneId",), True),
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


def load_highd(tracks_csv, tracks_meta_csv=None, recording_meta_csv=None) -> Tracks:
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
    cols = _read_csv(path, _HIGHD_TRACKS)
    meta: dict = {"format": "highd", "source": str(path), "reference_point": "centre (x + width/2)",
                  "units": "SI (as recorded)"}
    n = cols["frame"].size
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
        rec = _read_csv(rec_path, _HIGHD_RECORDING_META)
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
    meta["frame_rate"] = frame_rate

    # driving direction per vehicle
    ids_unique = np.unique(vid)
    tm_path = _path(tracks_meta_csv) if tracks_meta_csv is not None else _highd_sibling(path, "tracksMeta")
    if tm_path is not None:
        tm = _read_csv(tm_path, _HIGHD_TRACKS_META, text=("class",))
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

    order = np.lexsort((frame, vid))
    vid, frame, t, x, v, a, lane, direction = (c[order] for c in (vid, frame, t, x, v, a, lane, direction))
    dup = (np.diff(vid) == 0) & (np.diff(frame) == 0)
    if np.any(dup):
        k = int(np.flatnonzero(dup)[0])
        raise TrackDataError(f"vehicle {vid[k]} has two rows for frame {frame[k]}", column="frame", source=path)
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
    return Tracks(track_id, t, x, v, a, lane, 1.0 / frame_rate, meta)


# ------------------------------------------------------------------------------------------
# NGSIM
# ------------------------------------------------------------------------------------------

_NGSIM = (
    ("Vehicle_ID", ("Vehicle_ID",), True),
    ("Frame_ID", ("Frame_ID",), True),
    ("Local_Y", ("Local_Y",), True),
    ("v_Vel", ("v_Vel",), True),
    ("v_Acc", ("v_Acc",), True),
    ("Lane_ID", ("Lane_ID",), True),
    ("v_length", ("v_length", "v_Length"), False),
    ("Global_Time", ("Global_Time",), False),
    ("Location", ("Location",), False),
)


def load_ngsim(csv_path, location: str | None = None) -> Tracks:
    """Load the NGSIM US-101 / I-80 trajectory CSV.

    Parameters
    ----------
    csv_path : path
        The CSV with NGSIM's columns (``Vehicle_ID, Frame_ID, ..., Local_Y, ..., v_length, ...,
        v_Vel, v_Acc, Lane_ID, ..., Location``).
    location : str, optional
        Keep only the rows of this ``Location`` (case-insensitive, e.g. ``"us-101"``).  When
        the file has no ``Location`` column this just labels the data.

    Conversions: the longitudinal coordinate is ``Local_Y``, which NGSIM gives for the *front*
    of the vehicle, so the centre is ``Local_Y − v_length/2`` (when ``v_length`` is present,
    else ``Local_Y`` itself, noted in the meta).  Feet are converted to metres (positions,
    ft/s, ft/s²).  Time is ``Frame_ID × 0.1 s`` (10 Hz).

    Vehicle ids repeat across locations and periods, and the public file has duplicated rows:
    rows are keyed by ``(Location, Vehicle_ID)``, ordered by ``Global_Time`` (or ``Frame_ID``),
    exact duplicate rows are dropped, a second differing row for the same vehicle and time is
    dropped too (the first is kept; both counts are in the meta), a track is split wherever
    ``Frame_ID`` does not advance by one, and tracks are renumbered ``0..n−1``
    (``meta["source_ids"]`` lists ``[location, vehicle_id, first_frame]`` per track).
    """
    path = _path(csv_path)
    cols = _read_csv(path, _NGSIM, text=("Location",), row_hash=True)
    meta: dict = {"format": "ngsim", "source": str(path), "units_converted": "feet -> metres (x 0.3048)",
                  "frame_period": NGSIM_FRAME_PERIOD}
    n = cols["Frame_ID"].size
    if "Location" in cols:
        loc_str = np.char.lower(cols["Location"])
    else:
        loc_str = np.full(n, (location or "unknown").lower())
        meta["location_source"] = "argument" if location else "unknown (no Location column)"
    if location is not None and "Location" in cols:
        keep = loc_str == location.strip().lower()
        if not np.any(keep):
            present = ", ".join(sorted(set(loc_str.tolist()))[:6])
            raise TrackDataError(f"no rows for location {location!r} (present: {present})", column="Location",
                                 source=path)
        cols = {k: val[keep] for k, val in cols.items()}
        loc_str = loc_str[keep]
        meta["location_filter"] = location
    n = loc_str.size
    if n == 0:
        raise TrackDataError("no data rows", source=path)
    lines = cols["__line__"]
    vid = _integers(cols["Vehicle_ID"], "Vehicle_ID", path)
    frame = _integers(cols["Frame_ID"], "Frame_ID", path)
    lane = _integers(cols["Lane_ID"], "Lane_ID", path)
    locations, loc_code = np.unique(loc_str, return_inverse=True)
    timekey = cols["Global_Time"] if "Global_Time" in cols else frame.astype(np.float64)
    order = np.lexsort((lines, frame, timekey, vid, loc_code))
    loc_code, vid, frame, timekey, lane = (c[order] for c in (loc_code, vid, frame, timekey, lane))
    row_hash = cols["__hash__"][order]
    y_ft = cols["Local_Y"][order]
    vel = cols["v_Vel"][order]
    acc = cols["v_Acc"][order]
    length_ft = cols["v_length"][order] if "v_length" in cols else None

    same_key = (np.diff(loc_code) == 0) & (np.diff(vid) == 0) & (np.diff(timekey) == 0)
    drop = np.zeros(n, dtype=bool)
    drop[1:] = same_key
    exact = np.zeros(n, dtype=bool)
    # a row is an exact duplicate of the group's first row when the hashes match
    if np.any(same_key):
        grp_first = np.maximum.accumulate(np.where(np.concatenate(([True], ~same_key)), np.arange(n), 0))
        exact = drop & (row_hash == row_hash[grp_first])
    meta["duplicate_rows_dropped"] = int(np.sum(exact))
    meta["conflicting_rows_dropped"] = int(np.sum(drop & ~exact))
    keep = ~drop
    loc_code, vid, frame, lane, y_ft, vel, acc = (c[keep] for c in (loc_code, vid, frame, lane, y_ft, vel, acc))
    if length_ft is not None:
        length_ft = length_ft[keep]

    key_change = (np.diff(loc_code) != 0) | (np.diff(vid) != 0)
    seg = _segments(key_change, frame)
    starts = np.concatenate(([0], np.flatnonzero(np.diff(seg)) + 1))
    if length_ft is not None:
        y_ft = y_ft - 0.5 * length_ft
        meta["reference_point"] = "centre (Local_Y - v_length/2; Local_Y is the front of the vehicle)"
    else:
        meta["reference_point"] = "front (Local_Y; no v_length column to correct it)"
    meta["locations"] = [str(s) for s in locations]
    meta["source_ids"] = [[str(locations[loc_code[s]]), int(vid[s]), int(frame[s])] for s in starts]
    meta["split_at_frame_gaps"] = int(starts.size - np.unique(np.stack([loc_code, vid]), axis=1).shape[1])
    return Tracks(seg, frame * NGSIM_FRAME_PERIOD, y_ft * FEET, vel * FEET, acc * FEET, lane,
                  NGSIM_FRAME_PERIOD, meta)


# ------------------------------------------------------------------------------------------
# SUMO floating car data
# ------------------------------------------------------------------------------------------

# logical attribute -> accepted CSV headers (SUMO/xml2csv prefix them with the element name)
_SUMO_ATTRS = ("time", "id", "x", "angle", "type", "speed", "pos", "lane", "acceleration", "length")
_SUMO_TEXT = ("id", "type", "lane")


def _sumo_csv_spec(coordinate: str):
    req = {"time", "id", "speed", "lane", coordinate}
    spec = []
    for attr in _SUMO_ATTRS:
        prefix = "timestep" if attr == "time" else "vehicle"
        spec.append((attr, (f"{prefix}_{attr}", attr), attr in req))
    return spec


def _is_xml(path: Path) -> bool:
    name = path.name.lower()
    if name.endswith((".xml", ".xml.gz")):
        return True
    if name.endswith((".csv", ".csv.gz")):
        return False
    try:
        with _open_text(path) as fh:
            head = fh.read(256)
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    return head.lstrip().startswith("<")


def _read_fcd_xml(path: Path, coordinate: str) -> tuple[dict, dict]:
    """Columns of an FCD XML file (iterparse; memory stays flat) and the vType lengths in it."""
    required = ("id", "speed", "lane", coordinate)
    floats = {k: array("d") for k in ("time", "x", "angle", "speed", "pos", "acceleration", "length")}
    texts: dict[str, list] = {"id": [], "type": [], "lane": []}
    seen = {k: 0 for k in ("x", "angle", "pos", "acceleration", "length", "type")}
    vtype_len: dict[str, float] = {}
    time = None
    n = 0
    root = None
    try:
        fh = gzip.open(path, "rb") if path.suffix == ".gz" else open(path, "rb")
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    try:
        with fh:
            for event, elem in ET.iterparse(fh, events=("start", "end")):
                tag = elem.tag
                if event == "start":
                    if root is None:
                        root = elem
                    if tag == "timestep":
                        try:
                            time = float(elem.attrib["time"])
                        except KeyError:
                            raise TrackDataError("a <timestep> has no time", column="time", source=path) from None
                        except ValueError:
                            raise TrackDataError(f"cannot read time {elem.attrib['time']!r}", column="time",
                                                 source=path) from None
                    elif tag == "vType":
                        if "id" in elem.attrib and "length" in elem.attrib:
                            vtype_len[elem.attrib["id"]] = float(elem.attrib["length"])
                    elif tag == "vehicle":
                        at = elem.attrib
                        if time is None:
                            raise TrackDataError("a <vehicle> outside a <timestep>", column="time", source=path)
                        for key in required:
                            if key not in at:
                                raise TrackDataError(
                                    f"vehicle {at.get('id', '?')!r} at time {time:g} has no {key!r} attribute",
                                    column=key, source=path)
                        try:
                            floats["time"].append(time)
                            floats["speed"].append(float(at["speed"]))
                            for key in ("x", "angle", "pos", "acceleration", "length"):
                                if key in at:
                                    floats[key].append(float(at[key]))
                                    seen[key] += 1
                                else:
                                    floats[key].append(math.nan)
                        except ValueError as exc:
                            bad = next(k for k in ("speed", "x", "angle", "pos", "acceleration", "length")
                                       if k in at and not _floatable(at[k]))
                            raise TrackDataError(f"vehicle {at['id']!r} at time {time:g}: cannot read "
                                                 f"{at[bad]!r} as a number", column=bad, source=path) from exc
                        texts["id"].append(at["id"])
                        texts["lane"].append(at["lane"])
                        texts["type"].append(at.get("type", ""))
                        if "type" in at:
                            seen["type"] += 1
                        n += 1
                elif tag == "timestep":
                    elem.clear()
                    if root is not None:
                        root.clear()
    except ET.ParseError as exc:
        raise TrackDataError(f"not well-formed XML ({exc})", source=path) from None
    if root is None or root.tag != "fcd-export":
        raise TrackDataError(f"not an FCD file (root element {getattr(root, 'tag', None)!r}, "
                             f"expected 'fcd-export')", source=path)
    cols: dict = {"time": np.frombuffer(floats["time"], dtype=np.float64) if n else np.empty(0),
                  "speed": np.frombuffer(floats["speed"], dtype=np.float64) if n else np.empty(0),
                  "id": np.asarray(texts["id"], dtype=str), "lane": np.asarray(texts["lane"], dtype=str)}
    for key in ("x", "angle", "pos", "acceleration", "length"):
        if seen[key] == n and n:
            cols[key] = np.frombuffer(floats[key], dtype=np.float64)
        elif seen[key]:
            raise TrackDataError(f"present on only {seen[key]} of {n} vehicle records", column=key, source=path)
    if seen["type"]:
        cols["type"] = np.asarray(texts["type"], dtype=str)
    for key in ("time", "speed", "x", "angle", "pos", "acceleration", "length"):
        if key in cols and not np.all(np.isfinite(cols[key])):
            raise TrackDataError("contains a non-finite value", column=key, source=path)
    return cols, vtype_len


def _floatable(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _lane_index(lanes: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """SUMO lane id ``<edge>_<index>`` -> index; internal lanes (``:...``) -> marked for hold."""
    uniq, inv = np.unique(lanes, return_inverse=True)
    idx = np.empty(uniq.size, dtype=np.int64)
    internal = np.zeros(uniq.size, dtype=bool)
    for k, lane in enumerate(uniq):
        lane = str(lane)
        internal[k] = lane.startswith(":")
        head, _, tail = lane.rpartition("_")
        if not head or not tail.isdigit():
            raise TrackDataError(f"cannot read the lane index of {lane!r} (expected '<edge>_<index>')",
                                 column="lane", source=path)
        idx[k] = int(tail)
    return idx[inv], internal[inv]


def load_sumo_fcd(path, *, lengths: Mapping[str, float] | None = None,
                  default_length: float = SUMO_DEFAULT_LENGTH, coordinate: str = "x") -> Tracks:
    """Load SUMO floating-car-data output (``sumo --fcd-output``), XML or CSV.

    Parameters
    ----------
    path : path
        FCD XML (``.xml`` or ``.xml.gz``; parsed with ``iterparse``) or CSV (``;``-separated,
        columns ``timestep_time;vehicle_id;vehicle_x;...``, as SUMO writes for a ``.csv``
        output name or ``xml2csv.py`` produces; unprefixed names such as ``time;id;x`` work too).
    lengths : mapping, optional
        Vehicle lengths in m, keyed by vehicle id or by vType id (a vehicle id wins).
    default_length : float
        Length used when neither ``lengths``, a per-record ``length`` attribute, nor a
        ``<vType length=..>`` in the file gives one (SUMO's default passenger car is 5 m).
    coordinate : ``"x"`` or ``"pos"``
        ``"x"`` (default): the network x coordinate, for a straight road along the x axis.
        SUMO's ``x, y`` is the *front bumper*, so the centre is ``x − (L/2)·sin(angle)``
        (``angle`` in SUMO's navigation degrees, 90 = towards +x; without ``angle`` the
        vehicle is taken to head towards +x).  If most records head towards −x, positions
        are mirrored so they increase in the driving direction.  ``"pos"``: the distance
        along the lane, ``pos − L/2``; it restarts on every edge, so a track is split where
        ``pos`` decreases (use it only for a road that is one edge).

    Acceleration is SUMO's ``acceleration`` attribute when present (``--fcd-output.acceleration``),
    else the backward difference of speed, SUMO's own definition.  Lanes are SUMO lane indices
    (``<edge>_<index>``, 0 = rightmost); on internal junction lanes (``:...``) the previous lane
    is held.  A vehicle's record is split where time steps are missing (e.g. teleports).
    Tracks are numbered ``0..n−1`` in order of first appearance; ``meta["source_ids"]`` lists
    the SUMO vehicle id per track.
    """
    path = _path(path)
    if coordinate not in ("x", "pos"):
        raise TrackDataError(f"coordinate must be 'x' or 'pos', got {coordinate!r}")
    if not (default_length > 0 and math.isfinite(default_length)):
        raise TrackDataError(f"default_length must be positive, got {default_length}")
    if _is_xml(path):
        cols, vtype_len = _read_fcd_xml(path, coordinate)
        fmt = "xml"
    else:
        cols = _read_csv(path, _sumo_csv_spec(coordinate), text=_SUMO_TEXT, delimiter=None, skip_empty="id")
        cols.pop("__line__", None)
        vtype_len = {}
        fmt = "csv"
    n = cols["time"].size
    if n == 0:
        raise TrackDataError("no vehicle records", source=path)
    meta: dict = {"format": "sumo-fcd", "source": str(path), "file_type": fmt, "coordinate": coordinate,
                  "units": "SI (as recorded)"}

    # vehicles in order of first appearance
    names, first, code = np.unique(cols["id"], return_index=True, return_inverse=True)
    rank = np.empty(names.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(names.size)
    code = rank[code]
    order = np.lexsort((cols["time"], code))
    cols = {k: val[order] for k, val in cols.items()}
    code = code[order]
    time = cols["time"]
    dup = (np.diff(code) == 0) & (np.diff(time) == 0)
    if np.any(dup):
        k = int(np.flatnonzero(dup)[0])
        raise TrackDataError(f"vehicle {cols['id'][k]!r} appears twice at time {time[k]:g}", column="time",
                             source=path)
    steps = np.diff(np.unique(time))
    dt = float(np.median(steps)) if steps.size else 1.0
    dt = float(np.round(dt, 9))
    meta["step_length"] = dt

    # vehicle lengths: lengths[id] > lengths[type] > per-record length > vType in file > default
    vtypes = cols["type"] if "type" in cols else np.full(n, "", dtype=str)
    length = np.full(n, float(default_length))
    source_len = np.full(n, "default", dtype=object)
    if vtype_len:
        for vt, L in vtype_len.items():
            m = vtypes == vt
            length[m], source_len[m] = L, "vType in file"
    if "length" in cols:
        length, source_len = cols["length"].copy(), np.full(n, "record", dtype=object)
    if lengths:
        for key, L in lengths.items():
            L = float(L)
            if not (L > 0 and math.isfinite(L)):
                raise TrackDataError(f"length of {key!r} must be positive, got {L}", column="length")
        by_type = np.array([lengths.get(str(s), np.nan) for s in vtypes], dtype=float) if "type" in cols else None
        if by_type is not None:
            m = np.isfinite(by_type)
            length[m], source_len[m] = by_type[m], "lengths[type]"
        by_id = np.array([lengths.get(str(s), np.nan) for s in names], dtype=float)[code]
        m = np.isfinite(by_id)
        length[m], source_len[m] = by_id[m], "lengths[id]"
    meta["length_source_counts"] = {str(k): int(v) for k, v in zip(*np.unique(source_len.astype(str),
                                                                                return_counts=True))}
    meta["default_length"] = float(default_length)

    if coordinate == "x":
        heading = np.sin(np.radians(cols["angle"])) if "angle" in cols else np.ones(n)
        pos = cols["x"] - 0.5 * length * heading
        if np.median(heading) < 0:
            pos = -pos
            meta["mirrored"] = "the road runs towards -x: positions negated"
        meta["reference_point"] = "centre (x - length/2 * sin(angle); SUMO x is the front bumper)"
        split_pos = np.zeros(max(n - 1, 0), dtype=bool)
    else:
        pos = cols["pos"] - 0.5 * length
        meta["reference_point"] = "centre (pos - length/2; SUMO pos is the front bumper)"
        split_pos = np.diff(cols["pos"]) < 0

    # segments: new vehicle, missing time steps, or (pos) a new edge
    new = np.ones(n, dtype=bool)
    new[1:] = (np.diff(code) != 0) | (np.diff(time) > 1.5 * dt) | split_pos
    seg = np.cumsum(new) - 1
    starts = np.flatnonzero(new)

    lane, internal = _lane_index(cols["lane"], path)
    if np.any(internal):  # hold the last normal lane (or the next one at a track start)
        lane = lane.astype(np.float64)
        lane[internal] = np.nan
        idx = np.where(~np.isnan(lane) | new, np.arange(n), 0)
        np.maximum.accumulate(idx, out=idx)
        lane = lane[idx]
        for s, e in zip(starts, np.append(starts[1:], n)):
            seg_l = lane[s:e]
            if np.isnan(seg_l).any():
                good = np.flatnonzero(~np.isnan(seg_l))
                fill = seg_l[good[0]] if good.size else -1.0
                seg_l[np.isnan(seg_l)] = fill  # leading internal samples of a track
        lane = lane.astype(np.int64)
        meta["internal_lane_samples_held"] = int(np.sum(internal))

    speed = cols["speed"]
    if "acceleration" in cols:
        acc = cols["acceleration"]
        meta["acceleration_source"] = "acceleration attribute"
    else:
        acc = np.zeros(n)
        acc[1:] = np.diff(speed) / dt
        acc[new] = 0.0
        # first sample of a track: copy the next difference when there is one
        nxt = starts + 1
        ok = (nxt < n) & ~np.append(new[1:], True)[starts]
        acc[starts[ok]] = acc[nxt[ok]]
        meta["acceleration_source"] = "backward difference of speed"
    meta["source_ids"] = [str(s) for s in cols["id"][starts]]
    if "type" in cols:
        meta["track_types"] = [str(s) for s in vtypes[starts]]
    return Tracks(seg, time, pos, speed, acc, lane, dt, meta)


# ------------------------------------------------------------------------------------------
# dispatch
# ------------------------------------------------------------------------------------------

_PATTERNS = {"highd": ("*_tracks.csv", "*_tracks.csv.gz"), "ngsim": ("*.csv", "*.csv.gz"),
             "sumo": ("*.xml", "*.xml.gz", "*.csv", "*.csv.gz")}


def load(paths, format: str, **kwargs) -> Tracks:
    """Load one or several files of one format into one table (``iamp train DATA... --format``).

    ``format`` is ``"highd"``, ``"ngsim"`` or ``"sumo"``.  A directory stands for its files of
    that format (``*_tracks.csv`` for highD, ``*.csv`` for NGSIM, FCD ``*.xml``/``*.csv`` for
    SUMO).  Tables are concatenated with track ids renumbered where they collide; tables with
    different sampling periods are first resampled to the coarsest one.  Extra keyword
    arguments go to the format's loader.
    """
    fmt = str(format).strip().lower()
    loaders = {"highd": load_highd, "ngsim": load_ngsim, "sumo": load_sumo_fcd}
    if fmt not in loaders:
        raise TrackDataError(f"unknown format {format!r}; expected one of {', '.join(FORMATS)}")
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    files: list[Path] = []
    for p in paths:
        p = _path(p)
        if p.is_dir():
            found = sorted({f for pat in _PATTERNS[fmt] for f in p.glob(pat) if f.is_file()})
            if not found:
                raise TrackDataError(f"no {fmt} files ({', '.join(_PATTERNS[fmt])}) in the directory", source=p)
            files.extend(found)
        else:
            files.append(p)
    if not files:
        raise TrackDataError("no input files given")
    tables = [loaders[fmt](f, **kwargs) for f in files]
    dts = [tb.dt for tb in tables]
    coarse = max(dts)
    if any(abs(d - coarse) > 1e-9 * coarse for d in dts):
        tables = [tb if abs(tb.dt - coarse) <= 1e-9 * coarse else tb.resample(coarse) for tb in tables]
    return Tracks.concat(tables)
