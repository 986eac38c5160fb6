"""The reproduction's small closed-loop section (SPEC §15), present only with the ``[sim]`` extra.

``iamp reproduce`` runs a small version of the published campaign **afresh** — the ``merge``
mission (the ego's lane ends 400 m ahead), the paper's PMP, the active-set PMP, the avoidance
QP, the unconstrained ablation, IDM + MOBIL and SUMO's own lane change (LC2013) in medium
traffic, paired seeds — through :func:`iamp.simulation.campaign.run_campaign` into an emptied
``campaign-small`` folder (it never resumes from rows it did not make in this run) and adds its
table (success, contacts, the new follower's hard brakes, executed limit violations with
Wilson 95 % intervals; medians of time to merge, follower deceleration, executed peak, plan
time) to the report.  Without SUMO and Dask the section says so and names the extra to
install; the rest of the reproduction is unchanged.  The published campaign (4 missions x 7
planners x 3 densities, paired seeds) is ``reports/campaign-new/``, made by ``iamp campaign``
(its README gives the command).

This is the one place where the comparison layer reaches the simulation layer, lazily and
for the report only.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import cast

from iamp.core.atomic import write_text
from iamp.core.errors import MissingDependencyError

from .records import CampaignRun, CampaignSection, FullCampaign
from .tex import tex_escape

PLANNERS = ("pmp", "pmp-active", "qp-avoid", "free", "mobil", "sumo")
MISSION = "merge"
INSTALL = "pip install 'iamp[sim]'"


def campaign_section(out: Path, *, quick: bool, progress: Callable[[int, int], None] | None = None
                     ) -> CampaignSection:
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
    seeds, duration = (1, 30.0) if quick else (3, 60.0)
    folder = out / "campaign-small"
    out.mkdir(parents=True, exist_ok=True)
    fresh = Path(tempfile.mkdtemp(prefix=".campaign-small-", suffix=".tmp", dir=str(out)))
    try:
        with _workers_ignore_ctrl_c():
            ran = run_campaign(PLANNERS, ("medium",), seeds, fresh, missions=(MISSION,), workers=2,
                               duration_s=duration, deadline=False, progress=progress)
        folder.mkdir(exist_ok=True)
        for name in ("episodes.csv", "manifest.json", "errors.csv"):
            if (fresh / name).is_file():
                os.replace(fresh / name, folder / name)
            elif (folder / name).is_file() and name == "errors.csv":
                (folder / name).unlink()  # an old run's failures are not this run's
    finally:
        shutil.rmtree(fresh, ignore_errors=True)
    summary = summarise(read_rows(folder / "episodes.csv"), PLANNERS)
    table = latex_table(summary)
    write_text(out / "tables" / "campaign-small.tex", table)
    command = (f"iamp campaign --missions {MISSION} --planners {','.join(PLANNERS)} --traffic medium "
               f"--seeds {seeds} --duration {duration:g} --out {folder.name}")
    return {"available": True, "summary": summary, "ran": cast(CampaignRun, ran), "command": command,
            "table": "tables/campaign-small.tex", "full": full_campaign_shape(out)}


#: The Dask preload that :func:`dask_setup` is (this module).
PRELOAD = __name__


@contextlib.contextmanager
def _workers_ignore_ctrl_c() -> Iterator[None]:
    """While the block runs, every Dask worker process started in it runs :func:`dask_setup`
    (a worker preload, handed to the worker processes with the Dask configuration)."""
    import dask

    preloads = list(dask.config.get("distributed.worker.preload", default=[]) or [])
    with dask.config.set({"distributed.worker.preload": [*preloads, PRELOAD]}):
        yield


def dask_setup(worker: object) -> None:
    """Dask worker preload: the worker process ignores SIGINT (issue 29 item 14).

    A terminal's Ctrl-C goes to the whole process group, the campaign's worker processes
    included; each then printed its own tracebacks (tornado, asyncio) while the reproduction
    printed ``iamp: interrupted``.  Ignoring it, the workers are stopped by the cluster's
    shutdown in the main process, which is silent (:func:`iamp.simulation.campaign.run_campaign`).

    Parameters
    ----------
    worker : distributed.Worker
        The worker being started (unused).
    """
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def full_campaign_shape(out: Path) -> FullCampaign | None:
    """Missions, planners, densities and episodes of the published campaign
    (``out/campaign-new/summary.json``, SPEC §15: ``{"cells": [...]}``), or None."""
    import json

    path = out / "campaign-new" / "summary.json"
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))["cells"]
        missions = sorted({str(r["mission"]) for r in rows})
        planners = sorted({str(r["planner"]) for r in rows})
        traffic = sorted({str(r["traffic"]) for r in rows})
        episodes = sum(int(r["episodes"]) for r in rows)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return {"missions": missions, "planners": planners, "traffic": traffic, "episodes": episodes}


def _full_campaign(full: FullCampaign | None) -> str:
    if not full:
        return "The published campaign is made by \\texttt{iamp campaign} (docs/closed-loop.md)."
    names = ", ".join(str(tex_escape(p)) for p in full["planners"])
    return (f"The published campaign in \\texttt{{reports/campaign-new/}}: {len(full['missions'])} missions "
            f"$\\times$ {len(full['planners'])} planners ({names}) $\\times$ {len(full['traffic'])} densities, "
            f"{full['episodes']} episodes.")


def _provenance(ran: CampaignRun | None) -> str:
    """How many episodes this run made and how many it reused (always 0: it never resumes)."""
    if not ran:
        return "episodes run by this reproduction"
    text = f"{int(ran.get('ran', 0))} episodes run by this reproduction"
    if ran.get("skipped"):
        text += f", {int(ran['skipped'])} reused from an earlier run"
    if ran.get("failed"):
        text += f", {int(ran['failed'])} failed (errors.csv)"
    return text


def campaign_tex(section: CampaignSection) -> str:
    """The report's closed-loop section (a paragraph and the table, or the note)."""
    head = "\\section{Closed loop in SUMO traffic (small campaign)}\n"
    if not section.get("available"):
        return head + str(tex_escape(section["note"])) + "\n\n"
    return (head + "Receding-horizon planning every 0.1\\,s in seeded SUMO traffic (SPEC~\\S15): the ego's "
            "lane ends 400\\,m ahead and it must merge; the paper's PMP, the active-set PMP, the avoidance QP, "
            "the unconstrained ablation, IDM + MOBIL and SUMO's own lane change, medium density, paired seeds "
            "(too few to tell planners apart), run afresh by the reproduction with: \\texttt{"
            + str(tex_escape(section["command"])) + "}; " + _provenance(section.get("ran")) + ". "
            + _full_campaign(section.get("full")) + "\n\n"
            "\\noindent\\resizebox{\\linewidth}{!}{\\input{" + str(section["table"]) + "}}\n\n")
