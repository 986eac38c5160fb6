"""Issue 22 ("the everyday tool, second pass"): each item's regression test.

Every test here failed on the code before its fix (the commit message of each item says how it
was measured); the item number is in each test's name.
"""

from __future__ import annotations

import errno
from pathlib import Path

import pytest

from iamp.cli.main import main


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``iamp argv`` in-process: ``(exit status, stdout, stderr)``."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's refusals
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def _no_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make any episode an error: a refusal must come before SUMO starts."""
    import iamp.simulation.episode as episode

    def refuse(spec: object) -> None:
        raise AssertionError("the episode ran before the destinations were checked")

    monkeypatch.setattr(episode, "run_episode", refuse)


# --- item 2: simulate --log / --figure are checked before the episode ------------------------


@pytest.mark.parametrize("option", ["--log", "--figure"])
def test_item2_simulate_refuses_an_existing_file_before_the_episode(tmp_path, capsys, monkeypatch, option):
    _no_episode(monkeypatch)
    target = tmp_path / ("old.csv" if option == "--log" else "old.png")
    target.write_text("the user's file")
    code, out, err = run_main(["simulate", "--seed", "1", option, str(target)], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and option in err and str(target) in err and "--force" in err
    assert target.read_text() == "the user's file"


def test_item2_simulate_refuses_log_and_figure_on_one_path(tmp_path, capsys, monkeypatch):
    _no_episode(monkeypatch)
    same = tmp_path / "x.png"
    code, _, err = run_main(["simulate", "--log", str(same), "--figure", str(same)], capsys)
    assert code == 2 and "--figure" in err and "--log" in err and not same.exists()


def test_item2_simulate_refuses_an_unwritable_or_unknown_destination_before_the_episode(tmp_path, capsys,
                                                                                        monkeypatch):
    _no_episode(monkeypatch)
    code, _, err = run_main(["simulate", "--figure", str(tmp_path / "f.bmpx")], capsys)
    assert code == 2 and "--figure" in err and ".png" in err
    (tmp_path / "a-file").write_text("")
    code, _, err = run_main(["simulate", "--log", str(tmp_path / "a-file" / "f.csv")], capsys)
    assert code == 2 and err.count("\n") == 1 and "--log" in err and "a-file" in err


# --- item 4: environment errors are the user's situation: one line naming the path, exit 2 ----


def _full_disk(monkeypatch: pytest.MonkeyPatch, after: int = 0) -> None:
    """``os.fsync`` (every atomic write calls it) fails with ENOSPC after ``after`` successes."""
    import os

    calls = {"n": 0}
    real = os.fsync

    def fsync(fd: int) -> None:
        calls["n"] += 1
        if calls["n"] > after:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def _assert_env_line(code: int, err: str, path: object) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and "No space left on device" in err and str(path) in err
    assert "internal error" not in err and "Traceback" not in err


def test_item4_plan_csv_on_a_full_disk(tmp_path, capsys, monkeypatch):
    _full_disk(monkeypatch)
    target = tmp_path / "traj.csv"
    code, _, err = run_main(["plan", "paper-1-poly", "--csv", str(target)], capsys)
    _assert_env_line(code, err, target)
    assert list(tmp_path.iterdir()) == []  # no half file, no .tmp


def test_item4_plot_on_a_full_disk(tmp_path, capsys, monkeypatch):
    _full_disk(monkeypatch)
    target = tmp_path / "plan.png"
    code, _, err = run_main(["plot", "paper-1-poly", "--out", str(target)], capsys)
    _assert_env_line(code, err, target)
    assert list(tmp_path.iterdir()) == []


def test_item4_reproduce_on_a_full_disk_midway(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report  # where the CLI imports reproduce from
    from iamp.core.atomic import write_text

    def fake_reproduce(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        write_text(Path(out_dir) / "tables" / "results.tex", "x")
        return {}

    monkeypatch.setattr(report, "reproduce", fake_reproduce)
    _full_disk(monkeypatch, after=1)  # the folder's marker is written, the first table is not
    out = tmp_path / "rep"
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    _assert_env_line(code, err, out / "tables" / "results.tex")
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]


def test_item4_campaign_on_a_full_disk(tmp_path, capsys, monkeypatch):
    _full_disk(monkeypatch)
    out = tmp_path / "camp"
    code, _, err = run_main(["campaign", "--out", str(out), "--seeds", "1", "--quiet"], capsys)
    _assert_env_line(code, err, out)


def test_item4_simulate_log_on_a_read_only_folder_is_refused_before_the_episode(tmp_path, capsys, monkeypatch):
    import os
    import tempfile

    _no_episode(monkeypatch)

    def read_only(*a: object, **k: object) -> tuple[int, str]:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    code, _, err = run_main(["simulate", "--log", str(tmp_path / "log.csv")], capsys)
    assert code == 2 and err.count("\n") == 1 and "Read-only file system" in err and "--log" in err


def test_item4_unreachable_scheduler_is_one_line_before_any_work(tmp_path, capsys):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    out = tmp_path / "camp"
    code, _, err = run_main(["campaign", "--out", str(out), "--seeds", "1", "--scheduler", address, "--quiet"],
                            capsys)
    assert code == 2 and err.count("\n") == 1 and address in err and "scheduler" in err
    assert not out.exists()  # checked before the folder is made
    code, _, err = run_main(["campaign", "--out", str(out), "--scheduler", "tcp://:x", "--quiet"], capsys)
    assert code == 2 and "--scheduler" in err


# --- item 5: every numeric option is bounded and validated before any work -------------------


@pytest.mark.parametrize("argv", [
    ["simulate", "--seed", "-1"],
    ["simulate", "--seed", "4294967296"],
    ["simulate", "--duration", "1e9"],
    ["simulate", "--period", "0"],
    ["campaign", "--seeds", "1000000000", "--out", "{tmp}/c"],
    ["campaign", "--workers", "100000", "--out", "{tmp}/c"],
    ["compare", "paper-1-poly", "--repeats", "1000000000"],
    ["plot", "paper-1-poly", "--snapshots", "100000", "--out", "{tmp}/p.png"],
    ["train", "x.csv", "--out", "{tmp}/m.json", "--order", "1000"],
    ["train", "x.csv", "--out", "{tmp}/m.json", "--dt", "1e-9"],
    ["evaluate-predictor", "--data", "x.csv", "--format", "sumo", "--seed", "-5"],
])
def test_item5_numeric_options_are_bounded(tmp_path, capsys, monkeypatch, argv):
    _no_episode(monkeypatch)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, out, err = run_main(argv, capsys)
    option = next(a for a in argv if a.startswith("--") and a not in ("--out", "--data", "--format"))
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert option in err and "must be" in err
    assert not (tmp_path / "c").exists()


def test_item5_bounds_accept_their_ends():
    from iamp.cli.types import OPTION_BOUNDS, float_in, int_in

    seed = int_in("seed")
    assert seed("0") == 0 and seed(str(2**31 - 1)) == 2**31 - 1
    lo, hi = OPTION_BOUNDS["period_s"]
    assert float_in("period_s")(repr(lo)) == lo and float_in("period_s")(repr(hi)) == hi


# --- item 8: one rule for exit 3 and the cost ------------------------------------------------


@pytest.fixture
def local_planner(monkeypatch: pytest.MonkeyPatch) -> None:
    """``iamp plan`` with a PMP whose certificate budget is one box: two vehicles end ``local``."""
    import iamp.cli.plan as plan_cli
    from iamp.planners.pmp import PMPPlanner

    monkeypatch.setattr(plan_cli, "prepared_plan", lambda args: PMPPlanner(max_boxes=1).plan)


def test_item8_local_plan_exits_3_with_its_cost_in_json_and_text(capsys, local_planner):
    import json

    code, out, _ = run_main(["plan", "two-vehicle", "--json"], capsys)
    obj = json.loads(out)
    assert code == 3 and obj["status"] == "local" and obj["cost"] > 0 and len(obj["trajectory"]["t"]) == 101
    code, text, _ = run_main(["plan", "two-vehicle"], capsys)
    assert code == 3
    assert "status    local" in text and "no cost is reported" not in text
    assert f"cost J    {obj['cost']:.9g}" in text and "not certify" in text


def test_item8_failed_plan_exits_3_with_cost_null(capsys, monkeypatch):
    import json

    import iamp.cli.plan as plan_cli
    from iamp.core.errors import SolverError

    class Failing:
        def plan(self, problem: object) -> None:
            raise SolverError("diverged", "numerical_error")

    monkeypatch.setattr(plan_cli, "prepared_plan", lambda args: Failing().plan)
    code, out, _ = run_main(["plan", "paper-1-poly", "--json"], capsys)
    assert code == 3 and json.loads(out)["cost"] is None
    code, text, _ = run_main(["plan", "paper-1-poly"], capsys)
    assert code == 3 and "no cost is reported" in text


def test_item8_readme_states_the_rule():
    # the README became a front door (issue 31): the rule is on the site's usage page
    readme = (Path(__file__).resolve().parents[1] / "docs" / "usage.md").read_text(encoding="utf-8")
    assert "a\n`local` plan" in readme or "a `local` plan" in readme.replace("\n", " ")
    assert "exits 3 *with* its cost" in readme.replace("\n", " ")


# --- item 9: a touch of the corner is a touch, not UNSAFE / exit 4 -----------------------------


def test_item9_the_equality_touch_is_reported_as_a_touch_not_unsafe(capsys):
    import json

    code, text, _ = run_main(["plan", "paper-1-poly", "--require-safe"], capsys)
    assert code == 0 and "UNSAFE" not in text
    touch = [line for line in text.splitlines() if line.startswith("touch")]
    assert len(touch) == 1 and "sv1" in touch[0] and "[3.534, 3.550] s (16 ms)" in touch[0]
    assert "1.1 mm" in touch[0] and "10 mm" in touch[0]
    code, out, _ = run_main(["plan", "paper-1-poly", "--json", "--require-safe"], capsys)
    safety = json.loads(out)["safety"]
    v = safety["vehicles"][0]
    assert code == 0 and safety["unsafe"] is False and safety["safety_tolerance_m"] == 0.01
    assert safety["intrusion_free"] is False and 0.001 < v["max_intrusion_m"] < 0.0012  # still reported


def test_item9_the_tolerance_is_the_threshold(capsys):
    code, text, _ = run_main(["plan", "paper-1-poly", "--require-safe", "--safety-tolerance", "0"], capsys)
    assert code == 4 and "UNSAFE    sv1" in text
    code, text, _ = run_main(["plan", "paper-1-poly", "--require-safe", "--safety-tolerance", "0.00114"], capsys)
    assert code == 4  # the depth is 1.1414 mm: just above
    code, text, _ = run_main(["plan", "paper-1-poly", "--require-safe", "--safety-tolerance", "0.00115"], capsys)
    assert code == 0 and "touch" in text


def test_item9_a_real_intrusion_stays_unsafe(capsys):
    code, text, _ = run_main(["plan", "paper-2-poly", "--require-safe", "--safety-tolerance", "1"], capsys)
    assert code == 4 and "UNSAFE" in text  # the bodies overlap: never a touch, whatever the depth tolerance


def test_item9_touch_rule_on_generated_reports():
    from hypothesis import given
    from hypothesis import strategies as st

    from iamp.core.safety import SafetyReport, VehicleSafety

    @given(st.floats(0.0, 2.0), st.booleans(), st.booleans(), st.floats(0.0, 1.0))
    def check(depth: float, enters: bool, overlaps: bool, tol: float) -> None:
        v = VehicleSafety("v", ((1.0, 1.1),) if enters else (), depth if enters else 0.0,
                          ((1.0, 1.05),) if overlaps else (), 0.0)
        report = SafetyReport((v,), 4.8, 1.8, True)
        # unsafe beyond the tolerance  <=>  an overlap, or an entry deeper than the tolerance
        assert report.unsafe_beyond(tol) == (overlaps or (enters and depth > tol))
        assert v.touch_only(tol) == (enters and not overlaps and depth <= tol)

    check()


# --- item 3: the history smoother is linear in the history's length ----------------------------


def _old_grid_operator(t, dt: float, n: int):  # type: ignore[no-untyped-def]
    """The operator as the code before issue 22 built it: K interpolations of the K unit vectors."""
    import numpy as np

    from iamp.prediction.kinematics import history_grid

    tg, _ = history_grid(t, t, dt)
    return np.stack([np.interp(tg[-(n + 2):], t, e) for e in np.eye(t.size)], axis=1)


def test_item3_recursions_equal_the_dense_operator_on_small_histories():
    """The linear path (recursions on the data) equals the dense operator (recursions on the unit
    vectors, then a matrix product) to rounding, on generated sample times, noise and positions."""
    import numpy as np
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from iamp.prediction.initial_state import _operator, _rts

    @settings(max_examples=40, deadline=None)
    @given(st.integers(3, 60), st.integers(1, 4), st.floats(1e-3, 0.5), st.floats(0.1, 100.0),
           st.integers(0, 2**32 - 1))
    def check(K: int, B: int, sigma: float, q: float, seed: int) -> None:
        rng = np.random.default_rng(seed)
        t = np.cumsum(rng.uniform(0.02, 0.2, K))
        t = t - t[-1]
        Z = 20.0 * t + rng.normal(0.0, 0.5, (B, K))
        M = _operator(t.tobytes(), K, sigma, q)
        dense = np.einsum("bj,cjk->cbk", Z, M)
        s = _rts(t, Z, q, np.full(B, sigma))
        for c, got in enumerate((s.x, s.v, s.a)):
            scale = np.abs(Z).max() * (1.0 + np.abs(M[c]).sum(axis=0).max())
            np.testing.assert_allclose(got, dense[c], rtol=0, atol=1e-11 * scale)

    check()


def test_item3_grid_weights_equal_the_old_interpolation_operator():
    import numpy as np
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from iamp.prediction.predictor import _grid_operator

    @settings(max_examples=60, deadline=None)
    @given(st.integers(3, 80), st.sampled_from([0.05, 0.1, 0.2]), st.integers(1, 6), st.integers(0, 2**32 - 1))
    def check(K: int, dt: float, n: int, seed: int) -> None:
        rng = np.random.default_rng(seed)
        t = np.cumsum(rng.uniform(0.01, 0.3, K))
        t = t - t[-1]
        if t[-1] - t[0] < (n + 1) * dt:
            return
        old = _old_grid_operator(t, dt, n)
        new = _grid_operator(t.tobytes(), K, dt, n)
        np.testing.assert_allclose(new, old, rtol=0, atol=1e-12)

    check()


def test_item3_a_long_history_costs_linear_memory():
    """1,200 samples: the old K x K operators needed ~0.35 GB (3,000: 2.1 GB, 10,000: ~18 GB)."""
    import tracemalloc

    import numpy as np

    import iamp
    from iamp.prediction.predictor import Predictor

    K = 1200
    t = np.linspace(-0.01 * (K - 1), 0.0, K)
    x = 20.0 * t + 0.01 * np.random.default_rng(1).standard_normal(K)
    predictor = Predictor.default()
    tracemalloc.start()
    pred = predictor.predict(iamp.History(t=t, x=x))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 20e6, peak  # ~30 doubles per sample, not per sample squared
    assert abs(pred.x_poly[1] - 20.0) < 0.5


def test_item3_operator_cache_is_bounded_in_bytes(monkeypatch):
    import numpy as np

    import iamp.prediction.initial_state as ist

    monkeypatch.setattr(ist, "OPERATOR_CACHE_BYTES", 3 * 8 * 100 * 100 * 3)  # three operators of K = 100
    monkeypatch.setattr(ist, "_OPERATORS", type(ist._OPERATORS)())
    t = np.linspace(-1.0, 0.0, 100)
    for k in range(10):
        ist.smooth_histories(t, np.sin(t + k)[None], sigma=0.01 * (k + 1))
    assert sum(m.nbytes for m in ist._OPERATORS.values()) <= ist.OPERATOR_CACHE_BYTES
    assert len(ist._OPERATORS) == 3


# --- item 6: recorded data is checked for absurd values and plausibility; memory stays bounded --

_NGSIM = Path(__file__).parent / "fixtures" / "ngsim.csv"


def _ngsim_variant(tmp_path: Path, name: str, edit: object) -> Path:
    import csv

    header, *body = list(csv.reader(_NGSIM.open(newline="")))
    edit(header, body)  # type: ignore[operator]
    out = tmp_path / name
    with out.open("w", newline="") as fh:
        csv.writer(fh).writerows([header, *body])
    return out


def _set(column: str, row: int, value: str) -> object:
    def edit(header: list[str], body: list[list[str]]) -> None:
        body[row][header.index(column)] = value
    return edit


@pytest.mark.parametrize("column", ["Local_Y", "v_Vel", "v_Acc"])
@pytest.mark.parametrize("command", ["train", "evaluate-predictor"])
def test_item6_an_absurd_value_is_one_line_naming_file_and_line(tmp_path, capsys, column, command):
    # before: Local_Y = 1e308 -> exit 1 (a non-JSON float) in evaluate-predictor; v_Vel = 1e308 trained a model
    data = _ngsim_variant(tmp_path, "bad.csv", _set(column, 4, "1e308"))  # body row 4 = file line 6
    argv = (["train", "--format", "ngsim", "--out", str(tmp_path / "m.json"), str(data)] if command == "train"
            else ["evaluate-predictor", "--data", str(data), "--format", "ngsim", "--json"])
    code, out, err = run_main(argv, capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and str(data) in err and "line 6" in err
    assert not (tmp_path / "m.json").exists()


def test_item6_positions_in_centimetres_are_refused_with_the_unit_assumed(tmp_path, capsys):
    def to_cm(header: list[str], body: list[list[str]]) -> None:
        k = header.index("Local_Y")
        for r in body:
            r[k] = repr(float(r[k]) * 30.48)  # feet -> centimetres, the header still says feet
    data = _ngsim_variant(tmp_path, "cm.csv", to_cm)
    code, _, err = run_main(["train", "--format", "ngsim", "--out", str(tmp_path / "m.json"), str(data)], capsys)
    assert code == 2 and "feet (NGSIM)" in err and str(data) in err


def test_item6_reversed_frames_are_refused_swapped_ones_are_noted(tmp_path, capsys):
    def reverse(header: list[str], body: list[list[str]]) -> None:
        f = header.index("Frame_ID")
        for r in body:
            r[f] = str(1000 - int(r[f]))
    code, _, err = run_main(["train", "--format", "ngsim", "--out", str(tmp_path / "m.json"),
                             str(_ngsim_variant(tmp_path, "rev.csv", reverse))], capsys)
    assert code == 2 and "reversed" in err

    def swap(header: list[str], body: list[list[str]]) -> None:
        body[0], body[2] = body[2], body[0]  # vehicle 7's frame 101 before its 100
    from iamp.prediction.loaders import load

    tracks = load(_ngsim_variant(tmp_path, "swap.csv", swap), "ngsim")
    notes = " ".join(tracks.meta["load_report"]["notes"])
    assert "Frame_ID order" in notes and "plausibility: median implied speed" in notes


def test_item6_highd_without_recording_meta_says_the_frame_rate_it_assumed(tmp_path):
    import shutil

    from iamp.prediction.loaders import load

    src = Path(__file__).parent / "fixtures" / "highd"
    shutil.copy(src / "01_tracks.csv", tmp_path / "01_tracks.csv")
    shutil.copy(src / "01_tracksMeta.csv", tmp_path / "01_tracksMeta.csv")
    tracks = load(tmp_path / "01_tracks.csv", "highd")
    assert any("25 Hz" in n and "assumed" in n for n in tracks.meta["load_report"]["notes"])
    assert tracks.dt == pytest.approx(1 / 25)


def test_item6_a_huge_line_is_refused_before_it_is_read_whole(tmp_path, monkeypatch):
    import io

    import iamp.prediction.loaders.csv as lc

    monkeypatch.setattr(lc, "MAX_LINE_CHARS", 1000)
    fh = io.StringIO("a,b\n1,2\n" + "9" * 100_000 + "\n3,4\n")
    with pytest.raises(lc.TrackDataError, match="line 3 is longer than 1000 characters"):
        list(lc._bounded_lines(fh, tmp_path / "f.csv"))
    assert fh.tell() <= 8 + 1001  # read no further than the limit into the long line
    data = tmp_path / "long.csv"
    data.write_text(_NGSIM.read_text() + "7," + "1" * 5000 + "\n")
    from iamp.prediction.loaders import load

    with pytest.raises(lc.TrackDataError, match="longer than 1000"):
        load(data, "ngsim")


def test_item6_training_at_a_tiny_dt_is_refused_before_allocating(monkeypatch):
    import numpy as np

    import iamp.prediction.training as tr
    from iamp.prediction.tracks import Tracks

    t = np.arange(0, 100.0, 0.1)
    tracks = Tracks(np.zeros(t.size, dtype=np.int64), t, 20 * t, np.full(t.size, 20.0), np.zeros(t.size),
                    np.ones(t.size, dtype=np.int64), 0.1, {})
    monkeypatch.setattr(tr, "TRAIN_STATES_MAX", 50_000)  # 99.9 s at 1e-3 s: 99,901 states
    with pytest.raises(ValueError, match="99,901 states"):
        tr.track_accelerations(tracks, 1e-3)
    assert len(tr.track_accelerations(tracks, 2e-3)[0]) == 49_951 - 2


def test_item6_batch_prediction_in_chunks_equals_one_batch(monkeypatch):
    import numpy as np

    import iamp.prediction.predictor as pr

    P = pr.Predictor.default()
    rng = np.random.default_rng(1)
    t_hist = np.arange(-3.0, 1e-9, 0.1)
    X = 20.0 * t_hist[None, :] + rng.normal(0, 0.05, (37, t_hist.size)).cumsum(axis=1)
    q = np.linspace(0, 5, 11)
    whole = P.predict_batch(t_hist, X, q, 5.0)
    monkeypatch.setattr(pr, "BATCH_BYTES", 8 * 26 * (P.model.n_states + 4) * 5)  # 5 histories per chunk
    np.testing.assert_allclose(P.predict_batch(t_hist, X, q, 5.0), whole, rtol=0, atol=1e-9)


# --- item 7: model files: JSON types, an integer order, n_states = size of Q; plain messages -----


def _model_variant(tmp_path: Path, name: str, **changes: object) -> Path:
    import json

    from iamp.prediction.predictor import DEFAULT_MODEL_FILE

    src = Path(__file__).parents[1] / "prediction" / "data" / DEFAULT_MODEL_FILE
    d = json.loads(src.read_text())
    d.update(changes)
    out = tmp_path / name
    out.write_text(json.dumps(d))
    return out


@pytest.mark.parametrize(("changes", "key"), [
    ({"dt": "0.2"}, "dt"), ({"order": 4.5}, "order"), ({"order": 4.0}, "order"), ({"order": "4"}, "order"),
    ({"order": True}, "order"), ({"n_states": 14}, "n_states"), ({"n_states": 13.0}, "n_states"),
    ({"Q": "abc"}, "Q"), ({"lambda": [1, "x", 0, 0]}, "lambda"), ({"n_obs": "many"}, "n_obs")])
def test_item7_malformed_model_fields_are_refused_naming_the_key(tmp_path, capsys, changes, key):
    # before: a string dt was parsed, order 4.5 truncated to 4, n_states 14 with a 13-state Q accepted
    from iamp.prediction.mtd.io import load_model
    from iamp.prediction.mtd.model import ModelFileError

    path = _model_variant(tmp_path, "m.json", **changes)
    with pytest.raises(ModelFileError) as info:
        load_model(path)
    assert info.value.key == key
    code, out, err = run_main(["predict", "paper-2", "--model", str(path), "--json"], capsys)
    assert code == 2 and out == "" and f"key '{key}'" in err and len(err.strip().splitlines()) == 1


def test_item7_the_shipped_model_passes_the_type_checks():
    from iamp.prediction.mtd.io import load_model
    from iamp.prediction.predictor import DEFAULT_MODEL_FILE

    m = load_model(Path(__file__).parents[1] / "prediction" / "data" / DEFAULT_MODEL_FILE)
    assert m.n_states == m.Q.shape[1] and isinstance(m.order, int)


def test_item7_messages_carry_no_python_exception_names(tmp_path, capsys):
    import re

    from iamp.prediction.mtd.io import load_model
    from iamp.prediction.mtd.model import ModelFileError

    folder = tmp_path / "dir.json"
    folder.mkdir()
    binary = tmp_path / "bin.json"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    for bad in (folder, binary):
        with pytest.raises(ModelFileError) as info:
            load_model(bad)
        assert not re.search(r"\b[A-Z][A-Za-z]*(Error|Exception)\b", str(info.value)), str(info.value)
    for changes in ({"Q": [[["a"]]]}, {"lambda": {"x": 1}}, {"Q": [[[1.0]]]}):
        code, _, err = run_main(["predict", "paper-2", "--model", str(_model_variant(tmp_path, "m.json", **changes)),
                                 "--json"], capsys)
        assert code == 2 and not re.search(r"\b[A-Z][A-Za-z]*(Error|Exception)\b", err), err


# --- item 10: plan, predict and scenarios import no heavy module --------------------------------
# A comparison of import *sets*, not a timed test: before, `iamp plan` imported matplotlib (via
# iamp.cli.plot) and scipy.optimize (via the MTD estimators) -- 3.4x the CPU of a bare
# `import numpy, scipy.linalg`; without them it is 0.9x (measured with /usr/bin/time-like
# rusage in the closing note of issue 22).

_HEAVY = ("matplotlib", "scipy.optimize", "scipy.sparse", "scipy.stats", "cvxpy", "osqp", "clarabel", "piqp",
          "dask", "distributed", "numba", "pandas", "traci", "sumolib", "libsumo")


@pytest.mark.parametrize("argv", [["plan", "paper-1-poly", "--json"], ["plan", "two-vehicle", "--json"],
                                  ["predict", "paper-2", "--json"], ["scenarios"], []])
def test_item10_everyday_commands_import_no_heavy_module(argv):
    import json
    import subprocess
    import sys

    code = ("import contextlib, io, json, sys\n"
            "from iamp.cli.main import main\n"
            "argv = json.loads(sys.argv[1])\n"
            "if argv:\n"
            "    with contextlib.redirect_stdout(io.StringIO()):\n"
            "        status = main(argv)\n"
            "    assert status == 0, status\n"
            "else:\n"
            "    import iamp\n"
            "print(json.dumps(sorted(sys.modules)))\n")
    proc = subprocess.run([sys.executable, "-c", code, json.dumps(argv)], capture_output=True, text=True,
                          timeout=300, env={**__import__("os").environ, "PYTHONPATH": str(Path(__file__).parents[1])})
    assert proc.returncode == 0, proc.stderr[-2000:]
    loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    heavy = sorted(m for m in loaded if any(m == h or m.startswith(h + ".") for h in _HEAVY))
    assert heavy == [], heavy


def test_item10_the_lazy_names_still_resolve():
    import iamp.prediction.mtd as mtd
    from iamp.prediction.mtd.estimation import ESTIMATORS, fit, sample_sequence

    assert (mtd.fit, mtd.sample_sequence, mtd.ESTIMATORS) == (fit, sample_sequence, ESTIMATORS)
    with pytest.raises(AttributeError):
        mtd.no_such_name  # noqa: B018


# --- item 11: evaluate-predictor reads simulate --log; predict - reads stdin; exports -----------


def _synthetic_log(path: Path, seconds: float = 60.0, dt: float = 0.1) -> dict[str, tuple[object, object]]:
    """A step log written by iamp's own writer (SUMO is not needed): an ego and five neighbours
    with smooth speed profiles; returns each neighbour's (t, x) as written."""
    from types import SimpleNamespace

    import numpy as np

    from iamp.simulation.episode import write_log
    from iamp.simulation.metrics import StepLog

    log = StepLog()
    t = np.round(np.arange(0.0, seconds, dt), 6)
    rng = np.random.default_rng(3)
    v0 = rng.uniform(18, 30, 5)
    amp = rng.uniform(0.2, 1.0, 5)
    w = rng.uniform(0.1, 0.3, 5)
    x0 = np.array([-40.0, -10.0, 15.0, 45.0, 80.0])
    truth: dict[str, tuple[object, object]] = {}
    for tk in t:
        a = amp * np.sin(w * tk)
        v = v0 + amp / w * (1 - np.cos(w * tk))
        x = x0 + v0 * tk + amp / w * (tk - np.sin(w * tk) / w)
        log.t.append(float(tk))
        log.ego.append((25.0 * tk, 25.0, 1.75, 0.0, 0.0, 0.0))
        log.mode.append("track")
        log.plan_time.append(float("nan"))
        log.ids.append(tuple(f"car{i}" for i in range(5)))
        log.nb.append(np.column_stack([x, np.full(5, 5.25), v, a, np.ones(5), np.full(5, 4.5), np.full(5, 1.8)]))
    write_log(SimpleNamespace(log=log), path)  # type: ignore[arg-type]
    for i in range(5):
        truth[f"car{i}"] = (t, np.array([row[i, 0] for row in log.nb]))
    return truth


