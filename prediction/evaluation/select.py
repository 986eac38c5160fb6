"""Model selection on validation windows: the grid over the chain step, bin width and order.

The chain step ``Δt ∈ {0.1, 0.2, 0.5, 1.0}`` s, the bin width ``∈ {0.25, 0.5, 1.0}`` m/s² (bins
centred on 0 over ±3 m/s², outer bins open) and the order ``n ∈ 1..5`` with
``(n + 1) Δt <= 3`` s are chosen by the mean over ``h = 1..5`` s of the validation RMSE of the
MTD prediction, among the configurations whose bins are at least two acceleration quanta
``r/Δt²`` wide (:func:`eligible`).  The jerk spectral density of the initial-state smoother
is chosen first, on the constant-velocity baseline.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import NotRequired, TypedDict

import numpy as np

from iamp.prediction.initial_state import DEFAULT_JERK_PSD
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.predictor import Predictor
from iamp.prediction.tracks.table import Tracks
from iamp.prediction.training import symmetric_edges, train_from_tracks

from ..windows import (
    FUTURE_S,
    HISTORY_S,
    WindowMetrics,
    Windows,
    baseline_ca,
    baseline_cv,
    make_windows,
    metrics,
)

__all__ = ["A_MAX", "GRID_DT", "GRID_JERK_PSD", "GRID_ORDER", "GRID_WIDTH", "NOISE_LEVELS_M", "choose_jerk_psd",
           "eligible", "position_resolution", "select_model", "train_config"]

GRID_DT = (0.1, 0.2, 0.5, 1.0)
GRID_WIDTH = (0.25, 0.5, 1.0)
GRID_ORDER = (1, 2, 3, 4, 5)
#: Jerk spectral densities [m²/s⁵] of the initial-state smoother tried on validation.
GRID_JERK_PSD = (1.0, 3.0, 10.0, 30.0, 100.0)
#: Position noise [m] added to validation windows when choosing the jerk spectral density.
NOISE_LEVELS_M = (0.0, 0.03, 0.1)
A_MAX = 3.0


class ModelConfig(TypedDict):
    """A model configuration: chain step [s], bin width and range [m/s²], order, smoother jerk
    spectral density [m²/s⁵] and estimator (:func:`train_config`)."""

    dt: float
    width: float
    order: int
    a_max: NotRequired[float]
    jerk_psd: NotRequired[float]
    estimator: NotRequired[str]


class _GridConfig(TypedDict):
    """A configuration of the selection grid (every key of :class:`ModelConfig` but the estimator)."""

    dt: float
    width: float
    order: int
    a_max: float
    jerk_psd: float


#: A configuration of the selection grid scored on validation (functional form: ``lambda`` is a
#: keyword); :data:`SelectionRow` adds whether the selection rule admits it.
ScoredConfig = TypedDict("ScoredConfig", {
    "dt": float, "width": float, "order": int, "a_max": float, "jerk_psd": float, "n_states": int,
    "val": WindowMetrics, "val_cubic": WindowMetrics, "loglik": float, "n_obs": int, "n_parameters": int,
    "aic": float, "bic": float, "lambda": list[float], "fit_seconds": float})
#: One row of the selection grid (:func:`select_model`).
SelectionRow = TypedDict("SelectionRow", {
    "dt": float, "width": float, "order": int, "a_max": float, "jerk_psd": float, "n_states": int,
    "val": WindowMetrics, "val_cubic": WindowMetrics, "loglik": float, "n_obs": int, "n_parameters": int,
    "aic": float, "bic": float, "lambda": list[float], "fit_seconds": float, "eligible": bool,
    "excluded_because": str})


class JerkPsdSelection(TypedDict):
    """How :func:`choose_jerk_psd` chose ``q``: the validation CV RMSE per ``q`` and noise level."""

    criterion: str
    noise_m: list[float]
    rmse_mean: dict[str, list[float]]
    score: dict[str, float]


class Selection(TypedDict):
    """:func:`select_model`'s grid search and choice."""

    criterion: str
    n_val_windows: int
    position_resolution_m: float | None
    rows: list[SelectionRow]
    baselines: dict[str, dict[str, WindowMetrics]]
    jerk_psd: float
    jerk_psd_selection: JerkPsdSelection
    chosen: ModelConfig
    best_overall: ModelConfig


