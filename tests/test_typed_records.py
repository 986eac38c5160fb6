"""The typed records (issue 18 item 3) say what the JSON holds: every record a producer returns has
exactly the keys of its TypedDict (every required key, no key the type does not declare) and, where
the declared type is a plain scalar, a value of that type.  A producer that adds, drops or renames a
key without its type fails here (mypy cannot see the keys of a dict built at run time)."""

from __future__ import annotations

import types
import typing
from typing import NotRequired, Required, get_args, get_origin, get_type_hints

import numpy as np
import pytest

from iamp.comparison.agreement import records as agreement_records
from iamp.comparison.agreement.judge import QPConfig, compare_problem
from iamp.comparison.metrics import ManoeuvreMetrics, QualitativeEntry, manoeuvre_metrics, qualitative_comparison
from iamp.comparison.report.convergence import zoh_convergence
from iamp.comparison.report.records import ZohConvergence, ZohRow
from iamp.comparison.safety_compare import (
    RunJSON,
    SafetyComparisonJSON,
    SafetyJSON,
    VehicleSafetyJSON,
    safety_comparison,
    to_json,
)
from iamp.comparison.timing import StatsJSON, VersionsJSON, summarize, versions
from iamp.core.scenario import History
from iamp.planners.examples import paper_problem
from iamp.planners.pmp.planner import PMPPlanner
from iamp.prediction.loaders.report import LoadReport, LoadReportJSON
from iamp.prediction.mtd.model import ModelJSON, ModelSummary
from iamp.prediction.predictor import PredictionJSON, Predictor

SCALARS = (bool, int, float, str, type(None))


def _keys(td: type) -> tuple[set[str], set[str]]:
    """``(required, optional)`` keys of a TypedDict, ``NotRequired[...]`` read from its annotations
    (``from __future__ import annotations`` hides them from ``__required_keys__``)."""
    hints = get_type_hints(td, include_extras=True)
    optional = set(td.__optional_keys__)  # type: ignore[attr-defined]
    optional |= {k for k, t in hints.items() if get_origin(t) is NotRequired}
    optional -= {k for k, t in hints.items() if get_origin(t) is Required}
    return set(hints) - optional, optional


def _scalar_types(annotation: object) -> tuple[type, ...] | None:
    """The scalar types an annotation allows (``None`` when it is not made of plain scalars only)."""
    if get_origin(annotation) in (NotRequired, Required):
        annotation = get_args(annotation)[0]
    if annotation is type(None) or annotation is None:
        return (type(None),)
    if annotation in SCALARS:
        return (int, float) if annotation is float else (annotation,)  # type: ignore[return-value]
    if get_origin(annotation) in (typing.Union, types.UnionType):
        out: tuple[type, ...] = ()
        for a in get_args(annotation):
            s = _scalar_types(a)
            if s is None:
                return None
            out += s
        return out
    return None


def assert_record(record: object, td: type) -> None:
    """``record`` is a dict with exactly ``td``'s keys; scalar-typed values have their type."""
    assert isinstance(record, dict), type(record)
    required, optional = _keys(td)
    keys = set(record)
    assert required <= keys, f"{td.__name__}: missing {sorted(required - keys)}"
    assert keys <= required | optional, f"{td.__name__}: undeclared {sorted(keys - required - optional)}"
    hints = get_type_hints(td, include_extras=True)
    for k, v in record.items():
        allowed = _scalar_types(hints[k])
        if allowed is not None:
            ok = isinstance(v, allowed) and not (isinstance(v, bool) and bool not in allowed)
            assert ok, f"{td.__name__}.{k} = {v!r} is not {allowed}"


@pytest.fixture(scope="module")
def problem():
    return paper_problem(1)


def test_agreement_runs_and_pairs_have_their_declared_keys(problem):
    comp = compare_problem(problem, [QPConfig(solver="clarabel", hold="zoh", steps=20),
                                     QPConfig(solver="osqp", hold="zoh", steps=20)],
                           repeats=1, pmp_repeats=1, warmup=0)
    for run in comp.runs:
        d = run.to_json()
        assert_record(d, agreement_records.RunJSON)
        assert_record(d["time_s"], StatsJSON)
        if d["kkt"] is not None:
            assert_record(d["kkt"], agreement_records.KKTJSON)
    pmp_qp, qp_qp = comp.agreement[0], comp.agreement[-1]  # the PMP against a QP; the two QPs
    assert (qp_qp["a"], qp_qp["b"]) == ("qp-clarabel-zoh-20", "qp-osqp-zoh-20")
    for pair in comp.agreement:
        assert_record(pair, agreement_records.PairJSON)
        for check in pair["checks"].values():
            assert_record(check, agreement_records.CheckJSON)
    assert_record(pmp_qp["at_same_contact_times"], agreement_records.SameContactTimes)
    assert_record(pmp_qp["zoh_gap"], agreement_records.ZohGapJSON)
    assert_record(pmp_qp["continuous"], agreement_records.ContinuousJSON)
    for sign in pmp_qp["signs"]:
        assert_record(sign, agreement_records.SignEntry)


def test_safety_comparison_records(problem):
    res = to_json(safety_comparison(problem, steps=20))
    assert_record(res, SafetyComparisonJSON)
    for run in res["runs"]:
        assert_record(run, RunJSON)
        if run["safety"] is not None:
            assert_record(run["safety"], SafetyJSON)
            for v in run["safety"]["vehicles"]:
                assert_record(v, VehicleSafetyJSON)


def test_metrics_and_zoh_study_records(problem):
    pmp = PMPPlanner().plan(problem)
    m = manoeuvre_metrics(pmp)
    assert_record(m, ManoeuvreMetrics)
    qual = qualitative_comparison({"paper-1": m, "paper-2": manoeuvre_metrics(PMPPlanner().plan(paper_problem(2)))})
    assert_record(qual["paper-2"], QualitativeEntry)
    conv = zoh_convergence(problem, (10, 20))
    assert_record(conv, ZohConvergence)
    for row in conv["rows"]:
        assert_record(row, ZohRow)
    assert "ratio_to_next" in conv["rows"][0] and "ratio_to_next" not in conv["rows"][-1]


def test_prediction_records():
    pred = Predictor.default()
    t = np.round(np.arange(-30, 1) * 0.1, 10)
    p = pred.predict(History(t, 15.0 * t), 5.0, quantiles=(0.1, 0.9), n_samples=50, seed=0)
    assert_record(p.to_dict(), PredictionJSON)
    assert_record(pred.model.to_dict(), ModelJSON)
    assert_record(pred.model.summary(), ModelSummary)
    report = LoadReport(["a.csv"], 10, 8, {"gap": 2}, ["note"])
    assert_record(report.to_dict(), LoadReportJSON)


def test_timing_records():
    assert_record(summarize([1.0, 2.0, 3.0]).to_dict(), StatsJSON)
    assert_record(versions(), VersionsJSON)


def test_the_checker_fails_on_a_wrong_record():
    good = summarize([1.0, 2.0]).to_dict()
    with pytest.raises(AssertionError, match="missing"):
        assert_record({k: v for k, v in good.items() if k != "median"}, StatsJSON)
    with pytest.raises(AssertionError, match="undeclared"):
        assert_record({**good, "extra": 1}, StatsJSON)
    with pytest.raises(AssertionError, match="is not"):
        assert_record({**good, "n": "3"}, StatsJSON)
