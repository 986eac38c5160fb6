"""The bounded comparison (SPEC §14) as a LaTeX table for ``iamp reproduce``."""

from __future__ import annotations

from iamp.core.physical import PASSENGER_CAR

from ..bounded import BoundedRow
from .latex import Raw, booktabs_table, escape, sci


def _percent(rel: float) -> str:
    """``rel`` in per cent with a sign and two decimals; a cost change that rounds to zero is
    ``+0.00`` (never ``-0.00``: a plan cannot be cheaper with bounds than without)."""
    text = f"{100 * rel:+.2f}"
    return ("+0.00" if text == "-0.00" else text) + "\\,\\%"


def latex_table(rows: list[BoundedRow]) -> str:
    """The bounded comparison as a booktabs table (``iamp reproduce``: ``tables/bounded.tex``)."""
    body: list[list[str | Raw] | None] = []
    last = None
    for r in rows:
        if last is not None and r.scenario != last:
            body.append(None)
        last = r.scenario
        exceeded = ", ".join(name for name, p in r.peaks_json.items() if p.get("ok") is False) or "--"
        # plain text cells: booktabs_table escapes them (escaped here too, they printed "limits\_violated")
        body.append([r.scenario, Raw(r"\texttt{" + escape(r.planner) + "}"), r.status,
                     sci(r.cost, 6) if r.cost is not None else Raw("--"),
                     Raw(_percent(r.bound_cost_rel)) if r.bound_cost_rel is not None else Raw("--"),
                     Raw("--") if r.imposed is None else ("yes" if r.imposed else "judged"),
                     Raw("--") if exceeded == "--" else exceeded])
    lim = ", ".join(f"{k} {list(v) if isinstance(v, tuple) else v}" for k, v in PASSENGER_CAR.given().items())
    notes = (f"Limits: a passenger car ({lim}). Status infeasible: certified (Farkas) at every candidate; "
             "limits_violated: a verified plan beyond a bound its planner does not impose (judged by its exact "
             "peaks). Bounds cost: against the same planner without limits.")  # plain text: escaped once
    return booktabs_table(["scenario", "planner", "status", Raw("$J$"), "bounds cost", "imposed", "exceeds"], body,
                          caption="The paper's scenarios under a passenger car's limits", label="tab:bounded",
                          align="lllrrll", notes=notes)
