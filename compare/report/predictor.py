"""The predictor's evaluation in ``iamp reproduce`` (:func:`predictor_evaluation`): run, or
reuse, :func:`iamp.prediction.evaluation.evaluate.write_evaluation_report`, whose tables the report
inputs."""

from __future__ import annotations

import inspect
import json
from pathlib import Path
from typing import Any

from .config import ProgressFn, ReproduceConfig
from .records import PredictorSummary

__all__ = ["predictor_evaluation"]


def predictor_evaluation(out: Path, cfg: ReproduceConfig, notes: list[str],
                         progress: ProgressFn | None = None) -> PredictorSummary | None:
    """Run (or reuse) the predictor's evaluation and let it write its tables into ``out``.

    ``cfg.predictor_select``: ``True`` runs the model-selection grid (many minutes);
    ``False`` evaluates the default configuration only (tens of seconds); ``"auto"`` reuses an
    existing ``out/predictor_eval.json`` that has a selection, was computed on the same data
    set (fingerprint) and chose the shipped configuration, else behaves as ``False``.
    """
    if not cfg.predictor_eval:
        notes.append("predictor evaluation skipped (configuration).")
        return None
    try:
        from iamp.prediction.evaluation import evaluate as ev
    except ImportError as exc:
        notes.append(f"predictor evaluation unavailable ({exc.__class__.__name__}: {exc}).")
        return None
    mode = cfg.predictor_select
    existing = None
    if mode == "auto":
        path = out / "predictor_eval.json"
        try:
            old = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
        except (OSError, ValueError):
            old = None
        if old and old.get("selection"):
            try:
                fp = ev._dataset_fingerprint(ev._load_default_data())
                same_data = old.get("protocol", {}).get("dataset_sha256_track_t_x") == fp
            except Exception:  # cannot check: do not reuse
                same_data = False
            if same_data and old.get("chosen") == getattr(ev, "DEFAULT_CONFIG", None):
                existing = old
    try:
        if existing is not None:
            res = ev.write_evaluation_report(out, results=existing)
            how = ("reused the existing predictor_eval.json (model selection on the validation split, same data "
                   "set, chose the shipped configuration); its tables were rewritten")
        else:
            select = mode is True
            extra: dict[str, Any] = ({"progress": progress} if progress is not None
                                     and "progress" in inspect.signature(ev.write_evaluation_report).parameters
                                     else {})
            res = ev.write_evaluation_report(out, select=select, **extra)
            how = ("ran the evaluation with model selection" if select else
                   "evaluated the shipped configuration on the test split without re-running the model-selection "
                   "grid (run `iamp evaluate-predictor --out DIR` for it; it takes many minutes)")
    except Exception as exc:  # the predictor is optional for the planners' report
        notes.append(f"predictor evaluation failed ({exc.__class__.__name__}: {str(exc)[:200]}).")
        return None
    notes.append(f"predictor evaluation: {how}.")
    return {"how": how, "chosen": res.get("chosen"), "test": res.get("test"),
            "paper_histories": res.get("paper_histories"), "seconds": res.get("seconds"),
            "selection_run": bool(res.get("selection")), "file": "predictor_eval.json"}
