"""docs/closed-loop.md's campaign tables come from the campaigns' episodes.csv (issue 30 item 7)."""

from __future__ import annotations

from pathlib import Path

from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]


def _script():  # type: ignore[no-untyped-def]
    return load_script("campaign_tables")


def _row(**kw: str) -> dict[str, str]:
    base = {"mission": "merge", "traffic": "dense", "planner": "free", "seed": "1", "cooperation": "default",
            "success": "True", "contacts": "0", "contacts_at_fault": "0", "follower_max_decel": ""}
    return {**base, **kw}


def test_the_page_is_what_the_campaigns_say() -> None:
    page = (ROOT / "docs" / "closed-loop.md").read_text(encoding="utf-8")
    assert _script().render(page) == page


def test_counts_use_the_thresholds_and_the_judge() -> None:
    """Emergency at ≥ 8.9 m/s² (inclusive), hard braking above 4.5 m/s² (exclusive), contacts the
    judge blamed on the ego where it judged, every contact where it did not (format 15)."""
    s = _script()
    rows = [_row(follower_max_decel="8.9", contacts="2", contacts_at_fault="1"),
            _row(follower_max_decel="8.89", success="False"),
            _row(follower_max_decel="4.5"),
            _row(follower_max_decel="4.51")]
    assert s.counts(rows) == (4, 3, 1, 1, 3)
    old = [{k: v for k, v in r.items() if k != "contacts_at_fault"} for r in rows]
    assert s.counts(old) == (4, 3, 2, 1, 3)
    assert s.counts([]) == (0, 0, 0, 0, 0)


def test_before_and_after_compare_the_same_seeds() -> None:
    s = _script()
    after = [_row(seed="1"), _row(seed="2")]
    before = [_row(seed="1", success="False"), _row(seed="2"), _row(seed="3", success="False")]
    lines = s.before_after(before, after, ("merge",))
    assert lines[2] == "| merge, dense, `free` | 1/2; 0; 0; 0 | 2/2; 0; 0; 0 |"
    assert len(lines) == 3  # one planner in the data


def test_the_mission_table_keeps_cooperation_levels_apart() -> None:
    s = _script()
    lines = s.mission_table([("", [_row()]), ("", [_row(cooperation="low", success="False")])])
    assert lines[2] == "| merge, dense | 1/1; 0; 0; 0 |"
    assert lines[3] == "| merge, dense, cooperation low | 0/1; 0; 0; 0 |"


def test_failures_are_split_by_kind() -> None:
    s = _script()
    rows = [_row(success="False", contacts="1", stopped_at_end="True"),
            _row(success="False", contacts="0", stopped_at_end="True"),
            _row(success="False", contacts="0", stopped_at_end="False"),
            _row(success="True", contacts="0", stopped_at_end="False")]
    lines = s.failure_kinds([("default", rows)])
    assert lines[2] == "| default, `free` | 3/4 | 1 | 1 | 1 |"
