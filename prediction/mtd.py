r"""Raftery's mixture-transition-distribution (MTD) model of a high-order Markov chain.

The chain lives on ``m`` discrete states ``0..m-1`` (for the predictor: bins of the
longitudinal acceleration).  An order-``n`` MTD model has one column-stochastic transition
matrix per lag,

.. math::

    Q_i[j, k] = q^{(i)}_{jk} = P(x_{t} = j \mid x_{t-i} = k), \qquad i = 1..n,

(each **column** sums to one, so ``Q_i`` acts on column vectors of probabilities) and lag
weights ``λ`` on the simplex (``λ_i >= 0``, ``Σ_i λ_i = 1``).  The conditional law of the
next state is the mixture (Raftery 1985; the paper's eq. ``markov2``)

.. math::

    P(x_t = j \mid x_{t-1}, \dots, x_{t-n}) = \sum_{i=1}^{n} λ_i\, q^{(i)}_{j\, x_{t-i}} ,

and, by linearity of expectation, the marginal state distributions obey exactly the paper's
propagation rule (eq. ``prediction``)

.. math::

    \hat x_t = \sum_{i=1}^{n} λ_i\, Q_i\, \hat x_{t-i},

with ``\hat x_{t-i}`` the one-hot vectors of the observed states for ``t - i <= 0``.  Every
``\hat x_t`` is a convex combination of columns of stochastic matrices, so it stays on the
probability simplex.

Estimators (:func:`fit`)
------------------------
All three score the same likelihood, conditioned on the first ``n`` states of every
sequence,

.. math::

    \ell(λ, Q) = \sum_{t} \log \sum_{i=1}^{n} λ_i\, q^{(i)}_{x_t\, x_{t-i}},
    \qquad t = n, \dots, T-1 \text{ of every sequence},

and report ``AIC = 2k - 2\ell`` and ``BIC = k \ln N - 2\ell`` with ``N`` the number of
scored transitions and the nominal parameter count ``k = n\,m(m-1) + (n-1)`` (``m-1`` free
entries per column of every ``Q_i`` plus ``n-1`` free lag weights; columns that the data never
visit are counted too).

``"mle"`` (default)
    Raftery's maximum-likelihood estimate of ``λ`` **and** the ``Q_i`` jointly, by the EM
    algorithm for mixtures (latent lag ``z_t`` with ``P(z_t = i) = λ_i``).  E-step:
    ``r_{ti} = λ_i q^{(i)}_{x_t x_{t-i}} / Σ_l λ_l q^{(l)}_{x_t x_{t-l}}``; M-step:
    ``λ_i = Σ_t r_{ti} / N`` and ``q^{(i)}_{jk} = Σ_{t: x_t=j, x_{t-i}=k} r_{ti} /
    Σ_{t: x_{t-i}=k} r_{ti}``.  EM is accelerated with SQUAREM (with a monotonicity
    safeguard, so ``\ell`` never decreases) and stops when the increase of the average
    log-likelihood ``\ell/N`` over one cycle falls below ``tol``.  The joint likelihood is
    not concave and does have local maxima, so EM is restarted from a few starts (the empirical one and
    seeded random ones) and the best local maximum is kept — a global optimum is not
    guaranteed.
``"mle-lambda"``
    ``Q_i`` fixed at the empirical lag-``i`` transition matrices (normalised lag-``i`` counts,
    as in Ching, Fung & Ng 2004) and ``λ`` by maximum likelihood.  For fixed ``Q_i`` the
    log-likelihood is concave in ``λ``; it is maximised with the EM (multiplicative) update
    ``λ_i \leftarrow λ_i\, g_i`` where ``g_i = \frac1N \sum_t q^{(i)}_t / \sum_l λ_l q^{(l)}_t``
    is the gradient of ``\ell/N``.  Because ``\ell/N`` is concave and ``Σ_i λ_i g_i = 1``, the
    certificate ``\max_i g_i - 1`` bounds ``(\ell^* - \ell)/N``; iteration stops when it is
    below ``tol``.
``"lp"``
    The Ching–Fung–Ng (2004) linear programme: ``Q_i`` the empirical lag-``i`` matrices,
    ``\hat x`` the empirical state distribution, and ``λ`` minimising
    ``\| \sum_i λ_i Q_i \hat x - \hat x \|_\infty`` (or the ℓ1 norm) over the simplex, solved
    with :func:`scipy.optimize.linprog` (HiGHS).  Caveat, shown by the tests: for a
    stationary sequence every empirical ``Q_i`` nearly preserves ``\hat x``, so the objective
    is nearly flat and ``λ`` is poorly identified; it is kept for fidelity to the paper's
    reference, not as the default.

Important: for an MTD process with ``n > 1`` the empirical lag-``i`` matrix is the *marginal*
lag-``i`` transition matrix, which differs from ``q^{(i)}`` (it mixes in the other lags).
Only ``"mle"`` recovers ``q^{(i)}`` and ``λ`` of a true MTD process, and only where they are
identifiable: adding ``v 1^T`` (``Σ_j v_j = 0``) to ``λ_1 Q_1`` and subtracting it from
``λ_2 Q_2`` changes no transition probability, so with strictly positive ``Q_i`` the
parameters are determined only up to such shifts (a row of each ``Q_i`` with a zero blocks
them; the recovery tests use such matrices).  The transition law itself — all that the
predictor uses — is always identified.

Empty columns: a source state ``k`` that never occurs at lag ``i`` in the data leaves column
``k`` of ``Q_i`` undetermined; it is filled with the uniform distribution (``empty="uniform"``,
default) or the identity column ``e_k`` (``empty="identity"``, "stay where you are").  An
optional Dirichlet ``pseudocount`` is added to every count before normalising (the estimate
then is a MAP rather than an ML one); the default is 0.

The model is saved as JSON (:meth:`MTDModel.save`, written atomically) and read back with
:meth:`MTDModel.load`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from iamp.core.atomic import write_text as atomic_write_text  # re-exported for callers
from scipy.optimize import linprog

from iamp.core.errors import IampError

__all__ = [
    "ESTIMATORS",
    "FORMAT",
    "MTDModel",
    "ModelFileError",
    "aic",
    "bic",
    "count_transitions",
    "empirical_transition_matrices",
    "fit",
    "lag_table",
    "n_parameters",
    "sample_sequence",
]

#: Estimators accepted by :func:`fit`.
ESTIMATORS = ("mle", "mle-lambda", "lp")
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
# counting and likelihood helpers
# ---------------------------------------------------------------------------------------

def _as_sequences(sequences, n_states: int) -> list[np.ndarray]:
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


def lag_table(sequences, order: int, n_states: int | None = None) -> np.ndarray:
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
        rows.append(np.stack([s[order - i: T - i] for i in range(order + 1)], axis=1))
    if not rows:
        return np.zeros((0, order + 1), dtype=np.int64)
    return np.concatenate(rows, axis=0)


def count_transitions(sequences, n_states: int, order: int) -> np.ndarray:
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


def _normalise_columns(C: np.ndarray, pseudocount: float, empty: str) -> np.ndarray:
    """Column-normalise count matrices ``C[..., j, k]``; fill empty columns."""
    C = np.asarray(C, dtype=float) + pseudocount
    m = C.shape[-1]
    tot = C.sum(axis=-2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        Q = np.where(tot > 0, C / np.where(tot > 0, tot, 1.0), 0.0)
    emptycols = (tot[..., 0, :] <= 0)  # shape (..., m)
    if np.any(emptycols):
        fill = np.full((m, m), 1.0 / m) if empty == "uniform" else np.eye(m)
        idx = np.nonzero(emptycols)
        for pos in zip(*idx):
            *lead, k = pos
            Q[(*lead, slice(None), k)] = fill[:, k]
    return Q


def empirical_transition_matrices(sequences, n_states: int, order: int, *, pseudocount: float = 0.0,
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


def _unique_rows(rows: np.ndarray):
    if rows.shape[0] == 0:
        return rows, np.zeros(0)
    u, w = np.unique(rows, axis=0, return_counts=True)
    return u, w.astype(float)


def _lag_probs(Q: np.ndarray, rows: np.ndarray) -> np.ndarray:
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


# ---------------------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------------------

def readonly_array(a) -> np.ndarray:
    """A float copy of ``a`` that cannot be written to (for immutable results)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


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

    Q: np.ndarray
    lam: np.ndarray
    estimator: str = "given"
    edges: np.ndarray | None = None
    centres: np.ndarray | None = None
    dt: float | None = None
    state: str | None = None
    settings: dict = field(default_factory=dict)
    counts: np.ndarray | None = None
    loglik: float = float("nan")
    n_obs: int = 0
    provenance: dict = field(default_factory=dict)
    fit_info: dict = field(default_factory=dict)

    def __post_init__(self):
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
    def log_likelihood(self, sequences) -> tuple[float, int]:
        """Log-likelihood ``ℓ = Σ_t log Σ_i λ_i q^{(i)}_{x_t x_{t-i}}`` of ``sequences``.

        Returns
        -------
        (float, int)
            ``ℓ`` (``-inf`` if a transition has probability 0) and the number ``N`` of
            scored transitions (times ``t >= n`` of every sequence).
        """
        rows = lag_table(sequences, self.order, self.n_states)
        if rows.shape[0] == 0:
            return 0.0, 0
        p = _lag_probs(self.Q, rows) @ self.lam
        with np.errstate(divide="ignore"):
            return float(np.sum(np.log(p))), int(rows.shape[0])

    def transition_probabilities(self, past) -> np.ndarray:
        """``P(x_t = · | x_{t-1}, ..., x_{t-n})`` for a past given oldest-to-newest."""
        past = np.asarray(past, dtype=np.int64)
        if past.size < self.order:
            raise ValueError(f"needs the last {self.order} states")
        return sum(self.lam[i] * self.Q[i][:, past[-1 - i]] for i in range(self.order))

    # -- states -------------------------------------------------------------------------
    def states(self, values) -> np.ndarray:
        """Map physical values (e.g. accelerations) to state indices with :attr:`edges`."""
        if self.edges is None:
            raise ValueError("this model has no bin edges")
        return np.searchsorted(self.edges, np.asarray(values, dtype=float), side="right")

    # -- propagation and sampling --------------------------------------------------------
    def _initial_distributions(self, init) -> np.ndarray:
        init = np.asarray(init)
        if init.ndim == 1:
            idx = init.astype(np.int64)
            if idx.size < self.order:
                raise ValueError(f"needs at least {self.order} initial states (got {idx.size})")
            if idx.min() < 0 or idx.max() >= self.n_states:
                raise ValueError("initial states out of range")
            D = np.zeros((idx.size, self.n_states))
            D[np.arange(idx.size), idx] = 1.0
            return D
        if init.ndim == 2 and init.shape[1] == self.n_states and init.shape[0] >= self.order:
            return np.asarray(init, dtype=float)
        raise ValueError("init must be a state sequence or an array of distributions (T, m)")

    def propagate(self, init, steps: int) -> np.ndarray:
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
        """
        D = self._initial_distributions(init)
        n = self.order
        hist = [D[-1 - i] for i in range(n)]  # hist[i] = \hat x_{t-1-i}
        out = np.empty((int(steps), self.n_states))
        W = self.Q * self.lam[:, None, None]
        for s in range(int(steps)):
            x = W[0] @ hist[0]
            for i in range(1, n):
                x = x + W[i] @ hist[i]
            out[s] = x
            hist = [x] + hist[:-1]
        return out

    def propagate_batch(self, init_states: np.ndarray, steps: int) -> np.ndarray:
        """Vectorised :meth:`propagate` for many one-hot pasts.

        Parameters
        ----------
        init_states : numpy.ndarray of int, shape (B, T)
            ``B`` pasts of ``T >= n`` states each, oldest first.
        steps : int

        Returns
        -------
        numpy.ndarray, shape (B, steps, m)
        """
        S = np.asarray(init_states, dtype=np.int64)
        B = S.shape[0]
        n, m = self.order, self.n_states
        W = self.Q * self.lam[:, None, None]
        # hist[i] : (B, m) distribution at t-1-i ; Q_i x  ->  x @ Q_i^T
        hist = [np.eye(m)[S[:, -1 - i]] for i in range(n)]
        out = np.empty((B, int(steps), m))
        WT = np.transpose(W, (0, 2, 1))
        for s in range(int(steps)):
            x = hist[0] @ WT[0]
            for i in range(1, n):
                x = x + hist[i] @ WT[i]
            out[:, s] = x
            hist = [x] + hist[:-1]
        return out

    def sample(self, init, steps: int, n_samples: int, rng=None) -> np.ndarray:
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
        rng = np.random.default_rng(rng)
        init = np.asarray(init, dtype=np.int64)
        if init.size < self.order:
            raise ValueError(f"needs at least {self.order} initial states")
        n = self.order
        buf = np.empty((n_samples, n + int(steps)), dtype=np.int64)
        buf[:, :n] = init[-n:]
        cdf = np.cumsum(self.Q, axis=1)  # (n, m, m): cdf over j for each column k
        cdf[:, -1, :] = 1.0
        lam_cdf = np.cumsum(self.lam)
        lam_cdf[-1] = 1.0
        rows = np.arange(n_samples)
        for s in range(int(steps)):
            t = n + s
            lag = np.searchsorted(lam_cdf, rng.random(n_samples), side="right")
            lag = np.minimum(lag, n - 1)  # 0-based lag index -> lag i = lag + 1
            src = buf[rows, t - 1 - lag]
            col_cdf = cdf[lag, :, src]  # (n_samples, m)
            u = rng.random(n_samples)
            buf[:, t] = np.minimum((col_cdf < u[:, None]).sum(axis=1), self.n_states - 1)
        return buf[:, n:]

    # -- persistence --------------------------------------------------------------------
    def to_dict(self) -> dict:
        """A JSON-serialisable description (see :meth:`save`)."""
        return {
            "format": FORMAT,
            "orientation": "column-stochastic: Q[i-1][j][k] = P(x_t = j | x_{t-i} = k)",
            "order": self.order,
            "n_states": self.n_states,
            "dt": self.dt,
            "state": self.state,
            "settings": self.settings,
            "bins": {
                "quantity": "longitudinal acceleration [m/s^2]",
                "edges": None if self.edges is None else self.edges.tolist(),
                "centres": None if self.centres is None else self.centres.tolist(),
            },
            "estimator": self.estimator,
            "lambda": self.lam.tolist(),
            "Q": self.Q.tolist(),
            "counts": None if self.counts is None else self.counts.astype(int).tolist()
            if np.all(self.counts == np.round(self.counts)) else self.counts.tolist(),
            "loglik": self.loglik if math.isfinite(self.loglik) else None,
            "n_obs": self.n_obs,
            "n_parameters": self.n_parameters,
            "aic": self.aic if math.isfinite(self.loglik) else None,
            "bic": self.bic if math.isfinite(self.loglik) else None,
            "fit_info": self.fit_info,
            "provenance": self.provenance,
        }

    def save(self, path) -> Path:
        """Write the model as JSON, atomically (temporary file + ``os.replace``)."""
        path = Path(path)
        text = json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n"
        atomic_write_text(path, text)
        return path

    @classmethod
    def from_dict(cls, d: dict, source: str | None = None) -> MTDModel:
        """Build a model from :meth:`to_dict` output; raises :class:`ModelFileError`."""
        if not isinstance(d, dict):
            raise ModelFileError("must be a JSON object", None, source)
        if d.get("format") != FORMAT:
            raise ModelFileError(f"unsupported format {d.get('format')!r} (expected {FORMAT!r})",
                                 "format", source)
        for key in ("Q", "lambda", "order"):
            if key not in d:
                raise ModelFileError("is missing", key, source)
        bins = d.get("bins") or {}
        try:
            model = cls(Q=d["Q"], lam=d["lambda"], estimator=str(d.get("estimator", "given")),
                        edges=bins.get("edges"), centres=bins.get("centres"), dt=d.get("dt"),
                        state=d.get("state"), settings=d.get("settings") or {}, counts=d.get("counts"),
                        loglik=float(d["loglik"]) if d.get("loglik") is not None else float("nan"),
                        n_obs=int(d.get("n_obs", 0)), provenance=d.get("provenance") or {},
                        fit_info=d.get("fit_info") or {})
        except (ValueError, TypeError) as exc:
            raise ModelFileError(str(exc), None, source) from None
        if model.order != int(d["order"]):
            raise ModelFileError(f"says {d['order']} but Q has {model.order} lags", "order", source)
        return model

    @classmethod
    def load(cls, path) -> MTDModel:
        """Read a model written by :meth:`save`; raises :class:`ModelFileError`."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelFileError(f"cannot be read ({exc.__class__.__name__}: {exc})", None, str(path)) from None
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ModelFileError(f"is not valid JSON ({exc})", None, str(path)) from None
        return cls.from_dict(d, source=str(path))

    def summary(self) -> dict:
        """The headline numbers: order, states, estimator, λ, ℓ, N, k, AIC, BIC."""
        return {"order": self.order, "n_states": self.n_states, "dt": self.dt,
                "estimator": self.estimator, "lambda": self.lam.tolist(), "loglik": self.loglik,
                "n_obs": self.n_obs, "n_parameters": self.n_parameters, "aic": self.aic,
                "bic": self.bic}




