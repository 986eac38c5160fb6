"""The common table of recorded vehicle trajectories the predictor is trained on (SPEC §7).

Every loader (highD, NGSIM, SUMO FCD, see :mod:`iamp.prediction.loaders.formats`) returns a
:class:`Tracks`: one row per vehicle and sample, sorted by ``(track_id, t)``, with the
longitudinal position ``x`` of the vehicle *centre* increasing in the driving direction, its
speed ``v`` and acceleration ``a`` in SI units, and the lane id in the dataset's own numbering.

Within a track the samples are uniformly spaced by ``dt`` (loaders split a vehicle's record
where samples are missing).  Tables are saved as compressed ``.npz`` files; the simulated
dataset shipped with the package is returned by :func:`load_shipped_dataset`.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from iamp.core.errors import IampError
from iamp.prediction._typing import BoolArray, IntArray

__all__ = ["SHIPPED_DATASET", "TrackDataError", "Tracks", "load_shipped_dataset"]

#: File name of the shipped dataset inside the ``iamp.prediction`` package's ``data`` folder.
SHIPPED_DATASET = "sumo_highway.npz"

#: Version of the ``.npz`` layout written by :meth:`Tracks.save`.
FILE_FORMAT = "iamp-tracks"
FILE_VERSION = 1

_FLOAT_COLUMNS = ("t", "x", "v", "a")
_INT_COLUMNS = ("track_id", "lane")
_COLUMNS = ("track_id", "t", "x", "v", "a", "lane")

# Relative tolerance on the sampling period within a track (jitter from float round-off,
# e.g. frame / frame rate, or times read from a file with two decimals).
_DT_RTOL = 1e-3


class TrackDataError(IampError, ValueError):
    """Trajectory data that cannot be used: a bad file, a missing column, a bad value.

    Parameters
    ----------
    message : str
        What is wrong.
    column : str, optional
        The offending column (of the source file or of the table).
    source : str, optional
        The file the data came from.
    """

    def __init__(self, message: str, column: str | None = None, source: str | os.PathLike[str] | None = None):
        self.message = message
        self.column = column
        self.source = None if source is None else str(source)
        super().__init__(self.one_line())

    def one_line(self) -> str:
        parts = []
        if self.source:
            parts.append(self.source)
        if self.column:
            parts.append(f"column '{self.column}'")
        parts.append(self.message)
        return ": ".join(parts)


def _boundaries(track_id: np.ndarray) -> np.ndarray:
    """Row indices where a new track starts (excluding row 0)."""
    return np.flatnonzero(track_id[1:] != track_id[:-1]) + 1


@dataclass(frozen=True, eq=False)
class Tracks:
    """Per-vehicle longitudinal tracks, rows sorted by (track_id, t).

    Attributes
    ----------
    track_id : ndarray of int64
        Unique per vehicle across the whole table.
    t : ndarray of float64
        Time in s (per-track times; uniform sampling with period ``dt`` within a track).
    x : ndarray of float64
        Longitudinal position of the vehicle centre in m, increasing in the driving direction.
    v : ndarray of float64
        Longitudinal speed in m/s (>= 0 normally).
    a : ndarray of float64
        Longitudinal acceleration in m/s².
    lane : ndarray of int64
        Lane id in the dataset's own numbering.
    dt : float
        Sampling period in s.
    meta : dict
        Provenance: format, source files, frame rate, units converted, etc.  Must be JSON
        serialisable for :meth:`save`.
    y : ndarray of float64 or None
        Lateral position of the vehicle centre in m (optional; the loaders fill it when the
        data have it, in the dataset's lateral axis, in metres).

    The constructor converts the columns to the dtypes above and checks that they are
    one-dimensional, of equal length, finite, sorted by ``(track_id, t)`` and uniformly
    sampled with period ``dt`` within each track; anything else raises
    :class:`TrackDataError` naming the column.
    """

    track_id: np.ndarray
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lane: np.ndarray
    dt: float
    meta: dict[str, Any] = field(default_factory=dict)
    y: np.ndarray | None = None

    # -- construction -------------------------------------------------------------------------

    def __post_init__(self) -> None:
        source = self.meta.get("source") if isinstance(self.meta, dict) else None
        source = source if isinstance(source, str) else None
        if not isinstance(self.meta, dict):
            raise TrackDataError("meta must be a dict", column="meta")
        n = None
        for name in _COLUMNS:
            raw = getattr(self, name)
            try:
                arr = np.asarray(raw)
            except Exception as exc:  # pragma: no cover - exotic inputs
                raise TrackDataError(f"cannot convert to an array ({exc})", column=name, source=source) from None
            if arr.ndim != 1:
                raise TrackDataError(f"must be one-dimensional, got shape {arr.shape}", column=name, source=source)
            if name in _INT_COLUMNS:
                if arr.size and arr.dtype.kind == "f":
                    if not np.all(np.isfinite(arr)):
                        raise TrackDataError("contains NaN or infinite values", column=name, source=source)
                    if not np.all(arr == np.round(arr)):
                        raise TrackDataError("must hold integers", column=name, source=source)
                elif arr.size and arr.dtype.kind not in "iub":
                    raise TrackDataError(f"must hold integers, got dtype {arr.dtype}", column=name, source=source)
                arr = np.ascontiguousarray(arr, dtype=np.int64)
            else:
                if arr.size and arr.dtype.kind not in "iubf":
                    raise TrackDataError(f"must hold numbers, got dtype {arr.dtype}", column=name, source=source)
                arr = np.ascontiguousarray(arr, dtype=np.float64)
                if not np.all(np.isfinite(arr)):
                    bad = int(np.flatnonzero(~np.isfinite(arr))[0])
                    raise TrackDataError(f"contains NaN or infinite values (first at row {bad})",
                                         column=name, source=source)
            if n is None:
                n = arr.size
            elif arr.size != n:
                raise TrackDataError(f"has {arr.size} rows, expected {n} (the length of 'track_id')",
                                     column=name, source=source)
            object.__setattr__(self, name, arr)
        if self.y is not None:
            y = np.ascontiguousarray(np.asarray(self.y), dtype=np.float64)
            if y.shape != (n,):
                raise TrackDataError(f"has shape {y.shape}, expected ({n},)", column="y", source=source)
            if not np.all(np.isfinite(y)):
                raise TrackDataError("contains NaN or infinite values", column="y", source=source)
            object.__setattr__(self, "y", y)

        try:
            dt = float(self.dt)
        except (TypeError, ValueError):
            raise TrackDataError(f"must be a number, got {self.dt!r}", column="dt", source=source) from None
        if not np.isfinite(dt) or dt <= 0:
            raise TrackDataError(f"must be positive and finite, got {dt}", column="dt", source=source)
        object.__setattr__(self, "dt", dt)

        tid, t = self.track_id, self.t
        if n:
            dtid = np.diff(tid)
            if np.any(dtid < 0):
                bad = int(np.flatnonzero(dtid < 0)[0]) + 1
                raise TrackDataError(f"rows are not sorted by track id (row {bad})", column="track_id", source=source)
            same = dtid == 0
            steps = np.diff(t)[same]
            if steps.size:
                if np.any(steps <= 0):
                    bad = int(np.flatnonzero(same)[np.flatnonzero(steps <= 0)[0]]) + 1
                    raise TrackDataError(f"times are not strictly increasing within track {tid[bad]} (row {bad})",
                                         column="t", source=source)
                off = np.abs(steps - dt) > _DT_RTOL * dt
                if np.any(off):
                    k = int(np.flatnonzero(same)[np.flatnonzero(off)[0]]) + 1
                    raise TrackDataError(
                        f"sampling within track {tid[k]} is not uniform with dt={dt:g} s "
                        f"(step {t[k] - t[k - 1]:g} s at row {k}); split the track at gaps",
                        column="t", source=source)

    # -- basic access -------------------------------------------------------------------------

    def __len__(self) -> int:
        return int(self.track_id.size)

    def __repr__(self) -> str:
        fmt = self.meta.get("format", "?")
        return f"Tracks({len(self)} rows, {self.n_tracks} tracks, dt={self.dt:g} s, format={fmt!r})"

    @property
    def n_tracks(self) -> int:
        """Number of tracks."""
        return 0 if len(self) == 0 else int(_boundaries(self.track_id).size + 1)

    @property
    def duration(self) -> float:
        """Total observed time in s, summed over tracks (``rows × dt``)."""
        return len(self) * self.dt

    def ids(self) -> np.ndarray:
        """The unique track ids, ascending."""
        if len(self) == 0:
            return np.empty(0, dtype=np.int64)
        return self.track_id[np.concatenate(([0], _boundaries(self.track_id)))].copy()

    def _take(self, index: IntArray | BoolArray | slice, meta: dict[str, Any] | None = None) -> Tracks:
        return Tracks(self.track_id[index], self.t[index], self.x[index], self.v[index], self.a[index],
                      self.lane[index], self.dt, dict(self.meta) if meta is None else meta,
                      None if self.y is None else self.y[index])

    def track(self, tid: int) -> Tracks:
        """The rows of one track; :class:`TrackDataError` if there is no such track."""
        lo = np.searchsorted(self.track_id, tid, side="left")
        hi = np.searchsorted(self.track_id, tid, side="right")
        if hi <= lo:
            raise TrackDataError(f"no track with id {tid}", column="track_id", source=self.meta.get("source"))
        return self._take(slice(int(lo), int(hi)))

    def iter_tracks(self) -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Yield ``(tid, t, x, v, a, lane)`` for each track in id order (views, not copies)."""
        if len(self) == 0:
            return
        cuts = _boundaries(self.track_id)
        starts = np.concatenate(([0], cuts))
        parts = [np.split(col, cuts) for col in (self.t, self.x, self.v, self.a, self.lane)]
        for k, start in enumerate(starts):
            yield (int(self.track_id[start]), parts[0][k], parts[1][k], parts[2][k], parts[3][k], parts[4][k])

    def select(self, mask: ArrayLike) -> Tracks:
        """The rows where the boolean ``mask`` holds (tracks must stay gap-free)."""
        return self._take(np.asarray(mask, dtype=bool))

    # -- transformations ----------------------------------------------------------------------

    def resample(self, dt: float) -> Tracks:
        """Linear interpolation of ``x``, ``v`` and ``a`` per track onto a new uniform period.

        Each track is sampled at ``t0 + k·dt`` for every ``k`` that stays within the track's
        time span; the lane is held from the latest original sample at or before each new
        time (it is a category, not a number to interpolate).  A track shorter than ``dt``
        keeps only its first sample.  No anti-alias filtering is applied when downsampling.
        """
        dt = float(dt)
        if not np.isfinite(dt) or dt <= 0:
            raise TrackDataError(f"must be positive and finite, got {dt}", column="dt")
        out: dict[str, list[np.ndarray]] = {name: [] for name in _COLUMNS}
        eps = 1e-9 * max(dt, self.dt)
        ys: list[np.ndarray] = []
        y_all = np.split(self.y, _boundaries(self.track_id)) if self.y is not None and len(self) else []
        for k, (tid, t, x, v, a, lane) in enumerate(self.iter_tracks()):
            n_new = int(np.floor((t[-1] - t[0]) / dt + 1e-6)) + 1
            tn = t[0] + dt * np.arange(n_new)
            out["track_id"].append(np.full(n_new, tid, dtype=np.int64))
            out["t"].append(tn)
            out["x"].append(np.interp(tn, t, x))
            out["v"].append(np.interp(tn, t, v))
            out["a"].append(np.interp(tn, t, a))
            if y_all:
                ys.append(np.interp(tn, t, y_all[k]))
            idx = np.clip(np.searchsorted(t, tn + eps, side="right") - 1, 0, t.size - 1)
            out["lane"].append(lane[idx])
        meta = dict(self.meta)
        meta["resampled"] = {"from_dt": self.dt, "to_dt": dt, "method": "linear (lane: previous sample)"}
        cols = {k: (np.concatenate(v) if v else np.empty(0)) for k, v in out.items()}
        y_new = (np.concatenate(ys) if ys else np.empty(0)) if self.y is not None else None
        return Tracks(cols["track_id"], cols["t"], cols["x"], cols["v"], cols["a"], cols["lane"], dt, meta, y_new)

    @staticmethod
    def concat(tables: Sequence[Tracks]) -> Tracks:
        """Stack several tables with the same ``dt`` into one.

        Track ids are kept when they do not collide; otherwise every table after the first is
        renumbered by an offset (its ids plus one more than the largest id so far), and the
        offsets are recorded in ``meta["parts_id_offset"]``.
        """
        tables = list(tables)
        if not tables:
            raise TrackDataError("nothing to concatenate")
        for tb in tables:
            if not isinstance(tb, Tracks):
                raise TrackDataError(f"can only concatenate Tracks, got {type(tb).__name__}")
        if len(tables) == 1:
            return tables[0]
        dt = tables[0].dt
        for tb in tables[1:]:
            if abs(tb.dt - dt) > 1e-9 * dt:
                raise TrackDataError(f"sampling periods differ ({dt:g} s and {tb.dt:g} s); resample first",
                                     column="dt")
        all_ids = np.concatenate([tb.ids() for tb in tables])
        offsets = [0] * len(tables)
        if np.unique(all_ids).size != all_ids.size:
            nxt = 0
            for k, tb in enumerate(tables):
                if len(tb):
                    offsets[k] = nxt - int(tb.track_id.min()) if k else 0
                    nxt = int(tb.track_id.max()) + offsets[k] + 1
        cols = {name: np.concatenate([getattr(tb, name) for tb in tables]) for name in _COLUMNS}
        cols["track_id"] = np.concatenate([tb.track_id + off for tb, off in zip(tables, offsets)])
        order = np.lexsort((cols["t"], cols["track_id"]))
        meta: dict[str, Any] = {"format": "concat", "parts": [tb.meta for tb in tables]}
        if any(offsets):
            meta["parts_id_offset"] = offsets
        y = None
        if all(tb.y is not None for tb in tables):
            y = np.concatenate([tb.y for tb in tables if tb.y is not None])[order]
        c = {name: cols[name][order] for name in _COLUMNS}
        return Tracks(c["track_id"], c["t"], c["x"], c["v"], c["a"], c["lane"], dt=dt, meta=meta, y=y)

    def split_by_track(self, test_fraction: float, seed: int = 0) -> tuple[Tracks, Tracks]:
        """A deterministic held-out split by whole tracks: ``(train, test)``.

        ``round(test_fraction × n_tracks)`` tracks, drawn with ``numpy.random.default_rng(seed)``
        from the sorted ids, form the test table (at least one track in each part when
        ``0 < test_fraction < 1`` and there are two or more tracks).  The result depends only on
        the set of track ids, the fraction and the seed.
        """
        try:
            frac = float(test_fraction)
        except (TypeError, ValueError):
            raise TrackDataError(f"test_fraction must be a number, got {test_fraction!r}") from None
        if not (0.0 <= frac <= 1.0):
            raise TrackDataError(f"test_fraction must be within [0, 1], got {frac}")
        ids = self.ids()
        n = ids.size
        n_test = int(round(frac * n))
        if 0.0 < frac < 1.0 and n >= 2:
            n_test = min(max(n_test, 1), n - 1)
        rng = np.random.default_rng(seed)
        test_ids = np.sort(ids[rng.permutation(n)[:n_test]])
        is_test = np.isin(self.track_id, test_ids)
        split = {"test_fraction": frac, "seed": seed}
        train = self._take(~is_test, {**self.meta, "split": {**split, "part": "train"}})
        test = self._take(is_test, {**self.meta, "split": {**split, "part": "test"}})
        return train, test

    # -- files --------------------------------------------------------------------------------

    # -- files (layout in iamp.prediction.tracks.io) -----------------------------------------

    def save(self, path: str | os.PathLike[str], *, decimals: int | None = None) -> Path:
        """Write the table to a compressed ``.npz`` file, atomically (see :mod:`~iamp.prediction.tracks.io`)."""
        from .io import save_tracks

        return save_tracks(self, path, decimals=decimals)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Tracks:
        """Read a table written by :meth:`save` (:func:`~iamp.prediction.tracks.io.load_tracks`)."""
        from .io import load_tracks

        return load_tracks(path)


def load_shipped_dataset() -> Tracks:
    """The simulated highway dataset shipped inside the package (see :mod:`~iamp.prediction.tracks.io`)."""
    from .io import load_shipped_dataset as _load

    return _load()
