"""The paper's facts the reproduction report needs (its Table I and figure numbers) and the
scenarios :func:`iamp.comparison.report.reproduce` runs."""

from __future__ import annotations

from typing import TypedDict

__all__ = ["PAPER_FIG", "PAPER_TABLE_I", "SCENARIOS", "PaperRow"]


class PaperRow(TypedDict):
    """A row of the paper's Table I and vehicle 1's behaviour before ``t = 0``."""

    scenario: int
    v_e: float
    s_xf: float
    t_f: float
    x_s0: float
    v_s0: float
    before: str


#: The paper's Table I (SPEC §8) and the qualitative behaviour of vehicle 1 before t = 0.
PAPER_TABLE_I: dict[str, PaperRow] = {
    "paper-1": {"scenario": 1, "v_e": 20.0, "s_xf": 85.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 18.0,
                "before": "constant speed"},
    "paper-2": {"scenario": 2, "v_e": 20.0, "s_xf": 73.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 20.0,
                "before": "decelerating"},
    "paper-3": {"scenario": 3, "v_e": 20.0, "s_xf": 90.0, "t_f": 5.0, "x_s0": -15.0, "v_s0": 13.0,
                "before": "accelerating"},
}
#: The built-in scenarios :func:`iamp.comparison.report.reproduce` runs by default.
SCENARIOS = ("paper-1", "paper-2", "paper-3", "two-vehicle")
#: The paper's figure numbers per scenario: (the ``(x, y)`` snapshots, the positions).
PAPER_FIG: dict[str, tuple[int, int]] = {"paper-1": (4, 7), "paper-2": (5, 8), "paper-3": (6, 9)}