# ---------------------------------------------------------------------------------------
# estimation
# ---------------------------------------------------------------------------------------

def _em_lambda(P: np.ndarray, w: np.ndarray, lam0: np.ndarray, tol: float, max_iter: int):
    """Maximise ``Σ_r w_r log(P_r · λ)`` over the simplex (concave) by EM updates."""
    N = w.sum()
    lam = lam0.copy()
    gap = np.inf
    it = 0
    for it in range(1, max_iter + 1):
        mix = np.maximum(P @ lam, 1e-300)
        g = (w / mix) @ P / N  # gradient of ℓ/N
        gap = float(g.max() - 1.0)
        if gap < tol:
            break
        lam = lam * g
        lam = lam / lam.sum()
    return lam, {"iterations": it, "tolerance": tol, "certificate_max_grad_minus_1": gap,
                 "converged": bool(gap < tol)}


def _lp_lambda(Q: np.ndarray, xhat: np.ndarray, norm: str):
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


def fit(sequences, n_states: int, order: int, estimator: str = "mle", *, tol: float = 1e-10,
        max_iter: int = 20000, n_starts: int = 3, seed: int = 0, pseudocount: float = 0.0,
        empty: str = "uniform", lp_norm: str = "inf",
        edges=None, centres=None, dt: float | None = None, state: str | None = None,
        settings: dict | None = None,
        provenance: dict | None = None) -> MTDModel:
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
    info: dict = {"estimator": estimator}

    lam0 = np.full(n, 1.0 / n)
    if estimator == "lp":
        xhat = np.bincount(np.concatenate(seqs), minlength=m).astype(float)
        xhat /= xhat.sum()
        lam, lp_info = _lp_lambda(Q, xhat, lp_norm)
        info.update(lp_info)
    else:
        lam, em_info = _em_lambda(_lag_probs(Q, rows), w, lam0, tol, max_iter)
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
            best = None
            runs = []
            for Qs, ls in starts:
                Qe, le, joint = _em_joint(rows, w, Qs, ls, m, pseudocount, empty, tol, max_iter)
                ll = float(np.sum(w * np.log(np.maximum(_lag_probs(Qe, rows) @ le, 1e-300))))
                runs.append({**joint, "loglik": ll})
                if best is None or ll > best[0]:
                    best = (ll, Qe, le, len(runs) - 1)
            _, Q, lam, ibest = best
            info.update({"joint_em": {"starts": runs, "best_start": ibest, "seed": seed}})
    model = MTDModel(Q=Q, lam=lam, estimator=estimator, edges=edges, centres=centres, dt=dt,
                     state=state, settings=dict(settings or {}), counts=counts, n_obs=N,
                     provenance=dict(provenance or {}), fit_info=info)
    ll = float(np.sum(w * np.log(np.maximum(_lag_probs(model.Q, rows) @ model.lam, 0.0))))
    object.__setattr__(model, "loglik", ll)
    return model


