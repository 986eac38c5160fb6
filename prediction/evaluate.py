r"""Evaluation of the predictor: protocol, baselines, model selection and the report.

Protocol (the usual one of the trajectory-prediction literature, longitudinal only):

* The tracks are split **by whole track** (never one vehicle in two parts):
  ``rest, test = tracks.split_by_track(0.2, seed=0)`` and
  ``train, val = rest.split_by_track(0.25, seed=1)``.
* Every track is resampled to 0.1 s and cut into windows of 3 s of history (31 samples,
  ``t = -3..0``) and 5 s of future (``t = 0.1..5``), starting every ``stride_s = 1`` s.
* For each method the longitudinal error ``e_w(τ) = \hat x_w(τ) - x_w(τ)`` of window ``w`` is
  summarised as

  .. math::

      \mathrm{RMSE}(h) = \sqrt{\tfrac1W \sum_w e_w(h)^2}, \quad h = 1..5\ \mathrm{s}, \qquad
      \mathrm{ADE} = \tfrac{1}{W F} \sum_w \sum_{τ} |e_w(τ)|, \qquad
      \mathrm{FDE} = \tfrac1W \sum_w |e_w(5)|,

  the ADE over the ``F = 50`` future samples ``τ = 0.1..5`` s.
* Methods: ``mtd`` (the MTD predictor's propagated expected-acceleration trajectory),
  ``mtd-cubic`` (the least-squares cubic over ``[0, 5]`` s that the planners receive),
  ``markov1`` (first-order chain, same bins and step), ``mtd-lp`` (the Ching–Fung–Ng LP
  lag weights), ``mtd-mle-lambda`` (empirical ``Q_i``, ML lag weights), ``cv`` (constant
  velocity) and ``ca`` (constant acceleration, speed clamped at 0).  The baselines take
  ``v_0``, ``a_0`` from a least-squares quadratic over the last ``w`` seconds of the history
  (0.1 s grid), ``w ∈ {0.2, 0.3, 0.5, 1, 2}`` s chosen for each baseline on the validation
  split, so that they are not handicapped by a poor estimator; the MTD predictor takes its
  ``v_0`` the same way, with the window chosen for ``cv``.

Model selection (:func:`select_model`): the chain step ``Δt ∈ {0.1, 0.2, 0.5, 1.0}`` s, the
bin width ``∈ {0.25, 0.5, 1.0}`` m/s² (bins centred on 0 over ±3 m/s², outer bins open) and
the order ``n ∈ 1..5`` with ``(n + 1) Δt <= 3`` s (the history must hold ``n`` states) are
chosen by the mean over ``h = 1..5`` s of the validation RMSE of ``mtd`` (models fitted on
``train``), among the configurations whose bins are at least two acceleration quanta
``r/Δt²`` wide (``r``: the rounding step of the recorded positions, 0.01 m for the shipped
data; see :func:`eligible`); the best configuration overall is reported as well and, if it
differs, evaluated on test too.  The final model is refitted on ``train ∪ val`` with the chosen configuration and
evaluated once on ``test`` (:func:`run_evaluation`); that model is the shipped default
(:func:`train_default_model`).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from iamp.prediction.mtd import atomic_write_text
from iamp.prediction.predictor import (
    DEFAULT_MODEL_FILE,
    Predictor,
    local_quadratic,
    symmetric_edges,
    train_from_tracks,
)

__all__ = [
    "DEFAULT_CONFIG",
    "HORIZONS",
    "Windows",
    "baseline_ca",
    "baseline_cv",
    "evaluate_methods",
    "make_windows",
    "metrics",
    "paper_histories",
    "run_evaluation",
    "select_model",
    "split_tracks",
    "synthetic_tracks",
    "train_default_model",
    "write_evaluation_report",
]

#: Horizons [s] of the RMSE table.
HORIZONS = (1.0, 2.0, 3.0, 4.0, 5.0)
#: Window geometry [s].
HISTORY_S, FUTURE_S, STRIDE_S, EVAL_DT = 3.0, 5.0, 1.0, 0.1
#: Split seeds and fractions (by whole track).
TEST_FRACTION, TEST_SEED, VAL_FRACTION, VAL_SEED = 0.2, 0, 0.25, 1
#: Selection grid.
GRID_DT = (0.1, 0.2, 0.5, 1.0)
GRID_WIDTH = (0.25, 0.5, 1.0)
GRID_ORDER = (1, 2, 3, 4, 5)
#: Windows [s] of the quadratic fit giving v0, a0 to the baselines (chosen on validation).
GRID_BASELINE_WINDOW = (0.2, 0.3, 0.5, 1.0, 2.0)
BASELINE_WINDOW = 0.3
A_MAX = 3.0
#: Bump when the protocol or the model changes (cached results are then recomputed).
EVAL_VERSION = 3

#: The configuration chosen by :func:`select_model` on the shipped SUMO data (the evidence
#: is in ``reports/predictor_eval.json``); :func:`train_default_model` uses it.
DEFAULT_CONFIG = {"dt": 0.2, "width": 0.5, "order": 4, "a_max": A_MAX, "v0_window_s": 0.2, "estimator": "mle"}
#: The baselines' fit windows chosen with it.
DEFAULT_BASELINE_WINDOWS = {"cv": 0.2, "ca": 2.0}

#: CV reference on NGSIM (Deo & Trivedi 2018, 2-D RMSE in m at 1..5 s) — a different
#: dataset and a different (2-D) metric; quoted for scale only.
NGSIM_CV_REFERENCE = (0.73, 1.78, 3.13, 4.78, 6.68)


# ---------------------------------------------------------------------------------------
# data, splits, windows
# ---------------------------------------------------------------------------------------

def split_tracks(tracks):
    """``(train, val, test)`` by whole track with the module's fixed seeds."""
    rest, test = tracks.split_by_track(TEST_FRACTION, seed=TEST_SEED)
    train, val = rest.split_by_track(VAL_FRACTION, seed=VAL_SEED)
    return train, val, test, rest