def test_item11_the_simulate_log_loads_as_sumo_traffic_without_the_ego(tmp_path):
    import numpy as np

    from iamp.prediction.loaders import load
    from iamp.prediction.loaders.iamplog import IAMP_LOG_COLUMNS
    from iamp.simulation.episode import LOG_COLUMNS

    assert IAMP_LOG_COLUMNS == LOG_COLUMNS  # the loader's copy of the writer's header
    truth = _synthetic_log(tmp_path / "log.csv")
    tracks = load(tmp_path / "log.csv", "sumo")
    assert tracks.n_tracks == 5 and tracks.dt == pytest.approx(0.1)
    assert tracks.meta["load_report"]["dropped"] == {
        "the ego (iamp's planned vehicle; the predictor is evaluated on the traffic)": 600}
    for tid, t, x, v, *_ in tracks.iter_tracks():
        t_true, x_true = truth[tracks.meta["source_ids"][tid]]
        np.testing.assert_allclose(t, t_true, atol=5e-4)
        np.testing.assert_allclose(x, x_true, atol=5e-5)  # written with 4 decimals
        np.testing.assert_allclose(np.diff(x) / 0.1, 0.5 * (v[1:] + v[:-1]), atol=0.02)


def test_item11_evaluate_predictor_reads_the_simulate_log(tmp_path, capsys):
    import json

    _synthetic_log(tmp_path / "log.csv")
    code, out, err = run_main(["evaluate-predictor", "--data", str(tmp_path / "log.csv"), "--format", "sumo",
                               "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["tracks"] == 5 and res["windows"] > 0 and res["format"] == "sumo"
    assert any("iamp simulate --log" in n for n in res["load_report"]["notes"])


def test_item11_predict_reads_the_scenario_from_stdin(capsys, monkeypatch):
    import io
    import json

    code, text, _ = run_main(["scenarios", "--show", "paper-2"], capsys)
    assert code == 0
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    code, out, err = run_main(["predict", "-", "--json"], capsys)
    assert code == 0, err
    from_file = run_main(["predict", "paper-2", "--json"], capsys)[1]
    a, b = json.loads(out), json.loads(from_file)
    assert [v["x_poly"] for v in a["vehicles"]] == [v["x_poly"] for v in b["vehicles"]]


def test_item11_plan_batch_and_pmp_planner_are_exported():
    import iamp

    assert "plan_batch" in iamp.__all__ and "PMPPlanner" in iamp.__all__
    from iamp.planners.pmp import PMPPlanner
    from iamp.planners.pmp.batch import plan_batch

    assert iamp.PMPPlanner is PMPPlanner and iamp.plan_batch is plan_batch
    prob = iamp.load_scenario("paper-1-poly")
    batch = iamp.plan_batch([prob, prob])
    assert list(batch.cost) == pytest.approx([iamp.plan(prob).cost] * 2, rel=1e-9)


# --- item 12: every help text names only options that exist -------------------------------------


def _subparsers() -> dict[str, object]:
    import argparse

    from iamp.cli.main import build_parser

    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {"": parser, **action.choices}


def test_item12_help_texts_name_only_existing_options():
    import re

    subs = _subparsers()
    top = set(subs[""]._option_string_actions)  # type: ignore[attr-defined]
    every = set().union(*(p._option_string_actions for p in subs.values()))  # type: ignore[attr-defined]
    problems = []
    for name, parser in subs.items():
        text = parser.format_help()  # type: ignore[attr-defined]
        own = (set(parser._option_string_actions) | top) if name else every  # type: ignore[attr-defined]
        for opt in sorted(set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", text))):
            # options of another command named as such ("iamp simulate --log") are allowed
            if opt not in own and not re.search(rf"iamp\s+\w[\w-]*(?:\s+[^\s,;.)]+)*\s+{re.escape(opt)}\b", text):
                problems.append(f"{name or 'iamp'} --help names {opt}, which it does not have")
        if "%%" in text:
            problems.append(f"{name or 'iamp'} --help shows a literal %%")
    assert problems == [], problems


# --- item 13: output polish: rounded numbers, one sign per term, no None/never, exact limits ----

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_coef = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)


@given(st.lists(_coef, min_size=1, max_size=6), st.floats(min_value=-3, max_value=3))
@settings(max_examples=200, deadline=None)
def test_item13_polynomial_text_reads_back_as_the_polynomial(coeffs, t):
    # before: "-14.9664 + 19.7382 t + -0.0670795 t^2"
    import re

    import numpy as np

    from iamp.cli.text import polynomial

    text = polynomial(coeffs)
    assert "+ -" not in text and "- -" not in text and "+ +" not in text
    expr = re.sub(r" t\^(\d)", r"*t**\1", text).replace(" t", "*t")
    value = eval(expr, {"t": t})
    exact = float(np.polynomial.polynomial.polyval(t, coeffs))
    scale = sum(abs(c) * abs(t) ** k for k, c in enumerate(coeffs))
    assert abs(value - exact) <= 1e-5 * scale + 1e-300


def test_item13_simulate_summary_has_no_none_never_or_long_floats():
    from iamp.cli.simulate import summary_lines

    s = {"planner": "pmp", "traffic": "dense", "seed": 1, "duration_s": 60.0, "period_s": 0.2,
         "lane_changes": 0, "lane_change_done_s": None, "collisions": 0, "sumo_collisions": 0,
         "overlap_collisions": 0, "intrusion_s": 0.0, "min_gap_m": None, "min_ttc_s": None,
         "rms_accel": [0.1, 0.2], "rms_jerk": [0.3, 0.4], "plans": 3, "constrained_plans": 1,
         "failed_plans": 0, "late_plans": 0, "fallbacks": 0, "aborts": 0,
         "plan_time_s": {"p50": 1e-4, "p95": 2e-4, "max": 3e-4},
         "wall_s": {"total": 1.0, "sumo": 0.5, "prediction": 0.1, "planning": 0.1}, "max_rss_mb": 100.0}
    text = "\n".join(summary_lines(s))
    assert "None" not in text and "at never" not in text and "none completed" in text and "n/a" in text
    text = "\n".join(summary_lines({**s, "min_gap_m": 11.01702131844893, "min_ttc_s": 2.345678901,
                                    "lane_changes": 1, "lane_change_done_s": 7.25}))
    assert "min gap 11 m" in text and "min TTC 2.35 s" in text and "first completed at 7.2 s" in text


@given(st.floats(min_value=1e5, max_value=1e9, allow_nan=False).filter(lambda v: v > 1e5))
@settings(max_examples=100, deadline=None)
def test_item13_limit_messages_show_the_exact_offending_value(value):
    # before: x0 = -100000.1 was reported as "got -100000" (%g)
    import re

    from iamp.core.limits import LIMITS, abs_message, bound_message

    for msg in (abs_message(-value, LIMITS["position_max_m"], "m"), bound_message(value, 0.0, 1e5, "m")):
        assert msg is not None
        got = re.search(r"\(got (\S+)\)", msg)
        assert (got is not None and float(got.group(1)) == value) or float(got.group(1)) == -value


def test_item13_x0_just_beyond_the_limit_is_named_exactly(tmp_path, capsys):
    code, text, _ = run_main(["template"], capsys)
    assert code == 0
    import re

    bad = re.sub(r"(?m)^x0 = [^#\n]*", "x0 = -100000.1 ", text, count=1)
    assert bad != text
    (tmp_path / "s.toml").write_text(bad)
    code, _, err = run_main(["plan", str(tmp_path / "s.toml")], capsys)
    assert code == 2 and "-100000.1" in err


@pytest.mark.parametrize("n", [4, 10, 1000])
def test_item13_a_nominal_minimum_history_step_is_accepted(n):
    # before: t = -0.0003, -0.0002, -0.0001, 0 was refused: -0.0002 - -0.0003 = 9.999999999999999e-05 < 1e-4
    import numpy as np

    from iamp.core.errors import HistoryError
    from iamp.core.scenario import History

    t = [round(-1e-4 * k, 10) for k in range(n - 1, -1, -1)]
    History(t=t, x=[20.0 * s for s in t])
    with pytest.raises(HistoryError, match="at least 0.0001 s apart"):
        History(t=list(np.asarray(t) * 0.99), x=[20.0 * s for s in t])


def test_item10_the_lazy_backend_registry_agrees_with_the_classes():
    from iamp.planners.qp.backends import BACKENDS, SUPPORTS_INEQUALITIES
    from iamp.planners.qp.backends.base import QPBackend

    assert set(SUPPORTS_INEQUALITIES) == set(BACKENDS)
    for name, cls in BACKENDS.items():
        assert issubclass(cls, QPBackend) and cls.name == name
        assert cls.supports_inequalities is SUPPORTS_INEQUALITIES[name]


# --- item 16: stale .tmp after SIGKILL, --force through a symlink, a quiet interrupted campaign ---


def test_item16_a_killed_runs_temporary_files_are_removed_by_the_next_run(tmp_path):
    import os
    import subprocess
    import sys

    from iamp.core.outputs import guarded_folder

    out = tmp_path / "rep"
    with guarded_folder(out, "reproduce"):
        (out / "tables").mkdir()
    # a run killed (SIGKILL: no cleanup runs) in the middle of an atomic write
    code = ("import os, signal, sys\n"
            "from iamp.core.atomic import atomic_open\n"
            "with atomic_open(sys.argv[1]) as fh:\n"
            "    fh.write('half'); fh.flush()\n"
            "    os.kill(os.getpid(), signal.SIGKILL)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(out / "tables" / "results.tex")],
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}, timeout=120)
    assert proc.returncode == -9
    stale = list(out.rglob("*.tmp"))
    assert len(stale) == 1 and not (out / "tables" / "results.tex").exists()
    (out / ".notes.tmp").write_text("the user's")  # not an iamp temporary name: kept
    with guarded_folder(out, "reproduce"):
        assert list(out.rglob("*.tmp")) == [out / ".notes.tmp"]


def test_item16_force_onto_a_symlink_writes_through_it(tmp_path, capsys):
    import os

    target = tmp_path / "data" / "run.csv"
    target.parent.mkdir()
    target.write_text("old")
    link = tmp_path / "out.csv"
    os.symlink(target, link)
    code, _, err = run_main(["plan", "paper-1-poly", "--csv", str(link)], capsys)
    assert code == 2 and "--force" in err and target.read_text() == "old"
    code, _, err = run_main(["plan", "paper-1-poly", "--csv", str(link), "--force"], capsys)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(target)  # before: the link became a plain file
    assert target.read_text().startswith("t,x,y,vx,vy,ax,ay")
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.csv"]  # no temporary left


def test_item16_interrupting_a_campaign_prints_only_iamps_line(tmp_path, capsys, monkeypatch):
    import logging
    import sys
    import types
    import warnings

    class Future:
        pass

    class Client:
        def __init__(self, *a, **k):
            pass

        def submit(self, fn, spec, pure=False):
            return Future()

        def close(self):  # what Dask says when its workers are killed mid-task
            logging.getLogger("distributed.nanny").warning("Restarting worker")
            logging.getLogger("distributed.client").error("Failed to reconnect to scheduler")
            warnings.warn("Stream is closed", RuntimeWarning, stacklevel=2)
            warnings.warn("leaked semaphore", UserWarning, stacklevel=2)

    class LocalCluster:
        def __init__(self, *a, **k):
            pass

        def close(self):
            logging.getLogger("distributed.core").warning("Lost connection to 'tcp://127.0.0.1:1'")

    def as_completed(futures):
        raise KeyboardInterrupt
        yield  # pragma: no cover

    class ToStderr(logging.Handler):  # Dask configures its loggers with handlers to stderr
        def emit(self, record: logging.LogRecord) -> None:
            sys.stderr.write(self.format(record) + "\n")

    handler = ToStderr()
    logging.getLogger("distributed").addHandler(handler)
    monkeypatch.setattr(warnings, "showwarning",  # as outside pytest: a warning is printed on stderr
                        lambda message, category, *a, **k: sys.stderr.write(f"{category.__name__}: {message}\n"))
    fake = types.ModuleType("distributed")
    fake.Client, fake.LocalCluster, fake.as_completed = Client, LocalCluster, as_completed  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "distributed", fake)
    before = {n: (lg.level, lg.disabled) for n, lg in logging.root.manager.loggerDict.items()
              if isinstance(lg, logging.Logger) and n.split(".")[0] == "distributed"}
    code, _, err = run_main(["campaign", "--out", str(tmp_path / "camp"), "--seeds", "1", "--quiet"], capsys)
    assert code == 130
    logging.getLogger("distributed").removeHandler(handler)
    assert err == "iamp: interrupted\n", err
    # and the loggers are back to their levels afterwards (with the real Dask imported, its child
    # loggers have levels and stderr handlers of their own: those are silenced too, then restored)
    after = {n: (logging.getLogger(n).level, logging.getLogger(n).disabled) for n in before}
    assert after == before


