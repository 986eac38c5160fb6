"""scripts/campaign_markdown.py: the campaign's own numbers, formatted (SPEC §15, §17)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]


def _script():  # type: ignore[no-untyped-def]
    return load_script("campaign_markdown")


def _cell(planner: str, traffic: str, n: int, k: dict[str, int], rss: bool) -> dict[str, Any]:
    names = ["success", "contact", "hard_brake", "limit_violation"] + (
        ["contact_at_fault", "emergency_brake", "rss_dangerous"] if rss else [])
    cell: dict[str, Any] = {"mission": "merge", "planner": planner, "traffic": traffic, "episodes": n,
                            "time_to_merge_s_median": 10.0, "follower_max_decel_median": 2.0,
                            "ego_peak_accel_median": 3.0, "constrained_plans": 1, "executed_plans": 2,
                            "infeasible_plans": 0, "fallbacks": 0, "plan_time_p50_s_median": 0.001}
    for name in names:
        cell[f"{name}_episodes"] = k.get(name, 0)
    return cell


@pytest.mark.parametrize("rss", [True, False])
def test_the_responsibility_columns_pool_the_densities_and_appear_only_for_a_section_17_campaign(rss: bool) -> None:
    k1 = {"success": 9, "contact_at_fault": 1, "emergency_brake": 2, "rss_dangerous": 3}
    k2 = {"success": 10, "contact_at_fault": 0, "emergency_brake": 1, "rss_dangerous": 4}
    report = {"reference": "free", "paired": [],
              "cells": [_cell("pmp-active", "dense", 10, k1, rss), _cell("pmp-active", "los-e", 10, k2, rss)]}
    text = _script().markdown(report)
    header = next(line for line in text.splitlines() if line.startswith("| planner |"))
    row = next(line for line in text.splitlines() if line.startswith("| pmp-active |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert len(cells) == len(header.strip("|").split("|"))
    assert cells[2].startswith("19/20 ")
    if rss:
        assert "contact at fault" in header and "RSS-dangerous at fault" in header
        assert cells[4].startswith("1/20 ") and cells[5].startswith("3/20 ") and cells[6].startswith("7/20 ")
    else:
        assert "at fault" not in header
