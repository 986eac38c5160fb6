"""The leader-aware predictor (issue 23): car-following maths, leaders, evaluation, files, CLI, real data."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path, needs_data
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction.evaluation.leader import _rows_mask, bootstrap_table, errors
from iamp.prediction.initial_state import smooth_histories
from iamp.prediction.leader import car_following as cf
from iamp.prediction.leader.car_following import CarFollowingLaw, accel, calibrate, simulate
from iamp.prediction.leader.ego import iterate_with_planner, predict_follower_of_plan
from iamp.prediction.leader.leaders import derive_leaders, ngsim_leaders
from iamp.prediction.leader.model import (
    LeaderModel,
    LeaderPredictor,
    default_leader_model,
    load_any_model,
    train_leader_model,
)
from iamp.prediction.loaders import load
from iamp.prediction.mtd.model import ModelFileError
from iamp.prediction.predictor import Predictor
from iamp.prediction.windows import Windows, baseline_ca, baseline_cv, make_windows, metrics

REPO = Path(__file__).resolve().parents[1]
US101 = data_path("ngsim-us101", "us101_ngsim.csv.gz")
needs_us101 = needs_data("ngsim-us101", "us101_ngsim.csv.gz")

IDM = CarFollowingLaw("idm", {"a": 1.2, "b": 1.8, "v0": 30.0, "T": 1.3, "s0": 2.0})
LIN = CarFollowingLaw("linear", {"c_v": 0.4, "c_s": 0.08, "T": 1.2, "s0": 3.0})

speeds = st.floats(0.0, 29.0)


# ---------------------------------------------------------------------------------------
# car-following maths
# ---------------------------------------------------------------------------------------

@given(v=speeds, law=st.sampled_from([IDM, LIN]))
def test_equilibrium_gap_is_a_fixed_point(v: float, law: CarFollowingLaw) -> None:
    """At the equilibrium gap behind a leader at the same speed the law's acceleration is zero."""
    s = float(law.equilibrium_gap(v))
    assert abs(float(accel(law, v, s, v))) < 1e-9 * max(1.0, s)


@given(v=st.floats(1.0, 29.0), ds=st.floats(0.5, 20.0))
def test_idm_monotone_in_gap_and_closing_speed(v: float, ds: float) -> None:
    """IDM: a larger gap never lowers the acceleration; a faster-closing approach never raises it."""
    s = float(IDM.equilibrium_gap(v))
    assert accel(IDM, v, s + ds, v) >= accel(IDM, v, s, v)
    assert accel(IDM, v, s, v - ds * 0.5) <= accel(IDM, v, s, v) + 1e-12


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_linear_calibration_recovers_the_law(seed: int) -> None:
    """Noise-free rows of a linear law: least squares returns its parameters (closed form)."""
    rng = np.random.default_rng(seed)
    v, vl = rng.uniform(0, 30, 500), rng.uniform(0, 30, 500)
    s = rng.uniform(2, 70, 500)
    fit = calibrate("linear", v, s, vl, accel(LIN, v, s, vl))
    for k, val in LIN.params.items():
        assert fit.params[k] == pytest.approx(val, rel=1e-8, abs=1e-8)
    assert fit.fit["rms_residual_mps2"] < 1e-9


def test_idm_calibration_recovers_the_law() -> None:
    rng = np.random.default_rng(3)
    v, vl = rng.uniform(2, 28, 3000), rng.uniform(2, 28, 3000)
    s = IDM.equilibrium_gap(v) * rng.uniform(0.6, 2.0, 3000)
    fit = calibrate("idm", v, s, vl, accel(IDM, v, s, vl))
    for k, val in IDM.params.items():
        assert fit.params[k] == pytest.approx(val, rel=1e-3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), law=st.sampled_from([IDM, LIN]))
def test_simulation_keeps_order_and_nonnegative_speed(seed: int, law: CarFollowingLaw) -> None:
    """Whatever the leader does, the follower never passes its rear minus MIN_GAP_M and never reverses."""
    rng = np.random.default_rng(seed)
    B, M1 = 8, 51
    vl = np.maximum(np.cumsum(rng.normal(0, 1.5, (B, M1)), axis=1) + rng.uniform(0, 25, (B, 1)), 0.0)
    xl = 40.0 + np.concatenate([np.zeros((B, 1)), np.cumsum(0.5 * (vl[:, 1:] + vl[:, :-1]) * 0.1, axis=1)], axis=1)
    x0 = rng.uniform(0, 30, B)
    x, v = simulate(law, x0, rng.uniform(0, 35, B), xl, vl, 4.5, 0.1)
    assert np.all(v >= 0)
    assert np.all(np.diff(x, axis=1) >= -1e-12)
    gap_ok = x[:, 1:] <= np.maximum(xl[:, 1:] - 4.5 - cf.MIN_GAP_M, x[:, :-1]) + 1e-9
    assert np.all(gap_ok)


