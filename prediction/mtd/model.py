"""The trained MTD model (:class:`MTDModel`) and its file errors.

See :mod:`iamp.prediction.mtd` for the mathematics; propagation and sampling live in
:mod:`iamp.prediction.mtd.chain`, the JSON file format in :mod:`iamp.prediction.mtd.io`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from iamp.core.errors import IampError
from iamp.prediction._typing import FloatArray, IntArray, PathLike, Seed, StateSequences

from .counts import _lag_probs, aic, bic, lag_table, n_parameters

__all__ = ["FORMAT", "MTDModel", "ModelFileError", "readonly_array"]

#: ``format`` tag written into model files.
FORMAT = "iamp-mtd/1"

class ModelFileError(IampError, ValueError):
    """A model file that cannot be read or does not describe a valid MTD model.

    Parameters
    ----------
    message : str
        What is wrong.
    key : str, optional
        The offending JSON key.
    source : str, optional
        The file the model came from.
    """

    def __init__(self, message: str, key: str | None = None, source: str | None = None):
        self.message = message
        self.key = key
        self.source = source
        parts = [str(p) for p in (source, f"key '{key}'" if key else None) if p]
        super().__init__(": ".join(parts + [message]))


# ---------------------------------------------------------------------------------------
# the model file and the summary
# ---------------------------------------------------------------------------------------


class BinsJSON(TypedDict):
    """The state bins of a model file: what they discretise, their interior edges and centres."""

    quantity: str
    edges: list[float] | None
    centres: list[float] | None


#: A model file (:func:`~iamp.prediction.mtd.io.model_to_dict`, SPEC §4); functional form: ``lambda`` is a
#: keyword.
ModelJSON = TypedDict("ModelJSON", {
    "format": str, "kind": str, "orientation": str, "order": int, "n_states": int, "dt": float | None,
    "state": str | None, "settings": dict[str, float], "bins": BinsJSON, "estimator": str, "lambda": list[float],
    "Q": list[list[list[float]]], "counts": list[list[list[float]]] | list[list[list[int]]] | None,
    "loglik": float | None, "n_obs": int, "n_parameters": int, "aic": float | None, "bic": float | None,
    "fit_info": dict[str, object], "provenance": dict[str, object]})

#: :meth:`MTDModel.summary`: order, states, estimator, λ, ℓ, N, k, AIC, BIC.
ModelSummary = TypedDict("ModelSummary", {
    "order": int, "n_states": int, "dt": float | None, "estimator": str, "lambda": list[float], "loglik": float,
    "n_obs": int, "n_parameters": int, "aic": float, "bic": float})


# ---------------------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------------------

def readonly_array(a: ArrayLike) -> FloatArray:
    """A float copy of ``a`` that cannot be written to (for immutable results)."""
    out: FloatArray = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class MTDModel:
    """A trained MTD model (immutable).

    Attributes
    ----------
    Q : numpy.ndarray, shape (n, m, m)
        ``Q[i-1]`` is the column-stochastic lag-``i`` matrix,
        ``Q[i-1][j, k] = P(x_t = j | x_{t-i} = k)``.
    lam : numpy.ndarray, shape (n,)
        Lag weights on the simplex.
    estimator : str
        ``"mle"``, ``"mle-lambda"``, ``"lp"`` or ``"given"``.
    edges : numpy.ndarray or None, shape (m - 1,)
        Interior bin edges of the physical quantity (acceleration, m/s²); values below
        ``edges[0]`` fall in state 0, values at or above ``edges[-1]`` in state ``m-1``.
    centres : numpy.ndarray or None, shape (m,)
        Representative value of each state (used for the expected acceleration
        ``c · \\hat x_t``).
    dt : float or None
        Time step of the chain [s].
    state : str or None
        What the states discretise (free text, e.g. how the acceleration is computed).
    settings : dict
        Settings of the code that uses the model (e.g. the predictor's ``v0_window_s``).
    counts : numpy.ndarray or None, shape (n, m, m)
        The observed lag-``i`` counts the model was fitted to.
    loglik, n_obs : float, int
        Training log-likelihood and number of scored transitions.
    provenance : dict
        Where the training data came from and how the model was built.
    fit_info : dict
        Convergence details (iterations, tolerance, certificate).
    """

    Q: FloatArray
    lam: FloatArray
    estimator: str = "given"
    edges: FloatArray | None = None
    centres: FloatArray | None = None
    dt: float | None = None
    state: str | None = None
    settings: dict[str, float] = field(default_factory=dict)
    counts: FloatArray | None = None
    loglik: float = float("nan")
    n_obs: int = 0
    provenance: dict[str, object] = field(default_factory=dict)
    fit_info: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        Q = np.array(self.Q, dtype=float)
        lam = np.array(self.lam, dtype=float).ravel()
        if Q.ndim != 3 or Q.shape[1] != Q.shape[2] or Q.shape[0] < 1:
            raise ValueError(f"Q must have shape (n, m, m) (got {Q.shape})")
        n, m, _ = Q.shape
        if lam.shape != (n,):
            raise ValueError(f"lam must have {n} entries (got {lam.shape})")
        if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(lam))):
            raise ValueError("Q and lam must be finite")
        if np.any(Q < -1e-12) or np.any(np.abs(Q.sum(axis=1) - 1.0) > 1e-8):
            raise ValueError("every column of every Q_i must be a probability distribution")
        if np.any(lam < -1e-12) or abs(lam.sum() - 1.0) > 1e-8:
            raise ValueError("lam must lie on the simplex (λ_i >= 0, Σλ_i = 1)")
        Q = np.clip(Q, 0.0, None)  # only round-off negatives (>= -1e-12) reach this
        lam = np.clip(lam, 0.0, None)
        object.__setattr__(self, "Q", readonly_array(Q))
        object.__setattr__(self, "lam", readonly_array(lam))
        if self.edges is not None:
            e = np.array(self.edges, dtype=float).ravel()
            if e.shape != (m - 1,) or np.any(np.diff(e) <= 0) or not np.all(np.isfinite(e)):
                raise ValueError(f"edges must be {m - 1} strictly increasing finite numbers")
            object.__setattr__(self, "edges", readonly_array(e))
        if self.centres is not None:
            c = np.array(self.centres, dtype=float).ravel()
            if c.shape != (m,) or not np.all(np.isfinite(c)):
                raise ValueError(f"centres must be {m} finite numbers")
            object.__setattr__(self, "centres", readonly_array(c))
        if self.counts is not None:
            cnt = np.array(self.counts, dtype=float)
            if cnt.shape != (n, m, m) or np.any(cnt < 0):
                raise ValueError(f"counts must be non-negative with shape {(n, m, m)}")
            object.__setattr__(self, "counts", readonly_array(cnt))
        if self.dt is not None:
            if not (math.isfinite(float(self.dt)) and float(self.dt) > 0):
                raise ValueError("dt must be a positive number")
            object.__setattr__(self, "dt", float(self.dt))
        object.__setattr__(self, "provenance", dict(self.provenance))
        object.__setattr__(self, "settings", dict(self.settings))
        object.__setattr__(self, "fit_info", dict(self.fit_info))

    # -- sizes and information criteria ------------------------------------------------
    @property
    def order(self) -> int:
        """Order ``n`` of the chain."""
        return int(self.Q.shape[0])

    @property
    def n_states(self) -> int:
        """Number of states ``m``."""
        return int(self.Q.shape[1])

    @property
    def n_parameters(self) -> int:
        """``k = n m (m - 1) + (n - 1)``."""
        return n_parameters(self.n_states, self.order)

    @property
    def aic(self) -> float:
        """``AIC = 2k - 2ℓ`` of the training data."""
        return aic(self.loglik, self.n_parameters)

    @property
    def bic(self) -> float:
        """``BIC = k ln N - 2ℓ`` of the training data."""
        return bic(self.loglik, self.n_parameters, self.n_obs)

    # -- likelihood ---------------------------------------------------------------------
    def log_likelihood(self, sequences: StateSequences) -> tuple[float, int]:
        """Log-likelihood ``ℓ = Σ_t log Σ_i λ_i q^{(i)}_{x_t x_{t-i}}`` of ``sequences``.

        Returns
        -------
        (float, int)
            ``ℓ`` (``-inf`` if a transition has probability 0) and the number ``N`` of
            scored transitions (times ``t >= n`` of every sequence).
        """
        rows = lag_table(sequences, self.order, self.n_states)  # no rows: ℓ = 0 (empty sum), N = 0
        p = _lag_probs(self.Q, rows) @ self.lam
        with np.errstate(divide="ignore"):
            return float(np.sum(np.log(p))), int(rows.shape[0])

    def transition_probabilities(self, past: ArrayLike) -> FloatArray:
        """``P(x_t = · | x_{t-1}, ..., x_{t-n})`` for a past given oldest-to-newest."""
        states = np.asarray(past, dtype=np.int64)
        if states.size < self.order:
            raise ValueError(f"needs the last {self.order} states")
        out: FloatArray = np.zeros(self.n_states)
        for i in range(self.order):
            out = out + self.lam[i] * self.Q[i][:, states[-1 - i]]
        return out

    # -- states -------------------------------------------------------------------------
    def states(self, values: ArrayLike) -> IntArray:
        """Map physical values (e.g. accelerations) to state indices with :attr:`edges`."""
        if self.edges is None:
            raise ValueError("this model has no bin edges")
        return np.searchsorted(self.edges, np.asarray(values, dtype=float), side="right")

    # -- propagation and sampling --------------------------------------------------------

    # -- propagation and sampling (mathematics in iamp.prediction.mtd.chain) -------------
    def propagate(self, init: ArrayLike, steps: int) -> FloatArray:
        r"""Propagate ``\hat x_t = Σ_i λ_i Q_i \hat x_{t-i}``; see :func:`~iamp.prediction.mtd.chain.propagate`."""
        from .chain import propagate

        return propagate(self, init, steps)

    def propagate_batch(self, init_states: IntArray, steps: int) -> FloatArray:
        """Vectorised :meth:`propagate`; see :func:`~iamp.prediction.mtd.chain.propagate_batch`."""
        from .chain import propagate_batch

        return propagate_batch(self, init_states, steps)

    def sample(self, init: ArrayLike, steps: int, n_samples: int, rng: Seed = None) -> IntArray:
        """State paths drawn from the chain; see :func:`~iamp.prediction.mtd.chain.sample`."""
        from .chain import sample

        return sample(self, init, steps, n_samples, rng)

    # -- persistence (file format in iamp.prediction.mtd.io) ------------------------------
    def to_dict(self) -> ModelJSON:
        """A JSON-serialisable description (see :func:`~iamp.prediction.mtd.io.model_to_dict`)."""
        from .io import model_to_dict

        return model_to_dict(self)

    def save(self, path: PathLike) -> Path:
        """Write the model as JSON, atomically (temporary file + ``os.replace``)."""
        from .io import save_model

        return save_model(self, path)

    @classmethod
    def from_dict(cls, d: object, source: str | None = None) -> MTDModel:
        """Build a model from :meth:`to_dict` output; raises :class:`ModelFileError`."""
        from .io import model_from_dict

        return model_from_dict(d, source)

    @classmethod
    def load(cls, path: PathLike) -> MTDModel:
        """Read a model written by :meth:`save`; raises :class:`ModelFileError`."""
        from .io import load_model

        return load_model(path)

    def summary(self) -> ModelSummary:
        """The headline numbers: order, states, estimator, λ, ℓ, N, k, AIC, BIC."""
        return {"order": self.order, "n_states": self.n_states, "dt": self.dt,
                "estimator": self.estimator, "lambda": self.lam.tolist(), "loglik": self.loglik,
                "n_obs": self.n_obs, "n_parameters": self.n_parameters, "aic": self.aic,
                "bic": self.bic}

