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
* Derived from lateral and longitudinal position where the lane numbers are unusable
  (issue 29 item 5): every row's lane unknown (NGSIM's ``Lane_ID = 0``), or lane numbers that
  do not separate lanes (more than :data:`LANE_MISMATCH_MAX` of the leaders they give are a
  lane or more to the side, ``|Δy| >=`` :data:`SAME_LANE_TOL_M`; 4 % on US-101 with its lanes,
  97 % with ``Lane_ID = 0``).  The leader is then the nearest vehicle ahead at the same instant
  with ``|y_l - y_f| <`` :data:`SAME_LANE_TOL_M` (half a 3.5-m lane: the rule
  :func:`~iamp.prediction.leader.model.scenario_leaders` applies to a scenario).  Without
  lateral positions no leader is derived (the source says why): the leader-aware predictor then
  is its fallback.

Whatever the source, a window's leader is used only if it is ahead over the whole history
(:func:`~iamp.prediction.leader.windows.leader_windows`).
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

__all__ = ["DEFAULT_LENGTH_M", "LANE_MISMATCH_MAX", "SAME_LANE_TOL_M", "Leaders", "derive_leaders",
           "lateral_leaders", "ngsim_leaders"]

#: Length assumed for a vehicle of unknown length [m] (a passenger car).
DEFAULT_LENGTH_M = 4.5
#: Two vehicles share a lane when their lateral positions differ by less than this [m] (half a 3.5-m lane).
SAME_LANE_TOL_M = 1.75
#: Largest share of lane-number leaders a lane or more to the side for the lane numbers to count as usable.
LANE_MISMATCH_MAX = 0.25


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


def _lane_leaders(tracks: Tracks) -> IntArray:
    """Per row: the next vehicle ahead at the same instant with the same lane number (``-1``: none)."""
    n = len(tracks)
    frame = _frame_keys(tracks)
    order = np.lexsort((tracks.x, tracks.lane, frame))
    f, ln = frame[order], tracks.lane[order]
    same = (f[1:] == f[:-1]) & (ln[1:] == ln[:-1])
    leader = np.full(n, -1, dtype=np.int64)
    leader[order[:-1][same]] = tracks.track_id[order[1:][same]]
    # a vehicle cannot lead itself (two rows of one track at one instant do not occur in a valid table)
    leader[leader == tracks.track_id] = -1
    return leader


def lateral_leaders(tracks: Tracks, tol: float = SAME_LANE_TOL_M) -> IntArray:
    """Per row: the nearest vehicle strictly ahead at the same instant with ``|y_l - y_f| < tol`` (``-1``: none).

    Parameters
    ----------
    tracks : Tracks
        With lateral positions ``y`` in one road frame per instant.
    tol : float
        Lateral tolerance [m].

    Returns
    -------
    numpy.ndarray of int64, shape (N,)
        The leader's track id per row.

    Raises
    ------
    TrackDataError
        When ``tracks`` has no lateral positions.
    """
    if tracks.y is None:
        raise TrackDataError("no lateral positions to find lanes by", column="y")
    frame = _frame_keys(tracks)
    order = np.lexsort((tracks.x, frame))
    f, x, y, tid = frame[order], tracks.x[order], tracks.y[order], tracks.track_id[order]
    n = order.size
    lead = np.full(n, -1, dtype=np.int64)
    active = np.arange(n)
    k = 1
    while active.size:  # the k-th next vehicle in x at the same instant, until each row has one or none is left
        j = active + k
        inside = j < n
        active, j = active[inside], j[inside]
        same = f[j] == f[active]
        active, j = active[same], j[same]
        hit = (np.abs(y[j] - y[active]) < tol) & (x[j] > x[active]) & (tid[j] != tid[active])
        lead[active[hit]] = tid[j[hit]]
        active = active[~hit]
        k += 1
    out = np.full(n, -1, dtype=np.int64)
    out[order] = lead
    return out


def _unusable_lanes(tracks: Tracks, by_lane: IntArray, unknown_lane: int | None) -> str | None:
    """Why the lane numbers cannot say who follows whom (``None``: they can); module docstring."""
    if unknown_lane is not None and tracks.lane.size and np.all(tracks.lane == unknown_lane):
        return f"the lane number is {unknown_lane} (unknown) in every row"
    if tracks.y is None:
        return None
    i = np.flatnonzero(by_lane >= 0)
    if i.size == 0:
        return None
    frame = _frame_keys(tracks)
    key = tracks.track_id * 100_000_000 + frame
    order = np.argsort(key, kind="stable")
    j = order[np.searchsorted(key[order], by_lane[i] * 100_000_000 + frame[i])]
    share = float(np.mean(np.abs(tracks.y[j] - tracks.y[i]) >= SAME_LANE_TOL_M))
    if share > LANE_MISMATCH_MAX:
        return (f"{100 * share:.0f} % of the leaders by lane number are a lane or more to the side "
                f"(|dy| >= {SAME_LANE_TOL_M:g} m): the lane numbers do not separate lanes")
    return None


def derive_leaders(tracks: Tracks, length: FloatArray | None = None, unknown_lane: int | None = None) -> Leaders:
    """Leaders from lane (or lateral position) and position per instant (module docstring).

    Parameters
    ----------
    tracks : Tracks
        Positions must share one road frame at each instant (true within one NGSIM
        recording window, one SUMO run, one synthetic platoon).
    length : array of shape (N,), optional
        Vehicle length per row (NaN unknown).
    unknown_lane : int, optional
        The lane number that means "unknown" (NGSIM: 0); a table with it in every row has no
        usable lane numbers.

    Returns
    -------
    Leaders
        ``source`` says how they were found, and why lateral positions were used or no leader was
        derived.
    """
    n = len(tracks)
    lens = np.full(n, np.nan) if length is None else np.asarray(length, dtype=float)
    by_lane = _lane_leaders(tracks)
    why = _unusable_lanes(tracks, by_lane, unknown_lane)
    if why is None:
        return Leaders(by_lane, lens, "derived from lane and position")
    if tracks.y is None:
        return Leaders(np.full(n, -1, dtype=np.int64), lens,
                       f"none: {why} and there are no lateral positions to find lanes by (the leader-aware "
                       "predictor is its fallback)")
    return Leaders(lateral_leaders(tracks), lens,
                   f"derived from lateral position (|dy| < {SAME_LANE_TOL_M:g} m) and position, since {why}")


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
        out = derive_leaders(tracks, length, unknown_lane=0)  # NGSIM: Lane_ID 0 = unknown
        return Leaders(out.leader, length, f"{out.source} (no Preceding column or all 0)")
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
