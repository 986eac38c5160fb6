r"""Training the predictor's MTD model on a :class:`~iamp.prediction.tracks.table.Tracks` table.

The chain's state is the central second difference of the positions linearly resampled to
the model step ``Δt``, ``a_k = (x_{k+1} - 2 x_k + x_{k-1}) / Δt²``, binned by interior edges
(:func:`symmetric_edges`); each state's representative value is the mean training ``a_k`` in
its bin (:func:`bin_centres`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from iamp.prediction._typing import FloatArray
from iamp.prediction.initial_state import DEFAULT_JERK_PSD
from iamp.prediction.kinematics import second_differences
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.tracks.table import Tracks

__all__ = ["STATE_DEFINITION", "bin_centres", "symmetric_edges", "track_accelerations", "train_from_tracks"]

#: Written into trained models.
STATE_DEFINITION = ("longitudinal acceleration a_k = (x_{k+1} - 2 x_k + x_{k-1}) / dt^2 of the positions "
                    "linearly resampled to the model step dt [m/s^2]")


def symmetric_edges(width: float, a_max: float) -> np.ndarray:
    """Interior edges of bins of ``width`` centred on 0: ``±width/2, ±3width/2, …``.

    The outer bins are open: everything below ``-a_max`` / above ``a_max`` (rounded to the
    bin grid) falls into the first / last bin.  The number of bins is
    ``2·round(a_max/width) + 1`` (odd, with a bin centred on 0).
    """
    K = int(round(a_max / width))
    if K < 1:
        raise ValueError("a_max must be at least one bin width")
    return width * (np.arange(-K, K) + 0.5)


#: Most resampled states a training run builds (a few hundred MB at its peak; a model with the
#: smallest legal ``dt`` would resample hours of tracks to ~10^8 states otherwise).
TRAIN_STATES_MAX = 10_000_000


def track_accelerations(tracks: Tracks, dt: float) -> list[FloatArray]:
    """State values ``a_k`` of every track, computed as the predictor does.

    Each track's positions are linearly resampled onto ``t0 + k·dt`` and differenced
    (:func:`second_differences`); tracks with fewer than 3 resampled samples are skipped.
    """
    total = sum(int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
                for _tid, t, *_ in tracks.iter_tracks() if t.size >= 2)
    if total > TRAIN_STATES_MAX:
        span = sum(float(t[-1] - t[0]) for _tid, t, *_ in tracks.iter_tracks() if t.size >= 2)
        raise ValueError(f"a chain step dt = {dt:g} s resamples the {span:.6g} s of tracks to {total:,} states "
                         "(at most "
                         f"{TRAIN_STATES_MAX:,}: memory); use dt >= {span / TRAIN_STATES_MAX:.3g} s or less data")
    out = []
    for _tid, t, x, *_ in tracks.iter_tracks():
        if t.size < 2:
            continue
        K = int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
        if K < 3:
            continue
        out.append(second_differences(np.interp(t[0] + dt * np.arange(K), t, x), dt))
    return out


def bin_centres(accels: list[np.ndarray], edges: np.ndarray) -> np.ndarray:
    """Mean value within every bin (the bin's midpoint, or edge ± width/2, when empty)."""
    a = np.concatenate(accels) if accels else np.zeros(0)
    m = edges.size + 1
    s = np.searchsorted(edges, a, side="right")
    cnt = np.bincount(s, minlength=m)
    tot = np.bincount(s, weights=a, minlength=m)
    width = float(np.diff(edges).mean()) if edges.size > 1 else 1.0
    mid = np.r_[edges[0] - width / 2, 0.5 * (edges[:-1] + edges[1:]), edges[-1] + width / 2]
    return np.where(cnt > 0, tot / np.maximum(cnt, 1), mid)


def train_from_tracks(tracks: Tracks, *, dt: float, edges: ArrayLike, order: int, estimator: str = "mle",
                      jerk_psd: float = DEFAULT_JERK_PSD, provenance: Mapping[str, object] | None = None,
                      **fit_kwargs: Any) -> MTDModel:
    """Train an MTD acceleration model on a :class:`~iamp.prediction.tracks.table.Tracks` table.

    Parameters
    ----------
    tracks : Tracks
        Recorded trajectories (only ``t`` and ``x`` are used, so that the states are
        computed exactly as from an observed history).
    dt : float
        Chain time step [s].
    edges : array_like
        Interior acceleration bin edges [m/s²] (see :func:`symmetric_edges`).
    order : int
        Chain order ``n``.
    estimator : {"mle", "mle-lambda", "lp"}
    jerk_psd : float
        ``q`` of the predictor's initial-state smoother [m²/s⁵], stored in ``model.settings``.
    provenance : dict, optional
        Merged into the model's provenance (with the data's ``meta`` and sizes).
    **fit_kwargs
        Passed to :func:`iamp.prediction.mtd.fit`.

    Returns
    -------
    MTDModel
        With ``centres`` the mean training ``a_k`` per bin.
    """
    from iamp.prediction.mtd.estimation import fit

    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be positive (got {dt})")
    edges = np.asarray(edges, dtype=float)
    accels = track_accelerations(tracks, dt)
    if not accels or sum(a.size for a in accels) <= order:
        raise ValueError(f"no track is long enough to train an order-{order} chain at dt = {dt:g} s")
    seqs = [np.searchsorted(edges, a, side="right") for a in accels]
    meta = getattr(tracks, "meta", {})
    prov = {"data_meta": _jsonable({k: v for k, v in meta.items() if k != "source_ids"} if isinstance(meta, dict)
                                   else meta),
            "n_tracks_used": len(seqs), "n_states_observed": int(sum(s.size for s in seqs))}
    prov.update(provenance or {})
    return fit(seqs, edges.size + 1, order, estimator, edges=edges, centres=bin_centres(accels, edges),
               dt=dt, state=STATE_DEFINITION, settings={"jerk_psd": float(jerk_psd)}, provenance=prov,
               **fit_kwargs)


def _jsonable(obj: object) -> object:
    try:
        json.dumps(obj, allow_nan=False)
        return obj
    except (TypeError, ValueError):
        return str(obj)