@dataclass(frozen=True)
class Windows:
    """Evaluation windows sharing one time grid.

    Attributes
    ----------
    t_hist : numpy.ndarray, shape (K,)
        History times ``-3.0 .. 0`` [s].
    X_hist : numpy.ndarray, shape (W, K)
        Observed positions (shifted so that nothing depends on absolute position).
    t_fut : numpy.ndarray, shape (F,)
        Future times ``0.1 .. 5`` [s].
    X_fut : numpy.ndarray, shape (W, F)
        True future positions.
    track_id : numpy.ndarray, shape (W,)
    """

    t_hist: np.ndarray
    X_hist: np.ndarray
    t_fut: np.ndarray
    X_fut: np.ndarray
    track_id: np.ndarray

    @property
    def n(self) -> int:
        return int(self.X_hist.shape[0])


def make_windows(tracks, history_s: float = HISTORY_S, future_s: float = FUTURE_S,
                 stride_s: float = STRIDE_S, dt: float = EVAL_DT) -> Windows:
    """Cut every track (resampled to ``dt`` by linear interpolation) into windows.

    A window starts every ``stride_s`` seconds from the track's start; the position at
    ``t = 0`` of each window is subtracted from all its positions.
    """
    kh = int(round(history_s / dt))
    kf = int(round(future_s / dt))
    ks = max(int(round(stride_s / dt)), 1)
    H, F, ids = [], [], []
    for tid, t, x, *_ in tracks.iter_tracks():
        if t.size < 2:
            continue
        K = int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
        if K < kh + kf + 1:
            continue
        xg = np.interp(t[0] + dt * np.arange(K), t, x)
        starts = np.arange(0, K - kh - kf, ks)
        idx = starts[:, None] + np.arange(kh + kf + 1)[None, :]
        seg = xg[idx]
        seg = seg - seg[:, kh:kh + 1]
        H.append(seg[:, :kh + 1])
        F.append(seg[:, kh + 1:])
        ids.append(np.full(starts.size, tid))
    if not H:
        raise ValueError(f"no track is long enough for {history_s:g} s + {future_s:g} s windows")
    t_hist = dt * np.arange(-kh, 1)
    t_hist[-1] = 0.0
    return Windows(t_hist, np.concatenate(H), dt * np.arange(1, kf + 1), np.concatenate(F),
                   np.concatenate(ids))


