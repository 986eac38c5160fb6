r"""The library's front door (SPEC §12): load a scenario, plan it, compare planners.

>>> import iamp
>>> prob = iamp.load_scenario("paper-1-poly")
>>> plan = iamp.plan(prob)
>>> plan.status
'optimal'

Every planner solves the same problem: minimise the comfort cost

.. math::  J = \tfrac12 \int_0^{t_f} \big(u_x^2 + u_y^2\big)\,dt

of a planar double integrator between fixed boundary states, subject to one interior-point
equality per surrounding vehicle :math:`i` — at a free contact time :math:`t_i` the ego passes
through the named corner of the vehicle's safety box,

.. math::  s_x(t_i) = x_{s,i}(t_i) \pm (L_i/2 + S_{x,i}), \qquad s_y(t_i) = y_{s,i} \pm (W_i/2 + S_{y,i}),

(``planner="pmp"``: Pontryagin's minimum principle with co-state and Hamiltonian jump
conditions, the global contact times; ``planner="qp"``: the discretised QP of SPEC §3 with a
search over grid contact times), or — with ``constraint="avoid"`` — the avoidance QP of
SPEC §10, whose ego stays out of every safety region.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from iamp.core.errors import ScenarioError
from iamp.core.plan import Plan
from iamp.core.problem import Problem

PLANNERS = ("pmp", "qp")
CONSTRAINTS = ("equality", "avoid")


def load_scenario(spec: str | Path, model: str | Path | None = None) -> Problem:
    """A built-in scenario name or a TOML file (SPEC §4) as a plannable :class:`Problem`.

    Vehicles given by an observed ``history`` are predicted by the shared predictor (the
    shipped model, or the model file ``model``) and enter as the fitted cubic of SPEC §7;
    vehicles given by ``x_poly`` pass through unchanged.

    Raises
    ------
    iamp.ScenarioError
        The file or a field is invalid (the message names the file and the field).
    """
    from iamp.prediction.resolve import load_problem

    _, problem, _ = load_problem(str(spec), None if model is None else str(model))
    return problem


def plan(problem: Problem, planner: str = "pmp", *, solver: str | None = None, hold: str | None = None,
         steps: int = 100, contact: str | None = None, constraint: str = "equality") -> Plan:
    """Plan the lane change of ``problem``.

    Parameters
    ----------
    problem : Problem
    planner : {"pmp", "qp"}
        ``"pmp"`` (default): the indirect method with jump conditions, global contact times.
        ``"qp"``: the discretised QP on a uniform grid ``t_k = k t_f / N``.
    solver : {"clarabel", "osqp", ...}, optional
        QP backend (default ``"clarabel"``); QP only.
    hold : {"foh", "zoh"}, optional
        Input hold of the QP (default ``"foh"``, which is exact: SPEC §3.1); QP only.
    steps : int
        ``N``, the QP's grid intervals (and the JSON's output sampling for every planner).
    contact : {"grid", "refine"}, optional
        The QP's contact-time search: every grid node, or refined off the grid (default
        ``"grid"``); QP only.
    constraint : {"equality", "avoid"}
        The paper's interior-point equality (default) or the avoidance inequalities of
        SPEC §10 (QP only).

    Returns
    -------
    Plan
        A solver failure is a :class:`Plan` with a failure status and no cost, never an
        exception with a half result.

    Raises
    ------
    iamp.ScenarioError
        An option that does not exist or does not apply to the chosen planner.
    """
    if not isinstance(problem, Problem):
        raise ScenarioError(f"must be an iamp.Problem (got {type(problem).__name__})", "problem")
    if planner not in PLANNERS:
        raise ScenarioError(f"unknown planner {planner!r}; choose from {', '.join(PLANNERS)}", "planner")
    if constraint not in CONSTRAINTS:
        raise ScenarioError(f"unknown constraint {constraint!r}; choose from {', '.join(CONSTRAINTS)}", "constraint")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ScenarioError(f"must be a positive integer (got {steps!r})", "steps")
    if planner == "pmp":
        options = (("solver", solver), ("hold", hold), ("contact", contact))
        given = [name for name, value in options if value is not None]
        if given:
            raise ScenarioError("applies to the QP only (planner='qp')", given[0])
        if constraint != "equality":
            raise ScenarioError("the PMP planner implements the paper's equality only; use planner='qp'",
                                "constraint")
        from iamp.planners.pmp.planner import PMPPlanner

        result: Plan = PMPPlanner().plan(problem)
        return result
    kwargs: dict[str, Any] = {"steps": steps, "hold": hold or "foh", "solver": solver or "clarabel",
                              "contact": contact or "grid"}
    if constraint == "avoid":
        from iamp.planners.avoid.planner import AvoidQPPlanner

        return AvoidQPPlanner(**kwargs).plan(problem)
    from iamp.planners.qp.planner import QPPlanner

    return QPPlanner(**kwargs).plan(problem)


def compare(problem: Problem, *, steps: tuple[int, ...] | None = None,
            solvers: tuple[str, ...] = ("osqp", "clarabel"), holds: tuple[str, ...] = ("foh", "zoh"),
            repeats: int = 3) -> dict[str, Any]:
    """Run the PMP and every QP configuration on ``problem`` and judge every pair.

    Returns the object of SPEC §5b's ``iamp compare --json`` for this one problem:
    ``{"scenarios": [{"name", "runs", "agreement", ...}]}``.  In ``agreement`` the headline
    gaps compare the two runs as they came out; the identity at the QP's own contact times
    is under ``at_same_contact_times`` (see :mod:`iamp.comparison.agreement.judge` for every rule).

    Parameters
    ----------
    steps : tuple of int, optional
        QP grids (default ``(100,)`` for one vehicle, ``(20,)`` for more: a sweep over
        ``m`` contact times solves ``(N-1)!/(N-1-m)!`` QPs).
    solvers, holds : tuple of str
    repeats : int
        Timed plans per QP configuration.
    """
    from iamp.comparison.agreement.judge import compare_problem, default_configs

    if not isinstance(problem, Problem):
        raise ScenarioError(f"must be an iamp.Problem (got {type(problem).__name__})", "problem")
    grid = steps if steps is not None else ((100,) if problem.m == 1 else (20,))
    for n in grid:
        if n < problem.m + 1:
            raise ScenarioError(f"must be at least {problem.m + 1} for {problem.m} vehicle(s) (got {n})", "steps")
    configs = default_configs(steps=tuple(grid), solvers=tuple(solvers), holds=tuple(holds))
    comp = compare_problem(problem, configs, name=problem.name, repeats=repeats)
    return {"scenarios": [comp.to_json()]}
