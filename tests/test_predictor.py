"""The predictor Ω (prediction/predictor.py): behaviour on typical histories, the
Prediction contract, refusal of bad histories, exactness of the integration, speed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenario_texts import history_scenario

from iamp.core.errors import HistoryError
from iamp.core.scenario import History, loads_scenario
from iamp.prediction.evaluation.evaluate import paper_histories, synthetic_tracks
from iamp.prediction.mtd import ModelFileError, MTDModel
from iamp.prediction.predictor import (
    Prediction,
    Predictor,
    integrate_nodes,
    second_differences,
    symmetric_edges,
    train_from_tracks,
)

T_HIST = np.round(np.arange(-30, 1) * 0.1, 10)


def _hist(x, t=T_HIST, field="vehicles[0].history"):
    return History(t, x, field=field, source="test.toml")


def constant_speed(v=18.0, x0=-15.0):
    return _hist(x0 + v * T_HIST)


def braking(v0=20.0, a=-1.5, x0=-15.0):
    return _hist(x0 + v0 * T_HIST + 0.5 * a * T_HIST ** 2)


@pytest.fixture(scope="module")
def synthetic_predictor():
    tracks = synthetic_tracks(n_tracks=20, duration=60.0, seed=3)
    model = train_from_tracks(tracks, dt=0.2, edges=symmetric_edges(0.5, 3.0), order=2)
    return Predictor(model, "synthetic")


@pytest.fixture(scope="module", params=["default", "synthetic"])
def predictor(request, synthetic_predictor):
    return Predictor.default() if request.param == "default" else synthetic_predictor


# ---------------------------------------------------------------------------------------
# behaviour
# ---------------------------------------------------------------------------------------

def test_constant_speed_predicts_near_constant_speed(predictor):
    p = predictor.predict(constant_speed(), 5.0)
    assert np.all(np.abs(p.v - 18.0) < 0.5)
    assert abs(p.x[-1] - (-15.0 + 18.0 * 5.0)) < 1.5
    assert p.x[0] == pytest.approx(-15.0, abs=1e-9)  # the smoothed position: exact on a line


def test_braking_is_behind_and_accelerating_ahead_of_constant_velocity(predictor):
    pb = predictor.predict(braking(20.0, -1.5), 5.0)
    cv = -15.0 + 20.0 * pb.t
    assert np.all(pb.x[1:] < cv[1:])
    assert pb.a[0] < -0.5 and pb.v[-1] < 20.0  # it keeps decelerating for a while
    pa = predictor.predict(braking(13.0, 2.0), 5.0)
    cv = -15.0 + 13.0 * pa.t
    assert np.all(pa.x[1:] > cv[1:])
    assert pa.a[0] > 0.5 and pa.v[-1] > 13.0


def test_prediction_contract(predictor):
    p = predictor.predict(braking(), 5.0)
    assert isinstance(p, Prediction)
    assert len(p.x_poly) == 4 and all(isinstance(c, float) for c in p.x_poly)
    assert p.t[0] == 0.0 and p.t[-1] == 5.0
    assert np.allclose(np.diff(p.t), predictor.dt)
    assert p.x.shape == p.t.shape == p.v.shape == p.a.shape
    assert p.probs.shape == (p.t.size, predictor.model.n_states)
    assert np.allclose(p.probs.sum(axis=1), 1.0) and np.all(p.probs >= 0)
    # the cubic is the least-squares fit of the samples
    V = np.vander(p.t, 4, increasing=True)
    c, *_ = np.linalg.lstsq(V, p.x, rcond=None)
    assert np.allclose(p.x_poly, c, atol=1e-9)
    assert p.fit_rmse == pytest.approx(np.sqrt(np.mean((V @ c - p.x) ** 2)), abs=1e-12)
    assert np.allclose(p.x_fit(), V @ c)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.x_poly = (0.0,)
    with pytest.raises(ValueError):
        p.x[0] = 1.0  # read-only arrays


def test_horizon_not_a_multiple_of_the_step(synthetic_predictor):
    p = synthetic_predictor.predict(braking(), 4.9)
    assert p.t[-1] == 4.9 and p.t.size == 26
    full = synthetic_predictor.predict(braking(), 5.0)
    assert np.allclose(p.x[:-1], full.x[:-1])  # nodes 0 .. 4.8 s
    assert full.x[-2] < p.x[-1] < full.x[-1]


def test_paper_histories_are_sensible():
    P = Predictor.default()
    preds = {k: P.predict(h, 5.0) for k, h in paper_histories().items()}
    x1, x2, x3 = (preds[k].x_fit(5.0) for k in ("paper-1", "paper-2", "paper-3"))
    assert abs(x1 - 75.0) < 2.0
    assert x2 < -15.0 + 20.0 * 5.0   # braking: behind constant velocity
    assert x3 > -15.0 + 13.0 * 5.0   # accelerating: ahead of constant velocity
    assert all(abs(p.x_poly[0] + 15.0) < 0.2 for p in preds.values())


# ---------------------------------------------------------------------------------------
# exactness of the recursion
# ---------------------------------------------------------------------------------------

def _sticky_model(centres, dt=0.5, order=1):
    """A chain that never leaves its state: predictions continue the observed state."""
    m = len(centres)
    edges = 0.5 * (np.asarray(centres[:-1]) + np.asarray(centres[1:]))
    return MTDModel(Q=np.stack([np.eye(m)] * order), lam=np.full(order, 1 / order), edges=edges,
                    centres=centres, dt=dt)


def test_constant_acceleration_is_continued_exactly():
    P = Predictor(_sticky_model([-3.0, -1.5, 0.0, 1.5, 3.0], dt=0.5, order=2))
    p = P.predict(braking(20.0, -1.5), 5.0)
    assert np.allclose(p.x, -15.0 + 20.0 * p.t - 0.75 * p.t ** 2, atol=1e-9)
    assert np.allclose(p.x_poly, [-15.0, 20.0, -0.75, 0.0], atol=1e-9)
    assert np.allclose(p.v, 20.0 - 1.5 * p.t, atol=1e-9)
    assert np.allclose(p.a, -1.5)


def test_speed_is_clamped_at_zero():
    P = Predictor(_sticky_model([-4.0, 0.0, 4.0], dt=0.1))
    p = P.predict(braking(3.0, -4.0), 5.0)  # would stop after 0.75 s
    assert np.all(np.diff(p.x) >= 0)
    assert np.all(p.v >= 0) and p.v[-1] == 0.0
    assert p.x[-1] == pytest.approx(-15.0 + 3.0 ** 2 / 8.0, abs=0.05)  # v²/(2|a|) = 1.125 m


def test_integration_is_exact_for_linear_acceleration():
    dt = 0.5
    tn = dt * np.arange(11)
    q = np.linspace(0.0, 5.0, 37)
    x, v = integrate_nodes([2.0], [10.0], (0.5 * tn)[None, :], dt, q)  # a(t) = t/2
    assert np.allclose(x[0], 2.0 + 10.0 * q + q ** 3 / 12.0, atol=1e-12)
    assert np.allclose(v[0], 10.0 + q ** 2 / 4.0, atol=1e-12)


def test_second_differences():
    x = 3.0 + 2.0 * np.arange(6) * 0.2 + 0.5 * 1.3 * (np.arange(6) * 0.2) ** 2
    assert np.allclose(second_differences(x, 0.2), 1.3)


# ---------------------------------------------------------------------------------------
# bad histories, bad arguments
# ---------------------------------------------------------------------------------------

def test_too_short_history_is_refused_naming_the_field(predictor):
    need = predictor.min_history_s
    t = np.round(np.linspace(-0.5 * need, 0.0, 4), 12)
    h = History(t, 18.0 * t, field="vehicles[1].history", source="s.toml")
    with pytest.raises(HistoryError) as exc:
        predictor.predict(h, 5.0)
    assert exc.value.field == "vehicles[1].history.t"
    assert "shorter than the predictor needs" in str(exc.value)
    assert "s.toml" in str(exc.value)


def test_too_few_samples_is_refused():
    P = Predictor(_sticky_model([-1.0, 0.0, 1.0], dt=0.1))
    h = History([-3.0, 0.0], [-54.0, 0.0])
    with pytest.raises(HistoryError, match="samples"):
        P.predict(h, 5.0)


def test_exactly_minimal_history_is_accepted(predictor):
    n = predictor.model.order
    t = np.round(np.arange(-(n + 1), 1) * predictor.dt, 12)
    p = predictor.predict(History(t, 18.0 * t), 5.0)
    assert np.isfinite(p.x_poly).all()


@pytest.mark.parametrize("tf", [0.0, -1.0, float("nan"), float("inf"), "5", True])
def test_bad_horizon(tf, synthetic_predictor):
    with pytest.raises(ValueError):
        synthetic_predictor.predict(constant_speed(), tf)


def test_unevenly_sampled_history(synthetic_predictor):
    rng = np.random.default_rng(0)
    t = np.r_[np.sort(rng.uniform(-3.0, -0.05, 40)), 0.0]
    p = synthetic_predictor.predict(_hist(-15.0 + 18.0 * t, t=t), 5.0)
    assert np.all(np.abs(p.v - 18.0) < 0.5)


def test_model_without_bins_is_refused():
    with pytest.raises(ModelFileError, match="lacks"):
        Predictor(MTDModel(Q=np.eye(2)[None], lam=[1.0]))


# ---------------------------------------------------------------------------------------
# sampling, batch, speed, files, scenario
# ---------------------------------------------------------------------------------------

def test_quantiles_from_sampled_paths(synthetic_predictor):
    h = braking()
    p = synthetic_predictor.predict(h, 5.0, n_samples=400, quantiles=(0.1, 0.5, 0.9), seed=1)
    q10, q50, q90 = p.quantiles[0.1], p.quantiles[0.5], p.quantiles[0.9]
    assert np.all(q10 <= q50 + 1e-12) and np.all(q50 <= q90 + 1e-12)
    assert q90[-1] - q10[-1] > 0.5
    assert abs(q50[-1] - p.x[-1]) < 0.25 * (q90[-1] - q10[-1]) + 0.5  # median near the mean
    again = synthetic_predictor.predict(h, 5.0, n_samples=400, quantiles=(0.1, 0.5, 0.9), seed=1)
    assert np.array_equal(again.quantiles[0.5], q50)
    with pytest.raises(ValueError):
        synthetic_predictor.predict(h, 5.0, quantiles=(1.5,))


def test_batch_equals_single(predictor):
    hists = [constant_speed(), braking(), braking(13.0, 2.0), braking(25.0, -3.0)]
    X = np.stack([h.x for h in hists])
    q = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])  # on the grid of every model step
    raw = predictor.predict_batch(T_HIST, X, q, 5.0)
    cub = predictor.predict_batch(T_HIST, X, q, 5.0, cubic=True)
    for k, h in enumerate(hists):
        p = predictor.predict(h, 5.0)
        assert np.allclose(raw[k], np.interp(q, p.t, p.x), atol=1e-9)
        assert np.allclose(cub[k], p.x_fit(q), atol=1e-8)


def test_from_file_and_default(tmp_path, synthetic_predictor):
    path = synthetic_predictor.model.save(tmp_path / "model.json")
    P = Predictor.from_file(path)
    assert P.name == str(path)
    h = braking()
    assert np.allclose(P.predict(h, 5.0).x_poly, synthetic_predictor.predict(h, 5.0).x_poly, atol=0)
    d = Predictor.default()
    assert d.name == "builtin" and d.predict(h, 5.0).model == "builtin"
    prov = d.model.provenance
    assert prov["trained_by"] == "iamp.prediction.evaluate.train_default_model"  # restructure: keep
    assert "dataset_sha256_track_t_x" in prov and prov["split"]["test_seed"] == 0


def test_scenario_to_problem_uses_the_prediction():
    text = history_scenario(T_HIST, braking().x)
    sc = loads_scenario(text, "hist.toml")
    P = Predictor.default()
    problem, preds = sc.to_problem(P)
    assert problem.vehicles[0].x_poly == preds[0].x_poly == P.predict(sc.vehicles[0].history, 5.0).x_poly
