"""Leader data of prediction windows (a window's leader history and future in its frame).

The windows are :func:`~iamp.prediction.windows.make_windows`'s; the leaders
:class:`~iamp.prediction.leader.leaders.Leaders`.  Used to calibrate a car-following law on
trajectories (:func:`~iamp.prediction.leader.model.train_leader_model`) and by the evaluation.

A window's leader (the follower's leader at ``t = 0``, in the same lane then: by lane number, by
NGSIM's ``Preceding``, or by lateral position, :mod:`~iamp.prediction.leader.leaders`) is *known*
only if it is consistent over the whole 3-s history (issue 29 item 5): its track covers the
history and it is **ahead** at every history sample (bumper-to-bumper gap
``x_l - x_f - (L_l + L_f)/2 > 0``).  A leader that fails is counted in ``rejected`` and the window
is predicted by the fallback.  The lane is checked at ``t = 0`` only, not over the history: a
vehicle that cut in during the history is the one the follower reacts to (on 200 US-101 vehicles,
requiring ``|y_l - y_f| < 1.75 m`` at every history sample refused 39 of 244 ``Preceding``
leaders and raised the leader model's RMSE at 5 s from 6.33 to 6.44 m; without lane numbers,
from 6.43 to 6.53 m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from iamp.prediction._typing import BoolArray, FloatArray
from iamp.prediction.tracks import Tracks
from iamp.prediction.windows import Windows

from .leaders import Leaders

__all__ = ["LeaderWindows", "leader_windows"]


@dataclass(frozen=True)
class LeaderWindows:
    """Leader data of evaluation windows, in each window's frame (follower at 0 at ``t = 0``).

    Attributes
    ----------
    known : (W,) bool
    XL_hist : (W, K) leader positions at the history times (NaN where unknown)
    XL_fut : (W, F) leader positions at the future times (NaN where unknown)
    offset : (W,) ``(L_l + L_f)/2`` [m]
    future_extended : (W,) bool, the oracle future continues at the last recorded speed
    rejected : (W,) bool, a leader was named but is not ahead over the whole history
    """

    known: BoolArray
    XL_hist: FloatArray
    XL_fut: FloatArray
    offset: FloatArray
    future_extended: BoolArray
    rejected: BoolArray


def leader_windows(tracks: Tracks, leaders: Leaders, win: Windows) -> LeaderWindows:
    """The leaders of ``win`` (made by :func:`~iamp.prediction.windows.make_windows` of ``tracks``)."""
    if win.t0 is None:
        raise ValueError("windows without t0")
    W, K, F = win.n, win.t_hist.size, win.t_fut.size
    XLh = np.full((W, K), np.nan)
    XLf = np.full((W, F), np.nan)
    known = np.zeros(W, dtype=bool)
    ext = np.zeros(W, dtype=bool)
    rejected = np.zeros(W, dtype=bool)
    off = np.full(W, np.nan)
    ids = tracks.ids()
    cuts = np.flatnonzero(np.diff(tracks.track_id)) + 1
    starts = np.concatenate(([0], cuts))
    ends = np.concatenate((cuts, [len(tracks)]))
    L = leaders.lengths()
    eps = 1e-6
    for w in range(W):
        k = int(np.searchsorted(ids, win.track_id[w]))
        s, e = starts[k], ends[k]
        t = tracks.t[s:e]
        t0 = float(win.t0[w])
        r = s + int(np.argmin(np.abs(t - t0)))
        lid = int(leaders.leader[r])
        if lid < 0:
            continue
        j = int(np.searchsorted(ids, lid))
        if j >= ids.size or ids[j] != lid:
            continue
        ls, le = starts[j], ends[j]
        tl, xl = tracks.t[ls:le], tracks.x[ls:le]
        if tl[0] > t0 + win.t_hist[0] + eps or tl[-1] < t0 - eps:
            continue
        xf0 = float(np.interp(t0, t, tracks.x[s:e]))
        th = t0 + win.t_hist
        xlh = np.interp(th, tl, xl) - xf0
        o = 0.5 * (L[r] + L[ls + int(np.argmin(np.abs(tl - t0)))])
        if not np.all(xlh - (np.interp(th, t, tracks.x[s:e]) - xf0) - o > 0.0):  # not ahead over the history
            rejected[w] = True
            continue
        known[w] = True
        XLh[w] = xlh
        tf = t0 + win.t_fut
        fut = np.interp(tf, tl, xl) - xf0
        beyond = tf > tl[-1] + eps
        if np.any(beyond):
            ext[w] = True
            vlast = (xl[-1] - xl[-2]) / (tl[-1] - tl[-2]) if tl.size > 1 else 0.0
            fut[beyond] = xl[-1] - xf0 + max(vlast, 0.0) * (tf[beyond] - tl[-1])
        XLf[w] = fut
        off[w] = o
    return LeaderWindows(known, XLh, XLf, np.where(np.isfinite(off), off, 4.5), ext, rejected)
