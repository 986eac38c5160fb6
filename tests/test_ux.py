"""The everyday tool (issue 13): progress bars that stay silent when they must, ``-`` for standard
input, ``plan --csv``, ``iamp template``, ``scenarios --show``, ``iamp plot``, ``reproduce``
without LaTeX, shell completion, and the figure conventions (one palette, equal aspect,
units).

Each test checks what a user relies on, mostly numbers: the CSV's rows are the plan's
trajectory at ``t_k = k t_f / N``, the template plans to the paper's scenario-1 optimum, a
scenario piped in plans to the same cost as the file.
"""

from __future__ import annotations

import argparse
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from iamp.cli import progress as progress_mod
from iamp.cli.main import build_parser, main
from iamp.cli.scenarios import TEMPLATE
from iamp.core.scenario import builtin_names, builtin_text, load_scenario, loads_scenario

# --- helpers -----------------------------------------------------------------------------


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str], stdin: str | None = None,
             monkeypatch: pytest.MonkeyPatch | None = None) -> tuple[int, str, str]:
    """``iamp argv`` in-process: ``(exit status, stdout, stderr)``."""
    if stdin is not None:
        assert monkeypatch is not None
        monkeypatch.setattr(sys, "stdin", io.StringIO(stdin))
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def plan_json(argv: list[str], capsys: pytest.CaptureFixture[str], **kw: object) -> dict:
    code, out, err = run_main(["plan", *argv, "--json"], capsys, **kw)  # type: ignore[arg-type]
    assert code == 0, err
    return json.loads(out)


# --- progress ----------------------------------------------------------------------------


def test_progress_bar_draws_on_a_terminal_and_is_silent_otherwise(monkeypatch, capsys):
    monkeypatch.setattr(progress_mod, "_stderr_is_tty", lambda: True)
    with progress_mod.progress_bar(4, "work", enabled=True) as tick:
        for k in range(1, 5):
            tick(k, 4)
    assert "work" in capsys.readouterr().err  # a tqdm bar was drawn on the "terminal"
    with progress_mod.progress_bar(4, "work", enabled=False) as tick:  # --json / --quiet
        tick(2, 4)
        tick.describe("step")
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(progress_mod, "_stderr_is_tty", lambda: False)  # piped stderr
    with progress_mod.progress_bar(4, "work", enabled=True) as tick:
        tick(4, 4)
    assert capsys.readouterr().err == ""


def test_progress_enabled_and_accepts_progress():
    assert progress_mod.progress_enabled(argparse.Namespace())
    assert not progress_mod.progress_enabled(argparse.Namespace(json=True, quiet=False))
    assert not progress_mod.progress_enabled(argparse.Namespace(json=False, quiet=True))

    def with_progress(x: int, progress=None) -> int:
        if progress is not None:
            progress(1, 1)
        return x

    def without(x: int) -> int:
        return x

    assert progress_mod.accepts_progress(with_progress) and not progress_mod.accepts_progress(without)
    assert progress_mod.call_with_progress(without, 3, desc="d", enabled=False) == 3
    assert progress_mod.call_with_progress(with_progress, 5, desc="d", enabled=False) == 5


def test_qp_sweep_progress_is_silent_under_json_even_on_a_terminal(monkeypatch, capsys):
    """On a terminal the QP sweep draws a bar on stderr; with --json (or --quiet) stderr stays
    empty and stdout is exactly one JSON object."""
    monkeypatch.setattr(progress_mod, "_stderr_is_tty", lambda: True)
    from iamp.planners.qp.planner import QPPlanner

    for flag in ("--json", "--quiet"):
        code, _, err = run_main(["plan", "paper-1-poly", "--planner", "qp", "--steps", "20", flag], capsys)
        assert code == 0 and err == "", (flag, err)
    obj = json.loads(run_main(["plan", "paper-1-poly", "--planner", "qp", "--steps", "20", "--json"], capsys)[1])
    assert obj["status"] == "optimal"
    if progress_mod.accepts_progress(QPPlanner(steps=20).plan):
        code, _, err = run_main(["plan", "paper-1-poly", "--planner", "qp", "--steps", "20"], capsys)
        assert code == 0 and "QP sweep" in err  # the bar, when someone is watching


