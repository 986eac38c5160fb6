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
from typing import TYPE_CHECKING, Any

from iamp.core.errors import OptionError, ScenarioError
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners import registry

if TYPE_CHECKING:
    from iamp.comparison.agreement.judge import Comparison

#: The planner families and constraint kinds of the registry (:mod:`iamp.planners.registry`).
PLANNERS = registry.planners()
CONSTRAINTS = registry.constraints()


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
         steps: int = 100, contact: str | None = None, constraint: str = "equality", **options: Any) -> Plan:
    """Plan the lane change of ``problem``.

    Parameters
    ----------
    problem : Problem
    planner : str
        A planner family of the registry (:func:`iamp.planners.registry.planners`):
        ``"pmp"`` (default): the indirect method with jump conditions, global contact times.
        ``"qp"``: the discretised QP on a uniform grid ``t_k = k t_f / N``.
    solver : {"clarabel", "osqp", "piqp", "kkt"}, optional
        QP backend (default ``"clarabel"``; every backend of
        :data:`iamp.planners.qp.backends.BACKENDS`; the avoidance QP refuses ``kkt``, which
        solves equality-constrained QPs only); QP only.
    hold : {"foh", "zoh"}, optional
        Input hold of the QP (default ``"foh"``, which is exact: SPEC §3.1); QP only.
    steps : int
        ``N``, the QP's grid intervals (and the JSON's output sampling for every planner).
    contact : {"grid", "refine"}, optional
        The QP's contact-time search: every grid node, or refined off the grid (default
        ``"grid"``); QP only.
    constraint : {"equality", "avoid", "active"}
        The paper's interior-point equality on every vehicle (default), the avoidance
        inequalities of SPEC §10/§14 (QP only; option ``safety="continuous"`` (default) or
        ``"nodes"``), or the equality only on the vehicles in the way, chosen by the jump's
        sign (``"active"``, SPEC §14; PMP and QP).
    **options
        Further fields of the chosen planner's options dataclass (the registry entry's
        ``options``, e.g. :class:`~iamp.planners.pmp.options.PMPOptions` ``max_starts``);
        a name the planner does not have is an :class:`iamp.OptionError` listing its options.

    Returns
    -------
    Plan
        A solver failure is a :class:`Plan` with a failure status and no cost, never an
        exception with a half result.

    Raises
    ------
    iamp.OptionError
        An option (planner, constraint, solver, hold, contact, steps) that does not exist, has an
        invalid value or does not apply to the chosen planner; the message names the choices.
        It derives from :class:`iamp.ScenarioError` and :class:`iamp.IampError`.
    """
    if not isinstance(problem, Problem):
        raise ScenarioError(f"must be an iamp.Problem (got {type(problem).__name__})", "problem")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise OptionError(f"must be a positive integer (got {steps!r})", "steps")
    spec = registry.lookup(planner, constraint)
    given = {"solver": solver, "hold": hold, "contact": contact}
    for name, value in given.items():
        if value is not None and name not in spec.option_names():
            for other in registry.REGISTRY.values():  # an invalid value: name the choices first
                if name in other.option_names():
                    try:
                        other.make_options(**{name: value})
                    except OptionError as exc:
                        raise OptionError(f"{exc.message} ({refusal(name, spec)})", name) from None
            raise OptionError(refusal(name, spec), name)
    values = {**registry.options_of(spec, {"steps": steps, **given}), **options}
    if problem.limits is not None and not problem.limits.empty and isinstance(values.get("solver"), str):
        from iamp.planners.qp.options import check_limits_solver

        check_limits_solver(values["solver"])  # kkt cannot impose [limits]: an OptionError naming the others
    result: Plan = spec.make(**values).plan(problem)
    return result.judge_limits()  # SPEC §14: no verified plan of any planner beyond a given bound


def refusal(option: str, spec: registry.PlannerSpec) -> str:
    """Why ``option`` does not apply to ``spec``'s planner, naming the planners it applies to."""
    accept = registry.accepting(option)
    if accept == ("qp",):
        return "applies to the QP only (planner='qp')"
    return (f"does not apply to planner {spec.planner!r}"
            + (f" (it applies to planner {' or '.join(repr(a) for a in accept)})" if accept else ""))


def compare(problem: Problem, *, steps: tuple[int, ...] | None = None,
            solvers: tuple[str, ...] = ("osqp", "clarabel"), holds: tuple[str, ...] = ("foh", "zoh"),
            repeats: int = 3) -> Comparison:
    """Run the PMP and every QP configuration on ``problem`` and judge every pair.

    Returns a :class:`~iamp.comparison.agreement.judge.Comparison` (``.scenarios[0]``: the
    :class:`~iamp.comparison.agreement.judge.ProblemComparison` with ``runs`` and ``agreement``);
    its ``to_json()`` is the object of SPEC §5b's ``iamp compare --json`` for this one problem:
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
    from iamp.comparison.agreement.judge import Comparison, compare_problem, default_configs

    if not isinstance(problem, Problem):
        raise ScenarioError(f"must be an iamp.Problem (got {type(problem).__name__})", "problem")
    grid = steps if steps is not None else ((100,) if problem.m == 1 else (20,))
    for n in grid:
        if n < problem.m + 1:
            raise ScenarioError(f"must be at least {problem.m + 1} for {problem.m} vehicle(s) (got {n})", "steps")
    configs = default_configs(steps=tuple(grid), solvers=tuple(solvers), holds=tuple(holds))
    comp = compare_problem(problem, configs, name=problem.name, repeats=repeats)
    return Comparison([comp])
