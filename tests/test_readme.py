"""The README is a front door whose numbers come from the shipped code (issue 29 item 6, issue 31 item 5)."""

from __future__ import annotations

import re
from pathlib import Path

from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _script():  # type: ignore[no-untyped-def]
    return load_script("readme_results")


def test_the_readme_results_are_what_the_reports_say() -> None:
    """Regenerating the block from reports/ leaves the README unchanged (run the script after a reproduce)."""
    text = README.read_text(encoding="utf-8")
    assert _script().render(text) == text


def test_the_generated_table_reads_the_reports(tmp_path: Path) -> None:
    """Not vacuous: a changed cost in results.json changes the README block."""
    import json
    import shutil

    (tmp_path / "reports").mkdir()
    results = json.loads((ROOT / "reports" / "results.json").read_text(encoding="utf-8"))
    results["safety"][0]["runs"][0]["cost"] = 1234.5
    (tmp_path / "reports" / "results.json").write_text(json.dumps(results), encoding="utf-8")
    shutil.copytree(ROOT / "reports" / "campaign-new", tmp_path / "reports" / "campaign-new")
    block = _script().block(tmp_path)
    assert "| paper-1 | 1234.500 |" in block


def test_the_readme_is_a_front_door() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    # the two commands, and the test command is the one .ci/run runs
    assert "iamp reproduce" in text
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    command = re.search(r"pip install -e '\.\[test,sim,commonroad\]' && (python -m pytest [^\n`]+)", text)
    assert command is not None
    assert command.group(1).strip() in ci
    # no machine's absolute paths
    assert not re.search(r"(/work/|/tmp/|/root/|/home/)", text)


# -- added by mutation testing of scripts/readme_results.py (scripts/mutation_score.py, seed 3) ------------

import csv  # noqa: E402
import json  # noqa: E402

import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_episode = st.fixed_dictionaries({
    "planner": st.sampled_from(["pmp", "qp", "idm"]), "mission": st.sampled_from(["merge", "exit"]),
    "seed": st.integers(1, 3), "success": st.sampled_from(["True", "False"]),
    "contacts": st.sampled_from(["", "0", "1", "2", "7"]), "limit_violations": st.sampled_from(["", "0", "1", "3"])})


def _episodes_csv(root: Path, campaign: str, rows: list[dict[str, object]]) -> Path:
    """``rows`` written as ``root/reports/<campaign>/episodes.csv``."""
    path = root / "reports" / campaign / "episodes.csv"
    path.parent.mkdir(parents=True)
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return path


@settings(max_examples=40, deadline=None)
@given(st.lists(_episode, min_size=1, max_size=12))
def test_the_campaign_table_counts_the_episodes(tmp_path_factory: pytest.TempPathFactory,
                                                rows: list[dict[str, object]]) -> None:
    """Per planner: episodes; successes and their share; episodes with at least one contact (an empty
    field is none) and their share; episodes with at least one executed limit violation."""
    root = tmp_path_factory.mktemp("camp")
    path = _episodes_csv(root, "campaign-new", rows)
    lines = _script().campaign_table(path, root)
    missions = sorted({str(r["mission"]) for r in rows})
    seeds = len({r["seed"] for r in rows})
    # no manifest beside the episodes: the format is unknown and no note on it is made
    assert lines[0] == (f"Closed loop (`reports/campaign-new/episodes.csv`, episode format ?: missions "
                        f"{', '.join(missions)}; {seeds} paired seeds per density).")
    body = lines[4:]
    planners = sorted({str(r["planner"]) for r in rows})
    assert len(body) == len(planners)
    for planner, line in zip(planners, body):
        eps = [r for r in rows if r["planner"] == planner]
        n = len(eps)
        ok = sum(r["success"] == "True" for r in eps)
        contact = sum(str(r["contacts"]) not in ("", "0") for r in eps)
        limits = sum(str(r["limit_violations"]) not in ("", "0") for r in eps)
        assert line == (f"| {planner} | {n} | {ok} ({100 * ok / n:.1f} %) | {contact} ({100 * contact / n:.1f} %) | "
                        f"{limits} |")


def _results_with_a_scenario_missing(missing: str) -> dict[str, object]:
    results = json.loads((ROOT / "reports" / "results.json").read_text(encoding="utf-8"))
    s = results["safety"][0]
    s["runs"] = [r for r in s["runs"] if not str(r["label"]).startswith(missing)]
    return results


@pytest.mark.parametrize("missing", ["pmp", "qp-clarabel-foh", "qp-avoid-clarabel"])
def test_a_scenario_without_all_three_runs_is_left_out(missing: str) -> None:
    results = json.loads((ROOT / "reports" / "results.json").read_text(encoding="utf-8"))
    full = _script().reproduction_table(results)
    first = str(results["safety"][0]["name"])
    lines = _script().reproduction_table(_results_with_a_scenario_missing(missing))
    assert [ln for ln in full if not ln.startswith(f"| {first} |")] == lines
    assert len(lines) == len(full) - 1


