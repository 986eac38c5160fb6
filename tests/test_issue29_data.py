"""Issue 29 items 4, 5, 8: the unit of an NGSIM-layout file, leaders without lane numbers, IAMP_DATA.

Item 4: a file in metres was read as feet (every result x 0.3048).  The unit is now read from the
data (vehicle lengths and widths, lane width, speeds); the ambiguous case is refused with the
evidence; ``--units`` / ``units=`` says it.

Item 5: with ``Lane_ID = 0`` everywhere the leader-aware predictor took the next vehicle ahead in
*any* lane as the leader.  Leaders are now found by lateral position where the lane numbers are
unusable, and a window's leader is accepted only if it stays ahead and in the same lane over the
history; otherwise the prediction is the fallback's.

Item 8: the recorded data are found through ``IAMP_DATA`` (conftest's ``data_path``).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA_ENV, data_path, data_root, needs_data
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.prediction.loaders import TrackDataError, load, load_ngsim
from iamp.prediction.loaders.units import FOOT_M

REPO = Path(__file__).resolve().parents[1]
HEADER = ("Vehicle_ID,Frame_ID,Total_Frames,Global_Time,Local_X,Local_Y,Global_X,Global_Y,v_length,v_Width,"
          "v_Class,v_Vel,v_Acc,Lane_ID,Preceding,Following,Space_Headway,Time_Headway")


def _traffic_csv(path: Path, *, factor: float, speeds: list[float], length: float, width: float, lane_w: float,
                 lanes: int, with_length: bool = True, with_width: bool = True, lane_ids: bool = True,
                 frames: int = 60) -> Path:
    """Vehicles at constant speed, one per lane in turn, in NGSIM's layout; SI values divided by ``factor``
    (0.3048: feet, 1: metres)."""
    lines = [HEADER]
    for i, v in enumerate(speeds):
        ln = i % lanes
        y_lat = (ln + 0.5) * lane_w
        x0 = 50.0 + 30.0 * i
        for k in range(frames):
            front = x0 + v * 0.1 * k
            lines.append(",".join([
                str(i + 1), str(k + 1), str(frames), "0", f"{y_lat / factor:.5f}", f"{front / factor:.5f}", "0", "0",
                f"{(length if with_length else 0.0) / factor:.5f}", f"{(width if with_width else 0.0) / factor:.5f}",
                "2", f"{v / factor:.5f}", "0", str(ln + 1 if lane_ids else 0), "0", "0", "0", "0"]))
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------------------------------
# item 4: the unit from the data
# ---------------------------------------------------------------------------------------

@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speeds=st.lists(st.floats(0.5, 35.0), min_size=1, max_size=4), length=st.floats(3.5, 8.0),
       width=st.floats(1.6, 2.6), lane_w=st.floats(3.0, 4.0), lanes=st.integers(1, 3),
       evidence=st.sets(st.sampled_from(["length", "width", "lanes"]), min_size=1))
def test_unit_is_detected_and_both_units_load_the_same_tracks(tmp_path: Path, speeds: list[float], length: float,
                                                              width: float, lane_w: float, lanes: int,
                                                              evidence: set[str]) -> None:
    """Feet and metres versions of the same traffic load to the same SI tracks, each unit detected, whatever
    single piece of decisive evidence (lengths, widths, lane width) the file carries."""
    if "lanes" in evidence and (lanes < 2 or len(speeds) < 2):
        lanes, speeds = 2, speeds + [10.0]
    kw = {"speeds": speeds, "length": length, "width": width, "lane_w": lane_w, "lanes": lanes,
          "with_length": "length" in evidence, "with_width": "width" in evidence, "lane_ids": "lanes" in evidence}
    ft = load_ngsim(_traffic_csv(tmp_path / "ft.csv", factor=FOOT_M, **kw))
    m = load_ngsim(_traffic_csv(tmp_path / "m.csv", factor=1.0, **kw))
    assert ft.meta["units"] == "feet" and m.meta["units"] == "metres"
    np.testing.assert_allclose(m.x, ft.x, atol=1e-4)
    np.testing.assert_allclose(m.v, ft.v, atol=1e-4)
    assert m.y is not None and ft.y is not None
    np.testing.assert_allclose(m.y, ft.y, atol=1e-4)
    np.testing.assert_allclose(np.median(m.v), np.median(speeds), rtol=1e-6, atol=1e-4)  # not scaled by 0.3048
    assert any(n.startswith("units: metres (detected") for n in m.meta["load_report"]["notes"])


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speeds=st.lists(st.floats(0.5, 13.0), min_size=1, max_size=3), factor=st.sampled_from([FOOT_M, 1.0]))
def test_without_decisive_evidence_the_file_is_refused_unless_units_are_given(tmp_path: Path, speeds: list[float],
                                                                             factor: float) -> None:
    """No lengths, widths or lane ids and speeds plausible in both units: refused with the evidence; with
    ``units`` the file loads in that unit."""
    p = _traffic_csv(tmp_path / "a.csv", factor=factor, speeds=speeds, length=4.5, width=1.8, lane_w=3.5, lanes=1,
                     with_length=False, with_width=False, lane_ids=False)
    with pytest.raises(TrackDataError, match=r"cannot tell feet from metres: 95th percentile of v_Vel .*--units"):
        load_ngsim(p)
    name = "feet" if factor == FOOT_M else "metres"
    tb = load(p, "ngsim", units=name)
    assert tb.meta["units"] == name
    np.testing.assert_allclose(np.sort(np.unique(np.round(tb.v, 3))), np.sort(np.unique(np.round(speeds, 3))),
                               atol=2e-3)


def test_contradicting_evidence_is_refused(tmp_path: Path) -> None:
    """Lengths in metres but speeds only possible in feet: refused, both named."""
    p = _traffic_csv(tmp_path / "c.csv", factor=1.0, speeds=[60.0, 62.0], length=4.5, width=1.8, lane_w=3.5,
                     lanes=1)
    with pytest.raises(TrackDataError, match="contradicts itself: median v_length 4.5.*95th percentile of v_Vel"):
        load_ngsim(p)


def _iamp(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "iamp", *args], capture_output=True, text=True, timeout=600,
                          cwd=REPO)


def test_cli_reads_metres_like_feet_refuses_the_ambiguous_file_and_takes_units(tmp_path: Path) -> None:
    """``evaluate-predictor`` on the metres file gives the feet file's errors (before: x 0.3048); an ambiguous
    file is exit 2 with one line naming it and the evidence; ``train --units`` reads it; ``--units`` with
    another format is refused."""
    from iamp.prediction.evaluation.user import evaluate_file
    from iamp.prediction.loaders.formats import ngsim_options

    kw = {"speeds": [12.0, 14.0, 9.0, 11.0], "length": 4.6, "width": 1.9, "lane_w": 3.6, "lanes": 2,
          "frames": 120}
    feet = evaluate_file(_traffic_csv(tmp_path / "ft.csv", factor=FOOT_M, **kw), "ngsim", interaction=False,
                         resamples=10)
    metres = _traffic_csv(tmp_path / "m.csv", factor=1.0, **kw)
    r = _iamp("evaluate-predictor", "--data", str(metres), "--format", "ngsim", "--no-interaction", "--json", "-q")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["rmse_m"]["cv"] == pytest.approx(feet["rmse_m"]["cv"], abs=1e-3)
    amb = _traffic_csv(tmp_path / "amb.csv", factor=1.0, **{**kw, "lanes": 1}, with_length=False, with_width=False,
                       lane_ids=False)
    r = _iamp("evaluate-predictor", "--data", str(amb), "--format", "ngsim", "--no-interaction", "--json", "-q")
    assert r.returncode == 2 and r.stdout == "" and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert str(amb) in r.stderr and "--units" in r.stderr and "v_Vel" in r.stderr
    r = _iamp("train", str(amb), "--format", "ngsim", "--out", str(tmp_path / "m.json"), "--units", "metres")
    assert r.returncode == 0 and "units: metres (given" in r.stdout, r.stderr
    with pytest.raises(ValueError, match="--units applies to NGSIM data only"):
        ngsim_options("sumo", units="feet")


@needs_data("ngsim-us101", "us101_ngsim.csv.gz")
def test_shared_us101_is_detected_as_feet_and_loads_as_before() -> None:
    """The shared US-101 CSV is in feet (PROVENANCE: converted m -> ft); every piece of evidence says so and the
    table equals the one read with ``units="feet"``."""
    path = data_path("ngsim-us101", "us101_ngsim.csv.gz")
    tb = load_ngsim(path)
    note = tb.meta["load_report"]["notes"][0]
    assert tb.meta["units"] == "feet" and note.startswith("units: feet (detected")
    assert note.count("fits feet of") == 4 and "metres of" not in note
    given = load_ngsim(path, units="feet")
    assert np.array_equal(tb.x, given.x) and np.array_equal(tb.v, given.v)
    assert 13.0 < float(np.median(tb.v)) < 14.5  # 45 ft/s


# ---------------------------------------------------------------------------------------
# item 8: IAMP_DATA
# ---------------------------------------------------------------------------------------

def test_data_path_follows_iamp_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DATA_ENV, str(tmp_path))
    assert data_root() == tmp_path
    assert data_path("ngsim-us101", "x.csv") == tmp_path / "ngsim-us101" / "x.csv"
    mark = needs_data("ngsim-us101", "x.csv")
    assert mark.args[0] is True and str(tmp_path) in mark.kwargs["reason"] and DATA_ENV in mark.kwargs["reason"]
    monkeypatch.delenv(DATA_ENV)
    assert data_root() == REPO.parent / "shared" / "data"


def test_no_test_hardcodes_the_shared_data_folder() -> None:
    """Every test reaches the recorded data through conftest's ``data_path`` (so ``IAMP_DATA`` works)."""
    pattern = re.compile(r"""["']shared["']\s*/\s*["']data["']|["'][^"'\n]*shared/data""")
    mine = ("conftest.py", Path(__file__).name)
    offenders = [p.name for p in sorted((REPO / "tests").glob("*.py"))
                 if p.name not in mine and pattern.search(p.read_text(encoding="utf-8"))]
    assert offenders == []


