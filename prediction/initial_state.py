r"""Initial-state estimation from a noisy observed history: a Rauch–Tung–Striebel smoother.

Used alike by the predictor Ω and the constant-velocity / constant-acceleration baselines,
so that they differ only in what they assume about the future.

Model (constant acceleration driven by white jerk): state ``s = (x, v, a)``, and over a
step ``h`` between samples

.. math::

    s_{k+1} = F_h s_k + w_k, \quad
    F_h = \begin{pmatrix} 1 & h & h^2/2 \\ 0 & 1 & h \\ 0 & 0 & 1 \end{pmatrix}, \quad
    \operatorname{Cov} w_k = q \begin{pmatrix} h^5/20 & h^4/8 & h^3/6 \\ h^4/8 & h^3/3 & h^2/2 \\
    h^3/6 & h^2/2 & h \end{pmatrix},

observed as ``z_k = x_k + ε_k``, ``ε_k ~ N(0, σ^2)``.  ``q`` [m²/s⁵] is the jerk spectral
density (:data:`DEFAULT_JERK_PSD`, chosen on validation data, see
:func:`iamp.prediction.evaluate_state.choose_jerk_psd`).

Noise level ``σ`` of each history, from the data itself: for every four consecutive samples
the weights ``c_i = 1 / Π_{j≠i}(t_i - t_j)`` annihilate every quadratic (they form the third
divided difference), so ``d = Σ_i c_i z_i / \|c\|`` is free of the motion up to the jerk
(``≈ j h³``, 1 mm for 1 m/s³ at 0.1 s) and has variance ``σ²`` for white noise; ``σ`` is the
robust scale ``1.4826 · median |d|``, floored at :data:`NOISE_FLOOR_M`.

Initialisation (diffuse): the quadratic through the first three samples gives ``s_2`` and its
covariance ``σ² J Jᵀ`` (``J`` maps the three samples to ``(x, v, a)`` at ``t_2``); then the
Kalman filter runs forward and the RTS smoother backward,

.. math::

    G_k = P_{k|k} F^T P_{k+1|k}^{-1}, \qquad
    \hat s_{k|K} = \hat s_{k|k} + G_k (\hat s_{k+1|K} - F \hat s_{k|k}).

At the last sample (``t = 0``) the smoothed and filtered estimates coincide, so the initial
state uses only the past.  For data exactly on a quadratic the estimates are exact (the model
contains constant acceleration and the initialisation is unbiased).
"""

from __future__ import annotations

import collections
import functools
from dataclasses import dataclass

import numpy as np

from iamp.prediction._typing import FloatArray

__all__ = ["DEFAULT_JERK_PSD", "NOISE_FLOOR_M", "SmoothedHistory", "noise_sigma", "smooth_histories"]

#: Jerk spectral density ``q`` [m²/s⁵], chosen on the validation windows of the shipped data by
#: :func:`iamp.prediction.evaluation.select.choose_jerk_psd` (constant-velocity RMSE, mean over
#: 1..5 s, averaged over added noise of 0, 3 and 10 cm; 20 569 windows): q = 1: 3.81 m, 3: 3.76,
#: **10: 3.73**, 30: 3.74, 100: 3.79 (clean: 3.58 / 3.57 / 3.56 / 3.55 / 3.55; the former 0.2-s
#: quadratic fit scores 3.55 clean but 4.26 and 8.39 with 3 and 10 cm of noise).
DEFAULT_JERK_PSD = 10.0
#: Smallest measurement noise assumed [m] (positions recorded to 1 cm have σ ≈ 2.9 mm).
NOISE_FLOOR_M = 1e-3


@dataclass(frozen=True)
class SmoothedHistory:
    """Smoothed positions, speeds and accelerations of ``B`` histories at their ``K`` samples.

    Attributes
    ----------
    x, v, a : numpy.ndarray, shape (B, K)
    sigma : numpy.ndarray, shape (B,)
        The measurement noise used [m].
    """

    x: FloatArray
    v: FloatArray
    a: FloatArray
    sigma: FloatArray