def metrics(pred: np.ndarray, win: Windows, horizons=HORIZONS) -> dict:
    """RMSE at ``horizons``, ADE and FDE (metres) of predictions ``(W, F)`` at ``win.t_fut``."""
    err = pred - win.X_fut
    cols = [int(np.argmin(np.abs(win.t_fut - h))) for h in horizons]
    rmse = [float(np.sqrt(np.mean(err[:, c] ** 2))) for c in cols]
    return {"rmse": rmse, "rmse_mean": float(np.mean(rmse)), "ade": float(np.mean(np.abs(err))),
            "fde": float(np.mean(np.abs(err[:, -1]))), "n_windows": int(win.n)}


def _kin0(win: Windows, window_s: float):
    v0, a0 = local_quadratic(win.t_hist, win.X_hist, window_s)
    return win.X_hist[:, -1], np.maximum(v0, 0.0), a0


def baseline_cv(win: Windows, window_s: float = BASELINE_WINDOW) -> np.ndarray:
    """Constant velocity ``x_0 + v_0 τ`` (``v_0`` from a quadratic over the last ``window_s``)."""
    x0, v0, _ = _kin0(win, window_s)
    return x0[:, None] + v0[:, None] * win.t_fut[None, :]


def baseline_ca(win: Windows, window_s: float = BASELINE_WINDOW) -> np.ndarray:
    """Constant acceleration ``x_0 + v_0 τ + ½ a_0 τ²``, speed clamped at 0."""
    x0, v0, a0 = _kin0(win, window_s)
    tau = win.t_fut[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        stop = np.where(a0 < 0, v0 / np.where(a0 < 0, -a0, 1.0), np.inf)[:, None]
    s = np.minimum(tau, stop)
    return x0[:, None] + v0[:, None] * s + 0.5 * a0[:, None] * s * s


def evaluate_methods(win: Windows, models: dict, baseline_windows: dict | None = None) -> dict:
    """Metrics of the baselines and of every model in ``models`` (name → MTDModel).

    For each model ``name`` two rows are produced: ``name`` (raw propagated trajectory)
    and ``name + "-cubic"`` (the least-squares cubic over ``[0, 5]`` s).
    ``baseline_windows`` maps ``"cv"``/``"ca"`` to their fit windows [s].
    """
    bw = {"cv": BASELINE_WINDOW, "ca": BASELINE_WINDOW, **(baseline_windows or {})}
    out = {"cv": metrics(baseline_cv(win, bw["cv"]), win), "ca": metrics(baseline_ca(win, bw["ca"]), win)}
    for name, model in models.items():
        P = Predictor(model, name)
        out[name] = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S), win)
        out[name + "-cubic"] = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S,
                                                       cubic=True), win)
    return out


# ---------------------------------------------------------------------------------------
# selection, final evaluation, default model
# ---------------------------------------------------------------------------------------

def _train(tracks, cfg: dict, estimator: str | None = None, order: int | None = None, provenance=None):
    return train_from_tracks(tracks, dt=cfg["dt"], edges=symmetric_edges(cfg["width"], cfg.get("a_max", A_MAX)),
                             order=order or cfg["order"], estimator=estimator or cfg.get("estimator", "mle"),
                             v0_window_s=cfg.get("v0_window_s", BASELINE_WINDOW), provenance=provenance)


def position_resolution(tracks) -> float | None:
    """The rounding step of the recorded positions (``10^-d`` m), or ``None`` if finer than 1 µm."""
    x = np.asarray(tracks.x, dtype=float)
    for d in range(7):
        scaled = x * 10.0 ** d
        if np.all(np.abs(scaled - np.round(scaled)) < 1e-6 * np.maximum(1.0, np.abs(scaled) * 1e-9)):
            return 10.0 ** -d
    return None


def eligible(cfg: dict, resolution: float | None) -> tuple[bool, str]:
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


