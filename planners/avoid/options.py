"""The options of the avoidance QP (:class:`AvoidOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iamp.core.errors import OptionError

from ..qp.backends import BACKENDS, SUPPORTS_INEQUALITIES
from ..qp.hold import HOLDS
from ..qp.options import CONTACTS, check_choice, check_steps

#: ``--safety`` of the avoidance QP (SPEC §14): certified in continuous time, or at the nodes only.
SAFETY_MODES = ("continuous", "nodes")


def inequality_backends() -> tuple[str, ...]:
    """The registered QP backends that accept inequality rows (the avoidance QP needs them)."""
    return tuple(name for name in BACKENDS if SUPPORTS_INEQUALITIES[name])


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
    safety : {"continuous", "nodes"}
        ``--safety``: ``"continuous"`` (default, SPEC §14) keeps both half-planes at the crossing
        time and certifies every piece by its Bernstein coefficients (branch and bound over the
        crossing times); ``"nodes"`` imposes the inequalities at the grid nodes only (SPEC §10 as
        first written, kept for study; a plan that intrudes between nodes is ``unsafe``).
    max_solves : int
        QPs the continuous-time branch and bound may solve before it stops with ``local``.
    time_limit_s : float
        Its wall-time budget (``local`` beyond it; a budget never refuses a problem).
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None
    safety: str = field(default="continuous", metadata={
        "cli": "avoidance QP only: both half-planes at the crossing time and every piece certified by its "
               "Bernstein coefficients (continuous, default) or the inequalities at the nodes only (nodes, kept "
               "for study)", "choices": SAFETY_MODES})
    max_solves: int = 2000
    time_limit_s: float = 60.0

    def __post_init__(self) -> None:
        check_steps(self.steps)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_avoid_solver(self.solver)
        check_choice(self.contact, CONTACTS, "contact", "contact search")
        check_choice(self.safety, SAFETY_MODES, "safety", "safety mode")
        if isinstance(self.max_solves, bool) or not isinstance(self.max_solves, int) or self.max_solves < 1:
            raise OptionError(f"must be a positive integer (got {self.max_solves!r})", "max_solves")
        if not isinstance(self.time_limit_s, (int, float)) or not self.time_limit_s > 0:
            raise OptionError(f"must be a positive number of seconds (got {self.time_limit_s!r})", "time_limit_s")