# --- item 15: the README's numbers are the committed run's ---------------------------------------

_ROOT = Path(__file__).parents[1]


def _readme() -> str:
    """The README and the results report it links to (docs/results.md, moved out of it by issue 31; the
    speed tables in docs/bench.md, written from reports/bench.json by scripts/bench_table.py)."""
    return " ".join(" ".join((_ROOT / name).read_text(encoding="utf-8")
                             for name in ("README.md", "docs/results.md", "docs/bench.md")).split())


def test_item15_campaign_numbers_come_from_the_committed_campaign():
    import csv
    import json
    import re
    import statistics

    summary = json.loads((_ROOT / "reports" / "campaign" / "summary.json").read_text())
    rows = list(csv.DictReader((_ROOT / "reports" / "campaign" / "episodes.csv").open()))
    text = _readme()
    planners = sorted({r["planner"] for r in summary})
    seeds = {r["episodes"] for r in summary}
    assert f"{len(planners)} planners × 3 densities × {seeds.pop()} seeds, {len(rows)} episodes" in text
    by = {(r["planner"], r["traffic"]): r for r in summary}

    def ci(r: dict) -> str:
        lo, hi = r["collision_ci"]
        return f"{round(100 * r['collision_episodes'] / r['episodes'])} [{round(100 * lo)}, {round(100 * hi)}] %"

    for label, group in (("pmp, qp, qp-avoid", ("pmp", "qp", "qp-avoid")), ("sumo (LC2013)", ("sumo",))):
        cells = [ci(by[(group[0], t)]) for t in ("light", "medium", "dense")]
        assert all(ci(by[(p, t)]) == c for p in group for t, c in zip(("light", "medium", "dense"), cells))
        brake = round(100 * by[(group[0], "dense")]["hard_brake_rate"])
        assert f"| {label} | {' | '.join(cells)} | {brake} % |" in text
    for p in ("pmp", "qp-avoid"):
        p95 = " / ".join(f"{1e3 * by[(p, t)]['plan_time_p95_s_median']:.1f}" for t in ("light", "medium", "dense"))
        assert f"{p} {p95} ms" in text
    light = [r for r in rows if r["planner"] == "pmp" and r["traffic"] == "light"]
    dense = [r for r in rows if r["planner"] == "pmp" and r["traffic"] == "dense"]

    def med(rs: list, key: str) -> float:
        return statistics.median(float(r[key]) for r in rs)

    m = re.search(r"A 60 s pmp episode took ([\d.]+) s of wall time in light traffic \(median over seeds: SUMO "
                  r"([\d.]+) s, prediction ([\d.]+) s, planning ([\d.]+) s\) and ([\d.]+) s in dense", text)
    assert m is not None
    assert [float(g) for g in m.groups()] == [
        round(med(light, "wall_total_s"), 1), round(med(light, "wall_sumo_s"), 1),
        round(med(light, "wall_prediction_s"), 1), round(med(light, "wall_planning_s"), 2),
        round(med(dense, "wall_total_s"), 1)]
    peak = max(float(r["max_rss_mb"]) for r in rows)
    assert f"workers peaked at {round(peak, -1):.0f} MB" in text