# ---------------------------------------------------------------------------------------
# item 5: leaders without lane numbers
# ---------------------------------------------------------------------------------------

def _lane_less(src: Path, dst: Path, *, lateral_noise_m: float = 0.3, keep_local_x: bool = True) -> Path:
    """``src`` with ``Lane_ID`` and ``Preceding`` zeroed (and noise on ``Local_X``, or the column dropped)."""
    import csv

    rows = list(csv.reader(src.open(newline="")))
    ix = {c: i for i, c in enumerate(rows[0])}
    rng = np.random.default_rng(0)
    for r in rows[1:]:
        r[ix["Lane_ID"]] = r[ix["Preceding"]] = "0"
        r[ix["Local_X"]] = f"{float(r[ix['Local_X']]) + rng.normal(0.0, lateral_noise_m / FOOT_M):.3f}"
    if not keep_local_x:
        rows = [[c for k, c in enumerate(r) if k != ix["Local_X"]] for r in rows]
    with dst.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return dst


@pytest.fixture(scope="module")
def three_lanes(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """Generated 3-lane traffic (no lane changes, lanes 3.7 m apart): with lane numbers, without, and
    without lane numbers and lateral positions."""
    from iamp.prediction.leader.synthetic import i80_like, write_ngsim_csv

    d = tmp_path_factory.mktemp("lanes")
    full = write_ngsim_csv(d / "full.csv", i80_like(3, lanes=3, duration_s=150.0))
    return full, _lane_less(full, d / "no_lanes.csv"), _lane_less(full, d / "no_lateral.csv", keep_local_x=False)


def _rmse_5s_leader_and_fallback(path: Path) -> tuple[float, float, int, str]:
    from iamp.prediction.leader.leaders import leaders_for
    from iamp.prediction.leader.model import LeaderPredictor, default_leader_model
    from iamp.prediction.leader.windows import leader_windows
    from iamp.prediction.windows import make_windows

    tb = load(path, "ngsim")
    leaders = leaders_for(path, "ngsim", tb)
    win = make_windows(tb)
    lw = leader_windows(tb, leaders, win)
    lp = LeaderPredictor(default_leader_model())
    lead = lp.predict_batch(win.t_hist, win.X_hist, win.t_fut, 5.0, XL_hist=lw.XL_hist, has_leader=lw.known,
                            offset=lw.offset)
    fall = lp.fallback.predict_batch(win.t_hist, win.X_hist, win.t_fut, 5.0)

    def rmse(p: np.ndarray) -> float:
        return float(np.sqrt(np.mean((p[:, -1] - win.X_fut[:, -1]) ** 2)))

    return rmse(lead), rmse(fall), int(np.sum(lw.known)), leaders.source


def test_leader_model_without_lane_numbers_is_not_worse_than_its_fallback(three_lanes: tuple[Path, Path, Path]) -> None:
    """``Lane_ID = 0``, ``Preceding = 0``: leaders come from lateral positions and the leader model's RMSE at
    5 s is not above the fallback's (before: every vehicle in one lane, the next vehicle ahead in any lane
    taken as the leader); it equals the RMSE with the true lane numbers."""
    full, no_lanes, _ = three_lanes
    with_lanes = _rmse_5s_leader_and_fallback(full)
    lead, fall, known, source = _rmse_5s_leader_and_fallback(no_lanes)
    assert source.startswith("derived from lateral position") and "0 (unknown) in every row" in source
    assert known > 0 and lead <= fall
    assert lead == pytest.approx(with_lanes[0], rel=0.02) and known == with_lanes[2]


def test_derived_leaders_are_the_lane_predecessors(three_lanes: tuple[Path, Path, Path]) -> None:
    """The leaders found by lateral position are NGSIM's ``Preceding`` of the file with lanes (where both
    vehicles are recorded)."""
    from iamp.prediction.leader.leaders import ngsim_leaders

    full, no_lanes, _ = three_lanes
    a, b = load(full, "ngsim"), load(no_lanes, "ngsim")
    truth, derived = ngsim_leaders(full, a), ngsim_leaders(no_lanes, b)
    assert np.array_equal(a.track_id, b.track_id) and np.array_equal(a.t, b.t)
    has = truth.leader >= 0
    assert np.mean(derived.leader[has] == truth.leader[has]) > 0.99


def test_without_lateral_positions_no_leader_is_guessed(three_lanes: tuple[Path, Path, Path],
                                                        tmp_path: Path) -> None:
    """No lane numbers and no ``Local_X``: no leader is derived (the source says why), the leader model *is*
    its fallback, and ``iamp train --model-kind leader`` refuses with the reason."""
    _, _, bare = three_lanes
    lead, fall, known, source = _rmse_5s_leader_and_fallback(bare)
    assert known == 0 and lead == fall and source.startswith("none:") and "no lateral positions" in source
    r = _iamp("train", str(bare), "--format", "ngsim", "--model-kind", "leader", "--out", str(tmp_path / "l.json"),
              "-q")
    assert r.returncode == 2 and "no lateral positions" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "l.json").exists()


