r"""``iamp evaluate-predictor --data FILE --format F`` (SPEC §13): the predictor on a user's data.

Windows: 3 s of history and 5 s of future, every second of every track long enough
(:func:`~iamp.prediction.windows.make_windows`).  Methods: ``cv``, ``ca`` (the
baselines), ``mtd`` (the MTD predictor, raw propagated trajectory) and ``fo`` (a first-order
chain with the same bins and step).  All four take their initial state from the same RTS
smoother (:mod:`iamp.prediction.initial_state`).

Held-out evaluation (``split``): ``"vehicle"`` puts a seeded 20 % of the tracks aside
(:meth:`Tracks.split_by_track`); ``"time"`` keeps the first 80 % of the recording's time span
for training and evaluates on the rest (every track cut at that instant).  The models are then
trained on the training part with the default configuration; without ``split`` the given
model (or the shipped one) is evaluated on the whole file and ``fo`` is trained on the shipped
data.

Uncertainty: windows of one track are correlated, so the 95 % intervals are percentile
intervals of a **track (cluster) bootstrap**: ``B`` resamples of the tracks with replacement,
each window weighted by its track's multiplicity, of

.. math::

    Δ_{\mathrm{RMSE}}(h) = \mathrm{RMSE}_{method}(h) - \mathrm{RMSE}_{cv}(h), \qquad
    Δ_{\mathrm{ADE}},\ Δ_{\mathrm{FDE}} \text{ likewise}.

Lateral motion: the planners assume every surrounding vehicle keeps its lateral position
(SPEC keeps ``y`` constant); ``lateral_rmse_m`` reports that assumption's error when the data
carry lateral positions.
"""

from __future__ import annotations

import os

import numpy as np

from iamp.prediction._typing import FloatArray, IntArray, Progress
from iamp.prediction.loaders.formats import load_with_report, ngsim_options
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.predictor import Predictor
from iamp.prediction.tracks.table import Tracks

from ..windows import (
    FUTURE_S,
    HORIZONS,
    Windows,
    baseline_ca,
    baseline_cv,
    lateral_constant,
    make_windows,
)
from .records import DiffToCV, UserEvaluation

__all__ = ["SPLITS", "evaluate_file", "split_by_time"]

#: ``--split`` choices.
SPLITS = ("vehicle", "time")
HELD_OUT_FRACTION = 0.2
BOOTSTRAP_RESAMPLES = 1000


def split_by_time(tracks: Tracks, train_fraction: float = 1.0 - HELD_OUT_FRACTION) -> tuple[Tracks, Tracks]:
    """``(train, test)``: rows before / after ``t_min + train_fraction (t_max - t_min)``."""
    cut = float(tracks.t.min() + train_fraction * (tracks.t.max() - tracks.t.min()))
    early = tracks.t <= cut
    meta = {**tracks.meta, "split": {"by": "time", "cut_s": cut}}
    return Tracks(tracks.track_id[early], tracks.t[early], tracks.x[early], tracks.v[early], tracks.a[early],
                  tracks.lane[early], tracks.dt, meta, None if tracks.y is None else tracks.y[early]), \
        tracks.select(~early)


