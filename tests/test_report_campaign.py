"""The reproduction's closed-loop section: present with the [sim] extra, a plain note without."""

from __future__ import annotations

import sys

from iamp.comparison.report.campaign import PLANNERS, campaign_section, campaign_tex


def test_without_the_extra_the_section_names_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "iamp.simulation.campaign", None)  # import fails as without SUMO/Dask
    section = campaign_section(tmp_path, quick=True)
    assert section["available"] is False and "iamp[sim]" in section["note"]
    tex = campaign_tex(section)
    assert "iamp[sim]" in tex and "\\input" not in tex
    assert not (tmp_path / "campaign-small").exists()


def test_the_section_inputs_its_table():
    tex = campaign_tex({"available": True, "command": "iamp campaign --seeds 1", "table": "tables/x.tex"})
    assert "\\input{tables/x.tex}" in tex and "-{}-seeds" in tex


def _fake_campaign(collisions: int):  # type: ignore[no-untyped-def]
    """A stand-in for run_campaign with its resume semantics: skips the rows already in ``out``."""
    from iamp.simulation.campaign import COLUMNS, _append, read_rows

    def run(planners, traffics, seeds, out, **kw):  # type: ignore[no-untyped-def]
        from pathlib import Path

        path = Path(out) / "episodes.csv"
        done = {(r["planner"], r["traffic"], int(r["seed"])) for r in read_rows(path)}
        ran = 0
        for p in planners:
            for t in traffics:
                for s in range(1, seeds + 1):
                    if (p, t, s) in done:
                        continue
                    row = {c: 0 for c in COLUMNS}
                    row.update(mission="merge", planner=p, traffic=t, seed=s, contacts=collisions, duration_s=10.0,
                               success=not collisions)
                    _append(path, COLUMNS, row)
                    ran += 1
        return {"ran": ran, "skipped": len(done), "failed": 0, "seconds": 0.0}

    return run


def test_reproduction_never_resumes_from_an_existing_table(tmp_path, monkeypatch):
    """Issue 22 item 1: a committed campaign-small/episodes.csv is not reported as this run's table.

    The earlier file's episodes all collided; the reproduction's own episodes do not.  The old code
    resumed (0 run, every episode skipped) and reported the committed collisions as reproduced.
    """
    import iamp.simulation.campaign as campaign
    import iamp.simulation.network as network

    monkeypatch.setattr(network, "require_sumo", lambda: None)
    folder = tmp_path / "campaign-small"
    folder.mkdir()
    monkeypatch.setattr(campaign, "run_campaign", _fake_campaign(collisions=1))
    old = campaign_section(tmp_path, quick=True)  # the "committed" run: every episode a collision
    assert all(s["contact_episodes"] == s["episodes"] == 1 for s in old["summary"])
    monkeypatch.setattr(campaign, "run_campaign", _fake_campaign(collisions=0))
    new = campaign_section(tmp_path, quick=True)
    n = len(PLANNERS)
    assert new["ran"] == {"ran": n, "skipped": 0, "failed": 0, "seconds": 0.0}
    assert all(s["contact_episodes"] == 0 and s["success_episodes"] == 1 for s in new["summary"])
    rows = campaign.read_rows(folder / "episodes.csv")
    assert len(rows) == n and all(r["contacts"] == "0" for r in rows)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]  # the scratch folder is gone
    tex = campaign_tex(new)
    assert f"{n} episodes run by this reproduction" in tex and "reused" not in tex


def test_the_full_campaign_is_described_from_its_summary(tmp_path):
    """Issue 22 item 15: the report counted '3 planners' for a 4-planner campaign (typed in)."""
    import json

    from iamp.comparison.report.campaign import full_campaign_shape

    cells = [{"mission": m, "planner": p, "traffic": t, "episodes": 20} for m in ("merge", "onramp")
             for p in ("pmp", "qp", "qp-avoid", "sumo") for t in ("light", "medium", "dense")]
    (tmp_path / "campaign-new").mkdir()
    (tmp_path / "campaign-new" / "summary.json").write_text(json.dumps({"cells": cells, "paired": []}))
    full = full_campaign_shape(tmp_path)
    assert full == {"missions": ["merge", "onramp"], "planners": ["pmp", "qp", "qp-avoid", "sumo"],
                    "traffic": ["dense", "light", "medium"], "episodes": 480}
    tex = campaign_tex({"available": True, "command": "c", "table": "t.tex", "full": full})
    assert "2 missions" in tex and "4 planners" in tex and "480 episodes" in tex and "3 planners" not in tex
