"""The bench table of issue 32 is written from ``iamp bench --json`` (scripts/bench_table.py).

* the committed docs/bench.md and README block are what reports/bench.json says;
* every table has the header's number of columns in every row, one row per case / planner;
* every number in a table cell (outside the names) is a number of the JSON, formatted;
* a changed number in the JSON changes the table (the check is not vacuous).
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path
from typing import Any

import pytest
from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]


def _script():  # type: ignore[no-untyped-def]
    return load_script("bench_table")


bt = _script()


def _row(family: str, cpu: float | None, wall: float | None, status: str | None, solver: str | None = None,
         cost: float | None = 6.7) -> dict[str, Any]:
    return {"family": family, "problem": "p", "planner": "qp-avoid" if solver else "pmp", "solver": solver,
            "cpu_s": cpu, "wall_s": wall, "repeats": 3, "status": status, "cost": cost, "n_solves": 12,
            "deterministic": True}


def fake_run(scale: float = 1.0) -> dict[str, Any]:
    """A bench JSON with the keys the table reads, built by the bench's own verdicts and ratios."""
    from iamp.comparison.bench import limits

    rows = {"bounded_pmp_one_vehicle_certified": _row("bounded_pmp_one_vehicle_certified", 1.234e-3 * scale,
                                                      3.456e-3 * scale, "optimal"),
            "bounded_pmp_three_vehicles": _row("bounded_pmp_three_vehicles", 0.0271 * scale, 0.0912 * scale,
                                               "infeasible", cost=None),
            "avoid_limits_one_vehicle_osqp": _row("avoid_limits_one_vehicle", 4.44e-3 * scale, 0.0111 * scale,
                                                  "optimal", "osqp"),
            "avoid_limits_one_vehicle_piqp": _row("avoid_limits_one_vehicle", None, None, None, "piqp"),
            "avoid_limits_three_vehicles_clarabel": _row("avoid_limits_three_vehicles", 0.777 * scale,
                                                         2.31 * scale, "local", "clarabel")}
    rows["avoid_limits_one_vehicle_piqp"]["error"] = "ModuleNotFoundError: piqp"
    refs = {"pmp_plan": {"cpu_s": 23.4e-6, "wall_s": 61.7e-6}, "kkt_solve": {"cpu_s": 187e-6, "wall_s": 402e-6}}
    wl = {"steps": 50, "rows": rows, "targets": {k: limits.target_of(r) for k, r in rows.items()},
          "same_optimum": {"avoid_limits_one_vehicle": False, "avoid_limits_three_vehicles": False},
          "references": refs, "ratios": limits.ratios(rows, refs)}

    def ep(wall: float, planning: float, calls: int, ok: bool) -> dict[str, Any]:
        return {"episode": {"median": wall, "n": 1}, "wall_s": {"total": wall * 0.97, "sumo": 0.81,
                                                                "prediction": 1.13, "planning": planning},
                "planner_calls": calls, "success": ok, "contacts": 0, "limit_violations": 0}

    loop = {"case": {"mission": "merge", "traffic": "dense", "seed": 1, "duration_s": 60.0}, "repeats": 1,
            "planners": {"pmp": ep(76.2 * scale, 66.0, 78, False), "free": ep(3.37, 0.0226, 61, True)},
            "episode_s": {"pmp": 76.2 * scale, "free": 3.37}, "target_episode_s": 1.0}
    return {"planning_with_limits": wl, "loop": loop,
            "machine": {"cpu_count": 2, "platform": "Linux", "python": "3.11.7", "load_average_1min_before": 7.66,
                        "load_average_1min_after": 8.57}}


def _numbers(obj: Any) -> list[float]:
    if isinstance(obj, bool):
        return []
    if isinstance(obj, (int, float)):
        return [float(obj)]
    if isinstance(obj, dict):
        return [x for v in obj.values() for x in _numbers(v)]
    if isinstance(obj, list):
        return [x for v in obj for x in _numbers(v)]
    return []


def _tables(text: str) -> list[list[list[str]]]:
    """Every Markdown table of ``text`` as rows of cells (header first, the rule dropped)."""
    tables: list[list[list[str]]] = []
    current: list[list[str]] = []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not all(set(c) <= {"-"} for c in cells):
                current.append(cells)
        elif current:
            tables.append(current)
            current = []
    return tables


TOKEN = re.compile(r"(?<![\w.])(\d+(?:\.\d+)?(?:e[-+]?\d+)?)(?: (s|ms|µs))?(?![\w.])")


def _allowed(*runs: dict[str, Any]) -> set[str]:
    out: set[str] = set()
    for run in runs:
        for x in _numbers(run):
            out |= {bt.fmt_s(x), bt.fmt_ratio(x), str(int(x)) if x == int(x) else ""}
    return out


