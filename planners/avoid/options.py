"""The options of the avoidance QP (:class:`AvoidOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iamp.core.errors import OptionError

from ..qp.backends import BACKENDS, SUPPORTS_INEQUALITIES
from ..qp.hold import HOLDS
from ..qp.options import CONTACTS, LIMITS_BETWEEN, check_choice, check_steps

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
        QPs the continuous-time branch and bound may solve before it stops with ``local`` (a
        count of work: the same problem gives the same status and plan on any machine, SPEC §17;
        a budget never refuses a problem).
    max_boxes : int
        Crossing-time boxes the branch and bound may create before it stops with ``local``
        (a count of work, as ``max_solves``; boxes bounded by the dual polynomials alone are
        split without a QP).
    time_limit_s : None
        Removed (it was a wall-clock budget, which made the status depend on the machine and its
        load); any value is refused with :class:`~iamp.core.errors.OptionError` naming ``max_solves``.
    limits_between : {"certified", "nodes"}
        The car's limits (SPEC §14) between the grid nodes: ``"certified"`` (default) adds each
        piece's inner Bernstein coefficients as rows, so the speed and lateral bounds hold for
        every ``t`` (sufficient, slightly tighter than the exact bound); ``"nodes"`` imposes them at
        the nodes only (kept for study; a plan that passes a bound between nodes is
        ``limits_violated``).
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
    max_boxes: int = 20000
    time_limit_s: None = None
    limits_between: str = field(default="certified", metadata={
        "cli": "avoidance QP only: the car's limits between the grid nodes certified by each piece's Bernstein "
               "coefficients (certified, default) or imposed at the nodes only (nodes, kept for study)",
        "choices": LIMITS_BETWEEN})

    def __post_init__(self) -> None:
        check_steps(self.steps)
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_avoid_solver(self.solver)
        check_choice(self.contact, CONTACTS, "contact", "contact search")
        check_choice(self.safety, SAFETY_MODES, "safety", "safety mode")
        check_choice(self.limits_between, LIMITS_BETWEEN, "limits_between", "limits_between")
        if isinstance(self.max_solves, bool) or not isinstance(self.max_solves, int) or self.max_solves < 1:
            raise OptionError(f"must be a positive integer (got {self.max_solves!r})", "max_solves")
        if isinstance(self.max_boxes, bool) or not isinstance(self.max_boxes, int) or self.max_boxes < 1:
            raise OptionError(f"must be a positive integer (got {self.max_boxes!r})", "max_boxes")
        refuse_wall_clock_budget(self.time_limit_s)


def refuse_wall_clock_budget(time_limit_s: object) -> None:
    """Refuse the removed wall-clock budget ``time_limit_s`` (any value but ``None``).

    Parameters
    ----------
    time_limit_s : object
        The value given for the removed option.

    Raises
    ------
    OptionError
        When a value is given: budgets count work (SPEC §17), so the option names ``max_solves``.
    """
    if time_limit_s is not None:
        raise OptionError(f"was a wall-clock budget and is removed: a search budget counts work so that the "
                          f"same problem gives the same status and plan on any machine (SPEC §17); use "
                          f"max_solves (QP solves of the branch and bound, default 2000) instead "
                          f"(got {time_limit_s!r})", "time_limit_s")