def noise_sigma(t: FloatArray, Z: FloatArray, floor: float = NOISE_FLOOR_M) -> FloatArray:
    """Robust per-row noise level from normalised third divided differences (module docstring)."""
    t = np.asarray(t, dtype=float)
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    K = t.size
    if K < 4:
        return np.full(Z.shape[0], float(floor))
    C = _third_differences(t.tobytes(), K)
    D = np.zeros((Z.shape[0], K - 3))
    for i in range(4):
        D = D + C[:, i] * Z[:, i:K - 3 + i]
    sig: FloatArray = 1.4826 * _row_median(np.abs(D))
    return np.maximum(sig, float(floor))


@functools.lru_cache(maxsize=64)
def _third_differences(t_bytes: bytes, K: int) -> FloatArray:
    """The normalised weights ``c_i / |c|`` of the third divided differences of the samples ``t``
    (``(K - 3, 4)``; they depend on the sample times only, so one computation serves every history)."""
    t = np.frombuffer(t_bytes, dtype=np.float64, count=K)
    T = np.stack([t[i:K - 3 + i] for i in range(4)], axis=1)  # (K-3, 4)
    C = np.ones_like(T)
    for i in range(4):
        for j in range(4):
            if i != j:
                C[:, i] = C[:, i] / (T[:, i] - T[:, j])
    out: FloatArray = C / np.linalg.norm(C, axis=1, keepdims=True)
    out.setflags(write=False)
    return out


def _row_median(A: FloatArray) -> FloatArray:
    """``np.median(A, axis=1)`` bit for bit (the middle element, or the mean ``(a + b) / 2`` of the
    two middle ones, of each row: what numpy's median computes after its partition) without its
    generic machinery; rows with a NaN go through ``np.median``."""
    n = A.shape[1]
    if n == 0 or not np.isfinite(A).all():
        return np.asarray(np.median(A, axis=1), dtype=float)
    h = n // 2
    if n % 2:
        return np.partition(A, h, axis=1)[:, h].copy()
    P = np.partition(A, (h - 1, h), axis=1)
    return np.asarray((P[:, h - 1] + P[:, h]) / 2, dtype=float)


