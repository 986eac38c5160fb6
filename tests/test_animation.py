"""Pictures that move (issue 31 item 4): ``iamp plot --animate``, ``--episode``, ``--commonroad``.

The frames must show what the plan is: the ego's body (its own size) at the plan's position and
heading at each frame's time, every vehicle at its prediction; the output is written atomically
and never replaces a file without ``--force``.
"""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from conftest import data_path, needs_data
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.patches import Rectangle
from PIL import Image

import iamp
from iamp.cli.main import main as cli_main
from iamp.comparison.figures.animation import frame_times, plan_frames


@settings(max_examples=60, deadline=None)
@given(duration=st.floats(0.1, 200.0), fps=st.floats(1.0, 60.0), speed=st.floats(0.1, 20.0),
       cap=st.integers(2, 500))
def test_frame_times_cover_the_span_evenly_within_the_cap(duration: float, fps: float, speed: float, cap: int) -> None:
    ts = frame_times(duration, fps, speed, cap)
    assert ts[0] == 0.0 and ts[-1] == pytest.approx(duration)
    assert 2 <= len(ts) <= cap
    assert np.allclose(np.diff(ts), ts[1] - ts[0])
    if len(ts) < cap:  # not thinned: one frame every speed/fps seconds of plan time
        assert ts[1] - ts[0] <= speed / fps * (1 + 1e-9) + 1e-12


def _bodies(ax: matplotlib.axes.Axes, zorder: int) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle) and p.get_zorder() == zorder]


@pytest.mark.parametrize("name", ["paper-1-poly", "paper-2", "two-vehicle"])
def test_each_frame_draws_the_ego_where_the_plan_is(name: str) -> None:
    plan = iamp.plan(iamp.load_scenario(name))
    prob = plan.problem
    ts = frame_times(prob.tf, 4.0)
    fig, draw = plan_frames(plan, ts)
    X = plan.states(ts)
    ax = fig.axes[0]
    for k in range(len(ts)):
        draw(k)
        (ego,) = _bodies(ax, 4)
        assert (ego.get_width(), ego.get_height()) == pytest.approx((prob.ego.ego_length, prob.ego.ego_width))
        # the rectangle's centre is the ego's centre, its angle the heading
        corners = ego.get_patch_transform().transform([(0, 0), (1, 0), (1, 1), (0, 1)])
        assert corners.mean(axis=0) == pytest.approx(X[k, [0, 2]], abs=1e-9)
        assert np.radians(ego.get_angle()) == pytest.approx(np.arctan2(X[k, 3], X[k, 1]), abs=1e-12)
        vehicles = _bodies(ax, 2)
        assert len(vehicles) == len(prob.vehicles)
        for v, body in zip(prob.vehicles, vehicles):
            assert body.get_x() + body.get_width() / 2 == pytest.approx(float(v.position(ts[k])))
            assert body.get_width() == pytest.approx(v.length)


def test_the_cli_writes_a_gif_and_refuses_to_replace_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan.gif"
    assert cli_main(["plot", "paper-1-poly", "--animate", "--out", str(out), "--fps", "4"]) == 0
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == len(frame_times(iamp.load_scenario("paper-1-poly").tf, 4.0))
    before = out.read_bytes()
    assert cli_main(["plot", "paper-1-poly", "--animate", "--out", str(out)]) == 2
    assert out.read_bytes() == before
    assert "--force" in capsys.readouterr().err
    assert not list(tmp_path.glob(".*tmp"))


@pytest.mark.parametrize(("argv", "says"), [
    (["plot", "paper-1", "--animate", "--out", "x.png"], ".gif, .mp4"),
    (["plot", "--out", "x.gif"], "exactly one of"),
    (["plot", "paper-1", "--episode", "log.csv", "--out", "x.gif"], "exactly one of"),
    (["plot", "--episode", "no-such-log.csv", "--out", "x.gif"], "no such file"),
    (["plot", "--commonroad", "s.xml", "--out", "x.gif"], "go together"),
    (["plot", "paper-1", "--animate", "--fps", "0", "--out", "x.gif"], "fps"),
])
def test_bad_animation_requests_are_one_line_exit_2(argv: list[str], says: str, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) if "--fps" in argv else _nothing():
        code = cli_main(argv)
        assert code == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not list(tmp_path.iterdir())


