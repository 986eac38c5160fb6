"""The bounded comparison (SPEC §14) as a LaTeX table for ``iamp reproduce``."""

from __future__ import annotations

from iamp.core.physical import PASSENGER_CAR

from ..bounded import BoundedRow
from .latex import Raw, booktabs_table, escape, sci


def latex_table(rows: list[BoundedRow]) -> str:
    """The bounded comparison as a booktabs table (``iamp reproduce``: ``tables/bounded.tex``)."""
    body: list[list[str | Raw] | None] = []
    last = None
    for r in rows:
        if last is not None and r.scenario != last:
            body.append(None)
        last = r.scenario
        exceeded = ", ".join(name for name, p in r.peaks_json.items() if p.get("ok") is False) or "--"
        body.append([escape(r.scenario), Raw(r"\texttt{" + escape(r.planner) + "}"), escape(r.status),
                     sci(r.cost, 6) if r.cost is not None else Raw("--"),
                     Raw(f"{100 * r.bound_cost_rel:+.2f}\\,\\%") if r.bound_cost_rel is not None else Raw("--"),
                     Raw("--") if r.imposed is None else ("yes" if r.imposed else "judged"), escape(exceeded)])
    lim = ", ".join(f"{k} {list(v) if isinstance(v, tuple) else v}" for k, v in PASSENGER_CAR.given().items())
    notes = (f"Limits: a passenger car ({lim}). Status infeasible: certified (Farkas) at every candidate; "
             "limits\\_violated: a verified plan beyond a bound its planner does not impose (judged by its exact "
             "peaks). Bounds cost: against the same planner without limits.")
    return booktabs_table(["scenario", "planner", "status", Raw("$J$"), "bounds cost", "imposed", "exceeds"], body,
                          caption="The paper's scenarios under a passenger car's limits", label="tab:bounded",
                          align="lllrrll", notes=notes)