# ---------------------------------------------------------------------------------------
# predictor: fallback, plan as leader, iteration
# ---------------------------------------------------------------------------------------

T_HIST = np.round(np.arange(-30, 1) * 0.1, 10)


@settings(max_examples=25, deadline=None)
@given(v=st.floats(3, 30), a=st.floats(-1.5, 1.5), far=st.floats(cf.MAX_GAP_M + 1, 400))
def test_fallback_equals_mtd(v: float, a: float, far: float) -> None:
    """No leader, or a leader beyond MAX_GAP_M: the prediction is the MTD predictor's, bit for bit."""
    lp = LeaderPredictor(default_leader_model())
    X = (v * T_HIST + 0.5 * a * T_HIST ** 2)[None, :]
    q = 0.1 * np.arange(1, 51)
    mtd = Predictor.default().predict_batch(T_HIST, X, q, 5.0)
    assert np.array_equal(lp.predict_batch(T_HIST, X, q, 5.0), mtd)
    assert np.array_equal(lp.predict_batch(T_HIST, X, q, 5.0, XL_hist=X + 10, has_leader=[False]), mtd)
    assert np.array_equal(lp.predict_batch(T_HIST, X, q, 5.0, XL_hist=X + far + 4.5, has_leader=[True]), mtd)


def test_leader_in_equilibrium_is_followed_at_constant_speed() -> None:
    """Leader and follower at the same speed at the equilibrium gap: the prediction is constant speed."""
    law = default_leader_model().law
    lp = LeaderPredictor(LeaderModel(law))
    v = 15.0
    s = float(law.equilibrium_gap(v))
    X = (v * T_HIST)[None, :]
    q = 0.1 * np.arange(1, 51)
    x = lp.predict_batch(T_HIST, X, q, 5.0, XL_hist=X + s + 4.5, has_leader=[True], offset=4.5)[0]
    assert np.max(np.abs(x - v * q)) < 1e-6


def test_ego_cutting_in_slows_the_follower() -> None:
    """The ego merging 10 m ahead at 10 m/s: a follower at 20 m/s predicted to brake, never into the ego."""
    lp = LeaderPredictor(default_leader_model())
    x_hist = 20.0 * T_HIST
    t_plan = np.linspace(0, 5, 51)
    x_plan = 10.0 + 4.5 + 10.0 * t_plan
    poly, x = predict_follower_of_plan(lp, T_HIST, x_hist, t_plan, x_plan, 5.0, offset=4.5)
    free = lp.fallback.predict_batch(T_HIST, x_hist[None, :], t_plan, 5.0)[0]
    assert x[-1] < free[-1] - 5.0
    assert np.all(x <= x_plan - 4.5 - cf.MIN_GAP_M + 1e-9)
    fit = np.polynomial.polynomial.polyval(t_plan, poly)
    assert np.sqrt(np.mean((fit - x) ** 2)) < 1.0


def test_iteration_stops_at_the_fixed_point_and_at_max_iter() -> None:
    """A contraction converges within the iterations; an oscillation stops after max_iter."""
    def plan(poly: tuple[float, ...]) -> tuple[float, float]:
        return (poly[0], 0.0)

    res = iterate_with_planner(plan, lambda c, _: (0.5 * c + 1.0, 0.0, 0.0, 0.0), (0.0, 0, 0, 0), max_iter=20)
    assert res["converged"] and abs(res["x_poly"][0] - 2.0) < 0.2
    assert all(b < a for a, b in zip(res["changes_m"], res["changes_m"][1:]))
    osc = iterate_with_planner(plan, lambda c, _: (-c + 1.0, 0.0, 0.0, 0.0), (0.0, 0, 0, 0), max_iter=3)
    assert not osc["converged"] and osc["iterations"] == 3 and len(osc["changes_m"]) == 3


# ---------------------------------------------------------------------------------------
# leaders, loaders, windows, CIs
# ---------------------------------------------------------------------------------------