def test_item15_predictor_table_comes_from_the_committed_evaluation():
    import json

    ev = json.loads((_ROOT / "reports" / "predictor_eval.json").read_text())
    text = _readme()
    for label, key in (("constant velocity", "cv"), ("constant acceleration (v ≥ 0)", "ca"),
                       ("first-order chain", "markov1"), ("MTD, LP lag weights", "mtd-lp")):
        r = ev["test"][key]
        cells = [f"{v:.2f}" for v in (*r["rmse"], r["ade"], r["fde"])]
        assert f"| {label} | " in text
        row = text.split(f"| {label} | ")[1].split(" |", 7)[:7]
        assert [c.strip("* ") for c in row] == cells, (label, row, cells)  # bold marks the column's best
    r = ev["test"]["mtd-cubic"]
    row = text.split("| **MTD, order 4** (its cubic: the planner's input) | ")[1].split(" |", 7)[:7]
    assert [c.strip("* ") for c in row] == [f"{v:.2f}" for v in (*r["rmse"], r["ade"], r["fde"])]
    assert f"({ev['test']['cv']['n_windows']:,} windows" in text
    gains = [100 * (1 - m / c) for m, c in zip(r["rmse"], ev["test"]["cv"]["rmse"])]
    assert f"by {round(min(gains))}–{round(max(gains))} % in RMSE" in text