# --- standard input, CSV, template, --show ------------------------------------------------


def test_scenario_from_standard_input_plans_like_the_file(tmp_path, capsys, monkeypatch):
    text = builtin_text("two-vehicle")
    path = tmp_path / "two.toml"
    path.write_text(text, encoding="utf-8")
    from_file = plan_json([str(path)], capsys)
    from_stdin = plan_json(["-"], capsys, stdin=text, monkeypatch=monkeypatch)
    assert from_stdin["cost"] == pytest.approx(from_file["cost"], rel=1e-12)
    assert from_stdin["contact_times"] == pytest.approx(from_file["contact_times"], abs=1e-12)


def test_empty_standard_input_is_bad_input_naming_stdin(capsys, monkeypatch):
    code, out, err = run_main(["plan", "-"], capsys, stdin="", monkeypatch=monkeypatch)
    assert code == 2 and out == ""
    assert "<stdin>" in err and "ego" in err and "Traceback" not in err


@pytest.mark.parametrize("steps", [7, 40])
def test_csv_has_the_spec_columns_and_n_plus_1_rows(tmp_path, capsys, steps):
    csv = tmp_path / "traj.csv"
    obj = plan_json(["paper-2-poly", "--steps", str(steps), "--csv", str(csv)], capsys)
    lines = csv.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "t,x,y,vx,vy,ax,ay"
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    assert rows.shape == (steps + 1, 7)
    tf = obj["trajectory"]["t"][-1]
    np.testing.assert_allclose(rows[:, 0], np.linspace(0.0, tf, steps + 1), rtol=0, atol=1e-12)
    for k, key in enumerate(("t", "x", "y", "vx", "vy", "ax", "ay")):  # the JSON trajectory, to the last bit
        np.testing.assert_array_equal(rows[:, k], np.array(obj["trajectory"][key]))
    # the boundary conditions of the scenario are the first and last rows
    ego = load_scenario("paper-2-poly").ego
    np.testing.assert_allclose(rows[0, 1:5], [ego.x0, ego.y0, ego.vx0, ego.vy0], atol=1e-9)
    np.testing.assert_allclose(rows[-1, 1:5], [ego.xf, ego.yf, ego.vxf, ego.vyf], atol=1e-9)


def test_template_plans_as_it_is_to_the_paper_scenario_1_optimum(capsys, monkeypatch):
    code, out, _ = run_main(["template"], capsys)
    assert code == 0 and out == TEMPLATE
    assert sum(line.lstrip().startswith("#") for line in out.splitlines()) > 10  # it explains itself
    # without its [limits] table (a passenger car, SPEC §14) the template is the paper's scenario 1
    free = out[:out.index("[limits]")]
    obj = plan_json(["-"], capsys, stdin=free, monkeypatch=monkeypatch)
    ref = plan_json(["paper-1-poly"], capsys)
    assert obj["status"] == "optimal"
    assert obj["cost"] == pytest.approx(ref["cost"], rel=1e-12)  # same problem as the paper's scenario 1
    # as it is, the QP imposes the car's limits and plans within them
    obj = plan_json(["-", "--planner", "qp", "--steps", "40"], capsys, stdin=out, monkeypatch=monkeypatch)
    assert obj["status"] == "optimal" and all(v["ok"] for v in obj["limits"].values())
    assert obj["cost"] > ref["cost"]  # the bounds bind (a_x <= 3 m/s^2)
    # a planner that cannot impose every bound says so: never 'optimal' beyond a bound (exit 3)
    code, text, _ = run_main(["plan", "-", "--json"], capsys, stdin=out, monkeypatch=monkeypatch)
    pmp = json.loads(text)
    assert (code, pmp["status"]) in ((0, "optimal"), (3, "limits_violated"))
    if pmp["status"] == "optimal":
        assert all(v["ok"] for v in pmp["limits"].values())
    else:
        assert "beyond" in pmp["reason"] and any(not v["ok"] for v in pmp["limits"].values())