def select_model(train, val, *, grid_dt=GRID_DT, grid_width=GRID_WIDTH, grid_order=GRID_ORDER,
                 estimator: str = "mle", history_s: float = HISTORY_S, resolution="auto") -> dict:
    """Grid search on the validation windows; returns the table and the chosen config.

    1. The baselines' fit windows are chosen on the validation windows; the MTD predictor
       uses the constant-velocity one for its initial speed, so that MTD and CV differ only
       in the acceleration model.
    2. Every configuration with ``(n + 1) Δt <= history_s`` is fitted on ``train`` and scored
       on ``val``.  The choice is the best *eligible* one (:func:`eligible`, with the position
       resolution of the data); the best overall is reported too.

    Returns
    -------
    dict
        ``{"criterion", "n_val_windows", "rows": [...], "baselines": {...}, "baseline_windows",
        "position_resolution_m", "chosen": cfg, "best_overall": cfg}``; every row has the
        configuration, its eligibility, the validation metrics of ``mtd`` and ``mtd-cubic``,
        and the training log-likelihood, N, k, AIC and BIC.
    """
    win = make_windows(val)
    if resolution == "auto":
        resolution = position_resolution(train)
    baselines = {name: {f"{w:g}": metrics(fn(win, w), win) for w in GRID_BASELINE_WINDOW}
                 for name, fn in (("cv", baseline_cv), ("ca", baseline_ca))}
    bw = {name: float(min(tab, key=lambda k: tab[k]["rmse_mean"])) for name, tab in baselines.items()}
    rows = []
    for dt in grid_dt:
        for width in grid_width:
            for order in grid_order:
                if (order + 1) * dt > history_s + 1e-9:
                    continue
                cfg = {"dt": dt, "width": width, "order": order, "a_max": A_MAX, "v0_window_s": bw["cv"]}
                ok, why = eligible(cfg, resolution)
                rows.append({**_selection_row(train, win, cfg, estimator), "eligible": ok, "excluded_because": why})
    keys = ("dt", "width", "order", "a_max", "v0_window_s")
    best = min((r for r in rows if r["eligible"]), key=lambda r: r["val"]["rmse_mean"])
    overall = min(rows, key=lambda r: r["val"]["rmse_mean"])
    chosen = {**{k: best[k] for k in keys}, "estimator": estimator}
    return {"criterion": "mean over h = 1..5 s of the validation RMSE of the raw MTD prediction, among the "
                         "eligible configurations (bins at least two acceleration quanta wide)",
            "n_val_windows": win.n, "position_resolution_m": resolution, "rows": rows, "baselines": baselines,
            "baseline_windows": bw, "chosen": chosen,
            "best_overall": {**{k: overall[k] for k in keys}, "estimator": estimator}}


def _selection_row(train, win, cfg, estimator):
    t0 = time.perf_counter()
    model = _train(train, cfg, estimator=estimator)
    fit_s = time.perf_counter() - t0
    P = Predictor(model, "sel")
    raw = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S), win)
    cub = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S, cubic=True), win)
    return {**cfg, "n_states": model.n_states, "val": raw, "val_cubic": cub, "loglik": model.loglik,
            "n_obs": model.n_obs, "n_parameters": model.n_parameters, "aic": model.aic, "bic": model.bic,
            "lambda": model.lam.tolist(), "fit_seconds": fit_s}


def _dataset_fingerprint(tracks) -> str:
    h = hashlib.sha256()
    for col in (tracks.track_id, tracks.t, tracks.x):
        h.update(np.ascontiguousarray(col).tobytes())
    return h.hexdigest()


def _dataset_name(tracks) -> str:
    meta = tracks.meta if isinstance(tracks.meta, dict) else {}
    return str(meta.get("dataset") or meta.get("name") or meta.get("format") or "unknown")


def _load_default_data():
    from iamp.prediction.tracks import load_shipped_dataset

    return load_shipped_dataset()


def train_default_model(path=None, *, tracks=None, config: dict | None = None):
    """Train the shipped default model deterministically and (optionally) write it.

    Parameters
    ----------
    path : path-like, optional
        Where to write the JSON (atomically).  ``None``: do not write.  Pass
        ``"package"`` to overwrite ``prediction/data/mtd_default.json`` in the source tree.
    tracks : Tracks, optional
        Defaults to the shipped SUMO dataset.
    config : dict, optional
        Defaults to :data:`DEFAULT_CONFIG`.

    Returns
    -------
    MTDModel
        Fitted on ``train ∪ val`` (every track not in the test split).
    """
    tracks = _load_default_data() if tracks is None else tracks
    cfg = dict(DEFAULT_CONFIG if config is None else config)
    _, _, test, rest = split_tracks(tracks)
    prov = {
        "trained_by": "iamp.prediction.evaluate.train_default_model",
        "dataset": _dataset_name(tracks),
        "dataset_sha256_track_t_x": _dataset_fingerprint(tracks),
        "split": {"test_fraction": TEST_FRACTION, "test_seed": TEST_SEED,
                  "trained_on": "all tracks not in the test split (train + validation)",
                  "n_train_tracks": int(rest.n_tracks), "n_test_tracks": int(test.n_tracks),
                  "test_track_ids": [int(i) for i in test.ids()]},
        "config": cfg,
        "selection": "reports/predictor_eval.json (iamp.prediction.evaluate.run_evaluation)",
    }
    model = _train(rest, cfg, provenance=prov)
    if path is not None:
        if str(path) == "package":
            path = Path(__file__).resolve().parent / "data" / DEFAULT_MODEL_FILE
        model.save(path)
    return model


