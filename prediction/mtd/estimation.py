"""Estimation of the MTD model (:func:`fit`): joint EM with SQUAREM, ML lag weights, the LP.

The estimators and their mathematics are described in :mod:`iamp.prediction.mtd`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linprog

from iamp.prediction._typing import FloatArray, IntArray, Progress, Seed, StateSequences

from .counts import (
    _as_sequences,
    _check_empty,
    _lag_probs,
    _normalise_columns,
    _unique_rows,
    lag_table,
)
from .em import em_joint, em_lambda
from .model import MTDModel

__all__ = ["ESTIMATORS", "fit", "sample_sequence"]

#: Estimators accepted by :func:`fit`.
ESTIMATORS = ("mle", "mle-lambda", "lp")

def _lp_lambda(Q: FloatArray, xhat: FloatArray, norm: str) -> tuple[FloatArray, dict[str, object]]:
    r"""Ching–Fung–Ng LP: ``λ`` minimising ``‖Σ_i λ_i Q_i x̂ - x̂‖`` (∞ or ℓ1 norm) on the simplex."""
    n, m, _ = Q.shape
    A = np.stack([Q[i] @ xhat for i in range(n)], axis=1)  # (m, n): column i = Q_i x̂
    if norm == "inf":
        # variables [λ (n), w]; minimise w s.t. ±(Aλ - x̂) <= w
        c = np.r_[np.zeros(n), 1.0]
        A_ub = np.block([[A, -np.ones((m, 1))], [-A, -np.ones((m, 1))]])
        b_ub = np.r_[xhat, -xhat]
        A_eq = np.r_[np.ones(n), 0.0][None, :]
        bounds = [(0, None)] * n + [(0, None)]
    elif norm == "l1":
        # variables [λ (n), w (m)]; minimise Σ w s.t. ±(Aλ - x̂) <= w
        c = np.r_[np.zeros(n), np.ones(m)]
        A_ub = np.block([[A, -np.eye(m)], [-A, -np.eye(m)]])
        b_ub = np.r_[xhat, -xhat]
        A_eq = np.r_[np.ones(n), np.zeros(m)][None, :]
        bounds = [(0, None)] * (n + m)
    else:
        raise ValueError("lp_norm must be 'inf' or 'l1'")
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=[1.0], bounds=bounds, method="highs")
    if res.status != 0:
        raise RuntimeError(f"linprog failed: {res.message}")
    lam = np.clip(res.x[:n], 0.0, None)
    lam = lam / lam.sum()
    return lam, {"lp_norm": norm, "lp_objective": float(res.fun), "lp_status": res.message}


def fit(sequences: StateSequences, n_states: int, order: int, estimator: str = "mle", *, tol: float = 1e-10,
        max_iter: int = 20000, n_starts: int = 3, seed: int = 0, pseudocount: float = 0.0,
        empty: str = "uniform", lp_norm: str = "inf",
        edges: ArrayLike | None = None, centres: ArrayLike | None = None, dt: float | None = None,
        state: str | None = None,
        settings: Mapping[str, float] | None = None,
        provenance: Mapping[str, object] | None = None, progress: Progress | None = None) -> MTDModel:
    r"""Fit an order-``n`` MTD model to integer state sequences.

    Parameters
    ----------
    sequences : list of array_like of int
        State sequences with values in ``0..n_states-1``, each in time order (one per track;
        transitions never cross sequences).
    n_states : int
        ``m``.
    order : int
        ``n >= 1``.
    estimator : {"mle", "mle-lambda", "lp"}
        See the module docstring.  ``"mle"``: joint ML of ``λ`` and ``Q_i`` by EM (default);
        ``"mle-lambda"``: ``Q_i`` empirical, ``λ`` by (concave) ML; ``"lp"``: ``Q_i``
        empirical, ``λ`` by the Ching–Fung–Ng linear programme.
    tol : float
        Stopping tolerance on the average log-likelihood ``ℓ/N``: for ``"mle-lambda"`` the
        optimality certificate ``max_i g_i - 1 >= (ℓ* - ℓ)/N``; for ``"mle"`` the increase of
        ``ℓ/N`` over one (SQUAREM-accelerated) EM cycle.
    max_iter : int
        Iteration cap (reported in ``fit_info``; ``converged`` says whether ``tol`` was met).
    n_starts : int
        ``"mle"`` only: EM is run from the empirical start and ``n_starts - 1`` random starts
        (``Q_i`` halfway between the empirical matrix and a random stochastic matrix, ``λ``
        Dirichlet(1)); the start with the highest likelihood wins.  The joint likelihood has
        local maxima, which a single start does hit on synthetic data.
    seed : int
        Seed of the random starts (the fit is deterministic).
    pseudocount : float
        Dirichlet pseudo-count added to every count (0: plain ML).
    empty : {"uniform", "identity"}
        Fill for columns of source states never observed at a lag.
    lp_norm : {"inf", "l1"}
        Norm of the LP estimator.
    edges, centres, dt, state, settings, provenance
        Stored in the model unchanged (the physical meaning of the states).
    progress : callable, optional
        ``progress(done, total)`` after each EM start (``"mle"``).

    Returns
    -------
    MTDModel
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {', '.join(ESTIMATORS)} (got {estimator!r})")
    _check_empty(empty)
    if int(n_states) < 1 or int(order) < 1:
        raise ValueError("n_states and order must be >= 1")
    if pseudocount < 0:
        raise ValueError("pseudocount must be >= 0")
    m, n = int(n_states), int(order)
    seqs = _as_sequences(sequences, m)
    rows_all = lag_table(seqs, n, m)
    N = int(rows_all.shape[0])
    if N == 0:
        raise ValueError(f"no transitions to fit: every sequence is shorter than order + 1 = {n + 1}")
    counts = np.zeros((n, m, m))
    for i in range(1, n + 1):
        counts[i - 1] = np.bincount(rows_all[:, 0] * m + rows_all[:, i], minlength=m * m).reshape(m, m)
    Q = _normalise_columns(counts, pseudocount, empty)
    rows, w = _unique_rows(rows_all)
    info: dict[str, object] = {"estimator": estimator}

    lam0 = np.full(n, 1.0 / n)
    if estimator == "lp":
        xhat = np.bincount(np.concatenate(seqs), minlength=m).astype(float)
        xhat /= xhat.sum()
        lam, lp_info = _lp_lambda(Q, xhat, lp_norm)
        info.update(lp_info)
    else:
        lam, em_info = em_lambda(_lag_probs(Q, rows), w, lam0, tol, max_iter)
        info.update({"lambda_step": em_info})
        if estimator == "mle":
            # multi-start: the empirical start plus random starts (fixed seed: deterministic)
            # the λ-only optimum often sits on the boundary (λ_i = 0 is a fixed point of EM),
            # so the empirical start takes λ halfway between it and the uniform weights
            starts = [(Q, 0.5 * lam + 0.5 / n)]
            srng = np.random.default_rng(seed)
            for _ in range(max(int(n_starts), 1) - 1):
                Qr = np.stack([srng.dirichlet(np.ones(m), size=m).T for _ in range(n)])
                starts.append((0.5 * Q + 0.5 * Qr, srng.dirichlet(np.ones(n))))
            best: tuple[float, FloatArray, FloatArray, int] | None = None
            runs: list[dict[str, object]] = []
            for k_start, (Qs, ls) in enumerate(starts):
                Qe, le, joint = em_joint(rows, w, Qs, ls, m, pseudocount, empty, tol, max_iter)
                ll = float(np.sum(w * np.log(np.maximum(_lag_probs(Qe, rows) @ le, 1e-300))))
                runs.append({**joint, "loglik": ll})
                if best is None or ll > best[0]:
                    best = (ll, Qe, le, len(runs) - 1)
                if progress is not None:
                    progress(k_start + 1, len(starts))
            assert best is not None  # at least one start
            _, Q, lam, ibest = best
            info.update({"joint_em": {"starts": runs, "best_start": ibest, "seed": seed}})
    model = MTDModel(Q=Q, lam=lam, estimator=estimator, dt=dt,
                     edges=None if edges is None else np.asarray(edges, dtype=float),
                     centres=None if centres is None else np.asarray(centres, dtype=float),
                     state=state, settings=dict(settings or {}), counts=counts, n_obs=N,
                     provenance=dict(provenance or {}), fit_info=info)
    ll = float(np.sum(w * np.log(np.maximum(_lag_probs(model.Q, rows) @ model.lam, 0.0))))
    object.__setattr__(model, "loglik", ll)
    return model


def sample_sequence(model: MTDModel, length: int, rng: Seed = None, init: ArrayLike | None = None) -> IntArray:
    """Sample one state sequence of ``length`` states from ``model`` (for tests/simulation).

    The first ``n`` states are ``init`` or drawn uniformly.
    """
    rng = np.random.default_rng(rng)
    n = model.order
    if init is None:
        init = rng.integers(0, model.n_states, size=n)
    path = model.sample(init, length - n, 1, rng)[0]
    return np.concatenate([np.asarray(init, dtype=np.int64)[-n:], path])