def _errors(pred: FloatArray, win: Windows) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per window: squared errors at the horizons (W, H), mean |e| (W,), |e| at 5 s (W,)."""
    err = pred - win.X_fut
    cols = [int(np.argmin(np.abs(win.t_fut - h))) for h in HORIZONS]
    return err[:, cols] ** 2, np.mean(np.abs(err), axis=1), np.abs(err[:, -1])


def _track_sums(values: FloatArray, code: IntArray, n_tracks: int) -> FloatArray:
    """Per-track sums of per-window values (first axis)."""
    v = values.reshape(values.shape[0], -1)
    out = np.zeros((n_tracks, v.shape[1]))
    np.add.at(out, code, v)
    return out


def _bootstrap(errs: dict[str, tuple[FloatArray, FloatArray, FloatArray]], win: Windows, seed: int,
               resamples: int) -> dict[str, DiffToCV]:
    """Track-bootstrap 95 % intervals of every method's difference to ``cv`` (module docstring)."""
    _, code = np.unique(win.track_id, return_inverse=True)
    T = int(code.max()) + 1
    rng = np.random.default_rng(seed)
    weights = rng.multinomial(T, np.full(T, 1.0 / T), size=resamples).astype(float)  # (B, T)
    n_w = weights @ _track_sums(np.ones(win.n), code, T)  # (B, 1)

    def stats(e: tuple[FloatArray, FloatArray, FloatArray]) -> tuple[FloatArray, FloatArray, FloatArray]:
        sq, ade, fde = (weights @ _track_sums(x, code, T) / n_w for x in e)
        return np.sqrt(sq), ade[:, 0], fde[:, 0]

    base = stats(errs["cv"])
    out: dict[str, DiffToCV] = {}
    for name, e in errs.items():
        if name == "cv":
            continue
        rm, ad, fd = stats(e)
        d_rmse, d_ade, d_fde = rm - base[0], ad - base[1], fd - base[2]
        full_rmse = [float(np.sqrt(np.mean(e[0][:, k]))) - float(np.sqrt(np.mean(errs["cv"][0][:, k])))
                     for k in range(len(HORIZONS))]
        full_ade = float(np.mean(e[1]) - np.mean(errs["cv"][1]))
        full_fde = float(np.mean(e[2]) - np.mean(errs["cv"][2]))
        out[name] = {
            "rmse_m": [{"diff": full_rmse[k], "ci95": _ci(d_rmse[:, k])} for k in range(len(HORIZONS))],
            "ade_m": {"diff": full_ade, "ci95": _ci(d_ade)},
            "fde_m": {"diff": full_fde, "ci95": _ci(d_fde)},
        }
    return out


def _ci(x: FloatArray) -> list[float]:
    lo, hi = np.quantile(x, [0.025, 0.975])
    return [float(lo), float(hi)]