def test_template_history_alternative_is_valid_when_uncommented():
    text = TEMPLATE.replace("x_poly = [-15.0, 18.0, 0.0, 0.0]", "")
    for commented in ("[vehicles.history]", "t = [", "x = ["):
        text = text.replace("# " + commented, commented)
    sc = loads_scenario(text, "template-history")
    assert sc.needs_prediction and sc.vehicles[0].history is not None
    t, x = np.asarray(sc.vehicles[0].history.t), np.asarray(sc.vehicles[0].history.x)
    assert t[-1] == 0 and np.allclose(np.diff(x) / np.diff(t), 18.0)  # 18 m/s, as the x_poly it replaces


@pytest.mark.parametrize("name", builtin_names())
def test_scenarios_show_round_trips(name, capsys):
    code, out, _ = run_main(["scenarios", "--show", name], capsys)
    assert code == 0 and out == builtin_text(name)
    a, b = loads_scenario(out, "shown"), load_scenario(name)
    assert a.ego == b.ego and a.name == b.name
    for va, vb in zip(a.vehicles, b.vehicles, strict=True):
        assert (va.corner, va.y, va.length, va.width, va.x_poly) == (vb.corner, vb.y, vb.length, vb.width, vb.x_poly)


def test_scenarios_show_unknown_name_is_bad_input(capsys):
    code, out, err = run_main(["scenarios", "--show", "no-such"], capsys)
    assert code == 2 and out == "" and "--show" in err and "paper-1" in err


# --- iamp plot ----------------------------------------------------------------------------

MAGIC = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF-"}


