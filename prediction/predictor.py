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

1. **Resample** the observed positions onto ``t_k = k·Δt``, ``k = -K..0``,
   ``K = ⌊duration/Δt⌋``, by linear interpolation.
2. **States** of the last ``n`` available nodes ``k = -n..-1`` (``a_0`` needs ``x_1``):
   one-hot vectors ``\hat x_{-n}, …, \hat x_{-1}``.
3. **Propagation** ``\hat x_k = Σ_i λ_i Q_i \hat x_{k-i}`` for ``k = 0..M``,
   ``M = ⌈t_f/Δt⌉``, and the expected accelerations ``ā_k = c · \hat x_k`` at the nodes
   (``c``: the mean training ``a`` within each bin).
4. **Initial speed** ``v_0``: slope at ``t = 0`` of the least-squares quadratic through the
   raw history samples with ``t >= -w`` (at least the last three samples), ``w`` =
   ``model.settings["v0_window_s"]`` (chosen on validation data together with the
   constant-velocity baseline, which uses the same estimate).  ``x_0`` is the last observed
   position.
5. **Integration**, exact for the acceleration that is linear between the node values
   (``s ∈ [0, Δt]``, ``δ_k = ā_{k+1} - ā_k``):

   .. math::

       v(t_k + s) = v_k + ā_k s + δ_k \frac{s^2}{2Δt}, \qquad
       x(t_k + s) = x_k + v_k s + ā_k \frac{s^2}{2} + δ_k \frac{s^3}{6Δt},

   with the speed clamped at 0: if ``v_{k+1}`` would be negative the vehicle stops after
   ``v_k/|ā|`` with the interval's mean ``ā = (ā_k + ā_{k+1})/2``, moving ``v_k²/(2|ā|)``,
   and stays stopped for the interval.  Without the clamp the positions are linear in the
   ``ā_k``, i.e. they are the model's expected positions.
6. **Samples** at ``t = 0, Δt, …`` up to ``t_f`` (the last step shorter if ``t_f`` is not a
   multiple of ``Δt``), and the **fit**: the cubic ``x_s(t) = c_0 + c_1 t + c_2 t² + c_3 t³``
   minimising ``Σ_k (x_s(t_k) - x(t_k))²`` over the samples.

Optionally (``n_samples > 0``) state paths are sampled from the chain, integrated the same
way from the centres of the sampled states, and position quantiles returned.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from iamp.prediction.mtd import ModelFileError, MTDModel, readonly_array

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
#: Initial-speed fit window [s] for models that do not set ``settings["v0_window_s"]``.
DEFAULT_V0_WINDOW = 0.2
#: Written into trained models.
STATE_DEFINITION = ("longitudinal acceleration a_k = (x_{k+1} - 2 x_k + x_{k-1}) / dt^2 of the positions "
                    "linearly resampled to the model step dt [m/s^2]")


# ---------------------------------------------------------------------------------------
# finite differences and fits
# ---------------------------------------------------------------------------------------

