"""Hostile CommonRoad input (SPEC §16, :mod:`iamp.commonroad.inputs`): every edit of a shared
US-101 scenario (or solution, or command line) that no plan can use is refused with exit status 2
and exactly one line on standard error naming the file and the element -- never a traceback, an
"internal error", a Python exception's text, a runaway horizon or a plan.  The unedited scenario
still plans (exit 0), once.

Needs the ``[commonroad]`` extra and the shared scenarios (``$IAMP_DATA/commonroad/US101``,
default ``<repo>/../shared/data``: conftest's ``data_path``); skips with the reason otherwise.
"""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import data_path, needs_commonroad_data

pytest.importorskip("commonroad", reason="the [commonroad] extra is not installed (pip install 'iamp[commonroad]')")
pytest.importorskip("commonroad_dc", reason="the [commonroad] extra is not installed (pip install 'iamp[commonroad]')")

from iamp.cli.main import main

DATA = data_path("commonroad", "US101")
SCENARIO = DATA / "USA_US101-11_1_T-1.xml"
pytestmark = needs_commonroad_data("commonroad", "US101")

PP = "planningProblem"
GOAL = f"{PP}.goalState"
TIME = f"{GOAL}[0].time"
INIT_V = f"{PP}.initialState.velocity"


def _scenario(tmp_path: Path, edit: Callable[[str], str] | None = None, name: str = "cr.xml") -> Path:
    """The shared scenario, its planning problem edited by ``edit``, written to ``tmp_path/name``."""
    if not SCENARIO.is_file():
        pytest.skip(f"the shared CommonRoad scenario is absent ({SCENARIO})")
    xml = SCENARIO.read_text()
    a = xml.index("<planningProblem ")
    b = xml.index("</planningProblem>") + len("</planningProblem>")
    pp = xml[a:b] if edit is None else edit(xml[a:b])
    out = tmp_path / name
    out.write_text(xml[:a] + pp + xml[b:])
    return out


def _sub(old: str, new: str) -> Callable[[str], str]:
    """An edit replacing the text ``old`` (whitespace between tags free) by ``new``, which must occur."""
    pattern = re.compile(r">\s*<".join(map(re.escape, old.split("><"))))

    def edit(pp: str) -> str:
        out, n = pattern.subn(new, pp, count=1)
        assert n == 1, f"{old!r} not in the planning problem"
        return out
    return edit


def _goal_body(new: str) -> Callable[[str], str]:
    """The goal state (tags included) replaced by ``new``."""
    return lambda pp: re.sub(r"<goalState>.*</goalState>", new, pp, count=1, flags=re.S)


def _refused(capsys: pytest.CaptureFixture[str], argv: list[str], *names: str) -> str:
    """``iamp ARGV`` exits 2 with one line on stderr holding every one of ``names``."""
    rc = main(argv)
    _, err = capsys.readouterr()
    lines = err.splitlines()
    assert rc == 2, err
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("iamp: error: "), line
    for name in names:
        assert name in line, (name, line)
    for bad in ("Traceback", "internal error", "NoneType", "object has no attribute", "object is not iterable",
                "min() arg"):
        assert bad not in line, line
    return line


def _plan(path: Path) -> list[str]:
    return ["commonroad", "plan", str(path), "--json"]