@settings(max_examples=60, deadline=None)
@given(data=st.lists(st.tuples(st.integers(0, 2), st.floats(0.0, 200.0), st.floats(-6.0, 6.0)), min_size=1,
                     max_size=25, unique_by=lambda r: (r[0], round(r[1], 3))))
def test_lateral_leader_is_the_nearest_vehicle_ahead_within_half_a_lane(data: list[tuple[int, float, float]]) -> None:
    """Brute force: per instant, the leader of a row is the nearest row strictly ahead with ``|dy| < 1.75 m``."""
    from iamp.prediction.leader.leaders import SAME_LANE_TOL_M, lateral_leaders
    from iamp.prediction.tracks import Tracks

    rows = sorted(enumerate(data), key=lambda r: r[0])  # one row per vehicle id (= track), frames 0..2
    tid = np.array([i for i, _ in rows], dtype=np.int64)
    t = np.array([0.1 * f for _, (f, _, _) in rows])
    x = np.array([xx for _, (_, xx, _) in rows])
    y = np.array([yy for _, (_, _, yy) in rows])
    tb = Tracks(tid, t, x, np.zeros_like(x), np.zeros_like(x), np.zeros(tid.size, dtype=np.int64), 0.1, {}, y)
    got = lateral_leaders(tb)
    for i in range(len(tb)):
        ahead = [(tb.x[j] - tb.x[i], int(tb.track_id[j])) for j in range(len(tb))
                 if abs(tb.t[j] - tb.t[i]) < 1e-9 and tb.x[j] > tb.x[i] and abs(tb.y[j] - tb.y[i]) < SAME_LANE_TOL_M]
        want = min(ahead)[1] if ahead else -1
        if ahead and sum(1 for d, _ in ahead if d == min(ahead)[0]) > 1:
            continue  # a tie in x: either is right
        assert got[i] == want


