"""The options of the avoidance QP (:class:`AvoidOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from iamp.core.errors import OptionError

from ..qp.backends import BACKENDS
from ..qp.hold import HOLDS
from ..qp.options import CONTACTS, check_choice, check_steps


def inequality_backends() -> tuple[str, ...]:
    """The registered QP backends that accept inequality rows (the avoidance QP needs them)."""
    return tuple(name for name, cls in BACKENDS.items() if cls.supports_inequalities)


def check_avoid_solver(solver: object) -> None:
    """Refuse a backend that cannot solve the avoidance QP, naming the ones that can."""
    ok = inequality_backends()
    if solver in BACKENDS and solver not in ok:
        raise OptionError(f"QP backend {solver!r} solves equality-constrained QPs only, but the avoidance QP has "
                          f"inequality rows; choose from {', '.join(ok)}", "solver")
    check_choice(solver, ok, "solver", "solver")


@dataclass(frozen=True)
class AvoidOptions:
    """Options of :class:`~iamp.planners.avoid.planner.AvoidQPPlanner`.

    Parameters
    ----------
    steps : int
        Grid intervals ``N`` (at least 2).
    hold : {"foh", "zoh"}
    solver : str
        A registered QP backend that accepts inequalities (osqp, clarabel, piqp; ``kkt`` is refused).
    contact : {"grid", "refine"}
    solver_settings : dict, optional
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        check_steps(self.steps)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_avoid_solver(self.solver)
        check_choice(self.contact, CONTACTS, "contact", "contact search")
