r"""The bounded problem beside the paper's (SPEC §14, issue 19 item 7).

One scenario under a table of physical limits (default: :data:`iamp.core.physical.PASSENGER_CAR`)
planned by every planner that takes the problem:

* ``pmp`` — the PMP (bounded where the bounded PMP of ``planners/pmp/bounded.py`` exists,
  otherwise the paper's unbounded PMP, judged against the bounds);
* ``equality`` — the equality QP with every bound at every node (:mod:`iamp.planners.qp.bounded`);
* ``active`` — ``--constraint active`` around the equality QP (``planners/active_set.py``);
* ``avoid`` — the avoidance QP (SPEC §10).

Each row: the status (``optimal``, ``local``, ``infeasible`` with its reason,
``limits_violated`` when a planner that cannot impose a bound returns a plan beyond it), the
cost, the exact peaks (:mod:`iamp.core.peaks`), and what the bounds cost,
:math:`(J_\text{bounded} - J_\text{free}) / J_\text{free}`, against the same planner on the
unbounded problem.  ``pmp_vs_qp`` is the relative cost gap
:math:`|J_\text{PMP} - J_\text{QP}| / J_\text{QP}` when both are verified under the bounds (the
FOH QP's grid restricts the contact times and its jerk rows are per interval, so the gap falls
with :math:`N` rather than vanishing).  A planner whose module is not installed is reported as
``not available`` with the module it needs, never silently left out.
"""

from __future__ import annotations

import importlib.util
import time
from dataclasses import dataclass, field
from typing import TypedDict

from iamp.core.errors import IampError, ScenarioError
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.status import SUCCESS
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.registry import Planner

__all__ = ["BOUNDED_PLANNERS", "BoundedRow", "bounded_rows", "bounded_section", "markdown_table",
           "pmp_qp_gap", "section_lines"]

#: The planners of the bounded comparison, in table order, with the module each needs.
BOUNDED_PLANNERS: dict[str, str] = {
    "pmp": "iamp.planners.pmp.planner",
    "equality": "iamp.planners.qp.bounded",
    "active": "iamp.planners.active_set",
    "avoid": "iamp.planners.avoid.planner",
}


class BoundedRowJSON(TypedDict):
    """:meth:`BoundedRow.to_json`: one planner on one bounded scenario."""

    scenario: str
    planner: str
    available: bool
    status: str
    cost: float | None
    free_cost: float | None
    bound_cost_rel: float | None
    limits: dict[str, dict[str, object]]
    imposed: bool | None
    reason: str | None
    time_s: float | None


class BoundedSection(TypedDict):
    """:func:`bounded_section`: one scenario's bounded comparison (``iamp compare --bounded``)."""

    limits: dict[str, tuple[float, float] | float] | None
    steps: int
    hold: str
    solver: str
    rows: list[BoundedRowJSON]
    pmp_vs_qp_rel_gap: float | None


@dataclass
class BoundedRow:
    """One planner on one bounded scenario (module docstring)."""

    scenario: str
    planner: str
    available: bool
    status: str
    cost: float | None = None
    free_cost: float | None = None
    peaks: str = ""
    peaks_json: dict[str, dict[str, object]] = field(default_factory=dict)
    imposed: bool | None = None
    reason: str | None = None
    time_s: float | None = None

    @property
    def bound_cost_rel(self) -> float | None:
        """What the bounds cost: :math:`(J - J_\\text{free}) / J_\\text{free}`."""
        if self.cost is None or self.free_cost is None or self.free_cost <= 0:
            return None
        return (self.cost - self.free_cost) / self.free_cost

    def to_json(self) -> BoundedRowJSON:
        return {"scenario": self.scenario, "planner": self.planner, "available": self.available,
                "status": self.status, "cost": self.cost, "free_cost": self.free_cost,
                "bound_cost_rel": self.bound_cost_rel, "limits": self.peaks_json, "imposed": self.imposed,
                "reason": self.reason, "time_s": self.time_s}


def _available(planner: str) -> bool:
    try:
        return importlib.util.find_spec(BOUNDED_PLANNERS[planner]) is not None
    except ModuleNotFoundError:
        return False


def _planner(planner: str, steps: int, hold: str, solver: str) -> Planner:
    """The planner object (imports only what is installed; see :func:`_available`)."""
    if planner == "pmp":
        from iamp.planners.pmp.planner import PMPPlanner

        return PMPPlanner()
    from iamp.planners.qp.planner import QPPlanner

    if planner == "equality":
        return QPPlanner(steps=steps, hold=hold, solver=solver)
    if planner == "active":
        active_set = importlib.import_module("iamp.planners.active_set")
        active: Planner = active_set.ActiveSetPlanner(QPPlanner(steps=steps, hold=hold, solver=solver), "qp")
        return active
    from iamp.planners.avoid.planner import AvoidQPPlanner

    return AvoidQPPlanner(steps=steps, hold=hold, solver=solver)


def _imposes(planner: str, plan: Plan) -> bool:
    """Whether the planner imposed the bounds (rather than being judged after the fact)."""
    if planner == "pmp":
        return _available_module("iamp.planners.pmp.bounded")  # restructure: keep
    qp = plan.diagnostics.find(QPDiagnostics)  # active set: its base's diagnostics
    return (qp is not None and qp.limit_rows is not None) or plan.diagnostics.limits_infeasible is not None


