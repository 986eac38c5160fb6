r"""Finite differences, fits and the exact integration of the predicted accelerations.

Integration (:func:`integrate_nodes`), exact for an acceleration linear between node values
``ā_k`` at ``t_k = kΔt`` (``s ∈ [0, Δt]``, ``δ_k = ā_{k+1} - ā_k``):

.. math::

    v(t_k + s) = v_k + ā_k s + δ_k \frac{s^2}{2Δt}, \qquad
    x(t_k + s) = x_k + v_k s + ā_k \frac{s^2}{2} + δ_k \frac{s^3}{6Δt},

with the speed clamped at 0: if ``v_{k+1}`` would be negative the vehicle stops after
``v_k/|ā|`` with the interval's mean ``ā = (ā_k + ā_{k+1})/2``, moving ``v_k²/(2|ā|)``, and
stays stopped for the interval.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import ArrayLike

from iamp.prediction._typing import FloatArray, IntArray

__all__ = ["cubic_fit", "history_grid", "integrate_nodes", "integrate_positions", "local_quadratic",
           "second_differences"]


def history_grid(t: np.ndarray, x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Resample a history onto ``t_k = k·dt``, ``k = -K..0`` (linear interpolation)."""
    t = np.asarray(t, dtype=float)
    K = int(math.floor((t[-1] - t[0]) / dt + 1e-9))
    tg = dt * np.arange(-K, 1)
    tg[-1] = 0.0
    return tg, np.interp(tg, t, np.asarray(x, dtype=float))


def second_differences(x: np.ndarray, dt: float) -> np.ndarray:
    """``(x_{k+1} - 2 x_k + x_{k-1}) / dt²`` along the last axis (length ``K - 2``)."""
    xa = np.asarray(x, dtype=float)
    out: FloatArray = (xa[..., 2:] - 2.0 * xa[..., 1:-1] + xa[..., :-2]) / (dt * dt)
    return out


def cubic_fit(t: np.ndarray, x: np.ndarray) -> tuple[tuple[float, ...], float]:
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


