"""Markdown tables of a closed-loop campaign (SPEC §15) from its ``summary.json``.

    python scripts/campaign_markdown.py reports/campaign-new/summary.json > tables.md

Per mission: one row per planner, all densities pooled (k/n with Wilson 95 % intervals; medians
over the per-density cell medians; sums of plan counts), then the paired differences against the
campaign's reference planner over all densities (rates in percentage points with the paired
bootstrap interval and the exact McNemar p-value; continuous measures with the paired bootstrap
interval and the number of pairs where both are defined).  The numbers are the campaign's own
(``iamp campaign`` wrote ``summary.json``); this script only formats them.
"""

from __future__ import annotations

import json
import statistics
import sys
from typing import Any

from iamp.simulation.stats import wilson


def _pooled(cells: list[dict[str, Any]], name: str) -> str:
    n = sum(c["episodes"] for c in cells)
    k = sum(c[f"{name}_episodes"] for c in cells)
    lo, hi = wilson(k, n)
    return f"{k}/{n} [{100 * lo:.0f}, {100 * hi:.0f}]"


def _median(cells: list[dict[str, Any]], key: str, scale: float = 1.0, fmt: str = ".1f") -> str:
    vals = [c[key] for c in cells if c[key] is not None]
    return "–" if not vals else format(scale * statistics.median(vals), fmt)


def _rate(d: dict[str, Any]) -> str:
    return f"{100 * d['diff']:+.0f} [{100 * d['ci'][0]:+.0f}, {100 * d['ci'][1]:+.0f}], p = {d['p']:.2g}"


def _cont(d: dict[str, Any]) -> str:
    if d["diff"] is None:
        return "–"
    return f"{d['diff']:+.2f} [{d['ci'][0]:+.2f}, {d['ci'][1]:+.2f}] (n = {d['n']})"


def markdown(report: dict[str, Any]) -> str:
    """Per mission: the planners' pooled rates and medians, then the paired differences.  A campaign
    of SPEC §17's loop (cells with ``contact_at_fault_episodes``) adds RSS's responsibility columns:
    episodes with a contact the ego is responsible for, with a follower's emergency brake caused by
    the ego, and with time in a dangerous situation the ego is responsible for."""
    out: list[str] = []
    missions = list(dict.fromkeys(c["mission"] for c in report["cells"]))
    rss = all("contact_at_fault_episodes" in c for c in report["cells"])
    # episode format 17.5 measures the executed path's turns (simulation/kinematics.py)
    turns = all(c.get("curvature_violation_episodes") is not None for c in report["cells"])
    extra_head = " contact at fault | follower emergency brake | RSS-dangerous at fault |" if rss else ""
    for m in missions:
        cells = [c for c in report["cells"] if c["mission"] == m]
        planners = list(dict.fromkeys(c["planner"] for c in cells))
        out += [f"\n**{m}**\n",
                "| planner | n | success | contact |" + extra_head + " new follower brakes > 4.5 m/s² | "
                "executed limit violation |" + (" executed turn < 5 m radius |" if turns else "")
                + " t_merge [s] | follower decel [m/s²] | executed peak ‖a‖ [m/s²] | "
                "constrained / executed plans | infeasible plans | fallbacks | plan p50 [ms] |",
                "|---|---|---|---|" + "---|" * ((3 if rss else 0) + (1 if turns else 0))
                + "---|---|---|---|---|---|---|---|---|"]
        for p in planners:
            cs = [c for c in cells if c["planner"] == p]
            extra = (f" {_pooled(cs, 'contact_at_fault')} | {_pooled(cs, 'emergency_brake')} | "
                     f"{_pooled(cs, 'rss_dangerous')} |") if rss else ""
            out.append(
                f"| {p} | {sum(c['episodes'] for c in cs)} | {_pooled(cs, 'success')} | {_pooled(cs, 'contact')} |"
                f"{extra} {_pooled(cs, 'hard_brake')} | {_pooled(cs, 'limit_violation')} | "
                + (f"{_pooled(cs, 'curvature_violation')} | " if turns else "") +
                f"{_median(cs, 'time_to_merge_s_median')} | {_median(cs, 'follower_max_decel_median')} | "
                f"{_median(cs, 'ego_peak_accel_median')} | {sum(c['constrained_plans'] for c in cs)}/"
                f"{sum(c['executed_plans'] for c in cs)} | {sum(c['infeasible_plans'] for c in cs)} | "
                f"{sum(c['fallbacks'] for c in cs)} | {_median(cs, 'plan_time_p50_s_median', 1e3)} |")
        pairs = [c for c in report["paired"] if c["mission"] == m and c["traffic"] == "all"]
        if pairs:
            pair_head = " contact at fault [pp] | emergency brake [pp] | Δ RSS-dangerous time [s] |" if rss else ""
            out += [f"\nPaired against `{report['reference']}` (other − reference, all densities):\n",
                    "| planner | pairs | success [pp] | contact [pp] |" + pair_head + " hard brake [pp] | "
                    "Δ follower decel [m/s²] | Δ t_merge [s] | Δ executed peak [m/s²] |",
                    "|---|---|---|---|" + "---|" * (3 if rss else 0) + "---|---|---|---|"]
            for c in pairs:
                extra = (f" {_rate(c['contact_at_fault'])} | {_rate(c['emergency_brake'])} | "
                         f"{_cont(c['rss_dangerous_s'])} |") if rss else ""
                out.append(f"| {c['planner']} | {c['pairs']} | {_rate(c['success'])} | {_rate(c['contact'])} |"
                           f"{extra} {_rate(c['hard_brake'])} | {_cont(c['follower_max_decel'])} | "
                           f"{_cont(c['time_to_merge_s'])} | {_cont(c['ego_peak_accel'])} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python scripts/campaign_markdown.py SUMMARY.json")
    with open(sys.argv[1], encoding="utf-8") as fh:
        sys.stdout.write(markdown(json.load(fh)))
