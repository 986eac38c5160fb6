"""The options of the discretised-QP planner (:class:`QPOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from iamp.core.errors import OptionError

from .backends import BACKENDS
from .hold import HOLDS

#: The contact-time searches of the QP planners: every grid node, or refined off the grid.
CONTACTS = ("grid", "refine")


def check_choice(value: object, choices: tuple[str, ...] | list[str], field: str, what: str) -> None:
    """Raise :class:`~iamp.core.errors.OptionError` naming the choices unless ``value`` is one."""
    if value not in choices:
        raise OptionError(f"unknown {what} {value!r}; choose from {', '.join(choices)}", field)


def check_steps(steps: object, minimum: int = 1) -> None:
    """``steps`` must be an integer ``>= minimum`` (not a bool)."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < minimum:
        need = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise OptionError(f"must be {need} (got {steps!r})", "steps")


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
    solver_settings : dict, optional
        Overrides of the backend's settings.
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        check_steps(self.steps)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_choice(self.solver, tuple(BACKENDS), "solver", "solver")
        check_choice(self.contact, CONTACTS, "contact", "contact search")
