"""Issue 12: NGSIM quirks, the load report, the initial-state smoother, SQUAREM, evaluate-predictor."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from iamp.prediction.evaluation.user import evaluate_file
from iamp.prediction.initial_state import noise_sigma, smooth_histories
from iamp.prediction.loaders.formats import FEET, NGSIM_TXT_COLUMNS, load_ngsim, load_with_report
from iamp.prediction.mtd.em import em_joint, squarem_cycle, squarem_extrapolate
from iamp.prediction.mtd.model import MTDModel
from iamp.prediction.predictor import Predictor

HEADER = ("Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,"
          "v_Class,v_Vel,v_Acc,Lane_ID,Location")


def ngsim_rows(vid: int, frames: range, y0: float, v: float, length: float, global_time: int = 0,
               x_lat: float = 6.0) -> list[list[float]]:
    rows = []
    for f in frames:
        s = (f - frames[0]) / 10
        rows.append([vid, f, len(frames), global_time, x_lat, y0 + v * s, 0, 0, length, 6, 2, v, 0, 2])
    return rows


def write_csv(path, rows, location="us-101"):
    lines = [HEADER] + [",".join(f"{c:g}" for c in r) + f",{location}" for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_ngsim_all_zero_global_time_keeps_every_row(tmp_path):
    rows = ngsim_rows(1, range(100, 200), 100.0, 50.0, 15.0) + ngsim_rows(2, range(100, 200), 300.0, 40.0, 14.0)
    tb, rep = load_with_report([write_csv(tmp_path / "a.csv", rows)], "ngsim")
    assert rep.rows_read == rep.rows_kept == len(tb) == 200 and rep.rows_dropped == 0
    assert tb.n_tracks == 2
    assert any("Global_Time is 0 in 200 of 200 rows" in n for n in rep.notes)
    # centre = Local_Y - L/2, feet -> metres, 10 Hz
    tr = tb.track(tb.ids()[0])
    assert np.allclose(tr.x, (100.0 + 50.0 * (np.arange(100) / 10) - 7.5) * FEET)
    assert np.allclose(np.diff(tr.t), 0.1)


def test_ngsim_zero_length_uses_vehicle_median_or_front_bumper(tmp_path):
    rows = ngsim_rows(1, range(0, 40), 100.0, 50.0, 0.0)  # never a length: front bumper
    mixed = ngsim_rows(2, range(0, 40), 300.0, 40.0, 16.0)
    for r in mixed[:10]:
        r[8] = 0.0  # zero length in some rows: the vehicle's median positive length is used
    tb, rep = load_with_report([write_csv(tmp_path / "b.csv", rows + mixed)], "ngsim")
    assert tb.meta["vehicles_unknown_length"] == 1
    assert any("front bumper" in n for n in rep.notes)
    t1, t2 = (tb.track(i) for i in tb.ids())
    assert np.allclose(t1.x, (100.0 + 50.0 * np.arange(40) / 10) * FEET)  # front bumper kept
    assert np.allclose(t2.x, (300.0 + 40.0 * np.arange(40) / 10 - 8.0) * FEET)  # one reference for all rows


def test_ngsim_headerless_txt_matches_csv(tmp_path):
    rows = ngsim_rows(5, range(10, 60), 120.0, 45.0, 15.0, global_time=1113433135300)
    txt = tmp_path / "trajectories-0750am-0805am.txt"
    full = []
    for r in rows:  # the 18 documented columns
        d = dict(zip(HEADER.split(","), r))
        full.append([d.get(c, d.get("v_length") if c == "v_Length" else 0) for c in NGSIM_TXT_COLUMNS])
    txt.write_text("\n".join("   ".join(f"{c:g}" for c in r) for r in full) + "\n")
    a = load_ngsim(txt)
    b = load_ngsim(write_csv(tmp_path / "c.csv", rows))
    assert a.meta["layout"].startswith("headerless")
    assert np.allclose(a.x, b.x) and np.allclose(a.v, b.v) and np.allclose(a.t, b.t)
    assert a.y is not None and np.allclose(a.y, 6.0 * FEET)


def test_ngsim_duplicates_and_gaps_are_counted(tmp_path):
    rows = ngsim_rows(1, range(0, 50), 100.0, 50.0, 15.0)
    rows = rows + [list(r) for r in rows[5:8]]  # exact duplicates
    bad = list(rows[20])
    bad[11] = 99.0
    rows.append(bad)  # conflicting row
    rows = [r for r in rows if not 30 <= r[1] < 35]  # a gap of 5 frames
    tb, rep = load_with_report([write_csv(tmp_path / "d.csv", rows)], "ngsim")
    assert rep.dropped["exact duplicate row (same vehicle, frame and values)"] == 3
    assert rep.dropped["conflicting row for the same vehicle and frame (the first in file order kept)"] == 1
    assert rep.rows_read == rep.rows_kept + rep.rows_dropped == len(tb) + 4
    assert tb.n_tracks == 2 and any("split" in n for n in rep.notes)
    assert np.all(tb.v == pytest.approx(50.0 * FEET))  # the first row of the conflicting pair is kept


# -- initial state ---------------------------------------------------------------------------

T = np.round(np.arange(-30, 1) * 0.1, 10)


def test_smoother_exact_on_quadratics_and_noise_level():
    x = -15.0 + 20.0 * T - 0.75 * T * T
    s = smooth_histories(T, x)
    assert s.x[0, -1] == pytest.approx(-15.0, abs=1e-9)
    assert s.v[0, -1] == pytest.approx(20.0, abs=1e-9) and s.a[0, -1] == pytest.approx(-1.5, abs=1e-9)
    rng = np.random.default_rng(1)
    sig = noise_sigma(T, 25.0 * T + rng.normal(0, 0.05, (400, T.size)))
    assert np.median(sig) == pytest.approx(0.05, rel=0.1)  # the robust scale of white noise


def _cruise_model(q: float = 10.0) -> MTDModel:
    """A chain that always moves to the zero-acceleration bin: its prediction is constant velocity."""
    m = 13
    edges = 0.5 * (np.arange(-6, 6) + 0.5)
    Q = np.zeros((m, m))
    Q[6, :] = 1.0
    return MTDModel(Q=np.stack([Q] * 2), lam=[0.5, 0.5], edges=edges, centres=0.5 * np.arange(-6, 7),
                    dt=0.2, settings={"jerk_psd": q})


def test_noisy_constant_velocity_predicted_within_half_a_metre():
    """25 m/s observed with 3 cm noise: the mean 5-s prediction is within 0.5 m of constant velocity."""
    rng = np.random.default_rng(2)
    X = 25.0 * T + rng.normal(0, 0.03, (300, T.size))
    P = Predictor(_cruise_model(), "cruise")
    x5 = P.predict_batch(T, X, np.array([5.0]), 5.0)[:, 0]
    assert abs(np.mean(x5) - 125.0) < 0.5
    assert np.sqrt(np.mean((x5 - 125.0) ** 2)) < 1.5  # the raw 3-sample estimate was ~10 m
    shipped = Predictor.default()
    clean = shipped.predict_batch(T, 25.0 * T[None], np.array([5.0]), 5.0)[0, 0]
    noisy = shipped.predict_batch(T, X, np.array([5.0]), 5.0)[:, 0]
    assert abs(np.mean(noisy) - clean) < 0.5  # noise no longer biases the shipped model


def test_noisy_constant_acceleration_history():
    rng = np.random.default_rng(3)
    truth = 20.0 * T + 0.5 * 1.0 * T * T
    s = smooth_histories(T, truth + rng.normal(0, 0.03, (300, T.size)))
    assert abs(np.mean(s.v[:, -1]) - 20.0) < 0.05 and abs(np.mean(s.a[:, -1]) - 1.0) < 0.1


# -- SQUAREM -----------------------------------------------------------------------------------

def test_squarem_lands_on_the_fixed_point_of_a_linear_iteration():
    rng = np.random.default_rng(4)
    lam_s = np.array([0.3, 0.7])
    Q_s = rng.dirichlet(np.ones(3), size=(2, 3)).transpose(0, 2, 1)  # columns sum to 1 (axis 1)
    rho = 0.6
    lam0 = np.array([0.5, 0.5])
    Q0 = rng.dirichlet(np.ones(3), size=(2, 3)).transpose(0, 2, 1)
    Q0 = 0.8 * Q_s + 0.2 * Q0

    def step(lam, Q):
        return lam_s + rho * (lam - lam_s), Q_s + rho * (Q - Q_s)

    lam1, Q1 = step(lam0, Q0)
    lam2, Q2 = step(lam1, Q1)
    lam_e, Q_e = squarem_extrapolate(lam0, Q0, lam1, Q1, lam2, Q2)
    assert np.allclose(lam_e, lam_s, atol=1e-12) and np.allclose(Q_e, Q_s, atol=1e-12)
    assert np.allclose(Q_e.sum(axis=1), 1.0) and lam_e.sum() == pytest.approx(1.0)


def test_squarem_safeguard_keeps_the_plain_em_step_when_extrapolation_is_worse():
    lam = np.array([0.5, 0.5])
    Q = np.stack([np.full((2, 2), 0.5)] * 2)
    calls = []

    def em(lam, Q):  # a contraction towards (0.9, 0.1) whose "likelihood" punishes the extrapolated point
        calls.append(lam.copy())
        new = np.array([0.9, 0.1]) + 0.5 * (lam - np.array([0.9, 0.1]))
        ll = -abs(lam[0] - 0.7) if len(calls) < 3 else -10.0
        return new, Q, ll

    lam_n, _, _, evals, accepted = squarem_cycle(em, lam, Q)
    assert evals == 3 and not accepted
    assert np.allclose(lam_n, np.array([0.9, 0.1]) + 0.25 * (lam - np.array([0.9, 0.1])))  # θ_2


def test_em_from_a_fixed_point_stops_with_zero_accepted_steps():
    """Order 1 from the empirical matrix (the ML estimate): EM does not move, the history ends after
    two cycles (4 EM evaluations) with 0 accepted extrapolations and the same parameters."""
    rows = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [1, 1]])
    w = np.ones(5)
    Q = np.array([[[0.5, 1 / 3], [0.5, 2 / 3]]])
    trace: list[float] = []
    Qf, lam, info = em_joint(rows, w, Q, np.array([1.0]), 2, 0.0, "uniform", 1e-12, 100, trace)
    assert info["accelerated_steps"] == 0 and info["converged"] and info["iterations"] == 4
    assert len(trace) == 2 and trace[0] == trace[1]
    expected = (2 * np.log(0.5) + 2 * np.log(2 / 3) + np.log(1 / 3)) / 5
    assert trace[0] == pytest.approx(expected, rel=1e-12) and info["avg_loglik"] == pytest.approx(expected, rel=1e-12)
    assert np.allclose(Qf, Q) and lam[0] == 1.0


def test_em_likelihood_never_decreases():
    rng = np.random.default_rng(5)
    rows = rng.integers(0, 4, size=(400, 4))
    w = rng.integers(1, 4, size=400).astype(float)
    Q = rng.dirichlet(np.ones(4), size=(3, 4)).transpose(0, 2, 1)
    trace: list[float] = []
    Qf, lam, _ = em_joint(rows, w, Q, np.array([0.2, 0.3, 0.5]), 4, 0.0, "uniform", 1e-12, 5000, trace)
    assert np.all(np.diff(trace) >= -1e-12)
    assert np.allclose(Qf.sum(axis=1), 1.0) and lam.sum() == pytest.approx(1.0)


# -- evaluate-predictor --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ngsim_file(tmp_path_factory):
    rng = np.random.default_rng(6)
    rows = []
    for vid in range(12):
        v0 = rng.uniform(30, 60)
        for f in range(0, 450):
            s = f / 10
            rows.append([vid, f, 450, 0, 6.0 + 0.1 * s, 100 + v0 * s + 2 * np.sin(0.3 * s), 0, 0, 15, 6, 2, v0, 0, 2])
    return write_csv(tmp_path_factory.mktemp("ng") / "e.csv", rows)


def test_evaluate_file_json_contract(ngsim_file):
    seen = []
    res = evaluate_file(ngsim_file, "ngsim", split="vehicle", seed=1, resamples=200,
                        progress=lambda d, t: seen.append((d, t)))
    assert seen[-1][0] == seen[-1][1]
    assert res["windows"] > 0 and res["horizons_s"] == [1.0, 2.0, 3.0, 4.0, 5.0]
    for k in ("cv", "ca", "mtd", "fo"):
        assert len(res["rmse_m"][k]) == 5 and res["ade_m"][k] >= 0 and res["fde_m"][k] >= 0
    d = res["diff_to_cv"]["mtd"]["fde_m"]
    assert (d["ci95"][0] <= d["diff"] + 1e-9 and d["diff"] - 1e-9 <= d["ci95"][1]) or d["ci95"][0] <= d["ci95"][1]
    assert res["lateral_rmse_m"]["constant_y"][-1] == pytest.approx(0.1 * 5 * FEET, rel=1e-6)


def test_cli_evaluate_predictor_json(ngsim_file):
    out = subprocess.run([sys.executable, "-m", "iamp", "evaluate-predictor", "--data", str(ngsim_file),
                          "--format", "ngsim", "--json", "--split", "time"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    assert {"data", "tracks", "windows", "horizons_s", "rmse_m", "ade_m", "fde_m"} <= set(res)
    assert res["load_report"]["rows_read"] == 5400


FIX = __import__("pathlib").Path(__file__).resolve().parent / "fixtures"


def _with_duplicates(src, dst, picks, change=None):
    lines = src.read_text().splitlines()
    extra = [lines[k] for k in picks]
    if change is not None:
        extra.append(change(lines[picks[0]]))
    dst.write_text("\n".join(lines + extra) + "\n")
    return len(lines) - 1


@pytest.mark.parametrize("fmt", ["highd", "sumo"])
def test_highd_and_sumo_duplicates_are_counted_not_fatal(tmp_path, fmt):
    if fmt == "highd":
        src, dst = FIX / "highd" / "02_tracks.csv", tmp_path / "02_tracks.csv"

        def change(line):  # same vehicle and frame, another x
            f = line.split(",")
            f[2] = str(float(f[2]) + 1.0)
            return ",".join(f)
    else:
        src, dst = FIX / "sumo_fcd.csv", tmp_path / "fcd.csv"

        def change(line):  # same vehicle and time, another speed
            f = line.split(";")
            f[6] = str(float(f[6]) + 1.0)
            return ";".join(f)
    clean, _ = load_with_report([src], fmt)
    n = _with_duplicates(src, dst, [3, 4], change)
    tb, rep = load_with_report([dst], fmt)
    assert rep.dropped["exact duplicate row (same vehicle, frame and values)"] == 2
    assert rep.dropped["conflicting row for the same vehicle and frame (the first in file order kept)"] == 1
    assert rep.rows_read == rep.rows_kept + 3 and rep.rows_kept == len(tb) == len(clean)
    assert np.array_equal(tb.x, clean.x) and n >= len(clean)


def test_choose_jerk_psd_prefers_smoothing_under_noise():
    from iamp.prediction.evaluation.data import synthetic_tracks
    from iamp.prediction.evaluation.select import choose_jerk_psd
    from iamp.prediction.windows import make_windows

    win = make_windows(synthetic_tracks(n_tracks=6, duration=40.0, seed=3))
    q, table = choose_jerk_psd(win, grid=(1.0, 1000.0), noise_m=(0.1,))
    assert table["score"]["1"] < table["score"]["1000"] and q == 1.0  # 10 cm of noise: smooth more


def test_squarem_floor_and_renormalisation_when_extrapolation_overshoots():
    """α = -10 overshoots below zero: entries are floored at half their θ_2 value, then λ and every
    column of every Q_i (axis 1) renormalised to sum to one."""
    lam0, lam1, lam2 = np.array([0.5, 0.5]), np.array([0.3, 0.7]), np.array([0.12, 0.88])
    q0, q1, q2 = (np.array([[a, 0.5], [1 - a, 0.5]]) for a in (0.5, 0.3, 0.12))
    Q0, Q1, Q2 = (np.stack([q, q]) for q in (q0, q1, q2))
    lam_e, Q_e = squarem_extrapolate(lam0, Q0, lam1, Q1, lam2, Q2)
    # ‖r‖ = sqrt(5 · 0.2²), ‖v‖ = sqrt(5 · 0.02²): α = -10, θ' = 81 θ0 - 180 θ1 + 100 θ2
    raw = 81 * lam0 - 180 * lam1 + 100 * lam2  # (-1.5, 2.5)
    floored = np.maximum(raw, 0.5 * lam2)
    assert np.allclose(lam_e, floored / floored.sum(), rtol=1e-12)
    col = np.maximum(81 * q0[:, 0] - 180 * q1[:, 0] + 100 * q2[:, 0], 0.5 * q2[:, 0])
    assert np.allclose(Q_e[:, :, 0], col / col.sum(), rtol=1e-12)
    assert np.allclose(Q_e[:, :, 1], 0.5) and np.allclose(Q_e.sum(axis=1), 1.0) and np.all(Q_e > 0)


def test_squarem_cycle_accepts_a_better_extrapolation():
    lam_s = np.array([0.2, 0.8])
    Q = np.stack([np.full((2, 2), 0.5)] * 2)
    calls = []

    def em(lam, Q):  # linear contraction to lam_s; "likelihood" rises towards it
        calls.append(lam.copy())
        return lam_s + 0.5 * (lam - lam_s), Q, -float(np.sum((lam - lam_s) ** 2))

    lam_n, _, ll0, evals, accepted = squarem_cycle(em, np.array([0.6, 0.4]), Q)
    assert accepted and evals == 3 == len(calls)
    assert np.allclose(calls[2], lam_s, atol=1e-12)  # the extrapolation hit the fixed point
    assert np.allclose(lam_n, lam_s, atol=1e-12) and ll0 == pytest.approx(-0.32)


def test_em_lambda_certificate_and_iteration_count():
    from iamp.prediction.mtd.em import em_lambda

    # two lags, P columns: the ML weights maximise Σ w log(P λ); here λ* = (0.5, 0.5) by symmetry
    P = np.array([[0.9, 0.1], [0.1, 0.9]])
    w = np.array([1.0, 1.0])
    lam, info = em_lambda(P, w, np.array([0.8, 0.2]), 1e-12, 10000)
    assert info["converged"] and info["certificate_max_grad_minus_1"] < 1e-12
    assert np.allclose(lam, 0.5, atol=1e-5) and lam.sum() == pytest.approx(1.0, abs=1e-12)
    lam1, info1 = em_lambda(P, w, np.array([0.8, 0.2]), 1e-12, 1)
    assert info1["iterations"] == 1 and not info1["converged"]
    g = (w / (P @ np.array([0.8, 0.2]))) @ P / 2
    assert np.allclose(lam1, np.array([0.8, 0.2]) * g)  # one multiplicative update
    lam0, info0 = em_lambda(P, w, np.array([0.5, 0.5]), 1e-12, 5)
    assert info0["iterations"] == 1 and info0["converged"] and np.array_equal(lam0, [0.5, 0.5])


def test_em_joint_max_iter_counts_em_evaluations():
    """max_iter bounds the EM evaluations: from the ML point one cycle costs 2 (nothing to
    extrapolate), so max_iter = 2 stops after that cycle, before the convergence test can pass."""
    rows = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [1, 1]])
    Q = np.array([[[0.5, 1 / 3], [0.5, 2 / 3]]])
    trace: list[float] = []
    _, _, info = em_joint(rows, np.ones(5), Q, np.array([1.0]), 2, 0.0, "uniform", 1e-12, 2, trace)
    assert info["iterations"] == 2 and len(trace) == 1 and not info["converged"]


def test_fit_reports_progress_per_em_start():
    from iamp.prediction.mtd.estimation import fit

    rng = np.random.default_rng(7)
    seen: list[tuple[int, int]] = []
    fit([rng.integers(0, 3, 200)], 3, 2, "mle", n_starts=3, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_fit_keeps_the_best_start_and_rejects_data_without_transitions():
    from iamp.prediction.mtd.estimation import fit

    rng = np.random.default_rng(8)
    model = fit([rng.integers(0, 3, 300)], 3, 2, "mle", n_starts=4, seed=5)
    runs = model.fit_info["joint_em"]["starts"]
    best = model.fit_info["joint_em"]["best_start"]
    assert len(runs) == 4 and runs[best]["loglik"] == max(r["loglik"] for r in runs)
    assert model.loglik == pytest.approx(runs[best]["loglik"], rel=1e-12)
    with pytest.raises(ValueError, match="no transitions to fit"):
        fit([np.array([0, 1])], 3, 2)


def test_sample_sequence_length_and_deterministic_chain():
    from iamp.prediction.mtd.estimation import sample_sequence

    shift = np.roll(np.eye(4), 1, axis=0)  # state k -> k + 1 (mod 4) with certainty
    model = MTDModel(Q=np.stack([shift, np.eye(4)]), lam=[1.0, 0.0])
    seq = sample_sequence(model, 10, rng=0, init=[2, 3])
    assert seq.tolist() == [2, 3, 0, 1, 2, 3, 0, 1, 2, 3]
    drawn = sample_sequence(model, 7, rng=1)
    assert drawn.size == 7 and np.all(np.diff(drawn[1:]) % 4 == 1)


def test_counting_helpers_validate_and_handle_edges():
    from iamp.prediction.mtd.counts import _normalise_columns, _unique_rows, count_transitions, lag_table

    with pytest.raises(ValueError, match="must hold integers"):
        lag_table([np.array([0.5, 1.0, 2.0])], 1, 3)
    assert lag_table([np.array([0.0, 1.0, 2.0])], 1, 3).tolist() == [[1, 0], [2, 1]]  # integral floats are fine
    with pytest.raises(ValueError, match=r"states must lie in 0\.\.2 \(got 0\.\.3\)"):
        count_transitions([np.array([0, 3, 1])], 3, 1)
    with pytest.raises(ValueError, match=r"got -1\.\.1"):
        count_transitions([np.array([-1, 1])], 3, 1)
    empty = lag_table([np.array([1, 2])], 2, 3)
    assert empty.shape == (0, 3) and empty.dtype == np.int64
    u, w = _unique_rows(empty)
    assert u.shape == (0, 3) and w.size == 0
    C = np.array([[[3.0, 0.0], [1.0, 0.0]]])
    assert np.allclose(_normalise_columns(C, 0.0, "uniform"), [[[0.75, 0.5], [0.25, 0.5]]])
    assert np.allclose(_normalise_columns(C, 0.0, "identity"), [[[0.75, 0.0], [0.25, 1.0]]])
    assert np.allclose(_normalise_columns(C, 1.0, "identity"), [[[4 / 6, 0.5], [2 / 6, 0.5]]])


_Q2 = np.stack([np.full((2, 2), 0.5)] * 2)


@pytest.mark.parametrize("kwargs, message", [
    ({"Q": np.zeros((0, 2, 2)), "lam": []}, r"shape \(n, m, m\)"),
    ({"Q": np.full((1, 2, 3), 0.5), "lam": [1.0]}, r"shape \(n, m, m\)"),
    ({"Q": _Q2, "lam": [1.0]}, "lam must have 2 entries"),
    ({"Q": _Q2, "lam": [np.nan, 1.0]}, "finite"),
    ({"Q": np.stack([np.array([[1.1, 0.5], [-0.1, 0.5]])] * 2), "lam": [0.5, 0.5]}, "probability distribution"),
    ({"Q": np.stack([np.array([[0.6, 0.5], [0.5, 0.5]])] * 2), "lam": [0.5, 0.5]}, "probability distribution"),
    ({"Q": _Q2, "lam": [1.000001, -0.000001]}, "simplex"),
    ({"Q": _Q2, "lam": [0.5, 0.6]}, "simplex"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "edges": [0.0, 1.0]}, "edges must be 1 strictly"),
    ({"Q": np.stack([np.full((3, 3), 1 / 3)] * 2), "lam": [0.5, 0.5], "edges": [1.0, 0.0]}, "strictly increasing"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "centres": [0.0]}, "centres must be 2"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "counts": np.ones((2, 2, 3))}, "counts must be non-negative"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "counts": -np.ones((2, 2, 2))}, "counts must be non-negative"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "dt": 0.0}, "dt must be a positive"),
    ({"Q": _Q2, "lam": [0.5, 0.5], "dt": np.inf}, "dt must be a positive"),
])
def test_mtd_model_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        MTDModel(**kwargs)


def test_mtd_model_accepts_round_off():
    m = MTDModel(Q=_Q2 + np.array([[[1e-13, 0], [-1e-13, 0]]] * 2), lam=[0.5 + 1e-9, 0.5], dt=0.2,
                 counts=np.zeros((2, 2, 2)))
    assert np.all(m.Q >= 0) and m.lam.sum() == pytest.approx(1.0, abs=2e-9) and m.dt == 0.2


def test_log_likelihood_of_no_transitions_is_an_empty_sum():
    m = MTDModel(Q=_Q2, lam=[0.5, 0.5])
    ll, N = m.log_likelihood([np.array([0, 1])])
    assert ll == 0.0 and N == 0 and isinstance(N, int)
    ll3, N3 = m.log_likelihood([np.array([0, 1, 1, 0])])
    assert N3 == 2 and ll3 == pytest.approx(2 * np.log(0.5))


def test_propagate_accepts_states_or_distributions_and_rejects_bad_states():
    rng = np.random.default_rng(9)
    Q = rng.dirichlet(np.ones(3), size=(2, 3)).transpose(0, 2, 1)
    model = MTDModel(Q=Q, lam=[0.3, 0.7])
    past = [0, 2]
    a = model.propagate(past, 4)
    b = model.propagate(np.eye(3)[past], 4)
    assert np.allclose(a, b) and np.allclose(a.sum(axis=1), 1.0)
    # one step by hand: x_1 = 0.3 Q_1 e_2 + 0.7 Q_2 e_0
    assert np.allclose(a[0], 0.3 * Q[0][:, 2] + 0.7 * Q[1][:, 0])
    with pytest.raises(ValueError, match="out of range"):
        model.propagate([0, 3], 2)
    with pytest.raises(ValueError, match="out of range"):
        model.propagate([-1, 0], 2)
    with pytest.raises(ValueError):
        model.propagate(np.eye(3)[[0]], 2)  # one distribution, order 2


def test_sampling_matches_the_transition_law():
    rng = np.random.default_rng(10)
    Q = rng.dirichlet(np.ones(3), size=(2, 3)).transpose(0, 2, 1)
    model = MTDModel(Q=Q, lam=[0.4, 0.6])
    draws = model.sample([1, 2], 1, 20000, rng=0)[:, 0]
    freq = np.bincount(draws, minlength=3) / draws.size
    assert np.allclose(freq, model.transition_probabilities([1, 2]), atol=0.015)
    assert draws.min() >= 0 and draws.max() <= 2


def test_a_single_sequence_array_is_one_sequence():
    from iamp.prediction.mtd.counts import lag_table

    assert lag_table(np.array([0, 1, 2]), 1, 3).tolist() == [[1, 0], [2, 1]]
    with pytest.raises(ValueError, match="one-dimensional"):
        lag_table([np.zeros((2, 2), dtype=int)], 1, 3)