def test_the_valid_scenario_still_plans(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The unedited scenario, written as the edits are, plans and is valid (the one plan of this file)."""
    path = _scenario(tmp_path)
    rc = main(_plan(path))
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert json.loads(out)["commonroad"]["valid"] is True


@pytest.mark.parametrize("edit, field", [
    (_goal_body(""), f"'{GOAL}'"),  # no goal state at all (was: internal error, min() of nothing)
    (_goal_body("<goalState></goalState>"), f"'{GOAL}[0]'"),  # an empty goal state (was: 'NoneType' ... 'find')
    (_goal_body("<goalState/>"), f"'{GOAL}[0]'"),
    (_sub("<time><intervalStart>62</intervalStart><intervalEnd>72</intervalEnd></time>", ""), f"'{TIME}'"),
], ids=["no-goal-state", "empty-goal-state", "self-closed-goal-state", "goal-state-without-time"])
def test_a_missing_or_empty_goal_state_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                edit: Callable[[str], str], field: str) -> None:
    path = _scenario(tmp_path, edit)
    _refused(capsys, _plan(path), str(path), field)


@pytest.mark.parametrize("value", ["0", "-0.1", "nan", "inf", "abc"])
def test_an_invalid_time_step_size_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str) -> None:
    """``timeStepSize`` 0 divided by zero (internal error); negative, NaN, infinite or text too."""
    path = _scenario(tmp_path)
    path.write_text(path.read_text().replace('timeStepSize="0.1"', f'timeStepSize="{value}"', 1))
    _refused(capsys, _plan(path), str(path), "'commonRoad.timeStepSize'")


@pytest.mark.parametrize("value", ["1e9", "nan", "inf", "-1e9", "51"])
def test_an_absurd_initial_speed_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str) -> None:
    """1e9 m/s allocated 107 GiB for the road corridor; NaN was 'out of reach, needs inf m/s^2'
    (exit 3).  The bound is the vehicle type's speed range (type 2: [-13.9, 50.8] m/s)."""
    path = _scenario(tmp_path, _sub("<velocity><exact>16.6543</exact></velocity>",
                                    f"<velocity><exact>{value}</exact></velocity>"))
    line = _refused(capsys, _plan(path), str(path), f"'{INIT_V}'")
    if value not in ("nan", "inf"):
        assert "50.8" in line and "vehicle type 2" in line


@pytest.mark.parametrize("start, end", [(1000000, 1000010), (62, 1000000), (62, 20001)])
def test_a_goal_time_beyond_the_horizon_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], start: int,
                                                 end: int) -> None:
    """A goal a million steps ahead grew memory to 10 GB; iamp's horizon is at most 20000 steps and
    1000 s (``steps_max``, ``tf_max_s``)."""
    path = _scenario(tmp_path, _sub("<time><intervalStart>62</intervalStart><intervalEnd>72</intervalEnd></time>",
                                    f"<time><intervalStart>{start}</intervalStart><intervalEnd>{end}</intervalEnd>"
                                    "</time>"))
    line = _refused(capsys, _plan(path), str(path), f"'{TIME}'")
    assert "20000 steps" in line and "1000 s" in line


@pytest.mark.parametrize("length", ["-5", "0", "nan", "inf", "abc"])
def test_an_invalid_goal_rectangle_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], length: str) -> None:
    """A negative length was planned and judged 'optimal' (exit 0)."""
    path = _scenario(tmp_path, _sub("<length>2.2002</length>", f"<length>{length}</length>"))
    _refused(capsys, _plan(path), str(path), f"'{GOAL}[0].position.rectangle.length'")


def test_a_goal_interval_that_cannot_be_read_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Reversed, or NaN: commonroad-io's assertion text was the message; the element is named now."""
    path = _scenario(tmp_path, _sub("<intervalStart>62</intervalStart><intervalEnd>72</intervalEnd>",
                                    "<intervalStart>72</intervalStart><intervalEnd>62</intervalEnd>"))
    _refused(capsys, _plan(path), str(path), f"'{TIME}'", "exceeds")
    path = _scenario(tmp_path, _sub("<intervalStart>13.889</intervalStart>", "<intervalStart>nan</intervalStart>"))
    _refused(capsys, _plan(path), str(path), f"'{GOAL}[0].velocity'")


@pytest.mark.parametrize("edit", [
    lambda pp: re.sub(r"<planningProblem (id=\"\d+\")>.*</planningProblem>", r"<planningProblem \1></planningProblem>",
                      pp, flags=re.S),
    lambda pp: re.sub(r"<initialState>.*</initialState>", "", pp, flags=re.S),
], ids=["empty-planning-problem", "no-initial-state"])
def test_a_planning_problem_without_initial_state_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                           edit: Callable[[str], str]) -> None:
    """Was: ``not a readable CommonRoad scenario (TypeError: 'NoneType' object is not iterable)``."""
    path = _scenario(tmp_path, edit)
    _refused(capsys, _plan(path), str(path), f"'{PP}.initialState'", "missing")


SOLUTION_HEAD = '<?xml version="1.0" ?>\n<CommonRoadSolution benchmark_id="PM2:WX1:USA_US101-11_1_T-1:2020a">'
STATE = "<pmState><x>0.0</x><y>0.0</y><xVelocity>12.5</xVelocity><yVelocity>-10.9</yVelocity><time>0</time></pmState>"


