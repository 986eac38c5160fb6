"""The evaluation protocol (prediction/evaluate.py), the shipped model's provenance, and the
predictor's command-line interface (iamp/cli_prediction.py)."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from scenario_texts import history_scenario

from iamp.cli import prediction as cli_prediction
from iamp.prediction.evaluation import evaluate as E
from iamp.prediction.mtd import MTDModel
from iamp.prediction.predictor import DEFAULT_MODEL_FILE, Predictor
from iamp.prediction.tracks.table import Tracks

# ---------------------------------------------------------------------------------------
# protocol pieces
# ---------------------------------------------------------------------------------------


def _tracks(kind: str, n=3, duration=20.0, dt=0.1):
    cols = {k: [] for k in ("track_id", "t", "x", "v", "a", "lane")}
    t = dt * np.arange(int(round(duration / dt)) + 1)
    for tid in range(n):
        v0 = 15.0 + tid
        a = 0.0 if kind == "cv" else 0.3
        x = 100.0 * tid + v0 * t + 0.5 * a * t * t
        for key, val in zip(cols, (np.full(t.size, tid), t, x, v0 + a * t, np.full(t.size, a), np.zeros(t.size))):
            cols[key].append(val)
    return Tracks(*(np.concatenate(cols[k]) for k in cols), dt=dt, meta={"format": "test"})


def test_windows_geometry():
    win = E.make_windows(_tracks("cv", n=2, duration=20.0))
    # 20 s tracks: a window starts every 1 s while 3 s + 5 s fit: 0..12 s -> 13 per track
    assert win.n == 26
    assert win.t_hist.shape == (31,) and win.t_hist[0] == -3.0 and win.t_hist[-1] == 0.0
    assert win.t_fut.shape == (50,) and win.t_fut[0] == pytest.approx(0.1) and win.t_fut[-1] == pytest.approx(5.0)
    assert np.all(win.X_hist[:, -1] == 0.0)  # positions relative to t = 0
    assert set(win.track_id) == {0, 1}


def test_metrics_formulas():
    win = E.make_windows(_tracks("cv", n=1, duration=10.0))
    err = np.zeros_like(win.X_fut)
    err[:, :] = np.arange(win.n)[:, None] * 0.1 + win.t_fut[None, :]
    m = E.metrics(win.X_fut + err, win)
    for h, r in zip(E.HORIZONS, m["rmse"]):
        col = int(np.argmin(np.abs(win.t_fut - h)))
        assert r == pytest.approx(math.sqrt(np.mean(err[:, col] ** 2)))
    assert m["ade"] == pytest.approx(np.mean(np.abs(err)))
    assert m["fde"] == pytest.approx(np.mean(np.abs(err[:, -1])))
    assert m["rmse_mean"] == pytest.approx(np.mean(m["rmse"]))


def test_baselines_are_exact_on_their_own_motion():
    win = E.make_windows(_tracks("cv"))
    assert E.metrics(E.baseline_cv(win), win)["rmse"][-1] < 1e-9
    win = E.make_windows(_tracks("ca"))
    assert E.metrics(E.baseline_ca(win), win)["rmse"][-1] < 1e-9
    assert E.metrics(E.baseline_cv(win), win)["rmse"][-1] == pytest.approx(0.5 * 0.3 * 25.0, rel=1e-6)


def test_split_is_by_whole_track():
    tracks = E.synthetic_tracks(n_tracks=20, duration=20.0)
    train, val, test, rest = E.split_tracks(tracks)
    ids = [set(p.ids()) for p in (train, val, test)]
    assert not (ids[0] & ids[1]) and not (ids[0] & ids[2]) and not (ids[1] & ids[2])
    assert ids[0] | ids[1] | ids[2] == set(tracks.ids())
    assert set(rest.ids()) == ids[0] | ids[1]


@pytest.fixture(scope="module")
def small_results():
    tracks = E.synthetic_tracks(n_tracks=15, duration=40.0, seed=2)
    train, val, _, _ = E.split_tracks(tracks)
    sel = E.select_model(train, val, grid_dt=(0.2, 1.0), grid_width=(0.5, 1.0), grid_order=(1, 2, 3))
    res = E.run_evaluation(tracks, select=False, config=sel["chosen"])
    res["selection"] = sel
    return res


def test_selection_picks_the_validation_minimum(small_results):
    sel = small_results["selection"]
    best = min(sel["rows"], key=lambda r: r["val"]["rmse_mean"])
    assert {k: sel["chosen"][k] for k in ("dt", "width", "order")} == \
        {k: best[k] for k in ("dt", "width", "order")}
    # order 3 at dt = 1 s does not fit in a 3 s history and is skipped
    assert not any(r["dt"] == 1.0 and r["order"] == 3 for r in sel["rows"])
    assert len(sel["rows"]) == 2 * 3 + 2 * 2
    for r in sel["rows"]:
        k = r["order"] * r["n_states"] * (r["n_states"] - 1) + r["order"] - 1
        assert r["n_parameters"] == k
        assert r["bic"] == pytest.approx(k * math.log(r["n_obs"]) - 2 * r["loglik"])


def test_run_evaluation_reports_every_method(small_results):
    test = small_results["test"]
    assert {"cv", "ca", "mtd", "mtd-cubic", "markov1", "mtd-lp", "mtd-mle-lambda"} <= set(test)
    for r in test.values():
        assert len(r["rmse"]) == 5 and all(np.isfinite(r["rmse"]))
        assert r["rmse"] == sorted(r["rmse"])  # errors grow with the horizon
    # the cubic fit changes the predicted trajectory only a little
    assert abs(test["mtd-cubic"]["rmse"][-1] - test["mtd"]["rmse"][-1]) < 0.2
    assert set(small_results["paper_histories"]) == {"paper-1", "paper-2", "paper-3"}


def test_write_evaluation_report(tmp_path, small_results):
    E.write_evaluation_report(tmp_path, small_results)
    data = json.loads((tmp_path / "predictor_eval.json").read_text())
    assert data["test"]["cv"]["rmse"] == small_results["test"]["cv"]["rmse"]
    rmse = (tmp_path / "tables" / "predictor_rmse.tex").read_text()
    sel = (tmp_path / "tables" / "predictor_selection.tex").read_text()
    for tex in (rmse, sel):
        assert "\\toprule" in tex and "\\midrule" in tex and "\\bottomrule" in tex
    assert "0.73/1.78/3.13/4.78/6.68" in rmse and "different dataset and metric" in rmse
    assert "Constant velocity" in rmse and "MTD, cubic fit" in rmse
    assert "--" in sel  # skipped orders


# ---------------------------------------------------------------------------------------
# the shipped model and the committed report
# ---------------------------------------------------------------------------------------

def test_shipped_model_matches_the_default_config():
    P = Predictor.default()
    cfg = P.model.provenance["config"]
    assert cfg == E.DEFAULT_CONFIG
    assert P.model.order == cfg["order"] and P.dt == cfg["dt"] and P.model.estimator == cfg["estimator"]
    assert P.min_history_s <= 3.0  # the paper's 3 s histories are enough
    d = json.loads((__import__("importlib").resources.files("iamp.prediction") / "data" / DEFAULT_MODEL_FILE)
                   .read_text())
    assert {"bins", "dt", "order", "Q", "lambda", "estimator", "provenance", "counts"} <= set(d)


def test_train_default_model_reproduces_the_shipped_model():
    shipped = Predictor.default().model
    model = E.train_default_model()
    # The EM fit stops when the average log-likelihood l/N rises by less than tol = 1e-10 over a
    # cycle; it is not bitwise reproducible across numpy versions (summation order), and runs
    # that stop at such a point agree in l/N to about tol.  Near a maximum
    # l/N(θ*) - l/N(θ) ≈ ½ h δ², so an l/N gap of tol allows parameter offsets δ up to
    # sqrt(2 tol / h); with per-transition curvature h <= 1 that is sqrt(2 tol) ≈ 1.4e-5 (directions
    # of smaller curvature, e.g. the MTD's non-identified shifts, can move more: measured 1.7e-4
    # between tol = 1e-10 and 1e-15).  So: the likelihood to tol, the parameters to sqrt(2 tol), and
    # the transition law P(x_t | past) that the predictor uses to sqrt(2 tol).
    tol = 1e-10
    assert abs(model.loglik - shipped.loglik) / model.n_obs <= tol
    bound = np.sqrt(2 * tol)
    assert np.max(np.abs(model.Q - shipped.Q)) <= bound and np.max(np.abs(model.lam - shipped.lam)) <= bound
    rng = np.random.default_rng(0)
    for past in rng.integers(0, model.n_states, size=(50, model.order)):
        assert np.max(np.abs(model.transition_probabilities(past) - shipped.transition_probabilities(past))) <= bound
    assert model.provenance == shipped.provenance


# ---------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------

SV2 = """
[[vehicles]]
name = "sv2"
corner = "rear-upper"
y = -2.0
length = 4.8
width = 1.8
safety_x = 5.0
safety_y = 0.5
x_poly = [40.0, 18.0, 0.1]
"""


def _scenario_file(tmp_path, t=None, name="hist-2"):
    h = E.paper_histories()["paper-2"]
    t = h.t if t is None else t
    x = -15.0 + 20.0 * np.asarray(t) - 0.75 * np.asarray(t) ** 2
    p = tmp_path / f"{name}.toml"
    p.write_text(history_scenario(t, x, name=name, extra=SV2))
    return p


def test_cli_predict_json_contract(tmp_path, cli):
    path = _scenario_file(tmp_path)
    r = cli("predict", path, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert r.stdout.count("\n") == 1
    assert {"scenario", "model", "vehicles"} <= set(out)
    assert out["scenario"] == "hist-2" and out["model"] == "builtin"
    v1, v2 = out["vehicles"]
    assert {"name", "x_poly", "t", "x"} <= set(v1) and v1["name"] == "sv1"
    p = Predictor.default().predict(E.paper_histories()["paper-2"], 5.0)
    assert np.allclose(v1["x_poly"], p.x_poly, atol=1e-9) and np.allclose(v1["x"], p.x, atol=1e-9)
    assert np.allclose(v1["t"], p.t)
    # the x_poly vehicle passes through unchanged, sampled at the same times
    assert v2["x_poly"] == [40.0, 18.0, 0.1] and v2["t"] == v1["t"]
    assert np.allclose(v2["x"], 40.0 + 18.0 * np.array(v2["t"]) + 0.1 * np.array(v2["t"]) ** 2)


def test_cli_predict_with_model_file(tmp_path, cli):
    model = Predictor.default().model
    mpath = model.save(tmp_path / "m.json")
    r = cli("predict", _scenario_file(tmp_path), "--model", mpath, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["model"] == str(mpath)
    r = cli("predict", _scenario_file(tmp_path))
    assert r.returncode == 0 and "sv1" in r.stdout and "[history]" in r.stdout


def test_cli_predict_bad_inputs(tmp_path, cli):
    short = _scenario_file(tmp_path, t=[-0.2, -0.1, 0.0], name="short")
    r = cli("predict", short, "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "vehicles[0].history.t" in r.stderr and "short.toml" in r.stderr
    assert "Traceback" not in r.stderr
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    r = cli("predict", _scenario_file(tmp_path), "--model", bad)
    # one line naming the file (argparse validates --model: "iamp predict: error: argument --model: ...")
    assert r.returncode == 2 and r.stderr.startswith("iamp") and "error:" in r.stderr and "bad.json" in r.stderr
    assert r.stderr.count("\n") == 1
    r = cli("predict", tmp_path / "missing.toml")
    assert r.returncode == 2 and r.stderr.count("\n") == 1


def _fcd_csv(path, tracks):
    lines = ["timestep_time;vehicle_id;vehicle_x;vehicle_speed;vehicle_lane"]
    for tid, t, x, v, *_ in tracks.iter_tracks():
        for ti, xi, vi in zip(t, x, v):
            lines.append(f"{ti:.2f};veh{tid};{xi + 2.5:.2f};{vi:.2f};main_0")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cli_train(tmp_path, cli):
    data = _fcd_csv(tmp_path / "fcd.csv", E.synthetic_tracks(n_tracks=6, duration=40.0))
    out = tmp_path / "model.json"
    r = cli("train", data, "--format", "sumo", "--out", out, "--order", "2", "--dt", "0.2", "--bins", "9")
    assert r.returncode == 0, r.stderr
    for word in ("log-likelihood", "AIC", "BIC", "lambda"):
        assert word in r.stdout
    model = MTDModel.load(out)
    assert model.order == 2 and model.n_states == 9 and model.dt == 0.2
    assert model.provenance["trained_by"] == "iamp train"
    r = cli("train", data, "--format", "sumo", "--out", out, "--bins", "1,0")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert MTDModel.load(out).order == 2  # the existing file is untouched
    r = cli("train", tmp_path / "none.csv", "--format", "sumo", "--out", out)
    assert r.returncode == 2 and r.stderr.count("\n") == 1


def test_cli_functions_directly(tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="iamp")
    sub = parser.add_subparsers(dest="command")
    cli_prediction.add_parsers(sub)
    args = parser.parse_args(["predict", str(_scenario_file(tmp_path)), "--json"])
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["vehicles"][0]["name"] == "sv1"
    assert np.allclose(cli_prediction.parse_bins("4", 0.5, 2.0), [-1.0, 0.0, 1.0])
    assert np.allclose(cli_prediction.parse_bins(None, 1.0, 2.0), [-1.5, -0.5, 0.5, 1.5])
    with pytest.raises(ValueError):
        cli_prediction.parse_bins("a,b", 0.5, 2.0)