def paper_histories():
    """The three 3-s histories of SPEC §8 (0.1 s sampling, ``x(0) = -15``).

    1. constant 18 m/s;  2. braking at -1.5 m/s² to 20 m/s at ``t = 0``;
    3. accelerating at +2 m/s² to 13 m/s at ``t = 0``.
    """
    from iamp.core.scenario import History

    t = np.round(np.arange(-30, 1) * 0.1, 10)
    xs = {"paper-1": -15.0 + 18.0 * t,
          "paper-2": -15.0 + 20.0 * t - 0.75 * t * t,
          "paper-3": -15.0 + 13.0 * t + 1.0 * t * t}
    return {k: History(t, x, field="vehicles[0].history", source=k) for k, x in xs.items()}


def _paper_predictions(predictor: Predictor) -> dict:
    out = {}
    for name, h in paper_histories().items():
        p = predictor.predict(h, 5.0)
        out[name] = {"x_poly": list(p.x_poly), "fit_rmse": p.fit_rmse, "v_at_5s": float(p.v[-1]),
                     "x_at_5s": float(p.x[-1]), "a_at_0": float(p.a[0]), "a_at_1s": float(np.interp(1.0, p.t, p.a)),
                     "a_at_5s": float(p.a[-1])}
    return out


def run_evaluation(tracks=None, *, select: bool = True, config: dict | None = None) -> dict:
    """The whole protocol: selection on validation, final numbers on test.

    Parameters
    ----------
    tracks : Tracks, optional
        Defaults to the shipped SUMO dataset.
    select : bool
        Run the grid search (minutes); otherwise use ``config`` / :data:`DEFAULT_CONFIG`.
    config : dict, optional

    Returns
    -------
    dict
        JSON-ready results (see ``reports/predictor_eval.json``).
    """
    t_start = time.perf_counter()
    tracks = _load_default_data() if tracks is None else tracks
    train, val, test, rest = split_tracks(tracks)
    selection = select_model(train, val) if select else None
    cfg = dict(selection["chosen"] if selection else (config or DEFAULT_CONFIG))
    bw = dict(selection["baseline_windows"] if selection else DEFAULT_BASELINE_WINDOWS)
    final = _train(rest, cfg)
    models = {"mtd": final,
              "markov1": _train(rest, cfg, order=1),
              "mtd-lp": _train(rest, cfg, estimator="lp"),
              "mtd-mle-lambda": _train(rest, cfg, estimator="mle-lambda")}
    if selection and selection["best_overall"] != selection["chosen"]:
        models["mtd-best-overall"] = _train(rest, selection["best_overall"])
    win = make_windows(test)
    results = evaluate_methods(win, models, bw)
    # held-out log-likelihood of the state sequences (per transition)
    from iamp.prediction.predictor import track_accelerations

    seqs = [np.searchsorted(final.edges, a, side="right") for a in track_accelerations(test, cfg["dt"])]
    heldout = {}
    for name, m in models.items():
        if m.dt != final.dt or m.n_states != final.n_states:
            continue
        ll, N = m.log_likelihood(seqs)
        heldout[name] = {"loglik": ll if math.isfinite(ll) else None, "n_obs": N,
                         "loglik_per_transition": ll / N if N and math.isfinite(ll) else None}
    return {
        "protocol": {
            "history_s": HISTORY_S, "future_s": FUTURE_S, "stride_s": STRIDE_S, "eval_dt": EVAL_DT,
            "horizons_s": list(HORIZONS), "metric": "longitudinal position error [m]; RMSE at each horizon, "
            "ADE over the 50 future samples, FDE at 5 s",
            "split": {"test_fraction": TEST_FRACTION, "test_seed": TEST_SEED, "val_fraction_of_rest": VAL_FRACTION,
                      "val_seed": VAL_SEED, "by": "whole track"},
            "n_tracks": {"all": int(tracks.n_tracks), "train": int(train.n_tracks), "val": int(val.n_tracks),
                         "test": int(test.n_tracks)},
            "dataset": _dataset_name(tracks),
            "dataset_sha256_track_t_x": _dataset_fingerprint(tracks),
            "dataset_dt": tracks.dt,
            "eval_version": EVAL_VERSION,
        },
        "selection": selection,
        "chosen": cfg,
        "default_config": DEFAULT_CONFIG,
        "default_config_matches_selection": bool(selection is None or selection["chosen"] == DEFAULT_CONFIG),
        "baseline_windows_s": bw,
        "final_model": final.summary() | {"n_states": final.n_states, "edges": final.edges.tolist(),
                                          "centres": final.centres.tolist()},
        "test": results,
        "test_heldout_loglik": heldout,
        "paper_histories": _paper_predictions(Predictor(final, "final")),
        "paper_histories_other_models": {name: _paper_predictions(Predictor(m, name)) for name, m in models.items()
                                         if name != "mtd"},
        "ngsim_cv_reference_2d_rmse": {"values": list(NGSIM_CV_REFERENCE),
                                       "source": "Deo & Trivedi 2018 (CVPRW), NGSIM, 2-D RMSE: different "
                                                 "dataset and metric, for scale only"},
        "produced_by": "iamp.prediction.evaluate.run_evaluation / write_evaluation_report",
        "seconds": time.perf_counter() - t_start,
    }


