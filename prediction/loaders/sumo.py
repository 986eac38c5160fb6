"""Eclipse SUMO floating-car data (``--fcd-output``), XML (optionally gzipped) or CSV."""

from __future__ import annotations

import gzip
import math
import os
import xml.etree.ElementTree as ET
import zlib
from array import array
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from iamp.prediction._typing import Array
from iamp.prediction.tracks.table import TrackDataError, Tracks

from . import plausibility
from .csv import _open_text, _path, duplicate_rows, read_csv
from .iamplog import is_iamp_log, load_iamp_log
from .report import LoadReport

__all__ = ["SUMO_DEFAULT_LENGTH", "load_sumo_fcd"]

SUMO_DEFAULT_LENGTH = 5.0


_SUMO_ATTRS = ("time", "id", "x", "y", "angle", "type", "speed", "pos", "lane", "acceleration", "length")
_SUMO_TEXT = ("id", "type", "lane")


def _sumo_csv_spec(coordinate: str) -> list[tuple[str, tuple[str, ...], bool]]:
    req = {"time", "id", "speed", "lane", coordinate}
    spec: list[tuple[str, tuple[str, ...], bool]] = []
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
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as exc:
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    return bool(head.lstrip().startswith("<"))


def _read_fcd_xml(path: Path, coordinate: str) -> tuple[dict[str, Array], dict[str, float]]:
    """Columns of an FCD XML file (iterparse; memory stays flat) and the vType lengths in it."""
    required = ("id", "speed", "lane", coordinate)
    floats = {k: array("d") for k in ("time", "x", "y", "angle", "speed", "pos", "acceleration", "length")}
    texts: dict[str, list[str]] = {"id": [], "type": [], "lane": []}
    seen = {k: 0 for k in ("x", "y", "angle", "pos", "acceleration", "length", "type")}
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
                            for key in ("x", "y", "angle", "pos", "acceleration", "length"):
                                if key in at:
                                    floats[key].append(float(at[key]))
                                    seen[key] += 1
                                else:
                                    floats[key].append(math.nan)
                        except ValueError as exc:
                            bad = next(k for k in ("speed", "x", "y", "angle", "pos", "acceleration", "length")
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
    cols: dict[str, Array] = {"time": np.frombuffer(floats["time"], dtype=np.float64) if n else np.empty(0),
                  "speed": np.frombuffer(floats["speed"], dtype=np.float64) if n else np.empty(0),
                  "id": np.asarray(texts["id"], dtype=str), "lane": np.asarray(texts["lane"], dtype=str)}
    for key in ("x", "y", "angle", "pos", "acceleration", "length"):
        if seen[key] == n and n:
            cols[key] = np.frombuffer(floats[key], dtype=np.float64)
        elif seen[key]:
            raise TrackDataError(f"present on only {seen[key]} of {n} vehicle records", column=key, source=path)
    if seen["type"]:
        cols["type"] = np.asarray(texts["type"], dtype=str)
    for key in ("time", "speed", "x", "y", "angle", "pos", "acceleration", "length"):
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


def load_sumo_fcd(path: str | os.PathLike[str], *, lengths: Mapping[str, float] | None = None,
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

    A CSV with the header of ``iamp simulate --log`` is read as that log
    (:mod:`~iamp.prediction.loaders.iamplog`: the traffic, without the ego).

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
    if not _is_xml(path) and is_iamp_log(path):  # iamp's own `simulate --log` of SUMO traffic
        return load_iamp_log(path)
    if _is_xml(path):
        cols, vtype_len = _read_fcd_xml(path, coordinate)
        fmt = "xml"
    else:
        cols = read_csv(path, _sumo_csv_spec(coordinate), text=_SUMO_TEXT, delimiter=None, skip_empty="id")
        cols.pop("__line__", None)
        vtype_len = {}
        fmt = "csv"
    n = cols["time"].size
    if n == 0:
        raise TrackDataError("no vehicle records", source=path)
    report = LoadReport(sources=[str(path)], rows_read=int(n))
    meta: dict[str, Any] = {"format": "sumo-fcd", "source": str(path), "file_type": fmt, "coordinate": coordinate,
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
    value_cols = [cols[k] for k in ("x", "pos", "speed", "acceleration", "y") if k in cols]
    keep = duplicate_rows((np.diff(code) == 0) & (np.diff(time) == 0), value_cols + [cols["lane"]], report)
    if not np.all(keep):
        cols = {k: val[keep] for k, val in cols.items()}
        code = code[keep]
        time = cols["time"]
        n = int(time.size)
    report.rows_kept = n
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
    y_lat = None
    if "y" in cols and coordinate == "x":
        cos = np.cos(np.radians(cols["angle"])) if "angle" in cols else np.zeros(n)
        y_lat = cols["y"] - 0.5 * length * cos
        meta["lateral"] = "centre y - length/2 * cos(angle) (SUMO y is the front bumper)"
    if starts.size > names.size:
        report.note(f"{starts.size - names.size} track split(s) at missing time steps (no row dropped)")
    meta["load_report"] = report.to_dict()
    report.check()
    tracks = Tracks(seg, time, pos, speed, acc, lane, dt, meta, y_lat)
    return plausibility.apply(tracks, path, "metres (SUMO)", report)
