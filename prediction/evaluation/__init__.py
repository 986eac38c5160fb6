"""Evaluation of the predictor: windows, baselines, model selection, the report and a user's data."""

from __future__ import annotations

from .evaluate import (
    DEFAULT_CONFIG,
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
    paper_histories,
    run_evaluation,
    select_model,
    split_tracks,
    synthetic_tracks,
    train_default_model,
    write_evaluation_report,
)

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
