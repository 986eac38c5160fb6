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
    r"""Load a built-in scenario or a TOML scenario file (SPEC §4) as a plannable :class:`Problem`.

    Vehicles given by an observed ``history`` are predicted by the shared predictor
    (:class:`iamp.Predictor`: the shipped model, or the model file ``model``) and enter as
    the least-squares cubic of SPEC §7,

    .. math::  x_s(t) = c_0 + c_1 t + c_2 t^2 + c_3 t^3 ;

    vehicles given by ``x_poly`` pass through unchanged.

    Parameters
    ----------
    spec : str or pathlib.Path
        The path of a TOML scenario file, or the name of a built-in scenario (``iamp scenarios``
        lists them: ``"paper-1"``, ``"paper-1-poly"``, ..., ``"two-vehicle"``); an existing
        file of that name wins over a built-in.
    model : str or pathlib.Path, optional
        A predictor model file (JSON, as ``iamp train`` writes it) for the vehicles given by a
        ``history``; default: the model shipped with the package.

    Returns
    -------
    Problem
        The validated problem: the ego's boundary states and one
        :class:`SurroundingVehicle` per ``[[vehicles]]`` table, in the file's order.

    Raises
    ------
    iamp.ScenarioError
        The file cannot be read, is not TOML, or a field is missing, unknown, invalid or beyond
        the bounds of SPEC §6 (the message names the file, its line and the field).
    iamp.HistoryError
        A vehicle's ``history`` cannot be used by the predictor (too short, not strictly
        increasing, not ending at ``t = 0``); a subclass of :class:`iamp.ScenarioError`.
    iamp.prediction.mtd.ModelFileError
        The model file ``model`` cannot be read or is not a valid model (an
        :class:`iamp.IampError`).

    See Also
    --------
    plan : Plan the loaded problem.

    Examples
    --------
    >>> import iamp
    >>> problem = iamp.load_scenario("paper-1-poly")
    >>> problem.m, problem.tf
    (1, 5.0)
    >>> problem.vehicles[0].corner, problem.vehicles[0].x_poly
    ('front-lower', (-15.0, 18.0, 0.0, 0.0))
    """
    from iamp.prediction.resolve import load_problem

    _, problem, _ = load_problem(str(spec), None if model is None else str(model))
    return problem


def plan(problem: Problem, planner: str = "pmp", *, solver: str | None = None, hold: str | None = None,
         steps: int = 100, contact: str | None = None, constraint: str = "equality", **options: Any) -> Plan:
    r"""Plan the lane change of ``problem``: the minimum-comfort-cost trajectory through every corner.

    Every planner minimises :math:`J = \tfrac12 \int_0^{t_f} (u_x^2 + u_y^2)\,dt` of the planar
    double integrator between the fixed boundary states, with the ego at the corner of each
    vehicle's safety box at that vehicle's contact time :math:`t_i` (module docstring).  The
    plan is judged against ``problem.limits`` (SPEC §14) before it is returned.

    Parameters
    ----------
    problem : Problem
        The problem to plan (:func:`load_scenario`, or built directly).
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
        exception with a half result.  ``plan.status`` is ``"optimal"`` only after the plan
        checked its own residuals; ``plan.states(t)`` and ``plan.inputs(t)`` evaluate it.

    Raises
    ------
    iamp.OptionError
        An option (planner, constraint, solver, hold, contact, steps) that does not exist, has an
        invalid value or does not apply to the chosen planner; the message names the choices.
        It derives from :class:`iamp.ScenarioError` and :class:`iamp.IampError`.
    iamp.ScenarioError
        ``problem`` is not an :class:`iamp.Problem`.

    See Also
    --------
    PMPPlanner : The PMP planner with its options.
    compare : Run the PMP and the QP configurations and judge their agreement.

    Examples
    --------
    >>> import iamp
    >>> problem = iamp.load_scenario("paper-1-poly")
    >>> plan = iamp.plan(problem)
    >>> plan.status, round(plan.cost, 3)
    ('optimal', 22.865)
    >>> plan.contact_times.round(3).tolist()
    [3.52]
    >>> qp = iamp.plan(problem, "qp", solver="clarabel", steps=100)
    >>> qp.status, qp.contact_times.round(3).tolist()
    ('optimal', [3.5])
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

    Every configuration (each solver with each hold on each grid) plans the **same**
    :class:`Problem` object; every pair ``(pmp, QP)`` and ``(QP, QP)`` is judged by the rules of
    :mod:`iamp.comparison.agreement.judge` (same problem, statuses, the QP against its exact
    reference at its own contact times, KKT residuals recomputed from the matrices, constraint
    residuals).  In ``agreement`` the headline gaps compare the two runs as they came out; the
    identity at the QP's own contact times is under ``at_same_contact_times``.

    Parameters
    ----------
    problem : Problem
        The problem every planner solves.
    steps : tuple of int, optional
        QP grids ``N`` (default ``(100,)`` for one vehicle, ``(20,)`` for more: a sweep over
        ``m`` contact times solves ``(N-1)!/(N-1-m)!`` QPs).
    solvers : tuple of str
        QP backends (default ``("osqp", "clarabel")``; see :func:`plan`'s ``solver``).
    holds : tuple of str
        Input holds (default ``("foh", "zoh")``; see :func:`plan`'s ``hold``).
    repeats : int
        Timed plans per QP configuration.

    Returns
    -------
    Comparison
        ``.scenarios[0]`` is the
        :class:`~iamp.comparison.agreement.judge.ProblemComparison` with ``runs`` and
        ``agreement``; ``to_json()`` is the object of SPEC §5b's ``iamp compare --json`` for
        this one problem, ``{"scenarios": [{"name", "runs", "agreement", ...}]}``.

    Raises
    ------
    iamp.ScenarioError
        ``problem`` is not an :class:`iamp.Problem`, a grid has fewer than ``m + 1`` steps, or
        every hold is ``"zoh"`` under a jerk bound (``limits.jerk``).
    iamp.OptionError
        An unknown solver or hold (the message names the choices).

    See Also
    --------
    plan : One planner on one problem.

    Examples
    --------
    >>> import iamp
    >>> problem = iamp.load_scenario("paper-1-poly")
    >>> comparison = iamp.compare(problem, steps=(20,), solvers=("clarabel",), holds=("foh",), repeats=1)
    >>> [run.label for run in comparison.scenarios[0].runs]
    ['pmp', 'qp-clarabel-foh-20']
    >>> comparison.all_agree
    True
    >>> sorted(comparison.to_json()["scenarios"][0])[:4]
    ['agreement', 'm', 'name', 'pmp']
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
