"""The reproduction's small closed-loop section (SPEC §11), present only with the ``[sim]`` extra.

``iamp reproduce`` runs a small campaign — the PMP, the avoidance QP and SUMO's own
lane-change model (LC2013) in medium traffic, a few seeds of short episodes — through
:func:`iamp.simulation.campaign.run_campaign` and adds its table (collision and intrusion
rates with Wilson 95 % intervals, plan times) to the report.  The reproduction *reproduces*:
its episodes run afresh in a temporary folder, never resumed from an ``episodes.csv`` already
in ``out/campaign-small`` (a committed table would otherwise be reported as made by this run),
and the new file replaces the old one only when the campaign finished.  Without SUMO and Dask the
section says so and names the extra to install; the rest of the reproduction is unchanged.
The full campaign is ``reports/campaign/``, made by ``iamp campaign`` (its README gives the
command); the report describes it from its own ``summary.json`` (planners, densities, episodes
counted, never typed in).

This is the one place where the comparison layer reaches the simulation layer, lazily and
for the report only.
"""

from __future__ import annotations

import os
import shutil
import tempfile
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
    out.mkdir(parents=True, exist_ok=True)
    fresh = Path(tempfile.mkdtemp(prefix=".campaign-small-", suffix=".tmp", dir=str(out)))
    try:
        ran = run_campaign(PLANNERS, ("medium",), seeds, fresh, workers=2, duration_s=duration, deadline=False,
                           progress=progress)
        folder.mkdir(exist_ok=True)
        for name in ("episodes.csv", "errors.csv"):
            if (fresh / name).is_file():
                os.replace(fresh / name, folder / name)
            elif (folder / name).is_file() and name == "errors.csv":
                (folder / name).unlink()  # an old run's failures are not this run's
    finally:
        shutil.rmtree(fresh, ignore_errors=True)
    summary = summarise(read_rows(folder / "episodes.csv"))
    table = latex_table(summary)
    write_text(out / "tables" / "campaign-small.tex", table)
    command = (f"iamp campaign --planners {','.join(PLANNERS)} --traffic medium --seeds {seeds} "
               f"--duration {duration:g} --no-deadline --out {folder.name}")
    return {"available": True, "summary": summary, "ran": ran, "command": command,
            "table": "tables/campaign-small.tex", "full": full_campaign_shape(out)}


def full_campaign_shape(out: Path) -> dict[str, Any] | None:
    """Planners, densities and episodes of the full campaign in ``out/campaign/summary.json``."""
    import json

    path = out / "campaign" / "summary.json"
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))
        planners = sorted({str(r["planner"]) for r in rows})
        traffic = sorted({str(r["traffic"]) for r in rows})
        episodes = sum(int(r["episodes"]) for r in rows)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return {"planners": planners, "traffic": traffic, "episodes": episodes}


def _full_campaign(full: dict[str, Any] | None) -> str:
    if not full:
        return "The full campaign is made by \\texttt{iamp campaign} (\\texttt{reports/campaign/README.md})."
    names = ", ".join(str(tex_escape(p)) for p in full["planners"])
    return (f"The full campaign in \\texttt{{reports/campaign/}}: {len(full['planners'])} planners ({names}) "
            f"$\\times$ {len(full['traffic'])} densities, {full['episodes']} episodes.")


def _provenance(ran: dict[str, Any] | None) -> str:
    """How many episodes this run made and how many it reused (always 0: it never resumes)."""
    if not ran:
        return "episodes run by this reproduction"
    text = f"{int(ran.get('ran', 0))} episodes run by this reproduction"
    if ran.get("skipped"):
        text += f", {int(ran['skipped'])} reused from an earlier run"
    if ran.get("failed"):
        text += f", {int(ran['failed'])} failed (errors.csv)"
    return text


def campaign_tex(section: dict[str, Any]) -> str:
    """The report's closed-loop section (a paragraph and the table, or the note)."""
    head = "\\section{Closed loop in SUMO traffic (small campaign)}\n"
    if not section.get("available"):
        return head + str(tex_escape(section["note"])) + "\n\n"
    return (head + "Receding-horizon planning every 0.1\\,s in seeded SUMO traffic (SPEC~\\S11), "
            "the paper's PMP, the avoidance QP and SUMO's own lane-change model, medium density. "
            "A small smoke-size campaign made by the reproduction with: \\texttt{"
            + str(tex_escape(section["command"])) + "}; " + _provenance(section.get("ran")) + ". "
            + _full_campaign(section.get("full")) + "\n\n"
            "\\noindent\\resizebox{\\linewidth}{!}{\\input{" + str(section["table"]) + "}}\n\n")