def history_grid(t: np.ndarray, x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Resample a history onto ``t_k = k·dt``, ``k = -K..0`` (linear interpolation)."""
    t = np.asarray(t, dtype=float)
    K = int(math.floor((t[-1] - t[0]) / dt + 1e-9))
    tg = dt * np.arange(-K, 1)
    tg[-1] = 0.0
    return tg, np.interp(tg, t, np.asarray(x, dtype=float))


def second_differences(x: np.ndarray, dt: float) -> np.ndarray:
    """``(x_{k+1} - 2 x_k + x_{k-1}) / dt²`` along the last axis (length ``K - 2``)."""
    x = np.asarray(x, dtype=float)
    return (x[..., 2:] - 2.0 * x[..., 1:-1] + x[..., :-2]) / (dt * dt)


def cubic_fit(t: np.ndarray, x: np.ndarray) -> tuple[tuple, float]:
    """Least-squares cubic ``c0 + c1 t + c2 t² + c3 t³``; returns ``(c, rmse)``."""
    t = np.asarray(t, dtype=float)
    V = np.vander(t, 4, increasing=True)
    c, *_ = np.linalg.lstsq(V, np.asarray(x, dtype=float), rcond=None)
    rmse = float(np.sqrt(np.mean((V @ c - x) ** 2)))
    return tuple(float(ci) for ci in c), rmse


def local_quadratic(t: np.ndarray, X: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed and acceleration at ``t = 0`` from a least-squares quadratic.

    Parameters
    ----------
    t : numpy.ndarray, shape (K,)
        Sample times (increasing, ending at 0), shared by all rows.
    X : numpy.ndarray, shape (K,) or (B, K)
        Positions.
    window_s : float
        The fit uses the samples with ``t >= -window_s`` (at least the last three).

    Returns
    -------
    v0, a0 : numpy.ndarray, shape (B,) (scalars for 1-D ``X``)
        ``c_1`` and ``2 c_2`` of ``x ≈ c_0 + c_1 t + c_2 t²``.
    """
    t = np.asarray(t, dtype=float)
    keep = max(int(np.count_nonzero(t >= -window_s - 1e-9)), 3)
    if t.size < 3:
        raise ValueError("needs at least 3 samples")
    tt = t[-keep:]
    V = np.vander(tt, 3, increasing=True)
    G = np.linalg.pinv(V)  # (3, keep)
    C = np.asarray(X, dtype=float)[..., -keep:] @ G.T
    return C[..., 1], 2.0 * C[..., 2]


def _foh_nodes(x0, v0, abar, dt):
    """Node positions and speeds (B, M+1) under linear-between-nodes acceleration, v >= 0."""
    B, M1 = abar.shape
    M = M1 - 1
    a0, a1 = abar[:, :-1], abar[:, 1:]
    dv = dt * 0.5 * (a0 + a1)
    vs = np.empty((B, M + 1))
    vs[:, 0] = v0
    np.cumsum(dv, axis=1, out=vs[:, 1:])
    vs[:, 1:] += v0[:, None]
    xs = np.empty((B, M + 1))
    if np.all(vs >= 0.0):
        xs[:, 0] = x0
        np.cumsum(vs[:, :-1] * dt + dt * dt * (a0 / 3.0 + a1 / 6.0), axis=1, out=xs[:, 1:])
        xs[:, 1:] += x0[:, None]
        return xs, vs
    xs[:, 0], vs[:, 0] = x0, v0
    for k in range(M):
        v, x = vs[:, k], xs[:, k]
        v_new = v + dv[:, k]
        x_new = x + v * dt + dt * dt * (a0[:, k] / 3.0 + a1[:, k] / 6.0)
        stop = v_new < 0.0
        if np.any(stop):
            am = np.minimum(0.5 * (a0[:, k] + a1[:, k]), -1e-12)
            x_new = np.where(stop, x + v * v / (2.0 * -am), x_new)
            v_new = np.where(stop, 0.0, v_new)
        xs[:, k + 1], vs[:, k + 1] = x_new, v_new
    return xs, vs


def integrate_nodes(x0, v0, abar: np.ndarray, dt: float, query) -> tuple[np.ndarray, np.ndarray]:
    """Positions and speeds at ``query`` for accelerations linear between node values.

    Parameters
    ----------
    x0, v0 : array_like, shape (B,)
        Position and speed at ``t = 0`` (``v0 < 0`` is taken as 0).
    abar : numpy.ndarray, shape (B, M + 1)
        Accelerations at ``t_k = k dt``, ``k = 0..M``.
    dt : float
    query : array_like, shape (Q,)
        Times in ``[0, M dt]``.

    Returns
    -------
    x, v : numpy.ndarray, shape (B, Q)
        Exact (see the module docstring), with the speed clamped at 0.
    """
    abar = np.atleast_2d(np.asarray(abar, dtype=float))
    B = abar.shape[0]
    x0 = np.broadcast_to(np.asarray(x0, dtype=float), (B,)).copy()
    v0 = np.maximum(np.broadcast_to(np.asarray(v0, dtype=float), (B,)), 0.0)
    xs, vs = _foh_nodes(x0, v0, abar, dt)
    M = abar.shape[1] - 1
    q = np.asarray(query, dtype=float)
    k = np.clip(np.floor(q / dt + 1e-9).astype(int), 0, M - 1)
    s = (q - k * dt)[None, :]
    ak, d = abar[:, k], (abar[:, k + 1] - abar[:, k])
    xk, vk = xs[:, k], vs[:, k]
    x = xk + vk * s + 0.5 * ak * s * s + d * s ** 3 / (6.0 * dt)
    v = vk + ak * s + d * s * s / (2.0 * dt)
    # inside an interval where the vehicle stops: hold the stopping point
    stopped = vs[:, k + 1] == 0.0
    if np.any(stopped):
        x = np.where(stopped, np.minimum(x, xs[:, k + 1]), x)
        x = np.where(stopped & (v < 0), xs[:, k + 1], x)
        v = np.where(stopped, np.maximum(v, 0.0), v)
    return x, np.maximum(v, 0.0)


# ---------------------------------------------------------------------------------------
# the prediction
# ---------------------------------------------------------------------------------------

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
    """

    x_poly: tuple
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    probs: np.ndarray
    model: str
    fit_rmse: float
    quantiles: dict = field(default_factory=dict)
    n_samples: int = 0

    def __post_init__(self):
        object.__setattr__(self, "x_poly", tuple(float(c) for c in self.x_poly))
        for name in ("t", "x", "v", "a", "probs"):
            object.__setattr__(self, name, readonly_array(getattr(self, name)))
        object.__setattr__(self, "quantiles", {float(q): readonly_array(v) for q, v in self.quantiles.items()})

    def x_fit(self, t=None) -> np.ndarray:
        """The fitted cubic evaluated at ``t`` (default: the prediction times)."""
        t = self.t if t is None else np.asarray(t, dtype=float)
        return np.polynomial.polynomial.polyval(t, self.x_poly)

    def to_dict(self) -> dict:
        """JSON-ready dict (``x_poly``, ``t``, ``x``, ``v``, ``a``, ``model``, ``fit_rmse``)."""
        d = {"x_poly": list(self.x_poly), "t": self.t.tolist(), "x": self.x.tolist(),
             "v": self.v.tolist(), "a": self.a.tolist(), "model": self.model, "fit_rmse": self.fit_rmse}
        if self.quantiles:
            d["quantiles"] = {f"{q:g}": v.tolist() for q, v in self.quantiles.items()}
        return d


# ---------------------------------------------------------------------------------------
# the predictor
# ---------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def _default_model() -> MTDModel:
    name = f"iamp.prediction/data/{DEFAULT_MODEL_FILE}"
    ref = resources.files("iamp.prediction").joinpath("data", DEFAULT_MODEL_FILE)
    if not ref.is_file():
        raise ModelFileError("the shipped model is missing from the installed package "
                             "(iamp.prediction.evaluate.train_default_model('package') rebuilds it)", None, name)
    try:
        d = json.loads(ref.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"is not valid JSON ({exc})", None, name) from None
    return MTDModel.from_dict(d, source=name)


class Predictor:
    """Ω: an MTD model of the longitudinal acceleration plus the pipeline above.

    Parameters
    ----------
    model : MTDModel
        Must carry ``edges``, ``centres`` and ``dt`` (models trained with
        :func:`train_from_tracks` do).
    name : str
        Reported as :attr:`Prediction.model` (``"builtin"`` for the shipped model, else the
        file path).
    """

    def __init__(self, model: MTDModel, name: str = "custom"):
        missing = [k for k in ("edges", "centres", "dt") if getattr(model, k) is None]
        if missing:
            raise ModelFileError(f"the model lacks {', '.join(missing)} needed for prediction", missing[0], name)
        self.model = model
        self.name = str(name)
        self.dt = float(model.dt)
        self._fit_cache: dict = {}

    def __repr__(self) -> str:
        return (f"Predictor(model={self.name!r}, order={self.model.order}, states={self.model.n_states}, "
                f"dt={self.dt:g})")

    @classmethod
    def default(cls) -> Predictor:
        """The predictor with the model shipped in ``prediction/data/mtd_default.json``."""
        return cls(_default_model(), "builtin")

    @classmethod
    def from_file(cls, path) -> Predictor:
        """A predictor with the model in a JSON file (:meth:`MTDModel.save`)."""
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
    def _horizon(self, tf) -> tuple[int, np.ndarray]:
        if isinstance(tf, bool) or not isinstance(tf, (int, float, np.integer, np.floating)):
            raise ValueError(f"tf must be a number (got {tf!r})")
        tf = float(tf)
        if not (math.isfinite(tf) and tf > 0):
            raise ValueError(f"tf must be positive and finite (got {tf})")
        M = max(int(math.ceil(tf / self.dt - 1e-9)), 1)
        t = self.dt * np.arange(M + 1)
        t[-1] = tf
        return M, t

    @property
    def v0_window_s(self) -> float:
        """Window of the initial-speed fit [s] (``model.settings["v0_window_s"]``, default 0.2)."""
        return float(self.model.settings.get("v0_window_s", DEFAULT_V0_WINDOW))

    def _node_accelerations(self, states: np.ndarray, M: int) -> tuple[np.ndarray, np.ndarray]:
        """``(\\hat x_k, ā_k)`` for ``k = 0..M`` from the last ``n`` states (batch)."""
        probs = self.model.propagate_batch(np.atleast_2d(states), M + 1)
        return probs, probs @ self.model.centres

    def predict(self, history, tf: float = 5.0, *, n_samples: int = 0, quantiles=(), seed=None) -> Prediction:
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
        """
        history.require(min_samples=self.min_samples, min_duration=self.min_history_s)
        M, t = self._horizon(tf)
        qs = tuple(float(q) for q in quantiles)
        if any(not (0.0 <= q <= 1.0) for q in qs):
            raise ValueError("quantiles must lie in [0, 1]")
        model = self.model
        n = model.order
        _, xg = history_grid(history.t, history.x, self.dt)
        states = model.states(second_differences(xg[-(n + 2):], self.dt))  # a_{-n} .. a_{-1}
        probs, abar = self._node_accelerations(states, M)
        x0 = float(history.x[-1])
        v0 = max(float(local_quadratic(history.t, history.x, self.v0_window_s)[0]), 0.0)
        x, v = integrate_nodes(x0, v0, abar, self.dt, t)
        x, v = x[0], v[0]
        a = np.interp(t, self.dt * np.arange(M + 1), abar[0])
        key = (M, t[-1])
        cached = self._fit_cache.get(key)
        if cached is None:
            if len(self._fit_cache) > 64:
                self._fit_cache.clear()
            V = np.vander(t, 4, increasing=True)
            cached = self._fit_cache[key] = (np.linalg.pinv(V), V)
        coef = cached[0] @ x
        rmse = float(np.sqrt(np.mean((cached[1] @ coef - x) ** 2)))
        qdict = {}
        if qs and n_samples <= 0:
            n_samples = 500
        if n_samples > 0:
            paths = model.sample(states, M + 1, int(n_samples), seed)
            xs, _ = integrate_nodes(np.full(int(n_samples), x0), np.full(int(n_samples), v0),
                                    model.centres[paths], self.dt, t)
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
        M, t = self._horizon(tf)
        model = self.model
        n = model.order
        tg, _ = history_grid(t_hist, X_hist[0], self.dt)
        tg = tg[-(n + 2):]
        R = np.stack([np.interp(tg, t_hist, e) for e in np.eye(t_hist.size)], axis=1)  # linear in x
        states = model.states(second_differences(X_hist @ R.T, self.dt))
        _, abar = self._node_accelerations(states, M)
        v0 = np.maximum(local_quadratic(t_hist, X_hist, self.v0_window_s)[0], 0.0)
        q = np.asarray(query, dtype=float)
        if not cubic:
            return integrate_nodes(X_hist[:, -1], v0, abar, self.dt, q)[0]
        x, _ = integrate_nodes(X_hist[:, -1], v0, abar, self.dt, t)
        V = np.vander(t, 4, increasing=True)
        C, *_ = np.linalg.lstsq(V, x.T, rcond=None)
        return np.polynomial.polynomial.polyval(q, C)


# ---------------------------------------------------------------------------------------
# training from trajectory tables
# ---------------------------------------------------------------------------------------

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


def track_accelerations(tracks, dt: float) -> list[np.ndarray]:
    """State values ``a_k`` of every track, computed as the predictor does.

    Each track's positions are linearly resampled onto ``t0 + k·dt`` and differenced
    (:func:`second_differences`); tracks with fewer than 3 resampled samples are skipped.
    """
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


def train_from_tracks(tracks, *, dt: float, edges, order: int, estimator: str = "mle",
                      v0_window_s: float = DEFAULT_V0_WINDOW, provenance: dict | None = None,
                      **fit_kwargs) -> MTDModel:
    """Train an MTD acceleration model on a :class:`~iamp.prediction.tracks.Tracks` table.

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
    v0_window_s : float
        Window of the predictor's initial-speed fit [s], stored in ``model.settings``.
    provenance : dict, optional
        Merged into the model's provenance (with the data's ``meta`` and sizes).
    **fit_kwargs
        Passed to :func:`iamp.prediction.mtd.fit`.

    Returns
    -------
    MTDModel
        With ``centres`` the mean training ``a_k`` per bin.
    """
    from iamp.prediction.mtd import fit

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
               dt=dt, state=STATE_DEFINITION, settings={"v0_window_s": float(v0_window_s)}, provenance=prov,
               **fit_kwargs)


def _jsonable(obj):
    try:
        json.dumps(obj, allow_nan=False)
        return obj
    except (TypeError, ValueError):
        return str(obj)