def test_item15_no_selection_result_is_cited_when_the_committed_run_did_not_select():
    import json

    ev = json.loads((_ROOT / "reports" / "predictor_eval.json").read_text())
    tex = (_ROOT / "reports" / "tables" / "predictor_selection.tex").read_text()
    text = _readme()
    if ev["selection"] is None:
        assert "not run" in tex
        assert "was chosen on a separate validation split" not in text
        assert "no selection result is claimed" in text


def test_item15_speed_table_medians_come_from_the_committed_bench():
    import json

    b = json.loads((_ROOT / "reports" / "bench.json").read_text())
    text = _readme()
    assert f"| `plan_batch`, one-vehicle plans | {b['pmp_batch_plans_per_s']:,.0f} / s" in text
    solve = b["qp_native_solve_s"]
    assert f"`kkt` (direct banded KKT solve) | {1e6 * solve['kkt']:.0f} µs" in text
    assert f"… best iterative, PIQP | {1e6 * solve['piqp']:.0f} µs" in text
    assert f"… OSQP (polished to the exact solution) | {1e6 * solve['osqp']:.0f} µs" in text
    assert f"certified global (one source, run as Python) | {1e3 * b['pmp_plan_s']['two_vehicles']:.2f} ms" in text


# --- item 14: figures a paper reader can read ---------------------------------------------------