def _foh_nodes(x0: FloatArray, v0: FloatArray, abar: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
    """Node positions and speeds (B, M+1) under linear-between-nodes acceleration, v >= 0."""
    B, M1 = abar.shape
    M = M1 - 1
    a0, a1 = abar[:, :-1], abar[:, 1:]
    dv = dt * 0.5 * (a0 + a1)
    vs = np.empty((B, M + 1))
    vs[:, 0] = v0
    dv.cumsum(axis=1, out=vs[:, 1:])
    vs[:, 1:] += v0[:, None]
    xs = np.empty((B, M + 1))
    if (vs >= 0.0).all():
        xs[:, 0] = x0
        (vs[:, :-1] * dt + dt * dt * (a0 / 3.0 + a1 / 6.0)).cumsum(axis=1, out=xs[:, 1:])
        xs[:, 1:] += x0[:, None]
        return xs, vs
    # a vehicle stops: every row is summed step by step, v_{k+1} = v_k + δv_k and
    # x_{k+1} = (x_k + v_k Δt) + Δt²(ā_k/3 + ā_{k+1}/6), so a row that never stops is the sequential
    # accumulation of these terms (``np.add.accumulate``: the same additions in the same order);
    # the rows that stop follow the clamped recursion in Python floats (the same IEEE operations)
    vs[:, 1:] = dv
    vs[:, 0] = v0
    np.add.accumulate(vs, axis=1, out=vs)
    steps = np.empty((B, 2 * M + 1))
    steps[:, 0] = x0
    steps[:, 1::2] = vs[:, :-1] * dt
    steps[:, 2::2] = dt * dt * (a0 / 3.0 + a1 / 6.0)
    np.add.accumulate(steps, axis=1, out=steps)
    xs[:] = steps[:, ::2]
    for b in np.flatnonzero((vs < 0.0).any(axis=1)).tolist():
        xs[b], vs[b] = _clamped_row(float(x0[b]), float(v0[b]), a0[b].tolist(), a1[b].tolist(), dv[b].tolist(), dt)
    return xs, vs


def _clamped_row(x: float, v: float, a0: list[float], a1: list[float], dv: list[float],
                 dt: float) -> tuple[list[float], list[float]]:
    """The nodes of one vehicle with the speed clamped at 0 (module docstring): if ``v_{k+1}`` would be
    negative it stops after ``v_k/|ā|`` with ``ā = (ā_k + ā_{k+1})/2`` (at most ``-1e-12``)."""
    xs, vs = [x], [v]
    for k in range(len(dv)):
        v_new = v + dv[k]
        x_new = x + v * dt + dt * dt * (a0[k] / 3.0 + a1[k] / 6.0)
        if v_new < 0.0:
            am = min(0.5 * (a0[k] + a1[k]), -1e-12)
            x_new = x + v * v / (2.0 * -am)
            v_new = 0.0
        xs.append(x_new)
        vs.append(v_new)
        x, v = x_new, v_new
    return xs, vs


@functools.lru_cache(maxsize=256)
def _query_steps(q_bytes: bytes, shape: tuple[int, ...], dt: float,
                 M: int) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """``(k, k + 1, s, s³)`` of the query times ``q``: the interval ``k`` (clipped to ``0..M-1``) and the
    time ``s = q - k dt`` into it, as a row ``(1, Q)`` (they depend on ``q``, ``dt`` and ``M`` only)."""
    q = np.frombuffer(q_bytes, dtype=np.float64).reshape(shape)
    k = np.clip(np.floor(q / dt + 1e-9).astype(int), 0, M - 1)
    s = (q - k * dt)[None, :]
    s3 = s ** 3
    k1 = k + 1
    for a in (k, k1, s, s3):
        a.setflags(write=False)
    return k, k1, s, s3


def _row(a: ArrayLike, B: int) -> FloatArray:
    """``a`` as a new float array of shape ``(B,)`` (a scalar or one value broadcast)."""
    if isinstance(a, np.ndarray) and a.shape == (B,):
        return np.array(a, dtype=float)
    return np.broadcast_to(np.asarray(a, dtype=float), (B,)).copy()


def integrate_nodes(x0: ArrayLike, v0: ArrayLike, abar: np.ndarray, dt: float,
                    query: ArrayLike) -> tuple[FloatArray, FloatArray]:
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
    x, v = _integrate(x0, v0, abar, dt, query, speeds=True)
    assert v is not None
    return x, v


def integrate_positions(x0: ArrayLike, v0: ArrayLike, abar: np.ndarray, dt: float, query: ArrayLike) -> FloatArray:
    """The positions of :func:`integrate_nodes` alone (the same numbers; the speeds at ``query`` are
    computed only where a vehicle stops, where the positions need them).

    Parameters
    ----------
    x0, v0, abar, dt, query
        As :func:`integrate_nodes`.

    Returns
    -------
    numpy.ndarray, shape (B, Q)
        The positions at ``query``.
    """
    return _integrate(x0, v0, abar, dt, query, speeds=False)[0]


def _integrate(x0: ArrayLike, v0: ArrayLike, abar: np.ndarray, dt: float, query: ArrayLike,
               speeds: bool) -> tuple[FloatArray, FloatArray | None]:
    """:func:`integrate_nodes` (the speeds ``None`` unless ``speeds`` or a vehicle stops in an interval)."""
    abar = np.atleast_2d(np.asarray(abar, dtype=float))
    B = abar.shape[0]
    x_start = _row(x0, B)
    v_start = np.maximum(_row(v0, B), 0.0)
    xs, vs = _foh_nodes(x_start, v_start, abar, dt)
    M = abar.shape[1] - 1
    q = np.ascontiguousarray(query, dtype=float)
    k, k1, s, s3 = _query_steps(q.tobytes(), q.shape, float(dt), M)
    ak = abar[:, k]
    d = abar[:, k1] - ak
    x = xs[:, k] + vs[:, k] * s + 0.5 * ak * s * s + d * s3 / (6.0 * dt)
    # inside an interval where the vehicle stops: hold the stopping point
    stopped = vs[:, k1] == 0.0
    v = None
    if speeds or stopped.any():
        v = vs[:, k] + ak * s + d * s * s / (2.0 * dt)
    if stopped.any():
        assert v is not None
        x_stop = xs[:, k1]
        x = np.where(stopped, np.minimum(x, x_stop), x)
        x = np.where(stopped & (v < 0), x_stop, x)
        v = np.where(stopped, np.maximum(v, 0.0), v)
    return x, (None if v is None else np.maximum(v, 0.0))