# ---------------------------------------------------------------------------------------
# the report
# ---------------------------------------------------------------------------------------

_LABELS = {"cv": "Constant velocity", "ca": "Constant acceleration, $v \\ge 0$",
           "markov1": "First-order chain", "markov1-cubic": "First-order chain, cubic fit",
           "mtd": "MTD (propagated)", "mtd-cubic": "MTD, cubic fit (planner input)",
           "mtd-lp": "MTD, LP lag weights", "mtd-lp-cubic": "MTD, LP lag weights, cubic fit",
           "mtd-mle-lambda": "MTD, empirical $Q_i$ + ML $\\lambda$",
           "mtd-mle-lambda-cubic": "MTD, empirical $Q_i$ + ML $\\lambda$, cubic fit"}
_ORDER = ("cv", "ca", "markov1", "mtd", "mtd-cubic", "mtd-mle-lambda", "mtd-lp")


def _tex(text) -> str:
    return str(text).replace("\\", "/").replace("_", "\\_").replace("&", "\\&").replace("%", "\\%")


def rmse_table_tex(res: dict) -> str:
    """LaTeX booktabs table of the test RMSE/ADE/FDE."""
    cfg = res["chosen"]
    test = res["test"]
    bw = res.get("baseline_windows_s", {})
    keys = [k for k in _ORDER if k in test] + (["mtd-best-overall"] if "mtd-best-overall" in test else [])
    best = [min(test[k]["rmse"][i] for k in keys) for i in range(len(HORIZONS))]
    labels = dict(_LABELS)
    sel = res.get("selection") or {}
    if "mtd-best-overall" in test and sel.get("best_overall"):
        o = sel["best_overall"]
        labels["mtd-best-overall"] = (f"MTD, $\\Delta t={o['dt']:g}$\\,s, {o['width']:g}\\,m/s$^2$, $n={o['order']}$"
                                      "$^\\dagger$")
    lines = [
        "% generated by iamp.prediction.evaluate.write_evaluation_report -- do not edit",
        "\\begin{table}[t]",
        "\\centering",
        f"\\caption{{Longitudinal prediction error on held-out tracks of {_tex(res['protocol']['dataset'])} "
        f"({test['cv']['n_windows']} windows of 3\\,s history and 5\\,s future from "
        f"{res['protocol']['n_tracks']['test']} test tracks). RMSE in m at each horizon; ADE/FDE in m. "
        f"MTD: order {cfg['order']}, $\\Delta t={cfg['dt']:g}$\\,s, acceleration bins of "
        f"{cfg['width']:g}\\,m/s$^2$ over $\\pm{cfg['a_max']:g}$\\,m/s$^2$, chosen on a separate validation split; "
        f"initial speed, as for constant velocity, from a quadratic fit over the last {cfg.get('v0_window_s', 0.3):g}\\,s"
        + (f" (constant acceleration: {bw['ca']:g}\\,s)" if "ca" in bw else "") + ". "
        + ("$^\\dagger$Best on validation, but its bins are narrower than two acceleration quanta of the "
           "recorded positions (excluded by the selection rule). " if "mtd-best-overall" in test else "")
        + "Best value per column in bold. For scale only (different dataset and metric): constant velocity on "
        "NGSIM has 2-D RMSE " + "/".join(f"{v:.2f}" for v in NGSIM_CV_REFERENCE) +
        "\\,m at 1--5\\,s (Deo \\& Trivedi, 2018).}",
        "\\label{tab:predictor-rmse}",
        "\\begin{tabular}{l" + "r" * (len(HORIZONS) + 2) + "}",
        "\\toprule",
        "Method & " + " & ".join(f"{h:g}\\,s" for h in HORIZONS) + " & ADE & FDE \\\\",
        "\\midrule",
    ]
    for key in keys:
        r = test[key]
        cells = []
        for i, v in enumerate(r["rmse"]):
            s = f"{v:.2f}"
            cells.append(f"\\textbf{{{s}}}" if f"{v:.2f}" == f"{best[i]:.2f}" else s)
        lines.append(f"{labels.get(key, key)} & " + " & ".join(cells) + f" & {r['ade']:.2f} & {r['fde']:.2f} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def selection_table_tex(res: dict) -> str:
    """LaTeX booktabs table of the validation grid (mean RMSE per dt × width × order)."""
    sel = res.get("selection")
    lines = ["% generated by iamp.prediction.evaluate.write_evaluation_report -- do not edit",
             "\\begin{table}[t]", "\\centering"]
    if not sel:
        lines += ["\\caption{Model selection was not run for this report.}", "\\end{table}", ""]
        return "\n".join(lines)
    orders = sorted({r["order"] for r in sel["rows"]})
    ch = sel["chosen"]
    bw = sel.get("baseline_windows", {})
    cv_best = sel["baselines"]["cv"][f"{bw['cv']:g}"]["rmse_mean"] if "cv" in bw else None
    res_m = sel.get("position_resolution_m")
    lines += [
        "\\caption{Model selection on the validation split: mean over 1--5\\,s of the longitudinal RMSE (m) of "
        f"the propagated MTD prediction ({sel['n_val_windows']} windows) for each time step $\\Delta t$, bin width "
        "and order $n$; training BIC of the best order of each row in the last column. "
        + (f"Constant velocity scores {cv_best:.3f} (initial-speed window {bw['cv']:g}\\,s, also used by MTD). "
           if cv_best is not None else "")
        + f"Chosen (bold): $\\Delta t={ch['dt']:g}$\\,s, width {ch['width']:g}\\,m/s$^2$, $n={ch['order']}$. "
        + (f"$^\\dagger$Excluded: bins narrower than two acceleration quanta $r/\\Delta t^2$ of positions "
           f"recorded to $r={res_m:g}$\\,m. " if res_m else "")
        + "--: $(n+1)\\Delta t > 3$\\,s does not fit in the history.}",
        "\\label{tab:predictor-selection}",
        "\\begin{tabular}{rrr" + "r" * len(orders) + "r}",
        "\\toprule",
        "$\\Delta t$ [s] & width [m/s$^2$] & $m$ & " + " & ".join(f"$n={o}$" for o in orders) + " & BIC \\\\",
        "\\midrule",
    ]
    keys = []
    for r in sel["rows"]:
        if (r["dt"], r["width"]) not in keys:
            keys.append((r["dt"], r["width"]))
    for dt, width in keys:
        rs = {r["order"]: r for r in sel["rows"] if r["dt"] == dt and r["width"] == width}
        cells = []
        for o in orders:
            if o not in rs:
                cells.append("--")
                continue
            r = rs[o]
            s = f"{r['val']['rmse_mean']:.3f}"
            if (r["dt"], r["width"], r["order"]) == (ch["dt"], ch["width"], ch["order"]):
                s = f"\\textbf{{{s}}}"
            if not r.get("eligible", True):
                s += "$^\\dagger$"
            cells.append(s)
        rb = min(rs.values(), key=lambda r: r["val"]["rmse_mean"])
        m = next(iter(rs.values()))["n_states"]
        lines.append(f"{dt:g} & {width:g} & {m} & " + " & ".join(cells) + f" & {rb['bic']:.4g} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", "\\end{table}", ""]
    return "\n".join(lines)


def write_evaluation_report(out_dir="reports", results: dict | None = None, *, rerun: bool = False,
                            select: bool = True) -> dict:
    """Write the evaluation report (running the evaluation only when needed).

    Writes, atomically, ``out_dir/predictor_eval.json``, ``out_dir/tables/predictor_rmse.tex``
    and ``out_dir/tables/predictor_selection.tex``.

    Parameters
    ----------
    out_dir : path-like
    results : dict, optional
        Results of :func:`run_evaluation` to write.
    rerun : bool
        Recompute even if ``out_dir/predictor_eval.json`` already holds results of this
        protocol version (:data:`EVAL_VERSION`) for the shipped dataset; by default such
        results are reused and only the tables are regenerated (the full run with model
        selection takes minutes).
    select : bool
        When running: include the grid search (see :func:`run_evaluation`).

    Returns
    -------
    dict
        The results that were written.
    """
    out = Path(out_dir)
    res = results
    cached = out / "predictor_eval.json"
    if res is None and not rerun and cached.is_file():
        try:
            old = json.loads(cached.read_text(encoding="utf-8"))
            proto = old.get("protocol", {})
            if (proto.get("eval_version") == EVAL_VERSION
                    and proto.get("dataset_sha256_track_t_x") == _dataset_fingerprint(_load_default_data())
                    and (old.get("selection") is not None or not select)):
                res = old
        except (OSError, ValueError, AttributeError):
            res = None
    if res is None:
        res = run_evaluation(select=select)
    atomic_write_text(cached, json.dumps(res, indent=1, allow_nan=False) + "\n")
    atomic_write_text(out / "tables" / "predictor_rmse.tex", rmse_table_tex(res))
    atomic_write_text(out / "tables" / "predictor_selection.tex", selection_table_tex(res))
    return res


# ---------------------------------------------------------------------------------------
# synthetic data (tests, demos)
# ---------------------------------------------------------------------------------------

def synthetic_tracks(n_tracks: int = 40, duration: float = 90.0, dt: float = 0.1, seed: int = 0):
    """Synthetic highway-like tracks for tests: regime-switching, jerk-limited acceleration.

    Each track alternates phases of 2–6 s (cruise with probability 0.5, accelerate or brake
    at 0.8–2 m/s² with probability 0.25 each); the acceleration follows the phase's target
    with a 0.5 s first-order lag; speeds start in 12–30 m/s and stay within 5–33 m/s.
    """
    from iamp.prediction.tracks import Tracks

    rng = np.random.default_rng(seed)
    cols = {k: [] for k in ("track_id", "t", "x", "v", "a", "lane")}
    n = int(round(duration / dt)) + 1
    for tid in range(n_tracks):
        target = np.zeros(n)
        k = 0
        while k < n:
            L = max(int(rng.uniform(2.0, 6.0) / dt), 1)
            mode = rng.choice([0, 1, -1], p=[0.5, 0.25, 0.25])
            target[k:k + L] = mode * rng.uniform(0.8, 2.0)
            k += L
        a, v, x = np.zeros(n), np.zeros(n), np.zeros(n)
        v[0] = rng.uniform(12.0, 30.0)
        for i in range(1, n):
            a[i] = a[i - 1] + (target[i] - a[i - 1]) * dt / 0.5
            if (v[i - 1] > 33.0 and a[i] > 0) or (v[i - 1] < 5.0 and a[i] < 0):
                a[i] = 0.0
            v[i] = max(v[i - 1] + a[i] * dt, 0.0)
            x[i] = x[i - 1] + v[i - 1] * dt + 0.5 * a[i] * dt * dt
        for key, val in zip(cols, (np.full(n, tid), dt * np.arange(n), x, v, a, np.zeros(n, dtype=int))):
            cols[key].append(val)
    return Tracks(*(np.concatenate(cols[k]) for k in cols), dt=dt,
                  meta={"format": "synthetic", "name": "synthetic", "seed": seed})
