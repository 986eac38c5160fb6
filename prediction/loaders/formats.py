"""Loaders of recorded vehicle trajectories into the common :class:`~iamp.prediction.tracks.table.Tracks` table.

Supported sources
-----------------
``highd``
    The highD dataset (``XX_tracks.csv`` with, optionally, ``XX_tracksMeta.csv`` and
    ``XX_recordingMeta.csv``; found beside the tracks file when not given).
``ngsim``
    NGSIM US-101 / I-80 trajectories: the combined CSV, or the original headerless
    whitespace-separated ``.txt`` (:mod:`~iamp.prediction.loaders.ngsim`).
``sumo``
    Eclipse SUMO floating-car-data output (``--fcd-output``), XML (optionally gzipped) or
    the ``;``-separated CSV written by SUMO itself or by ``xml2csv.py``; also iamp's own
    ``iamp simulate --log`` (recognised by its header; :mod:`~iamp.prediction.loaders.iamplog`).

Every loader returns positions of the vehicle *centre*, increasing in the driving direction,
in metres, speeds in m/s and accelerations in m/s², and records what it converted in
``Tracks.meta``; every dropped row is counted under its reason in a
:class:`~iamp.prediction.loaders.report.LoadReport` (``meta["load_report"]``; :func:`load_with_report`
returns it).  Problems with a file raise :class:`~iamp.prediction.tracks.table.TrackDataError`
naming the file and the column.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from pathlib import Path

from iamp.prediction._typing import PathLike
from iamp.prediction.tracks.table import TrackDataError, Tracks

from .csv import _path
from .highd import HIGHD_DEFAULT_FRAME_RATE, load_highd
from .ngsim import FEET, NGSIM_FRAME_PERIOD, NGSIM_TXT_COLUMNS, load_ngsim
from .report import LoadReport
from .sumo import SUMO_DEFAULT_LENGTH, load_sumo_fcd

__all__ = ["FEET", "FORMATS", "HIGHD_DEFAULT_FRAME_RATE", "NGSIM_FRAME_PERIOD", "NGSIM_TXT_COLUMNS",
           "SUMO_DEFAULT_LENGTH", "LoadReport", "TrackDataError", "load", "load_highd", "load_ngsim",
           "load_sumo_fcd", "load_with_report", "ngsim_options"]

#: Formats understood by :func:`load` (the CLI's ``--format``).
FORMATS = ("highd", "ngsim", "sumo")

# ------------------------------------------------------------------------------------------
# dispatch
# ------------------------------------------------------------------------------------------

_PATTERNS = {"highd": ("*_tracks.csv", "*_tracks.csv.gz"), "ngsim": ("*.csv", "*.csv.gz", "*.txt", "*.txt.gz"),
             "sumo": ("*.xml", "*.xml.gz", "*.csv", "*.csv.gz")}


def load(paths: PathLike | Iterable[PathLike], format: str, **kwargs: object) -> Tracks:
    """Load one or several files of one format into one table (``iamp train DATA... --format``).

    ``format`` is ``"highd"``, ``"ngsim"`` or ``"sumo"``.  A directory stands for its files of
    that format (``*_tracks.csv`` for highD, ``*.csv`` for NGSIM, FCD ``*.xml``/``*.csv`` for
    SUMO).  Tables are concatenated with track ids renumbered where they collide; tables with
    different sampling periods are first resampled to the coarsest one.  Extra keyword
    arguments go to the format's loader.
    """
    fmt = str(format).strip().lower()
    loaders: dict[str, Callable[..., Tracks]] = {"highd": load_highd, "ngsim": load_ngsim, "sumo": load_sumo_fcd}
    if fmt not in loaders:
        raise TrackDataError(f"unknown format {format!r}; expected one of {', '.join(FORMATS)}")
    items = [paths] if isinstance(paths, (str, os.PathLike)) else paths
    files: list[Path] = []
    for item in items:
        p = _path(item)
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


def ngsim_options(fmt: str, location: str | None = None, units: str | None = None) -> dict[str, str]:
    """The NGSIM loader's options as keyword arguments of :func:`load` (``--location``, ``--units``).

    Parameters
    ----------
    fmt : str
        The format the options go with.
    location, units : str, optional
        :func:`~iamp.prediction.loaders.ngsim.load_ngsim`'s ``location`` and ``units``.

    Returns
    -------
    dict
        The options given (``None`` left out).

    Raises
    ------
    ValueError
        An option given for a format other than ``"ngsim"``.
    """
    opts = {k: v for k, v in (("location", location), ("units", units)) if v is not None}
    if opts and str(fmt).strip().lower() != "ngsim":
        raise ValueError(" and ".join(f"--{k}" for k in opts) + " applies to NGSIM data only")
    return opts


def load_with_report(paths: PathLike | Iterable[PathLike], format: str,
                     **kwargs: object) -> tuple[Tracks, LoadReport]:
    """:func:`load` and the merged :class:`LoadReport` of every file it read."""
    tracks = load(paths, format, **kwargs)
    meta = tracks.meta
    parts = meta.get("parts") if meta.get("format") == "concat" else [meta]
    reports = [LoadReport.from_dict(p["load_report"]) for p in (parts or []) if isinstance(p, dict)
               and "load_report" in p]
    report = LoadReport.merge(reports)
    return tracks, report
