"""The records of the predictor's evaluation (``reports/predictor_eval.json``), as typed dictionaries:
plain ``dict`` objects at run time, so the JSON is what it always was; the types say which keys it has."""

from __future__ import annotations

from typing import Any, TypedDict

from ..leader.car_following import LawJSON
from ..loaders.report import LoadReportJSON
from ..windows import WindowMetrics
from .select import ModelConfig, Selection

__all__ = ["BootstrapInfo", "BootstrapTable", "DiffCI", "DiffToCV", "EvalProtocol", "EvaluationJSON", "HeldoutLoglik",
           "InteractionSection", "LeaderModelNote", "MethodRow", "PaperPrediction", "Reference", "TableDiffToCV",
           "UserEvaluation"]


class EvalProtocol(TypedDict):
    """How the evaluation was made: windows, horizons, metric, splits, data set and version."""

    history_s: float
    future_s: float
    stride_s: float
    eval_dt: float
    horizons_s: list[float]
    metric: str
    split: dict[str, float | int | str]
    n_tracks: dict[str, int]
    dataset: str
    dataset_sha256_track_t_x: str
    dataset_dt: float | None
    eval_version: int


class HeldoutLoglik(TypedDict):
    """A model's held-out log-likelihood of the test state sequences (``None``: a zero-probability transition)."""

    loglik: float | None
    n_obs: int
    loglik_per_transition: float | None


class PaperPrediction(TypedDict):
    """A prediction of one of the paper's histories over 5 s."""

    x_poly: list[float]
    fit_rmse: float
    v_at_5s: float
    x_at_5s: float
    a_at_0: float
    a_at_1s: float
    a_at_5s: float


class Reference(TypedDict):
    """A published number for scale, with its source."""

    values: list[float]
    source: str


class EvaluationJSON(TypedDict):
    """The evaluation's results (:func:`run_evaluation`; ``reports/predictor_eval.json``)."""

    protocol: EvalProtocol
    selection: Selection | None
    chosen: ModelConfig
    default_config: ModelConfig
    default_config_matches_selection: bool
    jerk_psd: float
    final_model: dict[str, object]
    test: dict[str, WindowMetrics]
    test_heldout_loglik: dict[str, HeldoutLoglik]
    paper_histories: dict[str, PaperPrediction]
    paper_histories_other_models: dict[str, dict[str, PaperPrediction]]
    ngsim_cv_reference_2d_rmse: Reference
    produced_by: str
    seconds: float


# -- ``iamp evaluate-predictor DATA`` (SPEC §13): :func:`~.user.evaluate_file` ------------------


class DiffCI(TypedDict):
    """A difference to constant velocity [m] with its track-bootstrap 95 % interval."""

    diff: float
    ci95: list[float]


class DiffToCV(TypedDict):
    """A method against constant velocity: RMSE per horizon, ADE and FDE differences."""

    rmse_m: list[DiffCI]
    ade_m: DiffCI
    fde_m: DiffCI


class TableDiffToCV(TypedDict):
    """A method against the reference in a :func:`~.leader.bootstrap_table` (differences and intervals)."""

    rmse_m: list[float]
    rmse_ci95: list[list[float]]
    rmse_5s_rel: float
    rmse_5s_rel_ci95: list[float]
    fde_m: float
    fde_ci95: list[float]


class _MethodRowBase(TypedDict):
    rmse_m: list[float]
    rmse_ci95: list[list[float]]
    ade_m: float
    ade_ci95: list[float]
    fde_m: float
    fde_ci95: list[float]


class MethodRow(_MethodRowBase, total=False):
    """A method's RMSE per horizon, ADE and FDE [m] with track-bootstrap 95 % intervals."""

    diff_to_cv: TableDiffToCV


class _BootstrapTableBase(TypedDict):
    windows: int
    tracks: int


class BootstrapTable(_BootstrapTableBase, total=False):
    """:func:`~.leader.bootstrap_table`: every method's row (absent when no window)."""

    methods: dict[str, MethodRow]


class LeaderModelNote(TypedDict):
    """The evaluated leader model: where it comes from and its law."""

    note: str
    law: str
    params: dict[str, float]
    fit: dict[str, object]


class InteractionSection(TypedDict):
    """The ``interaction`` section of ``evaluate-predictor`` (:func:`~.leader.interaction_section`)."""

    leader_source: str
    leader_rows_known: float
    windows_leader_known: int
    windows_leader_rejected: int
    leader_future_extended: int
    congested_below_mps: float
    windows_congested: int
    leader_model: LeaderModelNote
    oracle: str
    oracle_law: LawJSON
    tables: dict[str, BootstrapTable]


class BootstrapInfo(TypedDict):
    """How the intervals were made."""

    resamples: int
    by: str
    seed: int
    interval: str


class _UserEvaluationBase(TypedDict):
    data: str
    format: str
    tracks: int
    windows: int
    horizons_s: list[float]
    rmse_m: dict[str, list[float]]
    ade_m: dict[str, float]
    fde_m: dict[str, float]
    lateral_rmse_m: dict[str, list[float]] | None
    lateral_assumption: str
    diff_to_cv: dict[str, DiffToCV]
    bootstrap: BootstrapInfo
    split: str | None
    seed: int
    model: str
    jerk_psd: float
    load_report: LoadReportJSON


class UserEvaluation(_UserEvaluationBase, total=False):
    """``iamp evaluate-predictor DATA --json`` (SPEC §13; :func:`~.user.evaluate_file`).

    ``interaction`` is an :class:`InteractionSection`, held as a plain dict because
    ``iamp.cli.prediction.print_interaction`` takes one (retype it there, then here)."""

    interaction: dict[str, Any]