def _em_joint(rows, w, Q, lam, m, pseudocount, empty, tol, max_iter):
    """Joint EM for (λ, Q_i), accelerated with SQUAREM; returns parameters and info.

    SQUAREM (Varadhan & Roland 2008, scheme S3): from ``θ0`` two EM steps give ``θ1, θ2``;
    with ``r = θ1 - θ0``, ``v = θ2 - 2θ1 + θ0`` and ``α = -‖r‖/‖v‖`` (at most -1) the
    extrapolation ``θ' = θ0 - 2α r + α² v`` keeps every column sum (its coefficients add to
    1); entries are floored at half their value in ``θ2`` (keeping them positive: an exact 0
    never revives under EM) and the columns renormalised; one EM step stabilises it, and the
    step is rejected (keeping the plain EM step ``θ2``) if the likelihood is below that at
    ``θ1``.  The log-likelihood therefore never decreases.  ``tol`` applies to the increase of
    ``ℓ/N`` over one cycle; ``max_iter`` counts EM steps.
    """
    n = Q.shape[0]
    N = w.sum()
    idx = [rows[:, 0] * m + rows[:, i + 1] for i in range(n)]

    def em(lam, Q):
        P = np.stack([Q[i].ravel()[idx[i]] for i in range(n)], axis=1)
        mix = np.maximum(P @ lam, 1e-300)
        ll = float(np.sum(w * np.log(mix))) / N
        R = P * lam * (w / mix)[:, None]  # weighted responsibilities r_ti
        lam2 = R.sum(axis=0) / N
        C = np.stack([np.bincount(idx[i], weights=R[:, i], minlength=m * m).reshape(m, m)
                      for i in range(n)])
        return lam2 / lam2.sum(), _normalise_columns(C, pseudocount, empty), ll

    def loglik(lam, Q):
        P = np.stack([Q[i].ravel()[idx[i]] for i in range(n)], axis=1)
        return float(np.sum(w * np.log(np.maximum(P @ lam, 1e-300)))) / N

    evals = 0
    prev = -np.inf
    delta = np.inf
    accepted = 0
    while evals < max_iter:
        lam1, Q1, ll0 = em(lam, Q)
        lam2, Q2, ll1 = em(lam1, Q1)
        evals += 2
        delta = ll0 - prev
        if delta < tol:
            break
        prev = ll0
        r = np.concatenate([lam1 - lam, (Q1 - Q).ravel()])
        v = np.concatenate([lam2 - 2 * lam1 + lam, (Q2 - 2 * Q1 + Q).ravel()])
        nv = float(np.linalg.norm(v))
        nxt = (lam2, Q2)
        if nv > 0:
            alpha = min(-float(np.linalg.norm(r)) / nv, -1.0)
            c0, c1, c2 = (1 + alpha) ** 2, -2 * alpha * (1 + alpha), alpha * alpha
            # extrapolate; entries that would fall below half their value after the plain
            # EM step are held there (exact zeros would never revive under EM), renormalise
            lam_e = np.maximum(c0 * lam + c1 * lam1 + c2 * lam2, 0.5 * lam2)
            Q_e = np.maximum(c0 * Q + c1 * Q1 + c2 * Q2, 0.5 * Q2)
            if lam_e.sum() > 0 and np.all(Q_e.sum(axis=1) > 0):
                lam_e = lam_e / lam_e.sum()
                Q_e = Q_e / Q_e.sum(axis=1, keepdims=True)
                lam3, Q3, ll_e = em(lam_e, Q_e)
                evals += 1
                if ll_e >= ll1:  # safeguard: never worse than the plain EM step
                    nxt = (lam3, Q3)
                    accepted += 1
        lam, Q = nxt
    ll = loglik(lam, Q)
    return Q, lam / lam.sum(), {"iterations": evals, "tolerance": tol, "accelerated_steps": accepted,
                                "last_increase_avg_loglik": float(delta), "avg_loglik": ll,
                                "converged": bool(delta < tol), "method": "EM + SQUAREM (S3)"}


def sample_sequence(model: MTDModel, length: int, rng=None, init=None) -> np.ndarray:
    """Sample one state sequence of ``length`` states from ``model`` (for tests/simulation).

    The first ``n`` states are ``init`` or drawn uniformly.
    """
    rng = np.random.default_rng(rng)
    n = model.order
    if init is None:
        init = rng.integers(0, model.n_states, size=n)
    path = model.sample(init, length - n, 1, rng)[0]
    return np.concatenate([np.asarray(init, dtype=np.int64)[-n:], path])