@pytest.mark.parametrize("text, field", [
    ('<?xml version="1.0"?><CommonRoadSolution/>', "'CommonRoadSolution.benchmark_id'"),  # was: ... 'replace'
    (SOLUTION_HEAD.replace("PM2:WX1:", "") + "</CommonRoadSolution>", "'CommonRoadSolution.benchmark_id'"),
    (SOLUTION_HEAD + "</CommonRoadSolution>", "'CommonRoadSolution'"),
    (SOLUTION_HEAD + '<pmTrajectory planningProblem="125"/></CommonRoadSolution>', "'CommonRoadSolution.pmTrajectory'"),
    (SOLUTION_HEAD + f'<pmTrajectory planningProblem="125">{STATE.replace("<x>0.0</x>", "")}</pmTrajectory>'
     "</CommonRoadSolution>", "'CommonRoadSolution.pmTrajectory.pmState.x'"),
    (SOLUTION_HEAD + f'<pmTrajectory planningProblem="125">{STATE.replace("<time>0</time>", "<time>a</time>")}'
     "</pmTrajectory></CommonRoadSolution>", "'CommonRoadSolution.pmTrajectory.pmState.time'"),
], ids=["no-benchmark-id", "short-benchmark-id", "no-trajectory", "no-state", "state-without-x", "text-time"])
def test_a_bad_solution_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                                      field: str) -> None:
    scenario = _scenario(tmp_path)
    solution = tmp_path / "sol.xml"
    solution.write_text(text)
    _refused(capsys, ["commonroad", "check", str(scenario), str(solution), "--json"], str(solution), field)


def test_a_folder_is_named_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Was: ``adir: no such file``."""
    folder = tmp_path / "adir"
    folder.mkdir()
    _refused(capsys, _plan(folder), str(folder), "is a folder")
    _refused(capsys, ["commonroad", "check", str(_scenario(tmp_path)), str(folder)], str(folder), "is a folder")


@pytest.mark.parametrize("planners", ["", ",", "free,,avoid", " "])
def test_bench_refuses_an_empty_planner_name(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             planners: str) -> None:
    """``--planners free --planners ''`` wrote an empty bench and exited 0."""
    folder = tmp_path / "adir"
    folder.mkdir()
    _scenario(folder)
    out = tmp_path / "bout"
    _refused(capsys, ["commonroad", "bench", str(folder), "--out", str(out), "--planners", "free",
                      "--planners", planners], "--planners")
    assert not out.exists()


def test_bench_shows_no_progress_off_a_terminal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Standard error is not a terminal here: no progress line ("  x.xml free") before the refusal
    of the folder's invalid scenario, only the refusal (as every iamp command's progress)."""
    folder = tmp_path / "adir"
    folder.mkdir()
    path = _scenario(folder, name="x.xml")
    path.write_text(path.read_text().replace('timeStepSize="0.1"', 'timeStepSize="0"', 1))
    for json_flag in ([], ["--json"]):
        line = _refused(capsys, ["commonroad", "bench", str(folder), "--planners", "free", *json_flag],
                        str(path), "'commonRoad.timeStepSize'")
        assert "x.xml free" not in line


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_FSIZE and SIGXFSZ as on Linux")
def test_a_full_disk_after_the_plan_is_one_line_without_leak_lines(tmp_path: Path) -> None:
    """A disk that fills while the solution is written (simulated by a 2 kB file-size limit,
    ``RLIMIT_FSIZE``, with ``SIGXFSZ`` ignored: the write fails with ``EFBIG``) is one line naming
    the file, exit 2.  The plan's drivability-checker objects are freed before the interpreter
    exits: without that (``gc.collect`` on a failed command) nanobind printed one line per object
    still alive -- 431 lines for this scenario."""
    import resource
    import signal
    import subprocess

    scenario = _scenario(tmp_path)
    out = tmp_path / "sol.xml"

    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))

    r = subprocess.run([sys.executable, "-m", "iamp", "commonroad", "plan", str(scenario), "--out", str(out)],
                       preexec_fn=limited, capture_output=True, text=True, timeout=600)
    lines = r.stderr.splitlines()
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1, lines[:5]
    assert str(out) in lines[0] and "too large" in lines[0].lower()
    assert "leak" not in r.stderr
    assert not out.exists()
