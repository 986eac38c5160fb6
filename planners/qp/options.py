"""The options of the discretised-QP planner (:class:`QPOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iamp.core.errors import OptionError

from .backends import BACKENDS, SUPPORTS_INEQUALITIES
from .hold import HOLDS

#: The contact-time searches of the QP planners: every grid node, or refined off the grid.
CONTACTS = ("grid", "refine")
#: Where the bounded QP imposes the speed and ``y`` bounds (SPEC §14).
LIMITS_BETWEEN = ("nodes", "certified")


def check_choice(value: object, choices: tuple[str, ...] | list[str], field: str, what: str) -> None:
    """Raise :class:`~iamp.core.errors.OptionError` naming the choices unless ``value`` is one."""
    if value not in choices:
        raise OptionError(f"unknown {what} {value!r}; choose from {', '.join(choices)}", field)


def check_steps(steps: object, minimum: int = 1) -> None:
    """``steps`` must be an integer ``>= minimum`` (not a bool)."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < minimum:
        need = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise OptionError(f"must be {need} (got {steps!r})", "steps")


def check_limits_solver(solver: str) -> None:
    """Refuse a backend that cannot impose a scenario's ``[limits]`` (inequality rows).

    Parameters
    ----------
    solver : str
        A registered QP backend.

    Raises
    ------
    OptionError
        ``solver`` solves equality-constrained QPs only (``kkt``); the message names the
        backends that take inequalities (field ``solver``).
    """
    if not SUPPORTS_INEQUALITIES.get(solver, True):
        ok = [name for name, yes in SUPPORTS_INEQUALITIES.items() if yes]
        raise OptionError(f"QP backend {solver!r} solves equality-constrained QPs only, but the scenario's [limits] "
                          f"are inequalities; choose from {', '.join(ok)}", "solver")


@dataclass(frozen=True)
class QPOptions:
    """Options of :class:`~iamp.planners.qp.planner.QPPlanner`.

    Parameters
    ----------
    steps : int
        Grid intervals ``N`` (``t_k = k t_f / N``).
    hold : {"foh", "zoh"}
        Input hold (FOH is exact for this problem: docs/spec.md, the QP baseline).
    solver : str
        A registered QP backend (:data:`iamp.planners.qp.backends.BACKENDS`: osqp, clarabel,
        piqp, kkt).
    contact : {"grid", "refine"}
    limits_between : {"nodes", "certified"}
        With ``problem.limits``: the speed and ``y`` bounds at the nodes only, or certified
        between them (:mod:`iamp.planners.qp.limits`).
    solver_settings : dict, optional
        Overrides of the backend's settings.
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None
    #: With a ``[limits]`` table (SPEC §14): the speed and ``y`` bounds at the grid nodes only
    #: (``nodes``; the exact violation between nodes is reported and a plan beyond a bound is
    #: ``limits_violated``) or certified between them by Bernstein rows (``certified``).  A CLI
    #: option (``--limits-between``; the metadata of :func:`iamp.planners.registry.option`, written
    #: out here because the registry imports this module).
    limits_between: str = field(default="nodes", metadata={
        "cli": "with a [limits] table: the speed and y bounds at the grid nodes (nodes; the exact violation "
               "between nodes is reported, a plan beyond a bound is limits_violated) or certified between the "
               "nodes too (Bernstein rows); the avoidance QP (--constraint avoid) certifies by default",
        "choices": LIMITS_BETWEEN})

    def __post_init__(self) -> None:
        check_steps(self.steps)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_choice(self.solver, tuple(BACKENDS), "solver", "solver")
        check_choice(self.contact, CONTACTS, "contact", "contact search")
        check_choice(self.limits_between, LIMITS_BETWEEN, "limits_between", "limits_between")
