"""scripts/campaign_merge_rows.py: the re-run planners' episodes put in place in a published campaign folder."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from conftest import load_script

cm = load_script("campaign_merge_rows")

COLUMNS = ["mission", "planner", "traffic", "seed", "success", "time_to_merge_s"]
MANIFEST = {"episode_format": "1.0", "duration_s": 60.0, "cooperation": "default", "planners": ["a", "b", "c"],
            "missions": ["merge"], "traffic": ["light"], "seeds": 2}


def _folder(path: Path, rows: list[list[object]], **manifest: object) -> Path:
    path.mkdir()
    with open(path / "episodes.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(COLUMNS)
        w.writerows(rows)
    (path / "manifest.json").write_text(json.dumps({**MANIFEST, **manifest}, indent=1), encoding="utf-8")
    return path


def _rows(path: Path) -> list[list[str]]:
    with open(path / "episodes.csv", newline="", encoding="utf-8") as f:
        return list(csv.reader(f))[1:]


def _published(tmp_path: Path) -> Path:
    return _folder(tmp_path / "pub", [["merge", "a", "light", 1, True, 5.0], ["merge", "a", "light", 2, False, ""],
                                      ["merge", "b", "light", 1, True, 6.0], ["merge", "b", "light", 2, True, 7.0],
                                      ["merge", "c", "light", 1, True, 8.0], ["merge", "c", "light", 2, True, 9.0]])


def test_the_new_rows_replace_the_run_planners_and_the_others_are_kept(tmp_path: Path) -> None:
    pub = _published(tmp_path)
    new = _folder(tmp_path / "new", [["merge", "c", "light", 2, False, ""], ["merge", "a", "light", 1, True, 4.0],
                                     ["merge", "c", "light", 1, True, 8.5], ["merge", "a", "light", 2, True, 12.0]],
                  episode_format="1.1", planners=["a", "c"])
    line = cm.merge(pub, new)
    assert "4 rows of a, c" in line and "2 kept" in line and "episode format 1.1" in line
    # the folder's planner order; each planner's rows as its source wrote them
    assert _rows(pub) == [["merge", "a", "light", "1", "True", "4.0"], ["merge", "a", "light", "2", "True", "12.0"],
                          ["merge", "b", "light", "1", "True", "6.0"], ["merge", "b", "light", "2", "True", "7.0"],
                          ["merge", "c", "light", "2", "False", ""], ["merge", "c", "light", "1", "True", "8.5"]]
    man = json.loads((pub / "manifest.json").read_text(encoding="utf-8"))
    assert man == {**MANIFEST, "episode_format": "1.1"}  # the planners list stays the folder's


@pytest.mark.parametrize("change", [{"cooperation": "low"}, {"duration_s": 30.0}, {"seeds": 3}])
def test_a_run_of_other_parameters_is_refused_and_nothing_changes(tmp_path: Path, change: dict[str, object]) -> None:
    pub = _published(tmp_path)
    before = (pub / "episodes.csv").read_bytes(), (pub / "manifest.json").read_bytes()
    new = _folder(tmp_path / "new", [["merge", "a", "light", 1, True, 4.0], ["merge", "a", "light", 2, True, 1.0]],
                  **change)
    with pytest.raises(SystemExit, match=f"differs .* in {next(iter(change))}"):
        cm.merge(pub, new)
    assert ((pub / "episodes.csv").read_bytes(), (pub / "manifest.json").read_bytes()) == before


def test_a_run_missing_an_episode_is_refused(tmp_path: Path) -> None:
    pub = _published(tmp_path)
    before = (pub / "episodes.csv").read_bytes()
    new = _folder(tmp_path / "new", [["merge", "a", "light", 1, True, 4.0]])
    with pytest.raises(SystemExit, match="planner a lacks 1 of the folder's episodes"):
        cm.merge(pub, new)
    assert (pub / "episodes.csv").read_bytes() == before