def _check_numbers(text: str, *runs: dict[str, Any]) -> int:
    allowed = _allowed(*runs)
    seen = 0
    for table in _tables(text):
        header = table[0]
        for row in table[1:]:
            assert len(row) == len(header), (header, row)
            for cell in row[1:]:  # the first column names the case (its "N = 50" is a name, not a number)
                for m in TOKEN.finditer(cell):
                    token = m.group(0)
                    assert token in allowed, (token, row)
                    seen += 1
    return seen


def test_every_number_of_the_tables_comes_from_the_json() -> None:
    after, before = fake_run(), fake_run(scale=7.0)
    doc = bt.document(after, before)
    assert _check_numbers(doc, after, before) > 30
    block = bt.readme_block(after, before)
    assert _check_numbers(block, after, before) > 20
    # a number that is not in the JSON is caught (the test can fail)
    with pytest.raises(AssertionError):
        _check_numbers(doc.replace("1.23 ms", "1.24 ms"), after, before)


def test_the_tables_have_one_row_per_case_and_planner() -> None:
    after = fake_run()
    tables = _tables(bt.document(after, None))
    targets, refs, loop = tables
    assert len(targets) - 1 == len(after["planning_with_limits"]["rows"])
    assert len(refs) - 1 == 2
    assert [r[0] for r in loop[1:]] == list(after["loop"]["planners"])
    # the verdicts: met only with an allowed status and a median within the target
    by_backend = {r[1]: r for r in targets[1:]}
    assert by_backend["osqp"][6:8] == ["**met**", "missed"]  # 4.44 ms <= 5 ms on CPU, 11.1 ms wall
    assert by_backend["clarabel"][6:8] == ["missed", "missed"]  # local: not certified
    assert by_backend["piqp"][2] == "ModuleNotFoundError: piqp" and by_backend["piqp"][3] == "n/a"
    assert [r[9] for r in loop[1:]] == ["missed", "missed"]  # 76.2 s and 3.37 s > 1 s
    assert [r[4] for r in loop[1:]] == ["n/a", "n/a"]  # no warm-up in this run: no first episode
    assert [r[2] for r in loop[1:]] == ["n/a", "n/a"]  # no CPU time in this run's JSON
    assert "n/a" in targets[1][-1]  # no before run: the column says so


def test_the_warm_up_episode_is_said_and_shown() -> None:
    """A run with a warm-up says so above the loop table and shows the warm-up's own wall time."""
    after = copy.deepcopy(fake_run())
    after["loop"]["warmup"] = 1
    for i, row in enumerate(after["loop"]["planners"].values()):
        row["first_episode_s"] = 2.5 + i
    text = bt.document(after, None)
    assert "after 1 untimed warm-up episode" in text
    loop = _tables(text)[2]
    assert [r[4] for r in loop[1:]] == ["2.5 s", "3.5 s"]


def test_the_episode_cpu_time_and_repeats_are_shown() -> None:
    """With repeats and CPU time in the JSON, the table shows the CPU medians and says what a figure is."""
    after = copy.deepcopy(fake_run())
    after["loop"]["repeats"] = 3
    for i, row in enumerate(after["loop"]["planners"].values()):
        row["cpu"] = {"median": 0.25 + i, "n": 3}
    text = bt.document(after, None)
    assert "median of 3 timed episodes" in text
    loop = _tables(text)[2]
    assert [r[2] for r in loop[1:]] == ["250 ms", "1.25 s"]


def test_a_changed_number_changes_the_table() -> None:
    after = fake_run()
    changed = copy.deepcopy(after)
    changed["planning_with_limits"]["rows"]["bounded_pmp_three_vehicles"]["cpu_s"] = 0.0555
    assert "55.5 ms" in bt.document(changed, None) and "55.5 ms" not in bt.document(after, None)


def test_the_committed_table_is_what_the_json_says(tmp_path: Path) -> None:
    """docs/bench.md and README.md's block equal what reports/bench.json says (rerun the script after a bench)."""
    assert bt.main(["--check"]) == 0
    # and the check fails on a stale document
    for rel in ("README.md", "docs/bench.md", "reports/bench.json", "reports/bench-before.json"):
        src = ROOT / rel
        if src.is_file():
            (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp_path / rel).write_text(src.read_text(encoding="utf-8"), encoding="utf-8")
    run = json.loads((tmp_path / "reports/bench.json").read_text(encoding="utf-8"))
    first = next(iter(run["planning_with_limits"]["rows"].values()))
    first["status"] = "changed-status"
    (tmp_path / "reports/bench.json").write_text(json.dumps(run), encoding="utf-8")
    assert bt.main(["--check"], root=tmp_path) == 1
    assert bt.main([], root=tmp_path) == 0 and bt.main(["--check"], root=tmp_path) == 0
    assert "changed-status" in (tmp_path / "docs/bench.md").read_text(encoding="utf-8")


def test_a_bench_without_the_issue_32_keys_is_refused(tmp_path: Path) -> None:
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports/bench.json").write_text(json.dumps({"pmp_plan_s": {}}), encoding="utf-8")
    with pytest.raises(SystemExit, match="no planning_with_limits"):
        bt.main(["--check"], root=tmp_path)
