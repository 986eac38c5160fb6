"""The sizes of ``iamp reproduce``'s experiments (:class:`ReproduceConfig`), and its progress
convention."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

#: ``progress(done, total)``, the project's progress convention.
ProgressFn = Callable[[int, int], None]
#: A QP configuration ``(solver, hold, contact, path)`` (``path`` may be left out: ``"cvxpy"``).
QPConfigTuple = tuple[str, ...]

__all__ = ["ProgressFn", "ReproduceConfig"]


@dataclass
class ReproduceConfig:
    """Sizes of the experiments (the defaults are the full report; :meth:`quick_config` is a
    smoke run).

    ``qp_one`` / ``qp_two`` list ``(solver, hold, contact, path)`` QP configurations for one-
    and two-vehicle scenarios, on ``steps_one`` / ``steps_two`` intervals (``path``:
    ``"cvxpy"`` — :class:`~iamp.planners.qp.planner.QPPlanner` — or ``"native"``).  Each plan is
    repeated up to ``plan_repeats`` times for its timing, stopping once the samples exceed
    ``plan_budget_s``.
    """

    steps_one: int = 100
    steps_two: int = 30
    qp_one: tuple[QPConfigTuple, ...] = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "zoh", "grid", "cvxpy"), ("clarabel", "foh", "refine", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    qp_two: tuple[QPConfigTuple, ...] = (("clarabel", "foh", "grid", "cvxpy"), ("osqp", "foh", "grid", "cvxpy"),
                     ("clarabel", "foh", "grid", "native"))
    zoh_steps: tuple[int, ...] = (25, 50, 100, 200, 400)
    plan_repeats: int = 3
    plan_budget_s: float = 4.0
    pmp_repeats: int = 200
    pmp_repeats_two: int = 20
    qp_solve_repeats: int = 30
    timing_scenarios: tuple[str, ...] = ("paper-1", "two-vehicle")
    predictor_eval: bool = True
    predictor_select: bool | str = "auto"
    quick: bool = False

    @classmethod
    def quick_config(cls) -> ReproduceConfig:
        return cls(steps_one=20, steps_two=8, zoh_steps=(25, 50, 100), plan_repeats=1, pmp_repeats=20,
                   pmp_repeats_two=5, qp_solve_repeats=5, predictor_select=False, quick=True)