def test_a_leader_not_ahead_over_the_history_is_refused_and_the_fallback_predicts() -> None:
    """A named leader that overlaps the follower during the history (a vehicle alongside, not ahead) is refused
    (counted in ``rejected``) and the window is the fallback's, bit for bit; one ahead throughout is known."""
    from iamp.prediction.leader.leaders import Leaders
    from iamp.prediction.leader.model import LeaderPredictor, default_leader_model
    from iamp.prediction.leader.windows import leader_windows
    from iamp.prediction.tracks import Tracks
    from iamp.prediction.windows import make_windows

    t = 0.1 * np.arange(100)
    xf = 10.0 * t
    cols = []
    for tid, x in ((0, xf), (1, xf + 30.0), (2, xf + 2.0 + 0.5 * t)):  # follower, leader ahead, one alongside
        cols.append((np.full(t.size, tid), t, x))
    tid = np.concatenate([c[0] for c in cols])
    tt = np.concatenate([c[1] for c in cols])
    xx = np.concatenate([c[2] for c in cols])
    tb = Tracks(tid, tt, xx, np.full(tt.size, 10.0), np.zeros(tt.size), np.zeros(tt.size, dtype=np.int64), 0.1, {})
    win = make_windows(tb.select(tb.track_id == 0))
    lp = LeaderPredictor(default_leader_model())
    fallback = lp.fallback.predict_batch(win.t_hist, win.X_hist, win.t_fut, 5.0)
    for leader, known in ((1, True), (2, False)):
        lead = np.where(tb.track_id == 0, leader, -1).astype(np.int64)
        lw = leader_windows(tb, Leaders(lead, np.full(tt.size, 4.5), "test"), win)
        assert bool(lw.known[0]) is known and bool(lw.rejected[0]) is (not known)
        pred = lp.predict_batch(win.t_hist, win.X_hist, win.t_fut, 5.0, XL_hist=lw.XL_hist, has_leader=lw.known,
                                offset=lw.offset)
        assert np.array_equal(pred, fallback) is (not known)