def train_config(tracks: Tracks, cfg: ModelConfig | _GridConfig, estimator: str | None = None, order: int | None = None,
                 provenance: Mapping[str, object] | None = None) -> MTDModel:
    """Train the MTD model of a configuration ``{"dt", "width", "order", "a_max", "jerk_psd", "estimator"}``."""
    return train_from_tracks(tracks, dt=cfg["dt"], edges=symmetric_edges(cfg["width"], cfg.get("a_max", A_MAX)),
                             order=order or cfg["order"], estimator=estimator or str(cfg.get("estimator", "mle")),
                             jerk_psd=cfg.get("jerk_psd", DEFAULT_JERK_PSD), provenance=provenance)


def position_resolution(tracks: Tracks) -> float | None:
    """The rounding step of the recorded positions (``10^-d`` m), or ``None`` if finer than 1 µm."""
    x = np.asarray(tracks.x, dtype=float)
    for d in range(7):
        scaled = x * 10.0 ** d
        if np.all(np.abs(scaled - np.round(scaled)) < 1e-6 * np.maximum(1.0, np.abs(scaled) * 1e-9)):
            return 10.0 ** -d
    return None


def eligible(cfg: ModelConfig | _GridConfig, resolution: float | None) -> tuple[bool, str]:
    """Selection rule: bins must be at least two acceleration quanta ``r/Δt²`` wide.

    Rounding positions to ``r`` makes ``a_k`` a multiple of ``r/Δt²``; narrower bins hold a
    single quantisation level each and leave the bins in between empty, so a model with them
    cannot handle a history whose accelerations fall between the levels (e.g. the paper's
    clean histories).
    """
    if resolution is None:
        return True, ""
    quantum = resolution / cfg["dt"] ** 2
    if cfg["width"] < 2.0 * quantum - 1e-12:
        return False, (f"bins of {cfg['width']:g} m/s^2 are narrower than two acceleration quanta "
                       f"(r/dt^2 = {quantum:g} m/s^2 for r = {resolution:g} m)")
    return True, ""


def choose_jerk_psd(win: Windows, grid: tuple[float, ...] = GRID_JERK_PSD,
                    noise_m: tuple[float, ...] = NOISE_LEVELS_M, seed: int = 0) -> tuple[float, JerkPsdSelection]:
    r"""The smoother's jerk spectral density ``q``, chosen on validation windows.

    Criterion: the constant-velocity RMSE (mean over ``h = 1..5`` s), averaged over the windows
    as recorded and with white position noise of each standard deviation in ``noise_m`` added
    (seeded), so that ``q`` suits clean and noisy data alike (the noise level itself is
    estimated per history, :func:`~iamp.prediction.initial_state.noise_sigma`).

    Returns ``(q, {"criterion", "noise_m", "rmse_mean": {q: [per noise level]}, "score": {q: mean}})``.
    """
    rng = np.random.default_rng(seed)
    noisy = [win if s == 0 else Windows(win.t_hist, win.X_hist + rng.normal(0.0, s, win.X_hist.shape), win.t_fut,
                                        win.X_fut, win.track_id) for s in noise_m]
    table = {f"{q:g}": [metrics(baseline_cv(w, q), w)["rmse_mean"] for w in noisy] for q in grid}
    score = {k: float(np.mean(v)) for k, v in table.items()}
    best = min(score, key=lambda k: score[k])
    return float(best), {"criterion": "mean over noise levels of the validation CV RMSE (mean over 1..5 s)",
                         "noise_m": list(noise_m), "rmse_mean": table, "score": score}


