r"""Who follows whom: the leader of every row of a :class:`~iamp.prediction.tracks.Tracks` table.

A :class:`Leaders` table is aligned with the rows of a ``Tracks`` table: ``leader[r]`` is the
track id of the vehicle ahead in the same lane at the instant of row ``r`` (``-1``: none
known), ``length[r]`` the length of the vehicle of row ``r`` [m] (NaN: unknown).  The
bumper-to-bumper gap of a follower ``f`` behind its leader ``l`` at a common instant is

.. math::

    s = x_l - x_f - \tfrac12 (L_l + L_f),

with ``x`` the centre positions of the table (same road frame; NGSIM's ``Local_Y`` is the
front bumper, the loader's centre is ``Local_Y - L/2``).  An unknown length counts as
:data:`DEFAULT_LENGTH_M`.

Sources
-------
* NGSIM's ``Preceding`` column (:func:`ngsim_leaders`): the ``Vehicle_ID`` ahead, 0 for none.
  The US-101 CSV in ``../shared/data`` has it (83 % of rows have a leader; the column was
  built from lane and position per frame, see its ``PROVENANCE.txt``).
* Derived from lane and position per instant (:func:`derive_leaders`) where the column is
  missing or 0 everywhere: at each time (rounded to the sampling period) and lane, the
  vehicles are sorted by ``x`` and each one's leader is the next one ahead (any distance).
  On the US-101 CSV the derived leader equals ``Preceding`` on the rows measured in the
  tests (``tests/test_leader.py``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from iamp.prediction._typing import FloatArray, IntArray, PathLike
from iamp.prediction.loaders.csv import _integers, _path, read_csv
from iamp.prediction.loaders.ngsim import FEET
from iamp.prediction.loaders.units import UNITS
from iamp.prediction.tracks import TrackDataError, Tracks

__all__ = ["DEFAULT_LENGTH_M", "Leaders", "derive_leaders", "ngsim_leaders"]

#: Length assumed for a vehicle of unknown length [m] (a passenger car).
DEFAULT_LENGTH_M = 4.5


@dataclass(frozen=True)
class Leaders:
    """Leader track id and own length per row of a ``Tracks`` table (module docstring).

    Attributes
    ----------
    leader : numpy.ndarray of int64, shape (N,)
        Track id of the leader (``-1``: none known).
    length : numpy.ndarray of float64, shape (N,)
        Length of the row's vehicle [m] (NaN: unknown).
    source : str
        ``"Preceding column"`` or ``"derived from lane and position"`` (or a caller's label).
    """

    leader: IntArray
    length: FloatArray
    source: str

    def __post_init__(self) -> None:
        if self.leader.shape != self.length.shape or self.leader.ndim != 1:
            raise TrackDataError("leader and length must be 1-D arrays of equal length", column="leader")

    @property
    def known_fraction(self) -> float:
        """Share of rows with a known leader."""
        return float(np.mean(self.leader >= 0)) if self.leader.size else 0.0

    def lengths(self) -> FloatArray:
        """``length`` with unknown values replaced by :data:`DEFAULT_LENGTH_M`."""
        out: FloatArray = np.where(np.isfinite(self.length) & (self.length > 0), self.length, DEFAULT_LENGTH_M)
        return out


def _frame_keys(tracks: Tracks) -> IntArray:
    """Integer time index of every row (``round(t / dt)``): rows of one instant share it."""
    out: IntArray = np.round(tracks.t / tracks.dt).astype(np.int64)
    return out


def derive_leaders(tracks: Tracks, length: FloatArray | None = None) -> Leaders:
    """Leaders from lane and position per instant (module docstring).

    Parameters
    ----------
    tracks : Tracks
        Positions must share one road frame at each instant (true within one NGSIM
        recording window, one SUMO run, one synthetic platoon).
    length : array of shape (N,), optional
        Vehicle length per row (NaN unknown).
    """
    n = len(tracks)
    frame = _frame_keys(tracks)
    order = np.lexsort((tracks.x, tracks.lane, frame))
    f, ln = frame[order], tracks.lane[order]
    same = (f[1:] == f[:-1]) & (ln[1:] == ln[:-1])
    leader = np.full(n, -1, dtype=np.int64)
    leader[order[:-1][same]] = tracks.track_id[order[1:][same]]
    # a vehicle cannot lead itself (two rows of one track at one instant do not occur in a valid table)
    leader[leader == tracks.track_id] = -1
    lens = np.full(n, np.nan) if length is None else np.asarray(length, dtype=float)
    return Leaders(leader, lens, "derived from lane and position")


_SPEC = (
    ("Vehicle_ID", ("Vehicle_ID",), True),
    ("Frame_ID", ("Frame_ID",), True),
    ("Preceding", ("Preceding",), False),
    ("v_length", ("v_length", "v_Length"), False),
)


def ngsim_leaders(path: str | os.PathLike[str], tracks: Tracks) -> Leaders:
    """Leaders of an NGSIM table from its file's ``Preceding`` column (module docstring).

    ``tracks`` must be :func:`~iamp.prediction.loaders.ngsim.load_ngsim` of the same file (its
    ``meta["source_ids"]`` maps tracks to ``(Vehicle_ID, first Frame_ID)``).  Falls back to
    :func:`derive_leaders` when the column is absent or 0 in every row.
    """
    p = _path(path)
    first = ""
    from iamp.prediction.loaders.csv import _open_text

    with _open_text(p) as fh:
        first = fh.readline()
    if "," not in first and ";" not in first:
        raise TrackDataError("leaders need the NGSIM CSV layout with a header line", source=p)
    cols = read_csv(p, _SPEC, delimiter=";" if first.count(";") > first.count(",") else ",")
    vid = _integers(cols["Vehicle_ID"], "Vehicle_ID", p)
    frame = _integers(cols["Frame_ID"], "Frame_ID", p)
    ids = tracks.meta.get("source_ids")
    if not isinstance(ids, list) or len(ids) != tracks.n_tracks:
        raise TrackDataError("the table was not loaded by load_ngsim (no source_ids)", column="meta", source=p)
    # (vehicle, frame) -> row of the table
    tframe = _frame_keys(tracks)
    track_vid = np.empty(tracks.n_tracks, dtype=np.int64)
    for k, (_loc, v, _f0) in enumerate(ids):
        track_vid[k] = int(v)
    tid_index = np.searchsorted(tracks.ids(), tracks.track_id)
    row_vid = track_vid[tid_index]
    key_rows = row_vid * 10_000_000 + tframe
    order = np.argsort(key_rows, kind="stable")
    sorted_keys = key_rows[order]

    def rows_of(v: IntArray, fr: IntArray) -> IntArray:
        k = v * 10_000_000 + fr
        pos = np.clip(np.searchsorted(sorted_keys, k), 0, sorted_keys.size - 1)
        out: IntArray = np.where(sorted_keys[pos] == k, order[pos], -1)
        return out

    length = np.full(len(tracks), np.nan)
    if "v_length" in cols:
        r = rows_of(vid, frame)
        ok = r >= 0
        factor = UNITS.get(str(tracks.meta.get("units", "feet")), FEET)  # the loader's unit decision
        length[r[ok]] = np.asarray(cols["v_length"], dtype=float)[ok] * factor
    if "Preceding" not in cols or not np.any(np.asarray(cols["Preceding"]) > 0):
        out = derive_leaders(tracks, length)
        return Leaders(out.leader, length, "derived from lane and position (no Preceding column or all 0)")
    prec = _integers(cols["Preceding"], "Preceding", p)
    r = rows_of(vid, frame)
    lr = rows_of(prec, frame)  # the leader's row at the same frame
    leader = np.full(len(tracks), -1, dtype=np.int64)
    ok = (r >= 0) & (prec > 0) & (lr >= 0)
    leader[r[ok]] = tracks.track_id[lr[ok]]
    return Leaders(leader, length, "Preceding column")


def leaders_for(path: PathLike, fmt: str, tracks: Tracks) -> Leaders:
    """The leaders of a loaded file: NGSIM's ``Preceding``, else derived from lane and position."""
    if fmt == "ngsim":
        try:
            return ngsim_leaders(path, tracks)
        except TrackDataError:
            pass
    return derive_leaders(tracks)
