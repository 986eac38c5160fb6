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
    # one mission, one density (in the caption); the plan times: in the timing table (machine-dependent)
    table = without_columns(latex_table(summary), (0, 1, -1))
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

    try:
        # distributed registers its configuration's defaults when first imported; imported inside
        # the block, they would be merged under the key the block sets and removed with it on exit
        # (dask.config.set deletes a key it inserted), leaving no ``distributed`` configuration for
        # the rest of the process
        import distributed  # noqa: F401
    except ImportError:  # pragma: no cover - the campaign itself says which extra it needs
        pass
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


def without_columns(table: str, drop: tuple[int, ...]) -> str:
    """A ``tabular`` (one row per line, cells separated by `` & ``) without the columns ``drop``
    (indices; negative from the end).  :func:`iamp.simulation.campaign.latex_table` starts with the
    mission and the density (one each here, said in the caption) and ends on the plan time, a wall
    time (in the timing table)."""
    out: list[str] = []
    spec_at, cells = None, 0
    for line in table.splitlines():
        stripped = line.rstrip()
        if stripped.startswith("\\begin{tabular}{") and stripped.endswith("}"):
            spec_at = len(out)
            out.append(stripped[len("\\begin{tabular}{"):-1])
        elif stripped.endswith("\\\\") and " & " in stripped:
            row = stripped[:-2].rstrip().split(" & ")
            gone = {k % len(row) for k in drop}
            kept = [c for k, c in enumerate(row) if k not in gone]
            cells = max(cells, len(kept))
            out.append(" & ".join(kept) + " \\\\")
        else:
            out.append(line)
    if spec_at is not None:  # one column letter per remaining cell
        spec = out[spec_at]
        gone = {k % len(spec) for k in drop} if spec else set()
        spec = "".join(c for k, c in enumerate(spec) if k not in gone)
        spec = spec[:cells] + "r" * max(cells - len(spec), 0) if cells else spec
        out[spec_at] = "\\begin{tabular}{" + spec + "}"
    return "\n".join(out) + ("\n" if table.endswith("\n") else "")


def campaign_plan_times(section: CampaignSection) -> list[tuple[str, int, float | None]]:
    """``(label, episodes, median over the episodes of each episode's median plan time)`` per
    planner of the small campaign (the timing table's closed-loop rows); empty without it."""
    if not section.get("available"):
        return []
    rows = []
    for c in section.get("summary", []):
        label = f"{c.get('mission', MISSION)}, {c.get('traffic', '')}: {c.get('planner', '?')}"
        median, n = c.get("plan_time_p50_s_median"), c.get("episodes", 0)
        rows.append((label, int(cast(int, n)), None if median is None else float(cast(float, median))))
    return rows


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
            "(too few to tell planners apart); " + _provenance(section.get("ran")) + ". "
            + _full_campaign(section.get("full")) + " The reproduction runs the small campaign afresh with\n"
            "\\begin{quote}\\raggedright\\small\\texttt{"
            + str(tex_escape(section["command"])).replace(",", ",\\allowbreak{}") + "}\n\\end{quote}\n\n"
            "\\begin{table}[H]\n\\centering\n\\caption{The small campaign (mission \\texttt{" + MISSION + "}, "
            "medium density): success and contacts (k/n, Wilson "
            "95\\,\\% interval in \\%), the new follower's hard brakes, executed limit violations, medians of the "
            "time to merge, the follower's deceleration and the executed peak acceleration, and the plans that were "
            "constrained. The plan times are in Table~\\ref{tab:timing} (machine-dependent).}\n"
            "\\label{tab:campaign-small}\n"
            "{\\setlength{\\tabcolsep}{3pt}\\resizebox{\\linewidth}{!}{\\input{" + str(section["table"])
            + "}}}\n\\end{table}\n\n")
