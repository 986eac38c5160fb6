r"""Evaluation windows, error metrics and the constant-velocity / -acceleration baselines.

Every track is resampled to ``EVAL_DT = 0.1`` s and cut into windows of ``HISTORY_S = 3`` s of
history (31 samples, ``t = -3..0``) and ``FUTURE_S = 5`` s of future (``t = 0.1..5``), starting
every ``STRIDE_S = 1`` s.  For each method the longitudinal error ``e_w(τ) = \hat x_w(τ) - x_w(τ)``
of window ``w`` is summarised as

.. math::

    \mathrm{RMSE}(h) = \sqrt{\tfrac1W \sum_w e_w(h)^2}, \quad h = 1..5\ \mathrm{s}, \qquad
    \mathrm{ADE} = \tfrac{1}{W F} \sum_w \sum_{τ} |e_w(τ)|, \qquad
    \mathrm{FDE} = \tfrac1W \sum_w |e_w(5)|.

The baselines take ``x_0``, ``v_0`` from the same RTS smoother as the predictor
(:mod:`iamp.prediction.initial_state`).  The constant-acceleration baseline takes ``a_0`` from
the least-squares quadratic over the last :data:`CA_WINDOW_S` of the history (``2 c_2``): the
smoother's ``a_0`` follows every short-lived acceleration of raw NGSIM positions and CA then
extrapolates it for 5 s (measured on the US-101 CSV, 1257 windows, RMSE at 5 s: CV 6.25 m; CA with
the smoother's ``a_0`` 26.76, with the quadratic over the last 1 s 14.92, 2 s 10.79, 3 s 8.77 m).
For white position noise ``σ`` the quadratic's ``a_0`` has standard deviation
``≈ 2σ\sqrt{180/(N T^4)}`` (``N`` samples over ``T`` s): 0.05 m/s² for 10 cm over 3 s at 10 Hz,
so CA's error stays bounded (``tests/test_leader.py``).  Exact for a history on a quadratic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from iamp.prediction._typing import BoolArray, FloatArray, IntArray, Progress
from iamp.prediction.initial_state import DEFAULT_JERK_PSD, smooth_histories
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.tracks.table import Tracks

__all__ = [
    "CA_WINDOW_S",
    "EVAL_DT",
    "FUTURE_S",
    "HISTORY_S",
    "HORIZONS",
    "STRIDE_S",
    "WindowMetrics",
    "Windows",
    "baseline_ca",
    "baseline_cv",
    "evaluate_methods",
    "make_windows",
    "metrics",
    "robust_ca",
]

#: Horizons [s] of the RMSE table.
HORIZONS = (1.0, 2.0, 3.0, 4.0, 5.0)
#: Window of the quadratic giving the constant-acceleration baseline's ``a_0`` [s].
CA_WINDOW_S = 3.0
#: Window geometry [s].
HISTORY_S, FUTURE_S, STRIDE_S, EVAL_DT = 3.0, 5.0, 1.0, 0.1


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
    t0 : numpy.ndarray, shape (W,)
        Time of ``t = 0`` of every window in its track's clock [s].
    Y_hist, Y_fut : numpy.ndarray or None, shapes (W, K), (W, F)
        Lateral positions (shifted likewise), when the data have them.
    """

    t_hist: FloatArray
    X_hist: FloatArray
    t_fut: FloatArray
    X_fut: FloatArray
    track_id: IntArray
    t0: FloatArray | None = None
    Y_hist: FloatArray | None = None
    Y_fut: FloatArray | None = None

    @property
    def n(self) -> int:
        """Number of windows."""
        return int(self.X_hist.shape[0])

    def take(self, index: IntArray | BoolArray | slice) -> Windows:
        """The windows selected by ``index`` (boolean mask or integer indices)."""
        def sub(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[index]
        return Windows(self.t_hist, self.X_hist[index], self.t_fut, self.X_fut[index], self.track_id[index],
                       sub(self.t0), sub(self.Y_hist), sub(self.Y_fut))


def make_windows(tracks: Tracks, history_s: float = HISTORY_S, future_s: float = FUTURE_S,
                 stride_s: float = STRIDE_S, dt: float = EVAL_DT) -> Windows:
    """Cut every track (resampled to ``dt`` by linear interpolation) into windows.

    A window starts every ``stride_s`` seconds from the track's start, for every track at
    least ``history_s + future_s`` long; the position at ``t = 0`` of each window is
    subtracted from all its positions (lateral positions likewise).
    """
    kh = int(round(history_s / dt))
    kf = int(round(future_s / dt))
    ks = max(int(round(stride_s / dt)), 1)
    H: list[FloatArray] = []
    F: list[FloatArray] = []
    YH: list[FloatArray] = []
    YF: list[FloatArray] = []
    ids: list[IntArray] = []
    t0s: list[FloatArray] = []
    lateral = tracks.y is not None
    y_all = tracks.y if tracks.y is not None else tracks.x
    cuts = np.flatnonzero(np.diff(tracks.track_id)) + 1
    for tid, t, x, y in zip(np.split(tracks.track_id, cuts), np.split(tracks.t, cuts), np.split(tracks.x, cuts),
                            np.split(y_all, cuts)):
        if t.size < 2:
            continue
        K = int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
        if K < kh + kf + 1:
            continue
        tg = t[0] + dt * np.arange(K)
        starts = np.arange(0, K - kh - kf, ks)
        idx = starts[:, None] + np.arange(kh + kf + 1)[None, :]
        seg = np.interp(tg, t, x)[idx]
        seg = seg - seg[:, kh:kh + 1]
        H.append(seg[:, :kh + 1])
        F.append(seg[:, kh + 1:])
        if lateral:
            ys = np.interp(tg, t, y)[idx]
            ys = ys - ys[:, kh:kh + 1]
            YH.append(ys[:, :kh + 1])
            YF.append(ys[:, kh + 1:])
        ids.append(np.full(starts.size, int(tid[0]), dtype=np.int64))
        t0s.append(tg[starts + kh])
    if not H:
        raise ValueError(f"no track is long enough for {history_s:g} s + {future_s:g} s windows")
    t_hist = np.asarray(dt * np.arange(-kh, 1), dtype=np.float64)
    t_hist[-1] = 0.0
    t_fut = np.asarray(dt * np.arange(1, kf + 1), dtype=np.float64)
    return Windows(t_hist, np.concatenate(H), t_fut, np.concatenate(F), np.concatenate(ids),
                   np.concatenate(t0s), np.concatenate(YH) if lateral else None,
                   np.concatenate(YF) if lateral else None)


class WindowMetrics(TypedDict):
    """:func:`metrics`: RMSE at each horizon, their mean, ADE and FDE [m] over ``n_windows`` windows."""

    rmse: list[float]
    rmse_mean: float
    ade: float
    fde: float
    n_windows: int


def metrics(pred: FloatArray, win: Windows, horizons: tuple[float, ...] = HORIZONS) -> WindowMetrics:
    """RMSE at ``horizons``, ADE and FDE (metres) of predictions ``(W, F)`` at ``win.t_fut``."""
    err = pred - win.X_fut
    cols = [int(np.argmin(np.abs(win.t_fut - h))) for h in horizons]
    rmse = [float(np.sqrt(np.mean(err[:, c] ** 2))) for c in cols]
    return {"rmse": rmse, "rmse_mean": float(np.mean(rmse)), "ade": float(np.mean(np.abs(err))),
            "fde": float(np.mean(np.abs(err[:, -1]))), "n_windows": int(win.n)}


def initial_kinematics(win: Windows, jerk_psd: float = DEFAULT_JERK_PSD) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(x_0, v_0, a_0)`` of every window from the RTS smoother (``v_0 >= 0``), as the predictor."""
    sm = smooth_histories(win.t_hist, win.X_hist, jerk_psd)
    return sm.x[:, -1], np.maximum(sm.v[:, -1], 0.0), sm.a[:, -1]


def baseline_cv(win: Windows, jerk_psd: float = DEFAULT_JERK_PSD) -> FloatArray:
    """Constant velocity ``x_0 + v_0 τ`` (``x_0``, ``v_0`` from :func:`initial_kinematics`)."""
    x0, v0, _ = initial_kinematics(win, jerk_psd)
    out: FloatArray = x0[:, None] + v0[:, None] * win.t_fut[None, :]
    return out


def baseline_ca(win: Windows, jerk_psd: float = DEFAULT_JERK_PSD, window_s: float = CA_WINDOW_S) -> FloatArray:
    """Constant acceleration ``x_0 + v_0 s + ½ a_0 s²``, ``s = min(τ, v_0/(-a_0))`` when braking (stops).

    ``x_0``, ``v_0`` from the smoother, ``a_0`` from the quadratic over the last ``window_s``
    (module docstring).
    """
    x0, v0, _ = initial_kinematics(win, jerk_psd)
    return robust_ca(win, x0, v0, window_s)


def robust_ca(win: Windows, x0: FloatArray, v0: FloatArray, window_s: float = CA_WINDOW_S) -> FloatArray:
    """Constant acceleration from ``x_0``, ``v_0`` with ``a_0`` from the least-squares quadratic over
    the last ``window_s`` of each history (robust to raw-position noise), stopping when braking."""
    from iamp.prediction.kinematics import local_quadratic

    _, a0 = local_quadratic(win.t_hist, win.X_hist, window_s)
    tau = win.t_fut[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        stop = np.where(a0 < 0, v0 / np.where(a0 < 0, -a0, 1.0), np.inf)[:, None]
    s = np.minimum(tau, stop)
    out: FloatArray = x0[:, None] + v0[:, None] * s + 0.5 * a0[:, None] * s * s
    return out


def lateral_constant(win: Windows) -> FloatArray | None:
    """The planners' lateral assumption: ``y(τ) = y(0)`` (every vehicle keeps its lane offset)."""
    if win.Y_hist is None:
        return None
    out: FloatArray = np.repeat(win.Y_hist[:, -1:], win.t_fut.size, axis=1)
    return out


def evaluate_methods(win: Windows, models: dict[str, MTDModel], jerk_psd: float = DEFAULT_JERK_PSD,
                     progress: Progress | None = None) -> dict[str, WindowMetrics]:
    """Metrics of the baselines and of every model in ``models`` (name → MTDModel).

    For each model ``name`` two rows are produced: ``name`` (raw propagated trajectory)
    and ``name + "-cubic"`` (the least-squares cubic over ``[0, 5]`` s).  The baselines use
    the smoother with ``jerk_psd``; every model its own ``settings["jerk_psd"]``.
    """
    from iamp.prediction.predictor import Predictor

    total = 2 + len(models)
    out = {"cv": metrics(baseline_cv(win, jerk_psd), win)}
    if progress is not None:
        progress(1, total)
    out["ca"] = metrics(baseline_ca(win, jerk_psd), win)
    if progress is not None:
        progress(2, total)
    for k, (name, model) in enumerate(models.items()):
        P = Predictor(model, name)
        out[name] = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S), win)
        out[name + "-cubic"] = metrics(P.predict_batch(win.t_hist, win.X_hist, win.t_fut, FUTURE_S,
                                                       cubic=True), win)
        if progress is not None:
            progress(3 + k, total)
    return out
