"""What ``iamp reproduce`` computes, typed: the scenarios it loads and plans (frozen dataclasses,
not serialised) and the records of ``results.json`` (typed dictionaries: plain ``dict`` objects at
run time, so the JSON is what it always was; the types say which keys it has).

``results.json`` (:class:`ResultsJSON`) holds per scenario a :class:`ScenarioJSON` (its Table I
row :class:`Table1Row`, the runs and verdicts of :mod:`iamp.comparison.agreement`, the metrics of
:mod:`iamp.comparison.metrics`), the ZOH study (:class:`ZohConvergence`), the timing
(:class:`TimingSection`), the predictor's evaluation (:class:`PredictorSummary`), the safety
comparison and the small closed-loop campaign (:class:`CampaignSection`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NotRequired, TypedDict

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.agreement.records import PairJSON, RunJSON
from iamp.comparison.bounded import BoundedRowJSON
from iamp.comparison.metrics import ManoeuvreMetrics, QualitativeEntry
from iamp.comparison.safety_compare import SafetyComparisonJSON
from iamp.comparison.timing import StatsJSON
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.scenario import Scenario
from iamp.prediction.predictor import Prediction

from .paper import PaperRow

__all__ = ["CampaignRun", "CampaignSection", "ConfigJSON", "EmptyStatsJSON", "FullCampaign", "HistoryJSON",
           "MachineJSON", "PredictionJSON", "PredictorSummary", "ResultsJSON", "ScenarioEntry", "ScenarioJSON",
           "ScenarioPlan", "Table1Row", "TimingSection", "VehicleJSON", "ZohConvergence", "ZohRow"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ScenarioEntry:
    """A built-in scenario as the reproduction loaded it (:func:`~.scenarios.load_scenario`).

    ``builtin`` is the name actually loaded (``<name>-poly`` when the history version could
    not be predicted: ``fallback``); ``source`` is ``"history"`` (vehicle 1 predicted) or
    ``"x_poly"``; ``predictions`` one per vehicle (``None`` for a vehicle given by ``x_poly``).
    """

    name: str
    builtin: str
    scenario: Scenario
    problem: Problem
    predictions: list[Prediction | None]
    source: str
    fallback: bool


@dataclass(frozen=True)
class ScenarioPlan:
    """One scenario planned by the PMP and every QP configuration (:func:`~.scenarios.plan_scenario`).

    ``results``: the plans by run label; ``runs`` and ``agreement``: their SPEC §5b JSON and
    the verdict of every pair.
    """

    results: dict[str, Plan]
    runs: list[RunJSON]
    agreement: list[PairJSON]
    agreement_source: str
    steps: int


class HistoryJSON(TypedDict):
    """Vehicle 1's observed history (times [s], positions [m])."""

    t: FloatArray
    x: FloatArray


class Table1Row(TypedDict):
    """A scenario's row of the paper's Table I with the geometry and trajectory the planners got."""

    v_e: float
    s_xf: float
    t_f: float
    x_s0: float
    v_s0: float
    x_poly: list[float]
    history: HistoryJSON | None
    L: float
    W: float
    S_x: float
    S_y: float
    y_s: float
    corner: str


class PredictionJSON(TypedDict):
    """Vehicle 1's prediction (:class:`~iamp.prediction.predictor.Prediction`'s arrays)."""

    x_poly: list[float]
    t: FloatArray
    x: FloatArray
    v: FloatArray
    a: FloatArray
    model: str
    fit_rmse: float


class VehicleJSON(TypedDict):
    """A surrounding vehicle of a scenario."""

    name: str
    corner: str
    y: float
    length: float
    width: float
    safety_x: float
    safety_y: float
    x_poly: list[float]


class ScenarioJSON(TypedDict):
    """One entry of ``results.json``'s ``scenarios``."""

    name: str
    builtin: str
    source: str
    fallback: bool
    table1: Table1Row
    paper_table1: PaperRow | None
    ego: dict[str, float]
    vehicles: list[VehicleJSON]
    prediction: PredictionJSON | None
    runs: list[RunJSON]
    agreement: list[PairJSON]
    agreement_source: str
    metrics: ManoeuvreMetrics | None
    #: each QP run's sweep: ``[[nodes...], cost]`` per candidate, by run label
    sweeps: dict[str, list[list[list[int] | float]]]


