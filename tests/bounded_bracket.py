"""Shared by the rule-B6 bracket tests (tests/test_agreement_zoh_bracket.py and
tests/test_agreement_foh_bracket.py): the generated bounded problems, a PMP / QP pair of runs and
the bracket property, written once for both holds."""

from __future__ import annotations

import copy

import numpy as np

from iamp.comparison.agreement.judge import compare_problem, default_configs
from iamp.comparison.agreement.runs import QPConfig, Run, run_pmp, run_qp
from iamp.core.physical import PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.examples import random_problem
from iamp.planners.pmp import PMPPlanner


def bounded(seed: int, frac: float) -> Problem:
    """``random_problem(seed)`` with the input box at ``frac`` of its unbounded PMP's inputs
    (at least ±0.5), as in tests/test_issue29_compare.py."""
    problem = random_problem(seed)
    U = PMPPlanner().plan(problem).inputs(np.linspace(0.0, problem.tf, 2001))
    return problem.with_limits(PhysicalLimits(
        ax=(frac * min(-0.5, float(U[:, 0].min())), frac * max(0.5, float(U[:, 0].max()))),
        ay=(frac * min(-0.5, float(U[:, 1].min())), frac * max(0.5, float(U[:, 1].max())))))


def run_pair(problem: Problem, N: int, hold: str) -> tuple[Run, Run]:
    """The bounded PMP's run and the Clarabel QP's run with ``hold`` on ``N`` steps."""
    pmp = run_pmp(problem, repeats=1, warmup=0)
    qp = run_qp(problem, QPConfig(solver="clarabel", hold=hold, steps=N), repeats=1, warmup=0, budget_s=0.0)
    return pmp, qp


def with_cost(plan: Plan, factor: float) -> Plan:
    """A copy of ``plan`` claiming ``factor`` times its cost."""
    wrong = copy.copy(plan)
    wrong.cost = float(plan.cost) * factor  # type: ignore[arg-type]
    return wrong


def bracket_property(seed: int, frac: float, N: int, hold: str) -> None:
    """Whenever the bounded PMP is certified optimal and the QP with ``hold`` is optimal, the pair
    agrees, and rule B6's bracket holds: 0 <= J_QP - J_b(t_Q) <= D (or a note says why the upper
    side could not be built)."""
    comp = compare_problem(bounded(seed, frac), default_configs(steps=(N,), solvers=("clarabel",), holds=(hold,)),
                           repeats=1, pmp_repeats=1, warmup=0, budget_s=0.0)
    pmp = comp.run("pmp").result
    (judged,) = comp.agreement
    qp = comp.run(judged["b"]).result
    if not (pmp.status == "optimal" and pmp.diagnostics.certified_global and qp.status == "optimal"):
        return
    assert judged["verdict"] == "agree", judged["reasons"]
    b = judged["bounded"]  # type: ignore[typeddict-item]
    J = b["pmp_at_contact_times_cost"]
    assert b["excess"] >= -1e-9 * J
    if b[f"{hold}_upper_reason"] is None:
        assert judged["checks"][f"bounded_{hold}_excess_rel"]["ok"]
        assert b["excess"] <= b[f"{hold}_upper_excess"] + 1e-9 * J
    else:
        assert any("upper side is not applied" in note for note in judged["notes"])


class WrongAtContactTimes:
    """A PMP whose fixed-contact-time plans report ``factor`` x their cost, or plan with the box
    widened by ``widen`` (its plans leave the problem's box), or at contact times later by
    ``shift`` (its plans miss the corner at the times asked)."""

    factor, widen, shift = 1.0, 1.0, 0.0

    def plan(self, problem: Problem, contact_times: object = None) -> Plan:
        if self.shift:
            return PMPPlanner().plan(problem, contact_times=np.asarray(contact_times) + self.shift)
        if self.widen != 1.0 and problem.limits is not None:
            lim = problem.limits
            wide = PhysicalLimits(ax=tuple(self.widen * x for x in lim.ax),  # type: ignore[arg-type, union-attr]
                                  ay=tuple(self.widen * x for x in lim.ay))  # type: ignore[arg-type, union-attr]
            return PMPPlanner().plan(problem.with_limits(wide), contact_times=contact_times)
        return with_cost(PMPPlanner().plan(problem, contact_times=contact_times), self.factor)
