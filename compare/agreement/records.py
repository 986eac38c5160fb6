"""The JSON records of an agreement comparison (SPEC §5b), as typed dictionaries.

A run (:class:`RunJSON`, :meth:`iamp.comparison.agreement.runs.Run.to_json`), a pair's verdict
(:class:`PairJSON`: its gaps, checks, reasons and notes) and their parts.  They are plain
``dict`` objects at run time: the JSON is what it always was; the types say which keys it has.
"""

from __future__ import annotations

from typing import NotRequired, TypedDict

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.timing import StatsJSON

__all__ = [
    "KKTJSON",
    "CheckJSON",
    "ContinuousJSON",
    "GridFeasibilityJSON",
    "PairJSON",
    "RunGaps",
    "RunJSON",
    "SameContactTimes",
    "SignEntry",
    "ZohGapJSON",
    "ZohReference",
]


class CheckJSON(TypedDict):
    """One named check ``value <= limit`` of a pair."""

    value: float | None
    limit: float | None
    ok: bool


class SignEntry(TypedDict):
    """One entry of ``signs``: ``Φ_x`` (or ``ν_x``) of a vehicle, its sign and meaning."""

    vehicle: str
    corner: str
    phi_x: float
    sign: int
    binding_for_safety: bool
    meaning: str


class RunGaps(TypedDict):
    """The headline gaps of one run against another (:func:`~.gaps.run_vs_run_gaps`)."""

    cost_rel_gap: float
    contact_time_gap: float
    state_sup_gap: float
    input_sup_gap: float
    jump_gap: float


class SameContactTimes(TypedDict):
    """A QP against the PMP re-solved at the QP's own contact times (:func:`~.gaps.at_same_contact_times`)."""

    reference: str
    contact_times: list[float]
    cost_rel_gap: float
    state_sup_gap: float
    input_sup_gap: float
    jump_gap: float
    nu_minus_phi: list[list[float]]
    contact_time_gap_to_grid_optimum: NotRequired[float]  # grid sweeps


class ContinuousJSON(TypedDict):
    """A pair's ``continuous`` object: the grid's spacing and the candidates bracketing ``t*``."""

    h: float
    bracket_cost: NotRequired[float]
    bracket_nodes: NotRequired[list[list[int]]]


class ZohGapJSON(TypedDict):
    """Rule 7: the ZOH cost's excess over the PMP's at the same contact times and its bracket."""

    gap: float
    leading_h2_term: float
    upper_bound: float
    rho: float
    ratio_to_leading: float | None


class ZohReference(TypedDict):
    """The exact ZOH optimum at grid contact nodes (:func:`~.references.zoh_reference`)."""

    cost: float
    X: NDArray[np.float64]
    U: NDArray[np.float64]
    nu: NDArray[np.float64]
    J_continuous: float
    gap_leading: float
    rho: float


class GridFeasibilityJSON(TypedDict):
    """Rule B1 of a bounded pair whose QP says ``infeasible`` beside a verified bounded PMP plan:
    the search for a plan of the QP's grid built from the PMP's plan
    (:func:`~.bounded_pair.grid_plan_from_pmp`)."""

    steps: int
    hold: str
    candidates: int  # contact-node candidates of the grid, (N - 1)^m
    examined: int  # nearest the PMP's contact times first, at most B1_MAX_CANDIDATES
    certified_no_plan: int  # the input box infeasible at the node times (Farkas), or a shared node, distinct corners
    violating: int  # the plan built there violates a row of the QP
    undecided: int  # the bounded PMP at the node times failed otherwise
    proved_infeasible: bool  # every candidate examined and certified to hold no plan: the QP's claim is proved
    worst_candidate: list[int] | None
    worst_row: str | None
    worst_node: int | None
    worst_violation_rel: float | None
    worst_equality_residual_rel: float | None
    plan_nodes: list[int] | None  # a plan of the grid (the QP's infeasible contradicted)
    plan_cost: float | None
    plan_equality_residual_rel: float | None
    plan_limit_violation_rel: float | None


class PairJSON(TypedDict):
    """One entry of SPEC §5b's ``agreement``: the verdict on a pair of runs ``a``, ``b``.

    The gaps are ``null`` when a run failed; the keys after ``jump_gap`` exist for a judged
    ``pmp`` / QP pair; ``verdict``, ``reasons``, ``notes`` and ``checks`` close every pair
    (:meth:`~.verdict.Checks.finish`).
    """

    a: str
    b: str
    cost_rel_gap: float | None
    contact_time_gap: float | None
    state_sup_gap: float | None
    input_sup_gap: float | None
    jump_gap: float | None
    at_same_contact_times: NotRequired[SameContactTimes]
    reference: NotRequired[str]
    signs: NotRequired[list[SignEntry]]
    zoh_gap: NotRequired[ZohGapJSON]
    continuous: NotRequired[ContinuousJSON]
    bounded: NotRequired[dict[str, float | str | None]]  # a bounded problem's pair (rule B6)
    grid_feasibility: NotRequired[GridFeasibilityJSON]  # a bounded pair, the QP infeasible (rule B1)
    verdict_basis: NotRequired[str]
    verdict: NotRequired[str]
    reasons: NotRequired[list[str]]
    notes: NotRequired[list[str]]
    checks: NotRequired[dict[str, CheckJSON]]


class KKTJSON(TypedDict):
    """A QP run's KKT residuals, recomputed from the QP matrices and the returned ``(x, y)``."""

    primal: float
    dual: float
    gap: float
    primal_rel: float
    dual_rel: float
    gap_rel: float
    source: str
    complementarity_rel: NotRequired[float]  # the limit rows of a bounded QP


class RunJSON(TypedDict):
    """One run as in SPEC §5b's ``runs`` (:meth:`~.runs.Run.to_json`)."""

    label: str
    planner: str
    solver: str | None
    hold: str | None
    steps: int | None
    path: str | None
    contact: str | None
    settings: dict[str, object] | None
    status: str
    cost: float | None
    contact_times: list[float]
    jumps: list[list[float]]
    time_s: StatsJSON | None
    x_poly_sha256: str
    problem_sha256: str
    residuals: dict[str, float]
    kkt: KKTJSON | None
    notes: list[str]
    # QP runs
    n_solves: NotRequired[int]
    failed_candidates: NotRequired[int]
    failed_statuses: NotRequired[list[str]]
    unpolished_candidates: NotRequired[int]
    # added by the reproduction (iamp.comparison.report.scenarios.plan_scenario) to verified runs
    constraint_role: NotRequired[list[str]]
    solve_time_s: NotRequired[float]
    grid_best: NotRequired[object]
