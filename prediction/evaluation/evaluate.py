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
  velocity) and ``ca`` (constant acceleration, speed clamped at 0).  Every method takes
  ``x_0``, ``v_0`` (and ``ca`` also ``a_0``) from the same RTS smoother
  (:mod:`iamp.prediction.initial_state`), whose jerk spectral density is chosen on the
  validation split by the constant-velocity RMSE.

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
from pathlib import Path
from typing import cast

import numpy as np

from iamp.core.atomic import write_text as atomic_write_text
from iamp.prediction._typing import PathLike
from iamp.prediction.initial_state import DEFAULT_JERK_PSD
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.predictor import DEFAULT_MODEL_FILE, Predictor
from iamp.prediction.tracks.split import TEST_FRACTION, TEST_SEED, VAL_FRACTION, VAL_SEED, split_tracks
from iamp.prediction.tracks.table import Tracks
from iamp.prediction.training import track_accelerations

from ..windows import (
    EVAL_DT,
    FUTURE_S,
    HISTORY_S,
    HORIZONS,
    STRIDE_S,
    Windows,
    baseline_ca,
    baseline_cv,
    evaluate_methods,
    make_windows,
    metrics,
)
from .data import paper_histories, synthetic_tracks
from .records import EvaluationJSON, HeldoutLoglik, PaperPrediction
from .report import NGSIM_CV_REFERENCE, rmse_table_tex, selection_table_tex
from .select import A_MAX, ModelConfig, select_model, train_config

__all__ = [
    "DEFAULT_CONFIG",
    "EVAL_DT",
    "FUTURE_S",
    "HISTORY_S",
    "HORIZONS",
    "STRIDE_S",
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
#: Split seeds and fractions (by whole track).
#: Bump when the protocol or the model changes (cached results are then recomputed).
EVAL_VERSION = 4

#: The configuration chosen by :func:`select_model` on the shipped SUMO data (the evidence
#: is in ``reports/predictor_eval.json``); :func:`train_default_model` uses it.
DEFAULT_CONFIG: ModelConfig = {"dt": 0.2, "width": 0.5, "order": 4, "a_max": A_MAX,
                               "jerk_psd": DEFAULT_JERK_PSD, "estimator": "mle"}

# ---------------------------------------------------------------------------------------
# data, splits, windows
# ---------------------------------------------------------------------------------------



def _dataset_fingerprint(tracks: Tracks) -> str:
    h = hashlib.sha256()
    for col in (tracks.track_id, tracks.t, tracks.x):
        h.update(np.ascontiguousarray(col).tobytes())
    return h.hexdigest()


def _dataset_name(tracks: Tracks) -> str:
    meta = tracks.meta if isinstance(tracks.meta, dict) else {}
    return str(meta.get("dataset") or meta.get("name") or meta.get("format") or "unknown")


def _load_default_data() -> Tracks:
    from iamp.prediction.tracks.table import load_shipped_dataset

    return load_shipped_dataset()


def train_default_model(path: PathLike | None = None, *, tracks: Tracks | None = None,
                        config: ModelConfig | None = None) -> MTDModel:
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
    cfg = (DEFAULT_CONFIG if config is None else config).copy()
    _, _, test, rest = split_tracks(tracks)
    prov = {
        "trained_by": "iamp.prediction.evaluate.train_default_model",  # restructure: keep (the shipped model)
        "dataset": _dataset_name(tracks),
        "dataset_sha256_track_t_x": _dataset_fingerprint(tracks),
        "split": {"test_fraction": TEST_FRACTION, "test_seed": TEST_SEED,
                  "trained_on": "all tracks not in the test split (train + validation)",
                  "n_train_tracks": int(rest.n_tracks), "n_test_tracks": int(test.n_tracks),
                  "test_track_ids": [int(i) for i in test.ids()]},
        "config": cfg,
        "selection": "reports/predictor_eval.json (iamp.prediction.evaluate.run_evaluation)",  # restructure: keep
    }
    model = train_config(rest, cfg, provenance=prov)
    if path is not None:
        if str(path) == "package":
            path = Path(__file__).resolve().parents[1] / "data" / DEFAULT_MODEL_FILE
        model.save(path)
    return model


def _paper_predictions(predictor: Predictor) -> dict[str, PaperPrediction]:
    out: dict[str, PaperPrediction] = {}
    for name, h in paper_histories().items():
        p = predictor.predict(h, 5.0)
        out[name] = {"x_poly": list(p.x_poly), "fit_rmse": p.fit_rmse, "v_at_5s": float(p.v[-1]),
                     "x_at_5s": float(p.x[-1]), "a_at_0": float(p.a[0]), "a_at_1s": float(np.interp(1.0, p.t, p.a)),
                     "a_at_5s": float(p.a[-1])}
    return out


def run_evaluation(tracks: Tracks | None = None, *, select: bool = True,
                   config: ModelConfig | None = None) -> EvaluationJSON:
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
    cfg = (selection["chosen"] if selection else (config or DEFAULT_CONFIG)).copy()
    q = float(cfg.get("jerk_psd", DEFAULT_JERK_PSD))
    final = train_config(rest, cfg)
    models = {"mtd": final,
              "markov1": train_config(rest, cfg, order=1),
              "mtd-lp": train_config(rest, cfg, estimator="lp"),
              "mtd-mle-lambda": train_config(rest, cfg, estimator="mle-lambda")}
    if selection and selection["best_overall"] != selection["chosen"]:
        models["mtd-best-overall"] = train_config(rest, selection["best_overall"])
    win = make_windows(test)
    results = evaluate_methods(win, models, q)
    # held-out log-likelihood of the state sequences (per transition)
    assert final.edges is not None and final.centres is not None
    seqs = [np.searchsorted(final.edges, a, side="right") for a in track_accelerations(test, cfg["dt"])]
    heldout: dict[str, HeldoutLoglik] = {}
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
        "jerk_psd": q,
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
        "produced_by": "iamp.prediction.evaluate.run_evaluation / write_evaluation_report",  # restructure: keep
        "seconds": time.perf_counter() - t_start,
    }


def write_evaluation_report(out_dir: PathLike = "reports", results: EvaluationJSON | None = None, *,
                            rerun: bool = False, select: bool = True) -> EvaluationJSON:
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
                res = cast(EvaluationJSON, old)  # this protocol version's results, on this data set
        except (OSError, ValueError, AttributeError):
            res = None
    if res is None:
        res = run_evaluation(select=select)
    atomic_write_text(cached, json.dumps(res, indent=1, allow_nan=False) + "\n")
    atomic_write_text(out / "tables" / "predictor_rmse.tex", rmse_table_tex(res))
    atomic_write_text(out / "tables" / "predictor_selection.tex", selection_table_tex(res))
    return res
