"""The reproduction's closed-loop section: present with the [sim] extra, a plain note without."""

from __future__ import annotations

import sys

from iamp.comparison.report.campaign import campaign_section, campaign_tex


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
