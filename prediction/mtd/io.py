"""The JSON file format of an MTD model (``format: iamp-mtd/1``).

Keys: ``format``, ``orientation`` (column-stochastic ``Q[i-1][j][k] = P(x_t = j | x_{t-i} = k)``),
``order``, ``n_states``, ``dt``, ``state``, ``settings``, ``bins`` (``edges``, ``centres``),
``estimator``, ``lambda``, ``Q``, ``counts``, ``loglik``, ``n_obs``, ``n_parameters``, ``aic``,
``bic``, ``fit_info``, ``provenance``.  Files are written atomically.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from iamp.core.atomic import write_text as atomic_write_text
from iamp.prediction._typing import PathLike

from .model import FORMAT, ModelFileError, ModelJSON, MTDModel

__all__ = ["load_model", "model_from_dict", "model_to_dict", "save_model"]


def model_to_dict(model: MTDModel) -> ModelJSON:
    """A JSON-serialisable description (see :meth:`save`)."""
    return {
        "format": FORMAT,
        "kind": "mtd",
        "orientation": "column-stochastic: Q[i-1][j][k] = P(x_t = j | x_{t-i} = k)",
        "order": model.order,
        "n_states": model.n_states,
        "dt": model.dt,
        "state": model.state,
        "settings": model.settings,
        "bins": {
            "quantity": "longitudinal acceleration [m/s^2]",
            "edges": None if model.edges is None else model.edges.tolist(),
            "centres": None if model.centres is None else model.centres.tolist(),
        },
        "estimator": model.estimator,
        "lambda": model.lam.tolist(),
        "Q": model.Q.tolist(),
        "counts": None if model.counts is None else model.counts.astype(int).tolist()
        if np.all(model.counts == np.round(model.counts)) else model.counts.tolist(),
        "loglik": model.loglik if math.isfinite(model.loglik) else None,
        "n_obs": model.n_obs,
        "n_parameters": model.n_parameters,
        "aic": model.aic if math.isfinite(model.loglik) else None,
        "bic": model.bic if math.isfinite(model.loglik) else None,
        "fit_info": model.fit_info,
        "provenance": model.provenance,
    }


def save_model(model: MTDModel, path: PathLike) -> Path:
    """Write the model as JSON, atomically (temporary file + ``os.replace``)."""
    out = Path(path)
    text = json.dumps(model_to_dict(model), indent=1, allow_nan=False) + "\n"
    atomic_write_text(out, text)
    return out


def model_from_dict(d: object, source: str | None = None) -> MTDModel:
    """Build a model from :meth:`to_dict` output; raises :class:`ModelFileError`."""
    if not isinstance(d, dict):
        raise ModelFileError("must be a JSON object", None, source)
    if d.get("format") != FORMAT:
        raise ModelFileError(f"unsupported format {d.get('format')!r} (expected {FORMAT!r})",
                             "format", source)
    if d.get("kind", "mtd") != "mtd":
        raise ModelFileError(f"is {d.get('kind')!r}, expected 'mtd' (a leader model is read by "
                             "iamp.prediction.leader.model.load_any_model)", "kind", source)
    for key in ("Q", "lambda", "order"):
        if key not in d:
            raise ModelFileError("is missing", key, source)
    _check_types(d, source)
    bins = d.get("bins") or {}
    try:
        model = MTDModel(Q=d["Q"], lam=d["lambda"], estimator=str(d.get("estimator", "given")),
                    edges=bins.get("edges"), centres=bins.get("centres"), dt=d.get("dt"),
                    state=d.get("state"), settings=d.get("settings") or {}, counts=d.get("counts"),
                    loglik=float(d["loglik"]) if d.get("loglik") is not None else float("nan"),
                    n_obs=int(d.get("n_obs", 0)), provenance=d.get("provenance") or {},
                    fit_info=d.get("fit_info") or {})
    except (ValueError, TypeError) as exc:
        raise ModelFileError(str(exc), None, source) from None
    if model.order != d["order"]:
        raise ModelFileError(f"says {d['order']} but Q has {model.order} lags", "order", source)
    if "n_states" in d and d["n_states"] != model.n_states:
        raise ModelFileError(f"says {d['n_states']} but Q is {model.n_states} x {model.n_states} per lag",
                             "n_states", source)
    return model


def _is_int(x: object) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_number(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _check_types(d: dict[str, Any], source: str | None) -> None:
    """The scalar keys have their JSON types: ``order`` and ``n_states`` integers (``4.5`` or
    ``"4"`` are refused, not truncated or parsed), ``dt`` a number or null, ``n_obs`` an integer,
    ``loglik`` a number or null."""
    for key, ok, what in (("order", _is_int, "an integer"), ("n_states", _is_int, "an integer"),
                          ("n_obs", _is_int, "an integer"), ("dt", _is_number, "a number of seconds"),
                          ("loglik", _is_number, "a number")):
        if key in d and not (d[key] is None and key in ("dt", "loglik")) and not ok(d[key]):
            raise ModelFileError(f"must be {what} (got {json.dumps(d[key])[:60]})", key, source)
    raw_bins = d.get("bins")
    bins: dict[str, Any] = raw_bins if isinstance(raw_bins, dict) else {}
    for key, value in (("Q", d["Q"]), ("lambda", d["lambda"]), ("counts", d.get("counts")),
                       ("bins.edges", bins.get("edges")), ("bins.centres", bins.get("centres"))):
        if value is None and key != "Q" and key != "lambda":
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                arr = np.asarray(value, dtype=float)
        except (ValueError, TypeError):
            raise ModelFileError("must be (nested lists of) numbers of one shape", key, source) from None
        if not np.all(np.isfinite(arr)):
            raise ModelFileError("must hold finite numbers only", key, source)
    if d["order"] < 1:
        raise ModelFileError(f"must be at least 1 (got {d['order']})", "order", source)

def load_model(path: PathLike) -> MTDModel:
    """Read a model written by :meth:`save`; raises :class:`ModelFileError`."""
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else "not UTF-8 text"
        raise ModelFileError(f"cannot be read ({why})", None, str(file)) from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"is not valid JSON ({exc})", None, str(file)) from None
    return model_from_dict(d, source=str(file))
