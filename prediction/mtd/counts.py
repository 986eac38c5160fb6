r"""Counting helpers of the MTD model: lag tables, transition counts, information criteria.

For state sequences ``x_0, x_1, …`` of every track and an order ``n`` the *scored* times are
``t = n, …, T-1``; the lag-``i`` count matrix is

.. math::

    C_i[j, k] = \#\{t \ge n : x_t = j,\ x_{t-i} = k\}, \qquad i = 1..n,

and the empirical lag-``i`` matrix is its column normalisation
``Q_i[j, k] = C_i[j, k] / Σ_j C_i[j, k]`` (with an optional Dirichlet pseudo-count).
"""

from __future__ import annotations

import math

import numpy as np

from iamp.prediction._typing import FloatArray, IntArray, StateSequences

__all__ = ["aic", "bic", "count_transitions", "empirical_transition_matrices", "lag_table", "n_parameters"]

def _as_sequences(sequences: StateSequences, n_states: int) -> list[IntArray]:
    if isinstance(sequences, np.ndarray) and sequences.ndim == 1:
        sequences = [sequences]
    out = []
    for s in sequences:
        a = np.asarray(s)
        if a.ndim != 1:
            raise ValueError("every sequence must be one-dimensional")
        if a.size and not np.issubdtype(a.dtype, np.integer):
            if not np.all(np.isfinite(a)) or np.any(a != np.round(a)):
                raise ValueError("state sequences must hold integers")
        a = a.astype(np.int64)
        if a.size and (a.min() < 0 or a.max() >= n_states):
            raise ValueError(f"states must lie in 0..{n_states - 1} (got {a.min()}..{a.max()})")
        out.append(a)
    return out


def lag_table(sequences: StateSequences, order: int, n_states: int | None = None) -> IntArray:
    """Stack the scored ``(x_t, x_{t-1}, ..., x_{t-n})`` tuples of all sequences.

    Parameters
    ----------
    sequences : list of array_like of int
        State sequences (each in time order).
    order : int
        ``n``; sequences shorter than ``n + 1`` contribute nothing.
    n_states : int, optional
        Used only to validate the states.

    Returns
    -------
    numpy.ndarray, shape (N, n + 1)
        Row ``r`` is ``(x_t, x_{t-1}, ..., x_{t-n})`` for one scored time ``t >= n``.
    """
    seqs = _as_sequences(sequences, n_states if n_states is not None else np.iinfo(np.int64).max)
    rows = []
    for s in seqs:
        T = s.size
        if T <= order:
            continue
        rows.append(np.column_stack([s[order - i: T - i] for i in range(order + 1)]))
    if not rows:
        return np.zeros((0, order + 1), dtype=np.int64)
    return np.concatenate(rows, axis=0)


def count_transitions(sequences: StateSequences, n_states: int, order: int) -> FloatArray:
    """Observed lag-``i`` transition counts.

    Parameters
    ----------
    sequences : list of array_like of int
        State sequences in ``0..n_states-1``.
    n_states : int
        ``m``.
    order : int
        ``n``.

    Returns
    -------
    numpy.ndarray, shape (n, m, m)
        ``C[i-1, j, k]`` = number of scored times ``t >= n`` with ``x_t = j`` and
        ``x_{t-i} = k`` (the same target times for every lag, those of the likelihood).
    """
    rows = lag_table(sequences, order, n_states)
    m = n_states
    C = np.zeros((order, m, m))
    for i in range(1, order + 1):
        C[i - 1] = np.bincount(rows[:, 0] * m + rows[:, i], minlength=m * m).reshape(m, m)
    return C


def _normalise_columns(C: FloatArray, pseudocount: float, empty: str) -> FloatArray:
    """Column-normalise count matrices ``C[..., j, k]``; fill empty columns."""
    C = np.asarray(C, dtype=float) + pseudocount
    m = C.shape[-1]
    tot = C.sum(axis=-2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        Q: FloatArray = C / tot  # counts are >= 0: a column with total 0 is empty (NaN here, filled below)
    emptycols = (tot[..., 0, :] <= 0)  # shape (..., m)
    if np.any(emptycols):
        fill = np.full((m, m), 1.0 / m) if empty == "uniform" else np.eye(m)
        idx = np.nonzero(emptycols)
        for pos in zip(*idx):
            *lead, k = pos
            Q[(*lead, slice(None), k)] = fill[:, k]
    return Q


def empirical_transition_matrices(sequences: StateSequences, n_states: int, order: int, *, pseudocount: float = 0.0,
                                  empty: str = "uniform") -> np.ndarray:
    """Empirical lag-``i`` transition matrices (normalised lag-``i`` counts).

    Returns
    -------
    numpy.ndarray, shape (n, m, m)
        Column-stochastic ``Q_i[j, k] ≈ P(x_t = j | x_{t-i} = k)``.
    """
    _check_empty(empty)
    return _normalise_columns(count_transitions(sequences, n_states, order), pseudocount, empty)


def _check_empty(empty: str) -> None:
    if empty not in ("uniform", "identity"):
        raise ValueError(f"empty must be 'uniform' or 'identity' (got {empty!r})")


def _unique_rows(rows: IntArray) -> tuple[IntArray, FloatArray]:
    """The distinct rows and their multiplicities (as weights)."""
    u, w = np.unique(rows, axis=0, return_counts=True)
    return u, w.astype(float)


def _lag_probs(Q: FloatArray, rows: IntArray) -> FloatArray:
    """``P[r, i] = Q_i[x_t, x_{t-i}]`` for each scored row."""
    n = Q.shape[0]
    P = np.empty((rows.shape[0], n))
    for i in range(n):
        P[:, i] = Q[i][rows[:, 0], rows[:, i + 1]]
    return P


def n_parameters(n_states: int, order: int) -> int:
    """Nominal number of free parameters ``k = n m (m - 1) + (n - 1)``."""
    return int(order * n_states * (n_states - 1) + (order - 1))


def aic(loglik: float, k: int) -> float:
    """Akaike information criterion ``AIC = 2k - 2ℓ``."""
    return 2.0 * k - 2.0 * loglik


def bic(loglik: float, k: int, n_obs: int) -> float:
    """Bayesian information criterion ``BIC = k ln N - 2ℓ``."""
    return k * math.log(max(n_obs, 1)) - 2.0 * loglik
