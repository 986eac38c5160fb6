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

Modules: :mod:`~iamp.prediction.mtd.counts` (lag tables, counts, AIC/BIC),
:mod:`~iamp.prediction.mtd.model` (the model), :mod:`~iamp.prediction.mtd.chain`
(propagation, sampling), :mod:`~iamp.prediction.mtd.estimation` (the estimators),
:mod:`~iamp.prediction.mtd.io` (the JSON file); this module re-exports their public names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from iamp.core.atomic import write_text as atomic_write_text

from .counts import (
    aic,
    bic,
    count_transitions,
    empirical_transition_matrices,
    lag_table,
    n_parameters,
)
from .model import FORMAT, ModelFileError, MTDModel, readonly_array

if TYPE_CHECKING:
    from .estimation import ESTIMATORS, fit, sample_sequence


def __getattr__(name: str) -> Any:
    """The estimators on first use: they import :mod:`scipy.optimize` (~0.5 s of start-up that
    prediction with a trained model does not need; issue 22 item 10)."""
    if name in ("ESTIMATORS", "fit", "sample_sequence"):
        from . import estimation

        return getattr(estimation, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "ESTIMATORS",
    "FORMAT",
    "MTDModel",
    "ModelFileError",
    "aic",
    "atomic_write_text",
    "bic",
    "count_transitions",
    "empirical_transition_matrices",
    "fit",
    "lag_table",
    "n_parameters",
    "readonly_array",
    "sample_sequence",
]