def _transition(h: float, q: float) -> tuple[FloatArray, FloatArray]:
    F = np.array([[1.0, h, 0.5 * h * h], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
    W = q * np.array([[h ** 5 / 20, h ** 4 / 8, h ** 3 / 6],
                      [h ** 4 / 8, h ** 3 / 3, h ** 2 / 2],
                      [h ** 3 / 6, h ** 2 / 2, h]])
    return F, W


def smooth_histories(t: FloatArray, Z: FloatArray, jerk_psd: float = DEFAULT_JERK_PSD,
                     sigma: FloatArray | float | None = None) -> SmoothedHistory:
    """RTS-smoothed ``(x, v, a)`` of histories sharing the sample times ``t``.

    Parameters
    ----------
    t : numpy.ndarray, shape (K,)
        Strictly increasing sample times, ``K >= 3``.
    Z : numpy.ndarray, shape (K,) or (B, K)
        Observed positions.
    jerk_psd : float
        ``q`` [m²/s⁵], > 0.
    sigma : float or array of shape (B,), optional
        Measurement noise [m]; estimated per history (:func:`noise_sigma`) when omitted.

    Returns
    -------
    SmoothedHistory
        Arrays of shape ``(B, K)`` (``B = 1`` for a 1-D ``Z``).

    For fixed ``t``, ``σ`` and ``q`` the gains do not depend on the data, so the smoother is a
    linear map ``z ↦ (x, v, a)``.  For short histories (``K <=`` :data:`OPERATOR_MAX_K`, the
    evaluation's many windows of 3 s) that map is computed once as a dense ``3 × K × K``
    operator (by smoothing the unit vectors) and cached, at most :data:`OPERATOR_CACHE_BYTES`
    in all; longer histories run the recursions on the data themselves, linear in ``K`` in
    time and memory (the two agree to rounding, tested).  Estimated noise levels are rounded to
    two significant digits (the estimate's own sampling error is far larger, about
    ``1/√(K-3)``).
    """
    return _smooth(t, Z, jerk_psd, sigma, 0)


def _smooth(t: FloatArray, Z: FloatArray, jerk_psd: float, sigma: FloatArray | float | None,
            first: int) -> SmoothedHistory:
    """:func:`smooth_histories` at the samples ``first..K-1`` alone (arrays ``(B, K - first)``).

    The dense operator's product is an ``einsum`` that accumulates each output over the samples ``j`` in
    their order, ``((0 + z_0 M[c, 0, k]) + z_1 M[c, 1, k]) + …``, whatever outputs it is asked for and however
    they are laid out: the operator's columns ``first..K-1`` of the three components side by side, one row
    per sample (:func:`_operator_tail`, ``"bj,jq->bq"``: one long run of outputs per sample instead of
    ``3 B`` short ones), give the numbers of :func:`smooth_histories`' ``"bj,cjk->cbk"`` bit for bit
    (``tests/test_prediction_smoothed_tail.py``) at a fraction of the work, and less again when few samples
    are needed (the predictor reads the last ``n + 2`` grid nodes of a 3-s history: 11 of 31 samples).
    """
    t = np.asarray(t, dtype=float)
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    B, K = Z.shape
    if K < 3 or t.size != K:
        raise ValueError("needs at least 3 samples, as many times as positions")
    if not jerk_psd > 0:
        raise ValueError(f"jerk_psd must be positive (got {jerk_psd})")
    if sigma is None:
        raw = noise_sigma(t, Z).tolist()
        rounded = {s: float(f"{s:.2g}") for s in set(raw)}  # (σ >= 0: no signed zeros to tell apart)
        sig = np.asarray([rounded[s] for s in raw])
    else:
        sig = np.broadcast_to(np.asarray(sigma, dtype=float), (B,)).copy()
    if K > OPERATOR_MAX_K:  # linear: the recursions on the data, O(B·K) time and memory
        s = _rts(t, Z, float(jerk_psd), sig)
        return SmoothedHistory(s.x[:, first:], s.v[:, first:], s.a[:, first:], sig)
    W = K - first
    out = np.empty((3, B, W))
    key = t.tobytes()
    if np.isnan(sig).any():  # np.unique groups the NaNs; == cannot
        levels, inverse = np.unique(sig, return_inverse=True)
        groups = [(float(level), inverse == j) for j, level in enumerate(levels)]
    else:  # np.unique's levels, in its order, without its sort of the whole array
        distinct = sorted(set(sig.tolist()))
        # one level (the closed loop's histories sit at the noise floor): every row, without a mask
        groups = [(distinct[0], slice(None))] if len(distinct) == 1 else [(level, sig == level) for level in distinct]
    for level, rows in groups:
        Mq = _operator_tail(key, K, float(level), float(jerk_psd), first)  # (K, 3 W)
        # the rows C-contiguous, as a mask's selection gives them (einsum's loops follow the strides)
        Zr = np.ascontiguousarray(Z[rows])
        out[:, rows] = np.einsum("bj,jq->bq", Zr, Mq).reshape(-1, 3, W).transpose(1, 0, 2)
    return SmoothedHistory(out[0], out[1], out[2], sig)


#: Longest history smoothed through a cached dense operator (3·K² doubles: 6.3 MB at 512);
#: longer ones run the recursions on the data (linear in K).
OPERATOR_MAX_K = 512
#: Bytes the cached operators may hold in all (least recently used dropped first).
OPERATOR_CACHE_BYTES = 64 * 1024 * 1024
_OPERATORS: collections.OrderedDict[tuple[bytes, int, float, float], FloatArray] = collections.OrderedDict()


def _operator(t_bytes: bytes, K: int, sigma: float, jerk_psd: float) -> FloatArray:
    """``M[c, j, k]``: component ``c`` (x, v, a) at sample ``k`` of the smoothed unit vector ``e_j``.

    Cached by ``(t, σ, q)``; the cache is bounded in bytes (:data:`OPERATOR_CACHE_BYTES`).
    """
    key = (t_bytes, K, sigma, jerk_psd)
    M = _OPERATORS.get(key)
    if M is not None:
        _OPERATORS.move_to_end(key)
        return M
    t = np.frombuffer(t_bytes, dtype=np.float64, count=K)
    s = _rts(t, np.eye(K), jerk_psd, np.full(K, sigma))
    M = np.stack([s.x, s.v, s.a])
    M.setflags(write=False)
    _OPERATORS[key] = M
    while sum(m.nbytes for m in _OPERATORS.values()) > OPERATOR_CACHE_BYTES and len(_OPERATORS) > 1:
        _OPERATORS.popitem(last=False)
    return M


_TAILS: collections.OrderedDict[tuple[bytes, int, float, float, int], FloatArray] = collections.OrderedDict()


def _operator_tail(t_bytes: bytes, K: int, sigma: float, jerk_psd: float, first: int) -> FloatArray:
    """``Mq[j, c W + r] = M[c, j, first + r]`` (``W = K - first``): :func:`_operator`'s columns ``first..K-1``,
    the three components side by side, C-contiguous; cached like the operators (their own bound)."""
    key = (t_bytes, K, sigma, jerk_psd, first)
    Mq = _TAILS.get(key)
    if Mq is not None:
        _TAILS.move_to_end(key)
        return Mq
    M = _operator(t_bytes, K, sigma, jerk_psd)
    Mq = np.ascontiguousarray(M[:, :, first:].transpose(1, 0, 2)).reshape(K, 3 * (K - first))
    Mq.setflags(write=False)
    _TAILS[key] = Mq
    while sum(m.nbytes for m in _TAILS.values()) > OPERATOR_CACHE_BYTES and len(_TAILS) > 1:
        _TAILS.popitem(last=False)
    return Mq


def _rts(t: FloatArray, Z: FloatArray, jerk_psd: float, sig: FloatArray) -> SmoothedHistory:
    """The Kalman filter and RTS recursions (module docstring) for rows ``Z`` with noise ``sig``."""
    B, K = Z.shape
    R = sig * sig  # (B,)
    # diffuse initialisation: the quadratic through samples 0..2, its state at t_2
    t0, t1, t2 = t[0] - t[2], t[1] - t[2], 0.0
    V = np.array([[1.0, t0, t0 * t0], [1.0, t1, t1 * t1], [1.0, t2, t2 * t2]])
    J = np.diag([1.0, 1.0, 2.0]) @ np.linalg.inv(V)  # samples -> (x, v, a) at t_2
    m = Z[:, :3] @ J.T  # (B, 3)
    P = R[:, None, None] * (J @ J.T)[None]  # (B, 3, 3)
    means = np.empty((B, K, 3))
    covs = np.empty((B, K, 3, 3))
    pred_means = np.empty((B, K, 3))
    pred_covs = np.empty((B, K, 3, 3))
    means[:, 2], covs[:, 2] = m, P
    Fs: list[FloatArray] = [np.eye(3)] * K
    for k in range(3, K):
        F, W = _transition(float(t[k] - t[k - 1]), float(jerk_psd))
        Fs[k] = F
        m = m @ F.T
        P = F @ P @ F.T + W
        pred_means[:, k], pred_covs[:, k] = m, P
        S = P[:, 0, 0] + R  # innovation variance (B,)
        Kg = P[:, :, 0] / S[:, None]  # gain (B, 3)
        m = m + Kg * (Z[:, k] - m[:, 0])[:, None]
        P = P - Kg[:, :, None] * P[:, None, 0, :]
        P = 0.5 * (P + np.transpose(P, (0, 2, 1)))
        means[:, k], covs[:, k] = m, P
    sm = means.copy()
    for k in range(K - 2, 1, -1):
        F = Fs[k + 1]
        G = covs[:, k] @ F.T @ np.linalg.inv(pred_covs[:, k + 1])  # (B, 3, 3)
        sm[:, k] = means[:, k] + np.einsum("bij,bj->bi", G, sm[:, k + 1] - pred_means[:, k + 1])
    for k in (1, 0):  # before the initialisation: the deterministic motion back from s_2
        F, _ = _transition(float(t[k] - t[2]), 0.0)
        sm[:, k] = sm[:, 2] @ F.T
    return SmoothedHistory(sm[..., 0], sm[..., 1], sm[..., 2], sig)