def _platoon_csv(path: Path, n: int = 6, seconds: float = 30.0, seed: int = 0, preceding: bool = True) -> None:
    """A platoon of IDM followers behind a stop-and-go leader, written in NGSIM's CSV layout (feet)."""
    rng = np.random.default_rng(seed)
    dt, K = 0.1, int(seconds / 0.1) + 1
    t = dt * np.arange(K)
    vl = 10 + 6 * np.sin(2 * np.pi * t / 20 + rng.uniform(0, 6))
    xs, vs = [np.cumsum(vl) * dt + 200.0], [vl]
    for _ in range(1, n):
        x = np.empty(K)
        v = np.empty(K)
        v[0] = vl[0]
        x[0] = xs[-1][0] - 4.5 - float(IDM.equilibrium_gap(v[0]))
        for k in range(K - 1):
            s = xs[-1][k] - x[k] - 4.5
            acc = float(np.clip(accel(IDM, v[k], s, vs[-1][k]), -8, 3))
            v[k + 1] = max(v[k] + acc * dt, 0.0)
            x[k + 1] = x[k] + 0.5 * (v[k] + v[k + 1]) * dt
        xs.append(x)
        vs.append(v)
    lines = ["Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,"
             "v_Class,v_Vel,v_Acc,Lane_ID,Preceding,Following,Space_Headway,Time_Headway"]
    ft = 0.3048
    for i in range(n):
        for k in range(K):
            front = (xs[i][k] + 2.25) / ft
            lines.append(f"{i + 1},{k + 1},{K},0,6.0,{front:.3f},0,0,{4.5 / ft:.3f},6,2,{vs[i][k] / ft:.3f},0,1,"
                         f"{i if (preceding and i) else 0},0,0,0")
    data = "\n".join(lines) + "\n"
    if path.suffix == ".gz":
        with gzip.open(path, "wt") as fh:
            fh.write(data)
    else:
        path.write_text(data)


def test_csv_gz_loads_like_csv_and_preceding_maps_to_tracks(tmp_path: Path) -> None:
    _platoon_csv(tmp_path / "p.csv")
    _platoon_csv(tmp_path / "p.csv.gz")
    a, b = load([tmp_path / "p.csv"], "ngsim"), load([tmp_path / "p.csv.gz"], "ngsim")
    assert np.array_equal(a.x, b.x) and np.array_equal(a.track_id, b.track_id)
    L = ngsim_leaders(tmp_path / "p.csv.gz", b)
    assert L.source == "Preceding column"
    # vehicle i+1 (track i) follows vehicle i (track i-1); the platoon head has none
    for tid in b.ids():
        rows = b.track_id == tid
        assert np.all(L.leader[rows] == (tid - 1 if tid > 0 else -1))
    assert np.allclose(L.length, 4.5, atol=1e-3)
    # derivation from lane + position gives the same leaders here
    assert np.array_equal(derive_leaders(b).leader, L.leader)


def test_missing_preceding_is_derived(tmp_path: Path) -> None:
    _platoon_csv(tmp_path / "p.csv.gz", preceding=False)
    tr = load([tmp_path / "p.csv.gz"], "ngsim")
    L = ngsim_leaders(tmp_path / "p.csv.gz", tr)
    assert L.source.startswith("derived")
    assert np.array_equal(L.leader, np.where(tr.track_id > 0, tr.track_id - 1, -1))


def test_leader_model_learns_the_platoon_and_beats_cv(tmp_path: Path) -> None:
    """IDM platoon data: the calibrated leader model predicts the followers better than CV at 5 s."""
    for s in range(3):
        _platoon_csv(tmp_path / f"p{s}.csv.gz", n=8, seconds=40.0, seed=s)
    tr = load([tmp_path / "p0.csv.gz"], "ngsim")
    lm = train_leader_model(tr, ngsim_leaders(tmp_path / "p0.csv.gz", tr), "idm")
    te = load([tmp_path / "p1.csv.gz"], "ngsim")
    from iamp.prediction.evaluation.leader import leader_windows

    win = make_windows(te)
    lw = leader_windows(te, ngsim_leaders(tmp_path / "p1.csv.gz", te), win)
    assert lw.known.sum() == np.sum(win.track_id > 0)
    lp = LeaderPredictor(lm)
    pred = lp.predict_batch(win.t_hist, win.X_hist, win.t_fut, 5.0, XL_hist=lw.XL_hist, has_leader=lw.known,
                            offset=lw.offset)
    k = lw.known
    cv = baseline_cv(win)
    e_l = np.sqrt(np.mean((pred[k, -1] - win.X_fut[k, -1]) ** 2))
    e_cv = np.sqrt(np.mean((cv[k, -1] - win.X_fut[k, -1]) ** 2))
    assert e_l < 0.5 * e_cv


