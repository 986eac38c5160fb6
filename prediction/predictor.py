r"""The predictor Ω of SPEC §7: observed history → predicted trajectory → cubic.

State of the chain: the **central second difference** of the positions on the model's
time grid,

.. math::

    a_k = \frac{x_{k+1} - 2 x_k + x_{k-1}}{Δt^2}, \qquad x_k = x(k Δt),

binned into acceleration bins.  ``a_k`` is the acceleration averaged over
``[t_{k-1}, t_{k+1}]`` with a triangular weight: the finite difference over ``2Δt`` *is* the
light smoothing, and no other filter is applied, so training and prediction compute the
state in exactly the same way (a smoothing filter would be centred inside a training track
but one-sided at the end of an observed history).  Rounding of the recorded positions to a
resolution ``r`` quantises ``a_k`` in steps of ``r/Δt²`` (1 m/s² for centimetres at
``Δt = 0.1`` s), which is why the evaluation excludes bins narrower than two such steps.

Pipeline of :meth:`Predictor.predict`:

1. **Initial-state estimation**: the observed positions are smoothed by the RTS smoother of
   :mod:`iamp.prediction.initial_state` (constant acceleration driven by white jerk of
   spectral density ``q = model.settings["jerk_psd"]``, default
   :data:`~iamp.prediction.initial_state.DEFAULT_JERK_PSD`; noise level estimated from the
   history).  ``x_0``, ``v_0`` are the smoothed position and speed at ``t = 0`` (``v_0 >= 0``);
   the constant-velocity and constant-acceleration baselines use the same estimates.  For a
   noise-free history on a quadratic the estimates are exact.
2. **Resample** the smoothed positions onto ``t_k = k·Δt``, ``k = -K..0``,
   ``K = ⌊duration/Δt⌋``, by linear interpolation.
3. **States** of the last ``n`` available nodes ``k = -n..-1`` (``a_0`` needs ``x_1``):
   one-hot vectors ``\hat x_{-n}, …, \hat x_{-1}``.
4. **Propagation** ``\hat x_k = Σ_i λ_i Q_i \hat x_{k-i}`` for ``k = 0..M``,
   ``M = ⌈t_f/Δt⌉``, and the expected accelerations ``ā_k = c · \hat x_k`` at the nodes
   (``c``: the mean training ``a`` within each bin).
5. **Integration** of the ``ā_k``, exact for an acceleration linear between the nodes, with
   the speed clamped at 0 (:func:`~iamp.prediction.kinematics.integrate_nodes`).  Without the
   clamp the positions are linear in the ``ā_k``, i.e. they are the model's expected positions.
6. **Samples** at ``t = 0, Δt, …`` up to ``t_f`` (the last step shorter if ``t_f`` is not a
   multiple of ``Δt``), and the **fit**: the cubic ``x_s(t) = c_0 + c_1 t + c_2 t² + c_3 t³``
   minimising ``Σ_k (x_s(t_k) - x(t_k))²`` over the samples.

Lateral motion is not predicted: the planners keep every surrounding vehicle in its lane
(SPEC: ``y`` constant); the evaluation reports the lateral error of that assumption.

Optionally (``n_samples > 0``) state paths are sampled from the chain, integrated the same
way from the centres of the sampled states, and position quantiles returned.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib import resources
from typing import TypedDict

import numpy as np
from numpy.typing import ArrayLike

from iamp.core.scenario import History
from iamp.prediction._typing import FloatArray, IntArray, PathLike, Seed
from iamp.prediction.initial_state import DEFAULT_JERK_PSD, _smooth
from iamp.prediction.kinematics import (
    cubic_fit,
    history_grid,
    integrate_nodes,
    integrate_positions,
    local_quadratic,
    second_differences,
)
from iamp.prediction.mtd import ModelFileError, MTDModel, readonly_array
from iamp.prediction.mtd.chain import expected_value
from iamp.prediction.training import (
    STATE_DEFINITION,
    bin_centres,
    symmetric_edges,
    track_accelerations,
    train_from_tracks,
)

__all__ = [
    "DEFAULT_MODEL_FILE",
    "STATE_DEFINITION",
    "Prediction",
    "Predictor",
    "bin_centres",
    "cubic_fit",
    "history_grid",
    "integrate_nodes",
    "local_quadratic",
    "second_differences",
    "symmetric_edges",
    "track_accelerations",
    "train_from_tracks",
]

#: Package-data file of the shipped model (``prediction/data/``).
DEFAULT_MODEL_FILE = "mtd_default.json"
#: Bytes of node probabilities :meth:`Predictor.predict_batch` holds at once (histories are
#: predicted in chunks below it: memory bounded whatever the model's ``dt``; the propagation's
#: buffer and its time-ordered copy hold up to twice this for a moment).
BATCH_BYTES = 64 << 20
#: Rows of node accelerations a :class:`Predictor` keeps (:meth:`Predictor._node_means`; about
#: 330 bytes each at the default ``dt`` over 8 s).
ABAR_CACHE_ROWS = 1 << 15


# ---------------------------------------------------------------------------------------
# the prediction
# ---------------------------------------------------------------------------------------

class _PredictionJSONBase(TypedDict):
    x_poly: list[float]
    t: list[float]
    x: list[float]
    v: list[float]
    a: list[float]
    model: str
    fit_rmse: float


class PredictionJSON(_PredictionJSONBase, total=False):
    """:meth:`Prediction.to_dict` (``quantiles``: positions at ``t`` per quantile, when sampled)."""

    quantiles: dict[str, list[float]]


@dataclass(frozen=True, eq=False)
class Prediction:
    """The output of Ω for one vehicle.

    Attributes
    ----------
    x_poly : tuple of 4 float
        Fitted cubic, ascending powers ``(c0, c1, c2, c3)``:
        ``x_s(t) = c0 + c1 t + c2 t² + c3 t³`` (SPEC §4; the paper's ``d, c, b, a``).
    t : numpy.ndarray
        Prediction times ``0, Δt, 2Δt, …, t_f`` (the last step is shorter if ``t_f`` is not
        a multiple of the model step).
    x : numpy.ndarray
        Predicted (expected) positions at ``t``, before the fit; ``x[0]`` is the last
        observed position.
    v : numpy.ndarray
        Speeds at ``t`` (central differences of the predicted positions).
    a : numpy.ndarray
        Expected state values ``ā_k = c · \\hat x_k`` at ``t`` (m/s²).
    probs : numpy.ndarray, shape (len(t), m)
        State distributions ``\\hat x_k`` at the nodes ``k = 0, 1, …``.
    model : str
        ``"builtin"`` or the model file path.
    fit_rmse : float
        RMS of the cubic fit residual over the samples [m].
    quantiles : dict
        ``{q: positions at t}`` from sampled chain paths (empty unless requested).
    n_samples : int
        Number of sampled paths behind ``quantiles``.

    See Also
    --------
    Predictor.predict : What makes one.
    """

    x_poly: tuple[float, ...]
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    probs: np.ndarray
    model: str
    fit_rmse: float
    quantiles: dict[float, FloatArray] = field(default_factory=dict)
    n_samples: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "x_poly", tuple(float(c) for c in self.x_poly))
        for name in ("t", "x", "v", "a", "probs"):
            object.__setattr__(self, name, readonly_array(getattr(self, name)))
        object.__setattr__(self, "quantiles", {float(q): readonly_array(v) for q, v in self.quantiles.items()})

    def x_fit(self, t: ArrayLike | None = None) -> FloatArray:
        """The fitted cubic :math:`x_s(t) = c_0 + c_1 t + c_2 t^2 + c_3 t^3` evaluated at ``t``.

        Parameters
        ----------
        t : array_like of float, optional
            Times [s] (default: the prediction times :attr:`t`).

        Returns
        -------
        numpy.ndarray
            Positions [m], the shape of ``t``.
        """
        times = self.t if t is None else np.asarray(t, dtype=float)
        out: FloatArray = np.polynomial.polynomial.polyval(times, self.x_poly)
        return out

    def to_dict(self) -> PredictionJSON:
        """The prediction as a JSON-ready dict (``iamp predict --json``).

        Returns
        -------
        dict
            ``x_poly``, ``t``, ``x``, ``v``, ``a`` (lists of float), ``model``, ``fit_rmse``,
            and ``quantiles`` (``{"0.1": positions at t, ...}``) when paths were sampled.
        """
        d: PredictionJSON = {"x_poly": list(self.x_poly), "t": self.t.tolist(), "x": self.x.tolist(),
             "v": self.v.tolist(), "a": self.a.tolist(), "model": self.model, "fit_rmse": self.fit_rmse}
        if self.quantiles:
            d["quantiles"] = {f"{q:g}": v.tolist() for q, v in self.quantiles.items()}
        return d


# ---------------------------------------------------------------------------------------
# the predictor
# ---------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=64)
def _grid_operator(t_bytes: bytes, K: int, dt: float, n: int) -> FloatArray:
    """``R`` with ``R @ x`` = the positions linearly resampled to the last ``n + 2`` grid nodes
    (dense, ``(n + 2) × K``; kept as the reference of :func:`_grid_weights`, which the predictor uses)."""
    idx, _, w, _ = _grid_weights(t_bytes, K, dt, n)
    R = np.zeros((idx.size, K))
    rows = np.arange(idx.size)
    R[rows, idx] += 1.0 - w
    R[rows, np.minimum(idx + 1, K - 1)] += w
    R.setflags(write=False)
    return R


@functools.lru_cache(maxsize=256)
def _grid_weights(t_bytes: bytes, K: int, dt: float, n: int) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """``(i, j, w, 1 - w)``: grid node ``r`` is ``(1 - w_r) x[i_r] + w_r x[j_r]``, ``j = min(i + 1, K - 1)``
    (linear interpolation at the last ``n + 2`` grid nodes, as ``np.interp``); O(n log K) instead of a
    ``K × K`` identity, computed once per sample times."""
    t = np.frombuffer(t_bytes, dtype=np.float64, count=K)
    tg, _ = history_grid(t, t, dt)
    tg = np.clip(tg[-(n + 2):], t[0], t[-1])
    idx = np.clip(np.searchsorted(t, tg, side="right") - 1, 0, K - 1)
    nxt = np.minimum(idx + 1, K - 1)
    span = t[nxt] - t[idx]
    w = np.where(span > 0, (tg - t[idx]) / np.where(span > 0, span, 1.0), 0.0)
    w1 = 1.0 - w
    for a in (idx, nxt, w, w1):
        a.setflags(write=False)
    return idx, nxt, w, w1


@functools.lru_cache(maxsize=256)
def _tail_weights(t_bytes: bytes, K: int, dt: float, n: int) -> tuple[int, IntArray, IntArray, FloatArray, FloatArray]:
    """``(first, i - first, j - first, w, 1 - w)`` of :func:`_grid_weights`: the interpolation reads the samples
    ``first..K-1`` alone (``first = min i``), counted from ``first``."""
    idx, nxt, w, w1 = _grid_weights(t_bytes, K, dt, n)
    first = int(idx.min()) if idx.size else K - 1
    i, j = idx - first, nxt - first
    i.setflags(write=False)
    j.setflags(write=False)
    return first, i, j, w, w1


@functools.lru_cache(maxsize=1)
def _default_model() -> MTDModel:
    name = f"iamp.prediction/data/{DEFAULT_MODEL_FILE}"
    ref = resources.files("iamp.prediction").joinpath("data", DEFAULT_MODEL_FILE)
    if not ref.is_file():
        raise ModelFileError("the shipped model is missing from the installed package "
                             "(iamp.prediction.evaluation.evaluate.train_default_model('package') rebuilds it)",
                             None, name)
    try:
        d = json.loads(ref.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"is not valid JSON ({exc})", None, name) from None
    return MTDModel.from_dict(d, source=name)


class Predictor:
    r"""Ω: an MTD model of the longitudinal acceleration plus the pipeline above.

    Parameters
    ----------
    model : MTDModel
        Must carry ``edges``, ``centres`` and ``dt`` (models trained with
        :func:`train_from_tracks` do).
    name : str
        Reported as :attr:`Prediction.model` (``"builtin"`` for the shipped model, else the
        file path).

    Attributes
    ----------
    dt : float
        The model's time step :math:`\Delta t` [s].
    min_history_s : float
        The shortest usable history, :math:`(n + 1)\Delta t` [s] for a model of order ``n``.

    Raises
    ------
    iamp.prediction.mtd.ModelFileError
        The model lacks ``edges``, ``centres`` or ``dt``.

    Examples
    --------
    >>> import iamp
    >>> predictor = iamp.Predictor.default()
    >>> predictor.name, predictor.min_history_s > 0
    ('builtin', True)
    """

    def __init__(self, model: MTDModel, name: str = "custom"):
        missing = [k for k in ("edges", "centres", "dt") if getattr(model, k) is None]
        if missing:
            raise ModelFileError(f"the model lacks {', '.join(missing)} needed for prediction", missing[0], name)
        assert model.dt is not None and model.centres is not None  # checked above
        self.model = model
        self.centres: FloatArray = model.centres
        self.name = str(name)
        self.dt = float(model.dt)
        self._fit_cache: dict[tuple[int, float], tuple[FloatArray, FloatArray]] = {}
        self._horizons: dict[float, tuple[int, FloatArray, FloatArray]] = {}

    def __repr__(self) -> str:
        return (f"Predictor(model={self.name!r}, order={self.model.order}, states={self.model.n_states}, "
                f"dt={self.dt:g})")

    @classmethod
    def default(cls) -> Predictor:
        """The predictor with the model shipped in the package (``prediction/data/mtd_default.json``).

        The model is read once per process; :func:`iamp.load_scenario` uses it for every
        history vehicle unless given another model file.

        Returns
        -------
        Predictor
            A predictor named ``"builtin"``.

        Raises
        ------
        iamp.prediction.mtd.ModelFileError
            The shipped model is missing from the installed package or is not valid.

        Examples
        --------
        >>> import iamp
        >>> predictor = iamp.Predictor.default()
        >>> predictor.name
        'builtin'
        """
        return cls(_default_model(), "builtin")

    @classmethod
    def from_file(cls, path: PathLike) -> Predictor:
        """A predictor with the model in a JSON file (as ``iamp train`` or :meth:`MTDModel.save` writes it).

        Parameters
        ----------
        path : str or os.PathLike
            The model file.

        Returns
        -------
        Predictor
            A predictor named by the path (:attr:`Prediction.model`).

        Raises
        ------
        iamp.prediction.mtd.ModelFileError
            The file cannot be read, is not JSON, or does not describe a valid model usable for
            prediction (the message names the file and the key).
        """
        return cls(MTDModel.load(path), str(path))

    # -- what the predictor needs ---------------------------------------------------------
    @property
    def min_history_s(self) -> float:
        """Shortest usable history [s]: ``(n + 1)·Δt`` (``n + 2`` grid nodes give ``n`` states)."""
        return (self.model.order + 1) * self.dt

    @property
    def min_samples(self) -> int:
        """Fewest raw samples: 3 (an acceleration needs three positions)."""
        return 3

    # -- prediction ------------------------------------------------------------------------
    def _horizon(self, tf: object) -> tuple[int, FloatArray]:
        M, t, _ = self._horizon_grid(tf)
        return M, t

    def _horizon_grid(self, tf: object) -> tuple[int, FloatArray, FloatArray]:
        """``(M, t, V)``: the nodes ``M``, the prediction times ``t`` and the cubic's Vandermonde matrix
        at ``t`` of the horizon ``tf`` (read-only; computed once per horizon)."""
        if isinstance(tf, bool) or not isinstance(tf, (int, float, np.integer, np.floating)):
            raise ValueError(f"tf must be a number (got {tf!r})")
        horizon = float(tf)
        if not (math.isfinite(horizon) and horizon > 0):
            raise ValueError(f"tf must be positive and finite (got {horizon})")
        cached = self._horizons.get(horizon)
        if cached is None:
            M = max(int(math.ceil(horizon / self.dt - 1e-9)), 1)
            t = np.asarray(self.dt * np.arange(M + 1), dtype=np.float64)
            t[-1] = horizon
            V = np.vander(t, 4, increasing=True)
            t.setflags(write=False)
            V.setflags(write=False)
            if len(self._horizons) > 64:
                self._horizons.clear()
            cached = self._horizons[horizon] = (M, t, V)
        return cached

    @property
    def jerk_psd(self) -> float:
        """Jerk spectral density ``q`` of the initial-state smoother [m²/s⁵] (``model.settings``)."""
        return float(self.model.settings.get("jerk_psd", DEFAULT_JERK_PSD))

    def initial_state(self, t_hist: FloatArray, X_hist: FloatArray) -> tuple[FloatArray, FloatArray, IntArray]:
        r"""The initial state of histories sharing the times ``t_hist`` (steps 1–3 above).

        The positions are RTS-smoothed, resampled to the model grid :math:`t_k = k\Delta t`, and their
        central second differences :math:`a_k = (x_{k+1} - 2x_k + x_{k-1})/\Delta t^2` binned into the
        chain's states.

        Parameters
        ----------
        t_hist : numpy.ndarray, shape (K,)
            Common history times [s] (strictly increasing, ending at 0).
        X_hist : numpy.ndarray, shape (B, K)
            Observed positions [m], one history per row.

        Returns
        -------
        x0 : numpy.ndarray, shape (B,)
            Smoothed position at ``t = 0`` [m].
        v0 : numpy.ndarray, shape (B,)
            Smoothed speed at ``t = 0`` [m/s], ``>= 0``.
        states : numpy.ndarray of int, shape (B, n)
            The bins of the last ``n`` second differences, oldest first.
        """
        t_hist = np.asarray(t_hist, dtype=float)
        first, idx, nxt, w, w1 = _tail_weights(t_hist.tobytes(), t_hist.size, self.dt, self.model.order)
        sm = _smooth(t_hist, X_hist, self.jerk_psd, None, first)  # the samples first..K-1 alone
        resampled = sm.x[:, idx] * w1 + sm.x[:, nxt] * w
        states = self.model.states(second_differences(resampled, self.dt))
        return sm.x[:, -1], np.maximum(sm.v[:, -1], 0.0), states

    def _node_accelerations(self, states: np.ndarray, M: int) -> tuple[np.ndarray, np.ndarray]:
        """``(\\hat x_k, ā_k)`` for ``k = 0..M`` from the last ``n`` states (batch)."""
        probs = self.model.propagate_batch(np.atleast_2d(states), M + 1)
        return probs, expected_value(probs, self.centres)

    @property
    def _abar_rows(self) -> dict[int, dict[bytes, FloatArray]]:
        """:meth:`_node_means`' rows, ``M`` -> (a past's states as bytes -> its ``ā_0..ā_M``), kept with
        the model: every predictor of the model (the closed loop makes one per episode) shares them."""
        store: dict[int, dict[bytes, FloatArray]] | None = self.model.__dict__.get("_abar_rows")
        if store is None:
            store = self.model.__dict__["_abar_rows"] = {}
        return store

    def forget_kept_rows(self) -> None:
        """Empty the node accelerations kept per past for this predictor's model
        (:meth:`_node_means`): later predictions compute them again, the same numbers."""
        self.model.__dict__.pop("_abar_rows", None)

    def _node_means(self, states: np.ndarray, M: int) -> FloatArray:
        """The ``ā_k`` of :meth:`_node_accelerations` alone, ``(B, M + 1)``, the same numbers, each
        distinct past propagated once per model (in a process).

        The chain's propagation depends on a history's ``n`` integer states alone, and they repeat:
        from period to period of the closed loop (a vehicle cruising keeps its bins) and between
        vehicles (about 93 % of the rows of a 60 s dense episode were seen before).  The propagation
        adds every entry's products one after another in a fixed order without BLAS
        (:func:`iamp.prediction.mtd.chain.propagate_batch`), so a row's numbers do not depend on the
        other rows of its batch: a kept row is the row a fresh batch would give, on any machine.
        Emptied when it holds :data:`ABAR_CACHE_ROWS` rows (a row recomputed is the same numbers).
        """
        S = np.ascontiguousarray(np.atleast_2d(states), dtype=np.int64)
        kept = self._abar_rows.setdefault(M, {})
        raw, w = S.tobytes(), S.shape[1] * S.itemsize  # each row's bytes, sliced from the batch's (C order)
        keys = [raw[i:i + w] for i in range(0, len(raw), w)] if w else [b""] * S.shape[0]
        new = [k for k in dict.fromkeys(keys) if k not in kept]
        if new:
            if sum(len(d) for d in self._abar_rows.values()) + len(new) > ABAR_CACHE_ROWS:
                for d in self._abar_rows.values():
                    d.clear()
            batch = np.frombuffer(b"".join(new), dtype=np.int64)
            _, abar = self._node_accelerations(batch.reshape(-1, S.shape[1]), M)
            for k, row in zip(new, abar):
                row.setflags(write=False)
                kept[k] = row
        if not keys:
            np.stack([])  # no rows: numpy's error, as ever
        out: FloatArray = np.concatenate([kept[k] for k in keys]).reshape(len(keys), M + 1)
        return out

    def predict(self, history: History, tf: float = 5.0, *, n_samples: int = 0, quantiles: Iterable[float] = (),
                seed: Seed = None) -> Prediction:
        """Predict the trajectory over ``[0, tf]`` and fit the cubic.

        Parameters
        ----------
        history : iamp.core.scenario.History
            Observed longitudinal history (strictly increasing ``t`` ending at 0).
        tf : float
            Horizon [s], > 0.
        n_samples : int
            Number of state paths sampled from the chain for :attr:`Prediction.quantiles`
            (0: none; 500 are drawn if ``quantiles`` is given with ``n_samples = 0``).
        quantiles : sequence of float in [0, 1]
            Position quantiles to report.
        seed : int or numpy.random.Generator, optional
            Seed of the sampling.

        Returns
        -------
        Prediction

        Raises
        ------
        iamp.core.errors.HistoryError
            The history is shorter than :attr:`min_history_s` or has fewer than
            :attr:`min_samples` samples (the error names the history field).
        ValueError
            ``tf`` is not a positive number or a quantile is outside [0, 1].

        Examples
        --------
        A vehicle observed for 2 s at 10 Hz, driving at 20 m/s and at ``x = 0`` now:

        >>> import numpy as np
        >>> import iamp
        >>> t = np.linspace(-2.0, 0.0, 21)
        >>> history = iamp.History(t=t, x=20.0 * t)
        >>> prediction = iamp.Predictor.default().predict(history, tf=5.0)
        >>> len(prediction.x_poly), round(prediction.x_poly[1], 1)   # the cubic; c1 is the speed
        (4, 20.0)
        >>> float(prediction.t[-1]), prediction.model
        (5.0, 'builtin')
        >>> float(prediction.x_fit(5.0))                             # x_s(5 s)
        99.2...
        """
        history.require(min_samples=self.min_samples, min_duration=self.min_history_s)
        M, t = self._horizon(tf)
        qs = tuple(float(q) for q in quantiles)
        if any(not (0.0 <= q <= 1.0) for q in qs):
            raise ValueError("quantiles must lie in [0, 1]")
        model = self.model
        x0s, v0s, st = self.initial_state(np.asarray(history.t, dtype=float), np.asarray(history.x, dtype=float))
        states = st[0]  # a_{-n} .. a_{-1}
        probs, abar = self._node_accelerations(states, M)
        x0, v0 = float(x0s[0]), float(v0s[0])
        x, v = integrate_nodes(x0, v0, abar, self.dt, t)
        x, v = x[0], v[0]
        a = np.interp(t, self.dt * np.arange(M + 1), abar[0])
        key = (M, float(t[-1]))
        cached = self._fit_cache.get(key)
        if cached is None:
            if len(self._fit_cache) > 64:
                self._fit_cache.clear()
            V = np.asarray(np.vander(t, 4, increasing=True), dtype=np.float64)
            cached = (np.asarray(np.linalg.pinv(V), dtype=np.float64), V)
            self._fit_cache[key] = cached
        coef = cached[0] @ x
        rmse = float(np.sqrt(np.mean((cached[1] @ coef - x) ** 2)))
        qdict: dict[float, FloatArray] = {}
        if qs and n_samples <= 0:
            n_samples = 500
        if n_samples > 0:
            paths = model.sample(states, M + 1, int(n_samples), seed)
            xs, _ = integrate_nodes(np.full(int(n_samples), x0), np.full(int(n_samples), v0),
                                    self.centres[paths], self.dt, t)
            qdict = {q: np.quantile(xs, q, axis=0) for q in qs}
        return Prediction(x_poly=coef, t=t, x=x, v=v, a=a, probs=probs[0], model=self.name, fit_rmse=rmse,
                          quantiles=qdict, n_samples=int(max(n_samples, 0)))

    # -- batch interface for the evaluation ------------------------------------------------
    def predict_batch(self, t_hist: np.ndarray, X_hist: np.ndarray, query: np.ndarray, tf: float,
                      *, cubic: bool = False) -> np.ndarray:
        """Vectorised :meth:`predict` for many histories sharing the same sample times.

        Parameters
        ----------
        t_hist : numpy.ndarray, shape (K,)
            Common history times (ending at 0).
        X_hist : numpy.ndarray, shape (B, K)
            Observed positions.
        query : numpy.ndarray, shape (Q,)
            Times in ``[0, tf]`` at which to report positions.
        tf : float
            Prediction horizon (the range of the cubic fit).
        cubic : bool
            Report the fitted cubic instead of the predicted trajectory.

        Returns
        -------
        numpy.ndarray, shape (B, Q)
            The same as :meth:`predict` one history at a time (to round-off).
        """
        t_hist = np.asarray(t_hist, dtype=float)
        X_hist = np.atleast_2d(np.asarray(X_hist, dtype=float))
        if (t_hist[-1] - t_hist[0]) + 1e-9 < self.min_history_s:
            raise ValueError(f"histories of {t_hist[-1] - t_hist[0]:g} s are shorter than the "
                             f"{self.min_history_s:g} s the model needs")
        M, t, V = self._horizon_grid(tf)
        # the node probabilities take B (M+1) m floats: histories go in chunks of at most
        # BATCH_BYTES (a model with the smallest legal dt has M = 5000 nodes over 5 s)
        rows = max(1, BATCH_BYTES // (8 * (M + 1) * (self.model.n_states + 4)))
        if X_hist.shape[0] > rows:
            return np.concatenate([self.predict_batch(t_hist, X_hist[s:s + rows], query, tf, cubic=cubic)
                                   for s in range(0, X_hist.shape[0], rows)])
        x0, v0, states = self.initial_state(t_hist, X_hist)
        abar = self._node_means(states, M)
        q = np.asarray(query, dtype=float)
        if not cubic:
            return integrate_positions(x0, v0, abar, self.dt, q)
        x = integrate_positions(x0, v0, abar, self.dt, t)
        C, *_ = np.linalg.lstsq(V, x.T, rcond=None)
        out: FloatArray = np.polynomial.polynomial.polyval(q, C)
        return out
