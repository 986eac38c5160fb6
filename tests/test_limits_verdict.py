"""SPEC §14: no verified plan of any planner exceeds a given bound.

Over generated scenarios and bounds, every plan that ``iamp.api.plan`` returns (PMP, equality
QP on each backend and hold, avoidance QP) as ``optimal`` or ``local`` lies within every bound
by its exact peaks and by a dense evaluation of its own trajectory; a plan beyond a bound is
``limits_violated`` and names the bound.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp import api
from iamp.core import status as sts
from iamp.core.errors import ScenarioError
from iamp.core.physical import PhysicalLimits
from iamp.core.plan import Plan
from iamp.planners.examples import random_problem

DENSE = 20_001


@st.composite
def bounds(draw: st.DrawFn) -> PhysicalLimits:
    """Bounds from generous to tight (the random scenarios peak at 1-30 m/s^2)."""
    ax = (-draw(st.floats(0.5, 12.0)), draw(st.floats(0.5, 12.0)))
    ay = (-draw(st.floats(0.3, 5.0)), draw(st.floats(0.3, 5.0)))
    vx = (draw(st.floats(0.0, 12.0)), draw(st.floats(25.0, 60.0)))
    return PhysicalLimits(ax=ax, ay=ay, a_total=draw(st.floats(1.0, 15.0)), vx=vx)


def _dense_within(plan: Plan, lim: PhysicalLimits) -> None:
    """The plan's own trajectory on a dense grid is inside every bound (tolerance 1e-6 relative)."""
    t = np.linspace(0.0, plan.problem.tf, DENSE)
    X, U = plan.states(t), plan.inputs(t)
    assert lim.ax is not None and lim.ay is not None and lim.vx is not None and lim.a_total is not None
    for col, (lo, hi) in ((0, lim.ax), (1, lim.ay)):
        assert U[:, col].min() >= lo - 1e-6 * max(1.0, abs(lo))
        assert U[:, col].max() <= hi + 1e-6 * max(1.0, abs(hi))
    assert np.hypot(U[:, 0], U[:, 1]).max() <= lim.a_total * (1 + 1e-6)
    assert X[:, 1].min() >= lim.vx[0] - 1e-6 * max(1.0, lim.vx[0])
    assert X[:, 1].max() <= lim.vx[1] * (1 + 1e-6)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**6), bounds(),
       st.sampled_from([("pmp", None, None, "equality"), ("qp", "clarabel", "foh", "equality"),
                        ("qp", "osqp", "zoh", "equality"), ("qp", "piqp", "foh", "equality"),
                        ("qp", "clarabel", "foh", "avoid")]))
def test_no_verified_plan_exceeds_a_given_bound(seed: int, lim: PhysicalLimits,
                                                config: tuple[str, str | None, str | None, str]) -> None:
    planner, solver, hold, constraint = config
    problem = random_problem(seed).with_limits(lim)
    try:
        plan = api.plan(problem, planner, solver=solver, hold=hold, steps=24, constraint=constraint)
    except ScenarioError as exc:  # the avoidance QP refuses a corner that does not describe the manoeuvre
        assert constraint == "avoid" and "corner" in str(exc)
        return
    if plan.status in sts.SUCCESS:
        assert plan.peaks is not None and plan.peaks.within, plan.peaks.line() if plan.peaks else None
        _dense_within(plan, lim)
    elif plan.status == sts.LIMITS_VIOLATED:
        assert plan.peaks is not None and plan.peaks.exceeded
        for p in plan.peaks.exceeded:
            assert p.name in plan.info["reason"] and p.violation > 0
    else:
        assert plan.cost is None or plan.status not in sts.SUCCESS


def test_the_verdict_is_idempotent_and_names_the_bound() -> None:
    # the PMP imposes the input box exactly (SPEC §14, planners/pmp/bounded.py): a tight ax is
    # within its peaks or infeasible with the reason, never exceeded
    problem = random_problem(3).with_limits(PhysicalLimits(ax=(-0.5, 0.5)))
    plan = api.plan(problem, "pmp")
    free = api.plan(problem.with_limits(None), "pmp")
    assert free.status == sts.OPTIMAL
    if plan.peaks is not None:
        peak = plan.peaks.peaks["ax"].peak
        assert plan.ok and -0.5 - 1e-9 <= peak[0] and peak[1] <= 0.5 + 1e-9  # type: ignore[index]
    else:
        assert plan.status == sts.INFEASIBLE and plan.info["reason"]
    # a speed bound it cannot impose: the plan is kept, limits_violated, the bound named
    vmax = float(free.states(np.linspace(0, problem.tf, DENSE))[:, 1].max())
    plan = api.plan(problem.with_limits(PhysicalLimits(vx=(0.0, vmax - 1.0))), "pmp")
    assert plan.status == sts.LIMITS_VIOLATED and "vx peaks at" in plan.info["reason"]
    reason = plan.info["reason"]
    assert plan.judge_limits() is plan and plan.info["reason"] == reason
    assert plan.to_json()["status"] == "limits_violated" and plan.to_json()["limits"]["vx"]["ok"] is False