@pytest.mark.parametrize("fmt", ["png", "svg", "pdf"])
def test_plot_writes_a_valid_file(tmp_path, capsys, fmt):
    out = tmp_path / f"plan.{fmt}"
    code, stdout, err = run_main(["plot", "two-vehicle", "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    data = out.read_bytes()
    if fmt == "svg":
        assert b"<svg" in data[:2000] and data.rstrip().endswith(b"</svg>")
    else:
        assert data.startswith(MAGIC[fmt])
    assert len(data) > 10_000
    assert "J = " in stdout and str(out) in stdout
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # atomic: no temporary left


def test_plot_refuses_an_unknown_format_before_planning(tmp_path, capsys):
    code, _, err = run_main(["plot", "paper-1-poly", "--out", str(tmp_path / "plan.jpeg")], capsys)
    assert code == 2 and "--out" in err
    assert not any(tmp_path.iterdir())


def test_plan_figure_is_to_scale_and_shows_the_contacts():
    from iamp.cli.plot import plan_figure
    from iamp.planners.pmp.planner import PMPPlanner

    plan = PMPPlanner().plan(load_scenario("two-vehicle").to_problem()[0])
    fig = plan_figure(plan)
    ax_xy = fig.axes[0]
    assert ax_xy.get_aspect() == 1.0  # equal aspect: a metre across = a metre along
    labels = [t.get_text() for t in ax_xy.get_legend().get_texts()]
    assert sum("contact" in s for s in labels) == 2
    for ax in fig.axes:  # every axis labelled, with a unit in brackets
        assert "[" in ax.get_xlabel() and "[" in ax.get_ylabel(), (ax.get_xlabel(), ax.get_ylabel())
    units = " ".join(ax.get_ylabel() for ax in fig.axes[1:])
    assert "m/s]" in units and "m/s$^2$" in units and "m/s$^3$" in units


def test_jerk_of_a_pmp_plan_is_piecewise_constant_with_a_jump_at_the_contact():
    from iamp.cli.plot import _jerk
    from iamp.planners.pmp.planner import PMPPlanner

    plan = PMPPlanner().plan(load_scenario("paper-1-poly").to_problem()[0])
    tt = np.linspace(0.0, plan.problem.tf, 2001)
    tj, J, impulsive = _jerk(plan, tt)
    assert not impulsive
    t1 = plan.contact_times[0]
    for side in (tj < t1 - 1e-2, tj > t1 + 1e-2):  # u is linear between contacts: constant jerk
        assert np.ptp(J[side], axis=0) == pytest.approx([0.0, 0.0], abs=1e-6)
    # u = −(p2, p4) and ṗ2 = −p1, ṗ4 = −p3, so the jerk is (p1, p3): it jumps by −Φ (p⁻ = p⁺ + Φ)
    jump = J[tj > t1 + 1e-2][0] - J[tj < t1 - 1e-2][-1]
    np.testing.assert_allclose(jump, -plan.jumps[0], rtol=1e-6, atol=1e-8)


# --- reproduce without LaTeX --------------------------------------------------------------


def test_reproduce_without_pdflatex_says_so_and_keeps_the_earlier_pdf(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report
    from iamp.core.outputs import write_marker

    out = tmp_path / "rep"
    out.mkdir()
    write_marker(out, "reproduce")  # the folder of an earlier run of iamp reproduce
    (out / "report.pdf").write_bytes(b"%PDF-1.5 stale, from an earlier run")

    def fake_reproduce(out_dir, progress=None, *, status=None, quick=False, config=None):
        (Path(out_dir) / "report.tex").write_text("\\documentclass{article}\\begin{document}x\\end{document}\n")
        if progress is not None:
            progress(0, 100)
            progress(100, 100)
        return {"outputs": ["report.tex"], "notes": [], "qualitative": {}}

    monkeypatch.setattr(report, "reproduce", fake_reproduce)
    empty_bin = tmp_path / "bin"
    empty_bin.mkdir()
    monkeypatch.setenv("PATH", str(empty_bin))  # no pdflatex anywhere
    assert shutil.which("pdflatex") is None
    code, stdout, err = run_main(["reproduce", "--out", str(out), "--quiet"], capsys)
    assert code == 0
    assert "cannot compile the PDF" in err and "pdflatex is not installed" in err
    assert "apt-get install texlive-latex-recommended texlive-latex-extra lmodern" in err
    # issue 22 item 1: never delete what cannot be rebuilt; say plainly that it is from an earlier run
    assert (out / "report.pdf").read_bytes() == b"%PDF-1.5 stale, from an earlier run"
    assert (out / "report.tex").is_file()
    assert "kept from an earlier run and does NOT match the new report.tex" in stdout


@pytest.mark.slow
def test_reproduce_quick_end_to_end_without_pdflatex(tmp_path):
    """The real command in a PATH without pdflatex (a minute: marked slow)."""
    import os

    from iamp.core.outputs import write_marker

    out = tmp_path / "rep"
    out.mkdir()
    write_marker(out, "reproduce")
    (out / "report.pdf").write_bytes(b"%PDF-1.5 stale")
    env = dict(os.environ, PATH=str(Path(sys.executable).parent))
    proc = subprocess.run([sys.executable, "-m", "iamp.cli", "reproduce", "--quick", "--out", str(out)],
                          capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "cannot compile the PDF" in proc.stderr
    assert (out / "report.pdf").read_bytes() == b"%PDF-1.5 stale" and (out / "report.tex").is_file()
    assert "does NOT match the new report.tex" in proc.stdout
    assert "\x1b[" not in proc.stderr and "\r" not in proc.stderr  # no bar: stderr is not a terminal


# --- shell completion ----------------------------------------------------------------------


def test_bash_completion_parses_and_knows_every_command(tmp_path, capsys):
    from iamp.cli.completion import describe_parser

    code, script, _ = run_main(["completion", "bash"], capsys)
    assert code == 0
    path = tmp_path / "iamp.bash"
    path.write_text(script)
    bash = shutil.which("bash")
    if bash is not None:
        assert subprocess.run([bash, "-n", str(path)], capture_output=True).returncode == 0
        # complete "iamp plan --planner " and "iamp pl"
        probe = (f"source {path}; COMP_WORDS=(iamp plan --planner ''); COMP_CWORD=3; _iamp; "
                 "echo \"${COMPREPLY[@]}\"; COMP_WORDS=(iamp pl); COMP_CWORD=1; _iamp; echo \"${COMPREPLY[@]}\"")
        lines = subprocess.run([bash, "-c", probe], capture_output=True, text=True).stdout.splitlines()
        assert lines[0].split() == ["pmp", "qp"]
        assert set(lines[1].split()) == {"plan", "plot"}
    _, commands = describe_parser(build_parser())
    for cmd in commands:
        assert f"        {cmd.name})" in script
        for opt in cmd.options:
            assert all(flag in script for flag in opt.flags)


def test_zsh_completion_parses(tmp_path, capsys):
    code, script, _ = run_main(["completion", "zsh"], capsys)
    assert code == 0 and script.startswith("#compdef iamp")
    zsh = shutil.which("zsh")
    if zsh is None:
        pytest.skip("zsh is not installed")
    path = tmp_path / "_iamp"
    path.write_text(script)
    assert subprocess.run([zsh, "-n", str(path)], capture_output=True).returncode == 0


# --- figure conventions ----------------------------------------------------------------------


def test_one_colour_per_planner_in_every_figure():
    from iamp.comparison.figures.style import PALETTE, planner_style

    labels = {"pmp": ["pmp", "PMP", "paper-1: PMP", "PMP plan (1 vehicle)"],
              "osqp": ["qp-osqp-foh-100", "osqp-zoh-20", "QP osqp solve, native, N=30 (2 vehicles)",
                       "paper-2: osqp-foh-100-refine"],
              "clarabel": ["qp-clarabel-foh-100", "clarabel-zoh-20", "QP clarabel solve, cvxpy, N=100 (1 vehicle)"]}
    for family, names in labels.items():
        assert {planner_style(n)["color"] for n in names} == {PALETTE[family]}
    assert len({PALETTE[k] for k in ("pmp", "clarabel", "osqp", "piqp", "kkt", "safety")}) == 6


def test_timing_table_states_the_pmp_once():
    from iamp.comparison.report.tables import table_timing

    timing = {"machine": {"python": "3.11", "cpu_count": 2, "load_average_1min": 1.0},
              "summary": {"QP clarabel solve, cvxpy, N=100 (1 vehicle)":
                          {"n": 5, "median": 2e-3, "q1": 1e-3, "q3": 3e-3}}}
    scen = [{"name": "paper-1", "runs": [{"label": "pmp", "time_s": {"n": 20, "median": 1e-4, "q1": 9e-5,
                                                                     "q3": 2e-4}}]}]
    tex = table_timing(timing, scen)
    rows = [line for line in tex.splitlines() if line.rstrip().endswith("\\\\") and "PMP" in line]
    assert len(rows) == 1 and "One measurement set" in tex  # one PMP row: the whole plan, timed once


def test_rounding_noise_is_not_drawn_as_a_signal():
    """A jerk that is constant up to 1e-13 gets a readable y-range, without offset notation."""
    from matplotlib.figure import Figure

    from iamp.comparison.figures.style import tidy_axis

    ax = Figure().add_subplot(1, 1, 1)
    y = 1.44 + 1e-13 * np.sin(np.arange(200.0))
    ax.plot(np.arange(200.0), y)
    tidy_axis(ax, y)
    lo, hi = ax.get_ylim()
    assert hi - lo >= 0.2 * 1.44 - 1e-12 and lo < 1.44 < hi
    ax2 = Figure().add_subplot(1, 1, 1)
    y2 = np.linspace(-3.0, 5.0, 50)  # a real signal keeps matplotlib's own limits
    ax2.plot(y2, y2)
    before = ax2.get_ylim()
    tidy_axis(ax2, y2)
    assert ax2.get_ylim() == before