def test_render_refuses_a_readme_without_both_markers() -> None:
    m = _script()
    for text in ("no block", f"a {m.BEGIN} b", f"a {m.END} b"):
        with pytest.raises(SystemExit, match="no <!-- results:begin -->"):
            m.render(text)


def test_check_exits_1_on_a_stale_readme_and_rewriting_fixes_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """``--check``: 0 when the block is what the reports say, 1 (and one line on stderr) when not; without
    ``--check`` the block is rewritten and the rest of the README kept."""
    m = _script()
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{m.BEGIN}\nstale\n{m.END}\noutro\n", encoding="utf-8")
    monkeypatch.setattr(m, "ROOT", tmp_path)  # the README read and written; render reads the reports
    assert m.main(["--check"]) == 1
    assert "differs" in capsys.readouterr().err
    assert m.main([]) == 0
    text = readme.read_text(encoding="utf-8")
    assert text == f"intro\n{m.BEGIN}\n{m.block()}\n{m.END}\noutro\n"  # the block from the repository's reports
    assert m.main(["--check"]) == 0
    assert readme.read_text(encoding="utf-8") == text
    with pytest.raises(SystemExit):
        m.main(["--help"])
    assert "The README's headline results, computed from what the shipped code wrote" in capsys.readouterr().out


def test_a_campaign_of_an_older_loop_says_so(tmp_path: Path) -> None:
    """The table names the campaign's episode format and says when the loop has changed since (SPEC §17)."""
    import json
    import shutil

    folder = tmp_path / "reports" / "campaign-new"
    shutil.copytree(ROOT / "reports" / "campaign-new", folder)
    for fmt, older in (("15.1", True), ("17.1", False)):
        manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
        manifest["episode_format"] = fmt
        (folder / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
        head = _script().campaign_table(folder / "episodes.csv", tmp_path)[0]
        assert f"episode format {fmt}" in head
        assert ("before SPEC §17's verified plans" in head) == older


@pytest.mark.parametrize(("fmt", "older"), [("16.9", True), ("17", False), ("17.0", False), ("?", False)])
def test_only_a_format_before_17_is_called_older(tmp_path: Path, fmt: str, older: bool) -> None:
    """The boundary: format 17 is SPEC §17's loop itself, not older; an unknown format makes no claim."""
    folder = tmp_path / "reports" / "campaign-new"
    folder.mkdir(parents=True)
    (folder / "episodes.csv").write_text("planner,mission,seed,success,contacts,limit_violations\n"
                                         "pmp,merge,1,True,0,0\n", encoding="utf-8")
    if fmt != "?":
        (folder / "manifest.json").write_text(json.dumps({"episode_format": fmt}), encoding="utf-8")
    head = _script().campaign_table(folder / "episodes.csv", tmp_path)[0]
    assert f"episode format {fmt}:" in head
    assert ("before SPEC §17's verified plans" in head) == older


_safe_episode = st.fixed_dictionaries({
    "planner": st.sampled_from(["free", "pmp-active", "sumo"]), "mission": st.sampled_from(["merge", "onramp"]),
    "traffic": st.sampled_from(["dense", "los-e"]), "seed": st.integers(1, 3),
    "success": st.sampled_from(["True", "False"]),
    "contacts_at_fault": st.sampled_from(["", "0", "1", "2"]), "contacts_not_at_fault": st.sampled_from(["", "0", "3"]),
    "follower_emergency_brakes": st.sampled_from(["", "0", "1"]),
    "follower_max_decel": st.sampled_from(["", "nan", "2.0", "4.5", "4.51", "4.6", "9.0"]),
    "rss_dangerous_s": st.sampled_from(["", "0.0", "0.1", "2.5"]), "limit_violations": st.sampled_from(["", "0", "2"])})


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(_safe_episode, min_size=1, max_size=12))
def test_the_safety_table_sums_the_responsibility_columns(tmp_path_factory: pytest.TempPathFactory,
                                                          rows: list[dict[str, object]]) -> None:
    """SPEC §17's table, per planner: successes, contacts at fault and not (summed), the follower's
    emergency brakes (summed), episodes whose new follower braked harder than 4.5 m/s² (4.5 itself is
    SUMO's normal hard braking, not counted), the RSS-dangerous time at fault (summed) and episodes
    with an executed limit violation; an empty or nan field is none."""
    root = tmp_path_factory.mktemp("safe")
    path = _episodes_csv(root, "campaign-safe", rows)
    (path.parent / "manifest.json").write_text(json.dumps({"episode_format": "17.2", "cooperation": "low",
                                                           "rss": {"response_time_s": 0.5}}), encoding="utf-8")
    lines = _script().safety_table([path], root)
    assert "episode format 17.2" in lines[0] and "cooperation low" in lines[0] and "response time 0.5 s" in lines[0]

    def num(v: object) -> float:
        return float(str(v)) if str(v) not in ("", "nan") else 0.0

    planners = sorted({str(r["planner"]) for r in rows})
    body = lines[4:]
    assert len(body) == len(planners)
    for planner, line in zip(planners, body):
        eps = [r for r in rows if r["planner"] == planner]
        n, ok = len(eps), sum(r["success"] == "True" for r in eps)
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[0] == planner and cells[1] == str(n) and cells[2] == f"{ok} ({100 * ok / n:.1f} %)"
        assert int(cells[3]) == sum(int(num(r["contacts_at_fault"])) for r in eps)
        assert int(cells[4]) == sum(int(num(r["contacts_not_at_fault"])) for r in eps)
        assert int(cells[5]) == sum(int(num(r["follower_emergency_brakes"])) for r in eps)
        assert int(cells[6]) == sum(num(r["follower_max_decel"]) > 4.5 + 1e-6 for r in eps)
        assert float(cells[7]) == pytest.approx(sum(num(r["rss_dangerous_s"]) for r in eps), abs=0.05)
        assert int(cells[8]) == sum(num(r["limit_violations"]) > 0 for r in eps)