def test_model_file_round_trip_and_kind_validation(tmp_path: Path) -> None:
    m = default_leader_model()
    m.save(tmp_path / "l.json")
    back = load_any_model(tmp_path / "l.json")
    assert isinstance(back, LeaderModel) and back.law.params == m.law.params
    d = json.loads((tmp_path / "l.json").read_text())
    d["kind"] = "bogus"
    (tmp_path / "b.json").write_text(json.dumps(d))
    with pytest.raises(ModelFileError, match="kind"):
        load_any_model(tmp_path / "b.json")
    d["kind"] = "leader"
    d["params"]["a"] = -1.0
    (tmp_path / "c.json").write_text(json.dumps(d))
    with pytest.raises(ModelFileError, match="params"):
        load_any_model(tmp_path / "c.json")
    assert load_any_model(REPO / "prediction" / "data" / "mtd_default.json").order >= 1  # type: ignore[union-attr]


def test_bootstrap_intervals() -> None:
    """Constant per-window errors give degenerate intervals at the value; a method equal to CV differs by 0."""
    tid = np.repeat(np.arange(10), 3)
    e = {"sq": np.full((30, 5), 4.0), "ade": np.full(30, 1.0), "fde": np.full(30, 2.0)}
    tb = bootstrap_table({"cv": e, "same": e}, tid, resamples=50)
    r = tb["methods"]["same"]
    assert r["rmse_m"][-1] == pytest.approx(2.0) and r["rmse_ci95"][-1] == pytest.approx([2.0, 2.0])
    assert r["diff_to_cv"]["rmse_5s_rel"] == 0.0 and r["diff_to_cv"]["fde_ci95"] == [0.0, 0.0]
    rng = np.random.default_rng(1)
    noisy = {"sq": rng.uniform(0, 9, (30, 5)), "ade": rng.uniform(0, 2, 30), "fde": rng.uniform(0, 4, 30)}
    tb = bootstrap_table({"cv": noisy}, tid, resamples=400)
    m = tb["methods"]["cv"]
    assert m["ade_ci95"][0] <= m["ade_m"] <= m["ade_ci95"][1] and m["ade_ci95"][0] < m["ade_ci95"][1]
    err = errors(np.zeros((2, 50)), np.ones((2, 50)), 0.1 * np.arange(1, 51))
    assert np.all(err["sq"] == 1.0) and np.all(err["fde"] == 1.0)


def test_rows_mask_of_a_vehicle_split() -> None:
    from iamp.prediction.evaluation.data import synthetic_tracks

    tr = synthetic_tracks(10, 20.0)
    train, test = tr.split_by_track(0.3, seed=0)
    m = _rows_mask(tr, train)
    assert m.sum() == len(train) and not np.any(np.isin(tr.track_id[m], test.ids()))


# ---------------------------------------------------------------------------------------
# robust constant acceleration
# ---------------------------------------------------------------------------------------

@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), sigma=st.sampled_from([0.03, 0.1]))
def test_ca_stays_bounded_on_noisy_histories(seed: int, sigma: float) -> None:
    """Quadratic motion plus white noise σ: CA's 5-s error stays within 5 standard deviations of its a_0 noise.

    The LS quadratic over 3 s (31 samples) has sd(a_0) ≈ 2σ√(180/(N T⁴)) (0.054 m/s² for 10 cm), so
    ½·sd·25 s² ≈ 0.7 m at 5 s; the smoother's a_0 (jerk PSD 10) is several times noisier.
    """
    rng = np.random.default_rng(seed)
    W = 200
    v, a = rng.uniform(5, 30, W), rng.uniform(-0.5, 0.5, W)
    tf = 0.1 * np.arange(1, 51)
    Xh = v[:, None] * T_HIST + 0.5 * a[:, None] * T_HIST ** 2 + rng.normal(0, sigma, (W, T_HIST.size))
    Xf = v[:, None] * tf + 0.5 * a[:, None] * tf ** 2
    win = Windows(T_HIST, Xh, tf, Xf, np.arange(W))
    rmse5 = metrics(baseline_ca(win), win)["rmse"][-1]
    sd_a = 2 * sigma * np.sqrt(180 / (31 * 3.0 ** 4))
    assert rmse5 < 5 * (0.5 * sd_a * 25) + 1.0 * sigma * 10
    sm = smooth_histories(T_HIST, Xh, 10.0)
    assert np.std(sm.a[:, -1] - a) > 2 * np.std(np.polyfit(T_HIST, Xh.T, 2)[0] * 2 - a)
    clean = Windows(T_HIST, Xh * 0 + v[:, None] * T_HIST + 0.5 * a[:, None] * T_HIST ** 2, tf, Xf, np.arange(W))
    assert metrics(baseline_ca(clean), clean)["rmse"][-1] < 1e-6 + 0.01 * np.max(np.abs(a))