# ---------------------------------------------------------------------------------------
# item 4, the unit rule itself (added by mutation testing of prediction/loaders/units.py, seed 3):
# detect_units on columns, fast
# ---------------------------------------------------------------------------------------

def _lanes(medians_m: list[float], rows: int = 25, factor: float = 1.0) -> dict[str, np.ndarray]:
    """Lane ids 1, 2, ... with ``rows`` rows each at the given lateral positions (SI / ``factor``)."""
    ids = np.repeat(np.arange(1, len(medians_m) + 1, dtype=float), rows)
    return {"Lane_ID": ids, "Local_X": np.repeat(np.asarray(medians_m) / factor, rows)}


@pytest.mark.parametrize(("column", "value"), [("v_length", 2.5), ("v_length", 9.0), ("v_Width", 1.2),
                                               ("v_Width", 3.0)])
def test_the_plausible_ranges_are_closed(column: str, value: float) -> None:
    """A median exactly at an end of its range (in metres) fits metres, and so do speeds of exactly
    SPEED_MAX_MPS (45 m/s): the ranges include their ends."""
    from iamp.prediction.loaders.units import detect_units

    d = detect_units({column: np.full(5, value), "v_Vel": np.full(5, 45.0)}, "f.csv", units="metres")
    assert re.search(r"; fits (feet and )?metres of", d.evidence[0]), d.evidence
    assert d.evidence[1] == ("95th percentile of v_Vel 45 (13.7 m/s as feet, 45 m/s as metres; fits feet and metres "
                             "of <= 45 m/s)")
    if column == "v_Width":  # the two units' width ranges do not overlap: decisive
        assert detect_units({column: np.full(5, value), "v_Vel": np.full(5, 45.0)}, "f.csv").units == "metres"
    for lane_w in (2.5, 5.5):
        assert detect_units(_lanes([0.0, lane_w]), "f.csv").units == "metres"


@settings(max_examples=40, deadline=None)
@given(data=st.data(), column=st.sampled_from(["v_length", "v_Width"]), factor=st.sampled_from([FOOT_M, 1.0]))
def test_a_length_or_a_width_alone_decides_the_unit(data: st.DataObject, column: str, factor: float) -> None:
    """A median width in WIDTH_RANGE_M, written in feet or in metres, is detected as that unit from that
    column alone; so is a median length in LENGTH_RANGE_M outside the overlap (a file value of 8.2-9 fits
    both: as metres below 8.2 m, as feet above 9 ft = 2.74 m)."""
    from iamp.prediction.loaders.units import LENGTH_RANGE_M, WIDTH_RANGE_M, detect_units

    if column == "v_Width":
        lo, hi = WIDTH_RANGE_M
    else:
        lo, hi = (9.0 * FOOT_M + 1e-3, 9.0) if factor == FOOT_M else (LENGTH_RANGE_M[0], 2.5 / FOOT_M - 1e-3)
    value_si = data.draw(st.floats(lo, hi))
    values = np.concatenate([np.full(7, value_si / factor), [0.0, -1.0, np.nan]])  # non-positive rows ignored
    d = detect_units({column: values}, "f.csv")
    assert d.units == ("feet" if factor == FOOT_M else "metres")
    assert d.evidence[0].startswith(f"median {column} {value_si / factor:.4g} (")


