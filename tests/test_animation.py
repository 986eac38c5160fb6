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
