"""Trajectory data for the predictor: the Tracks table, the highD / NGSIM / SUMO loaders and
the shipped SUMO dataset.

The fixtures in tests/fixtures are written by tests/fixtures/make_fixtures.py; the ground
truth formulas below repeat the ones documented there.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from iamp.core.errors import IampError
from iamp.prediction.loaders.formats import FEET, load, load_highd, load_ngsim, load_sumo_fcd
from iamp.prediction.tracks.table import TrackDataError, Tracks, load_shipped_dataset

FIX = Path(__file__).resolve().parent / "fixtures"
HIGHD = FIX / "highd"
REPO = Path(__file__).resolve().parents[1]


def _sumo_binary(name: str) -> str | None:
    try:
        import sumo

        cand = Path(sumo.SUMO_HOME) / "bin" / name
        if cand.is_file():
            return str(cand)
    except ImportError:
        pass
    return shutil.which(name)


requires_sumo = pytest.mark.skipif(_sumo_binary("sumo") is None or _sumo_binary("netconvert") is None,
                                   reason="Eclipse SUMO is not installed (pip install 'iamp[sumo]')")


def tracks_of(tb: Tracks) -> dict:
    return {tid: dict(t=t, x=x, v=v, a=a, lane=lane) for tid, t, x, v, a, lane in tb.iter_tracks()}


def simple(n_tracks=3, n=20, dt=0.1, **kw) -> Tracks:
    tid = np.repeat(np.arange(n_tracks), n)
    t = np.tile(np.arange(n) * dt, n_tracks) + tid * 5.0
    v = 20.0 + 0.5 * t
    x = 100.0 * tid + 20.0 * t + 0.25 * t ** 2
    a = np.full(t.size, 0.5)
    lane = np.where(np.tile(np.arange(n), n_tracks) < n // 2, 1, 2)
    return Tracks(tid, t, x, v, a, lane, dt, {"format": "test", **kw})


# ---------------------------------------------------------------------------------- highD

class TestHighD:
    def test_recording_with_meta(self):
        tb = load_highd(HIGHD / "01_tracks.csv")
        assert tb.dt == pytest.approx(1 / 20)  # frameRate 20 read from the recordingMeta
        assert tb.meta["frame_rate"] == 20.0 and tb.meta["frame_rate_source"] == "recordingMeta"
        assert tb.meta["driving_direction_source"] == "tracksMeta"
        assert list(tb.ids()) == [1, 2, 3]  # highD ids kept
        tr = tracks_of(tb)

        # id 1, direction 2: centre = x + width/2, t = frame / 20
        frames = np.arange(1, 41)
        np.testing.assert_allclose(tr[1]["t"], frames / 20)
        np.testing.assert_allclose(tr[1]["x"], 10 + 30 * frames / 20 + 4.5 / 2, atol=1e-4)
        np.testing.assert_allclose(tr[1]["v"], 30.0)
        np.testing.assert_allclose(tr[1]["a"], 0.0)
        assert set(tr[1]["lane"]) == {5}

        # id 2, direction 1 (towards -x): mirrored, x -> -(x + width/2), v and a negated
        frames = np.arange(5, 35)
        s = (frames - 5) / 20
        np.testing.assert_allclose(tr[2]["t"], frames / 20)
        np.testing.assert_allclose(tr[2]["x"], -(380 - 25 * s + 0.25 * s ** 2 + 12 / 2), atol=1e-4)
        np.testing.assert_allclose(tr[2]["v"], 25 - 0.5 * s, atol=1e-4)
        np.testing.assert_allclose(tr[2]["a"], -0.5)  # it is slowing down
        assert np.all(np.diff(tr[2]["x"]) > 0)  # positions increase in the driving direction
        np.testing.assert_array_equal(tr[2]["lane"], np.where(frames < 20, 2, 3))

        # id 3, direction 2, accelerating
        frames = np.arange(10, 40)
        s = (frames - 10) / 20
        np.testing.assert_allclose(tr[3]["x"], 50 + 20 * s + 0.5 * s ** 2 + 4.0 / 2, atol=1e-4)
        np.testing.assert_allclose(tr[3]["v"], 20 + s, atol=1e-4)
        np.testing.assert_allclose(tr[3]["a"], 1.0)
        assert tb.meta["n_tracks_direction_1_mirrored"] == 1

    def test_defaults_without_meta_files_and_frame_gaps(self):
        tb = load_highd(HIGHD / "02_tracks.csv")
        assert tb.dt == pytest.approx(1 / 25)  # highD default frame rate, recorded in the meta
        assert "default" in tb.meta["frame_rate_source"]
        assert "inferred" in tb.meta["driving_direction_source"]
        # vehicle 2 has frames 1..10 and 16..25: split into two tracks, renumbered
        assert tb.n_tracks == 3 and list(tb.ids()) == [0, 1, 2]
        assert tb.meta["source_ids"] == [1, 2, 2]
        tr = tracks_of(tb)
        frames = np.arange(1, 26)
        np.testing.assert_allclose(tr[0]["x"], -(300 - 30 * frames / 25 + 2.5), atol=1e-4)  # inferred dir. 1
        np.testing.assert_allclose(tr[0]["v"], 30.0)
        np.testing.assert_allclose(tr[1]["t"], np.arange(1, 11) / 25)
        np.testing.assert_allclose(tr[2]["t"], np.arange(16, 26) / 25)
        np.testing.assert_allclose(tr[2]["x"], 20 + 28 * np.arange(16, 26) / 25 + 2.0, atol=1e-4)

    def test_explicit_meta_paths(self, tmp_path):
        shutil.copy(HIGHD / "01_tracks.csv", tmp_path / "recording.csv")  # no siblings to find
        alone = load_highd(tmp_path / "recording.csv")
        assert alone.dt == pytest.approx(0.04)
        tb = load_highd(tmp_path / "recording.csv", HIGHD / "01_tracksMeta.csv", HIGHD / "01_recordingMeta.csv")
        assert tb.dt == pytest.approx(0.05)
        np.testing.assert_allclose(tb.x, load_highd(HIGHD / "01_tracks.csv").x)


# ---------------------------------------------------------------------------------- NGSIM

class TestNgsim:
    def test_units_ids_duplicates(self):
        tb = load_ngsim(FIX / "ngsim.csv")
        assert tb.dt == pytest.approx(0.1)
        # (Location, Vehicle_ID) keys, split at the frame gap, renumbered in sorted key order
        assert tb.meta["source_ids"] == [["i-80", 7, 200], ["us-101", 7, 100], ["us-101", 9, 100],
                                         ["us-101", 9, 120]]
        assert list(tb.ids()) == [0, 1, 2, 3]
        rep = tb.meta["load_report"]
        assert rep["dropped"]["exact duplicate row (same vehicle, frame and values)"] == 5
        assert rep["dropped"]["conflicting row for the same vehicle and frame (the first in file order kept)"] == 1
        assert rep["rows_read"] == rep["rows_kept"] + 6 == len(tb) + 6
        tr = tracks_of(tb)

        # us-101 vehicle 7: Local_Y is the front -> centre = Local_Y - v_length/2, feet -> metres
        frames = np.arange(100, 130)
        s = (frames - 100) / 10
        assert tr[1]["t"].size == 30  # duplicates dropped
        np.testing.assert_allclose(tr[1]["t"], frames * 0.1)
        np.testing.assert_allclose(tr[1]["x"], (100 + 50 * s - 15 / 2) * 0.3048, atol=1e-6)
        np.testing.assert_allclose(tr[1]["v"], 50 * 0.3048)  # the conflicting 99 ft/s row is gone
        assert set(tr[1]["lane"]) == {2}

        # i-80 vehicle 7 (same Vehicle_ID, other location), accelerating at 2 ft/s^2
        frames = np.arange(200, 220)
        s = (frames - 200) / 10
        np.testing.assert_allclose(tr[0]["x"], (500 + 40 * s + s ** 2 - 7) * FEET, atol=1e-6)
        np.testing.assert_allclose(tr[0]["v"], (40 + 2 * s) * FEET, atol=1e-6)
        np.testing.assert_allclose(tr[0]["a"], 2 * FEET)
        np.testing.assert_array_equal(tr[0]["lane"], np.where(frames < 210, 3, 4))

        # us-101 vehicle 9: two tracks around the missing frames 110..119
        np.testing.assert_allclose(tr[2]["t"], np.arange(100, 110) * 0.1)
        np.testing.assert_allclose(tr[3]["t"], np.arange(120, 130) * 0.1)
        np.testing.assert_allclose(tr[3]["x"], (300 + 40 * (np.arange(120, 130) - 100) / 10 - 10) * FEET)

    def test_location_filter(self):
        tb = load_ngsim(FIX / "ngsim.csv", location="US-101")
        assert tb.n_tracks == 3 and tb.meta["locations"] == ["us-101"]
        with pytest.raises(TrackDataError, match="Location"):
            load_ngsim(FIX / "ngsim.csv", location="lankershim")


# ---------------------------------------------------------------------------------- SUMO

class TestSumo:
    def test_xml_front_bumper_lengths_lanes_gaps(self):
        tb = load_sumo_fcd(FIX / "sumo_fcd.xml", lengths={"car": 4.5, "truck": 12.0})
        assert tb.dt == pytest.approx(0.1)
        assert tb.meta["source_ids"] == ["car.0", "car.1", "car.1", "truck.0"]
        assert tb.meta["acceleration_source"] == "acceleration attribute"
        tr = tracks_of(tb)
        t = np.arange(31) / 10
        np.testing.assert_allclose(tr[0]["t"], t)
        np.testing.assert_allclose(tr[0]["x"], 100 + 30 * t - 4.5 / 2, atol=1e-9)  # front bumper -> centre
        np.testing.assert_allclose(tr[0]["v"], 30.0)
        # hw_0 -> hw_1 at 1.5 s; the internal lane at 2.0 s holds lane 1; then hw2_1
        np.testing.assert_array_equal(tr[0]["lane"], np.where(t < 1.45, 0, 1))
        # car.1 teleported between 1.0 and 2.0 s: two tracks
        np.testing.assert_allclose(tr[1]["t"], np.arange(11) / 10)
        np.testing.assert_allclose(tr[2]["t"], 2 + np.arange(11) / 10)
        np.testing.assert_allclose(tr[2]["x"], 10 + 25 * tr[2]["t"] - 2.25, atol=1e-9)
        s = tr[3]["t"] - 0.5
        np.testing.assert_allclose(tr[3]["x"], 50 + 20 * s + s ** 2 - 6.0, atol=1e-9)
        np.testing.assert_allclose(tr[3]["v"], 20 + 2 * s, atol=1e-9)
        np.testing.assert_allclose(tr[3]["a"], 2.0)

    def test_default_and_per_vehicle_lengths(self):
        tb = load_sumo_fcd(FIX / "sumo_fcd.xml")
        assert tb.meta["default_length"] == 5.0 and tb.meta["length_source_counts"] == {"default": len(tb)}
        np.testing.assert_allclose(tb.track(0).x, 100 + 30 * np.arange(31) / 10 - 2.5, atol=1e-9)
        tb = load_sumo_fcd(FIX / "sumo_fcd.xml", lengths={"car": 4.5, "car.1": 3.0}, default_length=8.0)
        assert tb.track(0).x[0] == pytest.approx(100 - 2.25)  # by type
        assert tb.track(1).x[0] == pytest.approx(10 - 1.5)  # vehicle id wins over type
        assert tb.track(3).x[0] == pytest.approx(50 - 4.0)  # default

    def test_vtype_in_file(self, tmp_path):
        text = (FIX / "sumo_fcd.xml").read_text()
        text = text.replace('<timestep time="-0.10"/>', '<vType id="truck" length="10.00"/>')
        (tmp_path / "fcd.xml").write_text(text)
        tb = load_sumo_fcd(tmp_path / "fcd.xml")
        assert tb.track(3).x[0] == pytest.approx(50 - 5.0)
        assert tb.track(0).x[0] == pytest.approx(100 - 2.5)

    def test_csv_matches_xml(self):
        xml = load_sumo_fcd(FIX / "sumo_fcd.xml", lengths={"car": 4.5})
        csv = load_sumo_fcd(FIX / "sumo_fcd.csv", lengths={"car": 4.5})
        assert csv.meta["file_type"] == "csv"
        for col in ("track_id", "t", "x", "v", "a", "lane"):
            np.testing.assert_array_equal(getattr(xml, col), getattr(csv, col))

    def test_acceleration_from_speed(self):
        tb = load_sumo_fcd(FIX / "sumo_fcd_noacc.csv")
        assert tb.meta["acceleration_source"] == "backward difference of speed"
        np.testing.assert_allclose(tb.track(3).a, 2.0, atol=1e-9)
        np.testing.assert_allclose(tb.a[tb.track_id != 3], 0.0, atol=1e-9)

    def test_road_towards_minus_x_is_mirrored(self, tmp_path):
        lines = ['<fcd-export>']
        for k in range(10):
            lines.append(f'<timestep time="{k / 10:.2f}"><vehicle id="a" x="{500 - 20 * k / 10:.2f}" y="0" '
                         f'angle="270.00" type="t" speed="20.00" lane="e_0"/></timestep>')
        lines.append("</fcd-export>")
        (tmp_path / "w.xml").write_text("\n".join(lines))
        tb = load_sumo_fcd(tmp_path / "w.xml", default_length=4.0)
        np.testing.assert_allclose(tb.x, -(500 - 20 * np.arange(10) / 10 + 2.0), atol=1e-9)
        assert "mirrored" in tb.meta and np.all(np.diff(tb.x) > 0)
        np.testing.assert_allclose(tb.a, 0.0)

    def test_coordinate_pos(self):
        tb = load_sumo_fcd(FIX / "sumo_fcd.xml", coordinate="pos", lengths={"car": 4.5})
        # car.0's pos restarts on the internal lane at 2.0 s (then continues on hw2): split there
        assert tb.meta["source_ids"][:3] == ["car.0", "car.0", "car.1"]
        first = tb.track(0)
        np.testing.assert_allclose(first.t, np.arange(20) / 10)
        np.testing.assert_allclose(first.x, 100 + 30 * first.t - 2.25, atol=1e-9)
        assert all(np.all(np.diff(x) > 0) for _, _, x, _, _, _ in tb.iter_tracks())


# ---------------------------------------------------------------------------------- dispatch

class TestLoadDispatch:
    def test_ids_unique_across_files(self):
        tb = load([HIGHD / "01_tracks.csv", HIGHD / "01_tracks.csv"], "highd")
        assert tb.n_tracks == 6 and np.unique(tb.ids()).size == 6
        assert tb.meta["parts_id_offset"] == [0, 3]

    def test_directory_and_mixed_rates(self):
        tb = load(HIGHD, "HighD")
        assert tb.n_tracks == 6 and tb.dt == pytest.approx(0.05)  # 25 Hz file resampled to 20 Hz

    def test_each_format(self):
        assert load(FIX / "ngsim.csv", "ngsim").meta["format"] == "ngsim"
        assert load([FIX / "sumo_fcd.xml"], "sumo").meta["format"] == "sumo-fcd"

    def test_unknown_format(self):
        with pytest.raises(TrackDataError, match="unknown format"):
            load(FIX / "ngsim.csv", "interaction")


# ---------------------------------------------------------------------------------- bad files

def _drop_column(src: Path, dst: Path, name: str, delimiter=","):
    rows = [line.rstrip("\n").split(delimiter) for line in src.read_text().splitlines()]
    k = rows[0].index(name)
    dst.write_text("\n".join(delimiter.join(r[:k] + r[k + 1:]) for r in rows) + "\n")


class TestBadFiles:
    @pytest.mark.parametrize("src,column,loader,delim", [
        (HIGHD / "01_tracks.csv", "xVelocity", load_highd, ","),
        (HIGHD / "01_tracks.csv", "laneId", load_highd, ","),
        (FIX / "ngsim.csv", "Local_Y", load_ngsim, ","),
        (FIX / "ngsim.csv", "v_Acc", load_ngsim, ","),
        (FIX / "sumo_fcd.csv", "vehicle_speed", load_sumo_fcd, ";"),
        (FIX / "sumo_fcd.csv", "vehicle_x", load_sumo_fcd, ";"),
    ])
    def test_missing_column(self, tmp_path, src, column, loader, delim):
        bad = tmp_path / ("bad_" + src.name)
        _drop_column(src, bad, column, delim)
        with pytest.raises(TrackDataError) as err:
            loader(bad)
        msg = str(err.value)
        assert f"column '{column}'" in msg and str(bad) in msg and "\n" not in msg
        assert err.value.column == column and isinstance(err.value, ValueError)
        assert isinstance(err.value, IampError)

    def test_missing_meta_column(self, tmp_path):
        _drop_column(HIGHD / "01_recordingMeta.csv", tmp_path / "01_recordingMeta.csv", "frameRate")
        with pytest.raises(TrackDataError, match="column 'frameRate'"):
            load_highd(HIGHD / "01_tracks.csv", recording_meta_csv=tmp_path / "01_recordingMeta.csv")

    def test_non_numeric_value(self, tmp_path):
        text = (HIGHD / "01_tracks.csv").read_text().splitlines()
        fields = text[3].split(",")
        fields[6] = "fast"  # xVelocity
        text[3] = ",".join(fields)
        (tmp_path / "01_tracks.csv").write_text("\n".join(text) + "\n")
        with pytest.raises(TrackDataError, match=r"column 'xVelocity': line 4: cannot read 'fast'"):
            load_highd(tmp_path / "01_tracks.csv")

    def test_xml_vehicle_without_attribute(self, tmp_path):
        text = (FIX / "sumo_fcd.xml").read_text().replace('speed="30.00" ', "", 1)
        (tmp_path / "fcd.xml").write_text(text)
        with pytest.raises(TrackDataError, match="column 'speed'"):
            load_sumo_fcd(tmp_path / "fcd.xml")

    def test_not_xml_or_missing(self, tmp_path):
        (tmp_path / "broken.xml").write_text("<fcd-export><timestep time='0'>")
        with pytest.raises(TrackDataError, match="XML"):
            load_sumo_fcd(tmp_path / "broken.xml")
        with pytest.raises(TrackDataError, match="no such file"):
            load_highd(tmp_path / "nothing_tracks.csv")


# ---------------------------------------------------------------------------------- Tracks

class TestTracks:
    def test_validation_names_the_column(self):
        tb = simple()
        cols = dict(track_id=tb.track_id, t=tb.t, x=tb.x, v=tb.v, a=tb.a, lane=tb.lane)
        with pytest.raises(TrackDataError, match="column 'v'.*rows"):
            Tracks(**{**cols, "v": tb.v[:-1]}, dt=0.1, meta={})
        x = tb.x.copy()
        x[5] = np.nan
        with pytest.raises(TrackDataError, match="column 'x'.*NaN"):
            Tracks(**{**cols, "x": x}, dt=0.1, meta={})
        with pytest.raises(TrackDataError, match="column 'track_id'.*sorted"):
            Tracks(**{**cols, "track_id": tb.track_id[::-1]}, dt=0.1, meta={})
        t = tb.t.copy()
        t[3], t[4] = t[4], t[3]
        with pytest.raises(TrackDataError, match="column 't'.*increasing"):
            Tracks(**{**cols, "t": t}, dt=0.1, meta={})
        t = tb.t.copy()
        t[4:20] += 0.05
        with pytest.raises(TrackDataError, match="column 't'.*uniform"):
            Tracks(**{**cols, "t": t}, dt=0.1, meta={})
        with pytest.raises(TrackDataError, match="column 'dt'"):
            Tracks(**cols, dt=0.0, meta={})
        with pytest.raises(TrackDataError, match="column 'lane'.*integers"):
            Tracks(**{**cols, "lane": tb.lane + 0.5}, dt=0.1, meta={})

    def test_access(self):
        tb = simple()
        assert len(tb) == 60 and tb.n_tracks == 3
        assert tb.track_id.dtype == np.int64 and tb.lane.dtype == np.int64 and tb.x.dtype == np.float64
        np.testing.assert_array_equal(tb.ids(), [0, 1, 2])
        one = tb.track(1)
        assert len(one) == 20 and set(one.track_id) == {1}
        with pytest.raises(TrackDataError, match="no track"):
            tb.track(7)
        parts = list(tb.iter_tracks())
        assert [p[0] for p in parts] == [0, 1, 2]
        np.testing.assert_array_equal(parts[2][2], tb.x[40:])

    def test_save_load_round_trip(self, tmp_path):
        tb = simple(source="made up")
        path = tb.save(tmp_path / "t.npz")
        back = Tracks.load(path)
        for col in ("track_id", "t", "x", "v", "a", "lane"):
            np.testing.assert_allclose(getattr(back, col), getattr(tb, col), rtol=0, atol=1e-12)
            assert getattr(back, col).dtype == getattr(tb, col).dtype
        assert back.dt == tb.dt and back.meta == tb.meta
        np.testing.assert_array_equal(back.x, tb.x)  # exact without decimals
        # compact storage: rounded to the decimals, same bytes every time, atomic (no leftovers)
        tb.save(tmp_path / "c.npz", decimals=2)
        first = (tmp_path / "c.npz").read_bytes()
        tb.save(tmp_path / "c.npz", decimals=2)
        assert (tmp_path / "c.npz").read_bytes() == first
        compact = Tracks.load(tmp_path / "c.npz")
        np.testing.assert_allclose(compact.x, tb.x, atol=0.005 + 1e-12)
        assert sorted(os.listdir(tmp_path)) == ["c.npz", "t.npz"]
        umask = os.umask(0)
        os.umask(umask)
        assert (tmp_path / "t.npz").stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0600

    def test_load_bad_files(self, tmp_path):
        (tmp_path / "junk.npz").write_text("not a zip")
        with pytest.raises(TrackDataError, match="junk.npz"):
            Tracks.load(tmp_path / "junk.npz")
        np.savez_compressed(tmp_path / "other.npz", x=np.zeros(3))
        with pytest.raises(TrackDataError, match="column 'header'"):
            Tracks.load(tmp_path / "other.npz")
        with pytest.raises(TrackDataError, match="JSON"):
            simple(bad=object()).save(tmp_path / "m.npz")

    def test_resample(self):
        tb = simple(dt=0.1, n=21)
        down = tb.resample(0.2)
        assert down.dt == 0.2 and down.n_tracks == 3
        one = down.track(0)
        np.testing.assert_allclose(one.t, np.arange(11) * 0.2, atol=1e-12)
        np.testing.assert_allclose(one.v, 20 + 0.5 * one.t)  # linear in t: interpolation is exact
        np.testing.assert_array_equal(one.lane, np.where(one.t < 0.95, 1, 2))
        up = tb.resample(0.05).track(2)
        assert len(up) == 41
        np.testing.assert_allclose(up.v, 20 + 0.5 * up.t)
        # lane held from the latest sample at or before each new time (a category)
        np.testing.assert_array_equal(up.lane, np.where(up.t - up.t[0] < 0.95, 1, 2))
        assert down.meta["resampled"]["from_dt"] == 0.1

    def test_split_by_track(self):
        tb = simple(n_tracks=20, n=5)
        train, test = tb.split_by_track(0.25, seed=3)
        assert test.n_tracks == 5 and train.n_tracks == 15
        assert not set(train.ids()) & set(test.ids())
        assert len(train) + len(test) == len(tb)
        again = tb.split_by_track(0.25, seed=3)
        np.testing.assert_array_equal(again[1].ids(), test.ids())
        other = tb.split_by_track(0.25, seed=4)
        assert list(other[1].ids()) != list(test.ids())
        assert test.meta["split"] == {"test_fraction": 0.25, "seed": 3, "part": "test"}
        assert tb.split_by_track(0.01, seed=0)[1].n_tracks == 1  # at least one each side
        with pytest.raises(TrackDataError):
            tb.split_by_track(1.5)

    def test_concat(self):
        a, b = simple(n_tracks=2), simple(n_tracks=3)
        both = Tracks.concat([a, b])
        assert both.n_tracks == 5 and list(both.ids()) == [0, 1, 2, 3, 4]
        np.testing.assert_array_equal(both.track(2).x, b.track(0).x)
        with pytest.raises(TrackDataError, match="resample"):
            Tracks.concat([a, simple(dt=0.2)])


# ---------------------------------------------------------------------------------- shipped data

class TestShippedDataset:
    def test_loads_with_braking_acceleration_lane_changes(self):
        tb = load_shipped_dataset()
        assert tb.meta["format"] == "sumo-fcd" and "SUMO" in tb.meta["sumo_version"]
        assert tb.dt == pytest.approx(0.1)
        assert tb.n_tracks >= 300 and tb.duration > 3600 * 10
        assert np.any(tb.a < -1.0) and np.any(tb.a > 1.0)
        assert np.mean(tb.a < -1.0) > 0.01 and np.mean(tb.a > 1.0) > 0.01
        changes = sum(int(np.any(np.diff(lane) != 0)) for _, _, _, _, _, lane in tb.iter_tracks())
        assert changes >= 50
        assert np.all(tb.v >= 0)
        assert len(tb.meta["source_ids"]) == tb.n_tracks == len(tb.meta["track_types"])

    def test_provenance_json(self):
        data = resources.files("iamp.prediction").joinpath("data")
        npz = data.joinpath("sumo_highway.npz").read_bytes()
        info = json.loads(data.joinpath("sumo_highway.json").read_text())
        assert info["npz_sha256"] == hashlib.sha256(npz).hexdigest()
        assert len(npz) <= 3_100_000
        assert info["statistics"]["tracks"] == load_shipped_dataset().n_tracks
        for key in ("sumo_version", "seed", "step_length", "configuration", "command"):
            assert key in info


# ---------------------------------------------------------------------------------- with SUMO

@requires_sumo
def test_real_sumo_output_xml_equals_csv(tmp_path):
    """Run SUMO briefly on the shipped network; the XML and CSV FCD load identically."""
    sdir = REPO / "scripts" / "sumo"
    spec = importlib.util.spec_from_file_location("generate_dataset", sdir / "generate_dataset.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    subprocess.run([_sumo_binary("netconvert"), "-n", sdir / "highway.nod.xml", "-e", sdir / "highway.edg.xml",
                    "-x", sdir / "highway.con.xml", "-o", tmp_path / "net.xml", *gen.NETCONVERT_OPTIONS],
                   check=True, capture_output=True)
    for out in ("fcd.xml", "fcd.csv"):
        subprocess.run([_sumo_binary("sumo"), "-n", tmp_path / "net.xml", "-r", sdir / "highway.rou.xml",
                        "--step-length", "0.1", "--seed", "7", "--end", "40", "--fcd-output", tmp_path / out,
                        "--fcd-output.acceleration", "--no-step-log"], check=True, capture_output=True)
    xml = load_sumo_fcd(tmp_path / "fcd.xml", lengths={"car_calm": 4.6})
    csv = load_sumo_fcd(tmp_path / "fcd.csv", lengths={"car_calm": 4.6})
    assert xml.n_tracks >= 10
    for col in ("track_id", "t", "x", "v", "a", "lane"):
        np.testing.assert_array_equal(getattr(xml, col), getattr(csv, col))
    assert xml.meta["source_ids"] == csv.meta["source_ids"]
    # x (front bumper - length/2) advances with the speed: no jumps anywhere on the road
    for _, t, x, v, _, _ in xml.iter_tracks():
        if t.size > 1:
            np.testing.assert_allclose(np.diff(x) / xml.dt, v[1:], atol=0.11)  # 2-decimal output


@requires_sumo
def test_generation_script_is_deterministic(tmp_path):
    script = REPO / "scripts" / "sumo" / "generate_dataset.py"
    args = ["--end", "150", "--warmup", "30", "--min-track", "5"]
    shas = []
    for k in range(2):
        out = tmp_path / f"run{k}" / "small.npz"
        subprocess.run([sys.executable, script, *args, "--out", out], check=True, capture_output=True, timeout=120)
        info = json.loads(out.with_suffix(".json").read_text())
        assert info["npz_sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
        tb = Tracks.load(out)
        assert tb.n_tracks == info["statistics"]["tracks"] > 10 and tb.t.min() >= 30
        shas.append(info["npz_sha256"])
    assert shas[0] == shas[1]
