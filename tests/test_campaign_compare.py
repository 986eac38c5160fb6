"""scripts/campaign_compare.py: episode-by-episode comparison of two runs of one campaign."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("campaign_compare", ROOT / "scripts" / "campaign_compare.py")
assert spec is not None and spec.loader is not None
cc = importlib.util.module_from_spec(spec)
sys.modules["campaign_compare"] = cc
spec.loader.exec_module(cc)

COLUMNS = ["mission", "planner", "traffic", "seed", "success", "time_to_merge_s", "contacts", "contacts_at_fault",
           "limit_violations", "follower_emergency_brakes"]


def _write(path: Path, rows: list[list[object]]) -> Path:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        w.writerows(rows)
    return path


def test_sums_and_other_courses_over_the_common_episodes(tmp_path: Path) -> None:
    a = _write(tmp_path / "a.csv", [["merge", "pmp", "dense", 1, True, 12.5, 0, 0, 0, 0],
                                    ["merge", "pmp", "dense", 2, True, 7.2, 1, 1, 0, 2],
                                    ["merge", "sumo", "dense", 1, False, "", 0, 0, 3, 0],
                                    ["merge", "pmp", "dense", 9, True, 5.0, 0, 0, 0, 0]])  # not in b
    b = _write(tmp_path / "b.csv", [["merge", "pmp", "dense", 1, True, 34.9, 0, 0, 0, 0],
                                    ["merge", "pmp", "dense", 2, True, 7.2, 0, 0, 1, 2],
                                    ["merge", "sumo", "dense", 1, False, "", 0, 0, 3, 0]])
    res = cc.compare(cc.read(a), cc.read(b))
    pmp, sumo = res["pmp"], res["sumo"]
    assert pmp["n"] == 2 and sumo["n"] == 1
    assert (pmp["a:success"], pmp["b:success"]) == (2, 2)
    assert (pmp["a:contacts_at_fault"], pmp["b:contacts_at_fault"]) == (1, 0)
    assert (pmp["a:limit_violations"], pmp["b:limit_violations"]) == (0, 1)
    assert pmp["other_course"] == 1 and sumo["other_course"] == 0
    text = cc.table(res)
    assert "| pmp | 2 | 2 -> 2 | 1 -> 0 | 1 -> 0 | 0 -> 1 | 2 -> 2 | 1 |" in text


def test_a_file_without_a_column_is_refused_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("mission,planner,traffic,seed\nmerge,pmp,dense,1\n", encoding="utf-8")
    good = _write(tmp_path / "good.csv", [["merge", "pmp", "dense", 1, True, 1.0, 0, 0, 0, 0]])
    assert cc.main([str(bad), str(good)]) == 2
    assert "bad.csv: no column 'success'" in capsys.readouterr().err
    assert cc.main([str(tmp_path / "none.csv"), str(good)]) == 2
