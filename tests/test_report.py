"""The reproduction report (``iamp reproduce``): tables compile, figures are drawn, and the
numbers in ``results.json`` are the planners' own.

One quick reproduction (small grids, few repetitions, the predictor evaluation without
model selection) is shared by the tests of this module.  Nothing here depends on timing.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from iamp.comparison.figures.style import save_figure
from iamp.comparison.figures.trajectory import lane_lines, plot_positions, plot_xy_snapshots
from iamp.comparison.metrics import manoeuvre_metrics, qualitative_comparison
from iamp.comparison.report.convergence import zoh_convergence
from iamp.comparison.report.reproduction import ReproduceConfig, reproduce
from iamp.comparison.report.tex import tex_escape
from iamp.planners.examples import paper_problem
from iamp.planners.pmp.planner import PMPPlanner

PDFLATEX = shutil.which("pdflatex")
needs_pdflatex = pytest.mark.skipif(PDFLATEX is None, reason="pdflatex is not installed")


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    calls: dict = {"progress": [], "status": []}
    res = reproduce(out, progress=lambda done, total: calls["progress"].append((done, total)),
                    status=calls["status"].append, quick=True)
    return out, res, calls


def _png_has_ink(path: Path) -> bool:
    """True if the PNG has a reasonable share of non-white pixels."""
    import matplotlib.image as mpimg

    img = mpimg.imread(str(path))
    rgb = img[..., :3]
    non_white = np.any(rgb < 0.95, axis=-1)
    return non_white.mean() > 0.01


def _compile(folder: Path, tex: str) -> subprocess.CompletedProcess:
    return subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", tex], cwd=str(folder),
                          capture_output=True, text=True, errors="replace", timeout=240)


# --- the quick reproduction ------------------------------------------------------------


def test_progress_is_reported_per_step(quick_report):
    """``progress(done, total)``: one total, ``done`` never goes back and ends at the total;
    ``status(message)`` names every step."""
    _, _, calls = quick_report
    prog, status = calls["progress"], calls["status"]
    assert prog, "the progress callback was never called"
    totals = {total for _, total in prog}
    assert len(totals) == 1
    done = [d for d, _ in prog]
    assert done == sorted(done) and done[0] == 0 and done[-1] == prog[0][1]
    assert len(status) >= 5 and all(isinstance(m, str) and m for m in status)
    assert prog[0][1] == 100 * len(status)  # hundredths of a step


def test_outputs_exist(quick_report):
    out, res, _ = quick_report
    for rel in ("report.tex", "results.json", "tables/scenarios.tex", "tables/results.tex", "tables/metrics.tex",
                "tables/agreement.tex", "timing/timing.tex", "tables/convergence.tex"):
        assert (out / rel).is_file(), rel
    for rel in res["outputs"]:
        assert (out / rel).is_file(), rel
    assert not list(out.rglob("*.tmp")), "a temporary file was left behind"


def test_figures_are_drawn(quick_report):
    out, _, _ = quick_report
    names = ["xy-paper-1", "xy-paper-2", "xy-paper-3", "pos-paper-1", "pos-paper-2", "pos-paper-3",
             "J-paper-1", "costates-paper-1", "xy-two-vehicle", "pos-two-vehicle", "costates-two-vehicle",
             "zoh-convergence", "timing"]
    for name in names:
        folder = out / ("timing" if name == "timing" else "figures")  # wall times: machine-dependent (issue 29)
        png, pdf = folder / f"{name}.png", folder / f"{name}.pdf"
        assert png.stat().st_size > 10_000, name
        assert pdf.stat().st_size > 5_000, name
        assert pdf.read_bytes()[:5] == b"%PDF-", name
        assert _png_has_ink(png), name


def test_report_tex_includes_every_table_and_figure(quick_report):
    out, _, _ = quick_report
    tex = (out / "report.tex").read_text()
    for t in (out / "tables").glob("*.tex"):
        assert f"tables/{t.name}" in tex, t.name
    for f in (out / "figures").glob("*.pdf"):
        assert f"figures/{f.name}" in tex, f.name


@needs_pdflatex
def test_generated_tables_compile(quick_report, tmp_path):
    """Every generated table compiles on its own in a minimal booktabs document."""
    out, _, _ = quick_report
    tables = sorted((out / "tables").glob("*.tex"))
    assert tables
    body = "\n".join(f"\\input{{{t.as_posix()}}}\n\\clearpage" for t in tables)
    doc = ("\\documentclass{article}\n\\usepackage[margin=2cm]{geometry}\n\\usepackage[T1]{fontenc}\n"
           "\\usepackage{lmodern}\n\\usepackage{textcomp}\n\\usepackage{amsmath}\n\\usepackage{booktabs}\n"
           "\\usepackage{graphicx}\n\\usepackage{float}\n\\begin{document}\n" + body + "\n\\end{document}\n")
    (tmp_path / "tables.tex").write_text(doc)
    proc = _compile(tmp_path, "tables.tex")
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert (tmp_path / "tables.pdf").stat().st_size > 1000


@needs_pdflatex
def test_report_compiles(quick_report):
    out, _, _ = quick_report
    from iamp.cli.report import compile_pdf

    ok, msg = compile_pdf(out)
    assert ok, msg
    pdf = out / "report.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert pdf.stat().st_size > 50_000
    assert not list(out.glob(".pdflatex-*")), "the build folder was not removed"


def test_results_json_matches_a_direct_plan(quick_report):
    """The PMP numbers in results.json are those of PMPPlanner().plan on the same problem."""
    out, _, _ = quick_report
    data = json.loads((out / "results.json").read_text())
    from iamp.prediction.resolve import load_problem

    for s in data["scenarios"]:
        _, problem, _ = load_problem(s["builtin"])
        # the identical polynomial reached the report
        assert [list(v.x_poly) for v in problem.vehicles] == [v["x_poly"] for v in s["vehicles"]]
        direct = PMPPlanner().plan(problem)
        pmp = next(r for r in s["runs"] if r["label"] == "pmp")
        assert pmp["status"] == "optimal"
        assert pmp["cost"] == pytest.approx(direct.cost, rel=1e-12)
        assert np.allclose(pmp["contact_times"], direct.contact_times, rtol=0, atol=1e-10)
        assert np.allclose(pmp["jumps"], direct.jumps, rtol=1e-9, atol=1e-9)
        # every QP run has a status, and a cost only when optimal
        for r in s["runs"]:
            assert (r["cost"] is not None) == (r["status"] == "optimal")


def test_results_json_foh_agrees_with_pmp(quick_report):
    out, _, _ = quick_report
    data = json.loads((out / "results.json").read_text())
    for s in data["scenarios"]:
        for a in s["agreement"]:
            if a["a"] == "pmp" and "-foh-" in a["b"] and "clarabel" in a["b"]:
                assert a["verdict"] == "agree", (s["name"], a["b"], a.get("reasons"))
                assert abs(a["at_same_contact_times"]["cost_rel_gap"]) < 1e-8


def test_results_json_zoh_convergence(quick_report):
    _, res, _ = quick_report
    conv = res["zoh_convergence"]
    assert set(conv) == {"paper-1", "paper-2", "paper-3"}
    for c in conv.values():
        gaps = [r["zoh_gap"] for r in c["rows"]]
        assert all(g > 0 for g in gaps)
        ratios = [r["ratio_to_next"] for r in c["rows"][:-1]]
        assert all(3.5 < q < 4.5 for q in ratios), ratios
        assert all(abs(r["foh_gap"]) < 1e-8 * r["J_pmp"] for r in c["rows"])


def test_qualitative_comparison_is_reported(quick_report):
    _, res, _ = quick_report
    q = res["qualitative"]
    assert set(q) == {"paper-2", "paper-3"}
    for v in q.values():
        assert v["n_measures"] == 7
        assert v["n_more_aggressive"] + v["n_more_conservative"] <= v["n_measures"]
        assert v["observed_majority"] in ("more aggressive", "more conservative", "mixed")


# --- the pieces ------------------------------------------------------------------------


def test_manoeuvre_metrics_are_consistent():
    problem = paper_problem(1)
    res = PMPPlanner().plan(problem)
    m = manoeuvre_metrics(res)
    assert m["J"] == pytest.approx(res.cost)
    assert m["J_x"] + m["J_y"] == pytest.approx(res.cost, rel=1e-5)
    assert m["t_contact"][0] == pytest.approx(res.contact_times[0])
    assert 0 < m["t_cross"] < problem.tf
    U = res.trajectory.inputs(np.linspace(0, problem.tf, 2001))
    assert m["peak_ay"] == pytest.approx(np.max(np.abs(U[:, 1])), rel=1e-3)


def test_qualitative_comparison_directions():
    base = {"t_contact": [3.0], "t_cross": 2.0, "peak_ay": 1.0, "peak_jerk_y": 1.0, "peak_ax": 1.0, "J": 10.0,
            "final_gap_to_corner": [2.0]}
    aggressive = {"t_contact": [2.0], "t_cross": 1.0, "peak_ay": 2.0, "peak_jerk_y": 2.0, "peak_ax": 2.0, "J": 20.0,
                  "final_gap_to_corner": [-1.0]}
    calm = {"t_contact": [4.0], "t_cross": 3.0, "peak_ay": 0.5, "peak_jerk_y": 0.5, "peak_ax": 0.5, "J": 5.0,
            "final_gap_to_corner": [9.0]}
    q = qualitative_comparison({"paper-1": base, "paper-2": aggressive, "paper-3": calm})
    assert q["paper-2"]["n_more_aggressive"] == 7 and q["paper-2"]["consistent_with_paper"]
    assert q["paper-3"]["n_more_conservative"] == 7 and q["paper-3"]["consistent_with_paper"]
    q = qualitative_comparison({"paper-1": base, "paper-2": calm, "paper-3": aggressive})
    assert not q["paper-2"]["consistent_with_paper"] and not q["paper-3"]["consistent_with_paper"]


def test_zoh_convergence_uses_a_common_node():
    c = zoh_convergence(paper_problem(2), steps=(25, 50))
    t = [r["t_node"] for r in c["rows"]]
    assert t[0] == pytest.approx(t[1], abs=1e-12)
    assert c["rows"][0]["node"] * 2 == c["rows"][1]["node"]


def test_tex_escape():
    assert tex_escape("a_b & 50% #1") == "a\\_b \\& 50\\% \\#1"
    assert "$\\Phi$" in tex_escape("Φ")
    assert all(ord(ch) < 128 for ch in tex_escape("t* ≤ h, ν→Φ, 漢"))


def test_lane_lines_between_lane_centres():
    edges, dividers = lane_lines(paper_problem(1))
    assert dividers == [pytest.approx((-2.0 + 3.75) / 2)]
    assert edges[0] < -2.0 and edges[1] > 3.75


def test_figure_writes_are_atomic_and_complete(tmp_path):
    res = PMPPlanner().plan(paper_problem(3))
    paths = plot_xy_snapshots(res, tmp_path / "xy")
    paths += plot_positions(res, tmp_path / "pos")
    assert sorted(p.name for p in paths) == ["pos.pdf", "pos.png", "xy.pdf", "xy.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pos.pdf", "pos.png", "xy.pdf", "xy.png"]
    for p in paths:
        assert p.stat().st_size > 5_000


def test_save_figure_keeps_the_old_file_on_failure(tmp_path):
    from matplotlib.figure import Figure

    target = tmp_path / "f.png"
    target.write_bytes(b"old")
    fig = Figure()
    fig.add_subplot(1, 1, 1).plot([0, 1], [0, 1])
    with pytest.raises(ValueError):
        save_figure(fig, tmp_path / "f", formats=("png", "no-such-format"))
    # the PNG was replaced completely; the failed format left neither a file nor a temporary
    assert target.read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png"]


def test_quick_config_is_smaller():
    q, full = ReproduceConfig.quick_config(), ReproduceConfig()
    assert q.quick and not full.quick
    assert q.steps_one < full.steps_one and q.steps_two < full.steps_two
    assert full.steps_one == 100 and full.zoh_steps == (25, 50, 100, 200, 400)