def evaluate_file(data: str | os.PathLike[str], fmt: str, *, model: str | None = None, split: str | None = None,
                  seed: int = 0, resamples: int = BOOTSTRAP_RESAMPLES, location: str | None = None,
                  progress: Progress | None = None, leader_model: str | None = None,
                  interaction: bool = True, units: str | None = None) -> UserEvaluation:
    """Evaluate CV, CA, MTD and the first-order chain on a data file (SPEC §13 JSON).

    Parameters
    ----------
    data, fmt
        The file and its format (``highd``, ``ngsim``, ``sumo``).
    model : str, optional
        A model file to evaluate (without ``split``); default the shipped model.
    split : {"vehicle", "time"}, optional
        Train on one part of the file, evaluate on the held-out part (module docstring).
    seed : int
        Seed of the vehicle split and of the bootstrap.
    resamples : int
        Bootstrap resamples.
    location : str, optional
        NGSIM only: keep the rows of this ``Location`` (e.g. ``"us-101"``, ``"i-80"``).
    progress : callable, optional
        ``progress(done, total)`` after each step.
    leader_model : str, optional
        A leader model file (``kind: "leader"``) to evaluate (without ``split``; default the
        shipped one).  With ``split`` a leader model is calibrated on the training part.
    interaction : bool
        Evaluate the leader-aware predictor and add the ``interaction`` section (module
        docstring of :mod:`~iamp.prediction.evaluation.leader`).
    units : {"feet", "metres"}, optional
        NGSIM only: the file's unit (default: detected from the data,
        :mod:`~iamp.prediction.loaders.units`).

    Returns
    -------
    dict
        ``data``, ``format``, ``tracks``, ``windows``, ``horizons_s``, ``rmse_m``/``ade_m``/``fde_m``
        per method, ``diff_to_cv`` (with bootstrap ``ci95``), ``lateral_rmse_m``, ``load_report``,
        ``split``, ``model``, ``jerk_psd``.
    """
    from iamp.prediction.tracks.table import load_shipped_dataset

    from .evaluate import DEFAULT_CONFIG
    from .select import ModelConfig, train_config

    total = 8
    step = 0

    def tick() -> None:
        nonlocal step
        step += 1
        if progress is not None:
            progress(step, total)

    if split is not None and split not in SPLITS:
        raise ValueError(f"split must be one of {', '.join(SPLITS)} (got {split!r})")
    if split is not None and (model is not None or leader_model is not None):
        raise ValueError("--model and --split exclude each other (--split trains the model on the file)")
    tracks, report = load_with_report([data], fmt, **ngsim_options(fmt, location, units))
    tick()
    test = tracks
    mtd: MTDModel
    train: Tracks | None = None
    if split is None:
        mtd = Predictor.from_file(model).model if model is not None else Predictor.default().model
        train_note = model if model is not None else "builtin"
        fo_data = load_shipped_dataset()
    else:
        train, test = (tracks.split_by_track(HELD_OUT_FRACTION, seed=seed) if split == "vehicle"
                       else split_by_time(tracks))
        mtd = train_config(train, DEFAULT_CONFIG)
        train_note = f"trained on the {split} split's training part ({train.n_tracks} tracks)"
        fo_data = train
    tick()
    assert mtd.dt is not None  # a predictor's model (Predictor checks it) or one trained here
    cfg: ModelConfig = {**DEFAULT_CONFIG, "dt": mtd.dt,
                        "jerk_psd": float(mtd.settings.get("jerk_psd", DEFAULT_CONFIG["jerk_psd"]))}
    if mtd.edges is not None and mtd.edges.size > 1:
        cfg["width"] = float(np.diff(mtd.edges).mean())
    try:
        fo = train_config(fo_data, cfg, order=1)
    except ValueError as exc:
        raise ValueError(f"the first-order baseline is trained at the model's dt: {exc}") from None
    tick()
    win = make_windows(test)
    q = float(cfg["jerk_psd"])
    preds = {"cv": baseline_cv(win, q), "ca": baseline_ca(win, q)}
    tick()
    preds["mtd"] = Predictor(mtd, "mtd").predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S)
    tick()
    preds["fo"] = Predictor(fo, "fo").predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S)
    tick()
    inter = None
    if interaction:
        from iamp.prediction.evaluation.leader import interaction_section

        inter, extra = interaction_section(data, fmt, tracks, test, train, win, mtd, preds, leader_model=leader_model,
                                           split=split, seed=seed, resamples=resamples)
        preds.update(extra)
    tick()
    errs = {k: _errors(p, win) for k, p in preds.items()}
    lat = lateral_constant(win)
    lateral = None
    if lat is not None and win.Y_fut is not None:
        e = lat - win.Y_fut
        cols = [int(np.argmin(np.abs(win.t_fut - h))) for h in HORIZONS]
        lateral = {"constant_y": [float(np.sqrt(np.mean(e[:, c] ** 2))) for c in cols]}
    out: UserEvaluation = {
        "data": os.fspath(data), "format": fmt, "tracks": int(test.n_tracks), "windows": int(win.n),
        "horizons_s": [float(h) for h in HORIZONS],
        "rmse_m": {k: [float(np.sqrt(np.mean(e[0][:, c]))) for c in range(len(HORIZONS))] for k, e in errs.items()},
        "ade_m": {k: float(np.mean(e[1])) for k, e in errs.items()},
        "fde_m": {k: float(np.mean(e[2])) for k, e in errs.items()},
        "lateral_rmse_m": lateral,
        "lateral_assumption": "the planners keep every surrounding vehicle at its lateral position (y constant)",
        "diff_to_cv": _bootstrap(errs, win, seed, resamples),
        "bootstrap": {"resamples": resamples, "by": "track (cluster)", "seed": seed, "interval": "percentile 95 %"},
        "split": split, "seed": seed, "model": train_note, "jerk_psd": q,
        "load_report": report.to_dict(),
    }
    if inter is not None:
        out["interaction"] = dict(inter)
    tick()
    return out
