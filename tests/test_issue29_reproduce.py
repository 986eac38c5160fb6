"""Issue 29 items 14 and 15: ``iamp reproduce`` replaces its folder only when complete, and writes the
same bytes twice.

Item 14: the reproduction is written into a staging folder beside ``--out`` and exchanged with it
only when complete; Ctrl-C anywhere before leaves the old folder byte for byte, no staging folder,
one line ``iamp: interrupted`` and exit status 130.  Item 15: the deterministic writers (tables,
``results.json``, figures, ``report.tex``) give identical bytes when run twice, and the
machine-dependent numbers (wall times, the run time, versions) are only in ``timing/``.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.cli.main import main
from iamp.core.atomic import write_text
from iamp.core.outputs import guarded_folder

ROOT = Path(__file__).resolve().parents[1]


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``iamp argv`` in-process: ``(exit status, stdout, stderr)``."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (the lock file aside) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".iamp-lock"}


def _old_report(out: Path) -> dict[str, bytes]:
    """A folder of an earlier ``iamp reproduce`` with another command's outputs inside."""
    with guarded_folder(out, "reproduce"):
        write_text(out / "report.tex", "old report\n")
        write_text(out / "tables" / "results.tex", "old table\n")
        (out / "report.pdf").write_bytes(b"%PDF-1.5 old")
        write_text(out / "campaign-new" / "README.md", "the published campaign\n")
    return _tree(out)


def _fake_reproduce(interrupt: bool):  # type: ignore[no-untyped-def]
    def fake(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        write_text(Path(out_dir) / "report.tex", "new report\n")
        write_text(Path(out_dir) / "tables" / "results.tex", "new table\n")
        if interrupt:
            raise KeyboardInterrupt  # Ctrl-C half-way: two files new, the rest not yet
        write_text(Path(out_dir) / "figures" / "J.png", "new figure\n")
        return {"outputs": ["report.tex", "tables/results.tex", "figures/J.png"], "notes": [], "qualitative": {}}
    return fake


def test_item14_ctrl_c_midway_leaves_the_old_folder_and_one_line(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=True))
    code, stdout, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 130
    assert err == "iamp: interrupted\n" and stdout == ""
    assert _tree(out) == before  # not half old, half new
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]  # no staging folder left


def test_item14_a_complete_run_replaces_the_folder_and_keeps_other_outputs(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, stdout, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    after = _tree(out)
    assert after["report.tex"] == b"new report\n" and after["tables/results.tex"] == b"new table\n"
    assert after["figures/J.png"] == b"new figure\n"
    # what this run does not write stays: another command's folder, the earlier PDF (said so)
    assert after["campaign-new/README.md"] == before["campaign-new/README.md"]
    assert after["report.pdf"] == before["report.pdf"]
    assert after[".iamp-output"] == before[".iamp-output"]
    assert f"reproduction written to {out}/" in stdout and "iamp-staging" not in stdout + err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_item14_the_exchange_without_renameat2_also_completes(tmp_path, capsys, monkeypatch):
    import iamp.cli.report as cli_report
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    monkeypatch.setattr(cli_report, "_renameat2_exchange", lambda a, b: False)
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert (out / "report.tex").read_text() == "new report\n"
    assert (out / "campaign-new" / "README.md").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_item14_ownership_and_force_are_unchanged(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    papers = tmp_path / "papers"
    papers.mkdir()
    (papers / "mine.txt").write_text("the user's")
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(papers), "--no-pdf", "--quiet"], capsys)
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert sorted(p.name for p in papers.iterdir()) == ["mine.txt"]
    code, _, err = run_main(["reproduce", "--out", str(papers), "--no-pdf", "--quiet", "--force"], capsys)
    assert code == 0, err
    assert (papers / "mine.txt").read_text() == "the user's" and (papers / "report.tex").is_file()


