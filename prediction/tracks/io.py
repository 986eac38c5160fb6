"""Tracks files: the compressed ``.npz`` layout of :meth:`Tracks.save` and the shipped dataset."""

from __future__ import annotations

import json
import os
import zipfile
from importlib import resources
from pathlib import Path
from typing import IO, Any

import numpy as np

from iamp.core.atomic import atomic_open

from .table import _COLUMNS, FILE_FORMAT, FILE_VERSION, SHIPPED_DATASET, TrackDataError, Tracks

__all__ = ["load_shipped_dataset", "load_tracks", "save_tracks"]


def save_tracks(tracks: Tracks, path: str | os.PathLike[str], *, decimals: int | None = None) -> Path:
    """Write the table to a compressed ``.npz`` file, atomically; returns the path.

    The file is written to a temporary file in the same directory and then renamed over
    ``path``, so a reader never sees a partial file.  The bytes depend only on the table
    (fixed zip timestamps), so saving equal tables gives identical files.

    With ``decimals=None`` (default) the columns are stored exactly (float64).  With
    ``decimals=d`` the columns ``x``, ``v`` and ``a`` are rounded to ``d`` decimals and stored
    as difference-coded integers, which compresses far better; use it only when the data
    carry no more precision than that (e.g. SUMO output, written with 2 decimals).  Times
    that lie on the grid ``k·dt`` are always stored as integer step indices.  The meta dict
    is stored as a JSON string.
    """
    path = Path(path)
    try:
        meta_json = json.dumps(tracks.meta, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise TrackDataError(f"meta is not JSON serialisable ({exc})", column="meta", source=path) from None
    if decimals is not None:
        decimals = int(decimals)
        if not 0 <= decimals <= 9:
            raise TrackDataError(f"decimals must be within 0..9, got {decimals}")
    arrays: dict[str, np.ndarray] = {}
    encoding: dict[str, str] = {}
    header: dict[str, Any] = {"format": FILE_FORMAT, "version": FILE_VERSION, "dt": tracks.dt, "rows": len(tracks),
              "encoding": encoding}
    arrays["track_id"] = _delta_int(tracks.track_id)
    encoding["track_id"] = "delta"
    arrays["lane"] = _small_int(tracks.lane)
    encoding["lane"] = "int"
    steps = np.round(tracks.t / tracks.dt)
    if len(tracks) and np.all(np.abs(steps * tracks.dt - tracks.t) <= 1e-9 * max(1.0, float(np.abs(tracks.t).max()))):
        arrays["t"] = _delta_int(steps.astype(np.int64))
        encoding["t"] = "delta-steps"
    else:
        arrays["t"] = tracks.t
        encoding["t"] = "float64"
    for name in ("x", "v", "a", "y"):
        col = getattr(tracks, name)
        if col is None:
            continue
        if decimals is None:
            arrays[name] = col
            encoding[name] = "float64"
        else:
            q = np.round(col * 10.0 ** decimals)
            if q.size and np.abs(q).max() >= 2 ** 53:
                raise TrackDataError(f"values too large for {decimals} decimals", column=name)
            arrays[name] = _delta_int(q.astype(np.int64))
            encoding[name] = f"delta-decimals-{decimals}"
    arrays["header"] = np.array(json.dumps(header, sort_keys=True))
    arrays["meta"] = np.array(meta_json)

    with atomic_open(path, "wb") as fh:
        _write_npz(fh, arrays)
    return path

def load_tracks(path: str | os.PathLike[str]) -> Tracks:
    """Read a table written by :meth:`save`; :class:`TrackDataError` for a bad file."""
    path = Path(path)
    try:
        npz = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    except Exception as exc:
        raise TrackDataError(f"not a tracks .npz file ({exc})", source=path) from None
    with npz:
        names = set(npz.files)
        for key in ("header", "meta", *_COLUMNS):
            if key not in names:
                raise TrackDataError("missing from the file", column=key, source=path)
        try:
            header = json.loads(str(npz["header"][()]))
            meta = json.loads(str(npz["meta"][()]))
        except (ValueError, TypeError) as exc:
            raise TrackDataError(f"not valid JSON ({exc})", column="header/meta", source=path) from None
        if header.get("format") != FILE_FORMAT:
            raise TrackDataError(f"unknown format {header.get('format')!r}", column="header", source=path)
        if int(header.get("version", 0)) > FILE_VERSION:
            raise TrackDataError(f"file version {header.get('version')} is newer than this iamp reads "
                                 f"({FILE_VERSION})", column="header", source=path)
        dt = float(header["dt"])
        enc = header.get("encoding", {})
        cols = {}
        for name in _COLUMNS:
            raw = npz[name]
            kind = enc.get(name, "float64")
            if kind == "delta":
                col = np.cumsum(raw.astype(np.int64))
            elif kind == "delta-steps":
                col = np.cumsum(raw.astype(np.int64)) * dt
            elif kind.startswith("delta-decimals-"):
                d = int(kind.rsplit("-", 1)[1])
                col = np.cumsum(raw.astype(np.int64)) / 10.0 ** d
            elif kind in ("int", "float64"):
                col = raw
            else:
                raise TrackDataError(f"unknown encoding {kind!r}", column=name, source=path)
            cols[name] = col
        if "y" in names:  # optional lateral column (files without it stay readable)
            raw = npz["y"]
            kind = enc.get("y", "float64")
            if kind.startswith("delta-decimals-"):
                cols["y"] = np.cumsum(raw.astype(np.int64)) / 10.0 ** int(kind.rsplit("-", 1)[1])
            else:
                cols["y"] = raw
        if "rows" in header and cols["track_id"].size != int(header["rows"]):
            raise TrackDataError(f"has {cols['track_id'].size} rows, header says {header['rows']}",
                                 column="track_id", source=path)
    return Tracks(cols["track_id"], cols["t"], cols["x"], cols["v"], cols["a"], cols["lane"], dt, meta,
                  cols.get("y"))


def _write_npz(fh: IO[bytes], arrays: dict[str, np.ndarray]) -> None:
    """``np.savez_compressed`` with fixed zip timestamps, so equal tables give equal bytes."""
    with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9, allowZip64=True) as zf:
        for name, arr in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as out:
                np.lib.format.write_array(out, np.asanyarray(arr), allow_pickle=False)


def _delta_int(values: np.ndarray) -> np.ndarray:
    """First differences (first value kept) in the smallest integer dtype that holds them."""
    d = np.diff(values.astype(np.int64), prepend=np.int64(0))
    return _small_int(d)


def _small_int(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=np.int64)
    if values.size == 0:
        return values.astype(np.int8)
    lo, hi = int(values.min()), int(values.max())
    for dtype in (np.int8, np.int16, np.int32):
        info = np.iinfo(dtype)
        if info.min <= lo and hi <= info.max:
            return values.astype(dtype)
    return values


def load_shipped_dataset() -> Tracks:
    """The simulated highway dataset shipped inside the package (``prediction/data``).

    It is generated by ``scripts/sumo/generate_dataset.py`` with Eclipse SUMO; its provenance
    (SUMO version, seed, configuration, checksum) is in ``sumo_highway.json`` beside it and in
    the table's ``meta``.
    """
    ref = resources.files("iamp.prediction").joinpath("data", SHIPPED_DATASET)
    if not ref.is_file():
        raise TrackDataError("the shipped dataset is missing from the installed package",
                             source=f"iamp.prediction/data/{SHIPPED_DATASET}")
    with resources.as_file(ref) as path:
        return Tracks.load(path)