def _texts_inside(fig: object) -> list[str]:
    """Titles, labels and legend texts that stick out of the figure (clipped when saved)."""
    fig.canvas.draw()  # type: ignore[attr-defined]
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    box = fig.bbox  # type: ignore[attr-defined]
    texts = list(fig.texts)  # type: ignore[attr-defined]
    if getattr(fig, "_suptitle", None) is not None:
        texts.append(fig._suptitle)  # type: ignore[attr-defined]
    for ax in fig.axes:  # type: ignore[attr-defined]
        texts += [ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts]
        leg = ax.get_legend()
        if leg is not None:
            texts += list(leg.get_texts())
    out = []
    for t in texts:
        if not t.get_text() or not t.get_visible():
            continue
        b = t.get_window_extent(renderer)
        if b.x0 < box.x0 - 1 or b.x1 > box.x1 + 1 or b.y0 < box.y0 - 1 or b.y1 > box.y1 + 1:
            out.append(t.get_text())
    return out


def _synthetic_episode() -> object:
    from types import SimpleNamespace

    import numpy as np

    from iamp.simulation.metrics import StepLog

    log = StepLog()
    dt = 0.1
    for k in range(300):
        tk = k * dt
        s = min(max((tk - 10.0) / 5.0, 0.0), 1.0)
        y = -5.625 + 3.75 * (10 * s**3 - 15 * s**4 + 6 * s**5)
        log.t.append(tk)
        log.ego.append((25.0 * tk, 25.0, y, 0.0, 0.0, 0.0))
        log.mode.append("active" if 0 < s < 1 else "track")
        log.plan_time.append(1e-3)
        log.ids.append(("a", "b"))
        log.nb.append(np.array([[25.0 * tk - 30.0, -1.875, 25.0, 0.0, 1, 4.5, 1.8],
                                [24.0 * tk + 40.0, -1.875, 24.0, 0.0, 1, 4.5, 1.8]]))
    summary = {"planner": "pmp", "traffic": "light", "seed": 1, "lane_changes": 1, "collisions": 0,
               "period_s": dt}
    return SimpleNamespace(log=log, summary=summary)


