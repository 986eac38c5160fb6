"""A scenario turned into a plannable problem: history vehicles go through a predictor.

This sits in the prediction layer because it chooses the predictor (the shipped model by
default); :mod:`iamp.core.scenario` itself never imports the predictor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from iamp.core.problem import Problem
from iamp.core.scenario import Predicted, Scenario, load_scenario
from iamp.prediction.predictor import Predictor


def default_predictor() -> Predictor:
    """The shipped predictor (model ``prediction/data/mtd_default.json``)."""
    return Predictor.default()


def load_problem(spec: str, model: str | None = None) -> tuple[Scenario, Problem, list[Any]]:
    """Scenario file or built-in name -> ``(scenario, problem, predictions)``.

    Vehicles given by a ``history`` are predicted with the model file ``model`` or, if it is
    ``None``, the shipped model; vehicles given by ``x_poly`` pass through unchanged.
    """
    return problem_from_scenario(load_scenario(spec), model)


def problem_from_scenario(scenario: Scenario, model: str | None = None) -> tuple[Scenario, Problem, list[Any]]:
    """A loaded scenario -> ``(scenario, problem, predictions)``, predicting history vehicles
    with the model file ``model`` or the shipped model."""
    if not scenario.needs_prediction:
        problem, predictions = scenario.to_problem(None)
        return scenario, problem, predictions
    predictor = Predictor.from_file(model) if model is not None else default_predictor()
    problem, predictions = scenario.to_problem(predicted(scenario, predictor))
    return scenario, problem, predictions


def predicted(scenario: Scenario, predictor: Predictor) -> Predicted:
    """Every history of ``scenario`` predicted by ``predictor`` over the scenario's horizon, for
    :meth:`~iamp.core.scenario.Scenario.to_problem` (a prediction that raises is kept and raised
    there, in the vehicles' order, after the check of the predictor's time step)."""
    tf = scenario.ego.tf
    out: dict[int, object] = {}
    for v in scenario.vehicles:
        if v.history is not None:
            try:
                out[id(v.history)] = predictor.predict(v.history, tf)
            except Exception as exc:  # raised again by the core, where it is located
                out[id(v.history)] = exc
    name = getattr(predictor, "name", None)
    dt = getattr(predictor, "dt", None)
    return Predicted(out, str(name) if name is not None else None, float(dt) if isinstance(dt, (int, float)) else None)


@dataclass(frozen=True)
class _LeaderPrediction:
    x_poly: tuple[float, ...]
    t: Any
    x: Any


def problem_with_leader_model(scenario: Scenario, leader_model: str) -> tuple[Problem, list[Any]]:
    """``(problem, predictions)`` with every history vehicle predicted by the leader-aware predictor
    of the file ``leader_model`` (the vehicle ahead in its lane, |dy| < 1.75 m, as leader; the
    model's MTD fallback where there is none): the scenario-level counterpart of
    :func:`problem_from_scenario` (``iamp plan --leader-model``)."""
    from iamp.prediction.leader.model import SIM_DT, LeaderPredictor, predict_scenario

    lp = LeaderPredictor.from_file(leader_model)
    res = predict_scenario(lp, scenario.vehicles, scenario.ego.tf)
    by_history = {id(scenario.vehicles[i].history): _LeaderPrediction(c, t, x) for i, (c, t, x) in res.items()}
    return scenario.to_problem(Predicted(by_history, leader_model, SIM_DT))