class _nothing:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _write_log(path: Path) -> None:
    """A two-vehicle step log in the format of ``iamp simulate --log``: the ego changes lane."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "vehicle", "x", "y", "vx", "vy", "ax", "ay", "lane", "length", "width", "mode",
                    "plan_time_s"])
        for k in range(51):
            t = 0.1 * k
            w.writerow([f"{t:.3f}", "ego", 20 * t, -1.875 + 3.75 * min(t / 5, 1), 20, 0.75, 0, 0, "", "", "",
                        "plan", ""])
            w.writerow([f"{t:.3f}", "v1", 30 + 18 * t, 1.875, 18, "", 0, "", 1, 12, 2.4, "", ""])
            w.writerow([f"{t:.3f}", "v2", -20 + 22 * t, -1.875, 22, "", 0, "", 0, 4.5, 1.8, "", ""])


def test_an_episode_log_animates_with_every_vehicle(tmp_path: Path) -> None:
    log = tmp_path / "ep.csv"
    _write_log(log)
    out = tmp_path / "ep.gif"
    assert cli_main(["plot", "--episode", str(log), "--out", str(out), "--fps", "5", "--speed", "1"]) == 0
    with Image.open(out) as im:
        assert im.n_frames == len(frame_times(5.0, 5.0, 1.0, 300))
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    assert cli_main(["plot", "--episode", str(bad), "--out", str(tmp_path / "b.gif")]) == 2


@needs_data("commonroad", "US101")
def test_a_commonroad_solution_animates(tmp_path: Path) -> None:
    pytest.importorskip("commonroad", reason="needs the [commonroad] extra")
    folder = data_path("commonroad", "US101")
    scenario = sorted(folder.glob("*.xml"))[0]
    solution = tmp_path / "sol.xml"
    assert cli_main(["commonroad", "plan", str(scenario), "--out", str(solution)]) == 0
    out = tmp_path / "cr.gif"
    assert cli_main(["plot", "--commonroad", str(scenario), "--solution", str(solution), "--out", str(out),
                     "--fps", "2"]) == 0
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames >= 2


# -- added by mutation testing (scripts/mutation_score.py compare/figures/animation.py --seed 3) -----------
# Fast: the frames are drawn without encoding a GIF (``_write`` is replaced by a capture).

import math  # noqa: E402

from iamp.comparison.figures import animation as anim_mod  # noqa: E402


@settings(max_examples=80, deadline=None)
@given(duration=st.floats(0.1, 200.0), fps=st.floats(1.0, 60.0), speed=st.floats(0.1, 20.0),
       cap=st.integers(2, 500))
def test_frame_times_has_one_frame_per_speed_over_fps_capped(duration: float, fps: float, speed: float,
                                                             cap: int) -> None:
    """The count is ceil(duration fps / speed) + 1 (at least 2), thinned to at most ``max_frames``."""
    ts = frame_times(duration, fps, speed, cap)
    want = min(max(math.ceil(duration * fps / speed - 1e-9) + 1, 2), cap)
    assert len(ts) == want


@pytest.mark.parametrize("args", [(0.0, 10.0, 1.0, 10), (1.0, 0.0, 1.0, 10), (1.0, 10.0, 0.0, 10),
                                  (1.0, 10.0, 1.0, 1), (-1.0, 10.0, 1.0, 10), (1.0, -5.0, 1.0, 10)])
def test_frame_times_refuses_a_non_positive_span_rate_speed_or_cap(args: tuple[float, float, float, int]) -> None:
    with pytest.raises(ValueError, match="must be > 0"):
        frame_times(*args)


def test_the_output_format_needs_ffmpeg_only_for_mp4(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(anim_mod.shutil, "which", lambda name: None)
    assert anim_mod.check_animation_path("a/b.GIF") == Path("a/b.GIF")  # a GIF never needs ffmpeg
    with pytest.raises(iamp.MissingDependencyError, match="ffmpeg"):
        anim_mod.check_animation_path("b.mp4")
    with pytest.raises(iamp.ScenarioError, match=r"\.gif, \.mp4"):
        anim_mod.check_animation_path("b.png")
    monkeypatch.setattr(anim_mod.shutil, "which", lambda name: "/usr/bin/ffmpeg")
    assert anim_mod.check_animation_path("b.mp4") == Path("b.mp4")


def test_the_log_reader_puts_every_value_at_its_step(tmp_path: Path) -> None:
    """Rows in any order: the steps are the sorted distinct times; each value lands at its vehicle and
    step; what a row leaves empty (or a vehicle not seen at a step) is nan."""
    log = tmp_path / "l.csv"
    log.write_text("t,vehicle,x,y,vx,vy,lane,length,width\n"
                   "0.2,ego,4,0.5,20,,,,\n"
                   "0.0,ego,0,0,20,0.1,,4.5,1.9\n"
                   "0.1,v7,30,3.5,18,,1,12,2.5\n"
                   "0.1,ego,2,0.25,20,0.2,,,\n")
    t, tracks = anim_mod._read_log(log)
    np.testing.assert_array_equal(t, [0.0, 0.1, 0.2])
    assert set(tracks) == {"ego", "v7"}
    np.testing.assert_array_equal(tracks["ego"]["x"], [0.0, 2.0, 4.0])
    np.testing.assert_array_equal(tracks["ego"]["y"], [0.0, 0.25, 0.5])
    np.testing.assert_array_equal(tracks["ego"]["vy"], [0.1, 0.2, np.nan])
    np.testing.assert_array_equal(tracks["ego"]["length"], [4.5, np.nan, np.nan])
    np.testing.assert_array_equal(tracks["v7"]["x"], [np.nan, 30.0, np.nan])
    np.testing.assert_array_equal(tracks["v7"]["lane"], [np.nan, 1.0, np.nan])
    np.testing.assert_array_equal(tracks["v7"]["width"], [np.nan, 2.5, np.nan])


def test_the_log_reader_refuses_in_one_line_naming_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "none.csv"
    with pytest.raises(iamp.ScenarioError, match=r"cannot be read \(No such file or directory\)") as e:
        anim_mod._read_log(missing, "--episode")
    assert str(missing) in str(e.value) and "--episode" in str(e.value)
    (tmp_path / "cols.csv").write_text("t,vehicle,x,y\n0,ego,0,0\n")
    with pytest.raises(iamp.ScenarioError, match="needs the columns t, vehicle, vx, x, y"):
        anim_mod._read_log(tmp_path / "cols.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(iamp.ScenarioError, match="is not an `iamp simulate --log` file"):
        anim_mod._read_log(tmp_path / "empty.csv")
    (tmp_path / "noego.csv").write_text("t,vehicle,x,y,vx\n0,v1,0,0,1\n")
    with pytest.raises(iamp.ScenarioError, match="has no ego rows"):
        anim_mod._read_log(tmp_path / "noego.csv")


def _captured(monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    got: dict[str, object] = {}

    def capture(fig: object, draw: object, frames: int, path: object, fps: float, dpi: float) -> Path:
        got.update(fig=fig, draw=draw, frames=frames)
        return Path(str(path))

    monkeypatch.setattr(anim_mod, "_write", capture)
    return got


def _hlines(ax: matplotlib.axes.Axes) -> tuple[list[float], list[float]]:
    """(edges, dividers): the y of the solid and of the dashed horizontal lines."""
    flat = [ln for ln in ax.lines if len(set(ln.get_ydata())) == 1 and ln.get_zorder() == 0]
    solid = sorted(float(ln.get_ydata()[0]) for ln in flat if ln.get_linestyle() == "-")
    dashed = sorted(float(ln.get_ydata()[0]) for ln in flat if ln.get_linestyle() != "-")
    return solid, dashed


def _shifted_log(path: Path, dy: float) -> None:
    """``_write_log``'s episode moved by ``dy`` across the road."""
    _write_log(path)
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        r["y"] = f"{float(r['y']) + dy!r}"
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def test_each_episode_frame_draws_the_log_to_scale(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The episode of ``_write_log`` moved 5 m to the left (lanes centred at 3.125 and 6.875 m; the ego
    starts in the right one): lane edges at the centres -/+ half a lane (3.75 m), one divider half-way;
    a window of ``window_m`` centred on the ego; each vehicle's body at its logged centre with its
    logged size; the ego with ``ego_size`` (the log has none) and its path up to the frame's step."""
    log = tmp_path / "ep.csv"
    dy = 5.0
    _shifted_log(log, dy)
    got = _captured(monkeypatch)
    anim_mod.animate_episode(log, tmp_path / "ep.gif", fps=5.0, speed=1.0, window_m=100.0, ego_size=(5.0, 2.0))
    assert got["frames"] == len(frame_times(5.0, 5.0, 1.0, 300)) == 26
    fig, draw = got["fig"], got["draw"]
    ax = fig.axes[0]  # type: ignore[attr-defined]
    for j in (0, 13, 25):
        draw(j)  # type: ignore[operator]
        k = 2 * j  # frames every 0.2 s, log every 0.1 s
        t = 0.1 * k
        xe, ye = 20 * t, dy - 1.875 + 3.75 * min(t / 5, 1)
        edges, dividers = _hlines(ax)
        assert edges == pytest.approx([dy - 3.75, dy + 3.75]) and dividers == pytest.approx([dy])
        assert ax.get_xlim() == pytest.approx((xe - 50.0, xe + 50.0))
        (ego,) = _bodies(ax, 4)
        assert (ego.get_width(), ego.get_height()) == pytest.approx((5.0, 2.0))
        corners = ego.get_patch_transform().transform([(0, 0), (1, 0), (1, 1), (0, 1)])
        assert corners.mean(axis=0) == pytest.approx([xe, ye], abs=1e-9)
        want = {(30 + 18 * t, dy + 1.875, 12.0, 2.4), (-20 + 22 * t, dy - 1.875, 4.5, 1.8)}
        drawn = {(b.get_x() + b.get_width() / 2, b.get_y() + b.get_height() / 2, b.get_width(), b.get_height())
                 for b in _bodies(ax, 2)}
        assert len(drawn) == 2
        for w, d in zip(sorted(want), sorted(drawn)):
            assert d == pytest.approx(w)
        (path,) = [ln for ln in ax.lines if ln.get_zorder() == 3]
        np.testing.assert_allclose(path.get_xdata(), [20 * 0.1 * i for i in range(k + 1)], atol=1e-9)


def test_a_plan_frame_shows_safety_boxes_and_each_contact_from_its_time_on() -> None:
    """Each vehicle's safety box is x_s(t) -/+ (L/2 + S_x) by y -/+ (W/2 + S_y); the contact star
    appears at the frame whose time is the contact time, not before."""
    plan = iamp.plan(iamp.load_scenario("two-vehicle"))
    tcs = sorted(float(t) for t in plan.contact_times)
    ts = np.array([0.0, tcs[0] - 1e-6, tcs[0], tcs[1], plan.problem.tf])
    fig, draw = plan_frames(plan, ts)
    ax = fig.axes[0]
    stars = []
    for k, t in enumerate(ts):
        draw(k)
        boxes = _bodies(ax, 1)
        assert len(boxes) == len(plan.problem.vehicles)
        for v, box in zip(plan.problem.vehicles, boxes):
            hx, hy = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
            assert (box.get_x(), box.get_y()) == pytest.approx((float(v.position(t)) - hx, v.y - hy))
            assert (box.get_width(), box.get_height()) == pytest.approx((2 * hx, 2 * hy))
        stars.append([ln for ln in ax.lines if ln.get_marker() == "*"])
    assert [len(s) for s in stars] == [0, 0, 1, 2, 2]
    X = plan.states(np.array(tcs))
    drawn = sorted((float(s.get_xdata()[0]), float(s.get_ydata()[0])) for s in stars[3])
    np.testing.assert_allclose(drawn, sorted((float(x[0]), float(x[2])) for x in X), atol=1e-9)


@needs_data("commonroad", "US101")
def test_a_commonroad_frame_shows_the_solution_s_path_up_to_its_step(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """``animate_commonroad`` with its defaults (fps 10 = one frame per 0.1 s step): one frame per
    solution step; the view is the ego's path widened by 40 m along x and 25 m along y, and the
    figure has its proportions; frame j draws the path of every state up to its step, inclusive."""
    pytest.importorskip("commonroad", reason="needs the [commonroad] extra")
    from commonroad.common.solution import CommonRoadSolutionReader

    scenario = sorted(data_path("commonroad", "US101").glob("*.xml"))[0]
    solution = tmp_path / "sol.xml"
    assert cli_main(["commonroad", "plan", str(scenario), "--out", str(solution)]) == 0
    states = CommonRoadSolutionReader.open(str(solution)).planning_problem_solutions[0].trajectory.state_list
    steps = [int(s.time_step) for s in states]
    xy = np.array([s.position for s in states])
    got = _captured(monkeypatch)
    anim_mod.animate_commonroad(scenario, solution, tmp_path / "cr.gif")
    assert got["frames"] == len(steps)  # dt = 0.1 s in these scenarios, fps 10
    fig, draw = got["fig"], got["draw"]
    window = (xy[:, 0].min() - 40.0, xy[:, 0].max() + 40.0, xy[:, 1].min() - 25.0, xy[:, 1].max() + 25.0)
    w, h = fig.get_size_inches()  # type: ignore[attr-defined]
    assert (w, h) == pytest.approx((10.0, max(3.0, 10.0 * (window[3] - window[2]) / (window[1] - window[0]) + 0.6)))
    ax = fig.axes[0]  # type: ignore[attr-defined]
    for j in (0, len(steps) // 2):
        draw(j)  # type: ignore[operator]
        assert ax.get_xlim() == pytest.approx(window[:2]) and ax.get_ylim() == pytest.approx(window[2:])
        (path,) = [ln for ln in ax.lines if ln.get_zorder() == 60]
        np.testing.assert_allclose(path.get_xdata(), xy[: j + 1, 0])
        np.testing.assert_allclose(path.get_ydata(), xy[: j + 1, 1])
        assert steps[j] - steps[0] == j
