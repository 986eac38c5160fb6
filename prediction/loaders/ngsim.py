"""NGSIM US-101 / I-80 trajectory data, as users have it (SPEC §13).

Accepted files
--------------
* The combined CSV ("Next Generation Simulation Vehicle Trajectories", header line with
  ``Vehicle_ID, Frame_ID, Total_Frames, Global_Time, Local_X, Local_Y, ..., v_length, ...,
  v_Vel, v_Acc, Lane_ID, ..., Location``; comma, semicolon or whitespace separated).
* The original headerless, whitespace-separated ``.txt`` files (``trajectories-0750am-0805am.txt``
  etc.), whose 18 columns are, in the order of the NGSIM trajectory data documentation,
  :data:`NGSIM_TXT_COLUMNS`.

Conversions: feet → metres (``× 0.3048``: positions, ft/s, ft/s²); time ``Frame_ID × 0.1 s``.
A file of the same layout in metres is recognised from its data (vehicle lengths and widths, lane
width, speeds: :mod:`~iamp.prediction.loaders.units`) and read without the factor; where the data
cannot tell, the file is refused unless ``units="feet"`` or ``"metres"`` is given (``--units``).
Rows are keyed by ``(Location, Vehicle_ID, Frame_ID)``; ``Global_Time`` is never used (some
re-extractions leave it at zero, which would make every row of a vehicle look like the same
instant).  ``Local_Y`` is the **front bumper** (NGSIM's definition); the position of a vehicle
is its centre ``Local_Y − L/2`` with ``L`` the median positive ``v_length`` of the vehicle's
rows; a vehicle whose ``v_length`` is zero or missing in every row keeps the front bumper
as its reference point (counted in the report).  A constant offset per vehicle does not change
its motion, so the predictor is unaffected either way.  ``Local_X`` (lateral, front centre) is
kept as ``Tracks.y``.

Every dropped row is counted in the :class:`~iamp.prediction.loaders.report.LoadReport` under its
reason: exact duplicate rows (same key, same values), conflicting rows (same key, other values;
the first in file order is kept), rows of another ``Location`` when ``location`` is given.
Tracks are split where ``Frame_ID`` does not advance by one (noted, no row dropped).
"""

from __future__ import annotations

import os
import re
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from iamp.prediction._typing import Array, FloatArray, IntArray
from iamp.prediction.tracks.table import TrackDataError, Tracks

from . import plausibility
from .csv import _integers, _open_text, _path, _segments, duplicate_rows, read_csv
from .report import LoadReport
from .units import FOOT_M, detect_units

__all__ = ["FEET", "NGSIM_FRAME_PERIOD", "NGSIM_TXT_COLUMNS", "load_ngsim"]

#: One foot in metres (NGSIM units).
FEET = FOOT_M
#: NGSIM frame period [s] (10 Hz).
NGSIM_FRAME_PERIOD = 0.1
#: Columns of the original headerless ``.txt`` files, in file order.
NGSIM_TXT_COLUMNS = ("Vehicle_ID", "Frame_ID", "Total_Frames", "Global_Time", "Local_X", "Local_Y", "Global_X",
                     "Global_Y", "v_Length", "v_Width", "v_Class", "v_Vel", "v_Acc", "Lane_ID", "Preceding",
                     "Following", "Space_Hdwy", "Time_Hdwy")

_NGSIM = (
    ("Vehicle_ID", ("Vehicle_ID",), True),
    ("Frame_ID", ("Frame_ID",), True),
    ("Local_Y", ("Local_Y",), True),
    ("v_Vel", ("v_Vel",), True),
    ("v_Acc", ("v_Acc",), True),
    ("Lane_ID", ("Lane_ID",), True),
    ("Local_X", ("Local_X",), False),
    ("v_length", ("v_length", "v_Length"), False),
    ("v_Width", ("v_Width", "v_width"), False),
    ("Global_Time", ("Global_Time",), False),
    ("Location", ("Location",), False),
)
_VALUES = ("Local_Y", "v_Vel", "v_Acc", "Lane_ID", "Local_X", "v_length")


def _first_line(path: Path) -> str:
    try:
        with _open_text(path) as fh:
            for line in fh:
                if line.strip():
                    return str(line)
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as exc:
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    raise TrackDataError("the file is empty", source=path)


