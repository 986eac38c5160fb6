"""The MTD model (prediction/mtd.py): estimation, validity, information criteria, files.

Tolerances of the parameter-recovery tests (N ≈ 100 000 transitions, fixed seeds):

* ``"mle"`` (joint EM) recovers λ to 0.02 and every entry of every ``Q_i`` to 0.05 for an
  identifiable model (every row of every ``Q_i`` has a zero — see
  ``test_mtd_is_not_identifiable_with_dense_columns`` for why that matters).
* ``"lp"`` (Ching–Fung–Ng) and ``"mle-lambda"`` use the empirical lag-``i`` matrices, which
  recover the true *marginal* lag-``i`` transition matrices (to 0.03) — not the MTD's
  ``q^{(i)}``; the LP's λ is not identified (its objective is nearly flat), so for it we test
  only feasibility and LP optimality.
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from iamp.prediction.mtd import (
    ESTIMATORS,
    ModelFileError,
    MTDModel,
    aic,
    bic,
    count_transitions,
    empirical_transition_matrices,
    fit,
    n_parameters,
)

M = 4


def _circulant(offsets, probs):
    Q = np.zeros((M, M))
    for k in range(M):
        for o, p in zip(offsets, probs):
            Q[(k + o) % M, k] += p
    return Q


Q1 = _circulant([0, 1], [0.7, 0.3])
Q2 = _circulant([0, 3], [0.4, 0.6])
Q3 = _circulant([2, 3], [0.5, 0.5])
TRUE = {
    2: MTDModel(Q=np.stack([Q1, Q2]), lam=[0.6, 0.4]),
    3: MTDModel(Q=np.stack([Q1, Q2, Q3]), lam=[0.5, 0.3, 0.2]),
}


@pytest.fixture(scope="module", params=[2, 3])
def sampled(request):
    n = request.param
    true = TRUE[n]
    seqs = list(true.sample(np.zeros(n, dtype=int), 2000, 50, rng=np.random.default_rng(n)))
    return true, seqs


@pytest.fixture(scope="module")
def fits(sampled):
    true, seqs = sampled
    return {est: fit(seqs, M, true.order, est) for est in ESTIMATORS}


def _marginal_lag_matrices(model: MTDModel) -> np.ndarray:
    """Exact stationary lag-i transition matrices P(x_t = j | x_{t-i} = k) of an MTD chain.

    Lifts the order-n chain to the first-order chain on n-tuples (newest first), finds its
    stationary law, and reads the joint law of (x_t, x_{t-i}) off one more step.
    """
    n, m = model.order, model.n_states
    tuples = list(itertools.product(range(m), repeat=n))
    index = {s: r for r, s in enumerate(tuples)}
    T = np.zeros((len(tuples), len(tuples)))
    for s in tuples:
        p = model.transition_probabilities(list(reversed(s)))  # past oldest-first
        for j in range(m):
            T[index[(j,) + s[:-1]], index[s]] += p[j]
    w, V = np.linalg.eig(T)
    pi = np.real(V[:, np.argmin(np.abs(w - 1))])
    pi = pi / pi.sum()
    out = np.zeros((n, m, m))
    for s, ps in zip(tuples, pi):
        p = model.transition_probabilities(list(reversed(s)))
        for i in range(1, n + 1):
            out[i - 1, :, s[i - 1]] += ps * p
    return out / out.sum(axis=1, keepdims=True)


# ---------------------------------------------------------------------------------------
# recovery
# ---------------------------------------------------------------------------------------

def test_mle_recovers_lambda_and_Q(sampled, fits):
    true, _ = sampled
    model = fits["mle"]
    assert np.max(np.abs(model.lam - true.lam)) < 0.02
    assert np.max(np.abs(model.Q - true.Q)) < 0.05
    # and it is at least as likely as the truth (it is the maximiser)
    assert model.loglik >= true.log_likelihood(_seqs(sampled))[0] - 1e-6
    assert any(r["converged"] for r in model.fit_info["joint_em"]["starts"])


def _seqs(sampled):
    return sampled[1]


def test_empirical_matrices_are_the_marginal_lag_matrices(sampled, fits):
    true, _ = sampled
    marg = _marginal_lag_matrices(true)
    for est in ("lp", "mle-lambda"):
        assert np.max(np.abs(fits[est].Q - marg)) < 0.03
    # ... and these differ from the MTD's q^(i) for lags > 1 when n > 1
    assert np.max(np.abs(marg - true.Q)) > 0.1


def test_lp_estimator_is_lp_optimal_on_the_simplex(sampled, fits):
    true, seqs = sampled
    model = fits["lp"]
    xhat = np.bincount(np.concatenate(seqs), minlength=M) / sum(len(s) for s in seqs)

    def obj(lam):
        return np.max(np.abs(sum(l * Q @ xhat for l, Q in zip(lam, model.Q)) - xhat))

    assert model.lam.min() >= 0 and abs(model.lam.sum() - 1) < 1e-12
    assert obj(model.lam) == pytest.approx(model.fit_info["lp_objective"], abs=1e-9)
    rng = np.random.default_rng(0)
    for lam in [true.lam, np.full(true.order, 1 / true.order), *rng.dirichlet(np.ones(true.order), 20)]:
        assert obj(model.lam) <= obj(lam) + 1e-9
    # the caveat: the objective is tiny everywhere (λ poorly identified)
    assert obj(np.eye(true.order)[0]) < 0.01


def test_lp_l1_norm():
    true = TRUE[2]
    seqs = list(true.sample([0, 1], 500, 10, rng=1))
    model = fit(seqs, M, 2, "lp", lp_norm="l1")
    assert model.fit_info["lp_norm"] == "l1"
    assert abs(model.lam.sum() - 1) < 1e-12


def test_mle_lambda_is_the_concave_maximum(sampled, fits):
    true, seqs = sampled
    model = fits["mle-lambda"]
    info = model.fit_info["lambda_step"]
    assert info["converged"] and info["certificate_max_grad_minus_1"] < 1e-9
    rng = np.random.default_rng(1)
    for lam in rng.dirichlet(np.ones(true.order), 20):
        other = MTDModel(Q=model.Q, lam=lam)
        assert other.log_likelihood(seqs)[0] <= model.loglik + 1e-6


def test_mtd_is_not_identifiable_with_dense_columns():
    """Why the recovery test uses Q_i with zeros: moving a column-constant part between lags
    changes (λ, Q_i) but not a single transition probability."""
    rng = np.random.default_rng(3)
    Qa = np.stack([rng.dirichlet(np.ones(M) * 5, M).T for _ in range(2)])
    lam = np.array([0.5, 0.5])
    v = np.array([0.02, -0.02, 0.01, -0.01])
    Qb = Qa.copy()
    Qb[0] += v[:, None]
    Qb[1] -= v[:, None]
    a, b = MTDModel(Q=Qa, lam=lam), MTDModel(Q=Qb, lam=lam)
    for past in itertools.product(range(M), repeat=2):
        assert np.allclose(a.transition_probabilities(past), b.transition_probabilities(past), atol=1e-15)


def test_order_one_all_estimators_agree():
    true = MTDModel(Q=Q1[None], lam=[1.0])
    seqs = list(true.sample([0], 1000, 5, rng=0))
    models = [fit(seqs, M, 1, est) for est in ESTIMATORS]
    for m in models:
        assert m.lam.tolist() == [1.0]
        assert np.allclose(m.Q, models[0].Q, atol=1e-9)
    C = count_transitions(seqs, M, 1)[0]
    assert np.allclose(models[1].Q[0], C / C.sum(axis=0))


# ---------------------------------------------------------------------------------------
# validity
# ---------------------------------------------------------------------------------------

def _check_valid(model):
    assert np.all(model.Q >= 0) and np.all(model.Q <= 1)
    assert np.allclose(model.Q.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(model.lam >= 0) and abs(model.lam.sum() - 1.0) < 1e-12


def test_probabilities_valid_for_every_estimator(fits):
    for model in fits.values():
        _check_valid(model)


@pytest.mark.parametrize("empty", ["uniform", "identity"])
def test_empty_states_get_the_documented_column(empty):
    # state 4 of 5 never occurs
    seqs = [np.array([0, 1, 2, 3, 0, 1, 0, 2, 3, 3, 1, 0] * 20)]
    for est in ESTIMATORS:
        model = fit(seqs, 5, 2, est, empty=empty)
        _check_valid(model)
        expected = np.full(5, 0.2) if empty == "uniform" else np.eye(5)[4]
        for i in range(2):
            assert np.allclose(model.Q[i][:, 4], expected)


def test_propagated_distributions_stay_on_the_simplex(fits):
    for model in fits.values():
        D = model.propagate([0, 3, 1][-model.order:], 200)
        assert np.all(D >= -1e-15) and np.allclose(D.sum(axis=1), 1.0, atol=1e-12)


def test_propagation_is_the_papers_formula():
    model = TRUE[3]
    past = [2, 0, 1]
    x = [np.eye(M)[s] for s in past]
    for _ in range(5):
        x.append(sum(model.lam[i] * model.Q[i] @ x[-1 - i] for i in range(3)))
    D = model.propagate(past, 5)
    assert np.allclose(D, np.array(x[3:]), atol=1e-15)
    B = model.propagate_batch(np.array([past, [0, 0, 3]]), 5)
    assert np.allclose(B[0], D, atol=1e-15)
    assert np.allclose(B[1], model.propagate([0, 0, 3], 5), atol=1e-15)


def test_sampling_matches_the_transition_law():
    model = TRUE[2]
    paths = model.sample([1, 2], 1, 40000, rng=5)[:, 0]
    freq = np.bincount(paths, minlength=M) / paths.size
    assert np.allclose(freq, model.transition_probabilities([1, 2]), atol=0.01)


def test_invalid_inputs_raise():
    with pytest.raises(ValueError):
        MTDModel(Q=np.ones((1, 2, 2)), lam=[1.0])  # columns sum to 2
    with pytest.raises(ValueError):
        MTDModel(Q=np.stack([np.eye(2)] * 2), lam=[0.7, 0.7])
    with pytest.raises(ValueError):
        fit([[0, 1, 5]], 3, 1)
    with pytest.raises(ValueError):
        fit([[0, 1]], 3, 2)  # no transition to fit
    with pytest.raises(ValueError):
        fit([[0, 1, 0]], 2, 1, "bogus")


# ---------------------------------------------------------------------------------------
# likelihood, AIC, BIC
# ---------------------------------------------------------------------------------------

def test_loglik_aic_bic_formulas(fits, sampled):
    true, seqs = sampled
    n = true.order
    model = fits["mle"]
    ll = 0.0
    N = 0
    for s in seqs:
        for t in range(n, len(s)):
            ll += math.log(sum(model.lam[i] * model.Q[i][s[t], s[t - 1 - i]] for i in range(n)))
            N += 1
    assert model.loglik == pytest.approx(ll, rel=1e-10)
    assert model.n_obs == N
    k = n * M * (M - 1) + (n - 1)
    assert model.n_parameters == n_parameters(M, n) == k
    assert model.aic == pytest.approx(2 * k - 2 * ll, rel=1e-10)
    assert model.bic == pytest.approx(k * math.log(N) - 2 * ll, rel=1e-10)
    assert aic(-10.0, 3) == 26.0
    assert bic(-10.0, 3, 100) == pytest.approx(3 * math.log(100) + 20.0)


# ---------------------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------------------

def test_save_load_round_trip(tmp_path, fits):
    model = fits["mle"]
    model = MTDModel(Q=model.Q, lam=model.lam, estimator="mle", edges=[-1.0, 0.0, 1.0],
                     centres=[-1.5, -0.4, 0.4, 1.5], dt=0.2, state="test", counts=model.counts,
                     loglik=model.loglik, n_obs=model.n_obs, provenance={"data": "synthetic"},
                     fit_info=model.fit_info)
    path = model.save(tmp_path / "m.json")
    back = MTDModel.load(path)
    assert np.array_equal(back.Q, model.Q) and np.array_equal(back.lam, model.lam)
    assert np.array_equal(back.edges, model.edges) and np.array_equal(back.centres, model.centres)
    assert np.array_equal(back.counts, model.counts)
    assert (back.dt, back.state, back.estimator, back.loglik, back.n_obs) == \
        (model.dt, model.state, model.estimator, model.loglik, model.n_obs)
    assert back.provenance == {"data": "synthetic"}
    d = json.loads(path.read_text())
    assert d["orientation"].startswith("column-stochastic")
    assert d["aic"] == pytest.approx(model.aic) and d["bic"] == pytest.approx(model.bic)
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"]  # no temporary file left


def test_bad_model_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ModelFileError, match="not valid JSON"):
        MTDModel.load(bad)
    bad.write_text(json.dumps({"format": "iamp-mtd/1", "order": 1, "Q": [[[0.5, 0.5], [0.6, 0.5]]],
                               "lambda": [1.0]}))
    with pytest.raises(ModelFileError, match="probability"):
        MTDModel.load(bad)
    bad.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ModelFileError, match="format"):
        MTDModel.load(bad)
    with pytest.raises(ModelFileError, match="cannot be read"):
        MTDModel.load(tmp_path / "missing.json")


def test_empirical_transition_matrices_helper():
    seqs = [[0, 1, 0, 1, 1, 0]]
    Q = empirical_transition_matrices(seqs, 2, 1)
    # transitions 0->1, 1->0, 0->1, 1->1, 1->0 : from 0: {1: 2}, from 1: {0: 2, 1: 1}
    assert np.allclose(Q[0], [[0, 2 / 3], [1, 1 / 3]])