# ---------------------------------------------------------------------------------------
# CLI and real data
# ---------------------------------------------------------------------------------------

def _iamp(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "iamp", *args], capture_output=True, text=True, timeout=600,
                          cwd=REPO)


def test_cli_train_leader_and_evaluate_json_is_additive(tmp_path: Path) -> None:
    _platoon_csv(tmp_path / "p.csv.gz", n=8, seconds=40.0)
    r = _iamp("train", str(tmp_path / "p.csv.gz"), "--format", "ngsim", "--model-kind", "leader", "--out",
              str(tmp_path / "l.json"), "-q")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "l.json").read_text())["kind"] == "leader"
    r = _iamp("evaluate-predictor", "--data", str(tmp_path / "p.csv.gz"), "--format", "ngsim", "--leader-model",
              str(tmp_path / "l.json"), "--json", "-q")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert {"cv", "ca", "mtd", "leader"} <= set(res["rmse_m"]) and {"ade_m", "fde_m", "diff_to_cv"} <= set(res)
    tabs = res["interaction"]["tables"]
    assert set(tabs) == {"all", "free", "congested", "leader_known", "leader_unknown"}
    assert "leader-oracle" in tabs["all"]["methods"]
    r = _iamp("evaluate-predictor", "--data", str(tmp_path / "p.csv.gz"), "--format", "ngsim", "--leader-model",
              str(tmp_path / "p.csv.gz"))
    assert r.returncode == 2 and "not a usable leader model" in r.stderr and "Traceback" not in r.stderr


def test_cli_markdown_tables_match_the_json_and_refuse_overwrite(tmp_path: Path) -> None:
    """--markdown writes the 5-s RMSE of every method as the JSON has it, with the command; a second run
    without --force exits 2 with one line; --markdown with --no-interaction is refused."""
    _platoon_csv(tmp_path / "p.csv.gz", n=8, seconds=40.0)
    md = tmp_path / "t.md"
    args = ("evaluate-predictor", "--data", str(tmp_path / "p.csv.gz"), "--format", "ngsim", "--markdown", str(md))
    r = _iamp(*args, "--json", "-q")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    text = md.read_text()
    for name, row in res["interaction"]["tables"]["all"]["methods"].items():
        line = next(ln for ln in text.splitlines() if ln.startswith(f"| {name} |"))
        assert f"| {row['rmse_m'][-1]:.2f} [" in line
    assert "Command: `iamp evaluate-predictor" in text and "--markdown" in text
    r = _iamp(*args, "-q")
    assert r.returncode == 2 and "--force" in r.stderr and "Traceback" not in r.stderr
    r = _iamp(*args, "--force", "--no-interaction", "-q")
    assert r.returncode == 2 and "Traceback" not in r.stderr


@needs_us101
def test_us101_leaders_and_vehicle_split_beats_cv() -> None:
    """US-101: Preceding maps to tracks, the derivation agrees, and the leader model beats CV at 5 s."""
    from iamp.prediction.evaluation.user import evaluate_file

    tr = load([US101], "ngsim")
    L = ngsim_leaders(US101, tr)
    assert L.source == "Preceding column" and 0.8 < L.known_fraction < 0.9
    assert np.mean(derive_leaders(tr, L.length).leader == L.leader) > 0.99
    res = evaluate_file(US101, "ngsim", split="vehicle", resamples=200)
    all_ = res["interaction"]["tables"]["all"]["methods"]
    assert all_["leader"]["diff_to_cv"]["rmse_5s_rel"] < -0.15
    assert all_["leader"]["diff_to_cv"]["rmse_5s_rel_ci95"][1] < 0
    assert res["rmse_m"]["ca"][-1] < 2 * res["rmse_m"]["cv"][-1]  # the robust a_0: CA no longer explodes