@pytest.mark.parametrize("factor", [FOOT_M, 1.0])
@pytest.mark.parametrize("end", [0, 1])
def test_a_width_at_either_end_of_its_range_decides_the_unit(factor: float, end: int) -> None:
    """The ends of WIDTH_RANGE_M belong to it in both units: 3 m written in feet (9.8425) converts back to
    3.0000000000000004 m, which the round-off allowance keeps inside (hypothesis found it refused)."""
    from iamp.prediction.loaders.units import WIDTH_RANGE_M, detect_units

    value = WIDTH_RANGE_M[end] / factor
    d = detect_units({"v_Width": np.full(7, value)}, "f.csv")
    assert d.units == ("feet" if factor == FOOT_M else "metres")


@settings(max_examples=30, deadline=None)
@given(length_m=st.floats(2.5 / FOOT_M + 1e-6, 9.0))
def test_median_lengths_of_8_2_to_9_m_fit_both_units(length_m: float) -> None:
    """LENGTH_RANGE_M (2.5, 9) m and its image in feet (8.2, 29.5) overlap on 8.2-9: such a median
    length is plausible as metres and as feet (27-30 ft trucks) and does not decide alone."""
    from iamp.prediction.loaders.units import detect_units

    with pytest.raises(TrackDataError, match="cannot tell feet from metres: median v_length .*fits feet and metres"):
        detect_units({"v_length": np.full(5, length_m)}, "f.csv")


@settings(max_examples=40, deadline=None)
@given(p95_si=st.floats(13.8, 45.0), factor=st.sampled_from([FOOT_M, 1.0]))
def test_fast_speeds_alone_rule_metres_out(p95_si: float, factor: float) -> None:
    """Speeds whose 95th percentile read as metres exceeds 45 m/s can only be feet; the same speeds
    read as feet (below 45 m/s in metres) leave both units, and the file is refused."""
    from iamp.prediction.loaders.units import detect_units

    v = np.full(40, p95_si / FOOT_M)  # in feet: 45.3 .. 147.6 (as metres above 45)
    assert detect_units({"v_Vel": v}, "f.csv").units == "feet"
    with pytest.raises(TrackDataError, match="cannot tell feet from metres"):
        detect_units({"v_Vel": np.full(40, p95_si * 0.99)}, "f.csv")  # <= 45 in metres, slower in feet


@settings(max_examples=40, deadline=None)
@given(lane_w=st.floats(2.6, 5.4), lanes=st.integers(2, 5), factor=st.sampled_from([FOOT_M, 1.0]),
       offset=st.floats(-20.0, 20.0))
def test_the_lane_width_is_the_median_gap_of_adjacent_lanes(lane_w: float, lanes: int, factor: float,
                                                            offset: float) -> None:
    """Lanes ``lane_w`` apart (at any offset) decide the unit from Lane_ID/Local_X alone; an extra lane
    at the same Local_X as its neighbour (one zero gap among several) does not hide the others; lanes with
    fewer than MIN_LANE_ROWS rows are not counted."""
    from iamp.prediction.loaders.units import MIN_LANE_ROWS, detect_units

    name = "feet" if factor == FOOT_M else "metres"
    centres = [offset + k * lane_w for k in range(lanes)]
    d = detect_units(_lanes(centres, factor=factor), "f.csv")
    assert d.units == name
    assert f"lane width (median Local_X per Lane_ID) {lane_w / factor:.4g}" in d.evidence[0]
    if lanes >= 3:  # gaps [w, ..., w, 0]: the median is still w
        assert detect_units(_lanes([*centres, centres[-1]], factor=factor), "f.csv").units == name
    few = _lanes(centres, rows=MIN_LANE_ROWS - 1, factor=factor)
    with pytest.raises(TrackDataError, match="no v_length, v_Width or lane ids"):
        detect_units(few, "f.csv")
    assert detect_units(_lanes(centres, rows=MIN_LANE_ROWS, factor=factor), "f.csv").units == name


def test_a_given_unit_is_reported_with_the_evidence() -> None:
    from iamp.prediction.loaders.units import detect_units

    d = detect_units({"v_Width": np.full(5, 1.8)}, "f.csv", units="ft")
    assert (d.units, d.factor, d.how) == ("feet", FOOT_M, "given")
    assert d.note().startswith("units: feet (given; the data's evidence: median v_Width 1.8 (")
    assert detect_units({"v_Width": np.full(5, 1.8)}, "f.csv").note().startswith("units: metres (detected")