def test_item14_simulate_figure_shows_the_lane_change_against_distance(tmp_path):
    import numpy as np

    from iamp.simulation.figures import episode_figure, episode_figure_object

    fig = episode_figure_object(_synthetic_episode())  # type: ignore[arg-type]
    ego = next(line for line in fig.axes[0].lines if line.get_label() == "ego (centre)")
    x, y = np.asarray(ego.get_xdata()), np.asarray(ego.get_ydata())
    # before: the ego was drawn at x = 0 throughout (the frame moving with it): a vertical bar
    assert np.ptp(x) > 100.0 and np.ptp(y) == pytest.approx(3.75, abs=1e-6)
    assert np.all(np.diff(x) > 0)
    assert _texts_inside(fig) == []
    episode_figure(_synthetic_episode(), tmp_path / "e.png")  # type: ignore[arg-type]
    assert (tmp_path / "e.png").stat().st_size > 10_000


def test_item14_campaign_rates_titles_are_not_clipped(tmp_path, monkeypatch):
    import iamp.simulation.figures as figures

    figs = []
    monkeypatch.setattr(figures, "_save", lambda plt, fig, path: figs.append(fig) or path)
    keys = ("success", "contact", "hard_brake")  # the SPEC §15 cells (issue 20)
    summary = [{"mission": m, "planner": p, "traffic": t, **{f"{k}_rate": 0.5 for k in keys},
                **{f"{k}_ci": [0.3, 0.7] for k in keys}}
               for m in ("merge", "onramp") for p in ("pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
               for t in ("medium", "dense", "los-e")]
    figures.campaign_figures(summary, [], tmp_path)
    assert figs and all(_texts_inside(f) == [] for f in figs), [_texts_inside(f) for f in figs]


def test_item14_xy_caption_describes_the_prediction_the_plan_used():
    from iamp.cli.scenarios import load_cli_problem
    from iamp.comparison.report.document import vehicle1_words

    for name, before in (("paper-2", "decelerating"), ("paper-3", "accelerating")):
        _, prob, _ = load_cli_problem(name)
        text = vehicle1_words(name, prob)
        c = list(prob.vehicles[0].x_poly) + [0.0] * 4
        mean_a = (2 * c[2] * 5.0 + 3 * c[3] * 25.0) / 5.0
        assert f"was {before} before $t=0$" in text and f"{mean_a:+.2f}" in text
        # the predictions of scenarios 2 and 3 change speed by well under 1 m/s over 5 s
        assert abs(mean_a) < 0.1 and "nearly constant speed" in text


def _capture_figures(monkeypatch: pytest.MonkeyPatch, module: object) -> list:
    figs: list = []
    monkeypatch.setattr(module, "save_figure", lambda fig, stem: figs.append(fig) or [])
    return figs


def test_item14_costate_jump_labels_sit_off_the_lines_and_inside_the_axes(monkeypatch, tmp_path):
    import numpy as np

    import iamp
    import iamp.comparison.figures.comparison as comparison

    figs = _capture_figures(monkeypatch, comparison)
    for name in ("paper-1", "two-vehicle"):
        prob = iamp.load_scenario(name)
        comparison.plot_costates(iamp.plan(prob), {}, tmp_path / name)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    for fig in figs:
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        r = canvas.get_renderer()
        for ax in fig.axes:
            for text in ax.texts:
                b = text.get_window_extent(r)
                a = ax.get_window_extent(r)
                assert a.x0 - 1 <= b.x0 and b.x1 <= a.x1 + 1, text.get_text()  # before: Φ_1,y ran past x = tf
                for line in ax.lines:
                    if line.get_color() != comparison.PALETTE["pmp"]:
                        continue  # the co-state curves: a label must not cover them
                    pts = ax.transData.transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
                    inside = ((pts[:, 0] > b.x0) & (pts[:, 0] < b.x1) & (pts[:, 1] > b.y0) & (pts[:, 1] < b.y1))
                    assert not inside.any(), text.get_text()  # before: Φ_2,y = -0.4323 lay on p_3


def test_item14_timing_shows_no_quartiles_of_few_samples(monkeypatch, tmp_path):
    from matplotlib.container import ErrorbarContainer

    import iamp.comparison.figures.studies as studies

    figs = _capture_figures(monkeypatch, studies)
    whole = {"paper-1: PMP": {"median": 2e-5, "q1": 1.9e-5, "q3": 2.2e-5, "n": 200, "min": 1.5e-5, "max": 4e-5},
             "paper-1: osqp-foh-100": {"median": 1.1, "q1": 1.05, "q3": 1.2, "n": 3, "min": 1.0, "max": 1.3},
             "two-vehicle: osqp-foh-30": {"median": 4.0, "q1": 4.0, "q3": 4.0, "n": 1, "min": 4.0, "max": 4.0}}
    studies.plot_timing({"QP clarabel solve": [1e-3] * 10}, tmp_path / "t", whole_plans=whole)
    ax = figs[0].axes[0]
    bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 1  # only the row with n = 200 draws quartiles
    caps = {id(c) for b in bars for c in b.lines[1]}
    ends = sorted(float(x) for line in ax.lines if line.get_marker() == "|" and id(line) not in caps
                  for x in line.get_xdata())
    assert ends == [1.0, 1.3, 4.0, 4.0]


def test_item14_two_vehicle_safety_regions_are_told_apart(monkeypatch, tmp_path):
    from matplotlib.colors import to_rgba
    from matplotlib.patches import Rectangle

    import iamp
    import iamp.comparison.figures.safety as safety

    figs = _capture_figures(monkeypatch, safety)
    prob = iamp.load_scenario("two-vehicle")
    safety.plot_safety_xy({"equality (PMP)": iamp.plan(prob)}, tmp_path / "s")
    regions = [p for p in figs[0].axes[0].patches if isinstance(p, Rectangle) and not p.get_fill()]
    styles = {(to_rgba(p.get_edgecolor())[:3], str(p.get_linestyle())) for p in regions}
    assert len(styles) == 2  # before: one style (red dashed) for both vehicles' regions


def test_item14_xy_figures_are_readable_at_text_width(monkeypatch, tmp_path):
    # a figure set at a paper's text width (6.5 in) scales its fonts by 6.5 / width: the legend
    # must stay >= 7.5 pt (before: 10-11 in wide figures with 7-8 pt legends, i.e. 4-5 pt)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    import iamp
    import iamp.comparison.figures.safety as safety
    import iamp.comparison.figures.trajectory as trajectory

    figs_t = _capture_figures(monkeypatch, trajectory)
    figs_s = _capture_figures(monkeypatch, safety)
    trajectory.plot_xy_snapshots(iamp.plan(iamp.load_scenario("paper-2")), tmp_path / "xy")
    prob = iamp.load_scenario("two-vehicle")
    safety.plot_safety_xy({"equality (PMP)": iamp.plan(prob)}, tmp_path / "s")
    assert len(figs_t) == len(figs_s) == 1
    for fig in figs_t + figs_s:
        FigureCanvasAgg(fig)
        width = fig.get_size_inches()[0]
        legend = next(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)
        assert min(t.get_fontsize() for t in legend.get_texts()) * 6.5 / width >= 7.5
        assert _texts_inside(fig) == []
