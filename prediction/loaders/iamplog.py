"""iamp's own step log (``iamp simulate --log``) as recorded data (issue 22 item 11).

The log is CSV with the columns :data:`IAMP_LOG_COLUMNS` (the same as
``iamp.simulation.episode.LOG_COLUMNS``, which this layer may not import): one row per vehicle
and step, centres, SI units; ``vehicle`` is ``ego`` for iamp's planned vehicle and SUMO's id for
the traffic.  ``--format sumo`` reads such a file (the traffic is SUMO's); the loader recognises
it by its header.

What it assumes (said in the load report): the ego is left out, since a predictor of the
traffic is evaluated on the traffic, not on the vehicle iamp itself drove; a neighbour's speed
is its ``vx`` and its acceleration SUMO's (``ax``), else the backward difference of speed; the
time step is the median step of the log; a vehicle's track is split where steps are missing
(it left the ego's neighbourhood and came back).
"""

from __future__ import annotations

import os
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from iamp.prediction.tracks.table import TrackDataError, Tracks

from . import plausibility
from .csv import _open_text, _path, duplicate_rows, read_csv
from .report import LoadReport

__all__ = ["IAMP_LOG_COLUMNS", "is_iamp_log", "load_iamp_log"]

#: The header of ``iamp simulate --log`` (``iamp.simulation.episode.LOG_COLUMNS``).
IAMP_LOG_COLUMNS = ("t", "vehicle", "x", "y", "vx", "vy", "ax", "ay", "lane", "length", "width", "mode",
                    "plan_time_s")

_SPEC = [("t", ("t",), True), ("vehicle", ("vehicle",), True), ("x", ("x",), True), ("y", ("y",), True),
         ("vx", ("vx",), True), ("ax", ("ax",), True), ("lane", ("lane",), True)]


def is_iamp_log(path: Path) -> bool:
    """Whether the file's first line is the header of ``iamp simulate --log``."""
    try:
        with _open_text(path) as fh:
            first = fh.readline(4096)
    except (OSError, UnicodeDecodeError, EOFError, zlib.error):
        return False
    return tuple(c.strip() for c in first.strip().split(",")) == IAMP_LOG_COLUMNS


def _floats(text: np.ndarray) -> np.ndarray:
    out = np.full(text.size, np.nan)
    given = text != ""
    out[given] = text[given].astype(float)
    return out


def load_iamp_log(path: str | os.PathLike[str]) -> Tracks:
    """The traffic of an ``iamp simulate --log`` file as :class:`Tracks` (module docstring)."""
    path = _path(path)
    cols = read_csv(path, _SPEC, text=("vehicle", "ax", "lane"), delimiter=",")
    lines = cols.pop("__line__")
    n_read = int(cols["t"].size)
    report = LoadReport(sources=[str(path)], rows_read=n_read)
    traffic = cols["vehicle"] != "ego"
    report.drop("the ego (iamp's planned vehicle; the predictor is evaluated on the traffic)",
                int(n_read - np.sum(traffic)))
    cols = {k: v[traffic] for k, v in cols.items()}
    lines = lines[traffic]
    if cols["t"].size == 0:
        raise TrackDataError("no traffic rows (only the ego's)", source=path)
    try:
        acc_given, lane_f = _floats(cols["ax"]), _floats(cols["lane"])
    except ValueError:
        raise TrackDataError("a neighbour's ax or lane is not a number", source=path) from None
    if np.any(~np.isfinite(lane_f)):
        k = int(np.flatnonzero(~np.isfinite(lane_f))[0])
        raise TrackDataError(f"line {int(lines[k])}: a neighbour without a lane", column="lane", source=path)
    names, first, code = np.unique(cols["vehicle"], return_index=True, return_inverse=True)
    rank = np.empty(names.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(names.size)
    code = rank[code]
    order = np.lexsort((cols["t"], code))
    code, time, x, y, speed = code[order], cols["t"][order], cols["x"][order], cols["y"][order], cols["vx"][order]
    acc_given, lane, lines = acc_given[order], lane_f[order].astype(np.int64), lines[order]
    keep = duplicate_rows((np.diff(code) == 0) & (np.diff(time) == 0), [x, y, speed], report)
    code, time, x, y, speed, acc_given, lane, lines = (a[keep] for a in (code, time, x, y, speed, acc_given, lane,
                                                                         lines))
    n = int(time.size)
    report.rows_kept = n
    steps = np.diff(np.unique(time))
    dt = float(np.round(np.median(steps), 9)) if steps.size else 1.0
    new = np.ones(n, dtype=bool)
    new[1:] = (np.diff(code) != 0) | (np.diff(time) > 1.5 * dt)
    seg = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    by_rank = names[np.argsort(first, kind="stable")]
    acc = np.zeros(n)
    acc[1:] = np.diff(speed) / dt
    acc[new] = 0.0
    given = np.isfinite(acc_given)
    acc[given] = acc_given[given]
    meta: dict[str, Any] = {"format": "iamp-log", "source": str(path), "units": "SI (as logged)",
                            "reference_point": "centre (as logged)", "step_length": dt,
                            "acceleration_source": f"SUMO's (ax) for {int(np.sum(given))} of {n} rows, else the "
                                                   "backward difference of speed",
                            "source_ids": [str(by_rank[code[s]]) for s in starts]}
    report.note(f"iamp simulate --log: the traffic's {names.size} vehicle(s) at the log's step {dt:g} s; the ego is "
                "left out")
    if starts.size > names.size:
        report.note(f"{starts.size - names.size} track split(s) where a vehicle left the log and came back")
    meta["load_report"] = report.to_dict()
    report.check()
    tracks = Tracks(seg, time, x, speed, acc, lane, dt, meta, y)
    return plausibility.apply(tracks, path, "metres (iamp's log)", report, lines=lines)
