r"""Propagation and sampling of an MTD chain.

Marginal propagation (the paper's eq. ``prediction``): with ``\hat x_{t-i}`` the state
distributions of the last ``n`` steps (one-hot for observed states),

.. math::

    \hat x_t = \sum_{i=1}^{n} λ_i\, Q_i\, \hat x_{t-i}.

Sampling uses the latent-lag form: at every step a lag ``i`` is drawn with probability
``λ_i`` and the next state from column ``x_{t-i}`` of ``Q_i``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from iamp.prediction._typing import FloatArray, IntArray, Seed

if TYPE_CHECKING:
    from .model import MTDModel

__all__ = ["SPREAD_BYTES", "expected_value", "propagate", "propagate_batch", "sample"]

#: Bytes of the spread distributions :func:`propagate_batch` holds (``m`` times a distribution; longer
#: propagations reuse the buffer, larger batches go in chunks of rows).
SPREAD_BYTES = 16 << 20


def _initial_distributions(model: MTDModel, init: ArrayLike) -> FloatArray:
    past = np.asarray(init)
    if past.ndim == 1:
        idx = past.astype(np.int64)
        if idx.size < model.order:
            raise ValueError(f"needs at least {model.order} initial states (got {idx.size})")
        if idx.min() < 0 or idx.max() >= model.n_states:
            raise ValueError("initial states out of range")
        D = np.zeros((idx.size, model.n_states))
        D[np.arange(idx.size), idx] = 1.0
        return D
    if past.ndim == 2 and past.shape[1] == model.n_states and past.shape[0] >= model.order:
        return np.asarray(past, dtype=float)
    raise ValueError("init must be a state sequence or an array of distributions (T, m)")

def propagate(model: MTDModel, init: ArrayLike, steps: int) -> FloatArray:
    r"""Propagate state distributions ``\hat x_t = Σ_i λ_i Q_i \hat x_{t-i}``.

    Parameters
    ----------
    init : array_like
        The past, oldest first: either at least ``n`` state indices (turned into one-hot
        vectors) or an array ``(T, m)`` of distributions with ``T >= n``.
    steps : int
        Number of future steps.

    Returns
    -------
    numpy.ndarray, shape (steps, m)
        Row ``s`` is ``\hat x`` at ``s + 1`` steps after the last given state.

    Notes
    -----
    The arithmetic is :func:`propagate_batch`'s (one implementation): the same numbers, bit for bit.
    """
    D = _initial_distributions(model, init)
    n = model.order
    past = D[-1:-n - 1:-1][:, None, :]  # (n, 1, m), newest first
    out: FloatArray = _propagate(model, past, int(steps))[0]
    return out


def propagate_batch(model: MTDModel, init_states: IntArray, steps: int) -> FloatArray:
    r"""Vectorised :meth:`propagate` for many one-hot pasts.

    Parameters
    ----------
    init_states : numpy.ndarray of int, shape (B, T)
        ``B`` pasts of ``T >= n`` states each, oldest first.
    steps : int

    Returns
    -------
    numpy.ndarray, shape (B, steps, m)

    Notes
    -----
    Every entry is one sequential sum, in a fixed order,

    .. math::

        \hat x_t[j] = \Big(\big((W_1[j,0]\,x_{t-1}[0] + W_1[j,1]\,x_{t-1}[1]) + …\big)
                      + W_2[j,0]\,x_{t-2}[0] + …\Big) + … + W_n[j,m-1]\,x_{t-n}[m-1]

    with ``W_i = λ_i Q_i``: the ``n·m`` products of a step are formed elementwise and added one after
    another by one reduction along the outer axis of a C-contiguous buffer.  No BLAS product is used,
    so a row's numbers do not depend on the other rows of the batch, on their number, on the machine's
    BLAS or on its CPU (:meth:`iamp.prediction.predictor.Predictor._node_means` keeps rows on that
    ground; ``tests/test_loop_speed_prediction.py`` checks every entry against plain Python floats).
    """
    S = np.asarray(init_states, dtype=np.int64)
    n = model.order
    past = np.eye(model.n_states)[S[:, :-n - 1:-1].T]  # (n, B, m), newest first
    return _propagate(model, past, int(steps))


def _propagate(model: MTDModel, past: FloatArray, steps: int) -> FloatArray:
    """The propagation of :func:`propagate_batch` from ``past`` ``(n, B, m)``, newest first.

    The distributions are held spread along a last axis, ``X[r, k, b, j] = \\hat x_τ[b, k]`` for every
    ``j``, newest at the lowest row ``r``: the lags of a step (newest first) are then a contiguous block
    ``X[a : a + n]``, and their products with ``W`` spread alike are one elementwise product of two
    contiguous arrays (a broadcast product costs numpy a buffered copy of both operands, and the closed
    loop's batches are small: numpy's per-call work, not the arithmetic, is the propagation's time).
    Each step is one product, one reduction into the output and one spread copy of its result into
    ``X[a - 1]``; when the block reaches row 0 it is moved to the end of ``X`` (a copy: the same
    numbers).  ``X`` holds at most :data:`SPREAD_BYTES` (rows of the batch are propagated in chunks
    when needed: no sum mixes two rows, so chunks give the same numbers).
    """
    n, B, m = past.shape
    row_bytes = 8 * m * m  # one distribution of one row, spread
    rows = max(1, SPREAD_BYTES // (row_bytes * min(n + steps, 64)))
    if B > rows:
        return np.concatenate([_propagate(model, past[:, r:r + rows], steps) for r in range(0, B, rows)])
    T = min(n + steps, max(n + 1, SPREAD_BYTES // (row_bytes * max(B, 1))))  # time rows of X
    W = _lag_operators(model)  # (n, m, m): W[i, j, k] = λ_i Q_i[j, k]
    X = np.empty((T, m, B, m))
    X[T - n:] = past.transpose(0, 2, 1)[:, :, :, None]
    # Wb[i, k, b, j] = W_i[j, k] for every b
    Wb = np.ascontiguousarray(np.broadcast_to(W.transpose(0, 2, 1)[:, :, None, :], (n, m, B, m)))
    P = np.empty((n, m, B, m))  # P[i, k, b, j] = x_{t-1-i}[b, k] · W_i[j, k]
    flat = P.reshape(n * m, B, m)
    out = np.empty((steps, B, m))  # out[s] = \\hat x at step s
    spread = out.transpose(0, 2, 1)[:, :, :, None]  # (steps, m, B, 1): [s, k, b, .] = out[s, b, k]
    multiply, reduce = np.multiply, np.add.reduce
    a = T - n
    for s in range(steps):
        if a == 0:
            X[T - n:] = X[:n].copy()
            a = T - n
        multiply(X[a:a + n], Wb, out=P)
        reduce(flat, 0, None, out[s])
        a -= 1
        X[a] = spread[s]
    res: FloatArray = np.ascontiguousarray(out.transpose(1, 0, 2))
    return res


def expected_value(probs: FloatArray, values: FloatArray) -> FloatArray:
    """``Σ_k probs[..., k] · values[k]``, added in the order of ``k`` (no BLAS: the same numbers for a
    row whatever else is in the batch, on any machine).

    The products are laid out ``(k, row)`` in a C-contiguous buffer of at least two columns and added by
    one reduction along its outer axis, which numpy does row after row (with a single column it would
    sum along the column, pairwise: the spare zero column, discarded, prevents that), from
    ``initial = -0.0``: ``-0 + p = p`` for every ``p``, signed zeros and NaN included, so each sum is
    ``((p_0 + p_1) + p_2) + …`` exactly as a loop over ``k`` adding one product at a time, in 3 numpy calls
    instead of ``2 m`` (``tests/test_prediction_expected_value.py``).  A single distribution (1-D ``probs``)
    gives a numpy scalar, the same number (a NaN's sign aside: numpy's scalar arithmetic picks a NaN operand
    in the compiler's order).
    """
    m = probs.shape[-1]
    lead = probs.shape[:-1]
    N = math.prod(lead)
    P = np.zeros((m, max(N, 2)))
    np.multiply(probs.reshape(N, m).T, values[:, None], out=P[:, :N])
    acc: FloatArray = np.add.reduce(P, axis=0, initial=-0.0)[:N].reshape(lead)
    return acc if lead else acc[()]


def _lag_operators(model: MTDModel) -> FloatArray:
    """``W_i = λ_i Q_i``, ``(n, m, m)`` (the operands of :func:`propagate_batch`; read-only, computed once
    per model)."""
    W: FloatArray | None = model.__dict__.get("_lag_operators")
    if W is None:
        W = model.Q * model.lam[:, None, None]
        W.setflags(write=False)
        model.__dict__["_lag_operators"] = W
    return W


def sample(model: MTDModel, init: ArrayLike, steps: int, n_samples: int, rng: Seed = None) -> IntArray:
    """Draw state paths from the chain.

    At every step a lag ``i`` is drawn with probability ``λ_i`` and the next state from
    column ``x_{t-i}`` of ``Q_i`` (the latent-lag form of the MTD model).

    Parameters
    ----------
    init : array_like of int
        At least ``n`` past states, oldest first.
    steps, n_samples : int
    rng : numpy.random.Generator or int or None

    Returns
    -------
    numpy.ndarray of int, shape (n_samples, steps)
    """
    gen = np.random.default_rng(rng)
    past = np.asarray(init, dtype=np.int64)
    if past.size < model.order:
        raise ValueError(f"needs at least {model.order} initial states")
    n = model.order
    buf = np.empty((n_samples, n + int(steps)), dtype=np.int64)
    buf[:, :n] = past[-n:]
    # inverse-CDF sampling with u in [0, 1): the last CDF value is set to exactly 1 (not a
    # round-off 1 - 1e-16), so the drawn index never exceeds the last state / lag
    cdf = np.cumsum(model.Q, axis=1)  # (n, m, m): cdf over j for each column k
    cdf[:, -1, :] = 1.0
    lam_cdf = np.cumsum(model.lam)
    lam_cdf[-1] = 1.0
    rows = np.arange(n_samples)
    for s in range(int(steps)):
        t = n + s
        lag = np.searchsorted(lam_cdf, gen.random(n_samples), side="right")  # 0-based: lag i = lag + 1
        src = buf[rows, t - 1 - lag]
        col_cdf = cdf[lag, :, src]  # (n_samples, m)
        u = gen.random(n_samples)
        buf[:, t] = (col_cdf < u[:, None]).sum(axis=1)
    return buf[:, n:]