def test_the_readme_shows_the_safe_campaigns_where_present(tmp_path: Path) -> None:
    """With reports/campaign-safe present the block shows SPEC §17's table, not the older campaign's."""
    import shutil

    (tmp_path / "reports").mkdir()
    shutil.copy(ROOT / "reports" / "results.json", tmp_path / "reports" / "results.json")
    shutil.copytree(ROOT / "reports" / "campaign-new", tmp_path / "reports" / "campaign-new")
    assert "Closed loop (`reports/campaign-new/episodes.csv`" in _script().block(tmp_path)
    safe = tmp_path / "reports" / "campaign-safe"
    safe.mkdir()
    (safe / "episodes.csv").write_text(
        "planner,mission,traffic,seed,success,contacts_at_fault,contacts_not_at_fault,follower_emergency_brakes,"
        "follower_max_decel,rss_dangerous_s,limit_violations\nfree,merge,dense,1,True,0,0,0,2.0,0.0,0\n",
        encoding="utf-8")
    text = _script().block(tmp_path)
    assert "Closed loop with verified plans (`reports/campaign-safe/episodes.csv`" in text
    assert "campaign-new" not in text


def test_the_sl2015_baseline_is_a_row_over_the_same_grid(tmp_path: Path) -> None:
    """``reports/campaign-sl2015`` adds a row ``sumo (SL2015)`` to the default-cooperation table, over
    the episodes whose (mission, traffic, seed) the campaign has; none to a low-cooperation table."""
    base = {"mission": "merge", "traffic": "dense", "success": "True", "contacts_at_fault": "0",
            "contacts_not_at_fault": "0", "follower_emergency_brakes": "0", "follower_max_decel": "",
            "rss_dangerous_s": "0", "limit_violations": "0"}
    path = _episodes_csv(tmp_path, "campaign-safe", [{**base, "planner": "free", "seed": 1}])
    sl = _episodes_csv(tmp_path, "campaign-sl2015", [{**base, "planner": "sumo", "seed": 1, "success": "False"},
                                                     {**base, "planner": "sumo", "seed": 2}])
    for coop, want in (("default", True), ("low", False)):
        (path.parent / "manifest.json").write_text(json.dumps({"cooperation": coop}), encoding="utf-8")
        lines = _script().safety_table([path], tmp_path, sl)
        rows = [ln for ln in lines if ln.startswith("| sumo (SL2015) |")]
        assert bool(rows) is want
        if want:
            assert rows[0].startswith("| sumo (SL2015) | 1 | 0 (0.0 %) |")


def test_the_table_states_the_command_that_makes_the_campaign(tmp_path: Path) -> None:
    """From the manifest (and the summary's reference): the grid, the cooperation, SL2015 and the folder."""
    folder = tmp_path / "reports" / "campaign-x"
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps({"reference": "free"}), encoding="utf-8")
    meta = {"missions": ["merge", "onramp"], "planners": ["free", "sumo"], "traffic": ["los-e"], "cooperation": "low",
            "sublane": True}
    assert _script().command(meta, folder, tmp_path, 7) == (
        "`iamp campaign --missions merge,onramp --planners free,sumo --traffic los-e --cooperation low --sublane "
        "--seeds 7 --reference free --out reports/campaign-x`")