def _read_txt(path: Path) -> dict[str, Array]:
    """The headerless whitespace-separated original (18 numeric columns)."""
    want = {name: NGSIM_TXT_COLUMNS.index(name) for name in
            ("Vehicle_ID", "Frame_ID", "Global_Time", "Local_X", "Local_Y", "v_Length", "v_Width", "v_Vel", "v_Acc",
             "Lane_ID")}
    try:
        with _open_text(path) as fh:
            data = np.loadtxt(fh, usecols=list(want.values()), dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise TrackDataError(f"not the 18-column NGSIM text layout ({exc})", source=path) from None
    except (OSError, EOFError, zlib.error) as exc:  # a truncated or corrupt .gz
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    cols: dict[str, Array] = {name: data[:, k] for k, name in enumerate(want)}
    cols["v_length"] = cols.pop("v_Length")
    bad = ~np.isfinite(data)
    if np.any(bad):
        r, c = (int(i[0]) for i in np.nonzero(bad))
        raise TrackDataError(f"data row {r + 1}: value is not finite", column=list(want)[c], source=path)
    cols["__line__"] = np.arange(1, data.shape[0] + 1, dtype=np.int64)
    return cols


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _read(path: Path) -> tuple[dict[str, Array], str]:
    first = _first_line(path)
    if all(_is_number(tok) for tok in re.split(r"[\s,;]+", first.strip())):
        return _read_txt(path), "headerless whitespace-separated text (NGSIM documentation column order)"
    delim = ";" if first.count(";") > first.count(",") else ("," if "," in first else None)
    if delim is None:  # whitespace-separated with a header: normalise to the CSV reader
        cols = _read_whitespace_with_header(path, first)
        return cols, "whitespace-separated text with a header line"
    return read_csv(path, _NGSIM, text=("Location",), delimiter=delim), "CSV with a header line"


def _read_whitespace_with_header(path: Path, first: str) -> dict[str, Array]:
    header = [h.lower() for h in first.split()]
    cols: dict[str, Array] = {}
    use: dict[str, int] = {}
    for logical, names, required in _NGSIM:
        idx = next((header.index(n.lower()) for n in names if n.lower() in header), None)
        if idx is None:
            if required:
                raise TrackDataError("missing from the header", column=logical, source=path)
            continue
        if logical != "Location":
            use[logical] = idx
    try:
        with _open_text(path) as fh:
            data = np.loadtxt(fh, usecols=list(use.values()), skiprows=1, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise TrackDataError(f"cannot read the numbers ({exc})", source=path) from None
    for k, name in enumerate(use):
        cols[name] = data[:, k]
    cols["__line__"] = np.arange(2, data.shape[0] + 2, dtype=np.int64)
    return cols


def load_ngsim(csv_path: str | os.PathLike[str], location: str | None = None, units: str | None = None) -> Tracks:
    """Load NGSIM trajectory data (CSV with header, or the original headerless ``.txt``).

    Parameters
    ----------
    csv_path : path
        The file (``.gz`` accepted).
    location : str, optional
        Keep only the rows of this ``Location`` (case-insensitive, e.g. ``"us-101"``); rows of
        other locations are counted as dropped.  Without a ``Location`` column it labels the data.
    units : {"feet", "metres"}, optional
        The unit of lengths, speeds and accelerations in the file; default: detected from the data
        (:func:`~iamp.prediction.loaders.units.detect_units`), the file refused where the data
        cannot tell.  ``meta["units"]`` and a load-report note say which and why.

    Returns
    -------
    Tracks
        Track ids ``0..n−1``; ``meta["source_ids"]`` lists ``[location, vehicle_id, first_frame]``
        per track and ``meta["load_report"]`` the :class:`LoadReport` (see the module docstring).

    Raises
    ------
    TrackDataError
        A file that cannot be read, or whose unit the data do not single out (without ``units``).
    """
    path = _path(csv_path)
    cols, layout = _read(path)
    report = LoadReport(sources=[str(path)])
    n = int(cols["Frame_ID"].size)
    report.rows_read = n
    meta: dict[str, Any] = {"format": "ngsim", "source": str(path), "layout": layout,
                            "frame_period": NGSIM_FRAME_PERIOD, "keyed_by": "(Location, Vehicle_ID, Frame_ID)"}
    if n == 0:
        raise TrackDataError("no data rows", source=path)
    # locations as integer codes (the strings are dropped at once: memory on big files)
    if "Location" in cols:
        raw_names, loc_code = np.unique(cols.pop("Location"), return_inverse=True)
        names = np.asarray([str(x).strip().lower() for x in raw_names])
        locations, remap = np.unique(names, return_inverse=True)
        loc_code = remap[loc_code]
    else:
        locations = np.asarray([(location or "unknown").strip().lower()])
        loc_code = np.zeros(n, dtype=np.int64)
        meta["location_source"] = "argument" if location else "unknown (no Location column)"
        if location:
            report.note(f"no Location column: every row is labelled {location.strip().lower()!r} (--location "
                        "filters only a file with that column)")
    if location is not None and "location_source" not in meta:
        want = location.strip().lower()
        if want not in locations:
            present = ", ".join(str(x) for x in locations[:6])
            raise TrackDataError(f"no rows for location {location!r} (present: {present})", column="Location",
                                 source=path)
        keep = loc_code == int(np.flatnonzero(locations == want)[0])
        report.drop(f"Location is not {location!r}", int(np.sum(~keep)))
        cols = {k: val[keep] for k, val in cols.items()}
        loc_code = np.zeros(int(np.sum(keep)), dtype=np.int64)
        locations = np.asarray([want])
        meta["location_filter"] = location
    decision = detect_units(cols, path, units)
    factor = decision.factor
    meta["units"] = decision.units
    meta["units_converted"] = "feet -> metres (x 0.3048)" if decision.units == "feet" else "none (metres)"
    report.note(decision.note())
    cols.pop("v_Width", None)
    if "Global_Time" in cols:
        zeros = int(np.sum(cols.pop("Global_Time") == 0))
        report.note("Global_Time ignored: rows are keyed by Vehicle_ID and Frame_ID"
                    + (f" (Global_Time is 0 in {zeros} of {loc_code.size} rows)" if zeros else ""))
    vid = _integers(cols.pop("Vehicle_ID"), "Vehicle_ID", path)
    frame = _integers(cols.pop("Frame_ID"), "Frame_ID", path)
    file_line = cols.pop("__line__")
    order = np.lexsort((file_line, frame, vid, loc_code))
    loc_code, vid, frame = loc_code[order], vid[order], frame[order]
    same_vehicle = (np.diff(loc_code) == 0) & (np.diff(vid) == 0)
    unordered = int(np.sum(same_vehicle & (np.diff(file_line[order]) < 0)))
    if unordered:
        report.note(f"{unordered} row(s) of a vehicle came before an earlier Frame_ID in the file (frames swapped or "
                    "reversed): rows were put in Frame_ID order")
    file_line = file_line[order]
    del same_vehicle
    vals = {k: cols.pop(k)[order] for k in _VALUES if k in cols}
    del cols, order

    # duplicates of the key (the first row in file order is kept)
    same_key = (np.diff(loc_code) == 0) & (np.diff(vid) == 0) & (np.diff(frame) == 0)
    keep = duplicate_rows(same_key, list(vals.values()), report)
    loc_code, vid, frame, file_line = loc_code[keep], vid[keep], frame[keep], file_line[keep]
    vals = {k: v[keep] for k, v in vals.items()}
    lane = _integers(vals["Lane_ID"], "Lane_ID", path)
    report.rows_kept = int(loc_code.size)

    key_change = (np.diff(loc_code) != 0) | (np.diff(vid) != 0)
    seg = _segments(key_change, frame)
    starts = np.concatenate(([0], np.flatnonzero(np.diff(seg)) + 1))
    vstart = np.concatenate(([0], np.flatnonzero(key_change) + 1))
    n_vehicles = int(vstart.size)
    splits = int(starts.size - n_vehicles)
    if splits:
        report.note(f"{splits} track split(s) where Frame_ID skips frames (no row dropped)")

    y_front = vals["Local_Y"]
    L = _vehicle_lengths(vals.get("v_length"), vstart, y_front.size)
    unknown = ~np.isfinite(L)
    n_unknown = int(np.sum(unknown[vstart]))
    centre = np.where(unknown, y_front, y_front - 0.5 * np.where(unknown, 0.0, L))
    if n_unknown:
        report.note(f"{n_unknown} of {n_vehicles} vehicle(s) have no positive v_length: their reference point is "
                    "the front bumper (Local_Y), not the centre")
    meta["reference_point"] = ("centre (Local_Y - L/2, L = median positive v_length of the vehicle; Local_Y is the "
                               "front bumper)" + (f"; front bumper for {n_unknown} vehicle(s) of unknown length"
                                                  if n_unknown else ""))
    meta["vehicles_unknown_length"] = n_unknown
    meta["locations"] = [str(s) for s in locations]
    meta["source_ids"] = [[str(locations[loc_code[s]]), int(vid[s]), int(frame[s])] for s in starts]
    meta["split_at_frame_gaps"] = splits
    meta["load_report"] = report.to_dict()
    report.check()
    y_lat = vals["Local_X"] * factor if "Local_X" in vals else None
    tracks = Tracks(seg, frame * NGSIM_FRAME_PERIOD, centre * factor, vals["v_Vel"] * factor, vals["v_Acc"] * factor,
                    lane, NGSIM_FRAME_PERIOD, meta, y_lat)
    unit = ("feet (NGSIM), converted to metres" if decision.units == "feet" else "metres (no conversion)") + \
        f", {decision.how}"
    return plausibility.apply(tracks, path, unit, report, lines=file_line)


def _vehicle_lengths(length: FloatArray | None, vstart: IntArray, n: int) -> FloatArray:
    """Per row: the median positive ``v_length`` of its vehicle (NaN when it has none)."""
    out: FloatArray = np.full(n, np.nan)
    if length is None:
        return out
    bounds = np.append(vstart, n)
    for s, e in zip(bounds[:-1], bounds[1:]):
        seg = length[s:e]
        pos = seg[seg > 0]
        if pos.size:
            out[s:e] = float(np.median(pos))
    return out