def select_model(train: Tracks, val: Tracks, *, grid_dt: tuple[float, ...] = GRID_DT,
                 grid_width: tuple[float, ...] = GRID_WIDTH, grid_order: tuple[int, ...] = GRID_ORDER,
                 estimator: str = "mle", history_s: float = HISTORY_S,
                 resolution: float | str | None = "auto") -> Selection:
    """Grid search on the validation windows; returns the table and the chosen config.

    1. The jerk spectral density ``q`` of the initial-state smoother is chosen on the
       validation windows by the constant-velocity RMSE (every method then uses it, so that
       MTD and CV differ only in the acceleration model).
    2. Every configuration with ``(n + 1) Δt <= history_s`` is fitted on ``train`` and scored
       on ``val``.  The choice is the best *eligible* one (:func:`eligible`, with the position
       resolution of the data); the best overall is reported too.

    Returns
    -------
    dict
        ``{"criterion", "n_val_windows", "rows": [...], "baselines": {...}, "jerk_psd",
        "position_resolution_m", "chosen": cfg, "best_overall": cfg}``; every row has the
        configuration, its eligibility, the validation metrics of ``mtd`` and ``mtd-cubic``,
        and the training log-likelihood, N, k, AIC and BIC.
    """
    win = make_windows(val)
    res_m = position_resolution(train) if resolution == "auto" else resolution
    assert res_m is None or isinstance(res_m, float | int), "resolution: 'auto', a step in metres or None"
    baselines = {name: {f"{q:g}": metrics(fn(win, q), win) for q in GRID_JERK_PSD}
                 for name, fn in (("cv", baseline_cv), ("ca", baseline_ca))}
    q_cv, q_table = choose_jerk_psd(win)
    rows: list[SelectionRow] = []
    for dt in grid_dt:
        for width in grid_width:
            for order in grid_order:
                if (order + 1) * dt > history_s + 1e-9:
                    continue
                cfg: _GridConfig = {"dt": dt, "width": width, "order": order, "a_max": A_MAX, "jerk_psd": q_cv}
                ok, why = eligible(cfg, res_m)
                rows.append({**_selection_row(train, win, cfg, estimator), "eligible": ok, "excluded_because": why})
    best = min((r for r in rows if r["eligible"]), key=lambda r: r["val"]["rmse_mean"])
    overall = min(rows, key=lambda r: r["val"]["rmse_mean"])
    chosen = _config_of(best, estimator)
    return {"criterion": "mean over h = 1..5 s of the validation RMSE of the raw MTD prediction, among the "
                         "eligible configurations (bins at least two acceleration quanta wide)",
            "n_val_windows": win.n, "position_resolution_m": res_m, "rows": rows, "baselines": baselines,
            "jerk_psd": q_cv, "jerk_psd_selection": q_table, "chosen": chosen,
            "best_overall": _config_of(overall, estimator)}


def _config_of(row: SelectionRow, estimator: str) -> ModelConfig:
    """A grid row's configuration (``dt``, ``width``, ``order``, ``a_max``, ``jerk_psd``) with ``estimator``."""
    return {"dt": row["dt"], "width": row["width"], "order": row["order"], "a_max": row["a_max"],
            "jerk_psd": row["jerk_psd"], "estimator": estimator}


def _selection_row(train: Tracks, win: Windows, cfg: _GridConfig, estimator: str) -> ScoredConfig:
    t0 = time.perf_counter()
    model = train_config(train, cfg, estimator=estimator)
    fit_s = time.perf_counter() - t0
    P = Predictor(model, "sel")
    raw = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S), win)
    cub = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S, cubic=True), win)
    return {**cfg, "n_states": model.n_states, "val": raw, "val_cubic": cub, "loglik": model.loglik,
            "n_obs": model.n_obs, "n_parameters": model.n_parameters, "aic": model.aic, "bic": model.bic,
            "lambda": model.lam.tolist(), "fit_seconds": fit_s}