class ZohRow(TypedDict):
    """One grid of the ZOH convergence study (:func:`~.convergence.zoh_convergence`)."""

    N: int
    h: float
    node: int
    t_node: float
    J_pmp: float
    J_zoh: float | None
    J_foh: float | None
    zoh_gap: float | None
    foh_gap: float | None
    status_zoh: str
    status_foh: str
    ratio_to_next: NotRequired[float | None]  # every row but the last


class ZohConvergence(TypedDict):
    """The ZOH convergence study of one scenario."""

    solver: str
    t_contact: float
    rows: list[ZohRow]
    loglog_slope: float | None


class EmptyStatsJSON(TypedDict):
    """The statistics of no samples."""

    n: int
    median: None
    q1: None
    q3: None
    iqr: None


class MachineJSON(TypedDict):
    """The machine the timing ran on."""

    python: str
    cpu_count: int | None
    platform: str
    load_average_1min: float | None


class TimingSection(TypedDict):
    """The reproduction's timing (:func:`~.timing.timing_section`)."""

    samples: dict[str, list[float]]
    summary: dict[str, StatsJSON | EmptyStatsJSON]
    #: per scenario, per run label: the whole plan's statistics (``None``: not timed)
    full_plans: dict[str, dict[str, StatsJSON | None]]
    pmp_timed_without_diagnostics: bool
    machine: MachineJSON


class PredictorSummary(TypedDict):
    """The predictor's evaluation as ``results.json`` reports it (:func:`~.predictor.predictor_evaluation`)."""

    how: str
    chosen: object
    test: object
    paper_histories: object
    seconds: object
    selection_run: bool
    file: str


class FullCampaign(TypedDict):
    """The shape of the published campaign (``reports/campaign-new/summary.json``)."""

    missions: list[str]
    planners: list[str]
    traffic: list[str]
    episodes: int


class CampaignRun(TypedDict):
    """What :func:`iamp.simulation.campaign.run_campaign` did: episodes run, reused, failed."""

    ran: int
    skipped: int
    failed: int
    seconds: float


class CampaignSection(TypedDict):
    """The small closed-loop campaign (:func:`~.campaign.campaign_section`); ``available`` false:
    only a ``note``."""

    available: bool
    note: NotRequired[str]
    summary: NotRequired[list[dict[str, object]]]
    ran: NotRequired[CampaignRun]
    command: NotRequired[str]
    table: NotRequired[str]
    full: NotRequired[FullCampaign | None]


class ConfigJSON(TypedDict):
    """:class:`~.config.ReproduceConfig` as ``results.json`` records it (``dataclasses.asdict``)."""

    steps_one: int
    steps_two: int
    qp_one: tuple[tuple[str, ...], ...]
    qp_two: tuple[tuple[str, ...], ...]
    zoh_steps: tuple[int, ...]
    plan_repeats: int
    plan_budget_s: float
    pmp_repeats: int
    pmp_repeats_two: int
    qp_solve_repeats: int
    timing_scenarios: tuple[str, ...]
    predictor_eval: bool
    predictor_select: bool | str
    quick: bool


class ResultsJSON(TypedDict):
    """``results.json`` (what :func:`~.reproduction.reproduce` returns)."""

    produced_by: str
    config: ConfigJSON
    notes: list[str]
    versions: dict[str, str | None]
    scenarios: list[ScenarioJSON]
    qualitative: dict[str, QualitativeEntry]
    zoh_convergence: dict[str, ZohConvergence]
    timing: TimingSection
    predictor: PredictorSummary | None
    safety: list[SafetyComparisonJSON]
    campaign: dict[str, object]
    bounded: list[BoundedRowJSON]
    runtime_s: NotRequired[float]
    outputs: NotRequired[list[str]]