def test_item14_a_symlinked_output_folder_stays_a_link(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    real = tmp_path / "real"
    _old_report(real)
    link = tmp_path / "reports"
    os.symlink(real, link)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(link), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert link.is_symlink() and (real / "report.tex").read_text() == "new report\n"


def test_item14_a_full_disk_names_the_output_not_the_staging_folder(tmp_path, capsys, monkeypatch):
    import errno

    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    real_fsync = os.fsync
    state = {"armed": False}

    def fake(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        state["armed"] = True
        write_text(Path(out_dir) / "tables" / "results.tex", "x")
        return {}

    def fsync(fd: int) -> None:
        if state["armed"]:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(report, "reproduce", fake)
    monkeypatch.setattr(os, "fsync", fsync)
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "No space left on device" in err
    assert str(out / "tables" / "results.tex") in err and "iamp-staging" not in err
    assert _tree(out) == before


_SLOW_REPRODUCE = """
import sys, time
from pathlib import Path
import iamp.comparison.report.reproduction as report
from iamp.core.atomic import write_text

def fake(out_dir, progress=None, *, status=None, quick=False, config=None):
    write_text(Path(out_dir) / "report.tex", "new report\\n")
    Path(sys.argv[2]).write_text("half-way")
    time.sleep(120)

report.reproduce = fake
from iamp.cli.main import main
sys.exit(main(["reproduce", "--out", sys.argv[1], "--no-pdf"]))
"""


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="needs process groups (POSIX)")
def test_item14_sigint_to_the_process_group_as_a_terminal_sends_it(tmp_path):
    """The real signal, sent to the whole process group as a terminal's Ctrl-C is."""
    out = tmp_path / "reports"
    before = _old_report(out)
    ready = tmp_path / "ready"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_REPRODUCE, str(out), str(ready)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while not ready.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert ready.exists(), proc.communicate(timeout=10)
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    assert stderr == "iamp: interrupted\n" and stdout == ""
    assert _tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ready", "reports"]


def test_item14_a_killed_runs_staging_folder_is_removed_by_the_next_run(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    _old_report(out)
    stale = tmp_path / ".reports.iamp-staging-abcd1234"
    (stale / "tables").mkdir(parents=True)
    (stale / "tables" / "results.tex").write_text("a SIGKILLed run's")
    other = tmp_path / ".other.iamp-staging-abcd1234"  # another folder's: not ours to delete
    other.mkdir()
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert not stale.exists() and other.exists()


def test_item14_the_small_campaigns_workers_ignore_ctrl_c(tmp_path, monkeypatch):
    """The workers get a preload that ignores SIGINT (a terminal sends it to the whole process group;
    each worker printed tornado/asyncio tracebacks)."""
    pytest.importorskip("dask")
    pytest.importorskip("distributed")
    import dask

    import iamp.comparison.report.campaign as campaign
    import iamp.simulation.campaign as sim_campaign
    import iamp.simulation.network as network

    seen: dict[str, object] = {}

    def fake_run_campaign(*args, **kwargs):  # type: ignore[no-untyped-def]
        seen["preload"] = list(dask.config.get("distributed.worker.preload", default=[]))
        raise KeyboardInterrupt

    monkeypatch.setattr(sim_campaign, "run_campaign", fake_run_campaign)
    monkeypatch.setattr(network, "require_sumo", lambda: None)
    (tmp_path / "tables").mkdir()
    with pytest.raises(KeyboardInterrupt):
        campaign.campaign_section(tmp_path, quick=True)
    assert campaign.PRELOAD in seen["preload"]  # type: ignore[operator]
    assert campaign.PRELOAD not in (dask.config.get("distributed.worker.preload", default=[]) or [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tables"]  # its temporary folder removed
    # the preload, in a process of its own: SIGINT no longer raises KeyboardInterrupt
    code = ("import os, signal, time\n"
            "from iamp.comparison.report.campaign import dask_setup\n"
            "dask_setup(None)\n"
            "os.kill(os.getpid(), signal.SIGINT)\n"
            "time.sleep(0.2)\n"
            "print('still running')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0 and proc.stdout == "still running\n", proc.stderr


_CAMPAIGN_SECTION = """
import sys
from pathlib import Path
if __name__ == "__main__":
    from iamp.comparison.report.campaign import campaign_section
    def progress(done, total):
        Path(sys.argv[2]).write_text(str(done))
    try:
        campaign_section(Path(sys.argv[1]), quick=True, progress=progress)
    except KeyboardInterrupt:
        sys.stderr.write("iamp: interrupted\\n")
        sys.exit(130)
"""


@pytest.mark.slow
def test_item14_ctrl_c_during_the_real_small_campaign_prints_no_library_traceback(tmp_path):
    """The real small campaign (SUMO, a Dask cluster of 2 worker processes), SIGINT to the process
    group while episodes run: one line, no traceback from any library (about a minute)."""
    pytest.importorskip("distributed")
    from iamp.core.errors import MissingDependencyError
    from iamp.simulation.network import require_sumo

    try:
        require_sumo()
    except MissingDependencyError as exc:
        pytest.skip(str(exc))
    script = tmp_path / "section.py"
    script.write_text(_CAMPAIGN_SECTION)
    out, ready = tmp_path / "out", tmp_path / "ready"
    (out / "tables").mkdir(parents=True)
    proc = subprocess.Popen([sys.executable, str(script), str(out), str(ready)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, cwd=str(tmp_path),
                            env={**os.environ, "PYTHONPATH": str(ROOT)},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not ready.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        # the workers are in their episodes once one has finished: interrupt then (a fixed sleep of
        # 20 s outlived the whole campaign once the loop got faster)
        while time.monotonic() < deadline and proc.poll() is None and not (
                ready.exists() and ready.read_text().strip() not in ("", "0")):
            time.sleep(0.05)
        assert proc.poll() is None, "the campaign ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr[-3000:]
    assert stderr == "iamp: interrupted\n", stderr[-3000:]


# --- item 15: the same bytes twice; the machine-dependent numbers apart ------------------------------------


def _results(times: list[float], load: float) -> dict:  # type: ignore[type-arg]
    """A results dictionary shaped like ``iamp reproduce``'s, with wall times ``times``."""
    return {"produced_by": "iamp.comparison.report.reproduce", "config": {"steps_one": 100, "plan_budget_s": 4.0},
            "versions": {"python": "3.11.7", "numpy": "2.4.6"}, "runtime_s": times[0] * 100,
            "scenarios": [{"name": "paper-1", "runs": [
                {"label": "pmp", "cost": 12.38708127134567, "contact_times": [3.4029],
                 "time_s": {"n": 20, "median": times[1], "q1": times[2], "q3": times[3]}, "solve_time_s": times[4]},
                {"label": "qp-osqp-foh-100", "cost": 12.387081271345671, "time_s": {"n": 3, "median": times[5]}}],
                "agreement": [{"a": "pmp", "b": "qp-osqp-foh-100", "cost_rel_gap": 1.1e-05}]}],
            "timing": {"samples": {"QP osqp": times}, "machine": {"load_average_1min": load}},
            "bounded": [{"scenario": "paper-1", "planner": "pmp", "status": "optimal", "time_s": times[6]}],
            "campaign": {"available": True, "ran": {"ran": 18, "seconds": times[7]},
                         "summary": [{"mission": "merge", "traffic": "medium", "planner": "pmp", "episodes": 3,
                                      "success_episodes": 2, "plan_time_p50_s_median": times[8],
                                      "wall_s_median": times[9], "time_to_merge_s_median": 4.25}]},
            "predictor": {"how": "reused", "seconds": times[10]}}


@settings(max_examples=25, deadline=None)
@given(a=st.lists(st.floats(1e-6, 1e3), min_size=11, max_size=11),
       b=st.lists(st.floats(1e-6, 1e3), min_size=11, max_size=11), load=st.floats(0, 10))
def test_item15_results_json_is_the_same_bytes_whatever_the_wall_times(a, b, load):
    from iamp.comparison.report.machine import canonical_json, split_machine

    kept_a, machine_a = split_machine(_results(a, load))
    kept_b, _ = split_machine(_results(b, 0.0))
    assert canonical_json(kept_a) == canonical_json(kept_b)
    text = canonical_json(kept_a)
    for key in ('"time_s"', '"solve_time_s"', '"seconds"', '"runtime_s"', '"versions"', '"timing"',
                '"plan_time_p50_s_median"', '"wall_s_median"'):
        assert key not in text
    assert '"time_to_merge_s_median": 4.25' in text  # a simulated time is a result, not a wall time
    # every wall time is kept, under the path it came from
    assert machine_a["scenarios/paper-1/runs/pmp/time_s"]["median"] == a[1]
    assert machine_a["scenarios/paper-1/runs/pmp/solve_time_s"] == a[4]
    assert machine_a["bounded/paper-1:pmp/time_s"] == a[6]
    assert machine_a["campaign/summary/merge:medium:pmp/plan_time_p50_s_median"] == a[8]
    assert machine_a["runtime_s"] == a[0] * 100 and machine_a["versions"]["numpy"] == "2.4.6"


def test_item15_canonical_json_is_exact_and_sorted():
    import json

    from iamp.comparison.report.machine import canonical_json

    x = 12.38708127134567
    text = canonical_json({"b": x, "a": [x * (1 + 2e-16), -0.0]})
    assert json.loads(text) == {"a": [x * (1 + 2e-16), 0.0], "b": x}  # the planners' own numbers
    assert text.index('"a"') < text.index('"b"') and "-0.0" not in text
    assert canonical_json({"a": float("nan")}) == '{\n "a": null\n}\n'  # a missing number


def test_item15_round_off_is_shown_as_a_bound_in_the_agreement_table():
    from iamp.comparison.report.tables import table_agreement
    from iamp.comparison.report.tex import tex_sci

    def scen(gap: float) -> list:  # type: ignore[type-arg]
        same = {"cost_rel_gap": gap, "state_sup_gap": 3 * gap, "jump_gap": -gap,
                "contact_time_gap_to_grid_optimum": 0.0}
        return [{"name": "paper-1", "agreement": [{"a": "pmp", "b": "qp-clarabel-foh-100", "verdict": "agree",
                                                   "at_same_contact_times": same, "cost_rel_gap": 1.1e-5,
                                                   "contact_time_gap": 4.5e-3}]}]

    # two machines' round-off (issue 29: 1.2e-14 in the committed table, 7.9e-15 in a clone)
    assert table_agreement(scen(1.2e-14)) == table_agreement(scen(7.9e-15))
    assert "$<10^{-11}$" in table_agreement(scen(7.9e-15))
    assert tex_sci(3.2e-9, floor=1e-11) == "$3.2\\times10^{-9}$"  # above the bound: the number


def test_item15_figures_are_the_same_bytes_twice_and_carry_no_date_or_version(tmp_path):
    import matplotlib

    from iamp.comparison.figures.studies import plot_timing, plot_zoh_convergence
    from iamp.comparison.figures.trajectory import plot_positions
    from iamp.planners.examples import paper_problem
    from iamp.planners.pmp.planner import PMPPlanner

    plan = PMPPlanner().plan(paper_problem(1))
    files = {}
    for run in ("a", "b"):
        d = tmp_path / run
        paths = plot_positions(plan, d / "pos")
        paths += plot_zoh_convergence({"paper-1": ([0.2, 0.1, 0.05], [0.12, 0.03, 0.0076])}, d / "zoh")
        paths += plot_timing({"QP clarabel solve, cvxpy": [1e-3, 2e-3, 1.5e-3]}, d / "timing")
        files[run] = {p.name: p.read_bytes() for p in paths}
        time.sleep(1.1)  # a date with seconds in it would differ
    assert files["a"] == files["b"]
    version = matplotlib.__version__.encode()
    for name, data in files["a"].items():
        assert version not in data and b"Matplotlib" not in data, name
        assert b"CreationDate" not in data, name


def test_item15_the_timing_figure_prints_at_the_text_width_without_shrinking(tmp_path):
    """Issue 29 item 17: Figure 18 was 14 in wide at the text width (17 cm): 8 pt labels printed at ~3.5 pt."""
    import matplotlib.image as mpimg

    from iamp.comparison.figures.studies import plot_timing
    from iamp.comparison.figures.style import DPI

    samples = {f"QP {s} solve, {p}, N=100 (1 vehicle)": [1e-3, 2e-3, 1.5e-3] for s in ("clarabel", "osqp")
               for p in ("cvxpy", "native")}
    plans = {f"paper-1: {k}": {"n": 3, "median": 0.1, "q1": 0.09, "q3": 0.12, "min": 0.08, "max": 0.13}
             for k in ("PMP", "clarabel-foh-100", "osqp-foh-100")}
    png = next(p for p in plot_timing(samples, tmp_path / "timing", whole_plans=plans) if p.suffix == ".png")
    width_in = mpimg.imread(str(png)).shape[1] / DPI
    text_width_in = 17.0 / 2.54  # A4 with 2 cm margins
    assert width_in <= 1.1 * text_width_in  # printed at >= 90 % of its size: 8 pt labels stay >= 7 pt


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex is not installed")
def test_item15_pdflatex_writes_the_same_pdf_twice(tmp_path):
    from iamp.cli.report import compile_pdf

    (tmp_path / "report.tex").write_text("\\documentclass{article}\\ifdefined\\pdftrailerid\\pdftrailerid{}\\fi"
                                         "\\begin{document}Same bytes.\\end{document}\n")
    pdfs = []
    for _ in range(2):
        ok, msg = compile_pdf(tmp_path, runs=1)
        assert ok, msg
        pdfs.append((tmp_path / "report.pdf").read_bytes())
        time.sleep(1.1)
    assert pdfs[0] == pdfs[1]


def test_item15_the_campaign_table_has_no_wall_time_column():
    from iamp.comparison.report.campaign import without_columns

    table = ("\\begin{tabular}{llrr}\n\\toprule\nmission & planner & success & plan $p_{50}$ [ms] \\\\\n\\midrule\n"
             "merge & pmp & 3/3 & 0.69 \\\\\nmerge & free & 2/3 & 0.11 \\\\\n\\bottomrule\n\\end{tabular}\n")
    assert without_columns(table, (0, -1)) == ("\\begin{tabular}{lr}\n\\toprule\nplanner & success \\\\\n"
                                               "\\midrule\npmp & 3/3 \\\\\nfree & 2/3 \\\\\n\\bottomrule\n"
                                               "\\end{tabular}\n")


# --- item 17: what the reader sees ------------------------------------------------------------------------------


def test_item17_the_bounded_table_prints_its_words_once_escaped_and_no_negative_zero():
    from iamp.comparison.bounded import BoundedRow
    from iamp.comparison.report.bounded import latex_table

    rows = [BoundedRow(scenario="paper-3", planner="avoid", available=True, status="optimal", cost=6.387 - 1e-9,
                       free_cost=6.387),
            BoundedRow(scenario="paper-1", planner="pmp", available=True, status="limits_violated")]
    tex = latex_table(rows)
    assert "-0.00" not in tex and "+0.00\\,\\%" in tex
    assert "textbackslash" not in tex and "limits\\_violated" in tex


def test_item17_the_report_ends_on_conclusions_drawn_from_the_numbers():
    from iamp.comparison.report.document import conclusions_tex

    same = {"cost_rel_gap": 7.9e-15}
    res = {"scenarios": [
        {"name": "paper-1", "metrics": {"inside_safety_box": [[]], "body_overlap": [[]]},
         "agreement": [{"a": "pmp", "b": "qp-clarabel-foh-100", "verdict": "agree", "at_same_contact_times": same},
                       {"a": "pmp", "b": "qp-osqp-foh-100", "verdict": "disagree", "at_same_contact_times": same}]},
        {"name": "paper-2", "metrics": {"inside_safety_box": [[[1.95, 4.06]]], "body_overlap": [[[2.3, 3.6]]]},
         "agreement": []}],
        "zoh_convergence": {"paper-1": {"loglog_slope": 2.0021}},
        "qualitative": {"paper-3": {"paper_claim": "more conservative", "observed_majority": "more aggressive",
                                    "consistent_with_paper": False}},
        "bounded": [{"scenario": "paper-1", "planner": "active", "status": "optimal"},
                    {"scenario": "paper-2", "planner": "pmp", "status": "infeasible"}],
        "campaign": {"available": True, "summary": [{"planner": "pmp-active", "success_episodes": 2, "episodes": 3}]}}
    tex = conclusions_tex(res)  # type: ignore[arg-type]
    assert tex.startswith("\\section{Conclusions}")
    assert "agree}} in 1 of 2 comparisons" in tex.replace("\\textbf{PMP and the first-order-hold QP agree}", "agree}}")
    assert "$<10^{-11}$" in tex and "2.00" in tex and "\\textbf{not} consistent" in tex
    assert "paper-2 (the bodies overlap)" in tex and "paper-1 (the bodies" not in tex
    assert "1 of 2 scenario--planner pairs find an optimal plan" in tex and "1 is certified infeasible" in tex
    assert "pmp-active 2/3" in tex


def test_item14_what_another_command_writes_during_the_run_survives_the_exchange(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    _old_report(out)

    def fake(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        write_text(Path(out_dir) / "report.tex", "new report\n")
        # meanwhile another command writes into its own folder inside --out (the real one)
        write_text(out / "campaign-new" / "README.md", "the published campaign, updated\n")
        write_text(out / "campaign-new" / "episodes.csv", "seed\n1\n")
        write_text(out / "report.tex", "someone's edit, overwritten by the reproduction\n")
        return {"outputs": ["report.tex"], "notes": [], "qualitative": {}}

    monkeypatch.setattr(report, "reproduce", fake)
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert (out / "campaign-new" / "README.md").read_text() == "the published campaign, updated\n"
    assert (out / "campaign-new" / "episodes.csv").read_text() == "seed\n1\n"
    assert (out / "report.tex").read_text() == "new report\n"  # the reproduction's own output wins


def test_item14_a_subfolder_another_run_is_writing_is_refused(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report
    from iamp.core.outputs import output_lock

    out = tmp_path / "reports"
    before = _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    with output_lock(out / "campaign-new"):  # iamp campaign --out reports/campaign-new, running
        code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "campaign-new" in err and "another iamp run" in err
    after = _tree(out)
    after.pop("campaign-new/.iamp-lock", None)
    assert after == before


def test_the_workers_preload_leaves_the_dask_configuration_whole() -> None:
    """The preload's block (``_workers_ignore_ctrl_c``) sets one key of ``distributed``'s
    configuration; run before ``distributed`` was imported, the import inside the block merged
    its defaults under that key and the block's exit removed them all, so every later Dask cluster
    of the process failed (``KeyError: 'distributed'``: a test starting a ``LocalCluster`` after
    the reproduction's campaign, in the same worker).  In a fresh interpreter: the configuration
    after the block is the one before it."""
    pytest.importorskip("distributed")
    code = ("import dask\n"
            "from iamp.comparison.report.campaign import PRELOAD, _workers_ignore_ctrl_c\n"
            "with _workers_ignore_ctrl_c():\n"
            "    import distributed\n"
            "    assert PRELOAD in dask.config.get('distributed.worker.preload')\n"
            "assert dask.config.get('distributed.comm.require-encryption', default='missing') != 'missing'\n"
            "assert PRELOAD not in (dask.config.get('distributed.worker.preload') or [])\n"
            "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
