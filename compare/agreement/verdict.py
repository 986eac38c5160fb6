r"""How a pair of runs gets its verdict: named checks ``value ≤ limit`` and rules 0–1.

A verdict (SPEC §5b ``agreement[k].verdict``) is ``agree`` exactly when every check of the
pair passed; each failed check adds a reason (``name: value > limit (why)``), and
observations that do not fail the pair go to ``notes``.  The rules themselves are listed in
:mod:`iamp.comparison.agreement.judge`; this module holds the two every pair shares:

0. *Same problem*: both planners report the identical problem — the sha256 fingerprints of
   the ``x_poly`` coefficients, and of all other data, are equal
   (:mod:`iamp.comparison.agreement.fingerprints`).
1. *The PMP's own conditions*: every residual :math:`r` of
   :meth:`~iamp.planners.pmp.planner.PMPSolution.residuals` satisfies
   :math:`r / s \le` ``pmp_condition_residual`` with the scale
   :math:`s = \max(1, |J^*|, \max_k |x_{f,k}|)`, and the Hamiltonian-jump residual at
   ``t*`` satisfies :math:`r_H / \max(1, J^*) \le` ``pmp_hjump_at_optimum``.

Limits come from the TOLERANCES table (:func:`iamp.core.tolerances.tol`); a solver's own
limits are named ``cmp_<kind>_<solver>`` (:func:`solver_tol`).
"""

from __future__ import annotations

import numpy as np

from iamp.core.plan import Plan
from iamp.core.tolerances import tol

from .records import CheckJSON, PairJSON
from .runs import Run

__all__ = ["VERDICT_AGREE", "VERDICT_DISAGREE", "Checks", "plan_cost", "pmp_own_checks", "same_problem",
           "solver_tol"]

VERDICT_AGREE, VERDICT_DISAGREE = "agree", "disagree"


class Checks:
    """Collects named checks ``value ≤ limit`` and free-text notes."""

    def __init__(self) -> None:
        self.items: dict[str, CheckJSON] = {}
        self.reasons: list[str] = []
        self.notes: list[str] = []

    def check(self, name: str, value: float | None, limit: float | None, ok: bool | None = None,
              why: str = "") -> bool:
        """Record ``value ≤ limit`` (or the given ``ok``) under ``name``; a failure adds a reason."""
        v = float(value) if value is not None else None
        lim = float(limit) if limit is not None else None
        if ok is None:
            ok = v is not None and lim is not None and bool(np.isfinite(v)) and v <= lim
        passed = bool(ok)
        self.items[name] = {"value": v, "limit": lim, "ok": passed}
        if not passed:
            self.reasons.append(f"{name}: {v:.3g} > {lim:.3g}" + (f" ({why})" if why else "")
                                if v is not None and lim is not None else f"{name} failed ({why})")
        return passed

    def fail(self, text: str) -> None:
        """A failure that is not a number against a limit."""
        self.reasons.append(text)

    def verdict(self) -> str:
        """``agree`` when nothing failed, else ``disagree``."""
        return VERDICT_AGREE if not self.reasons else VERDICT_DISAGREE

    def finish(self, out: PairJSON) -> PairJSON:
        """``out`` with ``verdict``, ``reasons``, ``notes`` and ``checks`` appended (in that order)."""
        out["verdict"] = self.verdict()
        out["reasons"] = self.reasons
        out["notes"] = self.notes
        out["checks"] = self.items
        return out


def solver_tol(kind: str, solver: str) -> float:
    """The comparison limit ``cmp_<kind>_<solver>`` of the TOLERANCES table."""
    return tol(f"cmp_{kind}_{solver}")


def plan_cost(plan: Plan) -> float:
    """The cost of a verified plan (callers check ``Run.ok`` first)."""
    return float("nan") if plan.cost is None else float(plan.cost)


def same_problem(a: Run, b: Run, checks: Checks) -> None:
    """Rule 0: both runs report the identical problem (``x_poly`` first, then all other data)."""
    if a.x_poly_fingerprint != b.x_poly_fingerprint:
        checks.fail(f"the planners received different x_poly (sha256 {a.x_poly_fingerprint[:12]} vs "
                    f"{b.x_poly_fingerprint[:12]})")
    elif a.fingerprint != b.fingerprint:
        checks.fail(f"the planners received different problem data (sha256 {a.fingerprint[:12]} vs "
                    f"{b.fingerprint[:12]})")


def pmp_own_checks(pmp: Run, checks: Checks) -> None:
    """Rule 1: the PMP's residuals, recomputed by the plan, against the TOLERANCES table."""
    res = pmp.result
    cost = plan_cost(res)
    scale = max(1.0, abs(cost), float(np.max(np.abs(res.problem.ego.final))))
    for name in ("linear_system", "boundary", "interior_constraint", "h_minimisation", "costate_jump"):
        if name in res.residuals:
            checks.check(f"pmp_{name}_residual", res.residuals[name] / scale, tol("pmp_condition_residual"))
    if "hamiltonian_jump" in res.residuals:
        checks.check("pmp_hamiltonian_jump_at_t*", res.residuals["hamiltonian_jump"] / max(1.0, cost),
                     tol("pmp_hjump_at_optimum"))
