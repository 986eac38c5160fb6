"""The reproduction's small closed-loop section (SPEC §11), present only with the ``[sim]`` extra.

``iamp reproduce`` runs a small campaign — the PMP, the avoidance QP and SUMO's own
lane-change model (LC2013) in medium traffic, a few seeds of short episodes — through
:func:`iamp.simulation.campaign.run_campaign` and adds its table (collision and intrusion
rates with Wilson 95 % intervals, plan times) to the report.  Without SUMO and Dask the
section says so and names the extra to install; the rest of the reproduction is unchanged.
The full campaign (3 planners x 3 densities x 20 seeds) is ``reports/campaign/``, made by
``iamp campaign`` (its README gives the command).

This is the one place where the comparison layer reaches the simulation layer, lazily and
for the report only.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from iamp.core.atomic import write_text
from iamp.core.errors import MissingDependencyError

from .tex import tex_escape

PLANNERS = ("pmp", "qp-avoid", "sumo")
INSTALL = "pip install 'iamp[sim]'"


def campaign_section(out: Path, *, quick: bool, progress: Callable[[int, int], None] | None = None
                     ) -> dict[str, Any]:
    """Run the small campaign into ``out/campaign-small`` and return its summary and LaTeX.

    Returns ``{"available": False, "note": ...}`` when the ``[sim]`` extra is missing.
    """
    try:
        from iamp.simulation.campaign import latex_table, read_rows, run_campaign, summarise
        from iamp.simulation.network import require_sumo
    except (ImportError, MissingDependencyError) as exc:
        return {"available": False, "note": f"closed-loop section skipped: {exc}; install it with {INSTALL}"}
    try:
        require_sumo()
    except MissingDependencyError as exc:
        return {"available": False, "note": f"closed-loop section skipped: {exc}"}
    seeds, duration = (1, 10.0) if quick else (3, 30.0)
    folder = out / "campaign-small"
    ran = run_campaign(PLANNERS, ("medium",), seeds, folder, workers=2, duration_s=duration, deadline=False,
                       progress=progress)
    summary = summarise(read_rows(folder / "episodes.csv"))
    table = latex_table(summary)
    write_text(out / "tables" / "campaign-small.tex", table)
    command = (f"iamp campaign --planners {','.join(PLANNERS)} --traffic medium --seeds {seeds} "
               f"--duration {duration:g} --no-deadline --out {folder.name}")
    return {"available": True, "summary": summary, "ran": ran, "command": command,
            "table": "tables/campaign-small.tex"}


def campaign_tex(section: dict[str, Any]) -> str:
    """The report's closed-loop section (a paragraph and the table, or the note)."""
    head = "\\section{Closed loop in SUMO traffic (small campaign)}\n"
    if not section.get("available"):
        return head + str(tex_escape(section["note"])) + "\n\n"
    return (head + "Receding-horizon planning every 0.1\\,s in seeded SUMO traffic (SPEC~\\S11), "
            "the paper's PMP, the avoidance QP and SUMO's own lane-change model, medium density. "
            "A small smoke-size campaign made by the reproduction with: \\texttt{"
            + str(tex_escape(section["command"])) + "}. The full campaign (3 planners $\\times$ 3 densities "
            "$\\times$ 20 seeds) is in \\texttt{reports/campaign/}.\n\n"
            "\\noindent\\resizebox{\\linewidth}{!}{\\input{" + str(section["table"]) + "}}\n\n")