def _available_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def bounded_rows(name: str, problem: Problem, limits: PhysicalLimits | None = PASSENGER_CAR, steps: int = 50,
                 hold: str = "foh", solver: str = "clarabel",
                 planners: tuple[str, ...] = tuple(BOUNDED_PLANNERS)) -> list[BoundedRow]:
    """Plan ``problem`` under ``limits`` (``None``: the scenario's own ``[limits]``) with each
    planner, and the same planner without limits for what the bounds cost (module docstring).

    Every plan is judged (:meth:`iamp.core.plan.Plan.judge_limits`): a planner that returns a
    plan beyond a bound gets ``limits_violated``, never ``optimal``.
    """
    bounded = problem.with_limits(limits) if limits is not None else problem
    free_problem = problem.with_limits(None)
    rows: list[BoundedRow] = []
    for planner in planners:
        if not _available(planner):
            rows.append(BoundedRow(name, planner, False, "not available",
                                   reason=f"needs {BOUNDED_PLANNERS[planner]} (not on this branch)"))
            continue
        if planner in ("active", "avoid") and bounded.m == 0:
            rows.append(BoundedRow(name, planner, True, "not applicable", reason="no vehicle"))
            continue
        runner = _planner(planner, steps, hold, solver)
        start = time.perf_counter()
        try:
            plan = runner.plan(bounded).judge_limits()
            elapsed = time.perf_counter() - start
            free = runner.plan(free_problem)
        except IampError as exc:  # the planner refuses this scenario (e.g. a corner it cannot avoid)
            text = exc.one_line() if isinstance(exc, ScenarioError) else str(exc)
            rows.append(BoundedRow(name, planner, True, "refused", reason=" ".join(text.split())))
            continue
        pk = plan.peaks
        rows.append(BoundedRow(
            name, planner, True, plan.status, cost=plan.cost if plan.status in SUCCESS else None,
            free_cost=free.cost if free.status in SUCCESS else None,
            peaks=pk.line() if pk is not None else "", peaks_json=pk.to_json() if pk is not None else {},
            imposed=_imposes(planner, plan) if plan.trajectory is not None or _imposes(planner, plan) else None,
            reason=plan.diagnostics.reason or plan.diagnostics.why,
            time_s=elapsed))
    return rows


def bounded_section(name: str, problem: Problem, limits: PhysicalLimits | None = PASSENGER_CAR, steps: int = 50,
                    hold: str = "foh", solver: str = "clarabel") -> BoundedSection:
    """The JSON of one scenario's bounded comparison: the rows, the limits and the PMP = QP gap."""
    rows = bounded_rows(name, problem, limits, steps, hold, solver)
    lim = limits if limits is not None else problem.limits
    return {"limits": None if lim is None else lim.given(),
            "steps": steps, "hold": hold, "solver": solver, "rows": [r.to_json() for r in rows],
            "pmp_vs_qp_rel_gap": pmp_qp_gap(rows)}


def pmp_qp_gap(rows: list[BoundedRow]) -> float | None:
    r"""PMP = bounded QP: :math:`|J_\text{PMP} - J_\text{QP}| / J_\text{QP}` of one scenario's
    rows when both are verified under the bounds and the PMP imposed them (the bounded PMP);
    ``None`` otherwise."""
    by = {r.planner: r for r in rows}
    pmp, eq = by.get("pmp"), by.get("equality")
    if pmp is None or eq is None or pmp.cost is None or eq.cost is None or not pmp.imposed:
        return None
    return abs(pmp.cost - eq.cost) / max(abs(eq.cost), 1e-300)


def _fmt(x: float | None, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def section_lines(name: str, section: BoundedSection) -> list[str]:
    """Text lines of :func:`bounded_section` for ``iamp compare --bounded``."""
    out = [f"bounded problem ({name}; N = {section['steps']}, {section['hold']}, {section['solver']}):"]
    for r in section["rows"]:
        head = (f"  {r['planner']:9s} {r['status']:15s} J {_fmt(r['cost'], '.6g'):>12s}  "
                f"bounds cost {_fmt(None if r['bound_cost_rel'] is None else 100 * r['bound_cost_rel'], '+.2f')} %")
        if r["available"] and r["imposed"] is False:
            head += "  (bounds judged, not imposed)"
        out.append(head)
        if r["reason"]:
            out.append(f"            reason: {r['reason']}")
    if section["pmp_vs_qp_rel_gap"] is not None:
        out.append(f"  bounded PMP vs bounded QP: relative cost gap {section['pmp_vs_qp_rel_gap']:.3e}")
    return out


def markdown_table(rows: list[BoundedRow]) -> str:
    """The closing table of issue 19: scenario, planner, status, cost, what the bounds cost, peaks."""
    lines = ["| scenario | planner | status | J | bounds cost | imposed | peaks / reason |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        rel = None if r.bound_cost_rel is None else f"{100 * r.bound_cost_rel + 0.0:+.2f} %".replace("-0.00", "+0.00")
        what = r.peaks if r.peaks else ""
        if r.reason and r.status != "limits_violated":  # limits_violated: the peaks say it (EXCEEDS)
            what = (what + " — " if what else "") + r.reason.replace("|", "/")
        imposed = "-" if r.imposed is None else ("yes" if r.imposed else "no (judged)")
        lines.append(f"| {r.scenario} | {r.planner} | {r.status} | {_fmt(r.cost, '.6g')} | {rel or '-'} | "
                     f"{imposed} | {what} |")
    return "\n".join(lines)
